//! `cargo xtask bench-fw`: guest instructions per frame on QEMU with
//! `-icount shift=0` (one guest nanosecond per instruction), for the
//! software renderer and for the network streaming alone.
//!
//! The firmware's `bench` build logs, for every frame, the guest time when
//! its first row starts and the guest time spent rendering its 360 rows.
//! Frames are pipelined on the persistent port, so the time from one
//! frame's start to the next is the whole cost of a frame; minus the
//! rendering it is the network streaming alone (smoltcp, the MAC driver,
//! the frame server, RGB packing).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use clap::Args;

use crate::firmware::{build, Guest};
use crate::Result;

/// `cargo xtask bench-fw` options.
#[derive(Args)]
pub struct BenchArgs {
    /// Frames to request (the first is not counted).
    #[arg(long, default_value_t = 4)]
    pub frames: usize,
}

fn parse(uart: &str, tag: &str) -> Vec<u64> {
    uart.lines().filter_map(|l| l.trim().strip_prefix(tag)).filter_map(|v| v.trim().parse().ok()).collect()
}

/// Run the bench and print the two figures.
pub fn run(args: &BenchArgs) -> Result<()> {
    crate::tools::ensure_qemu()?;
    let frames = args.frames.max(3);
    let elf = build("qemu-npcm750", &["bench"])?;
    let mut g = Guest::boot(&elf, &["-icount", "shift=0"])?;
    let mut s = TcpStream::connect(("127.0.0.1", g.port_persistent)).map_err(|e| e.to_string())?;
    s.set_read_timeout(Some(Duration::from_secs(600))).map_err(|e| e.to_string())?;
    let light = rt_protocol::encode_raw_request([3 << 10, 4 << 10, -(2 << 10)]);
    let wall = Instant::now();
    s.write_all(&light.repeat(frames)).map_err(|e| e.to_string())?;
    let mut frame = vec![0u8; model::WIDTH * model::HEIGHT * 3];
    for i in 0..frames {
        s.read_exact(&mut frame).map_err(|e| format!("frame {i}: {e}"))?;
    }
    let wall = wall.elapsed();
    drop(s);
    // Every frame's lines are logged before its last bytes leave the guest.
    g.wait_for_log("bench: frame rendered", Duration::from_secs(5))?;
    let uart = g.uart();
    let starts = parse(&uart, "bench: frame start");
    let renders = parse(&uart, "bench: frame rendered");
    if starts.len() < frames || renders.len() < frames {
        return Err(format!(
            "expected {frames} bench lines, got {} starts / {} renders:\n{uart}",
            starts.len(),
            renders.len()
        ));
    }
    // Frames 1..frames-1: start-to-next-start periods (frame 0 warms up).
    let mut per_frame = Vec::new();
    let mut render = Vec::new();
    for i in 1..frames - 1 {
        per_frame.push(starts[i + 1] - starts[i]);
        render.push(renders[i]);
    }
    let avg = |v: &[u64]| v.iter().sum::<u64>() / v.len() as u64;
    let (total, rend) = (avg(&per_frame), avg(&render));
    let net = total.saturating_sub(rend);
    println!(
        "bench-fw: QEMU npcm750-evb, -icount shift=0, {frames} pipelined frames on the persistent port ({} counted)",
        per_frame.len()
    );
    println!("bench-fw: whole frame              {total:>13} guest instructions/frame");
    println!(
        "bench-fw: software renderer        {rend:>13} guest instructions/frame ({:.0} per pixel)",
        rend as f64 / (model::WIDTH * model::HEIGHT) as f64
    );
    println!(
        "bench-fw: network streaming alone  {net:>13} guest instructions/frame ({:.1} per payload byte)",
        net as f64 / frame.len() as f64
    );
    println!("bench-fw: (host wall clock {:.2} s for {frames} frames under icount)", wall.as_secs_f64());
    Ok(())
}
