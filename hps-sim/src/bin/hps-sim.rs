//! `hps-sim`: the board simulated on the host.
//!
//!     cargo run --release --bin hps-sim -- --listen 127.0.0.1:7878 [--mode rows] [--accelerator rtl] [--rtsp 127.0.0.1:8554]
//!
//! Seed protocol on the listen port, persistent protocol on the port + 1,
//! RTSP on `--rtsp` (default: the listen address, port 8554).

use std::net::SocketAddr;
use std::process::ExitCode;

use clap::Parser;
use hps_sim::{Config, Device, HpsSim, RenderMode};

#[derive(Parser)]
#[command(name = "hps-sim", about = "The ray tracer board simulated on the host")]
struct Args {
    /// Address of the seed-protocol port; the persistent port is the next one.
    #[arg(long, default_value_t = SocketAddr::from(([127, 0, 0, 1], rt_services::FRAME_PORT)))]
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
    /// Address of the RTSP server (the board as a network camera; RTP and
    /// RTCP leave from two free UDP ports). Default: the listen address
    /// with port 8554.
    #[arg(long)]
    rtsp: Option<SocketAddr>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let (render, device) = (args.mode, args.accelerator);
    match HpsSim::start_config(args.listen, Config { render, device }, true) {
        Ok(mut sim) => {
            let rtsp = args.rtsp.unwrap_or(SocketAddr::new(args.listen.ip(), rt_services::camera::rtsp::RTSP_PORT));
            let rtsp = match sim.start_rtsp(rtsp, device, true) {
                Ok(addr) => addr,
                Err(e) => {
                    eprintln!("hps-sim: cannot serve RTSP on {rtsp}: {e}");
                    return ExitCode::FAILURE;
                }
            };
            eprintln!(
                "hps-sim: {render:?} mode, {device:?} accelerator; frames on {} (one per connection), persistent on {}, \
                 RTSP on rtsp://{rtsp}/light/3,4,-2 (also /orbit, /live)",
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
