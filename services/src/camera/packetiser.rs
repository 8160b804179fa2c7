//! The sender side of one RTP session: the state that numbers and stamps a
//! stream's row packets (RFC 3550 section 5.1) and counts them for its
//! sender reports. The packets' format is [`wire::rtp`](super::wire::rtp).

use super::wire::rtcp::SenderReport;
use super::wire::rtp::{
    write_row_header, BufferTooShort, FrameStamp, PacketError, RowPacket, CLOCK_RATE, HEADER_BYTES, PAYLOAD_BYTES,
    PAYLOAD_TYPE,
};
use crate::frames::ROWS;
use crate::time::Instant;

/// RTP timestamp ticks in a millisecond of the crate's [`Instant`].
const TICKS_PER_MILLI: u64 = CLOCK_RATE as u64 / 1_000;

/// 90 kHz ticks since the clock's origin at `t` (what
/// [`Packetiser::begin_frame`] and [`Packetiser::sender_report`] take).
pub const fn ticks(t: Instant) -> u64 {
    t.millis().saturating_mul(TICKS_PER_MILLI)
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
    /// (what a NACK's 16-bit PID is resolved against, [`NackRequests`](super::wire::rtcp::NackRequests)), or
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
        write_row_header(self.ssrc, self.payload_type, packet, out)
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

    /// A sender report of this session for now (RFC 3550 section 6.4.1):
    /// `ntp` the wall clock in NTP format ([`ntp_timestamp`](super::wire::rtcp::ntp_timestamp)),
    /// `ticks` the same instant on the 90 kHz clock frames are stamped with
    /// (so the report's RTP timestamp lines up with the frames'), and the
    /// packets and payload octets numbered so far.
    pub const fn sender_report(&self, ntp: u64, ticks: u64) -> SenderReport {
        SenderReport {
            ssrc: self.ssrc,
            ntp_timestamp: ntp,
            rtp_timestamp: self.timestamp_at(ticks),
            packet_count: self.packets,
            octet_count: self.octets,
        }
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
    fn a_second_is_90000_ticks() {
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
        let ntp = 0x0123_4567_89ab_cdef;
        assert_eq!(
            p.sender_report(ntp, ticks(Instant::from_millis(2_500))),
            SenderReport {
                ssrc: 0x1234_5678,
                ntp_timestamp: ntp,
                rtp_timestamp: 0xa000_0000 + 225_000,
                packet_count: 360,
                octet_count: 360 * 1_448,
            }
        );
        p.emit(&RowPacket { seq: 1, timestamp: 0, row: 0 }, &mut [0; 20]).unwrap();
        assert_eq!(p.sender_report(ntp, 0).packet_count, 360, "a resend is not counted again");
    }
}
