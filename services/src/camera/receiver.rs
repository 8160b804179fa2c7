//! The receiving end of [`crate::camera::wire::rtp`]'s stream: RTP datagrams in, whole
//! frames and generic NACKs out.
//!
//! Sans-IO like the rest of the crate: the caller hands in each datagram
//! with the time ([`Receiver::receive`]), wakes it at
//! [`Receiver::deadline`] ([`Receiver::poll`]), sends what
//! [`Receiver::write_nack`] writes to the server's RTCP port, and gets each
//! finished frame through a callback while its bytes are still in the
//! receiver's buffers. A few frame buffers (the caller's) and bitmaps, no
//! allocation.
//!
//! # Frames
//!
//! Packets are grouped into frames by RTP timestamp and placed by their
//! RFC 4175 line number. The sender numbers a frame's 360 rows with
//! consecutive extended sequence numbers (low 16 bits in the RTP header,
//! high 16 in the RFC 4175 header, so no wrap has to be guessed), so a
//! frame's row 0 is `seq - row` of any of its packets: that is what orders
//! frames, finds the sequence number of a missing row, and counts frames of
//! which nothing arrived (a jump of `k * 360` numbers between frames).
//!
//! A frame is *closed* when its marker arrives, when a packet of a newer
//! frame does, or when no packet came for [`ReceiverConfig::repair_wait`].
//! A closed frame with rows missing asks for them (a NACK at once, then up
//! to [`ReceiverConfig::max_nacks`] in all, [`ReceiverConfig::nack_interval`]
//! apart) and waits up to [`ReceiverConfig::repair_wait`] for them. Frames
//! are handed over in order, as [`Quality::Exact`] (every row on first
//! sending), [`Quality::Repaired`] (every row, some after a NACK) or
//! [`Quality::Damaged`] (given up: each missing row is the previous
//! frame's).
//!
//! # Buffers
//!
//! A receiver of `N` frame buffers keeps one for the frame handed over
//! last and has up to `N - 1` frames in progress: a packet of one more
//! gives up on the oldest. So its memory for repairs is `N - 1` frames: on
//! a path whose repairs are slow beside the frame rate (a board that
//! renders the next frame before it reads the NACK), more buffers keep a
//! frame waiting for its rows while newer ones arrive. A frame given up
//! takes each row it misses from the frame handed over before it, which
//! its buffer keeps whole until then, so a damaged frame always shows the
//! previous frame where it has holes.

use core::time::Duration;

use model::{FRAME_BYTES, ROW_BYTES};

use crate::camera::wire::rtcp::{FMT_GENERIC_NACK, RTCP_RTPFB};
use crate::camera::wire::rtp::{BufferTooShort, HEADER_BYTES, PACKET_BYTES, PAYLOAD_TYPE};
use crate::frames::ROWS;
use crate::time::Instant;

const ROW_COUNT: usize = ROWS as usize;

/// Words of a one-bit-per-row bitmap.
const BITMAP_WORDS: usize = ROW_COUNT.div_ceil(32);

/// FCI entries a frame's missing rows can need: each entry covers 17
/// consecutive sequence numbers (RFC 4585 section 6.2.1, PID and BLP).
const ENTRIES_PER_FRAME: usize = ROW_COUNT.div_ceil(17);

/// The most frame buffers a receiver takes (so at most one less frames in
/// progress): what [`MAX_NACK_BYTES`] is sized for.
pub const MAX_BUFFERS: usize = 9;

/// The largest NACK [`Receiver::write_nack`] writes: header, sender and
/// media SSRC, and the entries for every frame in progress (at most
/// `MAX_BUFFERS - 1`); 716 bytes, one datagram.
pub const MAX_NACK_BYTES: usize = 12 + 4 * (MAX_BUFFERS - 1) * ENTRIES_PER_FRAME;

/// A jump in sequence numbers beyond which frames in between are not
/// counted lost: the sender restarted or the numbers are not to be trusted
/// (32,768 is also as far back as a NACK's 16-bit PID reaches).
const RESYNC_JUMP: u32 = 0x8000;

/// The longest a closed frame waits for repairs, however slow they are,
/// as a player's jitter buffer would: a board that renders its next frames
/// before it reads a NACK answers late (the emulated board, on its CPU).
/// At a frame rate the buffers cannot hold that long, a packet of one
/// frame more than they hold gives the oldest up sooner.
pub const MAX_REPAIR_WAIT: Duration = Duration::from_secs(3);

/// The longest time between two NACKs for one frame, however slow its
/// repairs have been.
pub const MAX_NACK_INTERVAL: Duration = Duration::from_millis(500);

/// How the receiver waits for repairs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReceiverConfig {
    /// Our SSRC, the NACKs' packet sender (RFC 4585 section 6.1).
    pub ssrc: u32,
    /// The payload type to accept (the SDP's, [`PAYLOAD_TYPE`]).
    pub payload_type: u8,
    /// Time between NACKs for the same frame, at least: once repairs were
    /// seen, twice the time they take (smoothed), so a slow path is not
    /// asked again before the rows already asked for could arrive.
    pub nack_interval: Duration,
    /// NACKs per frame, the first included (0: never ask).
    pub max_nacks: u8,
    /// How long a closed frame waits for its missing rows, at least (longer
    /// when the NACK rounds take longer: room for `max_nacks` of them, up
    /// to [`MAX_REPAIR_WAIT`]), and how long an open one waits for its
    /// next packet before it is closed.
    pub repair_wait: Duration,
}

impl ReceiverConfig {
    /// The defaults, NACKs sent as `ssrc`: up to 30 NACKs at least 25 ms
    /// apart (once repairs were seen, twice their time), for as long as
    /// those rounds take up to [`MAX_REPAIR_WAIT`], and 300 ms of quiet
    /// before a frame without its marker is closed. At 10% loss a row's
    /// NACK or its repair is lost one time in five, and a board that
    /// refuses to resend a packet twice within its round trip wastes the
    /// rounds that come sooner: with four rounds 71% of frames came whole
    /// through the suite's lossy relay at 10% (40 given up).
    /// 300 ms, not a frame time: a board rendering in software, or serving
    /// four viewers, sends a frame's rows in runs with pauses between (the
    /// emulated board's frames take half a second), and a frame closed at
    /// a pause asks for rows that are still on their way.
    pub const fn new(ssrc: u32) -> ReceiverConfig {
        ReceiverConfig {
            ssrc,
            payload_type: PAYLOAD_TYPE,
            nack_interval: Duration::from_millis(25),
            max_nacks: 30,
            repair_wait: Duration::from_millis(300),
        }
    }
}

/// How a frame was completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quality {
    /// Every row arrived without being asked for again.
    Exact,
    /// Every row arrived, some after a NACK.
    Repaired,
    /// Rows were still missing when the receiver gave up; they hold the
    /// previous frame's rows (black before the first frame).
    Damaged,
}

/// A finished frame, handed to the caller's callback.
#[derive(Clone, Copy, Debug)]
pub struct ReceivedFrame<'a> {
    /// The frame's RTP timestamp.
    pub timestamp: u32,
    /// How it was completed.
    pub quality: Quality,
    /// Rows that never arrived (filled from the previous frame).
    pub missing_rows: u16,
    /// Frames lost whole (not one packet arrived) just before this one.
    pub lost_before: u32,
    /// The rows that arrived after a NACK asked for them (repairs).
    pub repaired: Rows,
    /// The frame, [`FRAME_BYTES`] of RGB888, top row first.
    pub pixels: &'a [u8],
}

/// Why a datagram was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ignored {
    /// Shorter than a row's packet ([`PACKET_BYTES`]).
    Short,
    /// Not RTP version 2.
    Version,
    /// Not this stream's layout: CSRCs or a header extension, a line length
    /// other than one row, a line number beyond the frame, a second line or
    /// a non-zero offset.
    Layout,
    /// Another payload type.
    PayloadType,
    /// Another synchronisation source than the stream's first packet's.
    Ssrc,
}

/// What became of a datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// A new row of a frame in progress.
    Accepted,
    /// A row that had already arrived.
    Duplicate,
    /// A row of a frame already handed over (or given up).
    Late,
    /// Not a packet of this stream.
    Ignored(Ignored),
}

/// What happened so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReceiverCounts {
    /// Frames handed over [`Quality::Exact`].
    pub exact: u64,
    /// Frames handed over [`Quality::Repaired`].
    pub repaired: u64,
    /// Frames handed over [`Quality::Damaged`].
    pub damaged: u64,
    /// Frames of which no packet arrived.
    pub lost: u64,
    /// Datagrams accepted as new rows.
    pub packets: u64,
    /// Rows that arrived again.
    pub duplicates: u64,
    /// Rows of frames already handed over.
    pub late: u64,
    /// Datagrams that were not this stream's packets.
    pub ignored: u64,
    /// NACK packets written.
    pub nacks: u64,
    /// Rows asked for (once per NACK naming them).
    pub rows_nacked: u64,
    /// Rows that arrived after a NACK asked for them.
    pub rows_repaired: u64,
    /// Rows filled from the previous frame in damaged frames.
    pub rows_filled: u64,
    /// Sequence jumps too large to count lost frames across.
    pub resyncs: u64,
    /// Damaged frames handed over before their repair wait ended, because
    /// a newer frame needed their buffer.
    pub crowded_out: u64,
}

/// A set of a frame's rows, one bit each.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Rows([u32; BITMAP_WORDS]);

impl Rows {
    /// Whether row `y` is in the set.
    pub fn contains(&self, y: u16) -> bool {
        usize::from(y) < ROW_COUNT && self.has(usize::from(y))
    }

    /// Rows in the set.
    pub fn len(&self) -> u16 {
        self.count()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.count() == 0
    }

    fn has(&self, y: usize) -> bool {
        self.0[y / 32] & (1 << (y % 32)) != 0
    }

    fn set(&mut self, y: usize) {
        self.0[y / 32] |= 1 << (y % 32);
    }

    fn count(&self) -> u16 {
        self.0.iter().map(|w| w.count_ones() as u16).sum()
    }

    fn is_full(&self) -> bool {
        self.count() == ROWS
    }

    fn and(&self, other: &Rows) -> Rows {
        let mut out = *self;
        for (o, w) in out.0.iter_mut().zip(other.0) {
            *o &= w;
        }
        out
    }
}

/// Timers of a closed frame with rows missing.
#[derive(Clone, Copy, Debug)]
struct Closing {
    give_up: Instant,
    next_nack: Instant,
    nacks_sent: u8,
    /// When the last NACK for the frame went: a row it asked for that
    /// comes is a sample of the repair delay.
    asked_at: Option<Instant>,
}

/// A frame in progress.
#[derive(Clone, Copy, Debug)]
struct Assembly {
    timestamp: u32,
    /// The extended sequence number of row 0.
    base: u32,
    received: Rows,
    nacked: Rows,
    repaired: bool,
    lost_before: u32,
    last_packet: Instant,
    closed: Option<Closing>,
}

/// A parsed row packet.
struct RowIn<'a> {
    marker: bool,
    timestamp: u32,
    ssrc: u32,
    seq: u32,
    row: usize,
    pixels: &'a [u8],
}

/// Whether extended sequence number `a` comes after `b` (within half the
/// number space, as RFC 1982 serial numbers).
fn after(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// The RTP receiver of one stream (module docs). `B` is a frame buffer of
/// at least [`FRAME_BYTES`]: a `Vec<u8>` on the host, a static slice on a
/// board; `N` of them (2 to [`MAX_BUFFERS`]) keep `N - 1` frames in
/// progress.
pub struct Receiver<B, const N: usize> {
    config: ReceiverConfig,
    buffers: [B; N],
    /// The frames in progress, by buffer (never the last handed over's).
    slots: [Option<Assembly>; N],
    /// The buffer of the frame handed over last.
    last_delivered: usize,
    /// Row 0's sequence number of the frame handed over last.
    delivered_base: Option<u32>,
    /// Row 0's sequence number of the newest frame begun.
    newest_base: Option<u32>,
    media_ssrc: Option<u32>,
    counts: ReceiverCounts,
    /// The time from a NACK to the first row it brought, smoothed (RFC
    /// 6298's gain of 1/8).
    repair_delay: Option<Duration>,
}

impl<B: AsRef<[u8]> + AsMut<[u8]>, const N: usize> Receiver<B, N> {
    /// A receiver assembling frames in `buffers`, each at least
    /// [`FRAME_BYTES`] long. Their contents stand in for the frame before
    /// the first (zeros: black).
    pub fn new(config: ReceiverConfig, buffers: [B; N]) -> Result<Receiver<B, N>, BufferTooShort> {
        const { assert!(N >= 2 && N <= MAX_BUFFERS, "a receiver takes 2 to MAX_BUFFERS frame buffers") };
        if buffers.iter().any(|b| b.as_ref().len() < FRAME_BYTES) {
            return Err(BufferTooShort { needed: FRAME_BYTES });
        }
        Ok(Receiver {
            config,
            buffers,
            slots: [None; N],
            last_delivered: 0,
            delivered_base: None,
            newest_base: None,
            media_ssrc: None,
            counts: ReceiverCounts::default(),
            repair_delay: None,
        })
    }

    /// What happened so far.
    pub fn counts(&self) -> ReceiverCounts {
        self.counts
    }

    /// The time repairs take, smoothed, once one was seen: from a NACK to
    /// the first row it asked for.
    pub fn repair_delay(&self) -> Option<Duration> {
        self.repair_delay
    }

    /// The time between NACKs for one frame ([`ReceiverConfig::nack_interval`]).
    fn nack_interval(&self) -> Duration {
        let measured = self.repair_delay.map_or(Duration::ZERO, |d| 2 * d);
        self.config.nack_interval.max(measured).min(MAX_NACK_INTERVAL)
    }

    /// The stream's SSRC, once a packet arrived.
    pub fn media_ssrc(&self) -> Option<u32> {
        self.media_ssrc
    }

    /// The frame handed over last (the buffer's initial contents before
    /// the first).
    pub fn last_frame(&self) -> &[u8] {
        &self.buffers[self.last_delivered].as_ref()[..FRAME_BYTES]
    }

    /// Take one datagram from the RTP socket, received at `now`. Frames it
    /// finishes go to `deliver`, oldest first.
    pub fn receive(&mut self, now: Instant, datagram: &[u8], mut deliver: impl FnMut(ReceivedFrame<'_>)) -> Verdict {
        let verdict = self.take(now, datagram, &mut deliver);
        match verdict {
            Verdict::Accepted => self.counts.packets += 1,
            Verdict::Duplicate => self.counts.duplicates += 1,
            Verdict::Late => self.counts.late += 1,
            Verdict::Ignored(_) => self.counts.ignored += 1,
        }
        self.settle(now, false, &mut deliver);
        verdict
    }

    /// Run the timers at `now`: close frames no packet came for, give up on
    /// repairs past their wait. Frames finished go to `deliver`.
    pub fn poll(&mut self, now: Instant, mut deliver: impl FnMut(ReceivedFrame<'_>)) {
        for i in 0..N {
            if let Some(a) = &self.slots[i] {
                if a.closed.is_none() && now >= a.last_packet + self.config.repair_wait {
                    self.close(i, now);
                }
            }
        }
        self.settle(now, false, &mut deliver);
    }

    /// When [`poll`](Self::poll) or [`write_nack`](Self::write_nack) next
    /// has something to do (`None`: only a datagram can change anything).
    /// Call both after every datagram too: a NACK is due as soon as a
    /// frame closes.
    pub fn deadline(&self) -> Option<Instant> {
        self.slots
            .iter()
            .flatten()
            .filter_map(|a| match a.closed {
                None => Some(a.last_packet + self.config.repair_wait),
                // A whole frame waits only for the one before it.
                Some(_) if a.received.is_full() => None,
                Some(c) if c.nacks_sent < self.config.max_nacks => Some(c.next_nack.min(c.give_up)),
                Some(c) => Some(c.give_up),
            })
            .min()
    }

    /// Write a generic NACK (RFC 4585 section 6.2.1; sent on its own, a
    /// reduced-size RTCP packet per RFC 5506) for every missing row of the
    /// closed frames whose NACK is due at `now`; returns its length, or
    /// `None` when none is due. Send it to the server's RTCP port from the
    /// client's.
    pub fn write_nack(&mut self, now: Instant, out: &mut [u8; MAX_NACK_BYTES]) -> Option<usize> {
        let media = self.media_ssrc?;
        let max = self.config.max_nacks;
        let mut due = self.in_order();
        due.retain(|&i| {
            self.slots[i].is_some_and(|a| {
                a.closed.is_some_and(|c| c.nacks_sent < max && now >= c.next_nack) && !a.received.is_full()
            })
        });
        if due.is_empty() {
            return None;
        }
        let interval = self.nack_interval();
        let mut len = 12;
        let mut entry: Option<(u32, u16)> = None;
        let mut rows = 0u64;
        for i in due {
            let Some(a) = self.slots[i].as_mut() else { continue };
            for y in (0..ROW_COUNT).filter(|&y| !a.received.has(y)) {
                let seq = a.base.wrapping_add(y as u32);
                a.nacked.set(y);
                rows += 1;
                match &mut entry {
                    Some((pid, blp)) if (1..=16).contains(&seq.wrapping_sub(*pid)) => {
                        *blp |= 1 << (seq.wrapping_sub(*pid) - 1);
                    }
                    _ => {
                        if let Some(e) = entry.replace((seq, 0)) {
                            len = put_entry(out, len, e);
                        }
                    }
                }
            }
            if let Some(c) = a.closed.as_mut() {
                c.nacks_sent += 1;
                c.next_nack = now + interval;
                c.asked_at = Some(now);
            }
        }
        if let Some(e) = entry {
            len = put_entry(out, len, e);
        }
        let words = (len / 4 - 1) as u16;
        out[0] = 2 << 6 | FMT_GENERIC_NACK;
        out[1] = RTCP_RTPFB;
        out[2..4].copy_from_slice(&words.to_be_bytes());
        out[4..8].copy_from_slice(&self.config.ssrc.to_be_bytes());
        out[8..12].copy_from_slice(&media.to_be_bytes());
        self.counts.nacks += 1;
        self.counts.rows_nacked += rows;
        Some(len)
    }

    /// The buffers of the frames in progress, oldest first.
    fn in_order(&self) -> heapless::Vec<usize, N> {
        let mut order: heapless::Vec<usize, N> = (0..N).filter(|&i| self.slots[i].is_some()).collect();
        let base = |i: usize| self.slots[i].map_or(0, |a| a.base);
        order.sort_unstable_by(|&a, &b| match (after(base(a), base(b)), after(base(b), base(a))) {
            (true, _) => core::cmp::Ordering::Greater,
            (_, true) => core::cmp::Ordering::Less,
            _ => core::cmp::Ordering::Equal,
        });
        order
    }

    /// The buffer of the oldest frame in progress.
    fn oldest(&self) -> Option<usize> {
        (0..N).filter(|&i| self.slots[i].is_some()).reduce(|a, b| match (self.slots[a], self.slots[b]) {
            (Some(x), Some(y)) if after(x.base, y.base) => b,
            _ => a,
        })
    }

    fn take(&mut self, now: Instant, datagram: &[u8], deliver: &mut impl FnMut(ReceivedFrame<'_>)) -> Verdict {
        let packet = match self.parse(datagram) {
            Ok(p) => p,
            Err(why) => return Verdict::Ignored(why),
        };
        match self.media_ssrc {
            None => self.media_ssrc = Some(packet.ssrc),
            Some(s) if s != packet.ssrc => return Verdict::Ignored(Ignored::Ssrc),
            Some(_) => {}
        }
        let base = packet.seq.wrapping_sub(packet.row as u32);
        let slot = match (0..N).find(|&i| self.slots[i].is_some_and(|a| a.timestamp == packet.timestamp)) {
            Some(i) => i,
            None => {
                if self.delivered_base.is_some_and(|d| !after(base, d))
                    || self.newest_base.is_some_and(|n| !after(base, n))
                {
                    return Verdict::Late;
                }
                self.begin(now, packet.timestamp, base, deliver)
            }
        };
        self.place(slot, now, &packet)
    }

    /// Start a frame whose row 0 is `base`, newer than every frame so far;
    /// returns its buffer.
    fn begin(&mut self, now: Instant, timestamp: u32, base: u32, deliver: &mut impl FnMut(ReceivedFrame<'_>)) -> usize {
        let mut lost_before = 0;
        if let Some(newest) = self.newest_base {
            let jump = base.wrapping_sub(newest);
            if jump >= RESYNC_JUMP {
                self.counts.resyncs += 1;
            } else {
                lost_before = (jump / u32::from(ROWS)).saturating_sub(1);
                self.counts.lost += u64::from(lost_before);
            }
        }
        self.newest_base = Some(base);
        for i in 0..N {
            if self.slots[i].is_some_and(|a| a.closed.is_none()) {
                self.close(i, now);
            }
        }
        let free_buffer = |r: &Self| (0..N).find(|&i| i != r.last_delivered && r.slots[i].is_none());
        if free_buffer(self).is_none() {
            // One frame more than the buffers hold: the oldest waits no
            // longer (its buffer then keeps it, and the last one's is free).
            self.settle(now, true, deliver);
        }
        // Handing the oldest over freed the buffer it replaced (were that
        // not so, the oldest frame's buffer is the one to take).
        let free = free_buffer(self).or_else(|| self.oldest()).unwrap_or((self.last_delivered + 1) % N);
        self.slots[free] = Some(Assembly {
            timestamp,
            base,
            received: Rows::default(),
            nacked: Rows::default(),
            repaired: false,
            lost_before,
            last_packet: now,
            closed: None,
        });
        free
    }

    fn place(&mut self, slot: usize, now: Instant, packet: &RowIn<'_>) -> Verdict {
        let y = packet.row;
        let Some(a) = self.slots[slot].as_mut() else {
            return Verdict::Late;
        };
        if a.received.has(y) {
            return Verdict::Duplicate;
        }
        a.received.set(y);
        a.last_packet = now;
        if a.nacked.has(y) {
            a.repaired = true;
            self.counts.rows_repaired += 1;
            // Every row a NACK brought is a sample: a NACK's rows come in a
            // burst whose tail is what the next NACK must not overtake, so
            // the estimate goes halfway up to a longer sample at once and
            // an eighth of the way down to a shorter one.
            if let Some(asked) = a.closed.and_then(|c| c.asked_at) {
                let sample = now.saturating_duration_since(asked);
                self.repair_delay = Some(match self.repair_delay {
                    None => sample,
                    Some(d) if sample > d => (d + sample) / 2,
                    Some(d) => (d * 7 + sample) / 8,
                });
            }
        }
        let close = packet.marker && a.closed.is_none();
        let row = y * ROW_BYTES..(y + 1) * ROW_BYTES;
        self.buffers[slot].as_mut()[row].copy_from_slice(packet.pixels);
        if close {
            self.close(slot, now);
        }
        Verdict::Accepted
    }

    /// Copy row `y` of the frame handed over last into buffer `to`.
    fn fill_row(&mut self, to: usize, y: usize) {
        let row = y * ROW_BYTES..(y + 1) * ROW_BYTES;
        let (from, to) = (self.last_delivered, to);
        if from == to {
            return;
        }
        // Two distinct elements of the array, borrowed apart.
        let (low, high) = self.buffers.split_at_mut(from.max(to));
        let (src, dst) = if from < to { (&low[from], &mut high[0]) } else { (&high[0], &mut low[to]) };
        dst.as_mut()[row.clone()].copy_from_slice(&src.as_ref()[row]);
    }

    /// The sender is done with the frame in `slot`: ask for what is missing.
    fn close(&mut self, slot: usize, now: Instant) {
        let rounds = self.nack_interval() * u32::from(self.config.max_nacks);
        let wait = self.config.repair_wait.max(rounds.min(MAX_REPAIR_WAIT));
        if let Some(a) = self.slots[slot].as_mut() {
            a.closed = Some(Closing { give_up: now + wait, next_nack: now, nacks_sent: 0, asked_at: None });
        }
    }

    /// Hand over finished frames, oldest first; with `force`, the oldest
    /// frame in progress is finished whatever its state.
    fn settle(&mut self, now: Instant, mut force: bool, deliver: &mut impl FnMut(ReceivedFrame<'_>)) {
        while let Some(i) = self.oldest() {
            let Some(a) = self.slots[i] else { break };
            let given_up = a.closed.is_some_and(|c| now >= c.give_up);
            let whole = a.received.is_full();
            if !(force || given_up || whole) {
                break;
            }
            if force && !given_up && !whole {
                self.counts.crowded_out += 1;
            }
            force = false;
            self.finish(i, deliver);
        }
    }

    fn finish(&mut self, slot: usize, deliver: &mut impl FnMut(ReceivedFrame<'_>)) {
        let Some(a) = self.slots[slot].take() else { return };
        let missing = ROWS - a.received.count();
        for y in (0..ROW_COUNT).filter(|&y| !a.received.has(y)) {
            self.fill_row(slot, y);
        }
        let quality = match (missing, a.repaired) {
            (0, false) => Quality::Exact,
            (0, true) => Quality::Repaired,
            _ => Quality::Damaged,
        };
        match quality {
            Quality::Exact => self.counts.exact += 1,
            Quality::Repaired => self.counts.repaired += 1,
            Quality::Damaged => self.counts.damaged += 1,
        }
        self.counts.rows_filled += u64::from(missing);
        self.last_delivered = slot;
        self.delivered_base = Some(a.base);
        deliver(ReceivedFrame {
            timestamp: a.timestamp,
            quality,
            missing_rows: missing,
            lost_before: a.lost_before,
            repaired: a.received.and(&a.nacked),
            pixels: &self.buffers[slot].as_ref()[..FRAME_BYTES],
        });
    }

    /// The fields of a row packet as [`crate::camera::wire::rtp`] writes it.
    fn parse<'d>(&self, d: &'d [u8]) -> Result<RowIn<'d>, Ignored> {
        let (Some(h), Some(pixels)) = (d.first_chunk::<HEADER_BYTES>(), d.get(HEADER_BYTES..PACKET_BYTES)) else {
            return Err(Ignored::Short);
        };
        let be16 = |i: usize| u16::from_be_bytes([h[i], h[i + 1]]);
        let be32 = |i: usize| u32::from_be_bytes([h[i], h[i + 1], h[i + 2], h[i + 3]]);
        if h[0] >> 6 != 2 {
            return Err(Ignored::Version);
        }
        if h[1] & 0x7f != self.config.payload_type {
            return Err(Ignored::PayloadType);
        }
        // No CSRCs, no extension; one line of one row at offset 0.
        let line = be16(16);
        if h[0] & 0x1f != 0 || usize::from(be16(14)) != ROW_BYTES || line >= ROWS || be16(18) != 0 {
            return Err(Ignored::Layout);
        }
        Ok(RowIn {
            marker: h[1] & 0x80 != 0,
            timestamp: be32(4),
            ssrc: be32(8),
            seq: u32::from(be16(12)) << 16 | u32::from(be16(2)),
            row: usize::from(line),
            pixels,
        })
    }
}

/// Write FCI entry `(pid, blp)` at `at`; returns the end. Two frames
/// never need more than [`MAX_NACK_BYTES`]; past it the entry is dropped.
fn put_entry(out: &mut [u8; MAX_NACK_BYTES], at: usize, (pid, blp): (u32, u16)) -> usize {
    if at + 4 > out.len() {
        return at;
    }
    out[at..at + 2].copy_from_slice(&(pid as u16).to_be_bytes());
    out[at + 2..at + 4].copy_from_slice(&blp.to_be_bytes());
    at + 4
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::packetiser::Packetiser;
    use crate::camera::wire::rtcp::NackRequests;
    use crate::camera::wire::rtp::RowPacket;

    const SSRC: u32 = 0x1234_5678;
    const OURS: u32 = 0xc11e_0001;

    /// The sender: frames numbered by the crate's own packetiser.
    struct Sender {
        p: Packetiser,
        frame: u64,
    }

    impl Sender {
        fn new(first_seq: u32) -> Sender {
            Sender { p: Packetiser::new(SSRC, first_seq, 0x4000_0000), frame: 0 }
        }

        /// The 360 packets of the next frame, row y's pixels all
        /// `fill(frame, y)`.
        fn frame(&mut self) -> Vec<Vec<u8>> {
            let f = self.p.begin_frame(self.frame * 3_000);
            let k = self.frame;
            self.frame += 1;
            (0..ROWS)
                .map(|y| {
                    let packet = self.p.next_packet(f, y).unwrap();
                    datagram(&self.p, &packet, fill(k, y))
                })
                .collect()
        }

        /// Skip a frame: numbered and sent, but lost on the way.
        fn lose_frame(&mut self) {
            self.frame();
        }
    }

    fn datagram(p: &Packetiser, packet: &RowPacket, byte: u8) -> Vec<u8> {
        let mut d = vec![byte; PACKET_BYTES];
        p.emit(packet, &mut d).unwrap();
        d
    }

    fn fill(frame: u64, y: u16) -> u8 {
        (frame as u8).wrapping_mul(31) ^ (y as u8)
    }

    fn row_of(pixels: &[u8], y: u16) -> &[u8] {
        &pixels[usize::from(y) * ROW_BYTES..][..ROW_BYTES]
    }

    /// What the callback saw: timestamp, quality, missing rows, lost before,
    /// and the first byte of each row.
    #[derive(Debug, PartialEq)]
    struct Got {
        quality: Quality,
        missing: u16,
        lost_before: u32,
        rows: Vec<u8>,
    }

    struct Rx {
        r: Receiver<Vec<u8>, 3>,
        got: Vec<Got>,
        /// Whether every row must be one repeated byte (not for random
        /// payloads).
        check_rows: bool,
    }

    fn ms(t: u64) -> Instant {
        Instant::from_millis(t)
    }

    impl Rx {
        /// A receiver with short timings: 3 NACKs 15 ms apart, 50 ms of
        /// waiting (what these tests' times are written for).
        fn new() -> Rx {
            let config = ReceiverConfig {
                nack_interval: Duration::from_millis(15),
                max_nacks: 3,
                repair_wait: Duration::from_millis(50),
                ..ReceiverConfig::new(OURS)
            };
            Rx::with(config)
        }

        fn with(config: ReceiverConfig) -> Rx {
            // Two frames in progress, the last handed over kept.
            let r = Receiver::new(config, core::array::from_fn(|_| vec![0; FRAME_BYTES])).unwrap();
            Rx { r, got: vec![], check_rows: true }
        }

        fn feed(&mut self, t: u64, d: &[u8]) -> Verdict {
            let (got, check) = (&mut self.got, self.check_rows);
            self.r.receive(ms(t), d, |f| got.push(capture(f, check)))
        }

        fn feed_all<'a>(&mut self, t: u64, ds: impl IntoIterator<Item = &'a Vec<u8>>) {
            for d in ds {
                self.feed(t, d);
            }
        }

        fn poll(&mut self, t: u64) {
            let (got, check) = (&mut self.got, self.check_rows);
            self.r.poll(ms(t), |f| got.push(capture(f, check)));
        }

        fn nack(&mut self, t: u64) -> Option<Vec<u8>> {
            let mut out = [0u8; MAX_NACK_BYTES];
            self.r.write_nack(ms(t), &mut out).map(|n| out[..n].to_vec())
        }
    }

    fn capture(f: ReceivedFrame<'_>, check_rows: bool) -> Got {
        assert_eq!(f.pixels.len(), FRAME_BYTES);
        // Every row must be one byte repeated: no row is torn.
        for y in (0..ROWS).filter(|_| check_rows) {
            let r = row_of(f.pixels, y);
            assert!(r.iter().all(|&b| b == r[0]), "row {y} torn");
        }
        Got {
            quality: f.quality,
            missing: f.missing_rows,
            lost_before: f.lost_before,
            rows: (0..ROWS).map(|y| row_of(f.pixels, y)[0]).collect(),
        }
    }

    fn rows(frame: u64) -> Vec<u8> {
        (0..ROWS).map(|y| fill(frame, y)).collect()
    }

    fn exact(frame: u64) -> Got {
        Got { quality: Quality::Exact, missing: 0, lost_before: 0, rows: rows(frame) }
    }

    /// The sequence numbers a NACK asks for, as the sender reads it.
    fn asked(nack: &[u8], highest: u32) -> Vec<u32> {
        NackRequests::new(nack, SSRC, Some(highest)).with_limit(u16::MAX).collect()
    }

    #[test]
    fn frames_in_order_arrive_exact() {
        let (mut s, mut rx) = (Sender::new(1_000), Rx::new());
        for k in 0..3 {
            let f = s.frame();
            rx.feed_all(k * 10, &f);
            assert_eq!(rx.nack(k * 10), None);
        }
        assert_eq!(rx.got, [exact(0), exact(1), exact(2)]);
        assert_eq!(rx.r.counts().exact, 3);
        assert_eq!(rx.r.counts().packets, 1_080);
        assert_eq!(rx.r.deadline(), None);
        assert_eq!(row_of(rx.r.last_frame(), 7)[0], fill(2, 7));
    }

    #[test]
    fn reordered_rows_and_frames_overlapping_are_still_exact() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let (mut a, b) = (s.frame(), s.frame());
        a.swap(100, 200);
        // The marker comes before rows 357 and 358, which come after frame
        // 1's first rows.
        let (a_head, a_tail) = (a[..357].to_vec(), a[357..359].to_vec());
        rx.feed_all(0, &a_head);
        rx.feed(0, &a[359]);
        rx.feed_all(1, &b[..5]);
        assert_eq!(rx.got, []);
        rx.feed_all(1, &a_tail);
        assert_eq!(rx.got, [exact(0)], "complete before any NACK was written");
        rx.feed_all(2, &b[5..]);
        assert_eq!(rx.got, [exact(0), exact(1)]);
    }

    #[test]
    fn duplicates_are_dropped_once_counted() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let f = s.frame();
        for d in &f {
            assert_eq!(rx.feed(0, d), Verdict::Accepted);
            assert_eq!(rx.feed(0, d), if rx.got.is_empty() { Verdict::Duplicate } else { Verdict::Late });
        }
        assert_eq!(rx.got, [exact(0)]);
        assert_eq!((rx.r.counts().duplicates, rx.r.counts().late), (359, 1));
    }

    #[test]
    fn a_lost_row_is_asked_for_and_repaired() {
        let (mut s, mut rx) = (Sender::new(5_000), Rx::new());
        let f = s.frame();
        for (y, d) in f.iter().enumerate() {
            if y != 42 {
                rx.feed(0, d);
            }
        }
        assert_eq!(rx.r.deadline(), Some(ms(0)), "the marker closed it: a NACK is due");
        let nack = rx.nack(0).unwrap();
        assert_eq!(nack.len(), 16);
        assert_eq!(&nack[..12], [0x81, 205, 0, 3, 0xc1, 0x1e, 0, 1, 0x12, 0x34, 0x56, 0x78]);
        assert_eq!(asked(&nack, s.p.highest_seq().unwrap()), [5_042]);
        assert_eq!(rx.nack(1), None, "the next one waits for the interval");
        rx.feed(3, &f[42]);
        assert_eq!(rx.got, [Got { quality: Quality::Repaired, ..exact(0) }]);
        assert_eq!(rx.r.counts().repaired, 1);
        assert_eq!(rx.r.deadline(), None);
    }

    #[test]
    fn a_row_never_repaired_is_the_previous_frames_after_the_retries() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let f0 = s.frame();
        rx.feed_all(0, &f0);
        let f1 = s.frame();
        for (y, d) in f1.iter().enumerate() {
            if y != 7 && y != 8 {
                rx.feed(20, d);
            }
        }
        let highest = s.p.highest_seq().unwrap();
        let mut nacks = vec![];
        let mut t = 20;
        loop {
            if let Some(n) = rx.nack(t) {
                assert_eq!(asked(&n, highest), [367, 368]);
                nacks.push(t);
            }
            rx.poll(t);
            if rx.got.len() == 2 {
                break;
            }
            t = rx.r.deadline().unwrap().millis();
        }
        assert_eq!(nacks, [20, 35, 50], "three NACKs, 15 ms apart");
        assert_eq!(t, 70, "given up 50 ms after the marker");
        let mut expected = rows(1);
        expected[7] = fill(0, 7);
        expected[8] = fill(0, 8);
        assert_eq!(rx.got[1], Got { quality: Quality::Damaged, missing: 2, lost_before: 0, rows: expected });
        assert_eq!(rx.feed(71, &f1[7]), Verdict::Late);
        let c = rx.r.counts();
        assert_eq!((c.exact, c.damaged, c.nacks, c.rows_nacked, c.rows_filled), (1, 1, 3, 6, 2));
    }

    /// On a path whose repairs take 80 ms, asking again every 15 ms spends
    /// every NACK before the first answer can come (a lost resend is then
    /// never asked for): once a repair was seen, NACKs for a frame are
    /// twice the repair delay apart, and the frame waits for all of them.
    #[test]
    fn on_a_slow_path_nacks_are_spaced_by_the_repair_delay_and_the_wait_grows() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let f0 = s.frame();
        rx.feed_all(0, f0.iter().enumerate().filter(|&(y, _)| y != 5).map(|(_, d)| d));
        assert!(rx.nack(0).is_some());
        rx.feed(80, &f0[5]);
        assert_eq!(rx.r.repair_delay(), Some(Duration::from_millis(80)));
        let f1 = s.frame();
        rx.feed_all(100, f1.iter().enumerate().filter(|&(y, _)| y != 7).map(|(_, d)| d));
        let mut nacks = vec![];
        let mut t = 100;
        loop {
            if rx.nack(t).is_some() {
                nacks.push(t);
            }
            rx.poll(t);
            if rx.got.len() == 2 {
                break;
            }
            t = rx.r.deadline().expect("a frame waits").millis();
        }
        assert_eq!(nacks, [100, 260, 420], "160 ms apart, not 15");
        assert_eq!(t, 100 + 3 * 160, "given up after three rounds, not 50 ms");
    }

    #[test]
    fn a_damaged_frame_keeps_the_previous_row_though_the_next_frame_wrote_it() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let (f0, f1, f2) = (s.frame(), s.frame(), s.frame());
        rx.feed_all(0, &f0);
        rx.feed_all(10, f1.iter().enumerate().filter(|&(y, _)| y != 7).map(|(_, d)| d));
        // Frame 2 goes into frame 0's buffer, row 7 included, before frame
        // 1 gives up.
        rx.feed_all(12, &f2[..100]);
        assert_eq!(rx.got.len(), 1);
        rx.poll(60);
        let mut expected = rows(1);
        expected[7] = fill(0, 7);
        assert_eq!(rx.got[1], Got { quality: Quality::Damaged, missing: 1, lost_before: 0, rows: expected });
        rx.feed_all(61, &f2[100..]);
        assert_eq!(rx.got[2], exact(2));
    }

    #[test]
    fn a_third_frame_gives_up_on_the_oldest_and_order_is_kept() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let (f0, f1, f2) = (s.frame(), s.frame(), s.frame());
        rx.feed_all(0, &f0[1..]);
        rx.feed_all(1, &f1);
        assert_eq!(rx.got, [], "frame 1 is whole but waits for frame 0");
        rx.feed(2, &f2[0]);
        let mut expected = rows(0);
        expected[0] = 0; // before the first frame: the buffer's zeros
        assert_eq!(rx.got, [Got { quality: Quality::Damaged, missing: 1, lost_before: 0, rows: expected }, exact(1)]);
        rx.feed_all(3, &f2[1..]);
        assert_eq!(rx.got[2], exact(2));
    }

    /// With more buffers a frame waits for its repairs while newer frames
    /// arrive whole (a board that renders the next frames before it reads
    /// the NACK): seven in progress with eight buffers, where three
    /// buffers give the frame up at its third successor's first packet.
    #[test]
    fn more_buffers_keep_a_frame_waiting_for_its_repairs_while_newer_ones_come() {
        fn run<const N: usize>() -> (Vec<(Quality, bool)>, ReceiverCounts) {
            let mut s = Sender::new(0);
            let config = ReceiverConfig {
                nack_interval: Duration::from_millis(15),
                max_nacks: 3,
                repair_wait: Duration::from_millis(500),
                ..ReceiverConfig::new(OURS)
            };
            let mut r: Receiver<Vec<u8>, N> =
                Receiver::new(config, core::array::from_fn(|_| vec![0; FRAME_BYTES])).unwrap();
            let frames: Vec<Vec<Vec<u8>>> = (0..7).map(|_| s.frame()).collect();
            let mut got = vec![];
            let mut keep = |f: ReceivedFrame<'_>| got.push((f.quality, f.repaired.contains(5)));
            for (y, d) in frames[0].iter().enumerate().filter(|&(y, _)| y != 5) {
                r.receive(ms(y as u64 / 100), d, &mut keep);
            }
            let mut nack = [0u8; MAX_NACK_BYTES];
            assert!(r.write_nack(ms(4), &mut nack).is_some(), "row 5 asked for");
            for (k, f) in frames.iter().enumerate().skip(1) {
                for d in f {
                    r.receive(ms(4 + k as u64), d, &mut keep);
                }
            }
            // The repair comes after the six newer frames.
            r.receive(ms(20), &frames[0][5], &mut keep);
            (got, r.counts())
        }
        let (got, counts) = run::<8>();
        assert_eq!(got[0], (Quality::Repaired, true), "frame 0 waited for its row 5");
        assert_eq!(got.len(), 7);
        assert!(got[1..].iter().all(|&g| g == (Quality::Exact, false)), "{got:?}");
        assert_eq!((counts.rows_repaired, counts.damaged), (1, 0));
        let (got, counts) = run::<3>();
        assert_eq!(got[0], (Quality::Damaged, false), "three buffers gave frame 0 up");
        assert_eq!((counts.damaged, counts.late), (1, 1), "and its repair came late");
    }

    /// A repair that comes twice (asked for twice) arrives after its frame
    /// was handed over: late, it opens nothing and asks for nothing (a
    /// client that reopened the frame asked for its 359 other rows until
    /// it gave it up: 16,939 NACKed packets the board no longer had).
    #[test]
    fn a_row_of_a_finished_frame_opens_nothing_and_asks_for_nothing() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let f0 = s.frame();
        rx.feed_all(0, f0.iter().enumerate().filter(|&(y, _)| y != 17).map(|(_, d)| d));
        assert!(rx.nack(0).is_some());
        rx.feed(5, &f0[17]);
        assert_eq!(rx.got[0].quality, Quality::Repaired);
        assert_eq!(rx.feed(6, &f0[17]), Verdict::Late, "the second copy of the repair");
        rx.poll(1_000);
        assert_eq!(rx.nack(1_000), None);
        assert_eq!((rx.got.len(), rx.r.counts().late, rx.r.counts().damaged), (1, 1, 0));
    }

    /// A frame given up stays given up when its rows come later, however
    /// many frames were handed over since (frames are told apart by their
    /// sequence numbers, not a memory of timestamps).
    #[test]
    fn a_frame_given_up_stays_given_up_and_old_rows_are_late_at_any_frame_rate() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let f0 = s.frame();
        rx.feed_all(0, f0.iter().enumerate().filter(|&(y, _)| y != 5).map(|(_, d)| d));
        rx.poll(1_000);
        assert_eq!(rx.got[0].quality, Quality::Damaged);
        assert_eq!(rx.feed(1_001, &f0[5]), Verdict::Late);
        for k in 0..40u64 {
            let f = s.frame();
            rx.feed_all(1_002 + k, &f);
        }
        assert_eq!(rx.got.len(), 41);
        assert_eq!(rx.feed(2_000, &f0[5]), Verdict::Late, "a row of a frame long handed over");
        assert_eq!(rx.nack(2_000), None);
        assert_eq!(rx.r.counts().late, 2);
    }

    /// Every repaired row is a sample of the repair delay: the estimate
    /// goes halfway up to a longer sample at once (a NACK's rows come in a
    /// burst whose tail the next NACK must not overtake), an eighth of the
    /// way down to a shorter one.
    #[test]
    fn the_repair_delay_follows_the_tail_of_a_nack_s_rows() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let f0 = s.frame();
        rx.feed_all(0, f0.iter().enumerate().filter(|&(y, _)| !(10..12).contains(&y)).map(|(_, d)| d));
        assert!(rx.nack(0).is_some());
        rx.feed(30, &f0[10]);
        assert_eq!(rx.r.repair_delay(), Some(Duration::from_millis(30)));
        rx.feed(90, &f0[11]);
        assert_eq!(rx.r.repair_delay(), Some(Duration::from_millis(60)), "halfway up to 90");
        let f1 = s.frame();
        rx.feed_all(1_000, f1.iter().enumerate().filter(|&(y, _)| y != 3).map(|(_, d)| d));
        assert!(rx.nack(1_000).is_some());
        rx.feed(1_040, &f1[3]);
        assert_eq!(rx.r.repair_delay(), Some(Duration::from_micros(57_500)), "an eighth of the way down to 40");
        assert_eq!(rx.got.len(), 2);
    }

    #[test]
    fn whole_frames_lost_are_counted() {
        let (mut s, mut rx) = (Sender::new(0xfff0), Rx::new());
        let f0 = s.frame();
        rx.feed_all(0, &f0);
        s.lose_frame();
        s.lose_frame();
        let f3 = s.frame();
        rx.feed_all(100, &f3[2..]); // and its first two rows
        rx.poll(200);
        assert_eq!(rx.r.counts().lost, 2);
        assert_eq!(rx.got[1].lost_before, 2);
        assert_eq!(rx.got[1].quality, Quality::Damaged);
        assert_eq!(&rx.got[1].rows[..3], [fill(0, 0), fill(0, 1), fill(3, 2)]);
    }

    #[test]
    fn sequence_numbers_wrap_at_65536_and_at_2_pow_32() {
        for first in [0xff00u32, 0xffff_ff00] {
            let (mut s, mut rx) = (Sender::new(first), Rx::new());
            let f0 = s.frame();
            // Rows 255 and 256 straddle the wrap; 300 is after it.
            let lost = [250usize, 255, 256, 300];
            rx.feed_all(0, f0.iter().enumerate().filter(|(y, _)| !lost.contains(y)).map(|(_, d)| d));
            let nack = rx.nack(0).unwrap();
            let expected: Vec<u32> = lost.iter().map(|&y| first.wrapping_add(y as u32)).collect();
            assert_eq!(asked(&nack, s.p.highest_seq().unwrap()), expected);
            assert_eq!(nack.len(), 12 + 2 * 4, "250 + 255 + 256 in one entry's BLP, 300 in another");
            for &y in &lost {
                rx.feed(1, &f0[y]);
            }
            let f1 = s.frame();
            rx.feed_all(2, &f1);
            assert_eq!(rx.got, [Got { quality: Quality::Repaired, ..exact(0) }, exact(1)], "first {first:#x}");
        }
    }

    #[test]
    fn many_missing_rows_in_two_frames_fit_one_nack() {
        let (mut s, mut rx) = (Sender::new(77), Rx::new());
        let (f0, f1) = (s.frame(), s.frame());
        // Every other row of frame 0 past row 1, only the marker of frame 1.
        rx.feed_all(0, f0.iter().step_by(2));
        rx.feed(0, &f1[359]);
        let nack = rx.nack(0).unwrap();
        let mut expected: Vec<u32> = (0..360).filter(|y| y % 2 == 1).map(|y| 77 + y).collect();
        expected.extend((0..359).map(|y| 77 + 360 + y));
        let got = asked(&nack, s.p.highest_seq().unwrap());
        assert_eq!(got, expected);
        assert!(nack.len() <= MAX_NACK_BYTES);
    }

    #[test]
    fn a_lost_marker_closes_the_frame_after_a_quiet_wait() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let f0 = s.frame();
        rx.feed_all(0, &f0[..359]);
        assert_eq!(rx.nack(0), None, "still open");
        assert_eq!(rx.r.deadline(), Some(ms(50)));
        rx.poll(50);
        assert_eq!(asked(&rx.nack(50).unwrap(), 359), [359]);
        rx.feed(51, &f0[359]);
        assert_eq!(rx.got, [Got { quality: Quality::Repaired, ..exact(0) }]);
    }

    #[test]
    fn by_default_a_frame_sent_in_slow_runs_is_not_asked_for_before_its_rows_come() {
        // A board rendering in software (or sending to four viewers) sends
        // a frame in runs with pauses of a hundred milliseconds and more.
        let (mut s, mut rx) = (Sender::new(0), Rx::with(ReceiverConfig::new(OURS)));
        let f0 = s.frame();
        for (k, run) in f0.chunks(32).enumerate() {
            rx.feed_all(200 * k as u64, run);
            rx.poll(200 * k as u64 + 199);
            assert_eq!(rx.nack(200 * k as u64 + 199), None, "run {k}: nothing asked for yet");
        }
        assert_eq!(rx.got, [exact(0)]);
    }

    #[test]
    fn strays_and_garbage_are_ignored() {
        let (mut s, mut rx) = (Sender::new(0), Rx::new());
        let f0 = s.frame();
        let good = &f0[3];
        let mut cases: Vec<(Vec<u8>, Ignored)> = vec![
            (vec![], Ignored::Short),
            (good[..PACKET_BYTES - 1].to_vec(), Ignored::Short),
            (vec![0x80; 12], Ignored::Short),
        ];
        let mut edit = |at: usize, byte: u8, why| {
            let mut d = good.clone();
            d[at] = byte;
            cases.push((d, why));
        };
        edit(0, 0x40, Ignored::Version);
        edit(0, 0x81, Ignored::Layout); // a CSRC
        edit(0, 0x90, Ignored::Layout); // an extension
        edit(1, 97, Ignored::PayloadType);
        edit(15, 0, Ignored::Layout); // line length
        edit(16, 0x02, Ignored::Layout); // line 3 + 512
        edit(16, 0x80, Ignored::Layout); // the field bit
        edit(18, 0x80, Ignored::Layout); // a continuation
        edit(19, 0x01, Ignored::Layout); // an offset
        for (d, why) in &cases {
            assert_eq!(rx.feed(0, d), Verdict::Ignored(*why));
        }
        assert_eq!(rx.r.media_ssrc(), None, "nothing was taken yet");
        rx.feed_all(0, &f0);
        let mut other = s.frame()[0].clone();
        other[8] ^= 1;
        assert_eq!(rx.feed(1, &other), Verdict::Ignored(Ignored::Ssrc));
        assert_eq!(rx.got, [exact(0)]);
        assert_eq!(rx.r.counts().ignored, cases.len() as u64 + 1);
    }

    #[test]
    fn short_buffers_are_refused() {
        let r = Receiver::new(ReceiverConfig::new(1), [vec![0; FRAME_BYTES], vec![0; FRAME_BYTES - 1]]);
        assert_eq!(r.err(), Some(BufferTooShort { needed: FRAME_BYTES }));
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            failure_persistence: None, cases: 64, ..proptest::test_runner::Config::default()
        })]

        /// Any loss, duplication and reordering of three frames, then the
        /// receiver left alone: three frames out in order, none torn.
        #[test]
        fn any_mangling_hands_over_frames_in_order(
            drops in proptest::collection::vec(0usize..1_080, 0..40),
            dups in proptest::collection::vec(0usize..1_080, 0..40),
            swaps in proptest::collection::vec((0usize..1_080, 0usize..1_080), 0..40),
        ) {
            let mut s = Sender::new(0xfffe_ff00);
            let mut all: Vec<Vec<u8>> = (0..3).flat_map(|_| s.frame()).collect();
            for &(a, b) in &swaps {
                all.swap(a, b);
            }
            let mut keep: Vec<&Vec<u8>> = all.iter().enumerate().filter(|(i, _)| !drops.contains(i)).map(|(_, d)| d).collect();
            for &d in &dups {
                keep.push(&all[d]);
            }
            let mut rx = Rx::new();
            for (i, d) in keep.iter().enumerate() {
                rx.feed(i as u64 / 100, d);
                let _ = rx.nack(i as u64 / 100);
            }
            rx.poll(1_000);
            rx.poll(2_000);
            let c = rx.r.counts();
            proptest::prop_assert!(rx.got.len() <= 3);
            proptest::prop_assert_eq!(c.exact + c.repaired + c.damaged, rx.got.len() as u64);
            if drops.is_empty() && swaps.is_empty() {
                proptest::prop_assert_eq!(c.exact, 3);
            }
        }

        #[test]
        fn random_datagrams_never_panic(ds in proptest::collection::vec(proptest::collection::vec(proptest::num::u8::ANY, 0..1_500), 0..20),
                                        patch in proptest::collection::vec(proptest::num::u8::ANY, 20)) {
            let mut rx = Rx::new();
            rx.check_rows = false;
            for (i, mut d) in ds.into_iter().enumerate() {
                if i % 2 == 0 {
                    // Half look like the stream's packets from the header on.
                    d.resize(PACKET_BYTES, 0);
                    d[..20].copy_from_slice(&patch);
                    d[0] = 0x80;
                    d[1] = (d[1] & 0x80) | 96;
                    d[14..16].copy_from_slice(&1_440u16.to_be_bytes());
                    d[16] &= 0x01;
                    d[18..20].fill(0);
                }
                rx.feed(i as u64 * 7, &d);
                let _ = rx.nack(i as u64 * 7);
                rx.poll(i as u64 * 7 + 3);
            }
        }
    }
}
