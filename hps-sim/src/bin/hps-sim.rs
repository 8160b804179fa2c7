//! `hps-sim`: the board simulated on the host.
//!
//!     cargo run --release --bin hps-sim -- --listen 127.0.0.1:7878 [--mode rows] [--accelerator rtl] [--rtsp 127.0.0.1:8554]
//!         [--multicast-group 239.255.42.1 [--multicast-port 5006] [--multicast-ttl 1]] [--http 127.0.0.1:8080]
//!
//! Seed protocol on the listen port, persistent protocol on the port + 1,
//! RTSP on `--rtsp` (default: the listen address, port 8554); multicast
//! streams to `--multicast-group` when one is given; the board's web page
//! on `--http` when one is given (open `http://ADDR:PORT/` in a browser).

use std::net::SocketAddr;
use std::process::ExitCode;

use clap::Parser;
use hps_sim::{Config, Device, Fault, Faults, HpsSim, RenderMode};
use rt_services_std::cli::ServiceArgs;
use rt_services_std::rtsp::Options;

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
    #[command(flatten)]
    services: ServiceArgs,
    /// Inject a fault (repeat for more), so that `rt-client doctor` can be
    /// shown to name it: `wrong-pixel` (one pixel of every frame wrong,
    /// where the self-test does not look), `refuse-udp` (RTSP answers
    /// SETUP for UDP with 461), `old-version` (/status claims 0.0.1).
    #[arg(long, value_enum)]
    fault: Vec<Fault>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let (render, device) = (args.mode, args.accelerator);
    let faults = Faults::of(&args.fault);
    let mut sim = match HpsSim::start_config(args.listen, Config { render, device, faults }, true) {
        Ok(sim) => sim,
        Err(e) if e.kind() == std::io::ErrorKind::Unsupported => {
            eprintln!("hps-sim: --accelerator rtl: {e}");
            return ExitCode::FAILURE;
        }
        Err(e) => {
            eprintln!("hps-sim: cannot listen on {} and the next port: {e}", args.listen);
            return ExitCode::FAILURE;
        }
    };
    let options = Options { udp: !faults.refuse_udp, ..Options::new(true) };
    let started = match args.services.start(&mut sim, args.listen, options) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("hps-sim: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Some(http) = started.http {
        eprintln!("hps-sim: web page on http://{http}/");
    }
    eprintln!(
        "hps-sim: {render:?} mode, {device:?} accelerator; frames on {} (one per connection), persistent on {}, \
         RTSP on rtsp://{}/light/3,4,-2 (also /orbit, /live)",
        sim.frame_addr(),
        sim.persistent_addr(),
        started.rtsp
    );
    loop {
        std::thread::park();
    }
}
