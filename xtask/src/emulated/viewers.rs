//! Many viewers of the emulated board at once (the network camera's
//! sharing and admission, docs/streaming.md "Many viewers"): four real
//! players of one stream (GStreamer over UDP and inside the RTSP
//! connection, FFmpeg inside the RTSP connection, rt-client over UDP with
//! NACK repair), every frame byte-exact and their summed rate at least 90%
//! of one player's alone; a fifth is answered 453 and gets no RTP; once
//! the four have torn down, a new player is served at once. Each player is
//! a host of its own on a virtual LAN (lan.rs).

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::time::{Duration, Instant};

use super::lan::{Lan, BOARD};
use super::qemu_e2e::expected_frame;
use crate::images::firmware::Guest;
use crate::support::player::{Kind, Played, Player};
use crate::support::rtsp_client::RtspSession;
use crate::support::tools::root;
use crate::support::Result;
use model::ROW_BYTES;

/// The stream every viewer plays.
const PATH: &str = "/light/3,4,-2?fps=max";

/// Frames each player takes (the emulated board renders some five a
/// second on its CPU): enough that the four players' sessions overlap
/// though FFmpeg takes some seconds longer than rt-client to start.
const FRAMES: usize = 20;

/// The players, one of each kind the issue names and GStreamer over TCP.
const PLAYERS: [Kind; 4] = [Kind::GstUdp, Kind::FfmpegTcp, Kind::RtClient, Kind::GstTcp];

/// Run the test against the firmware `elf` (a frame-mode build), on a
/// virtual LAN (lan.rs): each player is a host of its own, as in a lab
/// (one address holds at most `SESSIONS_PER_ADDRESS` sessions).
pub fn run(elf: &Path) -> Result<()> {
    let mut lan = Lan::boot(elf, PLAYERS.len() + 2)?;
    let (alone_host, next_host) = (PLAYERS.len(), PLAYERS.len() + 1);
    let rtsp = SocketAddr::from((BOARD, 8554));
    let want = expected_frame([3 << 10, 4 << 10, -(2 << 10)])?;
    let url = format!("rtsp://{rtsp}{PATH}");
    let dir = root().join("target/viewers/emulated");
    let _ = std::fs::remove_dir_all(&dir);

    // One player alone: the rate the others' sum is held against.
    let alone_want = want.clone();
    let alone_fps = lan
        .on_host(alone_host, move || {
            let mut alone = RtspSession::open(rtsp, PATH, None)?;
            let mut times = Vec::new();
            for i in 0..FRAMES {
                let frame = alone.next_frame(Duration::from_secs(60))?;
                if frame.bytes != alone_want {
                    return Err(format!("the lone viewer's frame {i} is not the model's"));
                }
                times.push(Instant::now());
            }
            alone.teardown()?;
            Ok((FRAMES - 1) as f64 / times[FRAMES - 1].duration_since(times[0]).as_secs_f64().max(1e-6))
        })
        .map_err(|e| lan.with_uart(e))?;
    println!("viewers: one viewer alone: {alone_fps:.2} frames/s, {FRAMES} frames byte-exact");

    // Four at once, each from a host of its own.
    let players: Vec<Player> = PLAYERS
        .iter()
        .enumerate()
        .map(|(i, &kind)| Player::start_in(Some(lan.host(i)), kind, &url, FRAMES, &dir.join(format!("{i}"))))
        .collect::<Result<_>>()?;
    // While they play (the board logs four sessions), a fifth is refused:
    // 453, and no RTP.
    let from = lan.guest.uart().len();
    let sessions = format!("({} sessions)", PLAYERS.len());
    if let Err(e) = lan.guest.wait_for_line(from.saturating_sub(4096), &sessions, Duration::from_secs(60)) {
        return Err(lan.with_uart(format!("the four players' sessions: {e}")));
    }
    let fifth = lan.on_host(alone_host, move || fifth_is_refused(rtsp)).map_err(|e| lan.with_uart(e))?;
    let mut played = Vec::new();
    for p in players {
        let p: Played = p.wait(Duration::from_secs(120)).map_err(|e| lan.with_uart(e))?;
        if p.frames.len() != FRAMES {
            return Err(format!("{} got {} frames, not {FRAMES}: {}", p.kind.name(), p.frames.len(), p.log));
        }
        if let Some(k) = p.frames.iter().position(|(_, f)| *f != want) {
            let wrong = p.frames[k].1.chunks(ROW_BYTES).zip(want.chunks(ROW_BYTES)).filter(|(a, b)| a != b).count();
            return Err(lan.with_uart(format!(
                "{}: frame {k} is not the model's ({wrong} rows differ): {}",
                p.kind.name(),
                p.log
            )));
        }
        played.push(p);
    }
    // The rates over the time all four played: from the last one's first
    // frame to the first one's last (a player that hands frames over in
    // bursts, as FFmpeg does, is counted by what it handed over then).
    // rt-client's frames are its PNGs: its own report's rate counts.
    let timed: Vec<&Played> = played.iter().filter(|p| p.kind != Kind::RtClient).collect();
    let t1 = timed.iter().filter_map(|p| p.frames.first().map(|f| f.0)).max().ok_or("no frames")?;
    let t2 = timed.iter().filter_map(|p| p.frames.last().map(|f| f.0)).min().ok_or("no frames")?;
    let window = t2.saturating_duration_since(t1).as_secs_f64();
    let mut summed = 0.0;
    for p in &played {
        let fps = match p.kind {
            Kind::RtClient => p.fps,
            _ if window > 0.5 => p.frames.iter().filter(|f| f.0 > t1 && f.0 <= t2).count() as f64 / window,
            _ => p.fps,
        };
        println!("viewers: {}: {FRAMES} frames byte-exact, {fps:.2} frames/s", p.kind.name());
        summed += fps;
    }
    println!(
        "viewers: four at once: {summed:.2} frames/s summed ({:.0}% of one alone); {fifth}",
        100.0 * summed / alone_fps
    );
    if summed < 0.9 * alone_fps {
        return Err(format!("four viewers summed {summed:.2} frames/s, under 90% of one alone ({alone_fps:.2})"));
    }
    // They tore down: a new viewer is served at once.
    let took = lan
        .on_host(next_host, move || {
            let started = Instant::now();
            let mut next = RtspSession::open(rtsp, PATH, None).map_err(|e| format!("after the four: {e}"))?;
            let frame = next.next_frame(Duration::from_secs(10))?;
            if frame.bytes != want {
                return Err("the viewer after the four got a frame that is not the model's".into());
            }
            next.teardown()?;
            Ok(started.elapsed())
        })
        .map_err(|e| lan.with_uart(e))?;
    println!("viewers: after the four tore down, a new viewer had its first frame in {:.1} s", took.as_secs_f64());
    Ok(())
}

/// A fifth SETUP while four sessions play: 453, and nothing arrives on the
/// ports it offered.
fn fifth_is_refused(rtsp: SocketAddr) -> Result<String> {
    use std::io::{BufRead, BufReader, Write};
    let rtp = UdpSocket::bind("0.0.0.0:0").map_err(|e| e.to_string())?;
    let port = rtp.local_addr().map_err(|e| e.to_string())?.port();
    let mut ctrl = std::net::TcpStream::connect_timeout(&rtsp, Duration::from_secs(10)).map_err(|e| e.to_string())?;
    ctrl.set_read_timeout(Some(Duration::from_secs(10))).map_err(|e| e.to_string())?;
    let setup = format!(
        "SETUP rtsp://{rtsp}{PATH}/trackID=0 RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP;unicast;client_port={port}-{}\r\n\r\n",
        port + 1
    );
    ctrl.write_all(setup.as_bytes()).map_err(|e| e.to_string())?;
    let mut status = String::new();
    BufReader::new(&ctrl).read_line(&mut status).map_err(|e| format!("the fifth SETUP: {e}"))?;
    if !status.starts_with("RTSP/1.0 453") {
        return Err(format!("the fifth viewer's SETUP was answered {:?}, not 453", status.trim_end()));
    }
    rtp.set_read_timeout(Some(Duration::from_secs(2))).map_err(|e| e.to_string())?;
    let mut buf = [0u8; 2048];
    if let Ok(n) = rtp.recv(&mut buf) {
        return Err(format!("the refused fifth viewer got a {n}-byte datagram"));
    }
    Ok("a fifth was answered 453 and got no RTP in 2 s".into())
}

fn with_uart(g: &Guest, e: String) -> String {
    let uart = g.uart();
    let tail: Vec<&str> = uart.lines().rev().take(40).collect();
    format!("{e}\nthe emulated board's UART, last lines:\n{}", tail.into_iter().rev().collect::<Vec<_>>().join("\n"))
}

/// Debian's packages for the relay (tools/rtsp-relay.py): Python's GObject
/// bindings and gst-rtsp-server's.
pub const RELAY_PACKAGES: [&str; 2] = ["python3-gi", "gir1.2-gst-rtsp-server-1.0"];

/// Players through the relay.
const RELAYED: usize = 8;

/// Leading bytes of `frame` that are black, to a whole pixel: what a player
/// that joined a shared stream mid-frame never received (the relay packs
/// rows into packets of its own, so the join may fall inside a row).
fn missing_head_bytes(frame: &[u8]) -> usize {
    let first = frame.iter().position(|&b| b != 0).unwrap_or(frame.len());
    first - first % 3
}

/// Eight GStreamer players through tools/rtsp-relay.py (gst-rtsp-server,
/// shared media) from one session of the emulated board: every frame the
/// model's (a player that joined mid-frame: its first frame from the join
/// on), and the board serves the one session only.
pub fn relay(elf: &Path) -> Result<()> {
    let mut g = Guest::boot(elf, &[])?;
    let f = g.forwards.ok_or("the guest has no forwarded ports")?;
    let source = format!("rtsp://127.0.0.1:{}/light/3,4,-2?fps=3", f.rtsp);
    let port =
        std::net::TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map_err(|e| e.to_string())?.port();
    let dir = root().join("target/viewers/relay");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let log = std::fs::File::create(dir.join("relay.log")).map_err(|e| e.to_string())?;
    // Debian's Python: the GObject bindings are its packages.
    let relay = std::process::Command::new("/usr/bin/python3")
        .arg(root().join("tools/rtsp-relay.py"))
        .arg(&source)
        .args(["--address", "127.0.0.1", "--port", &port.to_string()])
        .stdout(log.try_clone().map_err(|e| e.to_string())?)
        .stderr(log)
        .spawn()
        .map_err(|e| format!("tools/rtsp-relay.py: {e}"))?;
    struct Kill(std::process::Child);
    impl Drop for Kill {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let _relay = Kill(relay);
    let url = format!("rtsp://127.0.0.1:{port}/relay");
    let deadline = Instant::now() + Duration::from_secs(20);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        if Instant::now() > deadline {
            return Err(format!(
                "the relay does not listen: {}",
                std::fs::read_to_string(dir.join("relay.log")).unwrap_or_default()
            ));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let from = g.uart().len();
    let frames = 4;
    let players: Vec<Player> = (0..RELAYED)
        .map(|i| Player::start(Kind::GstUdp, &url, frames, &dir.join(format!("{i}"))))
        .collect::<Result<_>>()?;
    let want = expected_frame([3 << 10, 4 << 10, -(2 << 10)])?;
    let mut joined_late = 0;
    for (i, p) in players.into_iter().enumerate() {
        let played = p.wait(Duration::from_secs(180)).map_err(|e| with_uart(&g, e))?;
        if played.frames.len() != frames {
            return Err(format!("relayed player {i}: {} frames of {frames}", played.frames.len()));
        }
        for (k, (_, f)) in played.frames.iter().enumerate() {
            // The relay's media is shared: a player that joins while a
            // frame is on its way gets that frame's remaining packets, the
            // bytes before them black (rtpvrawdepay's empty frame). Only
            // the first frame may be such a tail, and its bytes from the
            // join on are the model's.
            let from = if k == 0 { missing_head_bytes(f) } else { 0 };
            if let Some(at) = f[from..].iter().zip(&want[from..]).position(|(a, b)| a != b) {
                let at = from + at;
                let path = dir.join(format!("{i}/frame-{k}.rgb"));
                let _ = std::fs::write(&path, f);
                return Err(format!(
                    "relayed player {i}: frame {k} differs from the model's at row {}, byte {} (black before row {}, byte {}; {})",
                    at / ROW_BYTES,
                    at % ROW_BYTES,
                    from / ROW_BYTES,
                    from % ROW_BYTES,
                    path.display()
                ));
            }
            if from > 0 {
                joined_late += 1;
            }
        }
    }
    let uart = g.uart();
    let sessions = uart.get(from..).unwrap_or("").lines().filter(|l| l.contains("(2 sessions)")).count();
    if sessions > 0 {
        return Err("the board served more than one session while the players went through the relay".into());
    }
    g.wait_for_line(from, "(1 sessions)", Duration::from_secs(1)).map_err(|e| format!("the relay's session: {e}"))?;
    println!("viewers: {RELAYED} GStreamer players through tools/rtsp-relay.py (gst-rtsp-server, shared media), {frames} frames each byte-exact ({joined_late} joined mid-frame: that first frame exact from the join on), from one session of the emulated board");
    Ok(())
}
