//! `cargo xtask bench-fw`: the firmware's cost per frame, measured on QEMU
//! with `-icount shift=0` (one guest nanosecond per instruction, so the
//! figures are instruction counts; they move by a few in a million from
//! run to run, with when the host's ACKs arrive), and the board cost model
//! ([`crate::emulated::cost_model`]) applied to the counts.
//!
//! Three builds of the `bench` firmware serve pipelined frames on the
//! persistent port:
//!
//! * frame mode, the simulated accelerator's frame DMA filling the ring:
//!   the board's frame path;
//! * row mode, the simulated accelerator rendering a row per start: the
//!   board's row path;
//! * frame mode with the software renderer: the renderer's cost.
//!
//! The firmware logs per frame what it did (see firmware/src/bench.rs):
//! busy guest time (main-loop iterations that moved anything; the rest is
//! waiting for the emulated peer's ACKs), rendering time (the simulated
//! accelerator runs on the guest CPU, which the board's FPGA does not), and
//! counts of bus accesses, copies, cache maintenance and MAC bytes.
//! Streaming cost = busy time minus rendering time.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use clap::Args;

use super::cost_model::{self, FrameCounts, CONSTANTS};
use crate::images::firmware::{build, Guest};
use crate::support::Result;

/// `cargo xtask bench-fw` options.
#[derive(Args)]
pub struct BenchArgs {
    /// Frames to request per mode (the first and the last are not counted).
    /// Twelve: the one-viewer RTP figure moved by some 3% between runs of
    /// four counted frames (with when the host's ACKs and reports fall),
    /// by 1% with ten.
    #[arg(long, default_value_t = 12)]
    pub frames: usize,
    /// Measure the RTP path only.
    #[arg(long)]
    pub rtp_only: bool,
    /// Measure the web page's WebSocket path only.
    #[arg(long)]
    pub web_only: bool,
}

/// One `bench: counts` line (`u64`), or a mean of them per frame (`f64`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counts<T = u64> {
    lw_reads: T,
    lw_line_words: T,
    lw_writes: T,
    cpu_copied: T,
    lines_invalidated: T,
    lines_cleaned: T,
    uncached_read: T,
    mac_tx: T,
    mac_tx_zero_copy: T,
    tx_frames: T,
    busy_ns: T,
    render_ns: T,
    busy_loops: T,
}

impl<T> Counts<T> {
    fn fields_mut(&mut self) -> [&mut T; 13] {
        [
            &mut self.lw_reads,
            &mut self.lw_line_words,
            &mut self.lw_writes,
            &mut self.cpu_copied,
            &mut self.lines_invalidated,
            &mut self.lines_cleaned,
            &mut self.uncached_read,
            &mut self.mac_tx,
            &mut self.mac_tx_zero_copy,
            &mut self.tx_frames,
            &mut self.busy_ns,
            &mut self.render_ns,
            &mut self.busy_loops,
        ]
    }
}

impl Counts {
    const FIELDS: [&'static str; 13] = [
        "lw_reads",
        "lw_line_words",
        "lw_writes",
        "cpu_copied",
        "lines_invalidated",
        "lines_cleaned",
        "uncached_read",
        "mac_tx",
        "mac_tx_zero_copy",
        "tx_frames",
        "busy_ns",
        "render_ns",
        "busy_loops",
    ];

    /// Parse the text after `bench: counts`: every field, `name=value`.
    pub fn parse(line: &str) -> Option<Counts> {
        let mut c = Counts::default();
        let mut seen = 0;
        for pair in line.split_whitespace() {
            let (k, v) = pair.split_once('=')?;
            let i = Self::FIELDS.iter().position(|f| *f == k)?;
            *c.fields_mut()[i] = v.parse().ok()?;
            seen |= 1 << i;
        }
        (seen == (1 << Self::FIELDS.len()) - 1).then_some(c)
    }

    /// The mean of `lines`, per frame.
    fn mean(lines: &[Counts]) -> Counts<f64> {
        let mut mean = Counts::<f64>::default();
        for l in lines {
            let mut l = *l;
            for (m, v) in mean.fields_mut().into_iter().zip(l.fields_mut()) {
                *m += *v as f64;
            }
        }
        for m in mean.fields_mut() {
            *m /= lines.len() as f64;
        }
        mean
    }
}

/// What one mode measured, per frame.
struct Measured {
    counts: Counts<f64>,
    frames: usize,
}

impl Measured {
    fn streaming(&self) -> f64 {
        (self.counts.busy_ns - self.counts.render_ns).max(0.0)
    }

    fn model_counts(&self) -> FrameCounts {
        FrameCounts {
            instructions: self.streaming(),
            lw_reads: self.counts.lw_reads,
            lw_line_words: self.counts.lw_line_words,
            lw_writes: self.counts.lw_writes,
            lines_invalidated: self.counts.lines_invalidated,
            lines_cleaned: self.counts.lines_cleaned,
            uncached_read: self.counts.uncached_read,
            mac_tx: self.counts.mac_tx,
            mac_tx_zero_copy: self.counts.mac_tx_zero_copy,
            tx_frames: self.counts.tx_frames,
        }
    }
}

/// Boot a bench build with `features`, fetch `frames` pipelined frames,
/// and average the counts of all but the first and the last.
fn measure(features: &[&str], frames: usize) -> Result<Measured> {
    let mut all = vec!["bench"];
    all.extend_from_slice(features);
    let elf = build("qemu-npcm750", &all)?;
    let mut g = Guest::boot(&elf, &["-icount", "shift=0"])?;
    let mut s = TcpStream::connect(("127.0.0.1", g.port_persistent)).map_err(|e| e.to_string())?;
    s.set_read_timeout(Some(Duration::from_secs(600))).map_err(|e| e.to_string())?;
    let light = super::qemu_e2e::LIGHTS[0];
    s.write_all(&rt_services::encode_raw_request(light).repeat(frames)).map_err(|e| e.to_string())?;
    let mut frame = vec![0u8; model::FRAME_BYTES];
    let want = super::qemu_e2e::expected_frame(light)?;
    for i in 0..frames {
        s.read_exact(&mut frame).map_err(|e| format!("frame {i}: {e}"))?;
        if frame != want {
            return Err(format!("{features:?}: frame {i} differs from model::render_frame"));
        }
    }
    drop(s);
    g.wait_for_log("bench: counts", Duration::from_secs(5))?;
    let uart = g.uart();
    let lines: Vec<Counts> =
        uart.lines().filter_map(|l| l.trim().strip_prefix("bench: counts")).filter_map(Counts::parse).collect();
    if lines.len() < frames - 1 {
        return Err(format!("{features:?}: expected {} counts lines, got {}:\n{uart}", frames - 1, lines.len()));
    }
    let counted = &lines[1..frames - 1];
    Ok(Measured { counts: Counts::mean(counted), frames: counted.len() })
}

/// The frame-mode bench build serving one browser: the page's WebSocket
/// channel asking for a frame when the last one is in, as the page does;
/// `frames` frames checked against the model; the counts of the frames
/// sent, less the first and the last, per frame.
fn measure_web(frames: usize) -> Result<Measured> {
    let elf = build("qemu-npcm750", &["bench", "sim-accelerator"])?;
    let mut g = Guest::boot(&elf, &["-icount", "shift=0"])?;
    g.wait_for_log("web: page on TCP 80", Duration::from_secs(120))?;
    let f = g.forwards.ok_or("the guest has no forwarded web port")?;
    let from = g.uart().len();
    let s = TcpStream::connect(("127.0.0.1", f.web)).map_err(|e| e.to_string())?;
    let mut s = match super::web::handshake(s)? {
        Ok(s) => s,
        Err(code) => return Err(format!("WebSocket handshake answered {code}")),
    };
    s.set_read_timeout(Some(Duration::from_secs(600))).map_err(|e| e.to_string())?;
    let light = super::qemu_e2e::LIGHTS[0];
    let want = super::qemu_e2e::expected_frame(light)?;
    for i in 0..frames {
        if super::web::ws_frame(&mut s, light)? != want {
            return Err(format!("WebSocket: frame {i} differs from model::render_frame"));
        }
    }
    drop(s);
    g.wait_for_line(from, "client left", Duration::from_secs(30))?;
    let uart = g.uart();
    // Lines of frames rendered and sent (the display's attract mode renders
    // frames that go nowhere).
    let sent: Vec<Counts> = uart
        .get(from..)
        .unwrap_or("")
        .lines()
        .filter_map(|l| l.trim().strip_prefix("bench: counts"))
        .filter_map(Counts::parse)
        .filter(|c| c.mac_tx > model::FRAME_BYTES as u64 / 2)
        .collect();
    if sent.len() < frames - 1 {
        return Err(format!(
            "WebSocket: expected {} counts lines of frames sent, got {}:\n{uart}",
            frames - 1,
            sent.len()
        ));
    }
    let counted = &sent[1..frames - 1];
    let web: Vec<&str> = uart.lines().filter(|l| l.contains("bench: web")).collect();
    if let Some(l) = web.get(web.len() / 2) {
        println!("{}", l.trim());
    }
    Ok(Measured { counts: Counts::mean(counted), frames: counted.len() })
}

/// The web page's case: figures, estimate, one line with both
/// (`bench-fw --web-only`; the suite prints them after the browser test).
pub fn web_case(frames: usize) -> Result<()> {
    let name = "WebSocket (one browser, frame mode, rows copied into the socket)";
    let m = measure_web(frames)?;
    print_mode(name, &m);
    let p = print_estimate(name, &m, cost_model::FPGA_FRAME_CYCLES.value);
    println!(
        "bench-fw: {name}: {:.0} instructions per frame; board estimate {p:.0} frames/s for one browser",
        m.streaming()
    );
    Ok(())
}

/// How the RTP bench's viewers watch one stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Viewers {
    /// `n` unicast UDP viewers of the stream (one of them checks frames).
    Unicast(usize),
    /// `n` receivers of the stream's multicast group, in a network
    /// namespace of the bench's own.
    Multicast(usize),
    /// One viewer with RTP inside its RTSP connection (smoltcp TCP).
    Interleaved,
}

impl Viewers {
    fn name(self) -> String {
        match self {
            Viewers::Unicast(1) => "RTP (frame mode, rows zero-copy through two-buffer descriptors)".into(),
            Viewers::Unicast(n) => format!("RTP, {n} unicast viewers of one stream (one frame rendered, {n} copies)"),
            Viewers::Multicast(n) => format!("RTP, {n} multicast sessions of one stream (one copy to the group)"),
            Viewers::Interleaved => "RTP inside the RTSP connection (interleaved, smoltcp TCP)".into(),
        }
    }

    /// Row packets one rendered frame makes.
    fn copies(self) -> usize {
        match self {
            Viewers::Unicast(n) => n,
            _ => 1,
        }
    }
}

/// The frame-mode bench build over RTSP/RTP: a fixed-light stream at
/// `fps=max` watched as `viewers` say, `frames` frames checked against the
/// model (where a viewer here receives); the counts of all but the first
/// and the last frame the firmware rendered meanwhile, per frame rendered.
fn measure_rtp(frames: usize, viewers: Viewers) -> Result<Measured> {
    use crate::support::rtsp_client::{RtspSession, Transport};
    match viewers {
        Viewers::Multicast(n) => return measure_multicast(frames, n),
        Viewers::Unicast(n) if n > 1 => return measure_unicast_hosts(frames, n),
        _ => {}
    }
    let elf = build("qemu-npcm750", &["bench", "sim-accelerator"])?;
    let mut g = Guest::boot(&elf, &["-icount", "shift=0"])?;
    let f = g.forwards.ok_or("the guest has no forwarded RTSP port")?;
    let rtcp = std::net::SocketAddr::from(([127, 0, 0, 1], f.rtcp));
    let rtsp = std::net::SocketAddr::from(([127, 0, 0, 1], f.rtsp));
    let path = "/light/3,4,-2?fps=max";
    let want = super::qemu_e2e::expected_frame([3072, 4096, -2048])?;
    let mut sessions = Vec::new();
    let from = g.uart().len();
    match viewers {
        Viewers::Interleaved => sessions.push(RtspSession::open_with(rtsp, path, Some(rtcp), Transport::Tcp)?),
        _ => {
            for _ in 0..viewers.copies() {
                sessions.push(RtspSession::open(rtsp, path, Some(rtcp))?);
            }
        }
    }
    let s = &mut sessions[0];
    for i in 0..frames {
        let frame = s.next_frame(Duration::from_secs(600))?;
        if frame.bytes != want {
            return Err(format!("RTP: frame {i} differs from model::render_frame"));
        }
    }
    let repaired = s.frames.repaired_rows;
    for s in sessions {
        s.teardown()?;
    }
    if repaired > 0 {
        println!("bench-fw: RTP: {repaired} rows came by repair (the counts include the resends)");
    }
    counted(&mut g, from, frames, viewers)
}

/// Several unicast viewers, each a host of its own on the virtual LAN
/// (lan.rs): from one address (slirp's) the board gives
/// `SESSIONS_PER_ADDRESS` sessions. The first viewer checks `frames`
/// frames; the others hold their sessions.
fn measure_unicast_hosts(frames: usize, n: usize) -> Result<Measured> {
    use super::lan::{Lan, BOARD};
    use crate::support::rtsp_client::RtspSession;
    let elf = build("qemu-npcm750", &["bench", "sim-accelerator"])?;
    let mut lan = Lan::boot_with(&elf, n, &["-icount", "shift=0"])?;
    let rtsp = std::net::SocketAddr::from((BOARD, 8554));
    let want = super::qemu_e2e::expected_frame([3072, 4096, -2048])?;
    let from = lan.guest.uart().len();
    let sessions: Vec<RtspSession> = (0..n)
        .map(|k| lan.on_host(k, move || RtspSession::open(rtsp, "/light/3,4,-2?fps=max", None)))
        .collect::<Result<_>>()?;
    let mut sessions = sessions.into_iter();
    let mut first = sessions.next().ok_or("no viewer")?;
    for i in 0..frames {
        let frame = first.next_frame(Duration::from_secs(600))?;
        if frame.bytes != want {
            return Err(format!("RTP: frame {i} differs from model::render_frame"));
        }
    }
    first.teardown()?;
    for s in sessions {
        s.teardown()?;
    }
    counted(&mut lan.guest, from, frames, Viewers::Unicast(n))
}

/// Multicast: slirp would hand the group's packets to the host's own
/// network, so the board's MAC goes through the relay into a network
/// namespace of the bench's own (as the hostile-network test does), where
/// `n` receivers (`cargo xtask receive`) join the group and check their
/// `frames` frames.
fn measure_multicast(frames: usize, n: usize) -> Result<Measured> {
    use super::lossy::{self, ip, open_tap, Faults, Namespace, Relay};
    use crate::images::firmware::free_udp_port;
    lossy::available().map_err(|why| format!("the multicast bench needs network namespaces: {why}"))?;
    let elf = build("qemu-npcm750", &["bench", "sim-accelerator"])?;
    let tap = format!("rtb{}", std::process::id() % 100_000);
    let tap_file = open_tap(&tap)?;
    let ns = Namespace::new(&tap, &tap)?;
    ip(&["-n", &ns.0, "route", "add", "224.0.0.0/4", "dev", &tap])?;
    let (qemu_port, relay_port) = (free_udp_port()?, free_udp_port()?);
    let udp = std::net::UdpSocket::bind(("127.0.0.1", relay_port)).map_err(|e| e.to_string())?;
    let remote = std::net::SocketAddr::from(([127, 0, 0, 1], qemu_port));
    let relay = Relay::start(udp, remote, tap_file, Faults::default(), 1)?;
    let netdev = crate::images::firmware::dgram_netdev(qemu_port, relay_port);
    let [trace, events] = relay.qemu_args();
    let mut g = Guest::boot_netdev(&elf, &netdev, &["-icount", "shift=0", trace, events])?;
    g.wait_for_log("link up", Duration::from_secs(120))?;
    let from = g.uart().len();
    let xtask = std::env::current_exe().map_err(|e| e.to_string())?;
    let frames_arg = frames.to_string();
    let receivers: Vec<std::process::Child> = (0..n)
        .map(|_| {
            std::process::Command::new("ip")
                .args(["netns", "exec", &ns.0])
                .arg(&xtask)
                .args(["receive", "--rtsp", "10.0.2.15:8554", "--path", "/light/3,4,-2?fps=max&multicast"])
                .args(["--frames", &frames_arg, "--light", "3,4,-2", "--multicast", "10.0.2.2"])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .map_err(|e| e.to_string())
        })
        .collect::<Result<_>>()?;
    for (i, c) in receivers.into_iter().enumerate() {
        let o = c.wait_with_output().map_err(|e| e.to_string())?;
        if !o.status.success() {
            let said = String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
            return Err(format!("multicast receiver {i}: {said}"));
        }
    }
    counted(&mut g, from, frames, Viewers::Multicast(n))
}

/// The counts lines the guest printed since UART offset `from`, once its
/// sessions ended: all but the first and the last frame's, per frame
/// rendered.
fn counted(g: &mut Guest, from: usize, frames: usize, viewers: Viewers) -> Result<Measured> {
    g.wait_for_line(from, "session", Duration::from_secs(5))?;
    let uart = g.uart();
    let lines: Vec<Counts> = uart
        .get(from..)
        .unwrap_or("")
        .lines()
        .filter_map(|l| l.trim().strip_prefix("bench: counts"))
        .filter_map(Counts::parse)
        .collect();
    // Frames rendered before the stream (the display's attract mode) send
    // nothing: count from the stream's frames on.
    let copies = viewers.copies() as u64;
    let sent: Vec<Counts> = lines.into_iter().skip_while(|c| c.tx_frames < copies * model::HEIGHT as u64 / 2).collect();
    if sent.len() < frames - 1 {
        return Err(format!("RTP: expected {} counts lines of whole frames, got {}:\n{uart}", frames - 1, sent.len()));
    }
    let counted = &sent[1..frames - 1];
    // The lines come once per frame rendered; rows of a frame may fall in
    // the next line (384 rows in one, 336 in the next): scale the means to
    // one frame's copies.
    let mut mean = Counts::mean(counted);
    let rows = match viewers {
        Viewers::Interleaved => mean.tx_frames, // segments, not rows: no scaling
        _ => mean.mac_tx_zero_copy / model::ROW_BYTES as f64,
    };
    if rows > 0.0 && viewers != Viewers::Interleaved {
        let per_frame = (copies as f64 * model::HEIGHT as f64) / rows;
        for f in mean.fields_mut() {
            *f *= per_frame;
        }
        println!(
            "bench-fw: {}: {rows:.0} rows per counts line, scaled to {} per frame rendered",
            viewers.name(),
            copies as usize * model::HEIGHT
        );
    }
    let camera: Vec<&str> = uart.lines().filter(|l| l.contains("bench: camera")).collect();
    if let Some(l) = camera.get(camera.len() / 2) {
        println!("{}", l.trim());
    }
    Ok(Measured { counts: mean, frames: counted.len() })
}

/// The RTP cases beyond one viewer: four unicast viewers of one stream,
/// multicast, interleaved. Prints each case's figures and estimate; per
/// stream, the instructions a viewer costs.
fn rtp_cases(frames: usize) -> Result<()> {
    for viewers in [Viewers::Unicast(4), Viewers::Multicast(3), Viewers::Interleaved] {
        let m = measure_rtp(frames, viewers)?;
        print_mode(&viewers.name(), &m);
        let p = print_estimate(&viewers.name(), &m, cost_model::FPGA_FRAME_CYCLES.value);
        let n = match viewers {
            Viewers::Unicast(n) | Viewers::Multicast(n) => n,
            Viewers::Interleaved => 1,
        };
        let per_viewer = if matches!(viewers, Viewers::Unicast(_)) { m.streaming() / n as f64 } else { m.streaming() };
        println!(
            "bench-fw: {}: {:.0} instructions per frame rendered, {per_viewer:.0} per viewer's frame; {p:.0} frames/s rendered, {:.0} frames/s summed over {n} viewers",
            viewers.name(),
            m.streaming(),
            p * n as f64
        );
    }
    Ok(())
}

fn print_mode(name: &str, m: &Measured) {
    let payload = model::FRAME_BYTES as f64;
    println!("bench-fw: {name} ({} frames counted)", m.frames);
    println!(
        "  streaming           {:>11.0} guest instructions/frame ({:.2} per payload byte)",
        m.streaming(),
        m.streaming() / payload
    );
    println!("  rendering (guest)   {:>11.0} guest instructions/frame (not the board's CPU)", m.counts.render_ns);
    println!(
        "  LW bridge           {:>11.0} register reads, {:.0} line-buffer words, {:.0} register writes",
        m.counts.lw_reads, m.counts.lw_line_words, m.counts.lw_writes
    );
    println!(
        "  CPU                 {:>11.0} bytes copied, {:.0} cache lines invalidated, {:.0} cleaned, {:.0} bytes read uncached",
        m.counts.cpu_copied,
        m.counts.lines_invalidated,
        m.counts.lines_cleaned,
        m.counts.uncached_read
    );
    println!(
        "  MAC                 {:>11.0} bytes in {:.0} frames sent, {:.0} of them read by the MAC from the ring (zero-copy)",
        m.counts.mac_tx, m.counts.tx_frames, m.counts.mac_tx_zero_copy
    );
    println!("  main loop           {:>11.3} busy iterations", m.counts.busy_loops);
}

fn print_estimate(name: &str, m: &Measured, fpga_cycles: f64) -> f64 {
    let e = cost_model::estimate(&m.model_counts(), fpga_cycles);
    let cpu = e.cpu_seconds();
    println!(
        "board estimate, {name}: {:.0} frames/s ({}-bound; per frame CPU {:.2} ms, FPGA {:.2} ms, wire {:.2} ms)",
        e.fps(),
        e.bound(),
        cpu * 1e3,
        e.fpga * 1e3,
        e.wire * 1e3
    );
    for c in &e.cpu {
        println!("  {:<28} {:>8.3} ms  {:>5.1}% of the CPU", c.name, c.seconds * 1e3, 100.0 * c.seconds / cpu);
    }
    e.fps()
}

/// Run the three modes and print the figures and the cost model.
pub fn run(args: &BenchArgs) -> Result<()> {
    crate::support::tools::ensure_qemu()?;
    let frames = args.frames.max(4);
    if args.web_only {
        return web_case(frames);
    }
    if args.rtp_only {
        let rtp = measure_rtp(frames, Viewers::Unicast(1))?;
        print_mode(&Viewers::Unicast(1).name(), &rtp);
        let p = print_estimate("RTP", &rtp, cost_model::FPGA_FRAME_CYCLES.value);
        println!("goals, RTP: <= 100,000 instructions/frame: {:.0}; >= 220 frames/s: {p:.0}", rtp.streaming());
        return rtp_cases(frames);
    }
    let frame_mode = measure(&["sim-accelerator"], frames)?;
    let row_mode = measure(&["sim-accelerator", "row-mode"], frames)?;
    let software = measure(&[], frames)?;
    let rtp = measure_rtp(frames, Viewers::Unicast(1))?;
    println!("bench-fw: QEMU npcm750-evb, -icount shift=0, {frames} pipelined frames per mode on the persistent port");
    print_mode("frame mode (simulated frame DMA into the ring)", &frame_mode);
    print_mode("row mode (simulated accelerator, a row per start)", &row_mode);
    print_mode("RTP (frame mode, rows zero-copy through two-buffer descriptors)", &rtp);
    println!(
        "bench-fw: software renderer {:.0} guest instructions/frame ({:.0} per pixel); streaming {:.2} per payload byte",
        software.counts.render_ns,
        software.counts.render_ns / (model::WIDTH * model::HEIGHT) as f64,
        software.streaming() / model::FRAME_BYTES as f64
    );
    println!();
    println!("board cost model: per-operation costs on a DE1-SoC");
    for c in CONSTANTS {
        println!("  {:<36} {:>12.4e} {:<12} {}", c.name, c.value, c.unit, c.source);
    }
    let f = print_estimate("frame mode", &frame_mode, cost_model::FPGA_FRAME_CYCLES.value);
    let r = print_estimate("row mode", &row_mode, cost_model::FPGA_ROW_MODE_CYCLES.value);
    let p = print_estimate("RTP", &rtp, cost_model::FPGA_FRAME_CYCLES.value);
    let per_byte = frame_mode.streaming() / model::FRAME_BYTES as f64;
    println!(
        "goals: streaming <= 4 instructions/byte: {per_byte:.2} ({}); frame mode >= 150 frames/s: {f:.0} ({}); row mode >= 30: {r:.0} ({})",
        verdict(per_byte <= 4.0),
        verdict(f >= 150.0),
        verdict(r >= 30.0)
    );
    println!(
        "goals, RTP: <= 100,000 instructions/frame: {:.0} ({}); >= 220 frames/s: {p:.0} ({})",
        rtp.streaming(),
        verdict(rtp.streaming() <= 100_000.0),
        verdict(p >= 220.0)
    );
    rtp_cases(frames)?;
    web_case(frames)
}

fn verdict(ok: bool) -> &'static str {
    if ok {
        "met"
    } else {
        "NOT met"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_lines_parse_only_when_complete() {
        let line = " lw_reads=3 lw_line_words=0 lw_writes=2 cpu_copied=518400 lines_invalidated=16200 lines_cleaned=0 uncached_read=1200 mac_tx=537000 mac_tx_zero_copy=0 tx_frames=358 busy_ns=900 render_ns=100 busy_loops=7";
        let c = Counts::parse(line).expect("complete");
        assert_eq!((c.lw_reads, c.lines_invalidated, c.tx_frames, c.busy_ns), (3, 16200, 358, 900));
        assert_eq!(Counts::parse(" lw_reads=3"), None, "fields missing");
        assert_eq!(Counts::parse(&format!("{line} extra=1")), None, "unknown field");
        assert_eq!(Counts::parse(&line.replace("=3 ", "=x ")), None, "not a number");
        let m = Measured { counts: Counts::mean(&[c, c]), frames: 2 };
        assert_eq!(m.streaming(), 800.0);
        assert_eq!(m.model_counts().instructions, 800.0);
    }
}
