//! Retransmission bookkeeping: which frame slot and row each recent packet
//! came from, so a NACKed packet can be sent again unchanged.

use core::time::Duration;

use super::wire::rtp::RowPacket;
use crate::time::Instant;

/// Packets a [`FrameRepairWindow`] keeps at most: two frames of 360 rows
/// and slack, a power of two like the resend log's entries, which it
/// indexes by sequence number.
pub const REPAIR_ENTRIES: usize = 1_024;

/// A [`RepairWindow`] holding the packets of at least the last two frames.
pub type FrameRepairWindow = RepairWindow<REPAIR_ENTRIES>;

/// Most frame slots a [`RepairWindow`] tracks (a 32-bit mask, like the
/// frame ring's pins).
pub const MAX_SLOTS: usize = 32;

/// A sent packet a NACK can be answered with: its header fields and where
/// its row still is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Repair {
    /// The packet's header fields, for [`Packetiser::emit`](super::packetiser::Packetiser::emit).
    pub packet: RowPacket,
    /// The frame slot holding its row.
    pub slot: usize,
}

/// How a [`RepairWindow`] call changed which frame slots it holds (bit `i`:
/// slot `i`). The caller keeps the held ones out of reuse (pins them in
/// the frame ring, together with any pins of its own) and lets the
/// released ones go.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct SlotChanges {
    /// Slots the window holds now and did not before.
    pub held: u32,
    /// Slots the window held before and no longer does.
    pub released: u32,
}

/// Why a packet was not recorded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// The slot is not below [`MAX_SLOTS`].
    BadSlot(usize),
    /// The sequence number is not newer than the newest recorded (a
    /// retransmission, which is recorded already).
    NotNewer(u32),
}

impl core::fmt::Display for RecordError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RecordError::BadSlot(s) => write!(f, "slot {s} is not below {MAX_SLOTS}"),
            RecordError::NotNewer(seq) => write!(f, "sequence number {seq} is not newer than the window's"),
        }
    }
}

/// Consecutive packets recorded together: sequence numbers, rows and
/// one slot and timestamp (a frame's rows, while nothing breaks the run).
#[derive(Clone, Copy, Debug)]
struct Run {
    /// The sequence number of its first packet.
    first: u32,
    /// Packets in it (never 0 while it is in the window).
    count: u32,
    /// The row of its first packet.
    row: u16,
    timestamp: u32,
    slot: u8,
}

impl Run {
    /// Whether `packet` from `slot` continues this run.
    fn continued_by(&self, slot: u8, packet: &RowPacket) -> bool {
        self.slot == slot
            && self.timestamp == packet.timestamp
            && packet.seq == self.first.wrapping_add(self.count)
            && u32::from(packet.row) == u32::from(self.row) + self.count
    }
}

/// Packets from `first` on (up to the next span's `first`) whose hold
/// counts from `at`.
#[derive(Clone, Copy, Debug)]
struct Span {
    first: u32,
    at: Instant,
}

/// Hold spans a [`RepairWindow`] keeps: a frame's rows share one once the
/// frame is done ([`RepairWindow::restart_hold`]), and a window holds
/// under three frames. When they run out the two oldest merge into the
/// later one's time: their packets are then held longer, never shorter.
const SPANS: usize = 8;

/// Runs a [`RepairWindow`] keeps: a frame's rows are one run (a stream's
/// numbers run on across frames, but each frame has its own timestamp),
/// so a window of two frames holds two or three. Should they run out, the
/// oldest run leaves early (its packets can no longer be repaired).
const RUNS: usize = 32;

/// Retransmission bookkeeping (RFC 4585 section 3.1's "repair"): for each
/// of the last `N` packets sent, its header fields and the frame slot and
/// row its bytes are in, so a NACKed packet ([`NackRequests`](super::wire::rtcp::NackRequests)) is sent
/// again exactly as it was (same SSRC, payload type, sequence number and
/// timestamp: RFC 4585 leaves the repair to the sender, and a plain resend
/// is what a jitter buffer without RFC 4588 takes), its row read from the
/// slot once more, zero-copy.
///
/// A slot is *held* while any of its packets is in the window: the caller
/// keeps it out of reuse meanwhile ([`FrameRing::pin`]). Packets leave the
/// window when `N` newer ones were recorded, when a new frame begins
/// ([`forget_before`](Self::forget_before)), or when they are older than
/// the hold time ([`expire`](Self::expire)), so an idle stream lets its
/// slots go. Packets are kept as runs (consecutive numbers and rows of
/// one slot and timestamp) and hold times per span of packets, not per
/// packet: recording a run, dropping a frame and restarting a frame's
/// hold each cost a few steps, not one a packet (the board sends a frame
/// in a dozen runs of up to 32 rows).
///
/// [`FrameRing::pin`]: crate::frames::FrameRing::pin
#[derive(Clone, Debug)]
pub struct RepairWindow<const N: usize> {
    /// The packets in `oldest..next` that were recorded, oldest first (a
    /// number skipped by the sender is in none).
    runs: heapless::Deque<Run, RUNS>,
    oldest: u32,
    next: u32,
    started: bool,
    held: u32,
    hold: Duration,
    /// The hold times, oldest first; the first covers `oldest` (its
    /// `first` may lie before it).
    spans: heapless::Deque<Span, SPANS>,
}

impl<const N: usize> RepairWindow<N> {
    /// An empty window keeping packets for `hold` at most (at least two
    /// frame times; it also keeps no more than `N`).
    pub const fn new(hold: Duration) -> RepairWindow<N> {
        const { assert!(N.is_power_of_two() && N <= 1 << 16, "N bounds a window of sequence numbers") };
        RepairWindow {
            runs: heapless::Deque::new(),
            oldest: 0,
            next: 0,
            started: false,
            held: 0,
            hold,
            spans: heapless::Deque::new(),
        }
    }

    /// Empty the window (a new stream) and keep packets for `hold` from now
    /// on.
    pub fn clear(&mut self, hold: Duration) {
        self.runs.clear();
        (self.oldest, self.next, self.started) = (0, 0, false);
        self.held = 0;
        self.hold = hold;
        self.spans.clear();
    }

    /// The slots the window holds (bit `i`: slot `i`).
    pub const fn held(&self) -> u32 {
        self.held
    }

    /// Whether the window holds `slot`.
    pub const fn is_held(&self, slot: usize) -> bool {
        slot < MAX_SLOTS && self.held & (1 << slot) != 0
    }

    /// Packets in the window.
    pub fn len(&self) -> usize {
        self.runs.iter().map(|r| r.count as usize).sum()
    }

    /// Whether the window holds no packet.
    pub fn is_empty(&self) -> bool {
        self.held == 0
    }

    /// Record `packet`, sent at `now` with its row from `slot`. Its
    /// sequence number must be newer than every one recorded before (at
    /// most 2^31 ahead); the oldest packets leave the window to make room.
    pub fn record(&mut self, now: Instant, slot: usize, packet: RowPacket) -> Result<SlotChanges, RecordError> {
        self.record_run(now, slot, packet, 1)
    }

    /// Record `n` packets sent at `now`: `first` and the consecutive rows
    /// after it ([`RowPacket::nth`]), all from `slot`: the same as
    /// recording each with [`record`](Self::record), in a few steps.
    pub fn record_run(
        &mut self,
        now: Instant,
        slot: usize,
        first: RowPacket,
        n: u16,
    ) -> Result<SlotChanges, RecordError> {
        let slot8 =
            u8::try_from(slot).ok().filter(|&s| usize::from(s) < MAX_SLOTS).ok_or(RecordError::BadSlot(slot))?;
        if n == 0 {
            return Ok(SlotChanges::default());
        }
        let s = first.seq;
        if !self.started {
            (self.oldest, self.next, self.started) = (s, s, true);
        } else if s.wrapping_sub(self.next) >= 1 << 31 {
            return Err(RecordError::NotNewer(s));
        }
        let before = self.held;
        let n32 = u32::from(n);
        match self.runs.back_mut() {
            Some(r) if r.continued_by(slot8, &first) => r.count += n32,
            _ => {
                if self.runs.is_full() {
                    // Never expected (module docs): the oldest run leaves.
                    if let Some(r) = self.runs.pop_front() {
                        self.oldest = r.first.wrapping_add(r.count);
                    }
                }
                let run = Run { first: s, count: n32, row: first.row, timestamp: first.timestamp, slot: slot8 };
                let _ = self.runs.push_back(run);
            }
        }
        if !Self::before(self.oldest, self.next) {
            // Nothing older is left (the first packet, or a jump past the
            // window): no span covers anything.
            self.spans.clear();
        }
        let last = s.wrapping_add(n32 - 1);
        self.next = last.wrapping_add(1);
        if self.next.wrapping_sub(self.oldest) > N as u32 {
            // Keep the newest N: last - N + 1 ..= last.
            self.oldest = last.wrapping_sub(N as u32 - 1);
        }
        // The run's packets count their hold from `now`, as recorded one
        // by one (the span of the first stands for all of them).
        let from = if self.next.wrapping_sub(s) > self.next.wrapping_sub(self.oldest) { self.oldest } else { s };
        self.hold_from(from, now);
        self.trim();
        Ok(SlotChanges { held: self.held & !before, released: before & !self.held })
    }

    /// Drop the runs' packets before `oldest`, forget the spans that
    /// covered only those, and work out the slots still held.
    fn trim(&mut self) {
        while let Some(r) = self.runs.front_mut() {
            let end = r.first.wrapping_add(r.count);
            if !Self::before(self.oldest, end) {
                self.runs.pop_front();
            } else {
                if Self::before(r.first, self.oldest) {
                    let gone = self.oldest.wrapping_sub(r.first);
                    r.first = self.oldest;
                    r.row = r.row.wrapping_add(gone as u16);
                    r.count -= gone;
                }
                break;
            }
        }
        self.drop_passed_spans();
        self.held = self.runs.iter().fold(0, |m, r| m | 1 << r.slot);
    }

    /// Whether `a` comes before `b` (sequence numbers a window apart at
    /// most, so the signed difference orders them across the wrap).
    const fn before(a: u32, b: u32) -> bool {
        (a.wrapping_sub(b) as i32) < 0
    }

    /// The packets from `from` (in the window) on count their hold from
    /// `at`.
    fn hold_from(&mut self, from: u32, at: Instant) {
        while self.spans.back().is_some_and(|b| !Self::before(b.first, from)) {
            self.spans.pop_back();
        }
        if self.spans.back().is_some_and(|b| b.at == at) {
            return;
        }
        if self.spans.is_full() {
            // Merge the two oldest into the later time (held longer).
            if let (Some(a), Some(b)) = (self.spans.pop_front(), self.spans.pop_front()) {
                let _ = self.spans.push_front(Span { first: a.first, at: b.at });
            }
        }
        let _ = self.spans.push_back(Span { first: from, at });
    }

    /// Forget the spans whose packets all left (the next span starts at or
    /// before `oldest`).
    fn drop_passed_spans(&mut self) {
        while self.spans.get(1).is_some_and(|b| !Self::before(self.oldest, b.first)) {
            self.spans.pop_front();
        }
    }

    /// Count the hold of the packets from `first` (an extended sequence
    /// number) to the newest from `now`: a frame's packets are repairable
    /// for the hold after its last row went, however long its rows took to
    /// render (a receiver asks only once the frame's marker arrived).
    pub fn restart_hold(&mut self, first: u32, now: Instant) {
        if self.next == self.oldest {
            return;
        }
        let from =
            if self.next.wrapping_sub(first) <= self.next.wrapping_sub(self.oldest) { first } else { self.oldest };
        self.hold_from(from, now);
    }

    /// Drop the packets numbered before `seq` (a new frame begins: the
    /// window keeps the frame before it and no older one, so a stream
    /// never holds more than two slots); returns the slots released.
    pub fn forget_before(&mut self, seq: u32) -> SlotChanges {
        let before = self.held;
        if self.oldest != self.next && Self::before(self.oldest, seq) {
            self.oldest = if Self::before(seq, self.next) { seq } else { self.next };
            self.trim();
        }
        SlotChanges { held: 0, released: before & !self.held }
    }

    /// Drop the packets recorded longer than the hold time before `now`;
    /// returns the slots released.
    pub fn expire(&mut self, now: Instant) -> SlotChanges {
        let before = self.held;
        self.drop_passed_spans();
        while let Some(&span) = self.spans.front() {
            if now.saturating_duration_since(span.at) < self.hold {
                break;
            }
            self.oldest = self.spans.get(1).map_or(self.next, |b| b.first);
            self.spans.pop_front();
        }
        self.trim();
        SlotChanges { held: 0, released: before & !self.held }
    }

    /// The packet numbered `seq` (an extended sequence number, as
    /// [`NackRequests`](super::wire::rtcp::NackRequests) yields them), if still in the window: resend it
    /// with [`Packetiser::emit`](super::packetiser::Packetiser::emit) and its row from the slot.
    pub fn lookup(&self, seq: u32) -> Option<Repair> {
        if Self::before(seq, self.oldest) || !Self::before(seq, self.next) {
            return None;
        }
        self.runs.iter().find_map(|r| {
            let k = seq.wrapping_sub(r.first);
            (k < r.count).then(|| Repair {
                packet: RowPacket { seq, timestamp: r.timestamp, row: r.row.wrapping_add(k as u16) },
                slot: usize::from(r.slot),
            })
        })
    }
}

/// When each recent packet was last resent to one receiver, so that a
/// packet goes again at most once per round trip however often it is
/// NACKed (a receiver, or someone spoofing one, asking again before the
/// resend can have arrived). Indexed like a [`RepairWindow`]: sequence
/// number modulo `N`.
#[derive(Clone, Debug)]
pub struct ResendLog<const N: usize> {
    /// `(seq, ms)`: packet `seq` went again at `ms` (low 32 bits of the
    /// millisecond clock).
    at: [Option<(u32, u32)>; N],
}

/// A [`ResendLog`] as long as a [`FrameRepairWindow`].
pub type FrameResendLog = ResendLog<REPAIR_ENTRIES>;

impl<const N: usize> ResendLog<N> {
    /// Nothing resent.
    pub const fn new() -> ResendLog<N> {
        ResendLog { at: [None; N] }
    }

    /// Forget everything (a new receiver).
    pub fn clear(&mut self) {
        self.at.fill(None);
    }

    /// Whether packet `seq` may go again at `now`: not resent within
    /// `round_trip` before.
    pub fn may_resend(&self, seq: u32, now: Instant, round_trip: Duration) -> bool {
        match self.at[seq as usize % N] {
            Some((s, ms)) if s == seq => {
                let since = (now.millis() as u32).wrapping_sub(ms);
                u128::from(since) >= round_trip.as_millis()
            }
            _ => true,
        }
    }

    /// How long before `now` packet `seq` last went again, if it did (and
    /// the log still remembers it).
    pub fn since(&self, seq: u32, now: Instant) -> Option<Duration> {
        match self.at[seq as usize % N] {
            Some((s, ms)) if s == seq => Some(Duration::from_millis(u64::from((now.millis() as u32).wrapping_sub(ms)))),
            _ => None,
        }
    }

    /// Packet `seq` went again at `now`.
    pub fn resent(&mut self, seq: u32, now: Instant) {
        self.at[seq as usize % N] = Some((seq, now.millis() as u32));
    }
}

impl<const N: usize> Default for ResendLog<N> {
    fn default() -> Self {
        ResendLog::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::packetiser::Packetiser;
    use crate::camera::wire::rtcp::tests::nack;
    use crate::camera::wire::rtcp::NackRequests;
    use crate::camera::wire::rtp::HEADER_BYTES;
    use crate::frames::ROWS;

    fn row(seq: u32, y: u16) -> RowPacket {
        RowPacket { seq, timestamp: 7, row: y }
    }

    const T0: Instant = Instant::from_millis(0);

    proptest::proptest! {
        /// A run recorded at once leaves the window as the same packets
        /// recorded one by one: entries, holds and what each call reported.
        #[test]
        fn a_recorded_run_equals_its_packets_recorded_one_by_one(
            runs in proptest::collection::vec((0usize..6, 0u16..400, 0u16..360), 1..12),
            start in proptest::num::u32::ANY,
        ) {
            let hold = Duration::from_secs(1);
            let (mut a, mut b) = (RepairWindow::<64>::new(hold), RepairWindow::<64>::new(hold));
            let mut seq = start;
            for (i, (slot, n, row)) in runs.into_iter().enumerate() {
                let now = Instant::from_millis(i as u64);
                let first = RowPacket { seq, timestamp: i as u32, row };
                let b_before = b.held();
                for k in 0..n {
                    b.record(now, slot, first.nth(k)).unwrap();
                }
                let run = a.record_run(now, slot, first, n).unwrap();
                proptest::prop_assert_eq!(a.held(), b.held());
                let net = SlotChanges { held: b.held() & !b_before, released: b_before & !b.held() };
                proptest::prop_assert_eq!(run, net);
                proptest::prop_assert_eq!(a.len(), b.len());
                seq = seq.wrapping_add(u32::from(n));
                for back in 0..70u32 {
                    let s = seq.wrapping_sub(back);
                    proptest::prop_assert_eq!(a.lookup(s), b.lookup(s), "seq {}", s);
                }
            }
        }
    }

    /// The window as it was before hold spans: a time per packet, every
    /// packet of a frame touched to restart its hold. The reference the
    /// span-keeping window must agree with while its spans never merge.
    #[derive(Clone, Copy, Debug)]
    struct OldEntry {
        packet: RowPacket,
        slot: u8,
        at: Instant,
    }

    #[derive(Clone, Debug)]
    struct PerPacket<const N: usize> {
        entries: [Option<OldEntry>; N],
        oldest: u32,
        next: u32,
        started: bool,
        refs: [u32; MAX_SLOTS],
        held: u32,
        hold: Duration,
    }

    impl<const N: usize> PerPacket<N> {
        pub const fn new(hold: Duration) -> PerPacket<N> {
            const { assert!(N.is_power_of_two() && N <= 1 << 16, "N indexes a ring by sequence number") };
            PerPacket { entries: [None; N], oldest: 0, next: 0, started: false, refs: [0; MAX_SLOTS], held: 0, hold }
        }

        pub const fn held(&self) -> u32 {
            self.held
        }

        pub fn record(&mut self, now: Instant, slot: usize, packet: RowPacket) -> Result<SlotChanges, RecordError> {
            let slot8 =
                u8::try_from(slot).ok().filter(|&s| usize::from(s) < MAX_SLOTS).ok_or(RecordError::BadSlot(slot))?;
            let s = packet.seq;
            if !self.started {
                (self.oldest, self.next, self.started) = (s, s, true);
            } else if s.wrapping_sub(self.next) >= 1 << 31 {
                return Err(RecordError::NotNewer(s));
            }
            let before = self.held;
            let n = N as u32;
            if s.wrapping_sub(self.oldest) >= n {
                // Keep s - N + 1 ..= s: drop what is older.
                let keep_from = s.wrapping_sub(n - 1);
                let drop = self.next.wrapping_sub(self.oldest).min(keep_from.wrapping_sub(self.oldest));
                for i in 0..drop {
                    self.remove(self.oldest.wrapping_add(i));
                }
                self.oldest = keep_from;
            }
            self.entries[s as usize % N] = Some(OldEntry { packet, slot: slot8, at: now });
            self.refs[usize::from(slot8)] += 1;
            self.held |= 1 << slot8;
            self.next = s.wrapping_add(1);
            Ok(SlotChanges { held: self.held & !before, released: before & !self.held })
        }

        fn remove(&mut self, seq: u32) {
            if let Some(e) = self.entries[seq as usize % N].take() {
                let slot = usize::from(e.slot);
                self.refs[slot] -= 1;
                if self.refs[slot] == 0 {
                    self.held &= !(1 << slot);
                }
            }
        }

        pub fn restart_hold(&mut self, first: u32, now: Instant) {
            let from =
                if self.next.wrapping_sub(first) <= self.next.wrapping_sub(self.oldest) { first } else { self.oldest };
            let mut s = from;
            while s != self.next {
                if let Some(e) = self.entries[s as usize % N].as_mut() {
                    if e.packet.seq == s {
                        e.at = now;
                    }
                }
                s = s.wrapping_add(1);
            }
        }

        pub fn expire(&mut self, now: Instant) -> SlotChanges {
            let before = self.held;
            while self.oldest != self.next {
                let idx = self.oldest as usize % N;
                if let Some(e) = self.entries[idx] {
                    if now.saturating_duration_since(e.at) < self.hold {
                        break;
                    }
                }
                self.remove(self.oldest);
                self.oldest = self.oldest.wrapping_add(1);
            }
            SlotChanges { held: 0, released: before & !self.held }
        }

        pub fn lookup(&self, seq: u32) -> Option<Repair> {
            match self.entries[seq as usize % N] {
                Some(e) if e.packet.seq == seq => Some(Repair { packet: e.packet, slot: usize::from(e.slot) }),
                _ => None,
            }
        }
    }

    proptest::proptest! {
        /// Runs, restarted holds and expiry against the per-packet window,
        /// with at most seven distinct times (so no two spans merge):
        /// the same packets, slots and releases after every step.
        #[test]
        fn the_span_window_agrees_with_a_time_per_packet(
            steps in proptest::collection::vec((0u8..3, 0usize..5, 0u16..90, 0u64..7), 1..30),
            start in proptest::num::u32::ANY,
        ) {
            let hold = Duration::from_millis(250);
            let (mut new, mut old) = (RepairWindow::<64>::new(hold), PerPacket::<64>::new(hold));
            let (mut seq, mut frame_first) = (start, start);
            let mut times: Vec<u64> = steps.iter().map(|s| s.3 * 100).collect();
            times.sort_unstable();
            for ((kind, slot, n, _), ms) in steps.into_iter().zip(times) {
                let now = Instant::from_millis(ms);
                match kind {
                    0 => {
                        let first = RowPacket { seq, timestamp: ms as u32, row: 0 };
                        let c = new.record_run(now, slot, first, n).unwrap();
                        let mut want = SlotChanges::default();
                        let before = old.held();
                        for k in 0..n {
                            old.record(now, slot, first.nth(k)).unwrap();
                        }
                        if n > 0 {
                            want = SlotChanges { held: old.held() & !before, released: before & !old.held() };
                        }
                        proptest::prop_assert_eq!(c, want);
                        seq = seq.wrapping_add(u32::from(n));
                    }
                    1 => {
                        new.restart_hold(frame_first, now);
                        old.restart_hold(frame_first, now);
                        frame_first = seq;
                    }
                    _ => proptest::prop_assert_eq!(new.expire(now), old.expire(now)),
                }
                proptest::prop_assert_eq!(new.held(), old.held());
                for back in 0..80u32 {
                    let s = seq.wrapping_sub(back);
                    proptest::prop_assert_eq!(new.lookup(s), old.lookup(s), "seq {}", s);
                }
            }
        }
    }

    #[test]
    fn the_window_holds_two_frames_and_releases_a_slot_when_its_last_row_leaves() {
        let mut w = FrameRepairWindow::new(Duration::from_secs(1));
        let mut seq = 0xffff_ff00u32; // wraps during the third frame
        let mut changes = vec![];
        for slot in [0, 1, 2] {
            for y in 0..ROWS {
                let c = w.record(T0, slot, row(seq, y)).unwrap();
                if c != SlotChanges::default() {
                    changes.push((seq.wrapping_sub(0xffff_ff00), c));
                }
                seq = seq.wrapping_add(1);
            }
        }
        assert_eq!(
            changes,
            [
                (0, SlotChanges { held: 0b001, released: 0 }),
                (360, SlotChanges { held: 0b010, released: 0 }),
                (720, SlotChanges { held: 0b100, released: 0 }),
            ],
            "1,080 packets: frame 0's rows are partly still in"
        );
        assert_eq!(w.len(), REPAIR_ENTRIES);
        assert_eq!(w.lookup(0xffff_ff00), None, "gone");
        assert_eq!(w.lookup(0xffff_ff00 + 56), Some(Repair { packet: row(0xffff_ff38, 56), slot: 0 }));
        assert_eq!(
            w.lookup(0x10),
            Some(Repair { packet: row(0x10, 272), slot: 0 }),
            "past the wrap: frame 0's row 272"
        );
        let last = seq.wrapping_sub(1);
        assert_eq!(w.lookup(last).map(|r| (r.slot, r.packet.row)), Some((2, 359)));
        // Frame 3 goes into slot 0 again once it is released: 304 rows on.
        let mut released_at = None;
        for y in 0..ROWS {
            let c = w.record(T0, 3, row(seq, y)).unwrap();
            if c.released != 0 {
                released_at = Some((y, c.released));
            }
            seq = seq.wrapping_add(1);
        }
        assert_eq!(released_at, Some((303, 0b001)), "row 359 of frame 0 left 1,024 packets later");
        assert_eq!(w.held(), 0b1110);
    }

    #[test]
    fn an_idle_window_lets_its_slots_go() {
        let mut w = RepairWindow::<8>::new(Duration::from_millis(100));
        w.record(T0, 4, row(10, 0)).unwrap();
        w.record(Instant::from_millis(50), 5, row(11, 0)).unwrap();
        assert_eq!(w.expire(Instant::from_millis(99)), SlotChanges::default());
        assert_eq!(w.expire(Instant::from_millis(100)), SlotChanges { held: 0, released: 1 << 4 });
        assert_eq!((w.lookup(10), w.held()), (None, 1 << 5));
        assert_eq!(w.expire(Instant::from_millis(10_000)), SlotChanges { held: 0, released: 1 << 5 });
        assert!(w.is_empty());
        // Numbering goes on after the expired ones.
        assert!(w.record(Instant::from_millis(10_000), 4, row(12, 1)).is_ok());
    }

    #[test]
    fn bad_records_are_refused_and_jumps_clear_the_window() {
        let mut w = RepairWindow::<8>::new(Duration::from_secs(1));
        assert_eq!(w.record(T0, 32, row(1, 0)), Err(RecordError::BadSlot(32)));
        w.record(T0, 1, row(100, 0)).unwrap();
        w.record(T0, 1, row(102, 1)).unwrap(); // 101 was never recorded
        assert_eq!(w.record(T0, 1, row(102, 1)), Err(RecordError::NotNewer(102)));
        assert_eq!(w.record(T0, 1, row(50, 1)), Err(RecordError::NotNewer(50)));
        assert_eq!((w.lookup(101), w.len()), (None, 2));
        let c = w.record(T0, 2, row(1_000_000, 0)).unwrap();
        assert_eq!(c, SlotChanges { held: 0b100, released: 0b010 });
        assert_eq!((w.lookup(100), w.lookup(102), w.len()), (None, None, 1));
    }

    #[test]
    fn a_new_frame_leaves_the_window_the_one_before_it() {
        let mut w = FrameRepairWindow::new(Duration::from_secs(1));
        for (slot, first) in [(0usize, 100u32), (1, 460), (2, 820)] {
            w.forget_before(first.wrapping_sub(360));
            w.record_run(T0, slot, row(first, 0), ROWS).unwrap();
        }
        assert_eq!(w.held(), 0b110, "frames 2 and 3; frame 1 left when 3 began");
        assert_eq!(w.lookup(459), None);
        assert!(w.lookup(460).is_some() && w.lookup(1179).is_some());
        assert_eq!(w.forget_before(1180).released, 0b110);
        assert!(w.is_empty());
    }

    #[test]
    fn a_packet_is_resent_at_most_once_a_round_trip() {
        let mut log = FrameResendLog::new();
        let rtt = Duration::from_millis(40);
        assert!(log.may_resend(7, T0, rtt));
        log.resent(7, T0);
        assert!(!log.may_resend(7, Instant::from_millis(39), rtt));
        assert!(log.may_resend(7, Instant::from_millis(40), rtt));
        assert!(log.may_resend(7 + REPAIR_ENTRIES as u32, Instant::from_millis(1), rtt), "another packet");
        assert_eq!(log.since(7, Instant::from_millis(65)), Some(Duration::from_millis(65)));
        assert_eq!(log.since(7 + REPAIR_ENTRIES as u32, Instant::from_millis(65)), None, "never resent");
    }

    #[test]
    fn a_nack_is_answered_with_the_original_packet() {
        let mut p = Packetiser::new(0x1234_5678, 0x0001_0203, 0xa000_0000);
        let mut w = FrameRepairWindow::new(Duration::from_secs(1));
        let mut sent = vec![];
        for slot in [0, 1] {
            let f = p.begin_frame(u64::from(slot as u32) * 3_000);
            for y in 0..ROWS {
                let mut h = [0u8; HEADER_BYTES];
                let packet = p.write_header(f, y, &mut h).unwrap();
                w.record(Instant::from_millis(0), slot, packet).unwrap();
                sent.push(h);
            }
        }
        let highest = p.highest_seq().unwrap();
        let lost = [5usize, 6, 359, 360, 500];
        let pid = |i: usize| (0x0001_0203 + i as u32) as u16;
        let d = nack(9, p.ssrc(), &[(pid(5), 0b1), (pid(359), 0b1), (pid(500), 0)]);
        let resent: Vec<(usize, [u8; HEADER_BYTES])> = NackRequests::new(&d, p.ssrc(), Some(highest))
            .filter_map(|seq| w.lookup(seq))
            .map(|r| {
                let mut h = [0u8; HEADER_BYTES];
                p.emit(&r.packet, &mut h).unwrap();
                (r.slot, h)
            })
            .collect();
        let expected: Vec<_> = lost.iter().map(|&i| (i / 360, sent[i])).collect();
        assert_eq!(resent, expected);
    }
}
