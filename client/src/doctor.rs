//! `rt-client doctor [HOST]`: every link of the chain from this computer
//! to the board's picture checked in turn, one line each, a tick or a
//! cross and, for a cross, what to do (docs/diagnostics.md).
//!
//! The checks, in order: the name resolves; the seed port, the RTSP port
//! (OPTIONS, DESCRIBE) and the page's port (`/`, `/status`) answer; the
//! board's version is the client's; a frame at a known light from the
//! seed port equals the model's byte for byte; so does one over RTP/UDP,
//! and if none comes that way, one over RTP inside the RTSP connection
//! (then a firewall drops UDP, or the board refuses it); the renderer is
//! the FPGA; the self-test passed; the board's fault code. A check whose
//! prerequisite failed is not run, and says so.

use std::fmt::Write as _;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::Duration;

use model::Light;
#[cfg(test)]
use model::FRAME_BYTES;
use rt_services::camera::rtsp::RTSP_PORT;
use rt_services::web::WEB_PORT;
use rt_services::FRAME_PORT;

use crate::net;
use crate::rtsp;

/// The light of every frame the doctor compares.
pub const LIGHT: (f64, f64, f64) = (3.0, 4.0, -2.0);

/// How long a port may take to accept or answer.
const TIMEOUT: Duration = Duration::from_secs(5);

/// How long RTP over UDP may take to bring a whole frame.
const UDP_WAIT: Duration = Duration::from_secs(4);

/// Where the doctor looks.
#[derive(Clone, Debug)]
pub struct Target {
    /// The host, as given (name or address).
    pub host: String,
    /// The seed port.
    pub seed: u16,
    /// The RTSP port.
    pub rtsp: u16,
    /// The page's port.
    pub http: u16,
}

impl Target {
    /// `host` on the board's own ports.
    pub fn board(host: &str) -> Target {
        Target { host: host.to_string(), seed: FRAME_PORT, rtsp: RTSP_PORT, http: WEB_PORT }
    }
}

/// One check's outcome.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Check {
    /// Passed.
    pub ok: bool,
    /// What was found.
    pub line: String,
    /// For a failure: what to do.
    pub hint: String,
}

impl Check {
    fn pass(line: impl Into<String>) -> Check {
        Check { ok: true, line: line.into(), hint: String::new() }
    }

    fn fail(line: impl Into<String>, hint: impl Into<String>) -> Check {
        Check { ok: false, line: line.into(), hint: hint.into() }
    }
}

impl std::fmt::Display for Check {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.ok {
            write!(f, "✓ {}", self.line)
        } else {
            write!(f, "✗ {}\n    → {}", self.line, self.hint)
        }
    }
}

/// What `/status` said, as far as the doctor reads it.
#[derive(Clone, Debug, Default)]
struct Status {
    version: String,
    renderer: String,
    self_test: String,
    self_test_detail: String,
    mode: String,
    code: String,
}

/// The board's `/status` on the page at `addr` (`Host: host`), parsed.
pub fn get_status(addr: SocketAddr, host: &str) -> Result<serde_json::Value, String> {
    let (code, body) = http_get(addr, host, "/status").map_err(|e| e.to_string())?;
    if code != 200 {
        return Err(format!("answered {code}"));
    }
    serde_json::from_str(&body).map_err(|e| format!("not JSON: {e}"))
}

impl Status {
    fn parse(body: &str) -> Option<Status> {
        let v: serde_json::Value = serde_json::from_str(body).ok()?;
        Status::of(&v)
    }

    fn of(v: &serde_json::Value) -> Option<Status> {
        v.as_object()?;
        let text = |k: &str| v.get(k).and_then(|x| x.as_str()).unwrap_or_default().to_string();
        Some(Status {
            version: text("version"),
            renderer: text("renderer"),
            self_test: text("self_test"),
            self_test_detail: text("self_test_detail"),
            mode: text("mode"),
            code: text("code"),
        })
    }
}

/// Run every check on `target`, printing each line as it is known;
/// returns them all.
pub fn run(target: &Target, mut print: impl FnMut(&Check)) -> Vec<Check> {
    let mut checks = Vec::new();
    let mut note = |c: Check, checks: &mut Vec<Check>| {
        print(&c);
        checks.push(c);
    };
    let addrs: Vec<SocketAddr> = match (target.host.as_str(), 0).to_socket_addrs() {
        Ok(a) => a.filter(|a| a.is_ipv4()).collect(),
        Err(e) => {
            let hint = "check the name (`rt-client discover` lists the boards on this network), or give the address \
                        the board's UART or 7-segment displays show";
            note(Check::fail(format!("{} does not resolve: {e}", target.host), hint), &mut checks);
            return checks;
        }
    };
    let Some(ip) = addrs.first().map(SocketAddr::ip) else {
        note(Check::fail(format!("{} has no IPv4 address", target.host), "give the board's IPv4 address"), &mut checks);
        return checks;
    };
    note(Check::pass(format!("{} is {ip}", target.host)), &mut checks);

    // The ports.
    let seed = SocketAddr::new(ip, target.seed);
    let seed_open = port_check(seed, "seed port", &mut checks, &mut note);
    let rtsp_addr = SocketAddr::new(ip, target.rtsp);
    let url = rtsp::stream_url(rtsp_addr, "/light/3,4,-2?fps=10");
    let rtsp_ok = match rtsp_check(rtsp_addr, &url) {
        Ok(c) => {
            note(c, &mut checks);
            true
        }
        Err(c) => {
            note(c, &mut checks);
            false
        }
    };
    let http = SocketAddr::new(ip, target.http);
    let host_header =
        if target.http == WEB_PORT { target.host.clone() } else { format!("{}:{}", target.host, target.http) };
    let status = match page_check(http, &host_header) {
        Ok((c, status)) => {
            note(c, &mut checks);
            Some(status)
        }
        Err(c) => {
            note(c, &mut checks);
            None
        }
    };
    if checks.iter().skip(1).all(|c| !c.ok) {
        note(
            Check::fail(
                format!("{ip} answers on none of the board's ports"),
                "is the board powered and booted (UART: `net: address`)? on the same network? does ping reach it?",
            ),
            &mut checks,
        );
        return checks;
    }

    // Versions.
    if let Some(s) = &status {
        let ours = env!("CARGO_PKG_VERSION");
        note(
            if s.version == ours {
                Check::pass(format!("the board runs version {ours}, as this client"))
            } else {
                Check::fail(
                    format!("the board runs version {:?}, this client is {ours}", s.version),
                    "build the card and the client from one checkout (`cargo xtask sdcard`), or use the client of \
                     the board's version",
                )
            },
            &mut checks,
        );
    }

    // Frames against the model.
    let light = match Light::from_world(LIGHT.0, LIGHT.1, LIGHT.2) {
        Ok(l) => l,
        Err(e) => {
            note(Check::fail(format!("the doctor's light is invalid: {e:?}"), "report this as a bug"), &mut checks);
            return checks;
        }
    };
    let model = model_frame(&light);
    if seed_open {
        note(seed_frame_check(seed, &light, &model), &mut checks);
    }
    if rtsp_ok {
        for c in rtp_checks(rtsp_addr, &url, &model) {
            note(c, &mut checks);
        }
    }

    // What the board says of itself.
    if let Some(s) = &status {
        for c in status_checks(s) {
            note(c, &mut checks);
        }
    }
    checks
}

/// Whether `addr` accepts a connection; notes the check.
fn port_check(
    addr: SocketAddr,
    what: &str,
    checks: &mut Vec<Check>,
    note: &mut impl FnMut(Check, &mut Vec<Check>),
) -> bool {
    match TcpStream::connect_timeout(&addr, TIMEOUT) {
        Ok(_) => {
            note(Check::pass(format!("{what} {} accepts connections", addr.port())), checks);
            true
        }
        Err(e) => {
            note(Check::fail(format!("{what} {}: {e}", addr.port()), connect_hint(&e)), checks);
            false
        }
    }
}

fn connect_hint(e: &std::io::Error) -> &'static str {
    match e.kind() {
        std::io::ErrorKind::ConnectionRefused => {
            "the board answers but nothing listens there: is it the board (or hps-sim)? the UART log says which \
             services started"
        }
        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock => {
            "no answer: a firewall, another network, or the board is not up (UART: `net: address`)"
        }
        _ => "check the address and the network between here and the board",
    }
}

/// OPTIONS and DESCRIBE of `url` on the camera at `addr`.
fn rtsp_check(addr: SocketAddr, url: &str) -> Result<Check, Check> {
    let hint = "the camera does not answer RTSP: see the UART's `camera:` lines";
    let mut c =
        rtsp::RtspClient::connect(addr).map_err(|e| Check::fail(format!("RTSP port {}: {e}", addr.port()), hint))?;
    c.options(url).map_err(|e| Check::fail(format!("RTSP OPTIONS: {e}"), hint))?;
    let sdp = c.describe(url).map_err(|e| Check::fail(format!("RTSP DESCRIBE: {e}"), hint))?;
    if !sdp.contains("raw/90000") && !sdp.contains("RAW/90000") {
        return Err(Check::fail("RTSP DESCRIBE's SDP names no raw video stream", hint));
    }
    Ok(Check::pass(format!("RTSP port {} answers OPTIONS and DESCRIBE (raw RGB video)", addr.port())))
}

/// `/` and `/status` on the page's port.
fn page_check(addr: SocketAddr, host: &str) -> Result<(Check, Status), Check> {
    let hint = "the page does not answer: see the UART's `web:` lines";
    let (code, _) =
        http_get(addr, host, "/").map_err(|e| Check::fail(format!("page port {}: {e}", addr.port()), hint))?;
    if code != 200 {
        return Err(Check::fail(format!("GET / answered {code}"), hint));
    }
    let (code, body) = http_get(addr, host, "/status").map_err(|e| Check::fail(format!("GET /status: {e}"), hint))?;
    let status = (code == 200).then(|| Status::parse(&body)).flatten().ok_or_else(|| {
        Check::fail(format!("GET /status answered {code} without the board's status"), "is it the board's page?")
    })?;
    Ok((Check::pass(format!("page port {} serves the page and /status", addr.port())), status))
}

/// A GET of `path` with `Host: host`: the status code and the body.
fn http_get(addr: SocketAddr, host: &str, path: &str) -> std::io::Result<(u16, String)> {
    let mut s = TcpStream::connect_timeout(&addr, TIMEOUT)?;
    s.set_read_timeout(Some(TIMEOUT))?;
    s.set_write_timeout(Some(TIMEOUT))?;
    write!(s, "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\nUser-Agent: rt-client doctor\r\n\r\n")?;
    let mut raw = Vec::new();
    // The board closes after one answer (a page is well under a
    // megabyte); a server that keeps the connection open leaves its whole
    // answer read when the timeout ends the read.
    if let Err(e) = s.take(4 << 20).read_to_end(&mut raw) {
        if raw.is_empty() {
            return Err(e);
        }
    }
    let text = String::from_utf8_lossy(&raw);
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let code = head.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    Ok((code, body.to_string()))
}

/// The model's frame at `light`.
pub fn model_frame(light: &Light) -> Vec<u8> {
    model::render_frame(light)
}

/// Where `got` first differs from `want`, in words.
pub fn first_difference(got: &[u8], want: &[u8]) -> String {
    if got.len() != want.len() {
        return format!("{} bytes, a frame has {}", got.len(), want.len());
    }
    let Some(i) = got.iter().zip(want).position(|(a, b)| a != b) else { return "equal".into() };
    let pixel = i / 3;
    let (row, x) = (pixel / model::WIDTH, pixel % model::WIDTH);
    let differing = got.chunks(3).zip(want.chunks(3)).filter(|(a, b)| a != b).count();
    let mut s = String::new();
    let _ = write!(
        s,
        "{differing} pixel(s) differ, the first at row {row}, x {x}: expected {:02x}{:02x}{:02x}, got {:02x}{:02x}{:02x}",
        want[pixel * 3],
        want[pixel * 3 + 1],
        want[pixel * 3 + 2],
        got[pixel * 3],
        got[pixel * 3 + 1],
        got[pixel * 3 + 2]
    );
    s
}

fn seed_frame_check(addr: SocketAddr, light: &Light, model: &[u8]) -> Check {
    match net::fetch_frame(addr, light) {
        Ok(frame) if frame == model => {
            Check::pass(format!("a frame from the seed port equals the model's, byte for byte (light {LIGHT:?})"))
        }
        Ok(frame) => Check::fail(
            format!("the seed port's frame is not the model's: {}", first_difference(&frame, model)),
            "the accelerator renders wrong pixels: rebuild and load the FPGA image from this checkout; if the \
             self-test passed, report the pixel",
        ),
        Err(e) => Check::fail(format!("no frame from the seed port: {e}"), "see the UART log for the frame server"),
    }
}

/// A frame over RTP/UDP; if none comes, over RTP inside the RTSP
/// connection.
fn rtp_checks(addr: SocketAddr, url: &str, model: &[u8]) -> Vec<Check> {
    let compare = |frame: &[u8], how: &str| {
        if frame == model {
            Check::pass(format!("a frame over {how} equals the model's, byte for byte"))
        } else {
            Check::fail(
                format!("the frame over {how} is not the model's: {}", first_difference(frame, model)),
                "the accelerator renders wrong pixels (see the seed port's check)",
            )
        }
    };
    match rtsp::fetch_udp_frame(addr, url, UDP_WAIT) {
        Ok(frame) => vec![compare(&frame, "RTP/UDP")],
        Err(udp) => {
            let tcp = match rtsp::fetch_interleaved_frame(addr, url, UDP_WAIT) {
                Ok(frame) => compare(&frame, "RTP inside the RTSP connection (TCP)"),
                Err(e) => Check::fail(
                    format!("no frame over RTP inside the RTSP connection either: {e}"),
                    "see the UART's `camera:` lines",
                ),
            };
            let udp_check = if tcp.ok {
                Check::fail(
                    format!("no frame over RTP/UDP ({udp}), but over TCP"),
                    "a firewall between here and the board drops UDP, or the server refuses it: allow UDP from the \
                     board, or play over TCP (FFmpeg: -rtsp_transport tcp; GStreamer: protocols=tcp)",
                )
            } else {
                Check::fail(format!("no frame over RTP/UDP: {udp}"), "see the UART's `camera:` lines")
            };
            vec![udp_check, tcp]
        }
    }
}

/// The renderer, the self-test and the fault code, from `/status`.
fn status_checks(s: &Status) -> Vec<Check> {
    let mut out = Vec::new();
    out.push(match (s.renderer.as_str(), s.mode.as_str()) {
        ("fpga", "frames") => Check::pass("the FPGA renders (frame mode)"),
        ("fpga", _) if s.code != "E4" && s.self_test == "pass" => {
            Check::pass("the FPGA renders (row mode: a row-mode build, or register map version 1)")
        }
        ("fpga", _) => Check::fail(
            "the FPGA renders in row mode only: its frame DMA failed the self-test",
            "release the FPGA-to-SDRAM port (fpgaportrst, docs/flash-and-boot.md); docs/diagnostics.md, code E4",
        ),
        ("simulated", _) => Check::pass("the renderer is hps-sim's simulated accelerator (not a board)"),
        (r, _) => Check::fail(
            format!("the renderer is {r:?}, not the FPGA"),
            "load the FPGA image (boot.cmd's `fpga load`, MSEL switches) and see the self-test below",
        ),
    });
    out.push(match s.self_test.as_str() {
        "pass" => Check::pass("the boot self-test passed"),
        "" => Check::fail("/status names no self-test", "update the board's firmware"),
        other => Check::fail(format!("the boot self-test: {other}: {}", s.self_test_detail), "docs/diagnostics.md"),
    });
    out.push(match s.code.as_str() {
        "ok" => Check::pass("the board's fault code: ok"),
        "" => Check::fail("/status names no fault code", "update the board's firmware"),
        code => Check::fail(format!("the board's fault code: {code}"), "docs/diagnostics.md lists what it means"),
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_difference_names_its_first_pixel_and_how_many() {
        let want = vec![0u8; FRAME_BYTES];
        let mut got = want.clone();
        got[(100 * model::WIDTH + 200) * 3] = 0xff;
        assert_eq!(
            first_difference(&got, &want),
            "1 pixel(s) differ, the first at row 100, x 200: expected 000000, got ff0000"
        );
        assert_eq!(first_difference(&want, &want), "equal");
        assert_eq!(first_difference(&want[..3], &want), "3 bytes, a frame has 518400");
    }

    #[test]
    fn status_lines_name_what_is_wrong() {
        let board = Status {
            version: "0.1.0".into(),
            renderer: "fpga".into(),
            self_test: "pass".into(),
            mode: "frames".into(),
            code: "ok".into(),
            ..Status::default()
        };
        assert!(status_checks(&board).iter().all(|c| c.ok));
        let healthy_rows = Status { mode: "rows".into(), ..board.clone() };
        assert!(status_checks(&healthy_rows)[0].ok, "a row-mode build that passed is healthy");
        let rows = Status { mode: "rows".into(), self_test: "fail".into(), code: "E4".into(), ..board.clone() };
        let lines: Vec<Check> = status_checks(&rows);
        assert!(lines.iter().all(|c| !c.ok), "{lines:?}");
        assert!(lines[0].line.contains("row mode") && lines[0].hint.contains("fpgaportrst"));
        assert!(lines[2].line.contains("E4"));
        let software = Status { renderer: "software".into(), ..board };
        assert!(!status_checks(&software)[0].ok);
    }

    #[test]
    fn the_status_is_read_from_the_boards_json() {
        let s = Status::parse(
            r#"{"uptime_s":1,"renderer":"fpga","version":"0.1.0","self_test":"pass","self_test_detail":"self-test: PASS","mode":"frames","code":"ok"}"#,
        )
        .expect("parses");
        assert_eq!((s.version.as_str(), s.mode.as_str(), s.code.as_str()), ("0.1.0", "frames", "ok"));
        assert!(Status::parse("not json").is_none());
    }

    #[test]
    fn a_name_that_does_not_resolve_is_one_cross() {
        let checks = run(&Target::board("no-such-board.invalid"), |_| {});
        assert_eq!(checks.len(), 1);
        assert!(!checks[0].ok && checks[0].hint.contains("discover"), "{checks:?}");
    }
}
