//! The receive frame filter: which multicast frames reach the DMA.
//!
//! The MAC drops, before DMA, every frame its filter does not pass. Own
//! unicast and broadcast always pass; a multicast frame passes only if its
//! destination's bin is set in the 256-bin hash table and the filter has
//! HMC set (Cyclone V HPS Technical Reference Manual, EMAC register map:
//! `MAC_Frame_Filter` at 0x004, `Hash_Table_Reg0..7` at 0x500..0x51C; the
//! board's device tree, Linux `socfpga.dtsi`, says 256 bins, and
//! `dwmac1000_core.c::dwmac1000_set_filter` programs them the same way).
//! With filter 0 every multicast frame is dropped: mDNS queries, IGMP
//! queries, RTCP from a multicast group's viewers. QEMU's npcm-gmac
//! applies no filter at all; `cargo xtask test`'s relay does
//! (xtask/src/emulated/mac_filter.rs).

use smoltcp::wire::Ipv4Address;

/// `MAC_Frame_Filter` HMC (bit 2): multicast frames through the hash table.
pub const HMC: u32 = 1 << 2;
/// `MAC_Frame_Filter` HPF (bit 10): a frame passes on a hash or a perfect
/// (address register) match; Linux sets it always.
pub const HPF: u32 = 1 << 10;

/// The hash bins of a set of multicast MAC addresses, and the frame filter
/// value that passes them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MulticastFilter {
    bins: [u32; 8],
}

impl MulticastFilter {
    /// No multicast frame passes.
    pub const fn new() -> MulticastFilter {
        MulticastFilter { bins: [0; 8] }
    }

    /// Pass frames to Ethernet address `mac`.
    pub fn add(&mut self, mac: [u8; 6]) {
        let bin = hash_bin(mac);
        self.bins[usize::from(bin >> 5)] |= 1 << (bin & 31);
    }

    /// Pass frames to IPv4 group `group` (RFC 1112 section 6.4: 01-00-5E
    /// and the group's low 23 bits).
    pub fn add_group(&mut self, group: Ipv4Address) {
        let [_, b, c, d] = group.octets();
        self.add([0x01, 0x00, 0x5e, b & 0x7f, c, d]);
    }

    /// The `Hash_Table_Reg0..7` values.
    pub fn bins(&self) -> [u32; 8] {
        self.bins
    }

    /// The `MAC_Frame_Filter` value: HPF always (as Linux writes it), HMC
    /// when any bin is set.
    pub fn frame_filter(&self) -> u32 {
        if self.bins == [0; 8] {
            HPF
        } else {
            HPF | HMC
        }
    }
}

/// The hash bin of destination `mac`: the top 8 bits of the bit-reversed
/// CRC-32 of the address (Linux: `bitrev32(~crc32_le(~0, addr, 6)) >> 24`),
/// that is the CRC's low byte reversed.
pub fn hash_bin(mac: [u8; 6]) -> u8 {
    (crc32fast::hash(&mac) as u8).reverse_bits()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The register values for the groups the board joins (bins computed
    /// independently with Python's zlib.crc32: 224.0.0.251 -> 192,
    /// 224.0.0.1 -> 128).
    #[test]
    fn the_groups_the_board_joins_set_their_bins() {
        let mut f = MulticastFilter::new();
        assert_eq!(f.frame_filter(), HPF, "nothing joined: no hash");
        f.add_group(Ipv4Address::new(224, 0, 0, 251));
        assert_eq!(f.bins(), [0, 0, 0, 0, 0, 0, 1, 0]);
        f.add_group(Ipv4Address::new(224, 0, 0, 1));
        assert_eq!(f.bins(), [0, 0, 0, 0, 1, 0, 1, 0]);
        assert_eq!(f.frame_filter(), 0x404);
        // The camera's first two multicast groups: 01:00:5e:7f:2a:01 bin
        // 34, ..:02 bin 127.
        let mut g = MulticastFilter::new();
        g.add_group(Ipv4Address::new(239, 255, 42, 1));
        g.add_group(Ipv4Address::new(239, 255, 42, 2));
        assert_eq!(g.bins(), [0, 1 << 2, 0, 1 << 31, 0, 0, 0, 0]);
    }

    #[test]
    fn a_group_s_top_address_bit_is_not_in_its_mac() {
        let (mut a, mut b) = (MulticastFilter::new(), MulticastFilter::new());
        a.add_group(Ipv4Address::new(239, 128, 0, 1));
        b.add_group(Ipv4Address::new(239, 0, 0, 1));
        assert_eq!(a, b);
    }
}
