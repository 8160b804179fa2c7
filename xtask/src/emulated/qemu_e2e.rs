//! End-to-end tests of the firmware on QEMU's npcm750-evb with `npcm-gmac`:
//! real TCP clients through slirp's host forwarding, frames compared with
//! `model` byte for byte, the UART log checked.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use model::{render_frame, Light, FRAME_BYTES, WIDTH};
use rt_services::{encode_raw_request, FRAME_PORT, PERSISTENT_PORT};

use crate::images::firmware::Guest;
use crate::support::Result;

const IO_TIMEOUT: Duration = Duration::from_secs(120);

/// Lights (raw Q13.10) used by the tests.
pub const LIGHTS: [[i32; 3]; 4] =
    [[3 << 10, 4 << 10, -(2 << 10)], [-(5 << 10), 6 << 10, 1 << 10], [0, 8 << 10, -(7 << 10)], [1500, 2500, 700]];

fn wire(light: [i32; 3]) -> [u8; 12] {
    encode_raw_request(light)
}

/// The model's frame for a raw light.
pub fn expected_frame(light: [i32; 3]) -> Result<Vec<u8>> {
    let l = Light::from_raw(light[0], light[1], light[2]).map_err(|e| format!("test light: {e}"))?;
    Ok(render_frame(&l))
}

pub fn connect(port: u16) -> Result<TcpStream> {
    let s = TcpStream::connect(("127.0.0.1", port)).map_err(|e| format!("connect {port}: {e}"))?;
    s.set_read_timeout(Some(IO_TIMEOUT)).map_err(|e| e.to_string())?;
    s.set_nodelay(true).map_err(|e| e.to_string())?;
    Ok(s)
}

/// Read until EOF (or a reset, which counts as EOF); error on time-out.
fn read_to_eof(s: &mut TcpStream) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut buf = vec![0u8; 65536];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return Ok(out),
            Ok(n) => out.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => return Ok(out),
            Err(e) => return Err(format!("read after {} bytes: {e}", out.len())),
        }
    }
}

fn check_frame(got: &[u8], light: [i32; 3]) -> Result<()> {
    if got.len() != FRAME_BYTES {
        return Err(format!("light {light:?}: {} bytes, expected {FRAME_BYTES}", got.len()));
    }
    let want = expected_frame(light)?;
    if let Some(i) = got.iter().zip(&want).position(|(a, b)| a != b) {
        return Err(format!(
            "light {light:?}: first difference at byte {i} (pixel {}, row {})",
            i / 3 % WIDTH,
            i / 3 / WIDTH
        ));
    }
    Ok(())
}

/// One frame on the seed port: 12 bytes in, 518,400 out, then EOF.
fn single_frame(port: u16, light: [i32; 3]) -> Result<()> {
    let mut s = connect(port)?;
    s.write_all(&wire(light)).map_err(|e| e.to_string())?;
    let got = read_to_eof(&mut s)?;
    check_frame(&got, light)
}

fn t_seed_port_frames(g: &mut Guest) -> Result<()> {
    for light in &LIGHTS[..3] {
        single_frame(g.port_single, *light)?;
    }
    Ok(())
}

fn t_persistent_port_pipelined(g: &mut Guest) -> Result<()> {
    let mut s = connect(g.port_persistent)?;
    let lights = [LIGHTS[1], LIGHTS[3], LIGHTS[0]];
    let mut req = Vec::new();
    for l in lights {
        req.extend_from_slice(&wire(l));
    }
    s.write_all(&req).map_err(|e| e.to_string())?;
    for l in lights {
        let mut frame = vec![0u8; FRAME_BYTES];
        s.read_exact(&mut frame).map_err(|e| format!("persistent frame {l:?}: {e}"))?;
        check_frame(&frame, l)?;
    }
    s.shutdown(std::net::Shutdown::Write).map_err(|e| e.to_string())?;
    let rest = read_to_eof(&mut s)?;
    if !rest.is_empty() {
        return Err(format!("{} unexpected bytes after the last frame", rest.len()));
    }
    Ok(())
}

fn t_out_of_range_then_next_client(g: &mut Guest) -> Result<()> {
    let mut s = connect(g.port_single)?;
    s.write_all(&wire([1 << 23, 0, 0])).map_err(|e| e.to_string())?;
    let got = read_to_eof(&mut s)?;
    if !got.is_empty() {
        return Err(format!("out-of-range light answered with {} bytes", got.len()));
    }
    single_frame(g.port_single, LIGHTS[2])
}

fn t_close_mid_frame_then_next_client(g: &mut Guest) -> Result<()> {
    {
        let mut s = connect(g.port_single)?;
        s.write_all(&wire(LIGHTS[0])).map_err(|e| e.to_string())?;
        let mut part = vec![0u8; 100_000];
        s.read_exact(&mut part).map_err(|e| format!("first 100,000 bytes: {e}"))?;
        // Dropping the socket closes it mid-frame.
    }
    single_frame(g.port_single, LIGHTS[1])
}

/// Clients at once on the seed port in the overload test: more than its 18
/// sockets (firmware/src/net.rs FRAME_PORT_SOCKETS).
const OVERLOAD_CLIENTS: usize = 24;

/// Served byte-exact, or refused with no byte; anything else is an error.
fn served_or_refused(port: u16, light: [i32; 3]) -> Result<bool> {
    let mut s = match TcpStream::connect(("127.0.0.1", port)) {
        Ok(s) => s,
        Err(_) => return Ok(false),
    };
    s.set_read_timeout(Some(IO_TIMEOUT)).map_err(|e| e.to_string())?;
    // A refused connection may already be closed when the request goes.
    let _ = s.write_all(&wire(light));
    let got = read_to_eof(&mut s)?;
    if got.is_empty() {
        return Ok(false);
    }
    check_frame(&got, light)?;
    Ok(true)
}

/// Wait for the board's idle report after its last client (it comes a
/// second after the last session ends) and check that every socket listens
/// again: a burst then meets all 18 seed-port sockets, not some still
/// closing from the test before.
fn wait_until_every_socket_listens(g: &mut Guest) -> Result<()> {
    // No client yet: every socket has listened since boot.
    let Some(from) = g.uart().rfind("client") else { return Ok(()) };
    let idle = g.wait_for_line(from, "net: idle:", Duration::from_secs(15))?;
    // firmware/src/net.rs SOCKETS.
    if !idle.contains("24 of 24 sockets listening") {
        return Err(format!("the board's idle report is {idle:?}: not every socket listens"));
    }
    Ok(())
}

fn t_overload(g: &mut Guest) -> Result<()> {
    wait_until_every_socket_listens(g)?;
    let port = g.port_single;
    let clients: Vec<_> = (0..OVERLOAD_CLIENTS)
        .map(|i| std::thread::spawn(move || served_or_refused(port, LIGHTS[i % LIGHTS.len()])))
        .collect();
    let mut served = 0;
    for (i, c) in clients.into_iter().enumerate() {
        if c.join().map_err(|_| format!("client {i} panicked"))?? {
            served += 1;
        }
    }
    if served < 16 {
        return Err(format!("{served} of {OVERLOAD_CLIENTS} clients served, want at least 16 (the documented depth)"));
    }
    println!(
        "qemu e2e: overload: {served} of {OVERLOAD_CLIENTS} served byte-exact, {} refused with no byte",
        OVERLOAD_CLIENTS - served
    );
    // The very next client is served.
    single_frame(port, LIGHTS[1])
}

fn t_two_clients_at_once(g: &mut Guest) -> Result<()> {
    let (p1, p2) = (g.port_single, g.port_persistent);
    let a = std::thread::spawn(move || single_frame(p1, LIGHTS[3]));
    let b = std::thread::spawn(move || -> Result<()> {
        let mut s = connect(p2)?;
        s.write_all(&wire(LIGHTS[2])).map_err(|e| e.to_string())?;
        let mut frame = vec![0u8; FRAME_BYTES];
        s.read_exact(&mut frame).map_err(|e| format!("second client: {e}"))?;
        check_frame(&frame, LIGHTS[2])
    });
    let c = std::thread::spawn(move || single_frame(p1, LIGHTS[0]));
    for (name, h) in [("frame-port client", a), ("persistent-port client", b), ("second frame-port client", c)] {
        h.join().map_err(|_| format!("{name} panicked"))??;
    }
    Ok(())
}

fn t_uart_log(g: &mut Guest) -> Result<()> {
    // Let the last "done" lines reach the log.
    std::thread::sleep(Duration::from_millis(300));
    let uart = g.uart();
    let listening = format!("listening on TCP {FRAME_PORT} and {PERSISTENT_PORT}");
    for needle in ["link up:", listening.as_str(), "core 1 parked", SELFTEST_SKIPPED] {
        if !uart.contains(needle) {
            return Err(format!("UART log lacks {needle:?}:\n{uart}"));
        }
    }
    // Every light requested above appears in a request line.
    for l in LIGHTS {
        let text = format!("({}, {}, {})", l[0], l[1], l[2]);
        if !uart.lines().any(|line| line.contains("request") && line.contains(&text)) {
            return Err(format!("no request line for {text} in the UART log:\n{uart}"));
        }
    }
    let requests = uart.lines().filter(|l| l.contains("request")).count();
    // 3 seed + 3 pipelined + 1 after the bad one + 2 (mid-frame) + 3 concurrent.
    if requests < 12 {
        return Err(format!("{requests} request lines, expected at least 12:\n{uart}"));
    }
    if !uart.lines().any(|l| l.contains("closing") || l.contains("out of range") || l.contains("range")) {
        return Err(format!("the out-of-range request left no log line:\n{uart}"));
    }
    Ok(())
}

/// Run every test against one booted guest; print a summary line.
pub fn run(elf: &std::path::Path) -> Result<()> {
    let mut g = Guest::boot(elf, &[])?;
    type Test = fn(&mut Guest) -> Result<()>;
    let tests: [(&str, Test); 10] = [
        ("frames on the frame port equal the model", t_seed_port_frames),
        ("pipelined frames on the persistent port equal the model", t_persistent_port_pipelined),
        ("out-of-range request: no frame, next client served", t_out_of_range_then_next_client),
        ("client closing mid-frame: next client served", t_close_mid_frame_then_next_client),
        ("two clients at once both served", t_two_clients_at_once),
        ("24 seed-port clients at once: at least 16 served, the rest refused cleanly, the next served", t_overload),
        ("UART log shows link up and each request", t_uart_log),
        ("RTSP: a fixed light's frames equal the model's, a NACKed row comes back", t_rtsp_fixed_light),
        ("RTSP: an orbit's frames are the model's at their timestamps' lights", t_rtsp_orbit),
        ("RTSP: a live stream follows SET_PARAMETER", t_rtsp_live),
    ];
    // RT_E2E_ONLY=text runs only the tests whose name contains it (while
    // working on one).
    let only = std::env::var("RT_E2E_ONLY").unwrap_or_default();
    let (mut passed, mut failed) = (0, 0);
    for (name, t) in tests.into_iter().filter(|(name, _)| name.contains(only.as_str())) {
        let start = std::time::Instant::now();
        match t(&mut g) {
            Ok(()) => {
                passed += 1;
                println!("qemu e2e: {name} ... ok ({:.1} s)", start.elapsed().as_secs_f64());
            }
            Err(e) => {
                failed += 1;
                println!("qemu e2e: {name} ... FAILED: {e}");
            }
        }
    }
    println!("qemu-e2e: {passed} passed, {failed} failed");
    if failed > 0 {
        println!("--- UART log ---\n{}", g.uart());
        return Err(format!("{failed} QEMU end-to-end test(s) failed"));
    }
    Ok(())
}

/// The network camera's stream at `path`, through the forwarded RTSP and
/// RTCP ports.
fn rtsp_stream(g: &Guest, path: &str) -> Result<crate::support::rtsp_client::RtspSession> {
    let f = g.forwards.ok_or("the guest has no forwarded RTSP port")?;
    let rtcp = std::net::SocketAddr::from(([127, 0, 0, 1], f.rtcp));
    crate::support::rtsp_client::RtspSession::open(
        std::net::SocketAddr::from(([127, 0, 0, 1], f.rtsp)),
        path,
        Some(rtcp),
    )
}

fn t_rtsp_fixed_light(g: &mut Guest) -> Result<()> {
    let mut s = rtsp_stream(g, "/light/3,4,-2?fps=5")?;
    s.frames.drop_once = Some(17);
    let expected = expected_frame([3072, 4096, -2048])?;
    for i in 0..3 {
        let f = s.next_frame(Duration::from_secs(60))?;
        if f.bytes != expected {
            return Err(format!("RTSP frame {i} (timestamp {}) is not the model's", f.timestamp));
        }
    }
    let (repaired, nacks) = (s.frames.repaired_rows, s.nacks);
    s.teardown()?;
    if repaired == 0 {
        return Err("row 17, dropped on purpose, never came back by NACK".into());
    }
    println!("qemu e2e: 3 RTSP frames exact ({repaired} rows repaired after {nacks} NACKs)");
    Ok(())
}

fn t_rtsp_orbit(g: &mut Guest) -> Result<()> {
    let path = "/orbit?radius=3&height=4&period=2&fps=4";
    let spec =
        rt_services::camera::rtsp::StreamSpec::parse(&format!("rtsp://h{path}")).map_err(|e| format!("{e:?}"))?;
    let mut s = rtsp_stream(g, path)?;
    let live = model::Light::from_world(0.0, 4.0, 0.0).map_err(|e| format!("{e:?}"))?;
    for i in 0..2 {
        let f = s.next_frame(Duration::from_secs(60))?;
        let t = Duration::from_micros(u64::from(f.timestamp.wrapping_sub(s.rtptime)) * 100 / 9);
        let light = spec.light_at(t, live);
        if f.bytes != model::render_frame(&light) {
            return Err(format!("orbit frame {i} at media time {t:?} is not the model's for {light:?}"));
        }
    }
    s.teardown()
}

fn t_rtsp_live(g: &mut Guest) -> Result<()> {
    let mut s = rtsp_stream(g, "/live?fps=5")?;
    s.next_frame(Duration::from_secs(60))?;
    s.set_light(-2.0, 3.0, 1.5)?;
    let expected = expected_frame([-2048, 3072, 1536])?;
    // Frames begun before the request still carry the old light.
    for _ in 0..5 {
        if s.next_frame(Duration::from_secs(60))?.bytes == expected {
            return s.teardown();
        }
    }
    Err("no frame with the light SET_PARAMETER gave within 5 frames".into())
}

/// The boot self-test's line without an accelerator.
pub const SELFTEST_SKIPPED: &str = "self-test: skipped (no accelerator)";

/// The start of the boot self-test's line on the simulated accelerator
/// (hal-avalon `selftest::PLAN`).
pub const SELFTEST_PASS: &str = "self-test: PASS: row mode rows 0, 180, 359 at light (3072, 4096, -2048) and (1500, 2500, 700); frame mode 13 rows (0..=359) of a frame at light (-5120, 6144, 1024), each read once ROWS_DONE covered it; 9120 pixels equal the software renderer";

/// What the `selftest-fault` build must log: the self-test's failure at the
/// wrong pixel (firmware/src/selftest.rs `FAULT_PIXEL`, row 270, x 123, a
/// row of the frame half at hal-avalon `selftest::PLAN`'s frame light), with
/// the model's value and the simulated accelerator's (its RGB inverted),
/// and the fallback to software.
pub fn selftest_fault_lines() -> Result<Vec<String>> {
    let (row, x, raw) = (270u16, 123usize, [-5 << 10, 6 << 10, 1 << 10]);
    let light = Light::from_raw(raw[0], raw[1], raw[2]).map_err(|e| format!("self-test light: {e}"))?;
    let mut words = [0u32; WIDTH];
    model::render_row(row, &light, &mut words);
    let expected = words[x];
    Ok(vec![
        format!(
            "self-test: FAIL: frame mode, row {row}, x {x}: expected {expected:#08x}, got {:#08x} (light (-5120, 6144, 1024))",
            expected ^ 0xff_ffff
        ),
        "FPGA: failed its self-test: accelerator not used, software renderer from now on".into(),
    ])
}

/// What the `frame-port-fault` build must log: frame mode fails its
/// self-test (its memory never answers), row mode renders the same row
/// right, so the FPGA renders rows into the ring; the displays stay lit
/// without the scan-out, and the fault code is E4.
pub fn frame_port_fault_lines() -> Vec<String> {
    [
        "self-test: FAIL: frame mode, ",
        "FPGA: frame mode failed, row mode renders the same row right",
        "display: LEDs and 7-segment displays only",
        "status: E4: frame mode failed its self-test",
    ]
    .map(String::from)
    .to_vec()
}

/// The display's once-a-second line (firmware/src/display.rs,
/// rt-services `monitor::Report`): frames shown, refreshes, layout,
/// attract mode, and what is on screen.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DisplayLine {
    /// Frames that took effect since the scan-out was enabled.
    pub shown: u64,
    /// Display refreshes since enabled.
    pub refreshes: u64,
    /// `full` or `letterbox`.
    pub layout: String,
    /// Attract mode on.
    pub attract: bool,
    /// `light (x, y, z) from a client` / `from attract mode`.
    pub on_screen: Option<String>,
}

/// Parse `display: N frames shown, M refreshes, layout L, F fps, attract
/// on|off[, on screen: ...]`; `None` for any other line.
pub fn parse_display_line(line: &str) -> Option<DisplayLine> {
    let rest = line.trim().strip_prefix("display: ")?;
    let (shown, rest) = rest.split_once(" frames shown, ")?;
    let (refreshes, rest) = rest.split_once(" refreshes, layout ")?;
    let (layout, rest) = rest.split_once(", ")?;
    let (_fps, rest) = rest.split_once(" fps, attract ")?;
    let (attract, on_screen) = match rest.split_once(", on screen: ") {
        Some((a, s)) => {
            let s = s.split(", underrun").next().unwrap_or(s);
            (a, Some(s.split(", memory port fault").next().unwrap_or(s).to_string()))
        }
        None => (rest.split(',').next().unwrap_or(rest), None),
    };
    Some(DisplayLine {
        shown: shown.parse().ok()?,
        refreshes: refreshes.parse().ok()?,
        layout: layout.to_string(),
        attract: match attract {
            "on" => true,
            "off" => false,
            _ => return None,
        },
        on_screen,
    })
}

fn display_lines(g: &Guest) -> Vec<DisplayLine> {
    g.uart().lines().filter_map(parse_display_line).collect()
}

/// Wait up to `secs` for a display line `ok` accepts (after the first
/// `skip` lines).
fn wait_for_display(g: &Guest, skip: usize, secs: u64, ok: impl Fn(&DisplayLine) -> bool) -> Result<DisplayLine> {
    let until = std::time::Instant::now() + Duration::from_secs(secs);
    loop {
        if let Some(l) = display_lines(g).into_iter().skip(skip).find(&ok) {
            return Ok(l);
        }
        if std::time::Instant::now() > until {
            return Err(format!("no such display line within {secs} s"));
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The board on its own (map version 3 on the simulated accelerator):
/// attract mode on at boot, frames taking effect on the display while its
/// counter runs at the VGA rate, and a client's frame becoming the one on
/// screen.
fn t_display(g: &mut Guest) -> Result<()> {
    // Printed after the "listening" line `Guest::boot` waits for: it may
    // still be on its way.
    let announce = "display: VGA scan-out and board I/O (register map version 3): attract mode on";
    g.wait_for_log(announce, Duration::from_secs(10)).map_err(|e| format!("UART log lacks {announce:?}: {e}"))?;
    // Attract mode at boot: frames of its own shown, the counter moving.
    let first = wait_for_display(g, 0, 60, |l| l.attract && l.shown >= 1)?;
    let skip = display_lines(g).len();
    let later = wait_for_display(g, skip, 60, |l| l.shown > first.shown && l.refreshes > first.refreshes)?;
    let attract = |l: &DisplayLine| {
        l.on_screen
            .as_deref()
            .is_some_and(|s| s.ends_with("from attract mode") || s.ends_with("attract mode, captioned"))
    };
    if !attract(&later) || first.layout != "full" {
        return Err(format!("attract mode's frames not on screen at boot: {first:?}, then {later:?}"));
    }
    // The board's name and address on the picture for its first 30 s
    // after the address (attract frames take about a second each here).
    wait_for_display(g, 0, 40, |l| l.on_screen.as_deref().is_some_and(|s| s.ends_with("attract mode, captioned")))
        .map_err(|e| format!("no captioned attract frame (name and address) went on screen after boot: {e}"))?;
    let lines = display_lines(g);
    let (a, b) = (&lines[0], &lines[lines.len() - 1]);
    let per_line = (b.refreshes - a.refreshes) as f64 / (lines.len() - 1).max(1) as f64;
    if !(50.0..=70.0).contains(&per_line) {
        return Err(format!("{per_line:.1} refreshes per display line (a second), expected about 59.5"));
    }
    // A client's frame becomes the newest, so the one on screen.
    let light = [1234, 4096, -2000];
    let skip = display_lines(g).len();
    single_frame(g.port_single, light)?;
    let want = format!("light ({}, {}, {}) from a client", light[0], light[1], light[2]);
    let shown = wait_for_display(g, skip, 10, |l| l.on_screen.as_deref() == Some(want.as_str()))
        .map_err(|e| format!("the client's frame did not go on screen: {e}"))?;
    if shown.attract {
        return Err(format!("attract mode still on right after a client's request: {shown:?}"));
    }
    println!(
        "qemu e2e: display: attract mode at boot (captioned with name and address), {} frames shown in {} refreshes ({per_line:.1} a second), a client's frame on screen ... ok",
        later.shown, later.refreshes
    );
    Ok(())
}

/// Another build of the firmware (`renderer` is what its UART log must say
/// renders; `uart` more text it must contain, the self-test's lines):
/// frames on both ports byte-exact, and two clients at once; with
/// `display`, the VGA display's lines too ([`t_display`]).
pub fn variant(elf: &std::path::Path, renderer: &str, uart: &[String], display: bool) -> Result<()> {
    let mut g = Guest::boot(elf, &[])?;
    let start = std::time::Instant::now();
    let result = (|| {
        let line = format!("renderer: {renderer}");
        for needle in std::iter::once(&line).chain(uart) {
            g.wait_for_log(needle, Duration::from_secs(10)).map_err(|e| format!("UART log lacks {needle:?}: {e}"))?;
        }
        if display {
            t_display(&mut g)?;
        }
        t_seed_port_frames(&mut g)?;
        t_persistent_port_pipelined(&mut g)?;
        t_two_clients_at_once(&mut g)
    })();
    match result {
        Ok(()) => {
            println!(
                "qemu e2e: {renderer}: {} UART line(s) as expected, frames byte-exact on both ports ... ok ({:.1} s)",
                uart.len() + 1,
                start.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Err(e) => {
            println!("qemu e2e: {renderer} ... FAILED: {e}\n--- UART log ---\n{}", g.uart());
            Err(format!("the {renderer} build failed its tests"))
        }
    }
}

/// The reentry-test build: it turns the MMU and caches on and re-enters the
/// reset entry, which must clean and turn them off, then boot as usual and
/// serve a frame byte-exact.
pub fn reentry(elf: &std::path::Path) -> Result<()> {
    let g = Guest::boot(elf, &[])?;
    let start = std::time::Instant::now();
    let result = (|| {
        let uart = g.uart();
        for needle in [
            "reentry-test: MMU and caches on; jumping back to the reset entry",
            "(MMU on, D-cache on, I-cache on): cleaned and turned off before start-up",
            "reentry-test: second start-up, continuing",
        ] {
            if !uart.contains(needle) {
                return Err(format!("UART log lacks {needle:?}"));
            }
        }
        single_frame(g.port_single, LIGHTS[0])
    })();
    match result {
        Ok(()) => {
            println!(
                "qemu e2e: entry with MMU and caches on: cleaned, booted, frame byte-exact ... ok ({:.1} s)",
                start.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Err(e) => {
            println!("qemu e2e: entry with MMU and caches on ... FAILED: {e}\n--- UART log ---\n{}", g.uart());
            Err("the re-entry test failed".into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_lines_parse() {
        let l = parse_display_line(
            "display: 24 frames shown, 1259 refreshes, layout full, 1 fps, attract off, on screen: light (1234, 4096, -2000) from a client",
        )
        .unwrap();
        assert_eq!(
            l,
            DisplayLine {
                shown: 24,
                refreshes: 1259,
                layout: "full".into(),
                attract: false,
                on_screen: Some("light (1234, 4096, -2000) from a client".into()),
            }
        );
        let l =
            parse_display_line("display: 0 frames shown, 3 refreshes, layout letterbox, 0 fps, attract on, underrun")
                .unwrap();
        assert_eq!((l.layout.as_str(), l.attract, l.on_screen), ("letterbox", true, None));
        assert_eq!(parse_display_line("display: VGA scan-out and board I/O (register map version 3)"), None);
    }
}
