//! Frames as an RTP stream: uncompressed video per RFC 4175, one row a
//! packet, with RTCP sender reports and NACK-driven retransmission.
//!
//! Like the rest of the crate this is sans-IO: it writes headers into the
//! caller's buffers and parses the caller's datagrams; it sends nothing,
//! allocates nothing and knows no clock but the times it is handed.
//!
//! # A packet
//!
//! Each 480-pixel row of a frame is one RTP packet (RFC 3550 section 5.1,
//! RFC 4175 section 4):
//!
//! | bytes | field |
//! |---|---|
//! | 0 | V = 2, P = 0, X = 0, CC = 0 (`0x80`) |
//! | 1 | M (the frame's last row) and PT ([`PAYLOAD_TYPE`], 96) |
//! | 2..4 | sequence number: the low 16 bits of the extended counter |
//! | 4..8 | timestamp, 90 kHz ([`CLOCK_RATE`]); one per frame |
//! | 8..12 | SSRC |
//! | 12..14 | RFC 4175 extended sequence number: the high 16 bits |
//! | 14..16 | line header: Length = 1,440 octets |
//! | 16..18 | F = 0, Line No = the row |
//! | 18..20 | C = 0 (no further line), Offset = 0 pixels |
//! | 20..1460 | the row, 480 RGB888 pixels ([`ROW_BYTES`]) |
//!
//! GStreamer's `rtpvrawdepay` and FFmpeg's `rtpdec_rfc4175.c` read the
//! payload this way (`sampling=RGB, depth=8, width=480, height=360`).
//! With Ethernet (14), IPv4 (20) and UDP (8) headers a packet's headers are
//! [`FRAME_HEADER_BYTES`] = 62 bytes, which the board's zero-copy transmit
//! path puts in one buffer (`HeaderTemplate`, feature `smoltcp`) and the
//! row, straight from the frame ring, in a second.
//!
//! # The parts
//!
//! * [`Packetiser`]: one RTP session's sender state: SSRC, payload type,
//!   the extended sequence counter, frame timestamps, and the packet and
//!   octet counts for [`SenderReport`]s. It writes the 20 RTP + RFC 4175
//!   header bytes of a row ([`Packetiser::write_header`]).
//! * `HeaderTemplate` (feature `smoltcp`): the 62-byte Ethernet + IPv4 +
//!   UDP + RTP + RFC 4175 header of a row.
//! * RTCP (RFC 3550 section 6): [`SenderReport`], an SDES CNAME
//!   ([`write_sdes_cname`]), when to send them ([`ReportTimer`]), and the
//!   receiver's generic NACKs (RFC 4585 section 6.2.1) read out of any
//!   compound packet by [`NackRequests`].
//! * [`RepairWindow`]: which frame slot and row each recent packet came
//!   from, so a NACKed packet can be sent again unchanged (same SSRC, PT,
//!   sequence number and timestamp) from the frame ring, and which ring
//!   slots must therefore stay out of reuse.

use core::time::Duration;

use model::ROW_BYTES;

use crate::frames::ROWS;
use crate::time::Instant;

/// The dynamic RTP payload type the stream uses (RFC 3551 section 6: 96 to
/// 127 are dynamic; the session description maps it to `raw/90000`).
pub const PAYLOAD_TYPE: u8 = 96;

/// The RTP clock of uncompressed video: 90 kHz (RFC 4175 section 6.1,
/// "rate": 90000).
pub const CLOCK_RATE: u32 = 90_000;

/// Bytes of the fixed RTP header without CSRCs (RFC 3550 section 5.1).
pub const RTP_HEADER_BYTES: usize = 12;

/// Bytes of the RFC 4175 payload header for one line: the extended
/// sequence number (2) and one line header (6) (RFC 4175 section 4.3).
pub const PAYLOAD_HEADER_BYTES: usize = 8;

/// Bytes of RTP and RFC 4175 headers in front of a row: 12 + 2 + 6.
pub const HEADER_BYTES: usize = RTP_HEADER_BYTES + PAYLOAD_HEADER_BYTES;

/// Bytes of RTP payload per packet: the RFC 4175 payload header and the row
/// (what a [`SenderReport`]'s octet count adds up, RFC 3550 section 6.4.1).
pub const PAYLOAD_BYTES: usize = PAYLOAD_HEADER_BYTES + ROW_BYTES;

/// Bytes of a whole RTP packet (the UDP payload): 20 + 1,440 = 1,460.
pub const PACKET_BYTES: usize = HEADER_BYTES + ROW_BYTES;

/// Bytes of an Ethernet II header (destination, source, EtherType).
pub const ETHERNET_HEADER_BYTES: usize = 14;
/// Bytes of an IPv4 header without options (RFC 791 section 3.1).
pub const IPV4_HEADER_BYTES: usize = 20;
/// Bytes of a UDP header (RFC 768).
pub const UDP_HEADER_BYTES: usize = 8;

/// The IPv4 total length of a packet: 20 + 8 + 1,460 = 1,488.
pub const IPV4_TOTAL_LENGTH: u16 = (IPV4_HEADER_BYTES + UDP_HEADER_BYTES + PACKET_BYTES) as u16;
/// The UDP length of a packet: 8 + 1,460 = 1,468.
pub const UDP_LENGTH: u16 = (UDP_HEADER_BYTES + PACKET_BYTES) as u16;

/// Bytes of every header in front of a row on the wire: 14 + 20 + 8 + 20 = 62.
pub const FRAME_HEADER_BYTES: usize = ETHERNET_HEADER_BYTES + IPV4_HEADER_BYTES + UDP_HEADER_BYTES + HEADER_BYTES;

/// RTP timestamp ticks in a millisecond of the crate's [`Instant`].
const TICKS_PER_MILLI: u64 = CLOCK_RATE as u64 / 1_000;

/// 90 kHz ticks since the clock's origin at `t` (what
/// [`Packetiser::begin_frame`] and [`Packetiser::sender_report`] take).
pub const fn ticks(t: Instant) -> u64 {
    t.millis().saturating_mul(TICKS_PER_MILLI)
}

/// The caller's buffer is shorter than what is to be written into it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferTooShort {
    /// Bytes needed.
    pub needed: usize,
}

impl core::fmt::Display for BufferTooShort {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "buffer too short: {} bytes needed", self.needed)
    }
}

/// The first `n` bytes of `out`, or how many were needed.
fn front(out: &mut [u8], n: usize) -> Result<&mut [u8], BufferTooShort> {
    out.get_mut(..n).ok_or(BufferTooShort { needed: n })
}

// ---- RTP data packets --------------------------------------------------------------

/// The timestamp of one frame's packets (RFC 3550 section 5.1: "the
/// sampling instant of the first octet in the RTP data packet"; RFC 4175
/// section 4.1: every packet of a frame carries the frame's timestamp).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FrameStamp {
    /// The 32-bit RTP timestamp, offset by the session's random origin.
    pub timestamp: u32,
}

/// What identifies one row's packet: enough to write its headers again,
/// byte for byte, when it is retransmitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RowPacket {
    /// The extended (32-bit) sequence number: the RTP header carries the
    /// low 16 bits, the RFC 4175 payload header the high 16.
    pub seq: u32,
    /// The frame's RTP timestamp.
    pub timestamp: u32,
    /// The row, `0..360`; the last row carries the marker bit.
    pub row: u16,
}

impl RowPacket {
    /// Whether the packet carries the marker bit: it holds the frame's last
    /// row (RFC 4175 section 4.1, "M bit").
    pub const fn marker(&self) -> bool {
        self.row == ROWS - 1
    }

    /// The packet `k` after this one in a run of consecutive rows of the
    /// same frame: sequence number and row `k` on.
    pub const fn nth(&self, k: u16) -> RowPacket {
        RowPacket { seq: self.seq.wrapping_add(k as u32), timestamp: self.timestamp, row: self.row.wrapping_add(k) }
    }
}

/// Why a row cannot be packetised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PacketError {
    /// The buffer cannot hold the headers.
    BufferTooShort(BufferTooShort),
    /// The row is not `0..360`.
    BadRow(u16),
}

impl core::fmt::Display for PacketError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PacketError::BufferTooShort(e) => e.fmt(f),
            PacketError::BadRow(y) => write!(f, "row {y} is not in 0..{ROWS}"),
        }
    }
}

impl From<BufferTooShort> for PacketError {
    fn from(e: BufferTooShort) -> PacketError {
        PacketError::BufferTooShort(e)
    }
}

/// The sender side of one RTP session (RFC 3550 section 5.1 and 6.4.1):
/// one SSRC, one payload type, the extended sequence counter, the frame
/// timestamps, and the counts a [`SenderReport`] carries.
///
/// RFC 3550 asks for random initial values of the sequence number and of
/// the timestamp (section 5.1) and a random SSRC (section 8.1); the crate
/// has no random source, so the caller supplies all three.
#[derive(Clone, Debug)]
pub struct Packetiser {
    ssrc: u32,
    payload_type: u8,
    /// The extended sequence number of the next new packet.
    next_seq: u32,
    /// Whether any packet was numbered yet.
    sent_any: bool,
    /// Added to the tick count to form RTP timestamps.
    timestamp_origin: u32,
    /// The ticks of the newest frame, to keep frame timestamps strictly
    /// increasing.
    last_frame_ticks: Option<u64>,
    packets: u32,
    octets: u32,
}

impl Packetiser {
    /// A session with synchronisation source `ssrc`, first extended
    /// sequence number `first_seq`, and RTP timestamp `timestamp_origin` at
    /// tick 0, sending [`PAYLOAD_TYPE`].
    pub const fn new(ssrc: u32, first_seq: u32, timestamp_origin: u32) -> Packetiser {
        Packetiser {
            ssrc,
            payload_type: PAYLOAD_TYPE,
            next_seq: first_seq,
            sent_any: false,
            timestamp_origin,
            last_frame_ticks: None,
            packets: 0,
            octets: 0,
        }
    }

    /// The same session sending payload type `pt` (7 bits; the top bit is
    /// dropped) instead of [`PAYLOAD_TYPE`].
    pub const fn with_payload_type(mut self, pt: u8) -> Packetiser {
        self.payload_type = pt & 0x7f;
        self
    }

    /// The session's SSRC.
    pub const fn ssrc(&self) -> u32 {
        self.ssrc
    }

    /// The payload type it sends.
    pub const fn payload_type(&self) -> u8 {
        self.payload_type
    }

    /// The extended sequence number of the newest packet numbered so far
    /// (what a NACK's 16-bit PID is resolved against, [`NackRequests`]), or
    /// `None` before the first.
    pub const fn highest_seq(&self) -> Option<u32> {
        if self.sent_any {
            Some(self.next_seq.wrapping_sub(1))
        } else {
            None
        }
    }

    /// The RTP timestamp of tick `ticks` (90 kHz since the caller's origin),
    /// with the session's random offset (wrapping, as RTP timestamps do).
    pub const fn timestamp_at(&self, ticks: u64) -> u32 {
        self.timestamp_origin.wrapping_add(ticks as u32)
    }

    /// Stamp a new frame sampled at `ticks` (90 kHz since the caller's
    /// origin; [`ticks`] converts an [`Instant`]). Frames get strictly
    /// increasing timestamps: a frame begun on the same tick as the one
    /// before (or, by a misbehaving clock, earlier) gets the tick after it,
    /// so consecutive frames never share a timestamp, even at `fps=max`.
    pub fn begin_frame(&mut self, ticks: u64) -> FrameStamp {
        let ticks = match self.last_frame_ticks {
            Some(last) if ticks <= last => last.saturating_add(1),
            _ => ticks,
        };
        self.last_frame_ticks = Some(ticks);
        FrameStamp { timestamp: self.timestamp_at(ticks) }
    }

    /// The packet [`next_packet`](Self::next_packet) would number for row
    /// `row` of `frame`, numbering nothing: for a sender that writes the
    /// packet first and numbers it only once it went out.
    pub fn peek_packet(&self, frame: FrameStamp, row: u16) -> Result<RowPacket, PacketError> {
        if row >= ROWS {
            return Err(PacketError::BadRow(row));
        }
        Ok(RowPacket { seq: self.next_seq, timestamp: frame.timestamp, row })
    }

    /// Number `n` packets at once, the ones [`peek_packet`](Self::peek_packet)
    /// and the consecutive rows after it ([`RowPacket::nth`]) would be:
    /// [`next_packet`](Self::next_packet) `n` times, for a sender that sent
    /// a run of rows.
    pub fn advance(&mut self, n: u16) {
        if n == 0 {
            return;
        }
        let n = u32::from(n);
        self.next_seq = self.next_seq.wrapping_add(n);
        self.sent_any = true;
        self.packets = self.packets.wrapping_add(n);
        self.octets = self.octets.wrapping_add(n.wrapping_mul(PAYLOAD_BYTES as u32));
    }

    /// Number the packet of row `row` of `frame`: takes the next extended
    /// sequence number and counts the packet for the sender reports.
    pub fn next_packet(&mut self, frame: FrameStamp, row: u16) -> Result<RowPacket, PacketError> {
        if row >= ROWS {
            return Err(PacketError::BadRow(row));
        }
        let seq = self.next_seq;
        self.next_seq = seq.wrapping_add(1);
        self.sent_any = true;
        self.packets = self.packets.wrapping_add(1);
        self.octets = self.octets.wrapping_add(PAYLOAD_BYTES as u32);
        Ok(RowPacket { seq, timestamp: frame.timestamp, row })
    }

    /// Write the 20 RTP + RFC 4175 header bytes of `packet` into the front
    /// of `out` (RFC 3550 section 5.1, RFC 4175 section 4.3). Nothing is
    /// numbered or counted: this writes a new packet's header after
    /// [`next_packet`](Self::next_packet), and a retransmitted one's again.
    pub fn emit(&self, packet: &RowPacket, out: &mut [u8]) -> Result<(), BufferTooShort> {
        let out = front(out, HEADER_BYTES)?;
        let marker = if packet.marker() { 0x80 } else { 0 };
        out[0] = 2 << 6; // V = 2, P = 0, X = 0, CC = 0
        out[1] = marker | self.payload_type;
        out[2..4].copy_from_slice(&(packet.seq as u16).to_be_bytes());
        out[4..8].copy_from_slice(&packet.timestamp.to_be_bytes());
        out[8..12].copy_from_slice(&self.ssrc.to_be_bytes());
        // RFC 4175 section 4.3: Extended Sequence Number, then one line
        // header: Length (octets), F + Line No, C + Offset (pixels).
        out[12..14].copy_from_slice(&((packet.seq >> 16) as u16).to_be_bytes());
        out[14..16].copy_from_slice(&(ROW_BYTES as u16).to_be_bytes());
        out[16..18].copy_from_slice(&(packet.row & 0x7fff).to_be_bytes());
        out[18..20].copy_from_slice(&0u16.to_be_bytes());
        Ok(())
    }

    /// Number row `row` of `frame` and write its 20 header bytes into the
    /// front of `out` ([`next_packet`](Self::next_packet) and
    /// [`emit`](Self::emit)). Nothing is numbered when it fails.
    pub fn write_header(&mut self, frame: FrameStamp, row: u16, out: &mut [u8]) -> Result<RowPacket, PacketError> {
        if out.len() < HEADER_BYTES {
            return Err(BufferTooShort { needed: HEADER_BYTES }.into());
        }
        let packet = self.next_packet(frame, row)?;
        self.emit(&packet, out)?;
        Ok(packet)
    }

    /// A sender report for now (RFC 3550 section 6.4.1): `ntp` the wall
    /// clock in NTP format ([`ntp_timestamp`]), `ticks` the same instant on
    /// the 90 kHz clock frames are stamped with (so the report's RTP
    /// timestamp lines up with the frames'), and the packets and payload
    /// octets numbered so far (new packets only: retransmissions reuse
    /// their original numbers and are not counted again).
    pub const fn sender_report(&self, ntp: u64, ticks: u64) -> SenderReport {
        SenderReport {
            ssrc: self.ssrc,
            ntp_timestamp: ntp,
            rtp_timestamp: self.timestamp_at(ticks),
            packet_count: self.packets,
            octet_count: self.octets,
        }
    }
}

// ---- RTCP ----------------------------------------------------------------------

/// RTCP packet type of a sender report (RFC 3550 section 6.4.1).
pub const RTCP_SR: u8 = 200;
/// RTCP packet type of a receiver report (RFC 3550 section 6.4.2).
pub const RTCP_RR: u8 = 201;
/// RTCP packet type of source description items (RFC 3550 section 6.5).
pub const RTCP_SDES: u8 = 202;
/// RTCP packet type of transport-layer feedback (RFC 4585 section 6.1).
pub const RTCP_RTPFB: u8 = 205;
/// The FMT of a generic NACK in transport-layer feedback (RFC 4585
/// section 6.2.1).
pub const FMT_GENERIC_NACK: u8 = 1;

/// Bytes of a sender report without report blocks (RFC 3550 section
/// 6.4.1): header 4, SSRC 4, sender info 20.
pub const SENDER_REPORT_BYTES: usize = 28;

/// The interval between RTCP reports: RFC 3550 section 6.2's recommended
/// minimum of 5 seconds. One unicast sender has no one to synchronise with
/// by accident, so the interval is not randomised (section 6.3.1 draws it
/// from `[0.5, 1.5]` times this to keep many participants apart).
pub const REPORT_INTERVAL: Duration = Duration::from_secs(5);

/// Seconds from the NTP era 0 origin (1900-01-01) to the Unix epoch.
const NTP_UNIX_OFFSET: u64 = 2_208_988_800;

/// The 64-bit NTP timestamp (RFC 3550 section 4: seconds since 1900 in the
/// high 32 bits, the fraction in the low 32; era 0 wraps in 2036) of a wall
/// clock reading `since_unix_epoch`.
pub const fn ntp_timestamp(since_unix_epoch: Duration) -> u64 {
    let secs = since_unix_epoch.as_secs().wrapping_add(NTP_UNIX_OFFSET) & 0xffff_ffff;
    let frac = ((since_unix_epoch.subsec_nanos() as u64) << 32) / 1_000_000_000;
    secs << 32 | frac
}

/// The first word of an RTCP packet: V = 2, padding, the count (or FMT)
/// field, the packet type, and the length in 32-bit words minus one (RFC
/// 3550 section 6.4.1).
fn rtcp_header(count: u8, pt: u8, bytes: usize) -> [u8; 4] {
    let words = (bytes / 4 - 1) as u16;
    let [hi, lo] = words.to_be_bytes();
    [2 << 6 | (count & 0x1f), pt, hi, lo]
}

/// An RTCP sender report without reception report blocks (RFC 3550
/// section 6.4.1): the stream's sender never receives RTP, so RC = 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SenderReport {
    /// The sender's SSRC.
    pub ssrc: u32,
    /// The wall clock when the report was made, NTP format
    /// ([`ntp_timestamp`]).
    pub ntp_timestamp: u64,
    /// The same instant on the RTP clock, with the data packets' offset.
    pub rtp_timestamp: u32,
    /// RTP data packets sent since the session started (wrapping).
    pub packet_count: u32,
    /// RTP payload octets sent since the session started (wrapping; the
    /// RFC 4175 payload headers and the rows, not the RTP headers).
    pub octet_count: u32,
}

impl SenderReport {
    /// Write the report, [`SENDER_REPORT_BYTES`] bytes, into the front of
    /// `out`; returns the bytes written. An RTCP compound packet begins
    /// with it (RFC 3550 section 6.1); [`write_sdes_cname`] writes the
    /// CNAME that should follow.
    pub fn write(&self, out: &mut [u8]) -> Result<usize, BufferTooShort> {
        let out = front(out, SENDER_REPORT_BYTES)?;
        out[0..4].copy_from_slice(&rtcp_header(0, RTCP_SR, SENDER_REPORT_BYTES));
        out[4..8].copy_from_slice(&self.ssrc.to_be_bytes());
        out[8..16].copy_from_slice(&self.ntp_timestamp.to_be_bytes());
        out[16..20].copy_from_slice(&self.rtp_timestamp.to_be_bytes());
        out[20..24].copy_from_slice(&self.packet_count.to_be_bytes());
        out[24..28].copy_from_slice(&self.octet_count.to_be_bytes());
        Ok(SENDER_REPORT_BYTES)
    }
}

/// Bytes of an SDES packet with one chunk holding one CNAME of
/// `cname_len` octets: header 4, SSRC 4, item type and length 2, the text,
/// and 1 to 4 null octets ending the item list at a 32-bit boundary (RFC
/// 3550 section 6.5).
pub const fn sdes_cname_bytes(cname_len: usize) -> usize {
    8 + ((2 + cname_len) / 4 + 1) * 4
}

/// Write an SDES packet with `ssrc`'s CNAME item (RFC 3550 section 6.5.1:
/// every compound RTCP packet carries one, after the report) into the
/// front of `out`; returns the bytes written ([`sdes_cname_bytes`]). A
/// CNAME longer than 255 octets (the item's length field) is cut there.
pub fn write_sdes_cname(ssrc: u32, cname: &[u8], out: &mut [u8]) -> Result<usize, BufferTooShort> {
    let cname = cname.get(..255).unwrap_or(cname);
    let n = sdes_cname_bytes(cname.len());
    let out = front(out, n)?;
    out[0..4].copy_from_slice(&rtcp_header(1, RTCP_SDES, n));
    out[4..8].copy_from_slice(&ssrc.to_be_bytes());
    out[8] = 1; // CNAME
    out[9] = cname.len() as u8;
    out[10..10 + cname.len()].copy_from_slice(cname);
    out[10 + cname.len()..].fill(0);
    Ok(n)
}

/// When to send the next RTCP report: the first [`REPORT_INTERVAL`] / 2
/// after the stream starts (RFC 3550 section 6.2: "the initial delay ...
/// MAY be set to half the minimum interval"), then every
/// [`REPORT_INTERVAL`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReportTimer {
    next: Instant,
}

impl ReportTimer {
    /// A timer for a stream starting at `start`.
    pub fn new(start: Instant) -> ReportTimer {
        ReportTimer { next: start + REPORT_INTERVAL / 2 }
    }

    /// When the next report is due (a deadline for the caller's wait).
    pub const fn deadline(&self) -> Instant {
        self.next
    }

    /// Whether a report is due at `now`; when it is, the next one is
    /// scheduled [`REPORT_INTERVAL`] from `now`.
    pub fn poll(&mut self, now: Instant) -> bool {
        if now < self.next {
            return false;
        }
        self.next = now + REPORT_INTERVAL;
        true
    }
}

/// The extended sequence numbers a receiver reports lost in the generic
/// NACKs (RFC 4585 section 6.2.1) of one RTCP datagram.
///
/// The datagram may be a compound packet (RFC 3550 section 6.1: receiver
/// report first, SDES, then the feedback) or a reduced-size one holding
/// the NACK alone (RFC 5506). It is first checked as a whole the way RFC
/// 3550 appendix A.2 checks a compound packet: every packet's version 2,
/// its length inside the datagram, padding only on the last one, and the
/// lengths adding up to the datagram's; anything else yields nothing.
/// Only packet type 205 with FMT 1 for media source `media_ssrc` counts;
/// other packets and other feedback are skipped.
///
/// Each FCI entry (PID, BLP) yields PID, then PID + 1 + i for each set bit
/// i of BLP, lowest first. The 16-bit numbers are resolved against the
/// sender's newest extended sequence number: to the one at most 32,767
/// packets back with those low 16 bits; numbers ahead of it (never sent)
/// are dropped. Duplicates are not removed. At most
/// [`MAX_NACKED_PER_DATAGRAM`] numbers come out of one datagram, however
/// many it lists: a 1,500-byte NACK could otherwise ask for some 6,000
/// resends of 1,502 bytes each.
#[derive(Clone, Debug)]
pub struct NackRequests<'a> {
    /// The packets after the current one.
    rest: &'a [u8],
    /// The FCI entries of the current NACK not read yet.
    fci: &'a [u8],
    media_ssrc: u32,
    highest: u32,
    pid: u16,
    /// Offsets from `pid` still to yield: bit 0 the PID, bit i + 1 BLP's
    /// bit i.
    pending: u32,
    /// Numbers still allowed out.
    budget: u16,
}

/// The most sequence numbers [`NackRequests`] yields for one datagram:
/// two frames' packets ([`REPAIR_ENTRIES`]), all a [`FrameRepairWindow`]
/// could resend.
pub const MAX_NACKED_PER_DATAGRAM: u16 = REPAIR_ENTRIES as u16;

/// Whether `data` is a well-formed run of RTCP packets (RFC 3550 appendix
/// A.2, less the rule that the first be a report: RFC 5506 allows a
/// feedback packet alone).
fn valid_compound(mut data: &[u8]) -> bool {
    if data.is_empty() {
        return false;
    }
    while !data.is_empty() {
        let Some(&[b0, _, hi, lo]) = data.first_chunk::<4>() else {
            return false;
        };
        let len = (usize::from(u16::from_be_bytes([hi, lo])) + 1) * 4;
        let Some(packet) = data.get(..len) else {
            return false;
        };
        data = &data[len..];
        if b0 >> 6 != 2 {
            return false;
        }
        if b0 & 0x20 != 0 {
            // Padding: only on the last packet, at least one octet, and no
            // more than the packet's body.
            let pad = usize::from(packet[len - 1]);
            if !data.is_empty() || pad == 0 || pad > len - 4 {
                return false;
            }
        }
    }
    true
}

impl<'a> NackRequests<'a> {
    /// The lost packets `datagram` asks `media_ssrc` to send again, the
    /// sender's newest extended sequence number being `highest` (`None`
    /// before the first packet: nothing to resend).
    pub fn new(datagram: &'a [u8], media_ssrc: u32, highest: Option<u32>) -> NackRequests<'a> {
        let rest = match highest {
            Some(_) if valid_compound(datagram) => datagram,
            _ => &[],
        };
        NackRequests {
            rest,
            fci: &[],
            media_ssrc,
            highest: highest.unwrap_or(0),
            pid: 0,
            pending: 0,
            budget: MAX_NACKED_PER_DATAGRAM,
        }
    }

    /// The extended sequence number with low 16 bits `seq16` at most 32,767
    /// packets back from the newest, if there is one.
    fn resolve(&self, seq16: u16) -> Option<u32> {
        let back = (self.highest as u16).wrapping_sub(seq16);
        (back < 0x8000).then(|| self.highest.wrapping_sub(u32::from(back)))
    }

    /// Move to the next NACK for our media source; false at the end.
    fn next_nack(&mut self) -> bool {
        while let Some(&[b0, pt, hi, lo]) = self.rest.first_chunk::<4>() {
            // valid_compound checked every length and the padding.
            let len = (usize::from(u16::from_be_bytes([hi, lo])) + 1) * 4;
            let Some(packet) = self.rest.get(..len) else {
                break;
            };
            self.rest = &self.rest[len..];
            let pad = if b0 & 0x20 != 0 { usize::from(packet[len - 1]) } else { 0 };
            let body = packet.get(..len.saturating_sub(pad)).unwrap_or(&[]);
            if pt != RTCP_RTPFB || b0 & 0x1f != FMT_GENERIC_NACK {
                continue;
            }
            let Some(&[s0, s1, s2, s3]) = body.get(8..12).and_then(|b| b.first_chunk::<4>()) else {
                continue;
            };
            if u32::from_be_bytes([s0, s1, s2, s3]) == self.media_ssrc {
                self.fci = &body[12..];
                return true;
            }
        }
        self.rest = &[];
        false
    }
}

impl Iterator for NackRequests<'_> {
    type Item = u32;

    fn next(&mut self) -> Option<u32> {
        self.budget = self.budget.checked_sub(1)?;
        loop {
            if self.pending != 0 {
                let offset = self.pending.trailing_zeros();
                self.pending &= self.pending - 1;
                if let Some(seq) = self.resolve(self.pid.wrapping_add(offset as u16)) {
                    return Some(seq);
                }
            } else if let Some((&[p0, p1, b0, b1], rest)) = self.fci.split_first_chunk::<4>() {
                self.fci = rest;
                self.pid = u16::from_be_bytes([p0, p1]);
                self.pending = 1 | u32::from(u16::from_be_bytes([b0, b1])) << 1;
            } else if !self.next_nack() {
                return None;
            }
        }
    }
}

// ---- Retransmission ----------------------------------------------------------------

/// Entries of a [`FrameRepairWindow`]: two frames of 360 rows and slack, up
/// to the next power of two (which keeps the ring of entries continuous
/// where the 32-bit sequence number wraps).
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
    /// The packet's header fields, for [`Packetiser::emit`].
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

#[derive(Clone, Copy, Debug)]
struct Entry {
    packet: RowPacket,
    slot: u8,
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

/// Retransmission bookkeeping (RFC 4585 section 3.1's "repair"): for each
/// of the last `N` packets sent, its header fields and the frame slot and
/// row its bytes are in, so a NACKed packet ([`NackRequests`]) is sent
/// again exactly as it was (same SSRC, payload type, sequence number and
/// timestamp: RFC 4585 leaves the repair to the sender, and a plain resend
/// is what a jitter buffer without RFC 4588 takes), its row read from the
/// slot once more, zero-copy.
///
/// A slot is *held* while any of its packets is in the window: the caller
/// keeps it out of reuse meanwhile ([`FrameRing::pin`]). Packets leave the
/// window when `N` newer ones were recorded, or when they are older than
/// the hold time ([`expire`](Self::expire)), so an idle stream lets its
/// slots go. `N` must be a power of two (sequence numbers index a ring);
/// [`REPAIR_ENTRIES`] covers two frames and slack. The times are kept per
/// run of packets (a span), not per packet: recording a packet and
/// restarting a frame's hold touch no other entry.
///
/// [`FrameRing::pin`]: crate::frames::FrameRing::pin
#[derive(Clone, Debug)]
pub struct RepairWindow<const N: usize> {
    /// Entry of sequence number `s` at `s % N`: present exactly for the
    /// packets recorded in `oldest..next`.
    entries: [Option<Entry>; N],
    oldest: u32,
    next: u32,
    started: bool,
    /// Entries per slot.
    refs: [u32; MAX_SLOTS],
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
        const { assert!(N.is_power_of_two() && N <= 1 << 16, "N indexes a ring by sequence number") };
        RepairWindow {
            entries: [None; N],
            oldest: 0,
            next: 0,
            started: false,
            refs: [0; MAX_SLOTS],
            held: 0,
            hold,
            spans: heapless::Deque::new(),
        }
    }

    /// Empty the window (a new stream) and keep packets for `hold` from now
    /// on; in place, as the window is large.
    pub fn clear(&mut self, hold: Duration) {
        self.entries.fill(None);
        (self.oldest, self.next, self.started) = (0, 0, false);
        self.refs = [0; MAX_SLOTS];
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
        self.refs.iter().map(|&r| r as usize).sum()
    }

    /// Whether the window holds no packet.
    pub fn is_empty(&self) -> bool {
        self.held == 0
    }

    /// Record `packet`, sent at `now` with its row from `slot`. Its
    /// sequence number must be newer than every one recorded before (at
    /// most 2^31 ahead); the oldest packets leave the window to make room.
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
        if !Self::before(self.oldest, self.next) {
            // Nothing older is left (the first packet, or a jump past the
            // window): no span covers anything.
            self.spans.clear();
        }
        self.entries[s as usize % N] = Some(Entry { packet, slot: slot8 });
        self.refs[usize::from(slot8)] += 1;
        self.held |= 1 << slot8;
        self.next = s.wrapping_add(1);
        self.hold_from(s, now);
        Ok(SlotChanges { held: self.held & !before, released: before & !self.held })
    }

    /// Record a run of `n` packets sent at `now` from `slot`: `first` and
    /// the `n - 1` after it ([`RowPacket::nth`]). The same as
    /// [`record`](Self::record) for each, checked once.
    pub fn record_run(
        &mut self,
        now: Instant,
        slot: usize,
        first: RowPacket,
        n: u16,
    ) -> Result<SlotChanges, RecordError> {
        if n == 0 {
            return Ok(SlotChanges::default());
        }
        let before = self.held;
        self.record(now, slot, first)?;
        // `slot` passed the check; each later number is newer than the
        // one before: the checks in `record` hold for the rest, and the
        // span `record` opened at `first` covers them.
        let slot8 = slot as u8;
        // Counted first: a run longer than the window pushes out its own.
        self.refs[usize::from(slot8)] += u32::from(n - 1);
        let mut oldest = self.oldest;
        for k in 1..n {
            let s = first.seq.wrapping_add(u32::from(k));
            let entry = &mut self.entries[s as usize % N];
            if s.wrapping_sub(oldest) >= N as u32 {
                // The window is full (it always is past the first N): the
                // oldest leaves, as `record` would; numbers run on, so
                // its entry is the one this packet takes.
                if let Some(old) = entry {
                    let old = usize::from(old.slot);
                    self.refs[old] -= 1;
                    if self.refs[old] == 0 {
                        self.held &= !(1 << old);
                    }
                }
                oldest = oldest.wrapping_add(1);
            }
            *entry = Some(Entry { packet: first.nth(k), slot: slot8 });
        }
        self.oldest = oldest;
        self.next = first.seq.wrapping_add(u32::from(n));
        self.held |= 1 << slot8;
        self.drop_passed_spans();
        Ok(SlotChanges { held: self.held & !before, released: before & !self.held })
    }

    /// Drop the packet numbered `seq`, if present.
    fn remove(&mut self, seq: u32) {
        if let Some(e) = self.entries[seq as usize % N].take() {
            let slot = usize::from(e.slot);
            self.refs[slot] -= 1;
            if self.refs[slot] == 0 {
                self.held &= !(1 << slot);
            }
        }
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

    /// Drop the packets recorded longer than the hold time before `now`;
    /// returns the slots released (bounded: at most `N` entries).
    pub fn expire(&mut self, now: Instant) -> SlotChanges {
        let before = self.held;
        self.drop_passed_spans();
        while let Some(&span) = self.spans.front() {
            if now.saturating_duration_since(span.at) < self.hold {
                break;
            }
            let end = self.spans.get(1).map_or(self.next, |b| b.first);
            while self.oldest != end {
                self.remove(self.oldest);
                self.oldest = self.oldest.wrapping_add(1);
            }
            self.spans.pop_front();
        }
        SlotChanges { held: 0, released: before & !self.held }
    }

    /// The packet numbered `seq` (an extended sequence number, as
    /// [`NackRequests`] yields them), if still in the window: resend it
    /// with [`Packetiser::emit`] and its row from the slot.
    pub fn lookup(&self, seq: u32) -> Option<Repair> {
        match self.entries[seq as usize % N] {
            Some(e) if e.packet.seq == seq => Some(Repair { packet: e.packet, slot: usize::from(e.slot) }),
            _ => None,
        }
    }
}

// ---- The whole header -------------------------------------------------------------

/// Where a stream goes: both ends' MAC and IPv4 addresses and UDP ports.
#[cfg(feature = "smoltcp")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Endpoints {
    /// The board's MAC address.
    pub src_mac: smoltcp::wire::EthernetAddress,
    /// The next hop's MAC address (the client's, or the gateway's).
    pub dst_mac: smoltcp::wire::EthernetAddress,
    /// The board's address and the stream's source port.
    pub src: core::net::SocketAddrV4,
    /// The client's address and RTP port.
    pub dst: core::net::SocketAddrV4,
}

/// What goes into the UDP checksum field of a [`HeaderTemplate`]'s
/// packets. The zero-copy path never reads the row, so the software cannot
/// compute the full checksum itself.
#[cfg(feature = "smoltcp")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UdpChecksum {
    /// Zero: "no checksum" (RFC 768; allowed over IPv4). For a MAC without
    /// checksum insertion, or a frame sent with insertion off.
    Zero,
    /// The MAC's checksum engine computes it (the DWMAC's checksum
    /// insertion control, CIC 3 or 2). The field holds the pseudo-header
    /// sum (folded, not complemented), which CIC 3 ignores and CIC 2 (no
    /// pseudo-header in hardware) needs there, so either mode yields the
    /// right checksum.
    Offload,
}

/// The 62 bytes in front of a row on the wire: Ethernet II, IPv4, UDP, RTP
/// and RFC 4175 headers ([`FRAME_HEADER_BYTES`]), for the board's
/// zero-copy transmit path (the first buffer of a descriptor this header,
/// the second the row in the frame ring).
///
/// The Ethernet and IPv4 headers are smoltcp's (`EthernetRepr::emit`,
/// `Ipv4Repr::emit`: don't fragment, TTL 64, DSCP 0), written once; each
/// packet gets the next IPv4 identification (RFC 6864 section 4.1 lets an
/// atomic datagram's be anything; an incrementing one helps reading
/// captures) and its header checksum, computed here whether or not the MAC
/// inserts it again. The UDP header is written field by field: smoltcp's
/// `UdpRepr::emit` writes the payload too and panics on a header-only
/// buffer. IPv4 total length is [`IPV4_TOTAL_LENGTH`] (1,488), UDP length
/// [`UDP_LENGTH`] (1,468).
#[cfg(feature = "smoltcp")]
#[derive(Clone, Debug)]
pub struct HeaderTemplate {
    /// The padded header of the newest packet, as transmit-buffer words:
    /// the per-packet fields (IPv4 identification and checksum, RTP and
    /// RFC 4175 fields) are overwritten for each packet, the rest written
    /// once.
    words: HeaderWords,
    /// The big-endian words holding the IPv4 identification and checksum,
    /// with those fields zero (flags and fragment offset; TTL, protocol).
    ip_words: [u32; 2],
    /// The one's-complement sum of the IPv4 header with identification
    /// and checksum zero, not folded: a packet's checksum adds only its
    /// identification (RFC 1071's sum; RFC 1624 for why that is exact).
    ip_sum: u32,
    ident: u16,
}

/// Bytes in front of the Ethernet header in a transmit buffer: two, so
/// that the IPv4 header and all after it fall on word boundaries (Linux's
/// `NET_IP_ALIGN`; the `dwmac` crate's `TX_SKEW`).
pub const HEADER_PAD: usize = 2;

/// A row packet's padded header in 32-bit words: [`HEADER_PAD`] bytes,
/// then the [`FRAME_HEADER_BYTES`] (62) of the header.
pub const HEADER_WORDS: usize = (HEADER_PAD + FRAME_HEADER_BYTES) / 4;
const _: () = assert!((HEADER_PAD + FRAME_HEADER_BYTES).is_multiple_of(4));

/// One packet's padded header as the words of its transmit buffer: their
/// bytes in memory, whatever the CPU's byte order, are [`HEADER_PAD`] zero
/// bytes and the 62-byte header. Sixteen word stores put it in place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeaderWords(pub [u32; HEADER_WORDS]);

impl HeaderWords {
    /// The 62 header bytes (without the padding).
    pub fn bytes(&self) -> [u8; FRAME_HEADER_BYTES] {
        let mut out = [0u8; FRAME_HEADER_BYTES];
        for (i, b) in out.iter_mut().enumerate() {
            let at = HEADER_PAD + i;
            *b = self.0[at / 4].to_ne_bytes()[at % 4];
        }
        out
    }
}

#[cfg(feature = "smoltcp")]
impl HeaderTemplate {
    /// Word offsets of the per-packet fields in the padded header.
    const IP_IDENT_WORD: usize = (HEADER_PAD + ETHERNET_HEADER_BYTES + 4) / 4;
    const IP_CHECKSUM_WORD: usize = (HEADER_PAD + ETHERNET_HEADER_BYTES + 8) / 4;
    const RTP_WORD: usize = (HEADER_PAD + ETHERNET_HEADER_BYTES + IPV4_HEADER_BYTES + UDP_HEADER_BYTES) / 4;

    /// A template for `endpoints`, with `checksum` in the UDP checksum
    /// field; the first packet's IPv4 identification is `first_ident`.
    pub fn new(endpoints: &Endpoints, checksum: UdpChecksum, first_ident: u16) -> HeaderTemplate {
        use smoltcp::phy::ChecksumCapabilities;
        use smoltcp::wire::{
            checksum, EthernetFrame, EthernetProtocol, EthernetRepr, IpProtocol, Ipv4Packet, Ipv4Repr, UdpPacket,
        };

        const IP: core::ops::Range<usize> =
            HEADER_PAD + ETHERNET_HEADER_BYTES..HEADER_PAD + ETHERNET_HEADER_BYTES + IPV4_HEADER_BYTES;
        const UDP: core::ops::Range<usize> = IP.end..IP.end + UDP_HEADER_BYTES;
        let mut padded = [0u8; HEADER_WORDS * 4];
        let eth = EthernetRepr {
            src_addr: endpoints.src_mac,
            dst_addr: endpoints.dst_mac,
            ethertype: EthernetProtocol::Ipv4,
        };
        eth.emit(&mut EthernetFrame::new_unchecked(&mut padded[HEADER_PAD..IP.start]));
        let (src, dst) = (*endpoints.src.ip(), *endpoints.dst.ip());
        let ip = Ipv4Repr {
            src_addr: src,
            dst_addr: dst,
            next_header: IpProtocol::Udp,
            payload_len: usize::from(UDP_LENGTH),
            hop_limit: 64,
        };
        // Identification and checksum stay zero: they are per packet.
        ip.emit(&mut Ipv4Packet::new_unchecked(&mut padded[IP]), &ChecksumCapabilities::ignored());
        let ip_sum = padded[IP].chunks_exact(2).map(|h| u32::from(u16::from_be_bytes([h[0], h[1]]))).sum();
        let mut udp = UdpPacket::new_unchecked(&mut padded[UDP]);
        udp.set_src_port(endpoints.src.port());
        udp.set_dst_port(endpoints.dst.port());
        udp.set_len(UDP_LENGTH);
        udp.set_checksum(match checksum {
            UdpChecksum::Zero => 0,
            UdpChecksum::Offload => checksum::pseudo_header_v4(&src, &dst, IpProtocol::Udp, u32::from(UDP_LENGTH)),
        });
        let words = core::array::from_fn(|i| {
            u32::from_ne_bytes([padded[4 * i], padded[4 * i + 1], padded[4 * i + 2], padded[4 * i + 3]])
        });
        let ip_words = [Self::IP_IDENT_WORD, Self::IP_CHECKSUM_WORD].map(|i: usize| u32::from_be(words[i]));
        HeaderTemplate { words: HeaderWords(words), ip_words, ip_sum, ident: first_ident }
    }

    /// The IPv4 identification the next packet gets.
    pub const fn next_ident(&self) -> u16 {
        self.ident
    }

    /// The padded header of `packet` (new, or one resent from a
    /// [`RepairWindow`]) of `session`'s stream, as transmit-buffer words,
    /// valid until the next call. Every call takes the next IPv4
    /// identification (a resent packet is a new IP datagram) and fills in
    /// the IPv4 header checksum, which the MAC may insert again. The RTP
    /// and RFC 4175 fields are [`Packetiser::emit`]'s. Seven word stores:
    /// the rest of the header stays from the packets before.
    #[inline(always)]
    pub fn words(&mut self, session: &Packetiser, packet: &RowPacket) -> &HeaderWords {
        let ident = self.ident;
        self.ident = ident.wrapping_add(1);
        // At most ten 16-bit terms: two folds leave 16 bits.
        let sum = self.ip_sum + u32::from(ident);
        let sum = (sum & 0xffff) + (sum >> 16);
        let sum = (sum & 0xffff) + (sum >> 16);
        let w = &mut self.words.0;
        w[Self::IP_IDENT_WORD] = (self.ip_words[0] | u32::from(ident) << 16).to_be();
        w[Self::IP_CHECKSUM_WORD] = (self.ip_words[1] | u32::from(!(sum as u16))).to_be();
        let marker = if packet.marker() { 0x80 } else { 0 };
        // RFC 3550 section 5.1: V = 2, P = X = CC = 0, M, PT, sequence number.
        w[Self::RTP_WORD] = (2 << 30 | u32::from(marker | session.payload_type) << 16 | (packet.seq & 0xffff)).to_be();
        w[Self::RTP_WORD + 1] = packet.timestamp.to_be();
        w[Self::RTP_WORD + 2] = session.ssrc.to_be();
        // RFC 4175 section 4.3: extended sequence number, length; F + line
        // number, C + offset (0).
        w[Self::RTP_WORD + 3] = ((packet.seq & 0xffff_0000) | ROW_BYTES as u32).to_be();
        w[Self::RTP_WORD + 4] = (u32::from(packet.row & 0x7fff) << 16).to_be();
        &self.words
    }

    /// The header words as they stand: the newest packet's, or before any
    /// packet the fixed fields with the per-packet ones zero. Enough to
    /// tell the header's layout (EtherType, IPv4 flags, protocol), which
    /// every packet of the template shares.
    pub const fn current(&self) -> &HeaderWords {
        &self.words
    }

    /// Write the 62-byte header of `packet` into the front of `out`: the
    /// bytes of [`words`](Self::words) without the padding.
    pub fn write(&mut self, session: &Packetiser, packet: &RowPacket, out: &mut [u8]) -> Result<(), BufferTooShort> {
        let out = front(out, FRAME_HEADER_BYTES)?;
        out.copy_from_slice(&self.words(session, packet).bytes());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn session() -> Packetiser {
        Packetiser::new(0x1234_5678, 0x0001_0203, 0xa000_0000)
    }

    #[test]
    fn the_sizes_add_up() {
        assert_eq!((HEADER_BYTES, PACKET_BYTES, FRAME_HEADER_BYTES), (20, 1_460, 62));
        assert_eq!((IPV4_TOTAL_LENGTH, UDP_LENGTH), (1_488, 1_468));
        assert_eq!(ticks(Instant::from_millis(1_000)), 90_000);
    }

    #[test]
    fn a_rows_header_is_byte_exact() {
        let mut p = session();
        let f = p.begin_frame(90);
        let mut out = [0xffu8; 24];
        let packet = p.write_header(f, 5, &mut out).unwrap();
        assert_eq!(packet, RowPacket { seq: 0x0001_0203, timestamp: 0xa000_005a, row: 5 });
        #[rustfmt::skip]
        assert_eq!(out[..20], [
            0x80, 0x60, 0x02, 0x03,     // V=2, M=0, PT=96, seq low 16
            0xa0, 0x00, 0x00, 0x5a,     // timestamp
            0x12, 0x34, 0x56, 0x78,     // SSRC
            0x00, 0x01,                 // extended sequence number: high 16
            0x05, 0xa0,                 // Length 1,440
            0x00, 0x05,                 // F=0, Line No 5
            0x00, 0x00,                 // C=0, Offset 0
        ]);
        assert_eq!(out[20..], [0xff; 4], "nothing past the header");
    }

    #[test]
    fn the_last_row_carries_the_marker() {
        let mut p = session();
        let f = p.begin_frame(0);
        let mut out = [0u8; HEADER_BYTES];
        let packet = p.write_header(f, ROWS - 1, &mut out).unwrap();
        assert!(packet.marker());
        #[rustfmt::skip]
        assert_eq!(out, [
            0x80, 0xe0, 0x02, 0x03,
            0xa0, 0x00, 0x00, 0x00,
            0x12, 0x34, 0x56, 0x78,
            0x00, 0x01, 0x05, 0xa0,
            0x01, 0x67,                 // Line No 359
            0x00, 0x00,
        ]);
    }

    #[test]
    fn the_sequence_wraps_into_the_extended_half() {
        let mut p = Packetiser::new(1, 0x0000_fffe, 0);
        let f = p.begin_frame(0);
        let mut out = [0u8; HEADER_BYTES];
        let mut seen = [(0u16, 0u16); 3];
        for (y, s) in seen.iter_mut().enumerate() {
            p.write_header(f, y as u16, &mut out).unwrap();
            *s = (u16::from_be_bytes([out[2], out[3]]), u16::from_be_bytes([out[12], out[13]]));
        }
        assert_eq!(seen, [(0xfffe, 0), (0xffff, 0), (0x0000, 1)], "(RTP seq, extended high half)");
        assert_eq!(p.highest_seq(), Some(0x0001_0000));
        let mut p = Packetiser::new(1, u32::MAX, 0);
        assert_eq!(p.next_packet(f, 0).unwrap().seq, u32::MAX);
        assert_eq!(p.next_packet(f, 1).unwrap().seq, 0, "the extended counter wraps too");
    }

    #[test]
    fn frames_share_a_timestamp_and_never_with_the_next_frame() {
        let mut p = session();
        let mut out = [0u8; HEADER_BYTES];
        let stamp = |out: &[u8; HEADER_BYTES]| u32::from_be_bytes([out[4], out[5], out[6], out[7]]);
        let a = p.begin_frame(ticks(Instant::from_millis(1_000)));
        p.write_header(a, 0, &mut out).unwrap();
        let first = stamp(&out);
        p.write_header(a, 359, &mut out).unwrap();
        assert_eq!(stamp(&out), first, "one timestamp per frame");
        let b = p.begin_frame(ticks(Instant::from_millis(1_000)));
        let c = p.begin_frame(ticks(Instant::from_millis(999)));
        let d = p.begin_frame(ticks(Instant::from_millis(1_040)));
        assert_eq!(
            [a, b, c, d].map(|f| f.timestamp.wrapping_sub(0xa000_0000)),
            [90_000, 90_001, 90_002, 93_600],
            "same millisecond (fps=max) or a clock going back: the next tick"
        );
    }

    #[test]
    fn bad_rows_and_short_buffers_number_nothing() {
        let mut p = session();
        let f = p.begin_frame(0);
        assert_eq!(p.write_header(f, ROWS, &mut [0; 20]), Err(PacketError::BadRow(ROWS)));
        assert_eq!(p.write_header(f, 0, &mut [0; 19]), Err(PacketError::BufferTooShort(BufferTooShort { needed: 20 })));
        assert_eq!(p.highest_seq(), None);
        assert_eq!(p.write_header(f, 0, &mut [0; 20]).unwrap().seq, 0x0001_0203);
    }

    #[test]
    fn a_retransmitted_header_is_the_original() {
        let mut p = session();
        let f = p.begin_frame(7);
        let mut first = [0u8; HEADER_BYTES];
        let packet = p.write_header(f, 42, &mut first).unwrap();
        let g = p.begin_frame(8);
        p.write_header(g, 0, &mut [0; 20]).unwrap();
        let mut again = [0u8; HEADER_BYTES];
        p.emit(&packet, &mut again).unwrap();
        assert_eq!(again, first);
    }

    #[test]
    fn a_sender_report_counts_new_packets_and_lines_up_the_clocks() {
        let mut p = session();
        let f = p.begin_frame(ticks(Instant::from_millis(2_000)));
        for y in 0..ROWS {
            p.write_header(f, y, &mut [0; 20]).unwrap();
        }
        let ntp = ntp_timestamp(Duration::new(1_700_000_000, 500_000_000));
        assert_eq!(ntp, (1_700_000_000 + 2_208_988_800) << 32 | 0x8000_0000);
        let sr = p.sender_report(ntp, ticks(Instant::from_millis(2_500)));
        assert_eq!(
            sr,
            SenderReport {
                ssrc: 0x1234_5678,
                ntp_timestamp: ntp,
                rtp_timestamp: 0xa000_0000 + 225_000,
                packet_count: 360,
                octet_count: 360 * 1_448,
            }
        );
        let mut out = [0u8; 32];
        assert_eq!(sr.write(&mut out), Ok(28));
        #[rustfmt::skip]
        assert_eq!(out[..28], [
            0x80, 200, 0x00, 0x06,                          // V=2, RC=0, SR, 7 words
            0x12, 0x34, 0x56, 0x78,
            0xe8, 0xfe, 0x6f, 0x80, 0x80, 0x00, 0x00, 0x00, // NTP: 3,908,988,800.5 s
            0xa0, 0x03, 0x6e, 0xe8,                         // RTP timestamp
            0x00, 0x00, 0x01, 0x68,                         // 360 packets
            0x00, 0x07, 0xf4, 0x40,                         // 521,280 octets
        ]);
        assert_eq!(sr.write(&mut [0; 27]), Err(BufferTooShort { needed: 28 }));
    }

    #[test]
    fn an_sdes_cname_ends_on_a_word_with_a_null() {
        let mut out = [0xffu8; 24];
        assert_eq!(write_sdes_cname(0x0102_0304, b"rt@board", &mut out), Ok(20));
        #[rustfmt::skip]
        assert_eq!(out[..20], [
            0x81, 202, 0x00, 0x04, 1, 2, 3, 4,
            1, 8, b'r', b't', b'@', b'b', b'o', b'a', b'r', b'd',
            0, 0,
        ]);
        assert_eq!(sdes_cname_bytes(2), 16, "2 + 2 octets fill a word: a whole word of nulls after");
        assert_eq!(write_sdes_cname(1, &[b'x'; 300], &mut [0; 300]), Ok(sdes_cname_bytes(255)));
    }

    #[test]
    fn reports_go_out_half_an_interval_in_then_every_interval() {
        let mut t = ReportTimer::new(Instant::from_millis(1_000));
        assert_eq!(t.deadline(), Instant::from_millis(3_500));
        assert!(!t.poll(Instant::from_millis(3_499)));
        assert!(t.poll(Instant::from_millis(3_600)));
        assert_eq!(t.deadline(), Instant::from_millis(8_600));
        assert!(!t.poll(Instant::from_millis(8_000)));
    }

    /// An RTCP generic NACK (RFC 4585 section 6.2.1) from `sender` about
    /// `media`, with FCI entries `(pid, blp)`.
    fn nack(sender: u32, media: u32, entries: &[(u16, u16)]) -> Vec<u8> {
        let words = 2 + entries.len();
        let mut v = vec![0x81, 205];
        v.extend_from_slice(&(words as u16).to_be_bytes());
        v.extend_from_slice(&sender.to_be_bytes());
        v.extend_from_slice(&media.to_be_bytes());
        for (pid, blp) in entries {
            v.extend_from_slice(&pid.to_be_bytes());
            v.extend_from_slice(&blp.to_be_bytes());
        }
        v
    }

    /// An empty receiver report from `ssrc` (RFC 3550 section 6.4.2).
    fn rr(ssrc: u32) -> Vec<u8> {
        let mut v = vec![0x80, 201, 0, 1];
        v.extend_from_slice(&ssrc.to_be_bytes());
        v
    }

    fn nacked(datagram: &[u8], highest: u32) -> Vec<u32> {
        NackRequests::new(datagram, 0x1234_5678, Some(highest)).collect()
    }

    #[test]
    fn a_compound_nack_yields_the_pid_and_its_blp_bits() {
        let mut d = rr(0xdead_beef);
        d.extend(nack(0xdead_beef, 0x1234_5678, &[(0x1234, 0b1000_0000_0000_0101)]));
        assert_eq!(nacked(&d, 0x0002_1300), [0x0002_1234, 0x0002_1235, 0x0002_1237, 0x0002_1244]);
    }

    #[test]
    fn pids_resolve_into_the_last_32768_packets_across_the_wrap() {
        let d = nack(1, 0x1234_5678, &[(0xfff0, 0), (0xffff, 0b11), (0x0010, 0), (0x8010, 0)]);
        // Newest 0x0003_0010: 0xfff0 is in the previous high half, 0xffff
        // + 1 wraps into this one, 0x0010 is the newest itself and 0x8010
        // is 32,768 back: too far (it would as well be ahead).
        assert_eq!(nacked(&d, 0x0003_0010), [0x0002_fff0, 0x0002_ffff, 0x0003_0000, 0x0003_0001, 0x0003_0010]);
        assert_eq!(nacked(&nack(1, 0x1234_5678, &[(0x0011, 0)]), 0x0003_0010), [0; 0], "never sent");
        assert_eq!(nacked(&nack(1, 0x1234_5678, &[(0x8011, 0)]), 0x0003_0010), [0x0002_8011], "32,767 back");
        assert_eq!(NackRequests::new(&d, 0x1234_5678, None).count(), 0, "nothing sent yet");
    }

    #[test]
    fn other_packets_and_other_sources_are_skipped() {
        let mut d = rr(9);
        d.extend([0x81, 202, 0, 2, 0, 0, 0, 9, 1, 1, b'x', 0]); // SDES CNAME
        d.extend(nack(9, 0x0bad_0bad, &[(5, 0)])); // another stream
        let mut pli = nack(9, 0x1234_5678, &[]);
        pli[1] = 206; // PSFB, FMT 1: a picture loss indication
        d.extend(pli);
        let mut twcc = nack(9, 0x1234_5678, &[(6, 0)]);
        twcc[0] = 0x8f; // RTPFB FMT 15
        d.extend(twcc);
        d.extend(nack(9, 0x1234_5678, &[(7, 0), (9, 0)]));
        assert_eq!(nacked(&d, 100), [7, 9]);
    }

    #[test]
    fn padding_on_the_last_packet_is_not_fci() {
        let mut d = nack(9, 0x1234_5678, &[(7, 0), (0, 4)]);
        d[0] |= 0x20; // the last entry's word is now padding: 00 00 00 04
        assert_eq!(nacked(&d, 100), [7]);
    }

    #[test]
    fn one_datagram_asks_for_a_bounded_number_of_resends() {
        let d = nack(9, 0x1234_5678, &[(100, 0xffff); 300]);
        assert_eq!(nacked(&d, 200).len(), usize::from(MAX_NACKED_PER_DATAGRAM), "not 300 x 17");
        assert_eq!(nacked(&nack(9, 0x1234_5678, &[(100, 0xffff); 2]), 200).len(), 34);
    }

    #[test]
    fn malformed_datagrams_yield_nothing() {
        let good = nack(9, 0x1234_5678, &[(7, 0)]);
        assert_eq!(nacked(&good, 100), [7]);
        let mut cases: Vec<Vec<u8>> = vec![vec![], good[..good.len() - 1].to_vec()];
        let mut v1 = good.clone();
        v1[0] = 0x41; // version 1
        cases.push(v1);
        let mut long = good.clone();
        long[3] = 9; // past the end
        cases.push(long);
        let mut trailing = good.clone();
        trailing.extend([0x80, 201]); // half a header after
        cases.push(trailing);
        let mut pad_first = good.clone();
        pad_first[0] |= 0x20;
        pad_first.extend(rr(9));
        cases.push(pad_first);
        let mut pad_zero = good.clone();
        pad_zero[0] |= 0x20;
        *pad_zero.last_mut().unwrap() = 0;
        cases.push(pad_zero);
        let mut pad_huge = good.clone();
        pad_huge[0] |= 0x20;
        *pad_huge.last_mut().unwrap() = 200;
        cases.push(pad_huge);
        for (i, c) in cases.iter().enumerate() {
            assert_eq!(nacked(c, 100), [0; 0], "case {i}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            failure_persistence: None, ..proptest::test_runner::Config::default()
        })]

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..600),
                                    highest: u32) {
            let n = NackRequests::new(&bytes, 0x1234_5678, Some(highest)).count();
            proptest::prop_assert!(n <= 17 * (bytes.len() / 4));
        }

        #[test]
        fn random_nacks_yield_their_bits(entries in proptest::collection::vec((0u16..2000, proptest::num::u16::ANY), 0..40),
                                         pad in 0u8..8, tail in proptest::collection::vec(proptest::num::u8::ANY, 0..40)) {
            // Well-formed NACKs, then random bytes (valid or not).
            let mut d = nack(1, 0x1234_5678, &entries);
            let plain = nack(1, 0x1234_5678, &entries);
            if pad > 0 {
                let pad = usize::from(pad) * 4;
                d[0] |= 0x20;
                d.resize(d.len() + pad, 0);
                *d.last_mut().unwrap() = pad as u8;
                let words = (d.len() / 4 - 1) as u16;
                d[2..4].copy_from_slice(&words.to_be_bytes());
            }
            let expected: Vec<u32> = entries.iter().flat_map(|&(pid, blp)| {
                core::iter::once(u32::from(pid))
                    .chain((0..16).filter(move |i| blp & (1 << i) != 0).map(move |i| u32::from(pid) + 1 + i))
            }).filter(|&s| s <= 3_000).collect();
            proptest::prop_assert_eq!(nacked(&d, 3_000), expected.clone());
            proptest::prop_assert_eq!(nacked(&plain, 3_000), expected);
            let mut with_tail = d.clone();
            with_tail.extend(&tail);
            let _ = nacked(&with_tail, 3_000);
        }

        #[test]
        fn mutated_compounds_never_panic(flips in proptest::collection::vec((0usize..64, proptest::num::u8::ANY), 1..6),
                                         highest: u32) {
            let mut d = rr(9);
            d.extend(nack(9, 0x1234_5678, &[(7, 0xffff), (40_000, 1)]));
            d.extend(nack(9, 0x1234_5678, &[(8, 3)]));
            for (at, byte) in flips {
                let i = at % d.len();
                d[i] = byte;
            }
            let n = NackRequests::new(&d, 0x1234_5678, Some(highest)).count();
            proptest::prop_assert!(n <= 3 * 17);
        }
    }

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
    fn a_nack_is_answered_with_the_original_packet() {
        let mut p = session();
        let mut w = FrameRepairWindow::new(Duration::from_secs(1));
        let mut sent = vec![];
        for slot in [0, 1] {
            let f = p.begin_frame(u64::from(slot as u32) * 3_000);
            for y in 0..ROWS {
                let mut h = [0u8; HEADER_BYTES];
                let packet = p.write_header(f, y, &mut h).unwrap();
                w.record(T0, slot, packet).unwrap();
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
