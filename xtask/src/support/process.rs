//! Child processes of the tests: a guard that kills one on every path,
//! free loopback ports for a server, and waiting until it listens.

use std::fs;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::support::Result;

/// A child process killed (and reaped) when dropped, so no error path leaves
/// one running.
pub struct Guard(pub Child, pub &'static str);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A seed-protocol address whose next port is free too (hps-sim's
/// persistent port) and an RTSP address, all on loopback. Another process
/// may take them before hps-sim binds them: it then fails to start, and
/// [`wait_for_port`] says so.
pub fn free_ports() -> Result<(SocketAddr, SocketAddr)> {
    let bind = |port: u16| TcpListener::bind(("127.0.0.1", port));
    for _ in 0..64 {
        let a = bind(0).map_err(|e| format!("no free TCP port: {e}"))?;
        let listen = a.local_addr().map_err(|e| e.to_string())?;
        let Some(next) = listen.port().checked_add(1) else { continue };
        let Ok(b) = bind(next) else { continue };
        let c = bind(0).map_err(|e| format!("no free TCP port: {e}"))?;
        let rtsp = c.local_addr().map_err(|e| e.to_string())?;
        drop((a, b, c));
        return Ok((listen, rtsp));
    }
    Err("no two consecutive free TCP ports on 127.0.0.1".into())
}

/// Start `cmd`, a server called `name`, its standard error into `log`
/// (input and output to nowhere), and wait until it accepts connections
/// on `addr` ([`wait_for_port`]); killed when the guard drops.
pub fn start_server(mut cmd: Command, name: &'static str, log: &Path, addr: SocketAddr) -> Result<Guard> {
    let log_file = fs::File::create(log).map_err(|e| format!("{}: {e}", log.display()))?;
    let child = cmd.stdin(Stdio::null()).stdout(Stdio::null()).stderr(log_file).spawn();
    let mut server = Guard(child.map_err(|e| format!("{name}: {e}"))?, name);
    wait_for_port(&mut server, addr, log)?;
    Ok(server)
}

/// Wait until hps-sim accepts connections on `addr` (or has exited).
pub fn wait_for_port(sim: &mut Guard, addr: SocketAddr, log: &Path) -> Result<()> {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if let Ok(Some(status)) = sim.0.try_wait() {
            let text = fs::read_to_string(log).unwrap_or_default();
            return Err(format!("{} exited at start ({status}):\n{text}", sim.1));
        }
        if TcpStream::connect_timeout(&addr, Duration::from_millis(200)).is_ok() {
            return Ok(());
        }
        if Instant::now() > deadline {
            return Err(format!("{} does not accept connections on {addr} after 10 s", sim.1));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}
