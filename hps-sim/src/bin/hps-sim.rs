//! `hps-sim`: the board simulated on the host.
//!
//!     cargo run --release --bin hps-sim -- --listen 127.0.0.1:7878
//!
//! Seed protocol on the listen port, persistent protocol on the port + 1.

use std::net::SocketAddr;
use std::process::ExitCode;

use clap::Parser;
use hps_sim::HpsSim;

#[derive(Parser)]
#[command(name = "hps-sim", about = "The ray tracer board simulated on the host")]
struct Args {
    /// Address of the seed-protocol port; the persistent port is the next one.
    #[arg(long, default_value_t = SocketAddr::from(([127, 0, 0, 1], rt_protocol::FRAME_PORT)))]
    listen: SocketAddr,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match HpsSim::start(args.listen) {
        Ok(sim) => {
            eprintln!(
                "hps-sim: frames on {} (one per connection), persistent on {}",
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
