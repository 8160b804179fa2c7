//! The RTP packet of one row: uncompressed video per RFC 4175, one row a
//! packet, and the 4-byte head of a packet inside an RTSP connection.
//!
//! Formats only: no state, no clock. [`Packetiser`](crate::camera::packetiser::Packetiser)
//! numbers a session's packets and writes their headers with
//! [`write_row_header`].
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
//! [`FRAME_HEADER_BYTES`](crate::camera::frame_header::FRAME_HEADER_BYTES) = 62
//! bytes, which the board's zero-copy transmit
//! path puts in one buffer ([`frame_header`](crate::camera::frame_header)) and the
//! row, straight from the frame ring, in a second.

use model::ROW_BYTES;

use crate::frames::ROWS;

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

/// The 4 bytes in front of an RTP or RTCP packet sent inside an RTSP
/// connection (RFC 2326 section 10.12): `$`, the channel, the packet's
/// length (big-endian). Every interleaved sender writes it with this.
pub const fn interleaved_head(channel: u8, len: u16) -> [u8; 4] {
    let [hi, lo] = len.to_be_bytes();
    [b'$', channel, hi, lo]
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

/// Write the 20 RTP + RFC 4175 header bytes of `packet` from source `ssrc`
/// with payload type `payload_type` into the front of `out` (RFC 3550
/// section 5.1, RFC 4175 section 4.3).
pub fn write_row_header(ssrc: u32, payload_type: u8, packet: &RowPacket, out: &mut [u8]) -> Result<(), BufferTooShort> {
    let out = front(out, HEADER_BYTES)?;
    let marker = if packet.marker() { 0x80 } else { 0 };
    out[0] = 2 << 6; // V = 2, P = 0, X = 0, CC = 0
    out[1] = marker | payload_type;
    out[2..4].copy_from_slice(&(packet.seq as u16).to_be_bytes());
    out[4..8].copy_from_slice(&packet.timestamp.to_be_bytes());
    out[8..12].copy_from_slice(&ssrc.to_be_bytes());
    // RFC 4175 section 4.3: Extended Sequence Number, then one line
    // header: Length (octets), F + Line No, C + Offset (pixels).
    out[12..14].copy_from_slice(&((packet.seq >> 16) as u16).to_be_bytes());
    out[14..16].copy_from_slice(&(ROW_BYTES as u16).to_be_bytes());
    out[16..18].copy_from_slice(&(packet.row & 0x7fff).to_be_bytes());
    out[18..20].copy_from_slice(&0u16.to_be_bytes());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sizes_add_up() {
        assert_eq!((HEADER_BYTES, PAYLOAD_BYTES, PACKET_BYTES), (20, 1_448, 1_460));
    }

    #[test]
    fn an_interleaved_head_is_dollar_channel_length() {
        assert_eq!(interleaved_head(1, 0x05b4), [b'$', 1, 0x05, 0xb4]);
    }
}
