//! `cargo xtask linux-bench`: frames per second of `hps-linux` on the host
//! with the simulated accelerator, beside `hps-sim`'s, for one and for
//! four viewers at once (each a persistent-port client asking for a new
//! light every frame, two requests in flight), every frame checked against
//! the model. A figure, not a test: the host's speed is not the board's.
//!
//! hps-linux serves every client from one ring (the board's way: the seed
//! port's quota of 4 frames among all of them); hps-sim gives each client
//! a simulated accelerator of its own, so its four-viewer figure is what
//! the host's cores allow.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::Command;
use std::time::{Duration, Instant};

use model::{render_frame, Light, FRAME_BYTES};
use rt_services::seed::wire::encode_raw_request;

use crate::support::process::{free_ports, start_server};
use crate::support::tools::{cargo, root, step};
use crate::support::Result;

/// Seconds each measurement runs.
const SECONDS: u64 = 5;

/// Viewer counts measured.
const VIEWERS: [usize; 2] = [1, 4];

/// Run the benchmark and print its table.
pub fn run() -> Result<()> {
    step("build hps-linux and hps-sim (release)", cargo(&["build", "--release", "-p", "hps-linux", "-p", "hps-sim"]))?;
    let dir = root().join("target/linux-bench");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    println!("frames/s on this host, simulated accelerator, {SECONDS} s each, every frame checked:");
    println!("{:<10} {:>8} {:>12}", "server", "viewers", "frames/s");
    for (name, extra) in [("hps-linux", &["--accelerator", "sim"][..]), ("hps-sim", &[][..])] {
        for viewers in VIEWERS {
            let (listen, rtsp) = free_ports()?;
            let mut cmd = Command::new(root().join("target/release").join(name));
            cmd.args(extra).args(["--listen", &listen.to_string(), "--rtsp", &rtsp.to_string()]);
            let persistent = SocketAddr::new(listen.ip(), listen.port() + 1);
            let server = start_server(cmd, name, &dir.join(format!("{name}.log")), persistent)?;
            let fps = measure(persistent, viewers)?;
            drop(server);
            println!("{name:<10} {viewers:>8} {fps:>12.1}");
        }
    }
    Ok(())
}

/// Frames per second `viewers` persistent clients get together.
fn measure(addr: SocketAddr, viewers: usize) -> Result<f64> {
    let start = Instant::now();
    let until = start + Duration::from_secs(SECONDS);
    let threads: Vec<_> = (0..viewers).map(|v| std::thread::spawn(move || viewer(addr, v as i32, until))).collect();
    let mut frames = 0;
    for t in threads {
        frames += t.join().map_err(|_| "a viewer panicked")??;
    }
    Ok(frames as f64 / start.elapsed().as_secs_f64())
}

/// One viewer: two requests in flight, a new light each; the frames it
/// got by `until`, each checked against the model.
fn viewer(addr: SocketAddr, v: i32, until: Instant) -> Result<u64> {
    let io = |e: std::io::Error| format!("viewer {v} on {addr}: {e}");
    let mut s = TcpStream::connect(addr).map_err(io)?;
    s.set_read_timeout(Some(Duration::from_secs(30))).map_err(io)?;
    let light = |n: i32| [1000 + 37 * n + 500 * v, 4096, -2048];
    let mut asked = 0;
    for _ in 0..2 {
        s.write_all(&encode_raw_request(light(asked))).map_err(io)?;
        asked += 1;
    }
    let mut frame = vec![0u8; FRAME_BYTES];
    let mut got = 0;
    while Instant::now() < until {
        s.read_exact(&mut frame).map_err(io)?;
        let [x, y, z] = light(got as i32);
        let want = render_frame(&Light::from_raw(x, y, z).map_err(|e| format!("{e:?}"))?);
        if frame != want {
            return Err(format!("viewer {v}: frame {got} is not the model's"));
        }
        got += 1;
        s.write_all(&encode_raw_request(light(asked))).map_err(io)?;
        asked += 1;
    }
    Ok(got)
}
