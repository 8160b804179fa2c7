//! The server: every client from one board (one engine, one ring), frames
//! byte for byte the model's. In-process on the FPGA path (the driver on
//! the mapped-register code, the device model answering through the
//! file), and the program itself on the simulated accelerator.

mod support;

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use hps_linux::preflight::{Finding, Report};
use hps_linux::serve;
use rt_services_std::Server;
use support::{http_get, model_frame, seed_frame, simulated, through_dev_mem, Answered};

const LIGHTS: [[i32; 3]; 4] = [[3072, 4096, -2048], [-5120, 6144, 1024], [1500, 2500, 700], [0, 8192, 0]];

#[test]
fn the_fpga_path_serves_the_models_frames_through_the_mapped_registers() {
    let (bridge, window) = through_dev_mem();
    let port = Answered { port: window.into_port().unwrap(), bridge, sim: simulated() };
    let report = Report {
        fpga: Finding::Good("stand-in".into()),
        bridge: Finding::Good("stand-in".into()),
        window: "stand-in".into(),
        register_map: 3,
        build_id: 0,
    };
    let (board, facts) = serve::fpga(port, &report, Err("no frame memory here".into())).expect("the self-test passes");
    assert_eq!(facts.self_test.result, "pass", "{}", facts.self_test.detail);
    let mut sim = Server::start_board("127.0.0.1:0".parse().unwrap(), board.clone(), facts, false).unwrap();
    let http = sim.start_web("127.0.0.1:0".parse().unwrap(), false).unwrap();
    // Two clients at once, each its own light, from the one ring.
    let addr = sim.frame_addr();
    let clients: Vec<_> =
        LIGHTS[..2].iter().map(|&raw| std::thread::spawn(move || (raw, seed_frame(addr, raw)))).collect();
    for c in clients {
        let (raw, frame) = c.join().unwrap();
        assert!(frame == model_frame(raw), "the frame for {raw:?} is the model's");
    }
    assert_eq!(board.frames_begun(), 2, "both from the board's ring");
    let status = http_get(http, "/status");
    for field in ["\"renderer\":\"fpga\"", "\"mode\":\"rows\"", "\"self_test\":\"pass\""] {
        assert!(status.contains(field), "{field} in {status}");
    }
}

/// The program, killed when dropped.
struct Program(Child);

impl Drop for Program {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Start `hps-linux` with `args`; the seed and web addresses it prints.
fn start(args: &[&str]) -> (Program, SocketAddr, SocketAddr) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_hps-linux"))
        .args(args)
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .expect("hps-linux starts");
    let stderr = child.stderr.take().unwrap();
    let program = Program(child);
    let (mut seed, mut web) = (None, None);
    let mut lines = BufReader::new(stderr).lines();
    for line in lines.by_ref() {
        let line = line.unwrap();
        if let Some(rest) = line.split_once("web page on http://").map(|(_, r)| r) {
            web = rest.trim_end_matches('/').parse().ok();
        }
        if let Some(rest) = line.split_once("; frames on ").map(|(_, r)| r) {
            seed = rest.split(',').next().and_then(|a| a.parse().ok());
            break;
        }
    }
    // Keep reading its log: a closed pipe would end it at its next line.
    std::thread::spawn(move || lines.for_each(drop));
    (program, seed.expect("the seed address"), web.expect("the web address"))
}

#[test]
fn the_program_serves_many_clients_from_one_ring_on_the_simulated_accelerator() {
    let (_program, seed, web) =
        start(&["--accelerator", "sim", "--listen", "127.0.0.1:0", "--rtsp", "127.0.0.1:0", "--http", "127.0.0.1:0"]);
    let clients: Vec<_> = LIGHTS.iter().map(|&raw| std::thread::spawn(move || (raw, seed_frame(seed, raw)))).collect();
    for c in clients {
        let (raw, frame) = c.join().unwrap();
        assert!(frame == model_frame(raw), "the frame for {raw:?} is the model's");
    }
    let status = http_get(web, "/status");
    for field in ["\"renderer\":\"simulated\"", "\"mode\":\"frames\"", "\"frames_rendered\":4"] {
        assert!(status.contains(field), "{field} in {status}");
    }
}

#[test]
fn without_an_accelerator_it_stops_unless_told_to_fall_back_to_software() {
    let dir = tempfile::tempdir().unwrap();
    let sys = dir.path().join("sys");
    std::fs::create_dir_all(&sys).unwrap();
    let stand_in = ["--sysfs", sys.to_str().unwrap(), "--dev", dir.path().to_str().unwrap()];
    let out = Command::new(env!("CARGO_BIN_EXE_hps-linux"))
        .args(["--accelerator", "uio", "--listen", "127.0.0.1:0"])
        .args(stand_in)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no UIO device maps the lightweight bridge") && stderr.contains("--software-fallback"));
    let mut args = vec!["--accelerator", "uio", "--software-fallback", "--listen", "127.0.0.1:0"];
    args.extend(["--rtsp", "127.0.0.1:0", "--http", "127.0.0.1:0"]);
    args.extend(stand_in);
    let (_program, seed, web) = start(&args);
    let raw = LIGHTS[1];
    assert!(seed_frame(seed, raw) == model_frame(raw), "software frames are the model's");
    let status = http_get(web, "/status");
    assert!(status.contains("\"renderer\":\"software\""), "{status}");
}

/// `systemctl stop` sends SIGTERM: the program leaves the hardware quiet
/// and exits with success, promptly.
#[test]
fn sigterm_stops_the_program_cleanly() {
    let (mut program, seed, _) =
        start(&["--accelerator", "sim", "--listen", "127.0.0.1:0", "--rtsp", "127.0.0.1:0", "--http", "127.0.0.1:0"]);
    let raw = LIGHTS[0];
    assert!(seed_frame(seed, raw) == model_frame(raw));
    let pid = libc::pid_t::try_from(program.0.id()).unwrap();
    // SAFETY: a signal to the child this test started and still owns.
    assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(status) = program.0.try_wait().unwrap() {
            break status;
        }
        assert!(std::time::Instant::now() < deadline, "still running 20 s after SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status:?}");
}
