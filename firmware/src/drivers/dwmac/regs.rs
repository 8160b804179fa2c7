//! Register offsets and bits of the DesignWare GMAC (Synopsys DWC Ethernet
//! MAC 3.x) used by the driver.
//!
//! Sources: Cyclone V HPS TRM (cv_5v4), EMAC chapter, register map of
//! `emac0`/`emac1` (GMAC registers from offset 0x0000, DMA registers from
//! 0x1000); `shared/PLATFORM.md` "What QEMU's npcm-gmac emulates" and
//! "Minimal MAC bring-up". QEMU's model reads/writes past its register array
//! at 0x1060..0x1fff: the driver never touches those offsets.

/// MAC configuration.
pub const MAC_CONFIG: usize = 0x0000;
/// MAC frame filter.
pub const MAC_FRAME_FILTER: usize = 0x0004;
/// GMII (MDIO) address.
pub const GMII_ADDR: usize = 0x0010;
/// GMII (MDIO) data.
pub const GMII_DATA: usize = 0x0014;
/// Synopsys version (QEMU: 0x1032; Cyclone V: 0x1037 for 3.70a).
pub const VERSION: usize = 0x0020;
/// MAC address 0 high: `mac[5] << 8 | mac[4]`.
pub const MAC_ADDR0_HI: usize = 0x0040;
/// MAC address 0 low: `mac[3] << 24 | mac[2] << 16 | mac[1] << 8 | mac[0]`.
pub const MAC_ADDR0_LO: usize = 0x0044;

/// DMA bus mode.
pub const DMA_BUS_MODE: usize = 0x1000;
/// DMA transmit poll demand (any value).
pub const DMA_TX_POLL: usize = 0x1004;
/// DMA receive poll demand (any value).
pub const DMA_RX_POLL: usize = 0x1008;
/// Receive descriptor list base.
pub const DMA_RX_BASE: usize = 0x100c;
/// Transmit descriptor list base.
pub const DMA_TX_BASE: usize = 0x1010;
/// DMA status (write 1 to clear bits 16:0).
pub const DMA_STATUS: usize = 0x1014;
/// DMA operation mode.
pub const DMA_OP_MODE: usize = 0x1018;
/// DMA interrupt enable.
pub const DMA_INT_ENABLE: usize = 0x101c;
/// HW feature register (bit 24: enhanced descriptors).
pub const DMA_HW_FEATURE: usize = 0x1058;
/// First offset the driver must never touch (QEMU's register array ends).
pub const FORBIDDEN_FROM: usize = 0x1060;

/// MAC config bit 2, RE: receiver enable.
pub const MAC_CONFIG_RE: u32 = 1 << 2;
/// MAC config bit 3, TE: transmitter enable.
pub const MAC_CONFIG_TE: u32 = 1 << 3;
/// MAC config bit 11, DM: full duplex.
pub const MAC_CONFIG_DM: u32 = 1 << 11;
/// MAC config bit 14, FES: 100 Mbit/s (with PS).
pub const MAC_CONFIG_FES: u32 = 1 << 14;
/// MAC config bit 15, PS: port select, 1 = MII (10/100), 0 = GMII (1000).
pub const MAC_CONFIG_PS: u32 = 1 << 15;

/// GMII address bit 0, GB: MDIO busy.
pub const GMII_BUSY: u32 = 1 << 0;
/// GMII address bit 1, GW: write.
pub const GMII_WRITE: u32 = 1 << 1;
/// GMII address bits 5:2, CR: MDC clock range.
pub const GMII_CR_SHIFT: u32 = 2;
/// Clock range code 4: CSR clock 150-250 MHz, MDC = clock / 102
/// (PLATFORM.md "Minimal MAC bring-up" step 7).
pub const GMII_CR_150_250: u32 = 4;
/// GMII address bits 10:6, GR: PHY register.
pub const GMII_REG_SHIFT: u32 = 6;
/// GMII address bits 15:11, PA: PHY address.
pub const GMII_PHY_SHIFT: u32 = 11;

/// Bus mode bit 0, SWR: software reset (clears itself when done).
pub const BUS_MODE_SWR: u32 = 1 << 0;
/// Bus mode bits 13:8, PBL: programmable burst length.
pub const BUS_MODE_PBL_SHIFT: u32 = 8;
/// The burst length used (PLATFORM.md step 3).
pub const BUS_MODE_PBL: u32 = 8;

/// Status bit 2, TU: transmit buffer unavailable.
pub const STATUS_TU: u32 = 1 << 2;
/// Status bit 7, RU: receive buffer unavailable (clearing it restarts
/// receive in QEMU).
pub const STATUS_RU: u32 = 1 << 7;
/// Status bits 16:0 are write-1-to-clear.
pub const STATUS_W1C: u32 = 0x1_ffff;

/// Operation mode bit 1, SR: start receive.
pub const OP_MODE_SR: u32 = 1 << 1;
/// Operation mode bit 13, ST: start transmit.
pub const OP_MODE_ST: u32 = 1 << 13;
/// Operation mode bit 20, FTF: flush transmit FIFO.
pub const OP_MODE_FTF: u32 = 1 << 20;
/// Operation mode bit 21, TSF: transmit store and forward.
pub const OP_MODE_TSF: u32 = 1 << 21;
/// Operation mode bit 25, RSF: receive store and forward.
pub const OP_MODE_RSF: u32 = 1 << 25;

/// `MAC_ADDR0_HI` and `MAC_ADDR0_LO` values for `mac` (PLATFORM.md step 4).
pub const fn mac_address_regs(mac: [u8; 6]) -> (u32, u32) {
    let hi = (mac[5] as u32) << 8 | mac[4] as u32;
    let lo = (mac[3] as u32) << 24 | (mac[2] as u32) << 16 | (mac[1] as u32) << 8 | mac[0] as u32;
    (hi, lo)
}

/// GMII address register value for an MDIO access.
pub const fn gmii_addr(phy: u8, reg: u8, write: bool) -> u32 {
    let mut v = ((phy as u32 & 0x1f) << GMII_PHY_SHIFT)
        | ((reg as u32 & 0x1f) << GMII_REG_SHIFT)
        | (GMII_CR_150_250 << GMII_CR_SHIFT)
        | GMII_BUSY;
    if write {
        v |= GMII_WRITE;
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mac_address_layout() {
        let (hi, lo) = mac_address_regs([0x02, 0x00, 0x52, 0x54, 0x00, 0x12]);
        assert_eq!(hi, 0x1200);
        assert_eq!(lo, 0x5452_0002);
    }

    #[test]
    fn gmii_address_layout() {
        assert_eq!(gmii_addr(0, 1, false), (1 << 6) | (4 << 2) | 1);
        assert_eq!(gmii_addr(31, 31, true), (31 << 11) | (31 << 6) | (4 << 2) | 2 | 1);
    }

    #[test]
    fn registers_stay_below_qemus_array_end() {
        for r in [DMA_BUS_MODE, DMA_TX_POLL, DMA_RX_POLL, DMA_RX_BASE, DMA_TX_BASE, DMA_STATUS,
                  DMA_OP_MODE, DMA_INT_ENABLE, DMA_HW_FEATURE] {
            assert!(r < FORBIDDEN_FROM);
        }
    }
}
