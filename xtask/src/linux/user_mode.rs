//! The ARM executable serving under QEMU's user mode (`qemu-arm`, the
//! host's kernel underneath): with the simulated accelerator, a seed-port
//! frame, FFmpeg's RTSP frames and the page in Chromium, each byte for byte
//! the model's, all from the program's one ring.

use std::fs;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use model::{render_frame, Light};

use crate::support::browser::{check_page, ensure_browser, PageCheck};
use crate::support::player::{Kind, Player, PLAYER_PACKAGES};
use crate::support::process::{free_ports, start_server};
use crate::support::tools::{ensure_apt_packages, root};
use crate::support::Result;

/// The light of every check (world units), and the same as raw Q13.10.
const LIGHT: (f64, f64, f64) = (3.0, 4.0, -2.0);
const RAW: [i32; 3] = [3 << 10, 4 << 10, -(2 << 10)];

/// Frames FFmpeg takes, and the stream's rate.
const FFMPEG_FRAMES: usize = 3;
const FPS: u32 = 2;

/// Run the checks on `exe` (the ARM build).
pub fn serves(exe: &Path) -> Result<()> {
    ensure_checkers()?;
    let dir = root().join("target/linux-test/serve");
    fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let Served { seed: listen, rtsp, http } = Served::free()?;
    let log = dir.join("hps-linux.log");
    println!(
        "==> hps-linux serving under QEMU user mode: seed {listen}, RTSP {rtsp}, page {http} (log {})",
        log.display()
    );
    let started = Instant::now();
    let mut cmd = Command::new("qemu-arm");
    cmd.arg(exe).args(["--accelerator", "sim", "--listen", &listen.to_string(), "--rtsp", &rtsp.to_string()]);
    cmd.args(["--http", &http.to_string()]);
    let mut program = start_server(cmd, "hps-linux under qemu-arm", &log, http)?;
    check_services(Served { seed: listen, rtsp, http }, &dir, started)?;
    if let Ok(Some(status)) = program.0.try_wait() {
        return Err(format!("hps-linux exited during the test ({status}); see {}", log.display()));
    }
    println!("linux-test: served under QEMU user mode ... ok ({:.1} s)", started.elapsed().as_secs_f64());
    Ok(())
}

/// Install what [`check_services`] runs: the players and the browser.
pub fn ensure_checkers() -> Result<()> {
    ensure_apt_packages(&PLAYER_PACKAGES, None)?;
    ensure_browser()
}

/// Where a test reaches the program's three services.
#[derive(Clone, Copy, Debug)]
pub struct Served {
    pub seed: SocketAddr,
    pub rtsp: SocketAddr,
    pub http: SocketAddr,
}

impl Served {
    /// Free loopback ports for the three (the seed port's next one free
    /// too, for the persistent port).
    pub fn free() -> Result<Served> {
        let (seed, rtsp) = free_ports()?;
        let http =
            TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map_err(|e| format!("no free port: {e}"))?;
        Ok(Served { seed, rtsp, http })
    }
}

/// The checks of every way the ARM program runs (QEMU's user mode here,
/// a real kernel in [`super::system`]): a seed-port frame, FFmpeg's RTSP
/// frames and the page in Chromium, each the model's, and `/status`
/// saying what serves; `started` is when the program was started. Output
/// of the players and the browser goes under `dir`.
pub fn check_services(at: Served, dir: &Path, started: Instant) -> Result<()> {
    let Served { seed: listen, rtsp, http } = at;
    let light = Light::from_world(LIGHT.0, LIGHT.1, LIGHT.2).map_err(|e| format!("{e:?}"))?;
    let expected = render_frame(&light);

    let frame = seed_frame(listen)?;
    if frame != expected {
        return Err(format!("the seed port's frame from {listen} is not the model's"));
    }
    println!("linux-test: seed port: the model's frame, {:.1} s after start", started.elapsed().as_secs_f64());

    let url = format!("rtsp://{rtsp}/light/3,4,-2?fps={FPS}");
    let played =
        Player::start(Kind::FfmpegTcp, &url, FFMPEG_FRAMES, &dir.join("ffmpeg"))?.wait(Duration::from_secs(120))?;
    let exact = played.frames.iter().filter(|(_, f)| *f == expected).count();
    if played.frames.len() < FFMPEG_FRAMES || exact != played.frames.len() {
        return Err(format!(
            "FFmpeg got {} frames of {url}, {exact} of them the model's (wanted {FFMPEG_FRAMES}, all exact)",
            played.frames.len()
        ));
    }
    println!("linux-test: FFmpeg over RTSP: {exact} frames, each the model's");

    let check =
        PageCheck { url: format!("http://{http}"), out: dir.join("page"), timeout_s: 120, during: None, play_s: 0 };
    let summary = check_page(&check)?;
    println!("linux-test: the page in Chromium: {summary}");

    let status = http_get(http, "/status")?;
    for field in ["\"renderer\":\"simulated\"", "\"link\":\"Linux\""] {
        if !status.contains(field) {
            return Err(format!("/status lacks {field}: {status}"));
        }
    }
    Ok(())
}

/// One frame over the seed protocol at [`RAW`].
pub fn seed_frame(addr: SocketAddr) -> Result<Vec<u8>> {
    let io = |e: std::io::Error| format!("seed port {addr}: {e}");
    let mut s = TcpStream::connect(addr).map_err(io)?;
    s.set_read_timeout(Some(Duration::from_secs(60))).map_err(io)?;
    let request: Vec<u8> = RAW.iter().flat_map(|v| v.to_be_bytes()).collect();
    s.write_all(&request).map_err(io)?;
    let mut frame = Vec::new();
    s.read_to_end(&mut frame).map_err(io)?;
    Ok(frame)
}

/// `GET path` from `addr`: the whole answer.
fn http_get(addr: SocketAddr, path: &str) -> Result<String> {
    let io = |e: std::io::Error| format!("http://{addr}{path}: {e}");
    let mut s = TcpStream::connect(addr).map_err(io)?;
    s.set_read_timeout(Some(Duration::from_secs(30))).map_err(io)?;
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").map_err(io)?;
    let mut answer = String::new();
    s.read_to_string(&mut answer).map_err(io)?;
    Ok(answer)
}
