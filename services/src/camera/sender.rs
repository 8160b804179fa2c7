//! The network camera's RTP sender: what the RTSP server's sessions set
//! going ([`Camera`], through [`Bound`] as the server's
//! [`Streams`]).
//!
//! # Render once, send to many
//!
//! Sessions that ask for the same frames (the same light or orbit at the
//! same rate, [`StreamSpec::same_frames`]) share one *stream*: one frame
//! rendered per frame time, one SSRC and one numbering, one repair window,
//! as gst-rtsp-server's shared media and live555's reused source do. Each
//! session reaches its client through an *output*: UDP to its ports, its
//! RTSP connection (interleaved), or the stream's multicast group, which
//! every multicast session of the stream shares (each row goes to the
//! group once, whatever the number of receivers). A new output joins at
//! the next frame's first row, whose sequence number the `PLAY` answer
//! announces ([`Position`]); every frame spans exactly [`ROWS`] sequence
//! numbers (a frame that fails part way leaves the rest unused), so that
//! number is known before the frame begins.
//!
//! # Frames, slots and repair
//!
//! A stream begins a frame in the [`SlotSource`] (the frame ring) when one
//! is due (`fps=N`: every 1/N s; `fps=max`: as soon as every output has
//! the one before), with the light of its media time
//! ([`StreamSpec::light_at`]). Rows go to every output as they land, in
//! runs; an output that cannot take rows for [`OUTPUT_STALL`]
//! ([`TCP_OUTPUT_STALL`] inside an RTSP connection) is cut from
//! the frame and joins the next. One still behind when another output has
//! the whole frame and the next frame is due (`fps=N`), or after as long
//! again as the frame took (`fps=max`, at least [`MIN_LAG`]), is late: the
//! stream goes on without it while it finishes its frame from the slot,
//! which it holds meanwhile (one slot more per late output), and it joins
//! the first frame that begins after that. A slow client loses whole
//! frames, never parts of one, and never holds the others back
//! (gst-rtsp-server drops a client's backlog likewise); one that takes
//! nothing for its stall limit is cut. When every output has the frame it is ended, and its
//! packets stay in the stream's repair window until the frame after next
//! begins (and at most [`MIN_REPAIR_HOLD`] after their frame's end if the
//! stream stops): a stream holds at most two slots, the frame being sent
//! and the one before it ([`SLOTS_PER_STREAM`]). While every output playing
//! a stream has asked for repairs lately ([`LOSS_MEMORY`]), a frame begins
//! only once the oldest one in the window has been repairable for
//! [`REPAIR_ROUNDS`] NACK rounds; a stream that any output receives
//! cleanly never waits (a lossy viewer slows only itself).
//!
//! A NACK's packets go again unchanged, to the output that asked (for a
//! multicast output, to the group), oldest first and before new rows,
//! within limits that keep a flood of NACKs, real or spoofed, from
//! multiplying the board's output or starving other streams: a packet goes
//! again at most once a round trip to an output ([`ResendLog`]), an output
//! earns one resend per [`REPAIR_SHARE`] packets it was sent (a budget of
//! at most [`REPAIR_BURST`] banked), and one NACK datagram asks for at most
//! [`MAX_NACKED_PER_DATAGRAM`] packets.
//!
//! # Liveness
//!
//! A UDP output whose client sent RTCP (receiver reports, NACKs) and then
//! falls silent for [`RTCP_SILENCE`], or whose client's host answers
//! [`UNREACHABLE_LIMIT`] of its packets with ICMP port unreachable
//! ([`Camera::unreachable`]) without RTCP in between, ends its sessions
//! ([`Camera::take_ended`]): a crashed player costs the link seconds, not
//! the RTSP session timeout's minute. An interleaved output ends with its
//! connection; a multicast one costs nothing per receiver and lives as
//! long as an RTSP session keeps it.
//!
//! [`Position`]: crate::camera::rtsp::Position
//! [`ResendLog`]: crate::camera::repair::ResendLog
//! [`MAX_NACKED_PER_DATAGRAM`]: crate::camera::wire::rtcp::MAX_NACKED_PER_DATAGRAM

use core::net::{IpAddr, Ipv4Addr, SocketAddr};
use core::time::Duration;

use model::Light;

use crate::camera::packetiser::{self, Packetiser};
use crate::camera::repair::{FrameRepairWindow, FrameResendLog};
use crate::camera::report_timer::ReportTimer;
use crate::camera::rtsp::{
    Client, ConnId, EndReason, Fresh, Group, LightSource, Position, Profile, SessionId, SetUp, Status, StreamSpec,
    Streams, Transport, MAX_SESSIONS,
};
use crate::camera::wire::rtcp::{
    self, round_trip, write_bye, write_sdes_cname, NackRequests, SenderReport, BYE_BYTES, SENDER_REPORT_BYTES,
};
use crate::camera::wire::rtp::{FrameStamp, RowPacket};
use crate::frames::{FrameSource, ROWS};
use crate::time::Instant;

/// Frames in numbered slots that stay readable after [`FrameSource::end`]
/// while held: what a stream can resend from.
pub trait SlotSource: FrameSource<Frame = usize> {
    /// Keep the slots of `mask` (bit `i`: slot `i`) out of reuse, in
    /// addition to any other pins, replacing the previous mask.
    fn set_held(&mut self, mask: u32);
}

/// Slots a stream holds at most: the frame being sent and the one before
/// it, which its repair window keeps.
pub const SLOTS_PER_STREAM: usize = 2;

/// Slots the camera holds at most: [`SLOTS_PER_STREAM`] for each of
/// [`MAX_SESSIONS`] streams (every session a stream of its own).
pub const CAMERA_SLOTS: usize = SLOTS_PER_STREAM * MAX_SESSIONS;

/// Rows a stream gathers into one run while the source keeps landing
/// them (each run costs the sink one route lookup, the MAC one set of
/// descriptor control words and counts, the repair window one check):
/// 32 rows, 46 KB, 0.37 ms at 1 Gbit/s, the MAC's transmit ring.
pub const MIN_RUN: u16 = 32;

/// NACKed packets an output queues for resending (more are not
/// repairable: a receiver asking for more at once lost the stream).
pub const MAX_PENDING_REPAIRS: usize = 512;

/// An output earns one resend per this many packets it is sent: repairs
/// add at most a quarter to its traffic (10% loss needs about 11%,
/// counting lost resends).
pub const REPAIR_SHARE: u32 = 4;

/// Resends an output may bank: two frames' worth (it starts with half).
/// One frame's worth left a burst of loss on a loaded path (a client whose
/// socket overflowed, a relay that fell behind) over budget, its frame
/// given up, at 2% loss (the suite's lossy test, once in 61 frames).
pub const REPAIR_BURST: u32 = 2 * ROWS as u32;

/// The round trip assumed until a receiver report measures one.
pub const DEFAULT_ROUND_TRIP: Duration = Duration::from_millis(50);

/// The shortest round trip assumed (a LAN's is far less, but a receiver
/// needs a few milliseconds to notice a resend arrived).
pub const MIN_ROUND_TRIP: Duration = Duration::from_millis(5);

/// The longest round trip assumed: a resend that took longer is worth
/// sending again.
pub const MAX_ROUND_TRIP: Duration = Duration::from_secs(1);

/// A UDP or multicast output that takes no row for this long is cut from
/// the frame it is on and joins the next (a transmitter that stays full).
pub const OUTPUT_STALL: Duration = Duration::from_millis(500);

/// The least time an `fps=max` output that is behind gets, after the first
/// output had the whole frame, before it is cut from it (it gets as long
/// again as the frame took, at least this).
pub const MIN_LAG: Duration = Duration::from_millis(5);

/// The same for an output inside an RTSP connection: longer than TCP's
/// retransmission timeout (smoltcp's is a second at least), so that one
/// lost segment does not cost its viewer a frame; a client that stopped
/// reading is cut after it.
pub const TCP_OUTPUT_STALL: Duration = Duration::from_secs(3);

/// A UDP client that has sent RTCP and then sends none (nor an RTSP
/// request) for this long is gone: four times the 5 s report interval
/// players use (GStreamer's and FFmpeg's receiver reports).
pub const RTCP_SILENCE: Duration = Duration::from_secs(20);

/// ICMP port unreachable answers to an output's packets, with no RTCP in
/// between, after which its client is gone (Linux sends a few at once,
/// then one a second: `icmp_ratelimit`).
pub const UNREACHABLE_LIMIT: u8 = 3;

/// How long a stream that stopped keeps its last frames for a NACK: a
/// second, for a request that crosses a slow or lossy path.
pub const MIN_REPAIR_HOLD: Duration = Duration::from_secs(1);

/// How long an output counts as losing packets after a NACK asked for one
/// of its packets: while every output playing a stream does, the stream's
/// frames stay repairable for [`REPAIR_ROUNDS`] NACK rounds (a clean
/// stream is never slowed, nor one that any output receives cleanly).
pub const LOSS_MEMORY: Duration = Duration::from_secs(2);

/// NACK rounds a frame stays repairable for after its end on a stream
/// every output of which is losing packets, at least: at 10% loss a frame
/// of 360 rows has a resend lost nine times in ten, so the first round is
/// often not enough, and a NACK itself is lost one time in ten (three
/// rounds still left one frame in twenty given up in the suite's lossy
/// test). Six held a stream under a NACK flood from its own client to 71%
/// of its clean rate (the suite's hostile test wants 80%); four kept 84%.
/// At a measured LAN round trip of 1 ms the hold is 84 ms for the two
/// frames in the window while the stream loses packets: at most 24
/// frames/s for a viewer alone on a lossy path, exact.
pub const REPAIR_ROUNDS: u32 = 4;

/// A receiver's time to notice what is missing and ask again, added to
/// the round trip for a NACK round.
pub const NACK_REACTION: Duration = Duration::from_millis(20);

/// The longest a frame is held for repair before the one after next may
/// begin (a path this slow gets frames given up rather than none).
pub const MAX_FRAME_HOLD: Duration = Duration::from_millis(500);

/// The longest [`Cname`]: `raytracer@` and a dotted IPv4 address.
pub const MAX_CNAME_BYTES: usize = 32;

/// The CNAME in the sender reports' SDES (RFC 3550 section 6.5.1): `user@host`
/// with the host's numeric address (a board has no domain name), so two
/// boards on one network are two sources to a receiver, and every stream
/// of one board is one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cname {
    bytes: [u8; MAX_CNAME_BYTES],
    len: u8,
}

impl Cname {
    /// `raytracer@A.B.C.D` for the board at `ip`.
    pub fn for_address(ip: Ipv4Addr) -> Cname {
        use core::fmt::Write;
        let mut text: heapless::String<MAX_CNAME_BYTES> = heapless::String::new();
        // At most 10 + 15 bytes: it fits.
        let _ = write!(text, "raytracer@{ip}");
        let mut bytes = [0u8; MAX_CNAME_BYTES];
        bytes[..text.len()].copy_from_slice(text.as_bytes());
        Cname { bytes, len: text.len() as u8 }
    }

    /// The CNAME's octets.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }
}

/// Where an output's packets go.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dest {
    /// UDP to the client that set the session up.
    Udp {
        /// The client's address.
        addr: IpAddr,
        /// Its RTP port.
        rtp_port: u16,
        /// Its RTCP port.
        rtcp_port: u16,
    },
    /// Inside an RTSP connection (RFC 2326 section 10.12): `$`, the
    /// channel, the length, the packet.
    Interleaved {
        /// The connection.
        conn: ConnId,
        /// The channel of RTP packets.
        rtp_channel: u8,
        /// The channel of RTCP packets.
        rtcp_channel: u8,
    },
    /// UDP to a multicast group: RTP to its port, RTCP to the next.
    Multicast(Group),
}

/// The caller's way out.
pub trait RtpSink {
    /// Send a run of `count` row packets to `to`: `first` and the ones
    /// after it ([`RowPacket::nth`]), their 20 RTP and RFC 4175 header
    /// bytes [`Packetiser::emit`] of each, their rows those of frame slot
    /// `slot` (the same rows [`FrameSource::copy_row`] of `source` copies,
    /// while the frame is the current one; a resend's slot is held, not
    /// current, and only UDP outputs get resends). Returns how many went,
    /// from the front (the rest are offered again later).
    fn send_rows<S: FrameSource<Frame = usize>>(
        &mut self,
        to: &Dest,
        packetiser: &Packetiser,
        first: &RowPacket,
        count: u16,
        slot: usize,
        source: &mut S,
    ) -> u16;

    /// Send an RTCP packet to `to`'s RTCP port (or channel); `false` if it
    /// cannot be sent now (it is dropped: reports are periodic).
    fn send_rtcp(&mut self, to: &Dest, datagram: &[u8]) -> bool;

    /// Whether the camera should return to its caller now rather than
    /// ask the source for more rows: something arrived that the caller
    /// must take in (a NACK, on the board). Asked after each run of rows.
    fn should_yield(&mut self) -> bool {
        false
    }
}

/// The sender's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// A live stream's light before its first `SET_PARAMETER`.
    pub live_light: Light,
    /// Where multicast streams go; `None`: no multicast (461).
    pub multicast: Option<Multicast>,
    /// The CNAME of its reports: the board's ([`Cname::for_address`]).
    pub cname: Cname,
}

/// The multicast groups streams are sent to: a pool of [`MAX_SESSIONS`]
/// consecutive addresses, one a stream (as gst-rtsp-server's address
/// pool), so that a switch's IGMP snooping gives each receiver the stream
/// it joined and no other; every group uses the same ports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Multicast {
    /// The first group address (an administratively scoped one, RFC 2365,
    /// for a lab network: 239.255.0.0/16); stream `i` goes to this plus `i`.
    pub group: Ipv4Addr,
    /// The groups' RTP port (RTCP one above: where receivers send their
    /// reports and NACKs, to the group or to the board).
    pub base_port: u16,
    /// Time to live: 1 keeps the packets on the board's link.
    pub ttl: u8,
}

/// What an output has done, for logs and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OutputStats {
    /// Frames whose every row it was sent.
    pub frames: u32,
    /// Row packets sent (first sends).
    pub packets: u32,
    /// Row packets sent again for a NACK.
    pub resent: u32,
    /// NACKed packets no longer (or never) in the repair window.
    pub unrepairable: u32,
    /// NACKed packets not resent because they went again less than a
    /// round trip before.
    pub too_soon: u32,
    /// NACKed packets not resent because the output's repair budget was
    /// spent.
    pub over_budget: u32,
    /// Frames cut short: the output stalled, or paused, mid-frame.
    pub cut: u32,
    /// Frames it was still sending when they were due to end, finished
    /// from their slot while the stream went on.
    pub late: u32,
    /// NACK datagrams not read at all: the budget was spent.
    pub nacks_unread: u32,
    /// RTCP packets from its receivers (reports, NACKs), wherever they
    /// were sent: the RTCP port, or a multicast group's.
    pub reports: u32,
}

/// What a stream has done.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Frames rendered and sent to every output.
    pub frames: u32,
    /// Frames the source failed, or that stopped with the stream.
    pub failed: u32,
}

/// Why the sender ended a session itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gone {
    /// Its client sent RTCP, then none for [`RTCP_SILENCE`].
    Silent,
    /// Its client's host answered [`UNREACHABLE_LIMIT`] packets with ICMP
    /// port unreachable.
    Unreachable,
}

impl core::fmt::Display for Gone {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Gone::Silent => "no RTCP for 20 s",
            Gone::Unreachable => "ICMP port unreachable",
        })
    }
}

/// The frame a stream is sending.
#[derive(Clone, Copy, Debug)]
struct Frame {
    slot: usize,
    stamp: FrameStamp,
    /// The extended sequence number of its row 0.
    first_seq: u32,
    /// Rows landed (and numbered) so far.
    landed: u16,
    /// Rows recorded in the repair window so far: landed rows are
    /// recorded in one run just before any of them is sent, not a look
    /// at a time (a look often lands a single row).
    recorded: u16,
    /// When it began, and when the first output had all its rows (or all
    /// its rows had landed while an output waited for the next frame).
    begun_at: Instant,
    done_at: Option<Instant>,
}

impl Frame {
    fn packet(&self, row: u16) -> RowPacket {
        RowPacket { seq: self.first_seq.wrapping_add(u32::from(row)), timestamp: self.stamp.timestamp, row }
    }
}

/// One shared stream: its frames, numbering and pacing.
#[derive(Clone, Debug)]
struct Media {
    spec: StreamSpec,
    /// A live stream's light.
    live: Light,
    packetiser: Packetiser,
    /// Whether any output plays (the media time runs).
    running: bool,
    /// Media time (90 kHz ticks since the first `PLAY`) at `resumed_at`.
    media_at_resume: u64,
    resumed_at: Instant,
    /// When the next frame is due (`fps=N`).
    due: Instant,
    current: Option<Frame>,
    /// Row 0's sequence number of the frame before the current one (or of
    /// the last one): the oldest the repair window keeps.
    previous_first: Option<u32>,
    /// When the frame at `previous_first` ended, and the one before it: the
    /// oldest frame in the window, which the next frame's begin drops.
    ended_at: Option<Instant>,
    oldest_ended_at: Option<Instant>,
    /// The next frame waits until then for the oldest frame's repairs
    /// ([`Media::repairable_until`]), as the last poll found.
    repair_wait: Option<Instant>,
    stats: StreamStats,
    /// Which slot and row each recent packet came from.
    window: FrameRepairWindow,
}

impl Media {
    /// The frame whose row 0 is `first` ended (sent, failed or abandoned)
    /// at `now`.
    fn frame_ended(&mut self, first: u32, now: Instant) {
        self.previous_first = Some(first);
        self.oldest_ended_at = self.ended_at;
        self.ended_at = Some(now);
    }

    /// When the next frame may begin as far as repair goes: on a stream
    /// every output of which loses packets (`lossy`), once the oldest
    /// frame in the window (which that begin drops) has been held for
    /// `hold` since its end.
    fn repairable_until(&self, lossy: bool, hold: Duration) -> Option<Instant> {
        self.oldest_ended_at.filter(|_| lossy).map(|t| t + hold)
    }

    fn media_ticks(&self, now: Instant) -> u64 {
        if self.running {
            self.media_at_resume + packetiser::ticks(now).saturating_sub(packetiser::ticks(self.resumed_at))
        } else {
            self.media_at_resume
        }
    }

    /// Row 0's sequence number of the next frame to begin.
    fn next_frame_seq(&self) -> u32 {
        match self.current {
            Some(f) => f.first_seq.wrapping_add(u32::from(ROWS)),
            None => self.packetiser.next_seq(),
        }
    }
}

/// Where an output is in its stream's frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cursor {
    /// No session of it plays.
    Paused,
    /// Waiting for the frame whose row 0 is numbered `from` or later.
    Waiting { from: u32 },
    /// In the current frame, row `next` goes next.
    Sending { next: u16 },
    /// Behind when its frame was due to end: it finishes that frame, in
    /// `slot` (which it holds meanwhile), from packet `next` on, while the
    /// stream goes on without it, then waits for the next frame to begin.
    /// A slow client loses whole frames, never parts of one.
    Finishing { slot: u8, next: RowPacket },
}

/// One way out of a stream: a unicast client, or a multicast group.
#[derive(Clone, Debug)]
struct Output {
    media: usize,
    dest: Dest,
    /// Sessions of it that play.
    playing: u8,
    cursor: Cursor,
    repairs: heapless::Deque<u32, MAX_PENDING_REPAIRS>,
    /// Resends it may still make, times [`REPAIR_SHARE`].
    budget: u32,
    round_trip: Duration,
    /// Since when it takes no rows.
    stalled_since: Option<Instant>,
    reports: ReportTimer,
    /// When its client's RTCP last arrived.
    last_rtcp: Option<Instant>,
    unreachable: u8,
    stats: OutputStats,
    /// Packets of its stream an interleaved output skipped while playing
    /// (frames lost as a laggard): subtracted from the sequence numbers it
    /// sends, so that its client sees no jump. RFC 3550's receivers
    /// (appendix A.1: MAX_DROPOUT 3,000; FFmpeg's rtpdec) drop the first
    /// packet after a larger one, a row of the next frame. Outputs over UDP
    /// keep the stream's numbers: their NACKs name them. PLAY starts again
    /// at 0 (RTP-Info names the stream's number).
    seq_shift: u32,
    /// When each recent packet was resent to it.
    resends: FrameResendLog,
    /// Until when it counts as losing packets ([`LOSS_MEMORY`] after a
    /// NACK asked for one).
    lossy_until: Option<Instant>,
    /// How long after a resend its receiver asks for the same packet again
    /// (a NACK round as its receiver runs it, which may be far longer than
    /// the round trip its reports measure), once it has.
    nack_round: Option<Duration>,
}

impl Output {
    /// Packet `seq`, resent to it `since` ago, was asked for again: a
    /// sample of its NACK round. The estimate goes halfway up to a longer
    /// sample at once and an eighth of the way down to a shorter one (a
    /// resend lost again is the case the hold is for; a receiver asking
    /// at once, as a flood does, shortens nothing below the round trip).
    fn asked_again(&mut self, since: Duration) {
        let sample = since.min(MAX_ROUND_TRIP);
        self.nack_round = Some(match self.nack_round {
            None => sample,
            Some(d) if sample > d => (d + sample) / 2,
            Some(d) => (d * 7 + sample) / 8,
        });
    }

    /// One NACK round for it: the measured round trip and a receiver's
    /// reaction, or the round its receiver was seen to take, the longer.
    fn repair_round(&self) -> Duration {
        (self.round_trip + NACK_REACTION).max(self.nack_round.unwrap_or(Duration::ZERO))
    }

    /// Packet `p` as this output numbers it.
    fn numbered(&self, p: RowPacket) -> RowPacket {
        RowPacket { seq: p.seq.wrapping_sub(self.seq_shift), ..p }
    }

    /// Whether it goes inside a client's connection that took nothing the
    /// last time it was offered rows (its own backlog, not the
    /// transmitter's).
    fn connection_stalled(&self) -> bool {
        self.stalled_since.is_some() && matches!(self.dest, Dest::Interleaved { .. })
    }

    /// How long it may take no rows before it is cut from its frame.
    fn stall_limit(&self) -> Duration {
        match self.dest {
            Dest::Interleaved { .. } => TCP_OUTPUT_STALL,
            _ => OUTPUT_STALL,
        }
    }
}

/// A session: which output it goes through, and whether it plays.
#[derive(Clone, Copy, Debug)]
struct Member {
    session: SessionId,
    output: usize,
    client: IpAddr,
    playing: bool,
}

/// A sender report, an SDES CNAME chunk and a BYE: the largest compound
/// packet sent.
const RTCP_BYTES: usize = SENDER_REPORT_BYTES + rtcp::sdes_cname_bytes(MAX_CNAME_BYTES) + BYE_BYTES;

/// The RTP sender of up to `N` sessions: up to `N` streams and outputs,
/// with a repair window per stream and a resend log per output.
pub struct Camera<const N: usize = MAX_SESSIONS> {
    config: Option<Config>,
    media: [Option<Media>; N],
    outputs: [Option<Output>; N],
    members: [Option<Member>; N],
    /// Sessions the sender ended itself, for the RTSP server to forget.
    ended: heapless::Deque<(SessionId, Gone), N>,
    /// Goodbyes to send: an output's destination and its stream's last
    /// sender report (its wall-clock time is filled in when it goes).
    byes: heapless::Deque<(Dest, SenderReport), N>,
    /// Where RTCP packets are built.
    rtcp: [u8; RTCP_BYTES],
    /// Frames begun or ended over all streams (wrapping), for callers
    /// that give the rest of their loop a turn between frames.
    frame_edges: u32,
    /// Outputs made plus outputs ended ([`output_changes`](Self::output_changes)).
    output_changes: u32,
    /// Outputs finishing a late frame ([`Cursor::Finishing`]): the rest
    /// of the main loop skips them, at no cost, while there are none.
    late_outputs: u32,
    /// The held slots last given to the source ([`give_held`](Self::give_held)).
    held_given: u32,
}

impl<const N: usize> Default for Camera<N> {
    fn default() -> Self {
        Camera::new()
    }
}

impl<const N: usize> Camera<N> {
    /// No streams, not configured. `const`, so a board can keep it in a
    /// `static` (some 60 KiB for four sessions, most of it the resend
    /// logs: 12 KiB a session).
    pub const fn new() -> Camera<N> {
        const { assert!(N <= 32, "streams' slots live in 32-bit masks") };
        Camera {
            config: None,
            media: [const { None }; N],
            outputs: [const { None }; N],
            members: [const { None }; N],
            ended: heapless::Deque::new(),
            byes: heapless::Deque::new(),
            rtcp: [0; RTCP_BYTES],
            frame_edges: 0,
            output_changes: 0,
            late_outputs: 0,
            held_given: 0,
        }
    }

    /// Set the live light and the multicast groups (before the first
    /// session; a camera never configured serves no live stream and no
    /// multicast).
    pub fn configure(&mut self, config: Config) {
        self.config = Some(config);
    }

    /// The board's address changed: reports name it from now on.
    pub fn set_cname(&mut self, cname: Cname) {
        if let Some(c) = &mut self.config {
            c.cname = cname;
        }
    }

    /// Where its multicast streams go, if anywhere.
    pub fn multicast(&self) -> Option<Multicast> {
        self.config?.multicast
    }

    /// The CNAME its reports carry.
    fn cname(&self) -> Cname {
        self.config.map_or_else(|| Cname::for_address(Ipv4Addr::UNSPECIFIED), |c| c.cname)
    }

    /// The sessions it sends to, with their output's statistics.
    pub fn sessions(&self) -> impl Iterator<Item = (SessionId, OutputStats)> + '_ {
        self.members.iter().flatten().filter_map(|m| Some((m.session, self.outputs[m.output].as_ref()?.stats)))
    }

    /// `session`'s output's statistics.
    pub fn stats(&self, session: SessionId) -> Option<OutputStats> {
        let m = self.member(session)?;
        Some(self.outputs[m.output].as_ref()?.stats)
    }

    /// The statistics of `session`'s stream.
    pub fn stream_stats(&self, session: SessionId) -> Option<StreamStats> {
        let m = self.member(session)?;
        Some(self.media[self.outputs[m.output].as_ref()?.media].as_ref()?.stats)
    }

    /// Streams running or set up.
    pub fn streams(&self) -> usize {
        self.media.iter().flatten().count()
    }

    /// Outputs (unicast clients and multicast groups).
    pub fn outputs(&self) -> usize {
        self.outputs.iter().flatten().count()
    }

    /// Where `session`'s packets go.
    pub fn destination(&self, session: SessionId) -> Option<Dest> {
        Some(self.outputs[self.member(session)?.output].as_ref()?.dest)
    }

    /// The SSRC of `session`'s stream.
    pub fn ssrc(&self, session: SessionId) -> Option<u32> {
        let o = self.outputs[self.member(session)?.output].as_ref()?;
        Some(self.media[o.media].as_ref()?.packetiser.ssrc())
    }

    /// Packets `session`'s stream's repair window holds.
    pub fn repairable(&self, session: SessionId) -> usize {
        let Some(m) = self.member(session) else { return 0 };
        self.outputs[m.output].as_ref().and_then(|o| self.media[o.media].as_ref()).map_or(0, |s| s.window.len())
    }

    /// The frame slots the repair windows and late outputs hold (bit `i`:
    /// slot `i`); give it
    /// to the source ([`SlotSource::set_held`]) after every call that
    /// sends or forgets ([`Bound`] and [`poll`](Self::poll) do).
    pub fn held(&self) -> u32 {
        let late = match self.late_outputs {
            0 => 0,
            _ => self.outputs.iter().flatten().fold(0, |m, o| match o.cursor {
                Cursor::Finishing { slot, .. } => m | 1 << slot,
                _ => m,
            }),
        };
        self.media.iter().flatten().fold(late, |held, m| held | m.window.held())
    }

    /// Give the source the slots held now ([`held`](Self::held)).
    pub fn give_held<S: SlotSource>(&mut self, source: &mut S) {
        self.held_given = self.held();
        source.set_held(self.held_given);
    }

    /// A session the sender ended itself, and why: the RTSP server must
    /// forget it (`rtsp::Server::remove`). Call until `None` after each
    /// poll.
    pub fn take_ended(&mut self) -> Option<(SessionId, Gone)> {
        self.ended.pop_front()
    }

    fn member(&self, session: SessionId) -> Option<&Member> {
        self.members.iter().flatten().find(|m| m.session == session)
    }

    fn member_index(&self, session: SessionId) -> Option<usize> {
        self.members.iter().position(|m| m.as_ref().is_some_and(|m| m.session == session))
    }

    /// The multicast group of stream slot `i` ([`Multicast`]).
    fn group_of(&self, i: usize) -> Option<Group> {
        let m = self.config?.multicast?;
        let addr = Ipv4Addr::from(u32::from(m.group).checked_add(u32::try_from(i).ok()?)?);
        addr.is_multicast().then_some(Group { addr, port: m.base_port, ttl: m.ttl })
    }

    /// The groups multicast outputs send to now: the board joins them
    /// (IGMP), so that receivers' RTCP to a group reaches it through a
    /// snooping switch.
    pub fn multicast_groups(&self) -> impl Iterator<Item = Group> + '_ {
        self.outputs.iter().flatten().filter_map(|o| match o.dest {
            Dest::Multicast(g) => Some(g),
            _ => None,
        })
    }

    /// Counts outputs made and ended (wrapping): a caller that keeps
    /// something per output (the groups it joined) looks again when it
    /// changes.
    pub fn output_changes(&self) -> u32 {
        self.output_changes
    }

    /// The stream `spec` is (or would be) sent as: its slot.
    fn stream_for(&self, spec: &StreamSpec) -> Option<usize> {
        self.media.iter().position(|m| m.as_ref().is_some_and(|m| m.spec.same_frames(spec)))
    }

    // ---- What the RTSP server asks ----

    /// `SETUP` of `session` ([`Streams::setup`]).
    #[allow(clippy::too_many_arguments)]
    fn setup_session<S: SlotSource>(
        &mut self,
        session: SessionId,
        spec: &StreamSpec,
        transport: Transport,
        client: Client,
        fresh: Fresh,
        now: Instant,
        source: &mut S,
    ) -> Result<SetUp, Status> {
        if transport == Transport::Multicast && self.config.and_then(|c| c.multicast).is_none() {
            return Err(Status::UnsupportedTransport);
        }
        // SETUP again (not playing): the old stream and output are left,
        // once it is clear that the new ones can be had (counting what
        // leaving frees), so a refusal leaves the session as it was.
        if let Some(old) = self.member(session).copied() {
            let sole_user = |o: usize| self.members.iter().flatten().filter(|m| m.output == o).count() == 1;
            let frees_output = sole_user(old.output).then_some(old.output);
            let frees_stream = frees_output.and_then(|o| self.outputs[o].as_ref()).map(|o| o.media).filter(|&mi| {
                self.outputs
                    .iter()
                    .enumerate()
                    .all(|(j, o)| Some(j) == frees_output || o.as_ref().is_none_or(|o| o.media != mi))
            });
            let stream_ok =
                self.stream_for(spec).is_some() || self.media.iter().any(Option::is_none) || frees_stream.is_some();
            let group_shared = transport == Transport::Multicast
                && self.stream_for(spec).is_some_and(|mi| {
                    self.outputs.iter().flatten().any(|o| o.media == mi && matches!(o.dest, Dest::Multicast(_)))
                });
            let output_ok = group_shared || self.outputs.iter().any(Option::is_none) || frees_output.is_some();
            if !stream_ok || !output_ok {
                return Err(Status::NotEnoughBandwidth);
            }
            self.leave(session, now, source, false);
        }
        let free_member = self.members.iter().position(Option::is_none).ok_or(Status::NotEnoughBandwidth)?;
        let media = match self.stream_for(spec) {
            Some(i) => i,
            None => {
                let i = self.media.iter().position(Option::is_none).ok_or(Status::NotEnoughBandwidth)?;
                let live = match self.config {
                    Some(c) => c.live_light,
                    // A camera never configured: the light rt-client starts
                    // with (3, 4, -2 in Q13.10: always in range).
                    None => Light::from_raw(3 << 10, 4 << 10, -2 << 10).map_err(|_| Status::NotEnoughBandwidth)?,
                };
                self.media[i] = Some(Media {
                    spec: *spec,
                    live,
                    packetiser: Packetiser::new(fresh.ssrc, u32::from(fresh.seq), fresh.rtptime),
                    running: false,
                    media_at_resume: 0,
                    resumed_at: now,
                    due: now,
                    current: None,
                    previous_first: None,
                    ended_at: None,
                    oldest_ended_at: None,
                    repair_wait: None,
                    stats: StreamStats::default(),
                    window: FrameRepairWindow::new(MIN_REPAIR_HOLD),
                });
                i
            }
        };
        let group = match transport {
            Transport::Multicast => self.group_of(media),
            _ => None,
        };
        let shared = match (transport, group) {
            (Transport::Multicast, Some(g)) => self
                .outputs
                .iter()
                .position(|o| o.as_ref().is_some_and(|o| o.media == media && o.dest == Dest::Multicast(g))),
            _ => None,
        };
        let output = match shared {
            Some(o) => o,
            None => {
                let Some(o) = self.outputs.iter().position(Option::is_none) else {
                    self.forget_unused_media(media, source);
                    return Err(Status::NotEnoughBandwidth);
                };
                let dest = match (transport, group) {
                    (Transport::Udp { rtp_port, rtcp_port }, _) => Dest::Udp { addr: client.addr, rtp_port, rtcp_port },
                    (Transport::Interleaved { rtp_channel, rtcp_channel }, _) => {
                        Dest::Interleaved { conn: client.conn, rtp_channel, rtcp_channel }
                    }
                    (Transport::Multicast, Some(g)) => Dest::Multicast(g),
                    (Transport::Multicast, None) => {
                        self.forget_unused_media(media, source);
                        return Err(Status::UnsupportedTransport);
                    }
                };
                self.output_changes = self.output_changes.wrapping_add(1);
                self.outputs[o] = Some(Output {
                    media,
                    dest,
                    playing: 0,
                    cursor: Cursor::Paused,
                    repairs: heapless::Deque::new(),
                    budget: REPAIR_SHARE * REPAIR_BURST / 2,
                    round_trip: DEFAULT_ROUND_TRIP,
                    stalled_since: None,
                    reports: ReportTimer::new(now),
                    last_rtcp: None,
                    unreachable: 0,
                    stats: OutputStats::default(),
                    seq_shift: 0,
                    // Some 12 KiB built once per output (at SETUP, on a
                    // 256 KiB stack on the board: memory.x).
                    resends: FrameResendLog::new(),
                    lossy_until: None,
                    nack_round: None,
                });
                o
            }
        };
        self.members[free_member] = Some(Member { session, output, client: client.addr, playing: false });
        let ssrc = self.media[media].as_ref().map_or(fresh.ssrc, |m| m.packetiser.ssrc());
        Ok(SetUp { ssrc, group })
    }

    /// `PLAY` of `session` ([`Streams::play`]).
    fn play_session(&mut self, session: SessionId, now: Instant) -> Result<Position, Status> {
        let i = self.member_index(session).ok_or(Status::SessionNotFound)?;
        let Some(m) = self.members[i].as_mut() else { return Err(Status::SessionNotFound) };
        let was_playing = core::mem::replace(&mut m.playing, true);
        let Some(o) = self.outputs[m.output].as_mut() else { return Err(Status::SessionNotFound) };
        let Some(media) = self.media[o.media].as_mut() else { return Err(Status::SessionNotFound) };
        if !media.running {
            media.running = true;
            media.resumed_at = now;
            media.due = now;
        }
        if !was_playing {
            o.playing += 1;
        }
        let from = media.next_frame_seq();
        if o.cursor == Cursor::Paused {
            o.cursor = Cursor::Waiting { from };
            o.reports = ReportTimer::new(now);
            o.seq_shift = 0;
        }
        let seq = match o.cursor {
            Cursor::Waiting { from } => from,
            // Already in a frame (another session of the group plays):
            // the group's next frame is where this receiver starts whole.
            _ => from,
        };
        let media_ticks = media.media_ticks(now);
        Ok(Position { seq: seq as u16, rtptime: media.packetiser.timestamp_at(media_ticks), media_ticks })
    }

    /// `PAUSE` of `session` ([`Streams::pause`]).
    fn pause_session<S: SlotSource>(&mut self, session: SessionId, now: Instant, source: &mut S) {
        let Some(i) = self.member_index(session) else { return };
        let Some(m) = self.members[i].as_mut() else { return };
        if !core::mem::replace(&mut m.playing, false) {
            return;
        }
        let output = m.output;
        let Some(o) = self.outputs[output].as_mut() else { return };
        o.playing = o.playing.saturating_sub(1);
        if o.playing == 0 {
            if matches!(o.cursor, Cursor::Sending { .. } | Cursor::Finishing { .. }) {
                o.stats.cut += 1;
            }
            o.cursor = Cursor::Paused;
            let media = o.media;
            self.stop_if_idle(media, now, source);
        }
    }

    /// A stream none of whose outputs plays stops: its frame in progress is
    /// abandoned (its rows so far stay repairable), its media time halts.
    fn stop_if_idle<S: SlotSource>(&mut self, media: usize, now: Instant, source: &mut S) {
        let playing = self.outputs.iter().flatten().any(|o| o.media == media && o.cursor != Cursor::Paused);
        let Some(m) = self.media[media].as_mut() else { return };
        if playing || !m.running {
            return;
        }
        if let Some(f) = m.current.take() {
            source.end(f.slot);
            m.packetiser.skip_to(f.first_seq.wrapping_add(u32::from(ROWS)));
            m.window.restart_hold(f.first_seq, now);
            m.frame_ended(f.first_seq, now);
            m.stats.failed += 1;
            self.frame_edges = self.frame_edges.wrapping_add(1);
        }
        m.media_at_resume = m.media_ticks(now) + 1;
        m.running = false;
        self.give_held(source);
    }

    /// `session` is over: its membership goes; an output no session uses
    /// any more says goodbye and goes; a stream without outputs goes.
    fn leave<S: SlotSource>(&mut self, session: SessionId, now: Instant, source: &mut S, bye: bool) {
        let Some(i) = self.member_index(session) else { return };
        let Some(m) = self.members[i].take() else { return };
        if m.playing {
            if let Some(o) = self.outputs[m.output].as_mut() {
                o.playing = o.playing.saturating_sub(1);
                if o.playing == 0 {
                    o.cursor = Cursor::Paused;
                }
            }
        }
        let used = self.members.iter().flatten().any(|x| x.output == m.output);
        let Some(media) = self.outputs[m.output].as_ref().map(|o| o.media) else { return };
        if !used {
            // Its destination read in place: an output is some 12 KiB (its
            // resend log), not to be moved out to read one field.
            if let Some(dest) = self.outputs[m.output].as_ref().map(|o| o.dest) {
                self.outputs[m.output] = None;
                self.output_changes = self.output_changes.wrapping_add(1);
                if let (true, Some(m)) = (bye, self.media[media].as_ref()) {
                    let last = m.packetiser.sender_report(0, m.media_ticks(now));
                    let _ = self.byes.push_back((dest, last));
                }
            }
        }
        self.stop_if_idle(media, now, source);
        self.forget_unused_media(media, source);
    }

    /// Forget stream `media` if no output uses it.
    fn forget_unused_media<S: SlotSource>(&mut self, media: usize, source: &mut S) {
        if self.outputs.iter().flatten().any(|o| o.media == media) {
            return;
        }
        if let Some(m) = self.media[media].take() {
            if let Some(f) = m.current {
                source.end(f.slot);
            }
        }
        self.give_held(source);
    }

    /// End every session of output `o` (its client is gone).
    fn end_output<S: SlotSource>(&mut self, o: usize, why: Gone, now: Instant, source: &mut S) {
        while let Some(s) = self.members.iter().flatten().find(|m| m.output == o).map(|m| m.session) {
            self.leave(s, now, source, true);
            let _ = self.ended.push_back((s, why));
        }
    }

    /// RTCP from `session`'s client inside its RTSP connection: it is alive
    /// and its report may measure the round trip (no repair over TCP,
    /// which loses nothing).
    fn interleaved_rtcp(&mut self, session: SessionId, datagram: &[u8], now: Instant, wall: u64) {
        let Some(m) = self.member(session).copied() else { return };
        let Some(o) = self.outputs[m.output].as_mut() else { return };
        let Some(media) = self.media[o.media].as_ref() else { return };
        o.last_rtcp = Some(now);
        if let Some(rtt) = round_trip(datagram, media.packetiser.ssrc(), wall) {
            o.round_trip = rtt.clamp(MIN_ROUND_TRIP, MAX_ROUND_TRIP);
        }
    }

    // ---- Traffic ----

    /// An RTCP datagram arrived over UDP from `from` at `now` (`wall`
    /// the sender reports' clock): the output whose client that is (its
    /// RTCP port, else the address's first; for a multicast group, any
    /// member's address) stays alive, its report may measure the round
    /// trip, and the packets its NACKs ask for go again, within the
    /// limits. Datagrams from any other address are ignored. Returns the
    /// session it was for.
    pub fn rtcp_received<S: SlotSource, K: RtpSink>(
        &mut self,
        from: SocketAddr,
        datagram: &[u8],
        now: Instant,
        wall: u64,
        source: &mut S,
        sink: &mut K,
    ) -> Option<SessionId> {
        let (from, port) = (from.ip(), from.port());
        let exact =
            |o: &Output| matches!(o.dest, Dest::Udp { addr, rtcp_port, .. } if addr == from && rtcp_port == port);
        let by_addr = |o: &Output, i: usize, members: &[Option<Member>; N]| match o.dest {
            Dest::Udp { addr, .. } => addr == from,
            Dest::Multicast(_) => members.iter().flatten().any(|m| m.output == i && m.client == from),
            Dest::Interleaved { .. } => false,
        };
        let i = self.outputs.iter().position(|o| o.as_ref().is_some_and(exact)).or_else(|| {
            self.outputs.iter().enumerate().position(|(i, o)| o.as_ref().is_some_and(|o| by_addr(o, i, &self.members)))
        })?;
        let session = self.members.iter().flatten().find(|m| m.output == i && (m.client == from))?.session;
        let o = self.outputs[i].as_mut()?;
        let media = self.media[o.media].as_ref()?;
        o.last_rtcp = Some(now);
        o.stats.reports = o.stats.reports.wrapping_add(1);
        o.unreachable = 0;
        if let Some(rtt) = round_trip(datagram, media.packetiser.ssrc(), wall) {
            o.round_trip = rtt.clamp(MIN_ROUND_TRIP, MAX_ROUND_TRIP);
        }
        if matches!(o.dest, Dest::Interleaved { .. }) {
            return Some(session);
        }
        // What the budget can still pay for, counting the resends queued:
        // a NACK beyond it is not even read (a flood costs a look each).
        let affordable = (o.budget / REPAIR_SHARE) as usize;
        if affordable <= o.repairs.len() {
            o.stats.nacks_unread += 1;
            return Some(session);
        }
        let mut room = affordable - o.repairs.len();
        let mut asked = false;
        for seq in NackRequests::new(datagram, media.packetiser.ssrc(), media.packetiser.highest_seq()) {
            asked = true;
            let held = media.window.lookup(seq).is_some();
            let may_resend = o.resends.may_resend(seq, now, o.round_trip);
            // Asked again, a round trip or more after it went again: a
            // round of its receiver's (sooner is a duplicate, not a round).
            if let Some(since) = o.resends.since(seq, now).filter(|_| held && may_resend) {
                o.asked_again(since);
            }
            if !held {
                o.stats.unrepairable += 1;
            } else if !may_resend {
                // Resent (or queued to be) within the round trip.
                o.stats.too_soon += 1;
            } else if room > 0 && o.repairs.push_back(seq).is_ok() {
                // Its time counts from now: the same NACK again waits.
                o.resends.resent(seq, now);
                room -= 1;
            } else {
                o.stats.over_budget += 1;
            }
        }
        send_repairs(o, &media.window, &media.packetiser, source, sink);
        if asked {
            o.lossy_until = Some(now + LOSS_MEMORY);
        }
        Some(session)
    }

    /// How long stream `media`'s frames stay repairable after their end
    /// while it loses packets: [`REPAIR_ROUNDS`] NACK rounds of its
    /// slowest output (its round trip, or how long its receiver was seen
    /// to take to ask again, the longer), at most [`MAX_FRAME_HOLD`]. The window
    /// keeps two frames, so on a stream whose frames take less than this,
    /// a frame waits (the repair window is sized by time, not frames).
    fn frame_hold(&self, media: usize) -> Duration {
        let round = self
            .outputs
            .iter()
            .flatten()
            .filter(|o| o.media == media)
            .map(Output::repair_round)
            .max()
            .unwrap_or(DEFAULT_ROUND_TRIP + NACK_REACTION);
        (round * REPAIR_ROUNDS).min(MAX_FRAME_HOLD)
    }

    /// The host at `to` answered a packet of the stream with SSRC `ssrc` to
    /// its port `port` with ICMP port unreachable: after
    /// [`UNREACHABLE_LIMIT`] of them with no RTCP in between, the output's
    /// sessions end ([`take_ended`](Self::take_ended)). A message about
    /// another stream's packet (a forged one, which would have to guess the
    /// 32-bit SSRC) counts for nothing.
    pub fn unreachable<S: SlotSource>(&mut self, to: IpAddr, port: u16, ssrc: u32, now: Instant, source: &mut S) {
        let media = &self.media;
        let ours = |m: usize| media[m].as_ref().is_some_and(|m| m.packetiser.ssrc() == ssrc);
        let hit = |o: &Option<Output>| {
            o.as_ref().is_some_and(|o| {
                matches!(o.dest, Dest::Udp { addr, rtp_port, rtcp_port } if addr == to && (rtp_port == port || rtcp_port == port))
                    && ours(o.media)
            })
        };
        let Some(i) = self.outputs.iter().position(hit) else { return };
        let Some(o) = self.outputs[i].as_mut() else { return };
        o.unreachable = o.unreachable.saturating_add(1);
        if o.unreachable >= UNREACHABLE_LIMIT {
            self.end_output(i, Gone::Unreachable, now, source);
        }
    }

    /// Do what is due at `now`: goodbyes, reports, repairs, frames begun,
    /// rows that landed sent, silent clients ended, repair packets expired.
    /// `wall` is the sender reports' clock (NTP format,
    /// [`ntp_timestamp`](crate::camera::wire::rtcp::ntp_timestamp)). Returns whether anything was sent or
    /// begun (poll again at once if so).
    pub fn poll<S: SlotSource, K: RtpSink>(&mut self, now: Instant, wall: u64, source: &mut S, sink: &mut K) -> bool {
        let mut progress = false;
        while let Some((dest, last)) = self.byes.pop_front() {
            let n = self.goodbye(SenderReport { ntp_timestamp: wall, ..last });
            let _ = sink.send_rtcp(&dest, &self.rtcp[..n]);
            progress = true;
        }
        // Clients gone quiet.
        for i in 0..N {
            let silent = self.outputs[i].as_ref().is_some_and(|o| {
                matches!(o.dest, Dest::Udp { .. })
                    && o.last_rtcp.is_some_and(|t| now.saturating_duration_since(t) >= RTCP_SILENCE)
            });
            if silent {
                self.end_output(i, Gone::Silent, now, source);
                progress = true;
            }
        }
        for i in 0..N {
            progress |= self.poll_reports(i, now, wall, sink);
        }
        for media in 0..N {
            progress |= self.poll_stream(media, now, source, sink);
        }
        if self.late_outputs > 0 {
            progress |= self.cut_late_over_budget();
            self.late_outputs =
                self.outputs.iter().flatten().filter(|o| matches!(o.cursor, Cursor::Finishing { .. })).count() as u32;
        }
        if progress {
            self.give_held(source);
        }
        progress
    }

    /// Late outputs hold their frames' slots only within the camera's
    /// [`CAMERA_SLOTS`], so that the ring's other users never wait for a
    /// laggard: beyond it a late output is cut (its client gets that frame
    /// in part). A late output shares its stream with another output, so a
    /// stream with one holds three slots and one without, at most two: with
    /// [`MAX_SESSIONS`] sessions that fits, and this guard never cuts.
    fn cut_late_over_budget(&mut self) -> bool {
        let mut cut = false;
        while self.held().count_ones() as usize > CAMERA_SLOTS {
            let windows = self.media.iter().flatten().fold(0, |held, m| held | m.window.held());
            // A late output whose slot nothing else holds.
            let Some(o) = self
                .outputs
                .iter_mut()
                .flatten()
                .find(|o| matches!(o.cursor, Cursor::Finishing { slot, .. } if windows & (1 << slot) == 0))
            else {
                break;
            };
            if let Cursor::Finishing { next, .. } = o.cursor {
                o.cursor = Cursor::Waiting { from: next.seq.wrapping_add(u32::from(ROWS - next.row)) };
                o.stats.cut += 1;
                cut = true;
            }
        }
        cut
    }

    /// `sr`, the stream's CNAME and a BYE in `self.rtcp`; its length.
    fn goodbye(&mut self, sr: SenderReport) -> usize {
        let ssrc = sr.ssrc;
        let mut n = sr.write(&mut self.rtcp).unwrap_or(0);
        let cname = self.cname();
        n += write_sdes_cname(ssrc, cname.as_bytes(), &mut self.rtcp[n..]).unwrap_or(0);
        n + write_bye(ssrc, &mut self.rtcp[n..]).unwrap_or(0)
    }

    /// Output `i`'s sender report, if due.
    fn poll_reports<K: RtpSink>(&mut self, i: usize, now: Instant, wall: u64, sink: &mut K) -> bool {
        let cname = self.cname();
        let Some(o) = self.outputs[i].as_mut() else { return false };
        let Some(m) = self.media[o.media].as_ref() else { return false };
        if o.cursor == Cursor::Paused || !o.reports.poll(now) {
            return false;
        }
        let sr = m.packetiser.sender_report(wall, m.media_ticks(now));
        let n = sr.write(&mut self.rtcp).unwrap_or(0);
        let k = write_sdes_cname(m.packetiser.ssrc(), cname.as_bytes(), &mut self.rtcp[n..]).unwrap_or(0);
        let _ = sink.send_rtcp(&o.dest, &self.rtcp[..n + k]);
        true
    }

    /// Stream `media`'s repairs, frame and rows.
    fn poll_stream<S: SlotSource, K: RtpSink>(
        &mut self,
        mi: usize,
        now: Instant,
        source: &mut S,
        sink: &mut K,
    ) -> bool {
        let hold = self.frame_hold(mi);
        let Some(media) = self.media[mi].as_mut() else { return false };
        let mut progress = false;
        // Packets expire by time only between frames: a frame's hold
        // starts when its last row went, however long it took.
        if media.current.is_none() && media.window.expire(now).released != 0 {
            progress = true;
        }
        // Repairs first: a receiver waits for them more than for new rows.
        let mut repairs_left = false;
        for o in self.outputs.iter_mut() {
            let Some(o) = o.as_mut().filter(|o| o.media == mi && !o.repairs.is_empty()) else { continue };
            let before = o.stats.resent;
            repairs_left |= !send_repairs(o, &media.window, &media.packetiser, source, sink);
            progress |= o.stats.resent != before;
        }
        // Late outputs finish their frames; nothing waits for them.
        if self.late_outputs > 0 {
            for o in self.outputs.iter_mut().flatten().filter(|o| o.media == mi) {
                progress |= finish_late(o, &media.packetiser, source, sink, now);
            }
        }
        if !media.running {
            return progress;
        }
        if media.current.is_none() {
            if repairs_left {
                return progress;
            }
            let interval = media.spec.fps.interval();
            if interval.is_some_and(|_| now < media.due) {
                return progress;
            }
            // It waits for repairs only while every output playing it loses
            // packets: beside one that loses nothing, waiting would make a
            // lossy viewer's repairs everyone's frame rate (a laggard slows
            // only itself, as below). Alone, it waits for its own.
            let mut playing =
                self.outputs.iter().flatten().filter(|o| o.media == mi && o.cursor != Cursor::Paused).peekable();
            let all_lossy = playing.peek().is_some() && playing.all(|o| o.lossy_until.is_some_and(|t| now < t));
            media.repair_wait = media.repairable_until(all_lossy, hold).filter(|&t| now < t);
            if media.repair_wait.is_some() {
                return progress;
            }
            let ticks = media.media_ticks(now);
            let light = media.spec.light_at(Duration::from_micros(ticks * 100 / 9), media.live);
            // The window keeps the frame before the new one and no older
            // one: forget the older one first, so that its slot may take the
            // new frame (the source learns at once; with a late output,
            // which may read that slot too, at the poll's end).
            if let Some(p) = media.previous_first {
                let released = media.window.forget_before(p).released;
                if released != 0 && self.late_outputs == 0 {
                    self.held_given &= !released;
                    source.set_held(self.held_given);
                }
            }
            match source.begin(&light) {
                Ok(Some(slot)) => {
                    let stamp = media.packetiser.begin_frame(ticks);
                    let first_seq = media.packetiser.next_seq();
                    media.current =
                        Some(Frame { slot, stamp, first_seq, landed: 0, recorded: 0, begun_at: now, done_at: None });
                    self.frame_edges = self.frame_edges.wrapping_add(1);
                    if let Some(iv) = interval {
                        // Keep the rate; after a stall, start afresh.
                        media.due =
                            if now.saturating_duration_since(media.due) > iv { now + iv } else { media.due + iv };
                    }
                    for o in self.outputs.iter_mut().flatten().filter(|o| o.media == mi) {
                        if let Cursor::Waiting { from } = o.cursor {
                            if (first_seq.wrapping_sub(from) as i32) >= 0 {
                                o.cursor = Cursor::Sending { next: 0 };
                                o.stalled_since = None;
                                if matches!(o.dest, Dest::Interleaved { .. }) {
                                    o.seq_shift = o.seq_shift.wrapping_add(first_seq.wrapping_sub(from));
                                }
                            }
                        }
                    }
                    progress = true;
                }
                Ok(None) => return progress,
                Err(_) => {
                    media.stats.failed += 1;
                    if let Some(iv) = interval {
                        media.due = now + iv;
                    }
                    return progress;
                }
            }
        }
        let Some(mut frame) = media.current else { return progress };
        // The rows landed, asking again while the source lands more: rows
        // go in runs of up to MIN_RUN gathered while they keep coming, so
        // the per-run work is paid once a run, not once a row. A run goes
        // as soon as the source has nothing more right now, so no row
        // waits for a later one that is not on its way.
        let mut failed = false;
        let mut seen = frame.landed;
        // The furthest-behind output's next row; it changes only when rows
        // go, so it is worked out again only then. A client's connection
        // that took nothing (a laggard, interleaved) is left out while
        // another output still takes rows of the frame: it would make every
        // look a run of its own for everyone else (it is offered rows with
        // every run that goes). With no such other output it counts, or it
        // would be offered none.
        let behind_of = |outputs: &[Option<Output>; N]| {
            let (mut all, mut taking): (Option<u16>, Option<u16>) = (None, None);
            for o in outputs.iter().flatten().filter(|o| o.media == mi) {
                if let Cursor::Sending { next } = o.cursor {
                    all = Some(all.map_or(next, |m| m.min(next)));
                    if !o.connection_stalled() {
                        taking = Some(taking.map_or(next, |m| m.min(next)));
                    }
                }
            }
            match taking {
                Some(t) if t < ROWS => Some(t),
                _ => all,
            }
        };
        let mut behind = behind_of(&self.outputs);
        loop {
            let ready = match source.rows_ready(frame.slot) {
                Ok(r) => r.min(ROWS),
                Err(_) => {
                    failed = true;
                    break;
                }
            };
            let landing = ready > seen;
            seen = ready;
            // Rows still landing, not yet a run's worth for the output
            // furthest behind: look again at once (the common case, kept
            // to a compare or two: a frame takes a few hundred looks).
            if landing && ready < ROWS && behind.is_some_and(|b| ready < b + MIN_RUN) {
                continue;
            }
            if ready > frame.landed {
                media.packetiser.advance(ready - frame.landed);
                frame.landed = ready;
            }
            let mut refused = false;
            if let Some(b) = behind.filter(|&b| ready > b) {
                if ready - b >= MIN_RUN || ready == ROWS || !landing {
                    record_landed(&mut media.window, &mut frame, now);
                    for o in self.outputs.iter_mut().flatten().filter(|o| o.media == mi) {
                        let Cursor::Sending { next } = o.cursor else { continue };
                        if next >= ready {
                            continue;
                        }
                        let want = ready - next;
                        let first = o.numbered(frame.packet(next));
                        let sent = sink.send_rows(&o.dest, &media.packetiser, &first, want, frame.slot, source);
                        let sent = sent.min(want);
                        o.stats.packets += u32::from(sent);
                        // A group's budget grows with its receivers: each
                        // loses packets of its own.
                        let receivers = match o.dest {
                            Dest::Multicast(_) => u32::from(o.playing.max(1)),
                            _ => 1,
                        };
                        o.budget =
                            (o.budget + u32::from(sent) * receivers).min(REPAIR_SHARE * REPAIR_BURST * receivers);
                        let next = next + sent;
                        o.cursor = Cursor::Sending { next };
                        if sent > 0 {
                            progress = true;
                            o.stalled_since = None;
                        }
                        if sent < want {
                            // The transmitter is full: the others wait too.
                            // A connection already taking nothing holds
                            // back no one.
                            refused |= !o.connection_stalled();
                            o.stalled_since.get_or_insert(now);
                        }
                    }
                    behind = behind_of(&self.outputs);
                    if sink.should_yield() {
                        break;
                    }
                }
            }
            if refused || !landing || frame.landed == ROWS {
                break;
            }
            if behind.is_none() && sink.should_yield() {
                // Rows landing for no output yet: something received goes first.
                break;
            }
        }
        record_landed(&mut media.window, &mut frame, now);
        // Outputs done with the frame, or stalled too long, wait for the next.
        let next_frame = frame.first_seq.wrapping_add(u32::from(ROWS));
        // The frame counts as had once an output has every row of it, or
        // once every row landed while an output waits for the next frame
        // (one that joined, or was cut from this one): a stream whose only
        // reader stopped reading must not keep a joining viewer waiting for
        // that reader's stall limit.
        let had = frame.done_at.is_none()
            && self.outputs.iter().flatten().any(|o| {
                o.media == mi
                    && (o.cursor == Cursor::Sending { next: ROWS }
                        || (frame.landed == ROWS && matches!(o.cursor, Cursor::Waiting { .. })))
            });
        if had {
            frame.done_at.get_or_insert(now);
        }
        // Outputs still sending once the next frame is due (fps=N), or once
        // the first output has had the frame for as long again as it took
        // (fps=max), lose the rest of it, as gst-rtsp-server drops a slow
        // client's backlog: a laggard slows only itself.
        let lag_limit = frame.done_at.map(|done| match media.spec.fps.interval() {
            Some(_) => media.due.max(done),
            None => done + done.saturating_duration_since(frame.begun_at).max(MIN_LAG),
        });
        let lagging = frame.landed == ROWS && lag_limit.is_some_and(|t| now >= t);
        for o in self.outputs.iter_mut().flatten().filter(|o| o.media == mi) {
            match o.cursor {
                Cursor::Sending { next } if next == ROWS => {
                    o.cursor = Cursor::Waiting { from: next_frame };
                    o.stats.frames += 1;
                }
                Cursor::Sending { .. } if failed => o.cursor = Cursor::Waiting { from: next_frame },
                Cursor::Sending { next } if lagging => {
                    // Slots number fewer than 32 (the held masks' bits).
                    o.cursor = Cursor::Finishing { slot: frame.slot as u8, next: frame.packet(next) };
                    o.stats.late += 1;
                    self.late_outputs += 1;
                }
                Cursor::Sending { .. }
                    if o.stalled_since.is_some_and(|t| now.saturating_duration_since(t) >= o.stall_limit()) =>
                {
                    o.cursor = Cursor::Waiting { from: next_frame };
                    o.stats.cut += 1;
                }
                _ => {}
            }
        }
        let sending =
            self.outputs.iter().flatten().any(|o| o.media == mi && matches!(o.cursor, Cursor::Sending { .. }));
        if failed || (frame.landed == ROWS && !sending) {
            // The ring frees the slot, but the repair window (and any late
            // output) still reads it: the source must know at once, not at
            // the poll's end, or a stream polled after this one could
            // begin its frame there and overwrite these repairs.
            if let Some(bit) = 1u32.checked_shl(frame.slot as u32) {
                self.held_given |= bit;
                source.set_held(self.held_given);
            }
            source.end(frame.slot);
            media.window.restart_hold(frame.first_seq, now);
            if failed {
                media.packetiser.skip_to(next_frame);
                media.stats.failed += 1;
            } else {
                media.stats.frames += 1;
            }
            media.frame_ended(frame.first_seq, now);
            media.current = None;
            self.frame_edges = self.frame_edges.wrapping_add(1);
            progress = true;
        } else {
            media.current = Some(frame);
        }
        progress
    }

    /// When [`poll`](Self::poll) next has something to do by the clock
    /// alone (a frame due, a report, a silent client to end), if no stream
    /// waits for rows, the sink or a slot; the caller polls at least this
    /// often, and whenever the source may have progressed.
    pub fn next_deadline(&self) -> Option<Instant> {
        let frames = self.media.iter().flatten().filter_map(|m| {
            if !m.running || m.current.is_some() {
                return None;
            }
            let due = m.spec.fps.interval().map(|_| m.due);
            // None orders before Some: the later of the two, or either.
            due.max(m.repair_wait)
        });
        let outputs = self.outputs.iter().flatten().flat_map(|o| {
            let reports = (o.cursor != Cursor::Paused).then(|| o.reports.deadline());
            let silence = match o.dest {
                Dest::Udp { .. } => o.last_rtcp.map(|t| t + RTCP_SILENCE),
                _ => None,
            };
            [reports, silence]
        });
        frames.chain(outputs.flatten()).min()
    }

    /// Frames begun plus frames ended (sent or abandoned) over all
    /// streams since the camera was made (wrapping): a caller that stops
    /// polling when it changes handles one frame edge a turn.
    pub fn frame_edges(&self) -> u32 {
        self.frame_edges
    }

    /// Whether any stream is sending a frame, or has repairs, a late
    /// frame or goodbyes waiting: the caller should poll again soon.
    pub fn busy(&self) -> bool {
        !self.byes.is_empty()
            || self.media.iter().flatten().any(|m| m.current.is_some())
            || self
                .outputs
                .iter()
                .flatten()
                .any(|o| !o.repairs.is_empty() || matches!(o.cursor, Cursor::Finishing { .. }))
    }
}

/// Record `frame`'s rows landed since the last call in `window`, in one
/// run.
fn record_landed(window: &mut FrameRepairWindow, frame: &mut Frame, now: Instant) {
    if frame.landed > frame.recorded {
        let _ = window.record_run(now, frame.slot, frame.packet(frame.recorded), frame.landed - frame.recorded);
        frame.recorded = frame.landed;
    }
}

/// Send a [`Cursor::Finishing`] output's rows left of its frame while the
/// sink takes them; whether any went. One that takes none for its stall
/// limit is cut.
fn finish_late<S: FrameSource<Frame = usize>, K: RtpSink>(
    o: &mut Output,
    packetiser: &Packetiser,
    source: &mut S,
    sink: &mut K,
    now: Instant,
) -> bool {
    let Cursor::Finishing { slot, next } = o.cursor else { return false };
    let want = ROWS - next.row;
    let end = next.seq.wrapping_add(u32::from(want));
    let numbered = o.numbered(next);
    let sent = sink.send_rows(&o.dest, packetiser, &numbered, want, usize::from(slot), source).min(want);
    o.stats.packets += u32::from(sent);
    if sent == 0 {
        let since = *o.stalled_since.get_or_insert(now);
        if now.saturating_duration_since(since) >= o.stall_limit() {
            o.cursor = Cursor::Waiting { from: end };
            o.stats.cut += 1;
            return true;
        }
        return false;
    }
    o.stalled_since = None;
    o.cursor = if sent == want {
        o.stats.frames += 1;
        Cursor::Waiting { from: end }
    } else {
        Cursor::Finishing { slot, next: next.nth(sent) }
    };
    true
}

/// Resend output `o`'s NACKed packets still waiting, oldest request first,
/// while the sink takes them; whether none is left.
fn send_repairs<S: FrameSource<Frame = usize>, K: RtpSink>(
    o: &mut Output,
    window: &FrameRepairWindow,
    packetiser: &Packetiser,
    source: &mut S,
    sink: &mut K,
) -> bool {
    // Each was checked against the round trip and the budget when it was
    // queued (`rtcp_received`).
    while let Some(&seq) = o.repairs.front() {
        match window.lookup(seq) {
            // Left the window while it waited.
            None => o.stats.unrepairable += 1,
            Some(r) => {
                if sink.send_rows(&o.dest, packetiser, &r.packet, 1, r.slot, source) == 0 {
                    return false;
                }
                o.budget = o.budget.saturating_sub(REPAIR_SHARE);
                o.stats.resent += 1;
            }
        }
        o.repairs.pop_front();
    }
    true
}

/// The camera, the frame source and the time, as the RTSP server's
/// [`Streams`]: what [`rtsp::Server::handle`](crate::camera::rtsp::Server::handle)
/// and its `poll` are given. `wall` is the sender reports' clock.
pub struct Bound<'a, S, const N: usize = MAX_SESSIONS> {
    /// The camera.
    pub camera: &'a mut Camera<N>,
    /// Its frames.
    pub source: &'a mut S,
    /// Now.
    pub now: Instant,
    /// Now on the sender reports' clock (NTP format).
    pub wall: u64,
}

impl<S: SlotSource, const N: usize> Streams for Bound<'_, S, N> {
    fn setup(
        &mut self,
        session: SessionId,
        spec: &StreamSpec,
        transport: Transport,
        _profile: Profile,
        client: Client,
        fresh: Fresh,
    ) -> Result<SetUp, Status> {
        let r = self.camera.setup_session(session, spec, transport, client, fresh, self.now, self.source);
        self.camera.give_held(self.source);
        r
    }

    fn play(&mut self, session: SessionId) -> Result<Position, Status> {
        self.camera.play_session(session, self.now)
    }

    fn pause(&mut self, session: SessionId) {
        self.camera.pause_session(session, self.now, self.source);
    }

    fn end(&mut self, session: SessionId, _why: EndReason) {
        self.camera.leave(session, self.now, self.source, true);
        self.camera.give_held(self.source);
    }

    fn set_light(&mut self, session: SessionId, light: Light) {
        let Some(m) = self.camera.member(session).copied() else { return };
        let Some(o) = self.camera.outputs[m.output].as_ref() else { return };
        if let Some(media) = self.camera.media[o.media].as_mut() {
            if media.spec.light == LightSource::Live {
                media.live = light;
            }
        }
    }

    fn rtcp(&mut self, session: SessionId, datagram: &[u8]) {
        self.camera.interleaved_rtcp(session, datagram, self.now, self.wall);
    }

    fn group(&self, spec: &StreamSpec) -> Option<Group> {
        let i = self.camera.stream_for(spec).or_else(|| self.camera.media.iter().position(Option::is_none))?;
        self.camera.group_of(i)
    }
}

impl<M: crate::frames::FrameMemory, E: crate::frames::FrameEngine<M>, const SLOTS: usize> SlotSource
    for crate::frames::FrameRing<M, E, SLOTS>
{
    fn set_held(&mut self, mask: u32) {
        crate::frames::FrameRing::set_held(self, mask)
    }
}

#[cfg(test)]
mod tests;
