//! The DesignWare GMAC register block, typed.
//!
//! Offsets and bits: Cyclone V Hard Processor System Technical Reference
//! Manual (Intel, cv_5v4), chapter "Ethernet Media Access Controller",
//! register map of `emac0`/`emac1`: GMAC registers from offset 0x0000, DMA
//! registers from 0x1000. QEMU's `hw/net/npcm_gmac.c` implements the same
//! layout (docs/platform.md#qemus-npcm-gmac).
//!
//! The block ends at 0x105C, after the HW feature register: QEMU's model
//! keeps its registers in an array that ends at 0x1060 and does not bounds-
//! check accesses past it, so the driver cannot be allowed to name those
//! offsets; [`RegisterBlock`]'s size makes sure it cannot.

use core::mem::{offset_of, size_of};
use core::ptr::NonNull;

use arbitrary_int::{u4, u5, u6};
use bitbybit::bitfield;
use volatile_register::{RO, RW, WO};

/// MAC configuration register (0x0000).
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct MacConfig {
    /// PS: port select, 1 = MII (10/100 Mbit/s), 0 = GMII (1000 Mbit/s).
    #[bit(15, rw)]
    pub ps: bool,
    /// FES: 100 Mbit/s (with PS).
    #[bit(14, rw)]
    pub fes: bool,
    /// DM: full duplex.
    #[bit(11, rw)]
    pub dm: bool,
    /// TE: transmitter enable.
    #[bit(3, rw)]
    pub te: bool,
    /// RE: receiver enable (QEMU gates reception on it).
    #[bit(2, rw)]
    pub re: bool,
}

/// GMII (MDIO) address register (0x0010).
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct GmiiAddress {
    /// PA: PHY address.
    #[bits(11..=15, rw)]
    pub pa: u5,
    /// GR: PHY register.
    #[bits(6..=10, rw)]
    pub gr: u5,
    /// CR: MDC clock range (divider of the CSR clock).
    #[bits(2..=5, rw)]
    pub cr: u4,
    /// GW: the access is a write.
    #[bit(1, rw)]
    pub gw: bool,
    /// GB: busy; set to start an access, cleared by the MAC when done.
    #[bit(0, rw)]
    pub gb: bool,
}

/// MDC clock range code 4: CSR clock 150-250 MHz, MDC = CSR clock / 102
/// (Cyclone V TRM, `gmiigrp_gmii_address.cr`; the Cyclone V EMACs run their
/// CSR clock at 250 MHz from the preloader's PLL settings).
pub const CR_150_250_MHZ: u4 = u4::new(4);

/// DMA bus mode register (0x1000).
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct BusMode {
    /// PBL: programmable burst length in beats.
    #[bits(8..=13, rw)]
    pub pbl: u6,
    /// ATDS: 8-word descriptors; the driver keeps 4-word ones (off).
    #[bit(7, rw)]
    pub atds: bool,
    /// SWR: software reset of the whole MAC, cleared by the MAC when done.
    /// On the Cyclone V it completes only while the PHY drives the RX clock.
    #[bit(0, rw)]
    pub swr: bool,
}

/// DMA status register (0x1014); bits 16:0 are write-1-to-clear.
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct DmaStatus {
    /// RU: receive buffer unavailable (the receive DMA stopped for want of
    /// descriptors; QEMU restarts it when the bit is cleared).
    #[bit(7, rw)]
    pub ru: bool,
    /// TU: transmit buffer unavailable.
    #[bit(2, rw)]
    pub tu: bool,
}

impl DmaStatus {
    /// Every write-1-to-clear bit.
    pub const ALL_W1C: DmaStatus = DmaStatus::new_with_raw_value(0x1_ffff);
}

/// DMA operation mode register (0x1018).
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct OpMode {
    /// RSF: receive store and forward.
    #[bit(25, rw)]
    pub rsf: bool,
    /// TSF: transmit store and forward (required for checksum insertion:
    /// Linux `stmmac_dma_operation_mode` forces it when TX checksum offload
    /// is on).
    #[bit(21, rw)]
    pub tsf: bool,
    /// FTF: flush the transmit FIFO (self-clearing on the board; QEMU keeps
    /// it set).
    #[bit(20, rw)]
    pub ftf: bool,
    /// ST: start transmission.
    #[bit(13, rw)]
    pub st: bool,
    /// SR: start receive.
    #[bit(1, rw)]
    pub sr: bool,
}

/// HW feature register (0x1058): what the MAC was synthesised with.
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct HwFeature {
    /// ENHDESSEL: enhanced ("alternate") descriptors.
    #[bit(24, r)]
    pub enhdessel: bool,
    /// TXCOESEL: transmit checksum offload.
    #[bit(16, r)]
    pub txcoesel: bool,
}

/// The GMAC (MAC) registers at 0x0000.
#[repr(C)]
pub struct MacRegisters {
    /// 0x00 MAC configuration.
    pub config: RW<MacConfig>,
    /// 0x04 MAC frame filter.
    pub frame_filter: RW<u32>,
    // 0x08, 0x0c: hash table high/low (unused).
    _hash: [u32; 2],
    /// 0x10 GMII (MDIO) address.
    pub gmii_address: RW<GmiiAddress>,
    /// 0x14 GMII (MDIO) data, bits 15:0.
    pub gmii_data: RW<u32>,
    // 0x18 flow control, 0x1c VLAN tag (unused).
    _flow_vlan: [u32; 2],
    /// 0x20 Synopsys version (Cyclone V 0x1037 for 3.70a; QEMU 0x1032).
    pub version: RO<u32>,
    // 0x24..0x40: debug, wake-up, PMT, LPI and interrupt registers (unused).
    _misc: [u32; 7],
    /// 0x40 MAC address 0 high: `mac[5] << 8 | mac[4]`.
    pub address0_high: RW<u32>,
    /// 0x44 MAC address 0 low: `mac[3] << 24 | .. | mac[0]`.
    pub address0_low: RW<u32>,
}

/// The DMA registers at 0x1000.
#[repr(C)]
pub struct DmaRegisters {
    /// 0x00 bus mode.
    pub bus_mode: RW<BusMode>,
    /// 0x04 transmit poll demand (any value).
    pub tx_poll_demand: WO<u32>,
    /// 0x08 receive poll demand (any value).
    pub rx_poll_demand: WO<u32>,
    /// 0x0c receive descriptor list address (QEMU latches it only right
    /// after a reset).
    pub rx_descriptor_list: RW<u32>,
    /// 0x10 transmit descriptor list address.
    pub tx_descriptor_list: RW<u32>,
    /// 0x14 status.
    pub status: RW<DmaStatus>,
    /// 0x18 operation mode.
    pub op_mode: RW<OpMode>,
    /// 0x1c interrupt enable.
    pub interrupt_enable: RW<u32>,
    // 0x20..0x58: counters, watchdog, AXI bus mode, current host
    // descriptor and buffer addresses (unused; the missed-frame counter
    // clears on read, so it is not even read).
    _misc: [u32; 14],
    /// 0x58 HW feature.
    pub hw_feature: RO<HwFeature>,
}

/// The hash table's offset (Cyclone V HPS TRM, EMAC `Hash_Table_Reg0`).
pub const HASH_TABLE_OFFSET: usize = 0x500;

/// Words between the MAC registers and the hash table.
const GAP_WORDS: usize = (HASH_TABLE_OFFSET - size_of::<MacRegisters>()) / 4;

/// Words between the hash table and the DMA registers.
const GAP2_WORDS: usize = (0x1000 - HASH_TABLE_OFFSET - 32) / 4;

/// The whole register block, 0x0000 up to (not including) 0x105C.
#[repr(C)]
pub struct RegisterBlock {
    /// GMAC registers.
    pub mac: MacRegisters,
    // 0x0048..0x0500: more address registers, MMC counters, L3/L4 filters.
    _reserved: [u32; GAP_WORDS],
    /// 0x0500..0x0520 `Hash_Table_Reg0..7`: the 256-bin multicast hash
    /// (the Cyclone V's; the 64-bin registers at 0x08/0x0C are reserved
    /// there). QEMU's npcm-gmac stores the writes and filters nothing.
    pub hash_table: [RW<u32>; 8],
    // 0x0520..0x1000: VLAN hash, timestamping, more address registers.
    _reserved2: [u32; GAP2_WORDS],
    /// DMA registers.
    pub dma: DmaRegisters,
}

/// First offset that must never be accessed (QEMU's register array ends).
pub const FORBIDDEN_FROM: usize = 0x1060;

const _: () = {
    assert!(offset_of!(MacRegisters, config) == 0x00);
    assert!(offset_of!(MacRegisters, frame_filter) == 0x04);
    assert!(offset_of!(MacRegisters, gmii_address) == 0x10);
    assert!(offset_of!(MacRegisters, gmii_data) == 0x14);
    assert!(offset_of!(MacRegisters, version) == 0x20);
    assert!(offset_of!(MacRegisters, address0_high) == 0x40);
    assert!(offset_of!(MacRegisters, address0_low) == 0x44);
    assert!(offset_of!(RegisterBlock, hash_table) == HASH_TABLE_OFFSET);
    assert!(offset_of!(RegisterBlock, dma) == 0x1000);
    assert!(offset_of!(DmaRegisters, tx_poll_demand) == 0x04);
    assert!(offset_of!(DmaRegisters, rx_poll_demand) == 0x08);
    assert!(offset_of!(DmaRegisters, rx_descriptor_list) == 0x0c);
    assert!(offset_of!(DmaRegisters, tx_descriptor_list) == 0x10);
    assert!(offset_of!(DmaRegisters, status) == 0x14);
    assert!(offset_of!(DmaRegisters, op_mode) == 0x18);
    assert!(offset_of!(DmaRegisters, interrupt_enable) == 0x1c);
    assert!(offset_of!(DmaRegisters, hw_feature) == 0x58);
    // The block ends right after HW feature, before QEMU's hazard.
    assert!(size_of::<RegisterBlock>() == 0x105c);
    assert!(size_of::<RegisterBlock>() <= FORBIDDEN_FROM);
};

/// Exclusive access to one MAC's register block. Holds a raw pointer, never
/// a reference with a lifetime, so the compiler cannot assume the registers
/// are ordinary memory outside an access.
pub struct Regs {
    block: NonNull<RegisterBlock>,
}

impl Regs {
    /// The register block at `base`.
    ///
    /// # Safety
    ///
    /// `base` points to a DesignWare GMAC register block (mapped as Device or
    /// Strongly-ordered memory), or to memory laid out as one that outlives
    /// the value (host tests); nothing else accesses it while this value
    /// exists.
    pub const unsafe fn new(base: NonNull<RegisterBlock>) -> Regs {
        Regs { block: base }
    }

    /// The GMAC registers.
    pub fn mac(&self) -> &MacRegisters {
        // SAFETY: `new`'s contract: the block is valid and exclusively ours;
        // every field is a volatile cell, so a shared reference to it only
        // ever leads to volatile accesses.
        unsafe { &self.block.as_ref().mac }
    }

    /// The DMA registers.
    pub fn dma(&self) -> &DmaRegisters {
        // SAFETY: as in `mac`.
        unsafe { &self.block.as_ref().dma }
    }

    /// The multicast hash table registers.
    pub fn hash_table(&self) -> &[RW<u32>; 8] {
        // SAFETY: as in `mac`.
        unsafe { &self.block.as_ref().hash_table }
    }
}

// The driver's register writes, one method each, so the unsafe stores of
// volatile-register stay here. SAFETY (for every method below): `Regs::new`
// makes the block valid and exclusively ours; each is one volatile 32-bit
// store whose only effects are the MAC's documented ones.
impl Regs {
    /// Write the MAC configuration.
    pub fn set_config(&self, value: MacConfig) {
        // SAFETY: see above.
        unsafe { self.mac().config.write(value) }
    }

    /// Write the frame filter.
    pub fn set_frame_filter(&self, value: u32) {
        // SAFETY: see above.
        unsafe { self.mac().frame_filter.write(value) }
    }

    /// Write the multicast hash table.
    pub fn set_hash_table(&self, bins: [u32; 8]) {
        for (reg, value) in self.hash_table().iter().zip(bins) {
            // SAFETY: see above.
            unsafe { reg.write(value) }
        }
    }

    /// Start an MDIO access (with `gmii_data` written first for a write).
    pub fn start_mdio(&self, access: GmiiAddress, data: Option<u16>) {
        // SAFETY: see above.
        unsafe {
            if let Some(d) = data {
                self.mac().gmii_data.write(u32::from(d));
            }
            self.mac().gmii_address.write(access);
        }
    }

    /// Program MAC address 0.
    pub fn set_address(&self, mac: [u8; 6]) {
        let (hi, lo) = mac_address_words(mac);
        // SAFETY: see above.
        unsafe {
            self.mac().address0_high.write(hi);
            self.mac().address0_low.write(lo);
        }
    }

    /// Write the DMA bus mode.
    pub fn set_bus_mode(&self, value: BusMode) {
        // SAFETY: see above.
        unsafe { self.dma().bus_mode.write(value) }
    }

    /// Point the DMA at the descriptor rings (bus addresses).
    pub fn set_descriptor_lists(&self, rx: u32, tx: u32) {
        // SAFETY: see above; the caller placed valid rings there.
        unsafe {
            self.dma().rx_descriptor_list.write(rx);
            self.dma().tx_descriptor_list.write(tx);
        }
    }

    /// Clear the status bits set in `bits` (write 1 to clear).
    pub fn clear_status(&self, bits: DmaStatus) {
        // SAFETY: see above.
        unsafe { self.dma().status.write(bits) }
    }

    /// Write the operation mode.
    pub fn set_op_mode(&self, value: OpMode) {
        // SAFETY: see above.
        unsafe { self.dma().op_mode.write(value) }
    }

    /// Mask every DMA interrupt (the driver polls).
    pub fn disable_interrupts(&self) {
        // SAFETY: see above.
        unsafe { self.dma().interrupt_enable.write(0) }
    }

    /// Transmit poll demand: the DMA looks at the next TX descriptor.
    pub fn tx_poll_demand(&self) {
        // SAFETY: see above.
        unsafe { self.dma().tx_poll_demand.write(0) }
    }

    /// Receive poll demand: the DMA looks at the next RX descriptor.
    pub fn rx_poll_demand(&self) {
        // SAFETY: see above.
        unsafe { self.dma().rx_poll_demand.write(0) }
    }
}

/// `address0_high` and `address0_low` values for `mac`.
pub const fn mac_address_words(mac: [u8; 6]) -> (u32, u32) {
    let hi = (mac[5] as u32) << 8 | mac[4] as u32;
    let lo = (mac[3] as u32) << 24 | (mac[2] as u32) << 16 | (mac[1] as u32) << 8 | mac[0] as u32;
    (hi, lo)
}

/// The GMII address word that starts an MDIO access to `reg` of `phy`.
pub fn gmii_access(phy: u8, reg: u8, write: bool) -> GmiiAddress {
    GmiiAddress::DEFAULT
        .with_pa(u5::new(phy & 0x1f))
        .with_gr(u5::new(reg & 0x1f))
        .with_cr(CR_150_250_MHZ)
        .with_gw(write)
        .with_gb(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mac_address_layout() {
        let (hi, lo) = mac_address_words([0x02, 0x00, 0x52, 0x54, 0x00, 0x12]);
        assert_eq!(hi, 0x1200);
        assert_eq!(lo, 0x5452_0002);
    }

    #[test]
    fn gmii_address_layout() {
        assert_eq!(gmii_access(0, 1, false).raw_value(), (1 << 6) | (4 << 2) | 1);
        assert_eq!(gmii_access(31, 31, true).raw_value(), (31 << 11) | (31 << 6) | (4 << 2) | 2 | 1);
    }

    #[test]
    fn bitfields_sit_where_the_manual_says() {
        let c = MacConfig::DEFAULT.with_re(true).with_te(true).with_dm(true).with_fes(true).with_ps(true);
        assert_eq!(c.raw_value(), (1 << 2) | (1 << 3) | (1 << 11) | (1 << 14) | (1 << 15));
        let op = OpMode::DEFAULT.with_sr(true).with_st(true).with_ftf(true).with_tsf(true).with_rsf(true);
        assert_eq!(op.raw_value(), (1 << 1) | (1 << 13) | (1 << 20) | (1 << 21) | (1 << 25));
        assert_eq!(BusMode::DEFAULT.with_pbl(u6::new(8)).with_swr(true).raw_value(), (8 << 8) | 1);
        assert_eq!(DmaStatus::DEFAULT.with_ru(true).with_tu(true).raw_value(), (1 << 7) | (1 << 2));
        let qemu = HwFeature::new_with_raw_value(0x100d_4f37);
        assert!(!qemu.enhdessel() && qemu.txcoesel(), "QEMU: normal descriptors, TX checksum offload");
    }
}
