//! `rt-client`: fetch frames from the ray tracer (board, emulated board or
//! the simulated board started in-process) as PNG, GIF or a live window.

mod control;
mod live;
mod net;
mod orbit;
mod output;
mod script;
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
        /// The server's frame port, HOST:PORT. Without it, a simulated
        /// board is started in-process.
        #[arg(long)]
        server: Option<String>,
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
    /// A window onto the server's frames; move the light and see it
    /// re-rendered live.
    ///
    /// Mouse: drag with the left button orbits the light around the sphere
    /// (azimuth, elevation); the wheel changes its distance. Keys: arrows
    /// turn it by 5 degrees, PageUp/PageDown bring it closer/farther, Space
    /// starts/stops the automatic orbit, R resets, P saves the frame on
    /// screen as live-NNN.png, Escape (or closing the window) quits. The
    /// title shows the light, frames/s and median latency of the last
    /// second, the server and the connection state.
    Live {
        /// The server's frame port, HOST:PORT (the persistent port is the
        /// next one). Without it, a simulated board is started in-process.
        #[arg(long)]
        server: Option<String>,
        /// Enlarge the window by this integer factor (1-8).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=8))]
        scale: u32,
        /// Replay timed input events from FILE instead of the mouse and keys
        /// (docs/live-viewer.md: one `MS EVENT` per line).
        #[arg(long)]
        script: Option<PathBuf>,
        /// Write the frames shown to an animated GIF.
        #[arg(long)]
        record: Option<PathBuf>,
        /// On exit, save the last frame shown as PNG.
        #[arg(long)]
        save_last: Option<PathBuf>,
    },
    /// Measure the live viewer's input-to-screen latency (no window).
    BenchLive {
        /// The server's frame port; without it, a simulated board in-process.
        #[arg(long)]
        server: Option<String>,
        /// Input events to send.
        #[arg(long, default_value_t = 200)]
        events: usize,
        /// Input events per second.
        #[arg(long, default_value_t = 60.0)]
        hz: f64,
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
        Command::Frame { server, light, out } => frame(server.as_deref(), &light, &out),
        Command::Live { server, scale, script, record, save_last } => live(server, scale, script, record, save_last),
        Command::BenchLive { server, events, hz } => {
            board(server.as_deref()).and_then(|(addr, _b)| live::bench(addr, events, hz))
        }
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

/// The server's frame port, or a simulated board started in-process
/// (kept alive by the returned handle).
fn board(server: Option<&str>) -> Result<(SocketAddr, Option<HpsSim>), String> {
    match server {
        Some(s) => Ok((net::resolve(s).map_err(|e| e.to_string())?, None)),
        None => {
            let board = HpsSim::start_quiet(SocketAddr::from(([127, 0, 0, 1], 0)))
                .map_err(|e| format!("cannot start the simulated board: {e}"))?;
            eprintln!("rt-client: simulated board on {}", board.frame_addr());
            Ok((board.frame_addr(), Some(board)))
        }
    }
}

fn live(
    server: Option<String>,
    scale: u32,
    script: Option<PathBuf>,
    record: Option<PathBuf>,
    save_last: Option<PathBuf>,
) -> Result<(), String> {
    let script = match script {
        Some(p) => {
            Some(script::Script::parse(&std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?)?)
        }
        None => None,
    };
    let (addr, _board) = board(server.as_deref())?;
    let server_name = match &server {
        Some(s) => s.clone(),
        None => format!("simulated board {addr}"),
    };
    live::run(live::LiveOptions { server: addr, server_name, scale: scale as usize, script, record, save_last })
}

fn frame(server: Option<&str>, light: &Light, out: &std::path::Path) -> Result<(), String> {
    let (addr, _board) = board(server)?;
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
    let (addr, _board) = board(args.server.as_deref())?;
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
