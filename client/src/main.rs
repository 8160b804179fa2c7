//! `rt-client`: fetch frames from the ray tracer (board, emulated board or
//! the simulated board started in-process) as PNG, GIF or a live window.

mod net;
mod orbit;
mod output;
mod stats;
mod window;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use hps_sim::HpsSim;
use indicatif::{ProgressBar, ProgressStyle};
use model::Light;

use crate::orbit::OrbitPath;
use crate::output::FrameSink;
use crate::stats::RunStats;

#[derive(Parser)]
#[command(name = "rt-client", version, about = "Client of the real-time FPGA ray tracer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fetch one frame over the seed protocol and save it as PNG.
    Frame {
        /// The server's frame port, HOST:PORT.
        #[arg(long)]
        server: String,
        /// Light position in world units: X,Y,Z.
        #[arg(long, allow_hyphen_values = true)]
        light: Light,
        /// Output PNG.
        #[arg(long, default_value = "frame.png")]
        out: PathBuf,
    },
    /// Animate the light orbiting the sphere over the persistent port.
    Orbit {
        #[command(flatten)]
        run: RunArgs,
        /// Output: an animated GIF (`*.gif`) or a directory of PNG frames.
        #[arg(long, default_value = "orbit.gif")]
        out: PathBuf,
        /// Show the frames live in a window as they arrive.
        #[arg(long)]
        show: bool,
    },
    /// Measure frames/s and latency of an orbit, saving nothing.
    Bench {
        #[command(flatten)]
        run: RunArgs,
    },
}

#[derive(Args)]
struct RunArgs {
    /// The server's frame port, HOST:PORT (the persistent port is the next
    /// one). Without it, a simulated board is started in-process.
    #[arg(long)]
    server: Option<String>,
    /// Number of frames (light positions) in one orbit.
    #[arg(long, default_value_t = 48, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Orbit radius in world units.
    #[arg(long, default_value_t = 3.0)]
    radius: f64,
    /// Light height in world units.
    #[arg(long, default_value_t = 4.0, allow_hyphen_values = true)]
    height: f64,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Frame { server, light, out } => frame(&server, &light, &out),
        Command::Orbit { run, out, show } => orbit(&run, Some(out), show),
        Command::Bench { run } => orbit(&run, None, false),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rt-client: {e}");
            ExitCode::FAILURE
        }
    }
}

fn frame(server: &str, light: &Light, out: &std::path::Path) -> Result<(), String> {
    let addr = net::resolve(server).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let rgb = net::fetch_frame(addr, light).map_err(|e| e.to_string())?;
    let took = start.elapsed();
    output::save_png(&rgb, out)?;
    println!("wrote {} ({:.1} ms)", out.display(), took.as_secs_f64() * 1e3);
    Ok(())
}

fn orbit(args: &RunArgs, out: Option<PathBuf>, show: bool) -> Result<(), String> {
    let path = OrbitPath { frames: args.frames as usize, radius: args.radius, height: args.height };
    let lights = path.lights().map_err(|e| format!("orbit leaves the light range: {e}"))?;
    // Keep the in-process board alive for the whole run.
    let (addr, _board) = match &args.server {
        Some(s) => (net::resolve(s).map_err(|e| e.to_string())?, None),
        None => {
            let board = HpsSim::start_quiet(SocketAddr::from(([127, 0, 0, 1], 0)))
                .map_err(|e| format!("cannot start the simulated board: {e}"))?;
            eprintln!("rt-client: simulated board on {}", board.frame_addr());
            (board.frame_addr(), Some(board))
        }
    };
    let mut window = if show { Some(window::LiveWindow::open("rt-client orbit")?) } else { None };
    let mut sink = FrameSink::new(out)?;
    let bar = ProgressBar::new(lights.len() as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut sink_error = None;
    let persistent = net::persistent_addr(addr).map_err(|e| e.to_string())?;
    let stats: RunStats = orbit::run(persistent, &lights, |_, rgb| {
        bar.inc(1);
        if let Err(e) = sink.push(rgb) {
            sink_error = Some(e);
            return false;
        }
        window.as_mut().is_none_or(|w| w.show(rgb))
    })
    .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    if let Some(e) = sink_error {
        return Err(e);
    }
    println!("{}", stats.report());
    if let Some(written) = sink.finish()? {
        println!("{written}");
    }
    Ok(())
}
