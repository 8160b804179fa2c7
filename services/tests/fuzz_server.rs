//! Hostile input for the sans-IO frame server: random byte streams cut at
//! random points, random transport capacity and timing, random ends (close,
//! reset), in both modes. Checked: no panic; no frame byte for an invalid
//! request; frames only whole and in request order (a reset may cut the
//! last); every session ends; every frame begun is given back.
//!
//! `cargo test -p rt-services --test fuzz_server` runs proptest's default
//! 256 cases per property (the suite's short run);
//! `cargo xtask fuzz --cases 1000000` runs a million (release build).

use std::collections::HashMap;

use model::{Light, FRAME_BYTES, ROW_BYTES};
use proptest::prelude::*;
use rt_services::seed::server::{drive, Action, Mode, Session};
use rt_services::{encode_raw_request, FrameSource, Instant};

/// A frame source whose frames are cheap and recognisable: byte `i` of the
/// frame for light `l` is a hash of both. Rows become ready a few at a
/// time; it can be told to fail.
struct Fake {
    next: usize,
    open: HashMap<usize, ([i32; 3], u16)>,
    slots: usize,
    rows_per_poll: u16,
    fail_after_polls: Option<u32>,
}

fn byte(light: [i32; 3], i: usize) -> u8 {
    let h = (light[0] as u32).wrapping_mul(0x9E37_79B1)
        ^ (light[1] as u32).wrapping_mul(0x85EB_CA77)
        ^ (light[2] as u32).wrapping_mul(0xC2B2_AE3D)
        ^ (i as u32).wrapping_mul(0x27D4_EB2F);
    (h ^ (h >> 15)) as u8
}

impl FrameSource for Fake {
    type Frame = usize;
    type Error = &'static str;

    fn begin(&mut self, light: &Light) -> Result<Option<usize>, &'static str> {
        if self.open.len() >= self.slots {
            return Ok(None);
        }
        self.next += 1;
        self.open.insert(self.next, (light.raw(), 0));
        Ok(Some(self.next))
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, &'static str> {
        if let Some(n) = self.fail_after_polls.as_mut() {
            if *n == 0 {
                return Err("the fake accelerator failed");
            }
            *n -= 1;
        }
        let step = self.rows_per_poll;
        let e = self.open.get_mut(&frame).ok_or("unknown frame")?;
        e.1 = (e.1 + step).min(360);
        Ok(e.1)
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        let Some(&(light, rows)) = self.open.get(&frame) else { return 0 };
        if y >= rows || offset >= ROW_BYTES {
            return 0;
        }
        let n = out.len().min(ROW_BYTES - offset);
        let base = usize::from(y) * ROW_BYTES + offset;
        for (k, b) in out[..n].iter_mut().enumerate() {
            *b = byte(light, base + k);
        }
        n
    }

    fn end(&mut self, frame: usize) {
        self.open.remove(&frame);
    }
}

/// A piece of the client's byte stream.
#[derive(Clone, Debug)]
enum Piece {
    /// A valid request.
    Valid([i32; 3]),
    /// A request with a component out of range.
    Invalid([i32; 3]),
    /// Arbitrary bytes.
    Junk(Vec<u8>),
}

fn piece() -> impl Strategy<Value = Piece> {
    let coord = -(1 << 23)..(1 << 23);
    prop_oneof![
        6 => [coord.clone(), coord.clone(), coord.clone()].prop_map(Piece::Valid),
        1 => (prop::sample::select(vec![1i32 << 23, i32::MAX, i32::MIN, -(1 << 23) - 1]), coord.clone(), coord)
            .prop_map(|(bad, a, b)| Piece::Invalid([a, bad, b])),
        1 => prop::collection::vec(any::<u8>(), 0..30).prop_map(Piece::Junk),
    ]
}

/// How the client ends.
#[derive(Clone, Copy, Debug)]
enum End {
    /// Closes its sending side after the last byte.
    Close,
    /// Keeps the stream open (the server's request timeout ends it, or
    /// single mode's one frame).
    Linger,
    /// Resets after this many received bytes.
    Reset(usize),
}

#[derive(Clone, Debug)]
struct Case {
    mode: Mode,
    pieces: Vec<Piece>,
    cuts: Vec<usize>,
    capacities: Vec<usize>,
    gaps_ms: Vec<u64>,
    end: End,
    slots: usize,
    rows_per_poll: u16,
    fail_after_polls: Option<u32>,
}

fn case() -> impl Strategy<Value = Case> {
    (
        prop::bool::ANY,
        prop::collection::vec(piece(), 0..4),
        prop::collection::vec(1usize..20, 1..8),
        prop::collection::vec(prop_oneof![Just(0usize), 1usize..3000, Just(100_000usize)], 1..8),
        prop::collection::vec(prop_oneof![1u64..50, Just(3_000u64)], 1..6),
        prop_oneof![Just(End::Close), Just(End::Linger), (0usize..2 * FRAME_BYTES).prop_map(End::Reset)],
        1usize..3,
        1u16..120,
        prop::option::weighted(0.1, 0u32..50),
    )
        .prop_map(
            |(persistent, pieces, cuts, capacities, gaps_ms, end, slots, rows_per_poll, fail_after_polls)| Case {
                mode: if persistent { Mode::Persistent } else { Mode::Single },
                pieces,
                cuts,
                capacities,
                gaps_ms,
                // A persistent client that keeps its stream open may idle for
                // ever; lingering is for single mode.
                end: if persistent && matches!(end, End::Linger) { End::Close } else { end },
                slots,
                rows_per_poll,
                fail_after_polls,
            },
        )
}

/// The bytes the client sends, and the lights of the valid requests before
/// the first request that is not one (which ends the session).
fn stream(pieces: &[Piece]) -> (Vec<u8>, Vec<[i32; 3]>) {
    let mut bytes = Vec::new();
    for p in pieces {
        match p {
            Piece::Valid(l) | Piece::Invalid(l) => bytes.extend_from_slice(&encode_raw_request(*l)),
            Piece::Junk(j) => bytes.extend_from_slice(j),
        }
    }
    // Parse back the way the server must: 12-byte requests in order.
    let mut valid = Vec::new();
    for chunk in bytes.chunks(12) {
        if chunk.len() < 12 {
            break;
        }
        let l = [0, 4, 8].map(|o| i32::from_be_bytes([chunk[o], chunk[o + 1], chunk[o + 2], chunk[o + 3]]));
        if Light::from_raw(l[0], l[1], l[2]).is_err() {
            break;
        }
        valid.push(l);
    }
    (bytes, valid)
}

fn run(c: &Case) -> Result<(), TestCaseError> {
    let (bytes, valid) = stream(&c.pieces);
    let mut frames = Fake {
        next: 0,
        open: HashMap::new(),
        slots: c.slots,
        rows_per_poll: c.rows_per_poll,
        fail_after_polls: c.fail_after_polls,
    };
    let mut now = 0u64;
    let mut session: Session<usize> = Session::new(c.mode, Instant::from_millis(now));
    let (mut fed, mut step) = (0usize, 0usize);
    let mut received: Vec<u8> = Vec::new();
    let mut closed = None;
    let mut eof_sent = false;
    for _ in 0..200_000 {
        // Client: more bytes, cut at random points, with random gaps.
        if fed < bytes.len() {
            let n = c.cuts[step % c.cuts.len()].min(bytes.len() - fed);
            let taken = session.receive(Instant::from_millis(now), &bytes[fed..fed + n]);
            prop_assert!(taken <= n);
            fed += taken;
        } else if matches!(c.end, End::Close | End::Reset(_)) && !eof_sent {
            session.receive_eof();
            eof_sent = true;
        }
        if let End::Reset(at) = c.end {
            if received.len() >= at {
                session.abandon(&mut frames);
                closed = Some("reset");
                break;
            }
        }
        let cap = c.capacities[step % c.capacities.len()];
        let action = drive(
            &mut session,
            Instant::from_millis(now),
            &mut frames,
            |fill| {
                let mut buf = vec![0u8; cap.min(ROW_BYTES)];
                let n = fill(&mut buf);
                received.extend_from_slice(&buf[..n]);
                n
            },
            &mut String::new(),
        );
        match action {
            Action::Close(reason) => {
                closed = Some(if matches!(reason, rt_services::seed::server::Closed::Done) { "done" } else { "error" });
                break;
            }
            Action::Wait { .. } | Action::Send { .. } => {}
            _ => {}
        }
        now += c.gaps_ms[step % c.gaps_ms.len()];
        step += 1;
    }
    prop_assert!(
        closed.is_some(),
        "the session never ended ({} bytes fed of {}, {} received)",
        fed,
        bytes.len(),
        received.len()
    );
    prop_assert!(frames.open.is_empty(), "frames not given back: {:?}", frames.open.keys().collect::<Vec<_>>());
    // Frames only whole (but a reset, a failure or the end of a linger may
    // cut the last) and in order, for valid requests only.
    let allowed = match c.mode {
        Mode::Single => valid.len().min(1),
        Mode::Persistent => valid.len(),
    };
    let whole = received.len() / FRAME_BYTES;
    prop_assert!(whole <= allowed, "{whole} frames for {allowed} valid requests");
    for (k, chunk) in received.chunks(FRAME_BYTES).enumerate() {
        prop_assert!(k < allowed, "frame bytes beyond the valid requests");
        let l = valid[k];
        let ok = chunk.iter().enumerate().all(|(i, b)| *b == byte(l, i));
        prop_assert!(ok, "frame {} is not the one for request {}", k, k);
    }
    if closed == Some("done") {
        prop_assert_eq!(received.len() % FRAME_BYTES, 0, "a clean end sends whole frames only");
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn the_server_survives_hostile_clients(c in case()) {
        run(&c)?;
    }
}
