//! The 62 bytes in front of a row on the wire, Ethernet II, IPv4, UDP, RTP
//! and RFC 4175 headers ([`FRAME_HEADER_BYTES`]), made for the board's
//! zero-copy transmit path: the first buffer of a descriptor holds this
//! header, the second the row in the frame ring. The RTP part is the
//! [`Packetiser`](super::packetiser::Packetiser)'s; the rest is written once per destination
//! (`HeaderTemplate`, feature `smoltcp`) and patched per packet.

use super::wire::rtp::{HEADER_BYTES, PACKET_BYTES};
#[cfg(feature = "smoltcp")]
use super::{
    packetiser::Packetiser,
    wire::rtp::{front, BufferTooShort, RowPacket},
};
#[cfg(feature = "smoltcp")]
use model::ROW_BYTES;

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
    /// The client's (or the multicast group's) address and RTP port.
    pub dst: core::net::SocketAddrV4,
    /// The IPv4 time to live: [`UNICAST_TTL`], or a multicast group's.
    pub ttl: u8,
}

/// The time to live of unicast packets (smoltcp's default, as the board's
/// other packets have).
#[cfg(feature = "smoltcp")]
pub const UNICAST_TTL: u8 = 64;

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
/// `Ipv4Repr::emit`: don't fragment, DSCP 0; the TTL [`Endpoints::ttl`]), written once; each
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
            hop_limit: endpoints.ttl,
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
    /// [`RepairWindow`](super::repair::RepairWindow)) of `session`'s stream, as transmit-buffer words,
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
        w[Self::RTP_WORD] =
            (2 << 30 | u32::from(marker | session.payload_type()) << 16 | (packet.seq & 0xffff)).to_be();
        w[Self::RTP_WORD + 1] = packet.timestamp.to_be();
        w[Self::RTP_WORD + 2] = session.ssrc().to_be();
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

    #[test]
    fn the_sizes_add_up() {
        assert_eq!((IPV4_TOTAL_LENGTH, UDP_LENGTH, FRAME_HEADER_BYTES), (1_488, 1_468, 62));
    }
}
