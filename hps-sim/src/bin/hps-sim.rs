//! `hps-sim`: the board simulated on the host.
//!
//!     cargo run --release --bin hps-sim -- --listen 127.0.0.1:7878 [--mode rows] [--accelerator rtl] [--rtsp 127.0.0.1:8554]
//!         [--multicast-group 239.255.42.1 [--multicast-port 5006] [--multicast-ttl 1]] [--http 127.0.0.1:8080]
//!
//! Seed protocol on the listen port, persistent protocol on the port + 1,
//! RTSP on `--rtsp` (default: the listen address, port 8554); multicast
//! streams to `--multicast-group` when one is given; the board's web page
//! on `--http` when one is given (open `http://ADDR:PORT/` in a browser).

use std::net::{Ipv4Addr, SocketAddr};
use std::process::ExitCode;

use clap::Parser;
use hps_sim::{rtsp::Options, Config, Device, Fault, Faults, HpsSim, RenderMode};
use rt_services::camera::sender::Multicast;

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
    /// The first multicast group streams set up with
    /// `Transport: RTP/AVP;multicast` go to (without one, such a SETUP is
    /// answered 461): stream `i` of the camera goes to this address plus
    /// `i`, on `--multicast-port`; the server joins each group it sends to
    /// and hears RTCP on the next port.
    #[arg(long)]
    multicast_group: Option<Ipv4Addr>,
    /// The multicast groups' RTP port (RTCP: the next one).
    #[arg(long, default_value_t = 5006)]
    multicast_port: u16,
    /// The multicast packets' time to live (1: they stay on the link).
    #[arg(long, default_value_t = 1)]
    multicast_ttl: u8,
    /// Address of the board's web page (port 80 on the board): the live
    /// picture in a browser, the light under the mouse.
    #[arg(long)]
    http: Option<SocketAddr>,
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
    match HpsSim::start_config(args.listen, Config { render, device, faults }, true) {
        Ok(mut sim) => {
            let rtsp = args.rtsp.unwrap_or(SocketAddr::new(args.listen.ip(), rt_services::camera::rtsp::RTSP_PORT));
            let multicast = args.multicast_group.map(|group| Multicast {
                group,
                base_port: args.multicast_port,
                ttl: args.multicast_ttl,
            });
            if multicast.is_some_and(|m| !m.group.is_multicast()) {
                eprintln!("hps-sim: --multicast-group must be a multicast address (224.0.0.0/4)");
                return ExitCode::FAILURE;
            }
            let rtsp = match sim.start_rtsp_with(rtsp, Options { device, verbose: true, multicast, faults }) {
                Ok(addr) => addr,
                Err(e) => {
                    eprintln!("hps-sim: cannot serve RTSP on {rtsp}: {e}");
                    return ExitCode::FAILURE;
                }
            };
            if let Some(http) = args.http {
                match sim.start_web(http, true) {
                    Ok(addr) => eprintln!("hps-sim: web page on http://{addr}/"),
                    Err(e) => {
                        eprintln!("hps-sim: cannot serve the web page on {http}: {e}");
                        return ExitCode::FAILURE;
                    }
                }
            }
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
