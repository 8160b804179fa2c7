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
    #[arg(long, default_value_t = 6)]
    pub frames: usize,
    /// Measure the RTP path only.
    #[arg(long)]
    pub rtp_only: bool,
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

/// The frame-mode bench build over RTSP/RTP: a fixed-light stream at
/// `fps=max`, `frames` frames checked against the model; the counts of all
/// but the first and the last frame the firmware rendered meanwhile.
fn measure_rtp(frames: usize) -> Result<Measured> {
    let elf = build("qemu-npcm750", &["bench", "sim-accelerator"])?;
    let mut g = Guest::boot(&elf, &["-icount", "shift=0"])?;
    let f = g.forwards.ok_or("the guest has no forwarded RTSP port")?;
    let rtcp = std::net::SocketAddr::from(([127, 0, 0, 1], f.rtcp));
    let rtsp = std::net::SocketAddr::from(([127, 0, 0, 1], f.rtsp));
    let mut stream = crate::support::rtsp_client::Stream::open(rtsp, "/light/3,4,-2?fps=max", Some(rtcp))?;
    let want = super::qemu_e2e::expected_frame([3072, 4096, -2048])?;
    for i in 0..frames {
        let frame = stream.next_frame(Duration::from_secs(600))?;
        if frame.bytes != want {
            return Err(format!("RTP: frame {i} differs from model::render_frame"));
        }
    }
    let repaired = stream.repaired_rows;
    stream.teardown()?;
    if repaired > 0 {
        println!("bench-fw: RTP: {repaired} rows came by repair (the counts include the resends)");
    }
    g.wait_for_log("session", Duration::from_secs(5))?;
    let uart = g.uart();
    let lines: Vec<Counts> =
        uart.lines().filter_map(|l| l.trim().strip_prefix("bench: counts")).filter_map(Counts::parse).collect();
    // Frames rendered before the stream (the display's attract mode) send
    // nothing: count from the stream's frames on.
    let sent: Vec<Counts> = lines.into_iter().skip_while(|c| c.tx_frames < model::HEIGHT as u64 / 2).collect();
    if sent.len() < frames - 1 {
        return Err(format!("RTP: expected {} counts lines of whole frames, got {}:\n{uart}", frames - 1, sent.len()));
    }
    let counted = &sent[1..frames - 1];
    // The lines come once per frame rendered; with a fixed light at
    // fps=max they held 384 rows each, not 360 (16 frames sent per 15
    // "frame rendered" lines): scale the means to one frame sent.
    let mut mean = Counts::mean(counted);
    let rows = mean.mac_tx_zero_copy / model::ROW_BYTES as f64;
    if rows > 0.0 {
        let per_frame = model::HEIGHT as f64 / rows;
        for f in mean.fields_mut() {
            *f *= per_frame;
        }
        println!("bench-fw: RTP: {rows:.0} rows per counts line, scaled to {} per frame sent", model::HEIGHT);
    }
    let camera: Vec<&str> = uart.lines().filter(|l| l.contains("bench: camera")).collect();
    if let Some(l) = camera.get(camera.len() / 2) {
        println!("{}", l.trim());
    }
    Ok(Measured { counts: mean, frames: counted.len() })
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
    println!("  main loop           {:>11.0} busy iterations", m.counts.busy_loops);
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
    if args.rtp_only {
        let rtp = measure_rtp(frames)?;
        print_mode("RTP (frame mode, rows zero-copy through two-buffer descriptors)", &rtp);
        let p = print_estimate("RTP", &rtp, cost_model::FPGA_FRAME_CYCLES.value);
        println!("goals, RTP: <= 100,000 instructions/frame: {:.0}; >= 220 frames/s: {p:.0}", rtp.streaming());
        return Ok(());
    }
    let frame_mode = measure(&["sim-accelerator"], frames)?;
    let row_mode = measure(&["sim-accelerator", "row-mode"], frames)?;
    let software = measure(&[], frames)?;
    let rtp = measure_rtp(frames)?;
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
    Ok(())
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
