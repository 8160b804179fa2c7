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
//! path puts in one buffer ([`frame_header`](super::frame_header)) and the
//! row, straight from the frame ring, in a second.
//!
//! # The parts
//!
//! * [`Packetiser`]: one RTP session's sender state: SSRC, payload type,
//!   the extended sequence counter, frame timestamps, and the packet and
//!   octet counts for [`SenderReport`](super::rtcp::SenderReport)s. It writes the 20 RTP + RFC 4175
//!   header bytes of a row ([`Packetiser::write_header`]).
//! * [`frame_header`](super::frame_header): the 62-byte Ethernet + IPv4 +
//!   UDP + RTP + RFC 4175 header of a row, for the zero-copy path.
//! * RTCP (RFC 3550 section 6): [`SenderReport`](super::rtcp::SenderReport), an SDES CNAME
//!   ([`write_sdes_cname`](super::rtcp::write_sdes_cname)), when to send them ([`ReportTimer`](super::rtcp::ReportTimer)), and the
//!   receiver's generic NACKs (RFC 4585 section 6.2.1) read out of any
//!   compound packet by [`NackRequests`](super::rtcp::NackRequests).
//! * [`RepairWindow`](super::repair::RepairWindow): which frame slot and row each recent packet came
//!   from, so a NACKed packet can be sent again unchanged (same SSRC, PT,
//!   sequence number and timestamp) from the frame ring, and which ring
//!   slots must therefore stay out of reuse.

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
/// (what a [`SenderReport`](super::rtcp::SenderReport)'s octet count adds up, RFC 3550 section 6.4.1).
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

/// The 4 bytes in front of an RTP or RTCP packet sent inside an RTSP
/// connection (RFC 2326 section 10.12): `$`, the channel, the packet's
/// length (big-endian). Every interleaved sender writes it with this.
pub const fn interleaved_head(channel: u8, len: u16) -> [u8; 4] {
    let [hi, lo] = len.to_be_bytes();
    [b'$', channel, hi, lo]
}

/// RTP timestamp ticks in a millisecond of the crate's [`Instant`].
const TICKS_PER_MILLI: u64 = CLOCK_RATE as u64 / 1_000;

/// 90 kHz ticks since the clock's origin at `t` (what
/// [`Packetiser::begin_frame`] and [`SenderReport::now`](super::rtcp::SenderReport::now) take).
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
pub(crate) fn front(out: &mut [u8], n: usize) -> Result<&mut [u8], BufferTooShort> {
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
/// timestamps, and the counts a [`SenderReport`](super::rtcp::SenderReport) carries.
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
    /// (what a NACK's 16-bit PID is resolved against, [`NackRequests`](super::rtcp::NackRequests)), or
    /// `None` before the first.
    pub const fn highest_seq(&self) -> Option<u32> {
        if self.sent_any {
            Some(self.next_seq.wrapping_sub(1))
        } else {
            None
        }
    }

    /// The extended sequence number the next new packet gets.
    pub const fn next_seq(&self) -> u32 {
        self.next_seq
    }

    /// Leave the numbers up to `seq` unused (a frame that failed part way
    /// keeps its rows' numbers, so every frame spans exactly one number
    /// per row and a receiver counts the rest as lost). Nothing is counted
    /// for the sender reports.
    pub fn skip_to(&mut self, seq: u32) {
        self.next_seq = seq;
        self.sent_any = true;
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

    /// Packets numbered so far (new packets only: retransmissions reuse
    /// their original numbers and are not counted again), for the sender
    /// reports (wrapping, as RFC 3550 section 6.4.1 counts them).
    pub const fn packet_count(&self) -> u32 {
        self.packets
    }

    /// Payload octets of the packets numbered so far (wrapping).
    pub const fn octet_count(&self) -> u32 {
        self.octets
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
}
