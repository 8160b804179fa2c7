//! `hps-sim`: the board simulated on the host.
//!
//!     cargo run --release --bin hps-sim -- --listen 127.0.0.1:7878
//!
//! Seed protocol on the listen port, persistent protocol on the port + 1.

use std::net::SocketAddr;
use std::process::ExitCode;

use clap::{Parser, ValueEnum};
use hps_sim::{HpsSim, RenderMode};

#[derive(Parser)]
#[command(name = "hps-sim", about = "The ray tracer board simulated on the host")]
struct Args {
    /// Address of the seed-protocol port; the persistent port is the next one.
    #[arg(long, default_value_t = SocketAddr::from(([127, 0, 0, 1], rt_protocol::FRAME_PORT)))]
    listen: SocketAddr,
    /// How the simulated accelerator renders: whole frames by DMA into
    /// memory (the board's main mode) or one row per start.
    #[arg(long, value_enum, default_value_t = Mode::Frames)]
    mode: Mode,
}

#[derive(Clone, Copy, ValueEnum)]
enum Mode {
    /// Frame DMA into a ring of frame slots.
    Frames,
    /// Row by row through the line buffer.
    Rows,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let render = match args.mode {
        Mode::Frames => RenderMode::Frames,
        Mode::Rows => RenderMode::Rows,
    };
    match HpsSim::start_with(args.listen, render, true) {
        Ok(sim) => {
            eprintln!(
                "hps-sim: {render:?} mode; frames on {} (one per connection), persistent on {}",
                sim.frame_addr(),
                sim.persistent_addr()
            );
            loop {
                std::thread::park();
            }
        }
        Err(e) => {
            eprintln!("hps-sim: cannot listen on {} and the next port: {e}", args.listen);
            ExitCode::FAILURE
        }
    }
}
