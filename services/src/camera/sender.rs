//! The network camera's RTP sender: what [`crate::camera::rtsp`]'s actions set
//! going. One [`Stream`] per playing session draws frames from a
//! [`SlotSource`] (the frame ring), paces them at the session's rate,
//! numbers their rows with a [`Packetiser`], hands each row's packet to
//! the caller's [`RtpSink`], answers NACKs from the repair window, and
//! sends RTCP sender reports.
//!
//! Sans-IO like the rest of the crate: the sink sends (a std socket on the
//! host, a two-buffer DMA descriptor on the board), the caller supplies the
//! time and the datagrams. A packet names its row by frame slot and row
//! number; whether the sink copies the row or points the MAC at it is its
//! business, so the same sender runs on both.
//!
//! # Frames, slots and repair
//!
//! A frame is begun ([`FrameSource::begin`]) when it is due (`fps=N`: every
//! 1/N s; `fps=max`: as soon as the one before is sent), with the light
//! [`StreamSpec::light_at`] the stream's media time. Its rows go out as
//! they land; when the last has gone the frame is ended, but every packet
//! stays in the stream's [`FrameRepairWindow`] for the repair hold
//! ([`repair_hold`]) counted from the frame's last row (a receiver asks
//! only after the marker, and a frame rendered in software on the
//! emulated board takes longer than the hold to go out), and a slot that any window holds must not be
//! rendered into ([`Camera::held`], [`FrameRing::set_held`]). A NACK's
//! packets are sent again from there, unchanged.
//!
//! [`FrameRing::set_held`]: crate::frames::FrameRing::set_held

use core::net::IpAddr;
use core::time::Duration;

use model::Light;

use crate::camera::repair::FrameRepairWindow;
use crate::camera::rtcp::{self, write_sdes_cname, NackRequests, ReportTimer, SenderReport, SENDER_REPORT_BYTES};
use crate::camera::rtp::{self, FrameStamp, Packetiser, RowPacket};
use crate::camera::rtsp::{Action, SessionId, StreamSpec, MAX_SESSIONS};
use crate::frames::{FrameEngine, FrameMemory, FrameRing, FrameSource, ROWS};
use crate::time::Instant;

/// Frames in numbered slots that stay readable after [`FrameSource::end`]
/// while held: what a stream can resend from.
pub trait SlotSource: FrameSource<Frame = usize> {
    /// Keep the slots of `mask` (bit `i`: slot `i`) out of reuse, in
    /// addition to any other pins, replacing the previous mask.
    fn set_held(&mut self, mask: u32);
}

/// Where a stream's packets go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Destination {
    /// The client's address (the one that set the session up).
    pub addr: IpAddr,
    /// Its RTP port.
    pub rtp_port: u16,
    /// Its RTCP port.
    pub rtcp_port: u16,
}

/// The caller's way out.
pub trait RtpSink {
    /// Send the packet of `packet`: its 20 header bytes are
    /// [`Packetiser::emit`] of it, its payload row `packet.row` of frame
    /// slot `slot`. `false` if it cannot be sent now (nothing was sent;
    /// it is offered again later).
    fn send_row(&mut self, to: &Destination, packetiser: &Packetiser, packet: &RowPacket, slot: usize) -> bool;

    /// Send a run of `count` packets: `first` and the ones after it
    /// ([`RowPacket::nth`]), rows of slot `slot`. Returns how many went,
    /// from the front (the rest are offered again later). The default
    /// sends them one by one; a sink can do the per-run work once.
    fn send_rows(
        &mut self,
        to: &Destination,
        packetiser: &Packetiser,
        first: &RowPacket,
        count: u16,
        slot: usize,
    ) -> u16 {
        for k in 0..count {
            if !self.send_row(to, packetiser, &first.nth(k), slot) {
                return k;
            }
        }
        count
    }

    /// Send an RTCP datagram to the client's RTCP port; `false` if it
    /// cannot be sent now (it is dropped: reports are periodic).
    fn send_rtcp(&mut self, to: &Destination, datagram: &[u8]) -> bool;

    /// Whether the camera should return to its caller now rather than
    /// ask the source for more rows: something arrived that the caller
    /// must take in (a NACK, on the board). Asked after each run of rows.
    fn should_yield(&mut self) -> bool {
        false
    }
}

/// How long sent packets stay ready for a NACK: two frame times at the
/// stream's rate, and never less than [`MIN_REPAIR_HOLD`] (a receiver asks
/// only once a frame's marker arrived, and a slow link or host adds its
/// round trip).
pub fn repair_hold(spec: &StreamSpec) -> Duration {
    spec.fps.interval().map_or(MIN_REPAIR_HOLD, |i| (i * 2).max(MIN_REPAIR_HOLD))
}

/// The shortest repair hold: a second, for a NACK that crosses a slow or
/// lossy path, or waits behind a long poll (the emulated board renders a
/// frame on its CPU in one). It costs little: a window keeps at most
/// [`crate::camera::repair::REPAIR_ENTRIES`] packets (under three frames) whatever the hold.
pub const MIN_REPAIR_HOLD: Duration = Duration::from_secs(1);

/// The CNAME in the sender reports' SDES (RFC 3550 section 6.5.1).
pub const CNAME: &[u8] = b"raytracer@board";

/// What a stream has done, for logs and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Frames whose every row was sent.
    pub frames: u32,
    /// Row packets sent (first sends).
    pub packets: u32,
    /// Row packets sent again for a NACK.
    pub resent: u32,
    /// NACKed packets no longer (or never) in the repair window.
    pub unrepairable: u32,
    /// Frames the source failed (not sent whole).
    pub failed: u32,
}

/// The frame being sent.
#[derive(Clone, Copy, Debug)]
struct Current {
    slot: usize,
    stamp: FrameStamp,
    next_row: u16,
    /// The extended sequence number of its first row.
    first_seq: u32,
}

/// One session's sender state (its repair window lives in the [`Camera`],
/// so a stream is small enough to make on any stack).
#[derive(Clone, Debug)]
pub struct Stream {
    session: SessionId,
    spec: StreamSpec,
    to: Destination,
    packetiser: Packetiser,
    live: Light,
    /// Sending (`PLAY`) or holding (`PAUSE`).
    playing: bool,
    /// Media time (90 kHz ticks since the first `PLAY`) at `resumed_at`.
    media_at_resume: u64,
    resumed_at: Instant,
    /// When the next frame is due (`fps=N`).
    due: Instant,
    current: Option<Current>,
    /// NACKed packets not sent again yet (the sink was full): they go
    /// before new rows, which a receiver waits for less.
    repairs: heapless::Deque<u32, MAX_PENDING_REPAIRS>,
    reports: ReportTimer,
    stats: StreamStats,
}

/// Rows a stream gathers into one run while the source keeps landing
/// them (each run costs the sink one route lookup, the MAC one set of
/// descriptor control words and counts, the repair window one check):
/// 32 rows, 46 KB, 0.37 ms at 1 Gbit/s, the MAC's transmit ring. 16 cost
/// the emulated board some 4,800 instructions a frame more.
pub const MIN_RUN: u16 = 32;

/// NACKed packets a stream queues for resending (more are not repairable:
/// more than a frame's worth asked for at once is a receiver that lost
/// the stream, not a few rows).
pub const MAX_PENDING_REPAIRS: usize = 512;

impl Stream {
    /// The session.
    pub fn session(&self) -> SessionId {
        self.session
    }

    /// Where its packets go.
    pub fn destination(&self) -> Destination {
        self.to
    }

    /// What it has done.
    pub fn stats(&self) -> StreamStats {
        self.stats
    }

    /// The packetiser (SSRC, sequence numbers).
    pub fn packetiser(&self) -> &Packetiser {
        &self.packetiser
    }

    /// Whether it is sending.
    pub fn playing(&self) -> bool {
        self.playing
    }

    /// Media time at `now`, in 90 kHz ticks.
    fn media_ticks(&self, now: Instant) -> u64 {
        if self.playing {
            self.media_at_resume + rtp::ticks(now).saturating_sub(rtp::ticks(self.resumed_at))
        } else {
            self.media_at_resume
        }
    }

    /// When it next wants [`Camera::poll`]: `None` while it waits for
    /// something other than time (a slot, a row, the sink), or is paused.
    fn deadline(&self) -> Option<Instant> {
        match (self.playing, self.current, self.spec.fps.interval()) {
            (true, None, Some(_)) => Some(self.due),
            _ => None,
        }
    }
}

/// The RTP senders of up to `N` sessions, with a repair window each.
pub struct Camera<const N: usize = MAX_SESSIONS> {
    streams: [Option<Stream>; N],
    windows: [FrameRepairWindow; N],
    /// Where RTCP reports are built.
    rtcp: [u8; RTCP_BYTES],
}

/// A sender report and an SDES CNAME chunk, the compound packet sent.
const RTCP_BYTES: usize = SENDER_REPORT_BYTES + rtcp::sdes_cname_bytes(CNAME.len());

impl<const N: usize> Default for Camera<N> {
    fn default() -> Self {
        Camera::new()
    }
}

impl<const N: usize> Camera<N> {
    /// No streams. `const`, so a board can keep it in a `static` (its
    /// repair windows are some 32 KiB each).
    pub const fn new() -> Camera<N> {
        Camera {
            streams: [const { None }; N],
            windows: [const { FrameRepairWindow::new(MIN_REPAIR_HOLD) }; N],
            rtcp: [0; RTCP_BYTES],
        }
    }

    /// The streams.
    pub fn streams(&self) -> impl Iterator<Item = &Stream> {
        self.streams.iter().flatten()
    }

    /// The stream of `session`.
    pub fn stream(&self, session: SessionId) -> Option<&Stream> {
        self.streams().find(|s| s.session == session)
    }

    fn index(&self, session: SessionId) -> Option<usize> {
        self.streams.iter().position(|s| s.as_ref().is_some_and(|s| s.session == session))
    }

    /// Packets `session`'s repair window holds (what a NACK can get back).
    pub fn repairable(&self, session: SessionId) -> usize {
        self.index(session).map_or(0, |i| self.windows[i].len())
    }

    /// The frame slots the repair windows hold (bit `i`: slot `i`); give it
    /// to the source ([`SlotSource::set_held`]) after every call that
    /// sends or forgets.
    pub fn held(&self) -> u32 {
        self.windows.iter().fold(0, |m, w| m | w.held())
    }

    /// Carry out an action of the RTSP server at `now`. Returns, for a
    /// [`Action::Pause`], the position to report back with
    /// [`crate::camera::rtsp::Server::set_position`]: the sequence number and
    /// timestamp the next packet would have had.
    pub fn apply<S: SlotSource>(&mut self, action: Action, now: Instant, source: &mut S) -> Option<(u16, u32)> {
        match action {
            Action::Play { session, spec, client_addr, rtp_port, rtcp_port, ssrc, seq, rtptime, live } => {
                match self.index(session) {
                    Some(i) => {
                        // Resume: numbering and media time go on.
                        if let Some(s) = self.streams[i].as_mut() {
                            s.live = live;
                            if !s.playing {
                                s.playing = true;
                                s.resumed_at = now;
                                s.due = now;
                            }
                        }
                    }
                    None => {
                        let i = self.streams.iter().position(Option::is_none)?;
                        self.windows[i].clear(repair_hold(&spec));
                        self.streams[i] = Some(Stream {
                            session,
                            spec,
                            to: Destination { addr: client_addr, rtp_port, rtcp_port },
                            packetiser: Packetiser::new(ssrc, u32::from(seq), rtptime),
                            live,
                            playing: true,
                            media_at_resume: 0,
                            resumed_at: now,
                            due: now,
                            current: None,
                            repairs: heapless::Deque::new(),
                            reports: ReportTimer::new(now),
                            stats: StreamStats::default(),
                        });
                    }
                }
                None
            }
            Action::Pause { session } => {
                let i = self.index(session)?;
                let s = self.streams[i].as_mut()?;
                if let Some(c) = s.current.take() {
                    // The rest of the frame is not sent; its rows so far
                    // stay repairable.
                    source.end(c.slot);
                    self.windows[i].restart_hold(c.first_seq, now);
                    s.stats.failed += 1;
                }
                s.media_at_resume = s.media_ticks(now) + 1;
                s.playing = false;
                let next = s.packetiser.highest_seq().map_or(0, |h| h.wrapping_add(1));
                Some((next as u16, s.packetiser.timestamp_at(s.media_at_resume)))
            }
            Action::Stop { session } | Action::Timeout { session } => {
                self.forget(session, source);
                None
            }
            Action::SetLight { session, light } => {
                if let Some(s) = self.index(session).and_then(|i| self.streams[i].as_mut()) {
                    s.live = light;
                }
                None
            }
        }
    }

    /// Stop `session`'s stream and let its slots go.
    pub fn forget<S: SlotSource>(&mut self, session: SessionId, source: &mut S) {
        if let Some(i) = self.index(session) {
            if let Some(c) = self.streams[i].take().and_then(|s| s.current) {
                source.end(c.slot);
            }
            self.windows[i].clear(MIN_REPAIR_HOLD);
            source.set_held(self.held());
        }
    }

    /// Do what is due at `now`: begin frames, send the rows that landed,
    /// send reports, expire repair packets. `wall` is the sender reports'
    /// clock (NTP format, [`rtcp::ntp_timestamp`]): the wall clock where
    /// there is one, else the time since start. Returns whether anything
    /// was sent or begun (poll again at once if so).
    pub fn poll<S: SlotSource, K: RtpSink>(&mut self, now: Instant, wall: u64, source: &mut S, sink: &mut K) -> bool {
        let mut progress = false;
        for i in 0..N {
            let Some(s) = self.streams[i].as_mut() else { continue };
            let window = &mut self.windows[i];
            // Packets expire by time only between frames: a frame's hold
            // starts when its last row went (`restart_hold`), however long
            // it took; meanwhile the window's size bounds what it keeps.
            if s.current.is_none() && window.expire(now).released != 0 {
                progress = true;
            }
            if s.playing && s.reports.poll(now) {
                let sr = SenderReport::now(&s.packetiser, wall, s.media_ticks(now));
                let n = sr.write(&mut self.rtcp).unwrap_or(0);
                if let Ok(m) = write_sdes_cname(s.packetiser.ssrc(), CNAME, &mut self.rtcp[n..]) {
                    let _ = sink.send_rtcp(&s.to, &self.rtcp[..n + m]);
                }
            }
            if !s.repairs.is_empty() {
                let before = s.stats.resent;
                let done = s.send_repairs(window, sink);
                progress |= s.stats.resent != before;
                if !done {
                    continue;
                }
            }
            if !s.playing {
                continue;
            }
            if s.current.is_none() {
                let interval = s.spec.fps.interval();
                if interval.is_some() && now < s.due {
                    continue;
                }
                let media = s.media_ticks(now);
                let light = s.spec.light_at(Duration::from_micros(media * 100 / 9), s.live);
                match source.begin(&light) {
                    Ok(Some(slot)) => {
                        let stamp = s.packetiser.begin_frame(media);
                        let first_seq = s.packetiser.highest_seq().map_or(0, |h| h.wrapping_add(1));
                        s.current = Some(Current { slot, stamp, next_row: 0, first_seq });
                        if let Some(iv) = interval {
                            // Keep the rate; after a stall, start afresh.
                            s.due = if now.saturating_duration_since(s.due) > iv { now + iv } else { s.due + iv };
                        }
                        progress = true;
                    }
                    Ok(None) => continue,
                    Err(_) => {
                        s.stats.failed += 1;
                        if let Some(iv) = interval {
                            s.due = now + iv;
                        }
                        continue;
                    }
                }
            }
            let Some(mut c) = s.current else { continue };
            // The rows landed, asking again while the source lands more:
            // rows go in runs of up to MIN_RUN gathered while they keep
            // coming, so the per-run work (the sink's route, the window's
            // bookkeeping, the calls) is paid once a run, not once a row.
            // A run goes as soon as the source has nothing more right now,
            // so no row waits for a later one that is not on its way.
            let mut failed = false;
            let mut seen = c.next_row;
            loop {
                let ready = match source.rows_ready(c.slot) {
                    Ok(r) => r.min(ROWS),
                    Err(_) => {
                        failed = true;
                        break;
                    }
                };
                let landing = ready > seen;
                seen = ready;
                let waiting = ready.saturating_sub(c.next_row);
                if waiting > 0 && (waiting >= MIN_RUN || ready == ROWS || !landing) {
                    let Ok(first) = s.packetiser.peek_packet(c.stamp, c.next_row) else { break };
                    let sent = sink.send_rows(&s.to, &s.packetiser, &first, waiting, c.slot);
                    // The numbers peeked: nothing else numbers between.
                    s.packetiser.advance(sent);
                    let _ = window.record_run(now, c.slot, first, sent);
                    s.stats.packets += u32::from(sent);
                    c.next_row += sent;
                    progress |= sent > 0;
                    // Between runs: something received (a NACK) goes first.
                    if sent < waiting || sink.should_yield() {
                        break;
                    }
                }
                if c.next_row == ROWS || !landing {
                    break;
                }
            }
            if failed {
                source.end(c.slot);
                window.restart_hold(c.first_seq, now);
                s.current = None;
                s.stats.failed += 1;
                progress = true;
                continue;
            }
            if c.next_row == ROWS {
                source.end(c.slot);
                window.restart_hold(c.first_seq, now);
                s.current = None;
                s.stats.frames += 1;
            } else {
                s.current = Some(c);
            }
        }
        if progress {
            source.set_held(self.held());
        }
        progress
    }

    /// An RTCP datagram arrived from `from:port`: resend what its generic
    /// NACKs ask for, from the repair window of the stream whose client
    /// that is (the one with that RTCP port, else the address's first).
    /// Datagrams from any other address are ignored (RTCP is taken only
    /// from the session's client). Returns the session it was for.
    pub fn rtcp_received<K: RtpSink>(
        &mut self,
        from: IpAddr,
        port: u16,
        datagram: &[u8],
        sink: &mut K,
    ) -> Option<SessionId> {
        let is_from = |s: &Option<Stream>, exact: bool| {
            s.as_ref().is_some_and(|s| s.to.addr == from && (!exact || s.to.rtcp_port == port))
        };
        let i = (self.streams.iter().position(|s| is_from(s, true)))
            .or_else(|| self.streams.iter().position(|s| is_from(s, false)))?;
        let s = self.streams[i].as_mut()?;
        let window = &self.windows[i];
        for seq in NackRequests::new(datagram, s.packetiser.ssrc(), s.packetiser.highest_seq()) {
            if window.lookup(seq).is_none() || s.repairs.push_back(seq).is_err() {
                s.stats.unrepairable += 1;
            }
        }
        s.send_repairs(window, sink);
        Some(s.session)
    }

    /// When [`poll`](Self::poll) next has something to do by the clock
    /// alone (a frame due, a report, a repair packet to expire), if no
    /// stream waits for rows or slots; the caller polls at least this
    /// often, and whenever the source may have progressed.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.streams().flat_map(|s| [s.deadline(), s.playing.then(|| s.reports.deadline())]).flatten().min()
    }

    /// Whether any stream is sending a frame (waiting for its rows or the
    /// sink): the caller should poll again soon.
    pub fn busy(&self) -> bool {
        self.streams().any(|s| s.current.is_some() || !s.repairs.is_empty())
    }
}

impl Stream {
    /// Resend the NACKed packets still waiting, oldest request first, while
    /// the sink takes them; whether none is left.
    fn send_repairs<K: RtpSink>(&mut self, window: &FrameRepairWindow, sink: &mut K) -> bool {
        while let Some(&seq) = self.repairs.front() {
            match window.lookup(seq) {
                Some(r) => {
                    if !sink.send_row(&self.to, &self.packetiser, &r.packet, r.slot) {
                        return false;
                    }
                    self.stats.resent += 1;
                }
                // Left the window while it waited.
                None => self.stats.unrepairable += 1,
            }
            self.repairs.pop_front();
        }
        true
    }
}

impl<M: FrameMemory, E: FrameEngine<M>, const SLOTS: usize> SlotSource for FrameRing<M, E, SLOTS> {
    fn set_held(&mut self, mask: u32) {
        FrameRing::set_held(self, mask)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::rtsp::{Fps, Stream as Kind};
    use model::{FRAME_BYTES, ROW_BYTES};
    use std::cell::RefCell;
    use std::rc::Rc;

    /// Frame slots in host memory that the test's sink can read too.
    #[derive(Clone)]
    struct Shared(Rc<RefCell<Vec<u8>>>);

    impl FrameMemory for Shared {
        fn slot_address(&self, slot: usize) -> u32 {
            (slot * FRAME_BYTES) as u32
        }
        fn read_row(&mut self, slot: usize, y: u16, offset: usize, out: &mut [u8]) {
            let at = slot * FRAME_BYTES + usize::from(y) * ROW_BYTES + offset;
            out.copy_from_slice(&self.0.borrow()[at..at + out.len()]);
        }
        fn write_row(&mut self, slot: usize, y: u16, row: &[u8; ROW_BYTES]) {
            let at = slot * FRAME_BYTES + usize::from(y) * ROW_BYTES;
            self.0.borrow_mut()[at..at + ROW_BYTES].copy_from_slice(row);
        }
    }

    /// An engine that lands a recognisable frame for each light ([`pattern_row`]),
    /// `step` rows per progress call.
    struct Pattern {
        step: u16,
        rows: u16,
        /// No more rows land than this (the test moves it).
        cap: Rc<core::cell::Cell<u16>>,
    }

    fn pattern_row(light: &Light, y: u16) -> [u8; ROW_BYTES] {
        let [x, y0, z] = light.raw();
        let base = (x ^ y0.rotate_left(8) ^ z.rotate_left(16)) as usize + usize::from(y);
        core::array::from_fn(|i| (base + i) as u8)
    }

    impl FrameEngine<Shared> for Pattern {
        type Error = &'static str;
        fn start(&mut self, mem: &mut Shared, slot: usize, light: &Light) -> Result<(), &'static str> {
            for y in 0..ROWS {
                mem.write_row(slot, y, &pattern_row(light, y));
            }
            self.rows = 0;
            Ok(())
        }
        fn progress(&mut self, _: &mut Shared) -> Result<u16, &'static str> {
            self.rows = (self.rows + self.step).min(ROWS).min(self.cap.get().max(self.rows));
            Ok(self.rows)
        }
    }

    type Ring = FrameRing<Shared, Pattern, 4>;

    /// A packet as a receiver sees it.
    #[derive(Clone, Debug, PartialEq)]
    struct Received {
        to: Destination,
        header: [u8; rtp::HEADER_BYTES],
        row: Vec<u8>,
    }

    impl Received {
        fn seq16(&self) -> u16 {
            u16::from_be_bytes([self.header[2], self.header[3]])
        }
        fn ext_seq(&self) -> u32 {
            u32::from(u16::from_be_bytes([self.header[12], self.header[13]])) << 16 | u32::from(self.seq16())
        }
        fn timestamp(&self) -> u32 {
            u32::from_be_bytes(self.header[4..8].try_into().unwrap())
        }
        fn marker(&self) -> bool {
            self.header[1] & 0x80 != 0
        }
        fn line(&self) -> u16 {
            u16::from_be_bytes([self.header[16], self.header[17]]) & 0x7fff
        }
    }

    /// A sink reading rows out of the ring's memory (as hps-sim does),
    /// taking at most `room` row packets before it refuses.
    struct Sink {
        mem: Shared,
        room: usize,
        rows: Vec<Received>,
        rtcp: Vec<(Destination, Vec<u8>)>,
        /// `should_yield` says yes once this many rows went (`None`: never).
        yield_at: Option<usize>,
        yield_asked: usize,
    }

    impl RtpSink for Sink {
        fn send_row(&mut self, to: &Destination, p: &Packetiser, packet: &RowPacket, slot: usize) -> bool {
            if self.room == 0 {
                return false;
            }
            self.room -= 1;
            let mut header = [0; rtp::HEADER_BYTES];
            p.emit(packet, &mut header).unwrap();
            let mut row = vec![0; ROW_BYTES];
            self.mem.read_row(slot, packet.row, 0, &mut row);
            self.rows.push(Received { to: *to, header, row });
            true
        }
        fn send_rtcp(&mut self, to: &Destination, datagram: &[u8]) -> bool {
            self.rtcp.push((*to, datagram.to_vec()));
            true
        }
        fn should_yield(&mut self) -> bool {
            self.yield_asked += 1;
            self.yield_at.is_some_and(|n| self.rows.len() >= n)
        }
    }

    const CLIENT: IpAddr = IpAddr::V4(core::net::Ipv4Addr::new(10, 0, 2, 2));
    const SSRC: u32 = 0x1234_5678;

    fn light(x: f64) -> Light {
        Light::from_world(x, 4.0, -2.0).unwrap()
    }

    fn play(session: u64, stream: Kind, fps: Fps) -> Action {
        Action::Play {
            session: SessionId(session),
            spec: StreamSpec { stream, fps },
            client_addr: CLIENT,
            rtp_port: 6000,
            rtcp_port: 6001,
            ssrc: SSRC,
            seq: 65_500,
            rtptime: 0xffff_ff00,
            live: light(0.5),
        }
    }

    fn t(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    fn rig(step: u16) -> (Box<Camera<2>>, Ring, Sink) {
        let mem = Shared(Rc::new(RefCell::new(vec![0; 4 * FRAME_BYTES])));
        let ring = FrameRing::new(mem.clone(), Pattern { step, rows: 0, cap: Rc::new(core::cell::Cell::new(ROWS)) });
        let sink = Sink { mem, room: usize::MAX, rows: vec![], rtcp: vec![], yield_at: None, yield_asked: 0 };
        (Box::new(Camera::new()), ring, sink)
    }

    /// Poll at `now` until nothing progresses.
    fn settle(camera: &mut Camera<2>, now: Instant, ring: &mut Ring, sink: &mut Sink) {
        for _ in 0..10_000 {
            if !camera.poll(now, 0, ring, sink) {
                return;
            }
        }
        panic!("the camera never settled");
    }

    /// A generic NACK (RFC 4585 section 6.2.1) for `entries` (PID, BLP).
    fn nack(media: u32, entries: &[(u16, u16)]) -> Vec<u8> {
        let words = 2 + entries.len();
        let mut d = vec![0x81, 205];
        d.extend_from_slice(&(words as u16).to_be_bytes());
        d.extend_from_slice(&0xdead_beefu32.to_be_bytes());
        d.extend_from_slice(&media.to_be_bytes());
        for (pid, blp) in entries {
            d.extend_from_slice(&pid.to_be_bytes());
            d.extend_from_slice(&blp.to_be_bytes());
        }
        d
    }

    #[test]
    fn a_frame_goes_out_row_by_row_with_one_timestamp_and_a_marker_on_the_last() {
        let (mut camera, mut ring, mut sink) = rig(100);
        let fixed = light(2.0);
        assert_eq!(camera.apply(play(1, Kind::Light(fixed), Fps::Max), t(0), &mut ring), None);
        // fps=max never settles: the window keeps 1,024 packets, so slots
        // come free for ever.
        while sink.rows.len() <= usize::from(ROWS) {
            assert!(camera.poll(t(0), 0, &mut ring, &mut sink));
        }
        let frame: Vec<_> = sink.rows.iter().take(usize::from(ROWS)).collect();
        assert_eq!(frame.len(), usize::from(ROWS));
        for (y, p) in frame.iter().enumerate() {
            assert_eq!(p.line(), y as u16);
            assert_eq!(p.row, pattern_row(&fixed, y as u16), "row {y}");
            assert_eq!(p.ext_seq(), 65_500 + y as u32, "extended numbering across the 16-bit wrap");
            assert_eq!(p.timestamp(), frame[0].timestamp());
            assert_eq!(p.marker(), y == usize::from(ROWS) - 1);
            assert_eq!(p.to, Destination { addr: CLIENT, rtp_port: 6000, rtcp_port: 6001 });
            assert_eq!(u32::from_be_bytes(p.header[8..12].try_into().unwrap()), SSRC);
        }
        assert_eq!(frame[0].timestamp(), 0xffff_ff00, "the RTP-Info rtptime");
        assert_eq!(frame[36].seq16(), 0, "the low 16 bits wrapped after 65,535");
        let next = &sink.rows[usize::from(ROWS)];
        assert_ne!(next.timestamp(), frame[0].timestamp(), "fps=max: the next frame at once, a new timestamp");
    }

    #[test]
    fn one_poll_sends_the_rows_as_they_land_until_the_sink_asks_to_yield() {
        // Two rows land per look at the source: one poll still sends the
        // whole frame, in runs, asking the sink after each.
        let (mut camera, mut ring, mut sink) = rig(2);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(30)), t(0), &mut ring);
        assert!(camera.poll(t(0), 0, &mut ring, &mut sink));
        assert_eq!(sink.rows.len(), usize::from(ROWS), "the frame in one poll");
        assert_eq!(sink.yield_asked, usize::from(ROWS.div_ceil(MIN_RUN)), "asked after each run of MIN_RUN");
        // The sink asks to yield once 100 rows went: the poll returns at
        // the end of that run (runs of MIN_RUN while rows keep landing),
        // the next one goes on where it stopped.
        sink.yield_at = Some(usize::from(ROWS) + 100);
        assert!(camera.poll(t(34), 0, &mut ring, &mut sink));
        let run = usize::from(MIN_RUN);
        assert_eq!(sink.rows.len(), usize::from(ROWS) + (100 / run + 1) * run);
        sink.yield_at = None;
        assert!(camera.poll(t(34), 0, &mut ring, &mut sink));
        assert_eq!(sink.rows.len(), 2 * usize::from(ROWS));
        let lines: Vec<u16> = sink.rows[usize::from(ROWS)..].iter().map(Received::line).collect();
        assert_eq!(lines, (0..ROWS).collect::<Vec<_>>(), "no row lost or repeated at the yield");
    }

    #[test]
    fn rows_go_out_as_soon_as_the_source_stops_landing_more() {
        let (mut camera, mut ring, mut sink) = rig(2);
        let cap = Rc::clone(&ring.engine().cap);
        cap.set(5);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Max), t(0), &mut ring);
        assert!(camera.poll(t(0), 0, &mut ring, &mut sink));
        assert_eq!(sink.rows.len(), 5, "five landed, then none: all five go, short of a run");
        cap.set(40);
        assert!(camera.poll(t(0), 0, &mut ring, &mut sink));
        assert_eq!(sink.rows.len(), 40);
        assert!(!camera.poll(t(0), 0, &mut ring, &mut sink), "nothing new");
    }

    #[test]
    fn a_paced_stream_begins_a_frame_per_interval_at_its_media_time() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(30)), t(0), &mut ring);
        settle(&mut camera, t(0), &mut ring, &mut sink);
        assert_eq!(sink.rows.len(), usize::from(ROWS), "one frame at once");
        settle(&mut camera, t(20), &mut ring, &mut sink);
        assert_eq!(sink.rows.len(), usize::from(ROWS), "none before 1/30 s");
        assert_eq!(camera.next_deadline(), Some(t(33)));
        settle(&mut camera, t(34), &mut ring, &mut sink);
        assert_eq!(sink.rows.len(), 2 * usize::from(ROWS));
        let ts: Vec<u32> = sink.rows.iter().step_by(usize::from(ROWS)).map(Received::timestamp).collect();
        assert_eq!(ts[1].wrapping_sub(ts[0]), 34 * 90, "90 kHz media time");
    }

    #[test]
    fn an_orbit_renders_each_frame_at_its_media_time_and_resumes_after_pause() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        let spec = StreamSpec::parse("rtsp://h/orbit?period=4&fps=1").unwrap();
        camera.apply(play(1, spec.stream, spec.fps), t(0), &mut ring);
        settle(&mut camera, t(0), &mut ring, &mut sink);
        let pos = camera.apply(Action::Pause { session: SessionId(1) }, t(1_000), &mut ring);
        let next_seq = sink.rows.last().unwrap().seq16().wrapping_add(1);
        assert_eq!(pos, Some((next_seq, 0xffff_ff00u32.wrapping_add(90_000 + 1))));
        let before = sink.rows.len();
        settle(&mut camera, t(5_000), &mut ring, &mut sink);
        assert_eq!(sink.rows.len(), before, "paused: nothing sent");
        camera.apply(play(1, spec.stream, spec.fps), t(5_000), &mut ring);
        camera.poll(t(5_000), 0, &mut ring, &mut sink);
        let resumed = &sink.rows[before];
        assert_eq!(resumed.seq16(), next_seq, "numbering goes on");
        assert_eq!(resumed.timestamp(), 0xffff_ff00u32.wrapping_add(90_001), "media time skips the pause");
        let expected = spec.light_at(Duration::from_micros(90_001 * 100 / 9), light(0.0));
        assert_eq!(resumed.row, pattern_row(&expected, 0), "the light of the media time");
    }

    #[test]
    fn a_refusing_sink_delays_rows_without_gaps_in_the_numbering() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(10)), t(0), &mut ring);
        sink.room = 7;
        settle(&mut camera, t(0), &mut ring, &mut sink);
        assert_eq!(sink.rows.len(), 7);
        assert!(camera.busy());
        sink.room = usize::MAX;
        settle(&mut camera, t(1), &mut ring, &mut sink);
        let seqs: Vec<u32> = sink.rows.iter().map(Received::ext_seq).collect();
        assert_eq!(seqs, (65_500..65_500 + u32::from(ROWS)).collect::<Vec<_>>());
        assert!(sink.rows.last().unwrap().marker());
    }

    #[test]
    fn a_nack_gets_the_same_packets_again_and_only_from_the_client() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(10)), t(0), &mut ring);
        settle(&mut camera, t(0), &mut ring, &mut sink);
        let sent = sink.rows.clone();
        // Lost: 65,535 and 0 (across the wrap) and 3.
        let req = nack(SSRC, &[(65_535, 0b1), (3, 0)]);
        let stranger = IpAddr::V4(core::net::Ipv4Addr::new(10, 0, 2, 9));
        assert_eq!(camera.rtcp_received(stranger, 6001, &req, &mut sink), None);
        assert_eq!(sink.rows.len(), sent.len(), "a stranger's NACK is ignored");
        assert_eq!(camera.rtcp_received(CLIENT, 6001, &nack(0x999, &[(3, 0)]), &mut sink), Some(SessionId(1)));
        assert_eq!(sink.rows.len(), sent.len(), "another SSRC's NACK asks for nothing");
        assert_eq!(camera.rtcp_received(CLIENT, 6001, &req, &mut sink), Some(SessionId(1)));
        let again: Vec<u32> = sink.rows[sent.len()..].iter().map(Received::ext_seq).collect();
        assert_eq!(again, [65_535, 65_536, 65_539]);
        for r in &sink.rows[sent.len()..] {
            let original = sent.iter().find(|o| o.ext_seq() == r.ext_seq()).unwrap();
            assert_eq!(r, original, "byte for byte the original packet");
        }
        assert_eq!(camera.stream(SessionId(1)).unwrap().stats().resent, 3);
    }

    #[test]
    fn a_nack_arriving_while_the_next_frame_goes_out_is_still_answered() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(5)), t(0), &mut ring);
        settle(&mut camera, t(0), &mut ring, &mut sink);
        sink.room = 72;
        settle(&mut camera, t(200), &mut ring, &mut sink);
        assert_eq!(sink.rows.len(), 432);
        let row17 = sink.rows[17].clone();
        sink.room = usize::MAX;
        camera.rtcp_received(CLIENT, 6001, &nack(SSRC, &[(row17.seq16(), 0)]), &mut sink);
        assert_eq!(camera.stream(SessionId(1)).unwrap().stats().unrepairable, 0);
        assert_eq!(sink.rows.last(), Some(&row17));
    }

    #[test]
    fn repairs_the_sink_cannot_take_wait_and_go_before_new_rows() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(10)), t(0), &mut ring);
        settle(&mut camera, t(0), &mut ring, &mut sink);
        let sent = sink.rows.len();
        sink.room = 2;
        // Ask for 10 rows: 2 go at once, 8 wait.
        camera.rtcp_received(CLIENT, 6001, &nack(SSRC, &[(65_500, 0x1ff)]), &mut sink);
        assert_eq!(sink.rows.len(), sent + 2);
        assert!(camera.busy());
        sink.room = usize::MAX;
        settle(&mut camera, t(100), &mut ring, &mut sink);
        let again: Vec<u32> = sink.rows[sent..sent + 10].iter().map(Received::ext_seq).collect();
        assert_eq!(again, (65_500..65_510).collect::<Vec<_>>(), "all ten, before the next frame's rows");
        assert_eq!(sink.rows[sent + 10].line(), 0, "then the next frame");
        assert_eq!(camera.stream(SessionId(1)).unwrap().stats().resent, 10);
    }

    #[test]
    fn a_slowly_rendered_frame_stays_repairable_for_the_hold_after_its_last_row() {
        // One row per poll: the frame takes 3.6 s to go out at 10 ms a row,
        // far beyond the 400 ms hold of fps=5.
        let (mut camera, mut ring, mut sink) = rig(1);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(5)), t(0), &mut ring);
        let mut ms = 0;
        while sink.rows.len() < usize::from(ROWS) {
            camera.poll(t(ms), 0, &mut ring, &mut sink);
            ms += 10;
        }
        let first = sink.rows[0].clone();
        settle(&mut camera, t(ms + 350), &mut ring, &mut sink);
        let before = sink.rows.len();
        camera.rtcp_received(CLIENT, 6001, &nack(SSRC, &[(first.seq16(), 0)]), &mut sink);
        assert_eq!(sink.rows.len(), before + 1, "row 0, sent 3.6 s ago, is still repairable");
        assert_eq!(sink.rows[before], first);
    }

    #[test]
    fn sent_frames_hold_their_slot_for_the_repair_time_then_let_it_go() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(10)), t(0), &mut ring);
        settle(&mut camera, t(0), &mut ring, &mut sink);
        let slot0 = 0;
        assert_eq!(camera.held(), 1 << slot0);
        assert_eq!(ring.held(), 1 << slot0, "the ring knows");
        assert_eq!(ring.free_slots(), 3);
        // 10 fps: two frame times are 200 ms, the hold at least a second.
        settle(&mut camera, t(950), &mut ring, &mut sink);
        assert_eq!(camera.held() & 1, 1, "still repairable");
        settle(&mut camera, t(1_050), &mut ring, &mut sink);
        assert_eq!(camera.held() & 1, 0, "released after the hold");
        assert_eq!(ring.held() & 1, 0);
        let before = sink.rows.len();
        assert_eq!(camera.rtcp_received(CLIENT, 6001, &nack(SSRC, &[(65_500, 0)]), &mut sink), Some(SessionId(1)));
        assert_eq!(sink.rows.len(), before, "expired: not resent");
        assert_eq!(camera.stream(SessionId(1)).unwrap().stats().unrepairable, 1);
    }

    #[test]
    fn teardown_and_timeout_let_every_slot_go_and_a_live_light_moves() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        camera.apply(play(1, Kind::Live, Fps::Rate(10)), t(0), &mut ring);
        camera.apply(play(2, Kind::Light(light(1.0)), Fps::Rate(10)), t(0), &mut ring);
        assert_eq!(camera.apply(play(3, Kind::Live, Fps::Rate(10)), t(0), &mut ring), None);
        assert_eq!(camera.streams().count(), 2, "a camera of two");
        settle(&mut camera, t(0), &mut ring, &mut sink);
        let moved = light(-1.5);
        camera.apply(Action::SetLight { session: SessionId(1), light: moved }, t(1), &mut ring);
        settle(&mut camera, t(101), &mut ring, &mut sink);
        let live_rows: Vec<_> = sink.rows.iter().filter(|r| r.to.addr == CLIENT && r.line() == 0).collect();
        assert!(live_rows.iter().any(|r| r.row == pattern_row(&moved, 0)), "a frame with the new light");
        camera.apply(Action::Stop { session: SessionId(1) }, t(2), &mut ring);
        camera.apply(Action::Timeout { session: SessionId(2) }, t(2), &mut ring);
        assert_eq!(camera.streams().count(), 0);
        assert_eq!(camera.held(), 0);
        assert_eq!(ring.held(), 0);
        assert_eq!(ring.free_slots(), 4, "nothing left in use");
    }

    #[test]
    fn sender_reports_go_to_the_rtcp_port_while_playing() {
        let (mut camera, mut ring, mut sink) = rig(ROWS);
        camera.apply(play(1, Kind::Light(light(1.0)), Fps::Rate(1)), t(0), &mut ring);
        settle(&mut camera, t(0), &mut ring, &mut sink);
        settle(&mut camera, t(1_500), &mut ring, &mut sink);
        assert!(sink.rtcp.is_empty());
        settle(&mut camera, t(2_500), &mut ring, &mut sink);
        assert_eq!(sink.rtcp.len(), 1);
        let (to, d) = &sink.rtcp[0];
        assert_eq!(to.rtcp_port, 6001);
        assert_eq!(d[1], rtcp::RTCP_SR);
        assert_eq!(u32::from_be_bytes(d[4..8].try_into().unwrap()), SSRC);
        assert_eq!(u32::from_be_bytes(d[20..24].try_into().unwrap()), 2 * u32::from(ROWS), "packets so far");
        assert_eq!(d[SENDER_REPORT_BYTES + 1], rtcp::RTCP_SDES);
    }

    #[test]
    fn the_software_renderer_s_frame_arrives_equal_to_the_model_s() {
        let mut bytes = vec![0; FRAME_BYTES];
        let mut ring = FrameRing::<_, _, 1>::new(
            crate::frames::SliceMemory::new(0, &mut bytes),
            crate::frames::RowEngine::new(crate::frames::rows::SoftwareRenderer),
        );
        struct Copy(Vec<(RowPacket, usize)>);
        impl RtpSink for Copy {
            fn send_row(&mut self, _: &Destination, _: &Packetiser, p: &RowPacket, slot: usize) -> bool {
                self.0.push((*p, slot));
                true
            }
            fn send_rtcp(&mut self, _: &Destination, _: &[u8]) -> bool {
                true
            }
        }
        let mut camera = Box::new(Camera::<1>::new());
        let l = light(3.0);
        camera.apply(play(1, Kind::Light(l), Fps::Rate(1)), t(0), &mut ring);
        let mut sink = Copy(vec![]);
        for _ in 0..5_000 {
            camera.poll(t(0), 0, &mut ring, &mut sink);
            if sink.0.len() == usize::from(ROWS) {
                break;
            }
        }
        assert_eq!(sink.0.len(), usize::from(ROWS));
        let rows: Vec<u16> = sink.0.iter().map(|(p, _)| p.row).collect();
        assert_eq!(rows, (0..ROWS).collect::<Vec<_>>());
        drop(ring);
        assert_eq!(bytes, model::render_frame(&l), "the slot the packets point at holds the model's frame");
    }
}
