//! `cargo xtask soak`: a long run of the emulated board in one boot
//! (docs/reliability.md#soak). Persistent connections of pipelined frames,
//! reconnecting every so often, with seed-port frames mixed in; every frame
//! checked against the model by a CRC-32 per light computed once; at the
//! end the firmware's idle report must show every socket listening and
//! every descriptor free.

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use clap::Args;

use super::qemu_e2e::connect;
use crate::images::firmware::{build, Guest};
use crate::support::Result;

/// `cargo xtask soak` options.
#[derive(Args)]
pub struct SoakArgs {
    /// Frames in all.
    #[arg(long, default_value_t = 1000)]
    pub frames: usize,
}

/// Lights in turn (raw Q13.10).
const LIGHTS: [[i32; 3]; 6] = [
    [3 << 10, 4 << 10, -(2 << 10)],
    [-(5 << 10), 6 << 10, 1 << 10],
    [0, 8 << 10, -(7 << 10)],
    [1500, 2500, 700],
    [2048, 1024, -2560],
    [-4096, 6144, -3072],
];
/// Frames per persistent connection before it reconnects.
const PER_CONNECTION: usize = 40;
/// A seed-port frame after every this many.
const SEED_EVERY: usize = 25;

/// Run `frames` frames; the figures on one line.
pub fn soak(frames: usize) -> Result<String> {
    crate::support::tools::ensure_qemu()?;
    let elf = build("qemu-npcm750", &[])?;
    let digests: Vec<u32> = LIGHTS
        .iter()
        .map(|l| super::qemu_e2e::expected_frame(*l).map(|f| crc32fast::hash(&f)))
        .collect::<Result<_>>()?;
    let mut g = Guest::boot(&elf, &[])?;
    let start = Instant::now();
    let (mut done, mut seed, mut connections) = (0usize, 0usize, 0usize);
    let mut frame = vec![0u8; model::FRAME_BYTES];
    while done < frames {
        // One persistent connection: up to PER_CONNECTION frames, pipelined.
        let count = PER_CONNECTION.min(frames - done);
        let mut s = connect(g.port_persistent)?;
        connections += 1;
        let requests: Vec<u8> =
            (0..count).flat_map(|i| rt_services::encode_raw_request(LIGHTS[(done + i) % LIGHTS.len()])).collect();
        s.write_all(&requests).map_err(|e| e.to_string())?;
        s.shutdown(std::net::Shutdown::Write).map_err(|e| e.to_string())?;
        for i in 0..count {
            s.read_exact(&mut frame).map_err(|e| format!("frame {} (persistent): {e}", done + i))?;
            if crc32fast::hash(&frame) != digests[(done + i) % LIGHTS.len()] {
                return Err(format!("frame {} (persistent) is not the model's", done + i));
            }
            if (done + i + 1) % SEED_EVERY == 0 && done + i + 1 < frames {
                // A seed-port frame while the persistent one is open.
                let l = (done + i + 3) % LIGHTS.len();
                let mut t = connect(g.port_single)?;
                t.write_all(&rt_services::encode_raw_request(LIGHTS[l])).map_err(|e| e.to_string())?;
                let mut got = Vec::new();
                t.read_to_end(&mut got).map_err(|e| format!("seed frame: {e}"))?;
                if got.len() != model::FRAME_BYTES || crc32fast::hash(&got) != digests[l] {
                    return Err(format!("seed frame after {} is not the model's ({} bytes)", done + i, got.len()));
                }
                seed += 1;
            }
        }
        let mut rest = Vec::new();
        s.read_to_end(&mut rest).map_err(|e| e.to_string())?;
        if !rest.is_empty() {
            return Err(format!("{} bytes after the last frame of a connection", rest.len()));
        }
        done += count;
        if done % 100 < count {
            eprintln!("soak: {done} of {frames} frames");
        }
    }
    let elapsed = start.elapsed();
    // The firmware reports a second after the last client goes.
    let seen = g.uart().len();
    let idle = g.wait_for_line(seen, "net: idle:", Duration::from_secs(15))?;
    // firmware/src/net.rs SOCKETS; dwmac TX_RING and RX_RING.
    let want = "24 of 24 sockets listening, 32 of 32 TX and 128 of 128 RX descriptors free";
    if !idle.contains(want) {
        return Err(format!("the firmware's last idle report is {idle:?}, want {want:?}"));
    }
    Ok(format!(
        "soak: {} frames ({} pipelined over {connections} connections, {seed} on the seed port) in {:.0} s: 0 lost, 0 corrupted; at the end {want}",
        done + seed,
        done,
        elapsed.as_secs_f64()
    ))
}

/// `cargo xtask soak`.
pub fn run(args: &SoakArgs) -> Result<()> {
    println!("{}", soak(args.frames)?);
    Ok(())
}
