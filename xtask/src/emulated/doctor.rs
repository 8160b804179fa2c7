//! `cargo xtask doctor`: `rt-client doctor` against hps-sim and the
//! emulated board, each healthy (every line a tick, exit status 0) and
//! with a fault injected (the doctor must name it and exit 1):
//!
//! | fault | where | the doctor must say |
//! |---|---|---|
//! | the seed port closed | hps-sim, the doctor pointed at a port nothing listens on | `seed port N: ... refused` |
//! | an accelerator rendering a wrong frame | `hps-sim --fault wrong-pixel` | the seed port's frame is not the model's, at row 100, x 200 |
//! | RTSP refusing UDP | `hps-sim --fault refuse-udp` | no frame over RTP/UDP, but over TCP (a firewall) |
//! | a version mismatch | `hps-sim --fault old-version` | the board runs version "0.0.1" |
//! | frame mode failing its self-test | the `frame-port-fault` firmware (the frame DMA's memory never answers) | row mode only, self-test failed, code E4; frames still byte-exact |
//!
//! Loopback only: hps-sim on 127.0.0.1, the emulated board through QEMU's
//! user network (its ports forwarded to 127.0.0.1).

use std::fs;
use std::net::TcpListener;
use std::process::{Command, Stdio};
use std::time::Instant;

use crate::images::firmware::{self, Guest};
use crate::support::process::{free_ports, start_server, Guard};
use crate::support::tools::root;
use crate::support::Result;

/// What one doctor run printed, and whether it passed.
struct Diagnosis {
    passed: bool,
    text: String,
}

impl Diagnosis {
    /// The lines with a cross.
    fn crosses(&self) -> Vec<&str> {
        self.text.lines().filter(|l| l.starts_with('✗')).collect()
    }

    fn ticks(&self) -> usize {
        self.text.lines().filter(|l| l.starts_with('✓')).count()
    }
}

/// Run `rt-client doctor` with `args`.
fn doctor(args: &[String]) -> Result<Diagnosis> {
    let out = Command::new(root().join("target/release/rt-client"))
        .arg("doctor")
        .args(args)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("rt-client doctor: {e}"))?;
    let mut text = String::from_utf8_lossy(&out.stdout).into_owned();
    text.push_str(&String::from_utf8_lossy(&out.stderr));
    Ok(Diagnosis { passed: out.status.success(), text })
}

/// A healthy run: every check ticked, exit status 0.
fn healthy(what: &str, d: &Diagnosis) -> Result<()> {
    if !d.passed || !d.crosses().is_empty() {
        return Err(format!("doctor against {what}: expected every check to pass:\n{}", d.text));
    }
    println!("doctor: {what}: {} checks, all ticked", d.ticks());
    Ok(())
}

/// A run with `fault`: exit status 1 and a cross containing every one of
/// `says`.
fn names(what: &str, d: &Diagnosis, says: &[&str]) -> Result<()> {
    let found = d.crosses().into_iter().find(|l| says.iter().all(|s| l.contains(s)));
    match (d.passed, found) {
        (false, Some(line)) => {
            println!("doctor: {what}: named: {line}");
            Ok(())
        }
        _ => Err(format!("doctor against {what}: expected exit status 1 and a cross saying {says:?}:\n{}", d.text)),
    }
}

/// hps-sim with `faults`, its three services on free loopback ports; the
/// doctor's arguments for it.
fn hps_sim(faults: &[&str], tag: &str) -> Result<(Guard, Vec<String>)> {
    let (listen, rtsp) = free_ports()?;
    let http = TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map_err(|e| e.to_string())?;
    let dir = root().join("target/doctor");
    fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let log = dir.join(format!("hps-sim-{tag}.log"));
    let mut cmd = Command::new(root().join("target/release/hps-sim"));
    cmd.args(["--listen", &listen.to_string(), "--rtsp", &rtsp.to_string(), "--http", &http.to_string()]);
    for f in faults {
        cmd.args(["--fault", f]);
    }
    let sim = start_server(cmd, "hps-sim", &log, http)?;
    let args = vec![
        "127.0.0.1".to_string(),
        "--seed-port".into(),
        listen.port().to_string(),
        "--rtsp-port".into(),
        rtsp.port().to_string(),
        "--http-port".into(),
        http.port().to_string(),
    ];
    Ok((sim, args))
}

/// The doctor's arguments for a guest booted with forwarded ports.
fn guest_args(g: &Guest) -> Result<Vec<String>> {
    let f = g.forwards.as_ref().ok_or("the guest has no forwarded ports")?;
    Ok(vec![
        "127.0.0.1".to_string(),
        "--seed-port".into(),
        f.single.to_string(),
        "--rtsp-port".into(),
        f.rtsp.to_string(),
        "--http-port".into(),
        f.web.to_string(),
    ])
}

/// Run the step: hps-sim healthy and with four faults, then the emulated
/// board healthy and with its frame path at fault.
pub fn run() -> Result<()> {
    crate::support::tools::build_host_programs()?;
    let started = Instant::now();

    let (sim, args) = hps_sim(&[], "healthy")?;
    healthy("hps-sim", &doctor(&args)?)?;
    // The seed port closed: a port nothing listens on.
    let closed = TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map_err(|e| e.to_string())?.port();
    let mut shut = args.clone();
    shut[2] = closed.to_string();
    names("hps-sim, its seed port closed", &doctor(&shut)?, &[&format!("seed port {closed}"), "refused"])?;
    drop(sim);

    let (sim, args) = hps_sim(&["wrong-pixel"], "wrong-pixel")?;
    names(
        "hps-sim with an accelerator that renders a wrong pixel",
        &doctor(&args)?,
        &["seed port's frame is not the model's", "row 100, x 200"],
    )?;
    drop(sim);

    let (sim, args) = hps_sim(&["refuse-udp"], "refuse-udp")?;
    let d = doctor(&args)?;
    names("hps-sim refusing RTP over UDP", &d, &["no frame over RTP/UDP", "but over TCP"])?;
    if !d.text.contains("✓ a frame over RTP inside the RTSP connection (TCP) equals the model's") {
        return Err(format!("doctor against hps-sim refusing UDP: no frame over TCP:\n{}", d.text));
    }
    drop(sim);

    let (sim, args) = hps_sim(&["old-version"], "old-version")?;
    names("hps-sim of another version", &doctor(&args)?, &["the board runs version \"0.0.1\""])?;
    drop(sim);

    let elf = firmware::build("qemu-npcm750", &["sim-accelerator"])?;
    let g = Guest::boot(&elf, &[])?;
    let d = doctor(&guest_args(&g)?)?;
    healthy("the emulated board", &d).map_err(|e| format!("{e}\nthe board's UART:\n{}", g.uart()))?;
    drop(g);

    let elf = firmware::build("qemu-npcm750", &["frame-port-fault"])?;
    let g = Guest::boot(&elf, &[])?;
    let d = doctor(&guest_args(&g)?)?;
    let board = "the emulated board whose frame DMA's memory never answers";
    names(board, &d, &["row mode only"]).map_err(|e| format!("{e}\nthe board's UART:\n{}", g.uart()))?;
    names(board, &d, &["the board's fault code: E4"])?;
    for still in ["✓ a frame from the seed port equals the model's", "✓ a frame over RTP/UDP equals the model's"] {
        if !d.text.contains(still) {
            return Err(format!("doctor against {board}: the board must still serve frames ({still:?}):\n{}", d.text));
        }
    }
    println!("doctor: {board}: still serves byte-exact frames (row mode)");
    println!("doctor: done in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}
