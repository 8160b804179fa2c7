//! `hps-sim`: the board simulated on the host.
//!
//!     cargo run --release --bin hps-sim -- --listen 127.0.0.1:7878 [--mode rows] [--accelerator rtl]
//!
//! Seed protocol on the listen port, persistent protocol on the port + 1.

use std::net::SocketAddr;
use std::process::ExitCode;

use clap::Parser;
use hps_sim::{Config, Device, HpsSim, RenderMode};

#[derive(Parser)]
#[command(name = "hps-sim", about = "The ray tracer board simulated on the host")]
struct Args {
    /// Address of the seed-protocol port; the persistent port is the next one.
    #[arg(long, default_value_t = SocketAddr::from(([127, 0, 0, 1], rt_protocol::FRAME_PORT)))]
    listen: SocketAddr,
    /// How the simulated accelerator renders: whole frames by DMA into
    /// memory (the board's main mode) or one row per start.
    #[arg(long, value_enum, default_value_t = RenderMode::Frames)]
    mode: RenderMode,
    /// Which accelerator renders: hal-avalon's simulated one (built from
    /// the model) or the Verilated RTL of fpga/rtl (cycle by cycle: about a
    /// second per frame; logs the simulated clocks per frame).
    #[arg(long, value_enum, default_value_t = Device::Sim)]
    accelerator: Device,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let (render, device) = (args.mode, args.accelerator);
    match HpsSim::start_config(args.listen, Config { render, device }, true) {
        Ok(sim) => {
            eprintln!(
                "hps-sim: {render:?} mode, {device:?} accelerator; frames on {} (one per connection), persistent on {}",
                sim.frame_addr(),
                sim.persistent_addr()
            );
            loop {
                std::thread::park();
            }
        }
        Err(e) if e.kind() == std::io::ErrorKind::Unsupported => {
            eprintln!("hps-sim: --accelerator rtl: {e}");
            ExitCode::FAILURE
        }
        Err(e) => {
            eprintln!("hps-sim: cannot listen on {} and the next port: {e}", args.listen);
            ExitCode::FAILURE
        }
    }
}
