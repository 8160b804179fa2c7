//! DMA descriptor encodings of the DesignWare MAC, both formats, as pure
//! functions.
//!
//! Bit positions: Cyclone V HPS Technical Reference Manual (cv_5v4), EMAC
//! chapter, "Descriptor Formats" (alternate/enhanced descriptors, which the
//! Cyclone V EMACs use); Linux `drivers/net/ethernet/stmicro/stmmac/descs.h`
//! (both formats: `ETDES0_*`/`TDES1_*`, `RDES0_*`); QEMU
//! `hw/net/npcm_gmac.c` / `include/hw/net/npcm_gmac.h`, which decodes the
//! normal format only. 4-word descriptors (bus mode ATDS off). Summary in
//! docs/platform.md#dwmac-descriptors.
//!
//! | field | normal | enhanced |
//! |---|---|---|
//! | TDES0 | OWN 31 (status below) | OWN 31, IC 30, LS 29, FS 28, CIC 23:22, TER 21, TCH 20 |
//! | TDES1 | IC 31, LS 30, FS 29, CIC 28:27, TER 25, TCH 24, TBS2 21:11, TBS1 10:0 | TBS2 28:16, TBS1 12:0 |
//! | RDES0 | OWN 31, FL 29:16 (incl. 4-byte FCS), ES 15, FS 9, LS 8 | same |
//! | RDES1 | DIC 31, RER 25, RCH 24, RBS2 21:11, RBS1 10:0 | DIC 31, RBS2 28:16, RER 15, RCH 14, RBS1 12:0 |
//!
//! The driver uses ring mode (no chaining), one descriptor per frame, one
//! buffer per descriptor (buffer 2 size 0) for the smoltcp path and two for
//! [`crate::split`] (header in buffer 1, payload in buffer 2), no
//! interrupts, and checksum
//! insertion chosen per frame when the MAC has it ([`crate::csum`]): CIC = 3
//! (IPv4 header, and TCP/UDP with the pseudo-header) for TCP and UDP, CIC = 1
//! (IPv4 header only) for ICMP and every other IPv4 payload, CIC = 0 for
//! frames that are not IP (ARP). The stack computes ICMP checksums itself:
//! the databook's engine would corrupt a filled-in ICMP checksum under
//! CIC 2/3 (STM32 RM0090 rev 21, 33.5.2 "Transmit checksum offload": "for
//! ICMP-over-IPv4 packets, the checksum field in the ICMP packet must
//! always be 0x0000 in both modes"), and QEMU does not insert ICMP
//! checksums at all (`gmac_tx_get_csum` / `net_checksum_calculate` in
//! npcm_gmac.c).
//!
//! # Two buffers in ring mode
//!
//! With TCH (second address chained) clear, TDES3 is the bus address of
//! buffer 2 and TBS2 its size; the DMA sends buffer 1 then buffer 2 as one
//! stretch of the frame. Bit positions: Linux `stmmac/descs.h`
//! (`TDES1_BUFFER2_SIZE_MASK` = 21:11, `ETDES1_BUFFER2_SIZE_MASK` = 28:16),
//! `stmmac/descs_com.h` (`norm_set_tx_desc_len_on_ring`,
//! `enh_set_tx_desc_len_on_ring` fill TBS2 in ring mode) and
//! `stmmac/ring_mode.c` (`jumbo_frm` puts buffer 2's address in `des3`);
//! QEMU `include/hw/net/npcm_gmac.h` (`TX_DESC_TDES1_BFFR2_SZ_MASK`:
//! `extract32(word, 11, 11)`).
//!
//! QEMU's model sends buffer 2 (read in QEMU 10.0's and the current
//! `hw/net/npcm_gmac.c`, `gmac_try_send_next_packet`): after buffer 1
//! (`tdes2`, `TX_DESC_TDES1_BFFR1_SZ_MASK`), "If not chained we'll have a
//! second buffer": unless TDES1 bit 24 (TCH) is set it reads
//! `TX_DESC_TDES1_BFFR2_SZ_MASK(tdes1)` bytes from `tdes3` and appends them;
//! on LS it runs `net_checksum_calculate` over the assembled frame with the
//! CIC of the FS descriptor, then `qemu_send_packet`. So buffer 2 works
//! there, and a one-buffer descriptor must keep TBS2 = 0 (it does: QEMU
//! reads buffer 2 whenever TCH is clear). Up to QEMU 10.0.2 the same
//! function sends the *first* frame's bytes again for every further frame
//! it finds in one call (`prev_buf_size` is not reset after a send; fixed
//! in 10.0.3 and master by "hw/net/npcm_gmac.c: Send the right data for
//! second packet in a row"); the driver is not affected because it demands
//! a poll after every descriptor and QEMU transmits inside that register
//! write, one frame per call.

use crate::regs::HwFeature;

/// Descriptor word 0 bit 31, both formats, TX and RX: the DMA owns it.
pub const OWN: u32 = 1 << 31;

/// The descriptor format the MAC was synthesised with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DescFormat {
    /// Normal descriptors (QEMU's npcm-gmac).
    Normal,
    /// Enhanced ("alternate") descriptors (the Cyclone V EMACs).
    Enhanced,
}

impl DescFormat {
    /// The format announced by the HW feature register (offset 0x1058,
    /// bit 24 ENHDESSEL; Cyclone V TRM, EMAC register `HW_Feature`).
    pub const fn from_hw_feature(hw_feature: HwFeature) -> DescFormat {
        if hw_feature.enhdessel() {
            DescFormat::Enhanced
        } else {
            DescFormat::Normal
        }
    }

    /// Largest buffer size (buffer 1 or 2) a descriptor can describe (11
    /// bits normal, 13 bits enhanced; TBS1 and TBS2 have the same width).
    pub const fn max_buffer(self) -> usize {
        match self {
            DescFormat::Normal => (1 << 11) - 1,
            DescFormat::Enhanced => (1 << 13) - 1,
        }
    }
}

mod normal {
    pub const TDES1_CIC_SHIFT: u32 = 27; // 28:27
    pub const TDES1_LS: u32 = 1 << 30;
    pub const TDES1_FS: u32 = 1 << 29;
    pub const TDES1_TER: u32 = 1 << 25;
    pub const TDES1_TCH: u32 = 1 << 24;
    pub const TBS2_SHIFT: u32 = 11; // 21:11
    pub const TBS1_MASK: u32 = 0x7ff; // 10:0
    pub const RDES1_RER: u32 = 1 << 25;
    pub const RBS1_MASK: u32 = 0x7ff; // 10:0
}

mod enhanced {
    pub const TDES0_CIC_SHIFT: u32 = 22; // 23:22
    pub const TDES0_LS: u32 = 1 << 29;
    pub const TDES0_FS: u32 = 1 << 28;
    pub const TDES0_TER: u32 = 1 << 21;
    pub const TDES0_TCH: u32 = 1 << 20;
    pub const TBS2_SHIFT: u32 = 16; // 28:16
    pub const TBS1_MASK: u32 = 0x1fff; // 12:0
    pub const RDES1_RER: u32 = 1 << 15;
    pub const RBS1_MASK: u32 = 0x1fff; // 12:0
}

/// RDES0 bit 15: error summary.
pub const RDES0_ES: u32 = 1 << 15;
/// RDES0 bit 9: first descriptor of a frame.
pub const RDES0_FS: u32 = 1 << 9;
/// RDES0 bit 8: last descriptor of a frame.
pub const RDES0_LS: u32 = 1 << 8;
/// RDES0 bits 29:16: frame length including the 4-byte FCS.
pub const RDES0_FL_SHIFT: u32 = 16;
/// Mask of RDES0's frame length after shifting (14 bits).
pub const RDES0_FL_MASK: u32 = 0x3fff;
/// Bytes of frame check sequence at the end of every received frame.
pub const FCS_LEN: usize = 4;

/// Checksum insertion control (CIC, TDES0 23:22 enhanced, TDES1 28:27
/// normal): what the MAC computes on transmit. Encodings: STM32 RM0090 rev
/// 21, "TDES0: Transmit descriptor Word0", bits 23:22 (the same
/// Synopsys GMAC; the Cyclone V TRM's EMAC "Transmit Descriptor" table has
/// the same field).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChecksumInsertion {
    /// CIC = 0: the frame goes out as it is.
    Off = 0,
    /// CIC = 1: only the IPv4 header checksum is calculated and inserted.
    HeaderOnly = 1,
    /// CIC = 2: IPv4 header and payload (TCP/UDP/ICMP) checksums, the
    /// pseudo-header *not* calculated in hardware (the engine's "first
    /// mode": the field must hold the pseudo-header sum). Never used by the
    /// driver; here for the engine model in the tests.
    NoPseudoHeader = 2,
    /// CIC = 3: the IPv4 header checksum and the TCP/UDP checksum including
    /// the pseudo-header ("full"; what Linux stmmac's `TX_CIC_FULL` asks
    /// for).
    Full = 3,
}

impl ChecksumInsertion {
    /// The value of a 2-bit CIC field.
    pub const fn from_bits(bits: u32) -> ChecksumInsertion {
        match bits & 0b11 {
            0 => ChecksumInsertion::Off,
            1 => ChecksumInsertion::HeaderOnly,
            2 => ChecksumInsertion::NoPseudoHeader,
            _ => ChecksumInsertion::Full,
        }
    }
}

/// TDES0 and TDES1 for a whole frame of `len` bytes in buffer 1 (first and
/// last segment), `end_of_ring` on the ring's last descriptor, with
/// checksum insertion `csum`. TDES0 comes back *without* OWN: the driver
/// sets OWN in a separate, last write. `len` is truncated to the format's
/// buffer-size field.
pub const fn tx_control(format: DescFormat, len: usize, end_of_ring: bool, csum: ChecksumInsertion) -> [u32; 2] {
    tx_control_split(format, len, 0, end_of_ring, csum)
}

/// As [`tx_control`], for a whole frame in two buffers, ring mode (TCH
/// clear, so TDES3 holds buffer 2's address): `len1` bytes of buffer 1
/// (TDES2) followed by `len2` bytes of buffer 2 (TDES3) on the wire. Each
/// length is truncated to the format's buffer-size field
/// ([`DescFormat::max_buffer`]).
pub const fn tx_control_split(
    format: DescFormat,
    len1: usize,
    len2: usize,
    end_of_ring: bool,
    csum: ChecksumInsertion,
) -> [u32; 2] {
    match format {
        DescFormat::Normal => {
            let mut tdes1 = normal::TDES1_FS
                | normal::TDES1_LS
                | (csum as u32) << normal::TDES1_CIC_SHIFT
                | (len2 as u32 & normal::TBS1_MASK) << normal::TBS2_SHIFT
                | (len1 as u32 & normal::TBS1_MASK);
            if end_of_ring {
                tdes1 |= normal::TDES1_TER;
            }
            [0, tdes1]
        }
        DescFormat::Enhanced => {
            let mut tdes0 = enhanced::TDES0_FS | enhanced::TDES0_LS | (csum as u32) << enhanced::TDES0_CIC_SHIFT;
            if end_of_ring {
                tdes0 |= enhanced::TDES0_TER;
            }
            let tdes1 =
                (len2 as u32 & enhanced::TBS1_MASK) << enhanced::TBS2_SHIFT | (len1 as u32 & enhanced::TBS1_MASK);
            [tdes0, tdes1]
        }
    }
}

/// What the DMA reads from a transmit descriptor's TDES0 and TDES1 (the
/// inverse of [`tx_control_split`], for diagnostics and the tests' model of
/// the DMA).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TxFields {
    /// First segment of a frame.
    pub first: bool,
    /// Last segment of a frame.
    pub last: bool,
    /// End of ring: the next descriptor is the first.
    pub end_of_ring: bool,
    /// Second address chained: TDES3 is the next descriptor, not buffer 2.
    pub chained: bool,
    /// Buffer 1 size (TBS1).
    pub len1: usize,
    /// Buffer 2 size (TBS2).
    pub len2: usize,
    /// Checksum insertion control.
    pub csum: ChecksumInsertion,
}

/// Decode TDES0 and TDES1.
pub const fn tx_fields(format: DescFormat, [tdes0, tdes1]: [u32; 2]) -> TxFields {
    match format {
        DescFormat::Normal => TxFields {
            first: tdes1 & normal::TDES1_FS != 0,
            last: tdes1 & normal::TDES1_LS != 0,
            end_of_ring: tdes1 & normal::TDES1_TER != 0,
            chained: tdes1 & normal::TDES1_TCH != 0,
            len1: (tdes1 & normal::TBS1_MASK) as usize,
            len2: ((tdes1 >> normal::TBS2_SHIFT) & normal::TBS1_MASK) as usize,
            csum: ChecksumInsertion::from_bits(tdes1 >> normal::TDES1_CIC_SHIFT),
        },
        DescFormat::Enhanced => TxFields {
            first: tdes0 & enhanced::TDES0_FS != 0,
            last: tdes0 & enhanced::TDES0_LS != 0,
            end_of_ring: tdes0 & enhanced::TDES0_TER != 0,
            chained: tdes0 & enhanced::TDES0_TCH != 0,
            len1: (tdes1 & enhanced::TBS1_MASK) as usize,
            len2: ((tdes1 >> enhanced::TBS2_SHIFT) & enhanced::TBS1_MASK) as usize,
            csum: ChecksumInsertion::from_bits(tdes0 >> enhanced::TDES0_CIC_SHIFT),
        },
    }
}

/// The CIC field of a transmit descriptor's TDES0 and TDES1 (what the MAC
/// reads).
pub const fn tx_checksum_insertion(format: DescFormat, [tdes0, tdes1]: [u32; 2]) -> ChecksumInsertion {
    match format {
        DescFormat::Normal => ChecksumInsertion::from_bits(tdes1 >> normal::TDES1_CIC_SHIFT),
        DescFormat::Enhanced => ChecksumInsertion::from_bits(tdes0 >> enhanced::TDES0_CIC_SHIFT),
    }
}

/// RDES1 for a receive buffer of `buffer_len` bytes in buffer 1,
/// `end_of_ring` on the ring's last descriptor.
pub const fn rx_control(format: DescFormat, buffer_len: usize, end_of_ring: bool) -> u32 {
    match format {
        DescFormat::Normal => {
            let mut rdes1 = buffer_len as u32 & normal::RBS1_MASK;
            if end_of_ring {
                rdes1 |= normal::RDES1_RER;
            }
            rdes1
        }
        DescFormat::Enhanced => {
            let mut rdes1 = buffer_len as u32 & enhanced::RBS1_MASK;
            if end_of_ring {
                rdes1 |= enhanced::RDES1_RER;
            }
            rdes1
        }
    }
}

/// What a receive descriptor's RDES0 says (same in both formats).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxStatus {
    /// The DMA still owns it: nothing received yet.
    Dma,
    /// OWN is clear and the frame starts here, but the last-segment bit is
    /// not set (yet: QEMU clears OWN before it sets LS; or for good: a frame
    /// spread over several descriptors).
    Incomplete,
    /// A whole good frame of `len` bytes, FCS excluded.
    Frame {
        /// Frame length without the FCS.
        len: usize,
    },
    /// A frame flagged bad (error summary), too short to hold an FCS, or
    /// the continuation of a frame spread over several descriptors (no FS).
    Bad,
}

/// Decode RDES0.
pub const fn rx_status(rdes0: u32) -> RxStatus {
    if rdes0 & OWN != 0 {
        return RxStatus::Dma;
    }
    if rdes0 & RDES0_FS == 0 {
        return RxStatus::Bad;
    }
    if rdes0 & RDES0_LS == 0 {
        return RxStatus::Incomplete;
    }
    let fl = ((rdes0 >> RDES0_FL_SHIFT) & RDES0_FL_MASK) as usize;
    if rdes0 & RDES0_ES != 0 || fl < FCS_LEN {
        return RxStatus::Bad;
    }
    RxStatus::Frame { len: fl - FCS_LEN }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ChecksumInsertion::{Full, Off};

    /// Bits `hi..=lo` of `word`.
    fn field(word: u32, hi: u32, lo: u32) -> u32 {
        (word >> lo) & ((1u64 << (hi - lo + 1)) - 1) as u32
    }
    fn bit(word: u32, n: u32) -> bool {
        word & (1 << n) != 0
    }

    #[test]
    fn hw_feature_bit_24_selects_the_format() {
        // QEMU npcm-gmac's HW feature value (npcm_gmac.c reset value): bit 24 clear.
        let hw = HwFeature::new_with_raw_value;
        assert_eq!(DescFormat::from_hw_feature(hw(0x100d_4f37)), DescFormat::Normal);
        assert_eq!(DescFormat::from_hw_feature(hw(0x100d_4f37 | (1 << 24))), DescFormat::Enhanced);
        assert_eq!(DescFormat::from_hw_feature(hw(1 << 24)), DescFormat::Enhanced);
        assert_eq!(DescFormat::from_hw_feature(hw(!(1 << 24))), DescFormat::Normal);
    }

    #[test]
    fn normal_tx_descriptor_bit_positions() {
        let [t0, t1] = tx_control(DescFormat::Normal, 1514, false, Off);
        assert_eq!(t0, 0, "normal TDES0 carries only OWN/status");
        assert!(!bit(t1, 31), "IC 31 off");
        assert!(bit(t1, 30), "LS 30");
        assert!(bit(t1, 29), "FS 29");
        assert_eq!(field(t1, 28, 27), 0, "CIC 28:27 off");
        assert!(!bit(t1, 25), "TER 25 only at ring end");
        assert!(!bit(t1, 24), "TCH 24 off (ring mode)");
        assert_eq!(field(t1, 21, 11), 0, "TBS2 21:11 = 0");
        assert_eq!(field(t1, 10, 0), 1514, "TBS1 10:0");
        let [_, t1_end] = tx_control(DescFormat::Normal, 60, true, Off);
        assert!(bit(t1_end, 25), "TER 25");
        assert_eq!(field(t1_end, 10, 0), 60);
        assert_eq!(t1_end, (1 << 30) | (1 << 29) | (1 << 25) | 60);
    }

    #[test]
    fn enhanced_tx_descriptor_bit_positions() {
        let [t0, t1] = tx_control(DescFormat::Enhanced, 1514, false, Off);
        assert!(!bit(t0, 31), "OWN is set separately");
        assert!(!bit(t0, 30), "IC 30 off");
        assert!(bit(t0, 29), "LS 29");
        assert!(bit(t0, 28), "FS 28");
        assert_eq!(field(t0, 23, 22), 0, "CIC 23:22 off");
        assert!(!bit(t0, 21), "TER 21 only at ring end");
        assert!(!bit(t0, 20), "TCH 20 off");
        assert_eq!(field(t1, 28, 16), 0, "TBS2 28:16 = 0");
        assert_eq!(field(t1, 12, 0), 1514, "TBS1 12:0");
        let [t0_end, t1_end] = tx_control(DescFormat::Enhanced, 4000, true, Off);
        assert!(bit(t0_end, 21), "TER 21");
        assert_eq!(t0_end, (1 << 29) | (1 << 28) | (1 << 21));
        assert_eq!(t1_end, 4000, "13-bit size field holds 4000");
    }

    #[test]
    fn two_buffer_normal_descriptor_bit_positions() {
        // An RTP row: 62-byte header in buffer 1, 1440 pixel bytes in buffer 2.
        let [t0, t1] = tx_control_split(DescFormat::Normal, 62, 1440, false, Full);
        assert_eq!(t0, 0, "normal TDES0 carries only OWN/status");
        assert_eq!(field(t1, 21, 11), 1440, "TBS2 21:11");
        assert_eq!(field(t1, 10, 0), 62, "TBS1 10:0");
        assert!(!bit(t1, 24), "TCH 24 clear: TDES3 is buffer 2, not the next descriptor");
        assert!(bit(t1, 30) && bit(t1, 29), "LS and FS: the whole frame");
        assert_eq!(field(t1, 28, 27), 3, "CIC 28:27");
        assert_eq!(t1, (1 << 30) | (1 << 29) | (3 << 27) | (1440 << 11) | 62);
        // The largest sizes fill their fields and no neighbour.
        let [_, max] = tx_control_split(DescFormat::Normal, 2047, 2047, true, Off);
        assert_eq!(max, (1 << 30) | (1 << 29) | (1 << 25) | (0x7ff << 11) | 0x7ff);
    }

    #[test]
    fn two_buffer_enhanced_descriptor_bit_positions() {
        let [t0, t1] = tx_control_split(DescFormat::Enhanced, 62, 1440, false, Full);
        assert_eq!(field(t1, 28, 16), 1440, "TBS2 28:16");
        assert_eq!(field(t1, 12, 0), 62, "TBS1 12:0");
        assert_eq!(t1, (1440 << 16) | 62, "nothing else in TDES1");
        assert!(!bit(t0, 20), "TCH 20 clear: TDES3 is buffer 2");
        assert_eq!(t0, (1 << 29) | (1 << 28) | (3 << 22), "LS, FS, CIC 3");
        let [_, max] = tx_control_split(DescFormat::Enhanced, 8191, 8191, true, Off);
        assert_eq!(max, (0x1fff << 16) | 0x1fff);
    }

    #[test]
    fn two_buffer_descriptors_decode_back() {
        for format in [DescFormat::Normal, DescFormat::Enhanced] {
            for (len1, len2, end, csum) in [(62, 1440, false, Full), (14, 0, true, Off), (1514, 1, false, Off)] {
                let f = tx_fields(format, tx_control_split(format, len1, len2, end, csum));
                let want = TxFields { first: true, last: true, end_of_ring: end, chained: false, len1, len2, csum };
                assert_eq!(f, want, "{format:?}");
            }
            assert_eq!(tx_control(format, 60, true, Full), tx_control_split(format, 60, 0, true, Full));
        }
        // Chaining bits decode where the table puts them.
        assert!(tx_fields(DescFormat::Normal, [0, 1 << 24]).chained);
        assert!(tx_fields(DescFormat::Enhanced, [1 << 20, 0]).chained);
        assert!(!tx_fields(DescFormat::Enhanced, [0, 1 << 24]).chained);
    }

    #[test]
    fn checksum_insertion_bits() {
        let [n0, n1] = tx_control(DescFormat::Normal, 1514, false, Full);
        assert_eq!((n0, field(n1, 28, 27)), (0, 3), "normal: CIC in TDES1 28:27");
        assert_eq!(n1 & !(0b11 << 27), tx_control(DescFormat::Normal, 1514, false, Off)[1]);
        let [e0, e1] = tx_control(DescFormat::Enhanced, 1514, false, Full);
        assert_eq!(field(e0, 23, 22), 3, "enhanced: CIC in TDES0 23:22");
        assert_eq!(e0 & !(0b11 << 22), tx_control(DescFormat::Enhanced, 1514, false, Off)[0]);
        assert_eq!(e1, 1514);
    }

    #[test]
    fn every_cic_value_round_trips_through_both_formats() {
        use ChecksumInsertion::{HeaderOnly, NoPseudoHeader};
        for format in [DescFormat::Normal, DescFormat::Enhanced] {
            for cic in [Off, HeaderOnly, NoPseudoHeader, Full] {
                let [t0, t1] = tx_control(format, 60, true, cic);
                assert_eq!(tx_checksum_insertion(format, [t0, t1]), cic, "{format:?} {cic:?}");
            }
        }
        let [n0, n1] = tx_control(DescFormat::Normal, 60, false, HeaderOnly);
        assert_eq!((n0, field(n1, 28, 27)), (0, 1));
        let [e0, _] = tx_control(DescFormat::Enhanced, 60, false, HeaderOnly);
        assert_eq!(field(e0, 23, 22), 1);
    }

    #[test]
    fn formats_differ_where_the_table_says() {
        // The same frame must not encode the same way in both formats:
        // QEMU reads enhanced TDES1 as normal and finds no LS (npcm_gmac.c).
        let n = tx_control(DescFormat::Normal, 100, false, Off);
        let e = tx_control(DescFormat::Enhanced, 100, false, Off);
        assert_ne!(n, e);
        assert!(!bit(e[1], 30), "enhanced TDES1 has no normal LS bit");
    }

    #[test]
    fn rx_control_bit_positions() {
        let n = rx_control(DescFormat::Normal, 1536, false);
        assert_eq!(field(n, 10, 0), 1536, "RBS1 10:0");
        assert_eq!(field(n, 21, 11), 0, "RBS2 21:11");
        assert!(!bit(n, 25) && !bit(n, 24) && !bit(n, 31));
        let n_end = rx_control(DescFormat::Normal, 1536, true);
        assert_eq!(n_end, (1 << 25) | 1536, "RER 25");

        let e = rx_control(DescFormat::Enhanced, 1536, false);
        assert_eq!(field(e, 12, 0), 1536, "RBS1 12:0");
        assert_eq!(field(e, 28, 16), 0, "RBS2 28:16");
        assert!(!bit(e, 15) && !bit(e, 14) && !bit(e, 31));
        let e_end = rx_control(DescFormat::Enhanced, 1536, true);
        assert_eq!(e_end, (1 << 15) | 1536, "RER 15");
    }

    #[test]
    fn rx_status_decodes_rdes0() {
        let frame = |fl: u32| (fl << 16) | (1 << 9) | (1 << 8);
        assert_eq!(rx_status(OWN | frame(64)), RxStatus::Dma);
        assert_eq!(rx_status(frame(64)), RxStatus::Frame { len: 60 });
        assert_eq!(rx_status(frame(1518)), RxStatus::Frame { len: 1514 });
        // FL is 14 bits, 29:16.
        assert_eq!(rx_status(frame(0x3fff)), RxStatus::Frame { len: 0x3fff - 4 });
        // QEMU's race: OWN clear, FS set, LS not yet set.
        assert_eq!(rx_status((64 << 16) | (1 << 9)), RxStatus::Incomplete);
        assert_eq!(rx_status((64 << 16) | (1 << 8)), RxStatus::Bad, "continuation (LS, no FS)");
        assert_eq!(rx_status(frame(64) | (1 << 15)), RxStatus::Bad, "ES 15");
        assert_eq!(rx_status(frame(2)), RxStatus::Bad, "shorter than the FCS");
    }

    #[test]
    fn max_buffer_sizes() {
        assert_eq!(DescFormat::Normal.max_buffer(), 2047);
        assert_eq!(DescFormat::Enhanced.max_buffer(), 8191);
    }
}
