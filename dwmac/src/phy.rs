//! Ethernet PHY over MDIO (IEEE 802.3 clause 22): scan, generic
//! auto-negotiation, the Micrel KSZ9021 RGMII skews, link wait.
//!
//! Register numbers and bits: IEEE 802.3-2018 clause 22.2.4 (registers 0-10,
//! 15); KSZ9021RN data sheet (Micrel, rev. 1.2), "Register Map" (register
//! 0x1f PHY control, extended registers through 0x0b/0x0c). The sequence
//! follows U-Boot `drivers/net/phy/micrel_ksz90x1.c` and Linux
//! `drivers/net/phy/micrel.c` (docs/platform.md#phy).
//!
//! [`LinkMonitor`] watches the link from the main loop: a cable plugged in
//! late, a switch renegotiating to another speed, or a link lost and found
//! again all end in a MAC configuration that matches the PHY.

use core::fmt;

use embedded_hal::delay::DelayNs;

/// Basic mode control (reg 0).
pub const BMCR: u8 = 0;
/// Basic mode status (reg 1).
pub const BMSR: u8 = 1;
/// PHY identifier 1 (reg 2).
pub const PHYID1: u8 = 2;
/// PHY identifier 2 (reg 3).
pub const PHYID2: u8 = 3;
/// Auto-negotiation advertisement (reg 4).
pub const ANAR: u8 = 4;
/// Auto-negotiation link partner ability (reg 5).
pub const ANLPAR: u8 = 5;
/// 1000BASE-T control (reg 9).
pub const CTRL1000: u8 = 9;
/// 1000BASE-T status (reg 10).
pub const STAT1000: u8 = 10;
/// KSZ9021 extended register address (reg 0x0b; bit 15 = write).
pub const KSZ_EXT_CTRL: u8 = 0x0b;
/// KSZ9021 extended register write data (reg 0x0c).
pub const KSZ_EXT_WRITE: u8 = 0x0c;
/// KSZ9021 PHY control (reg 0x1f): bit 6 1000, bit 5 100, bit 3 full duplex.
pub const KSZ_PHY_CTRL: u8 = 0x1f;

/// BMCR bit 15: reset (self-clearing).
pub const BMCR_RESET: u16 = 1 << 15;
/// BMCR bit 13: speed select (LSB).
pub const BMCR_SPEED100: u16 = 1 << 13;
/// BMCR bit 12: auto-negotiation enable.
pub const BMCR_ANENABLE: u16 = 1 << 12;
/// BMCR bit 9: restart auto-negotiation.
pub const BMCR_ANRESTART: u16 = 1 << 9;
/// BMCR bit 8: full duplex.
pub const BMCR_FULLDPLX: u16 = 1 << 8;
/// BMCR bit 6: speed select (MSB, 1000 Mbit/s).
pub const BMCR_SPEED1000: u16 = 1 << 6;
/// BMSR bit 8: extended status (1000BASE-T registers present).
pub const BMSR_ESTATEN: u16 = 1 << 8;
/// BMSR bit 5: auto-negotiation complete.
pub const BMSR_ANEGCOMPLETE: u16 = 1 << 5;
/// BMSR bit 2: link status (latched low).
pub const BMSR_LSTATUS: u16 = 1 << 2;
/// ANAR: 100BASE-TX full, 100BASE-TX half, 10BASE-T full, half (bits 8..5),
/// selector 00001 (IEEE 802.3).
pub const ANAR_ALL_10_100: u16 = (1 << 8) | (1 << 7) | (1 << 6) | (1 << 5) | 0x01;
/// CTRL1000 bit 9: advertise 1000BASE-T full duplex.
pub const CTRL1000_FULL: u16 = 1 << 9;
/// CTRL1000 bit 8: advertise 1000BASE-T half duplex.
pub const CTRL1000_HALF: u16 = 1 << 8;
/// CTRL1000 bit 12: manual master/slave configuration.
pub const CTRL1000_MS_MANUAL: u16 = 1 << 12;
/// CTRL1000 bit 11: configure as master (with bit 12).
pub const CTRL1000_MASTER: u16 = 1 << 11;
/// STAT1000 bit 11: link partner is 1000BASE-T full-duplex capable.
pub const STAT1000_LP_FULL: u16 = 1 << 11;
/// STAT1000 bit 10: link partner is 1000BASE-T half-duplex capable.
pub const STAT1000_LP_HALF: u16 = 1 << 10;

/// An MDIO bus (clause 22), with the delay its users poll with.
pub trait Mdio: DelayNs {
    /// Read register `reg` of the PHY at `phy`.
    fn read(&mut self, phy: u8, reg: u8) -> Result<u16, MdioTimeout>;
    /// Write register `reg` of the PHY at `phy`.
    fn write(&mut self, phy: u8, reg: u8, value: u16) -> Result<(), MdioTimeout>;
}

/// The MDIO interface stayed busy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MdioTimeout;

impl fmt::Display for MdioTimeout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("MDIO access timed out")
    }
}

impl core::error::Error for MdioTimeout {}

/// A PHY found on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PhyId {
    /// MDIO address 0..=31.
    pub addr: u8,
    /// Identifier register 1 (OUI bits 3-18).
    pub id1: u16,
    /// Identifier register 2 (OUI bits 19-24, model, revision).
    pub id2: u16,
}

impl PhyId {
    /// A Micrel KSZ9021 (OUI 0x0022, model 0x21: ID 0x0022 / 0x161x).
    /// Source: KSZ9021RN data sheet, registers 2 and 3.
    pub const fn is_ksz9021(&self) -> bool {
        self.id1 == 0x0022 && (self.id2 & 0xfff0) == 0x1610
    }
}

impl fmt::Display for PhyId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "PHY {} id {:04x}:{:04x}", self.addr, self.id1, self.id2)
    }
}

/// Link speed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Speed {
    /// 10 Mbit/s.
    M10,
    /// 100 Mbit/s.
    M100,
    /// 1000 Mbit/s.
    M1000,
}

/// A negotiated link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Link {
    /// Speed.
    pub speed: Speed,
    /// Full duplex.
    pub full_duplex: bool,
}

impl fmt::Display for Link {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mbit = match self.speed {
            Speed::M10 => 10,
            Speed::M100 => 100,
            Speed::M1000 => 1000,
        };
        let duplex = if self.full_duplex { "full" } else { "half" };
        write!(f, "{mbit} Mbit/s {duplex} duplex")
    }
}

/// Board-specific PHY settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PhyConfig {
    /// KSZ9021 RGMII skews `(ext reg 0x104 clock/control, ext reg 0x105 RX
    /// data)`, written only when the PHY found is a KSZ9021.
    pub ksz9021_skews: Option<(u16, u16)>,
    /// Force 1000BASE-T master mode on a KSZ9021 (U-Boot does so for a chip
    /// erratum).
    pub ksz9021_force_master: bool,
}

/// Errors of the PHY bring-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhyError {
    /// No PHY answered at any address 0..=31.
    NotFound,
    /// An MDIO access timed out.
    Mdio,
    /// The PHY stayed in reset.
    ResetTimeout,
}

impl From<MdioTimeout> for PhyError {
    fn from(_: MdioTimeout) -> Self {
        PhyError::Mdio
    }
}

impl fmt::Display for PhyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PhyError::NotFound => "no PHY answers on MDIO addresses 0..31",
            PhyError::Mdio => "MDIO access timed out",
            PhyError::ResetTimeout => "PHY stayed in reset",
        })
    }
}

impl core::error::Error for PhyError {}

/// Scan addresses 0..=31; the first whose ID is neither 0x0000 nor 0xffff
/// wins. Addresses whose MDIO access times out are skipped.
pub fn scan(mdio: &mut impl Mdio) -> Result<PhyId, PhyError> {
    for addr in 0..32u8 {
        let (Ok(id1), Ok(id2)) = (mdio.read(addr, PHYID1), mdio.read(addr, PHYID2)) else {
            continue;
        };
        let blank = |v: u16| v == 0 || v == 0xffff;
        if !(blank(id1) && blank(id2)) {
            return Ok(PhyId { addr, id1, id2 });
        }
    }
    Err(PhyError::NotFound)
}

/// Reset the PHY, apply board settings, advertise everything it can do and
/// restart auto-negotiation.
pub fn configure(mdio: &mut impl Mdio, phy: PhyId, cfg: &PhyConfig) -> Result<(), PhyError> {
    let a = phy.addr;
    mdio.write(a, BMCR, BMCR_RESET)?;
    // IEEE 802.3 22.2.4.1.1: reset completes within 0.5 s.
    let mut reset_done = false;
    for attempt in 0..=RESET_POLLS {
        if attempt > 0 {
            mdio.delay_us(RESET_POLL_INTERVAL_US);
        }
        if mdio.read(a, BMCR)? & BMCR_RESET == 0 {
            reset_done = true;
            break;
        }
    }
    if !reset_done {
        return Err(PhyError::ResetTimeout);
    }
    if phy.is_ksz9021() {
        if let Some((clk_ctl, rx_data)) = cfg.ksz9021_skews {
            ksz9021_ext_write(mdio, a, 0x104, clk_ctl)?;
            ksz9021_ext_write(mdio, a, 0x105, rx_data)?;
        }
    }
    mdio.write(a, ANAR, ANAR_ALL_10_100)?;
    let bmsr = mdio.read(a, BMSR)?;
    if bmsr & BMSR_ESTATEN != 0 {
        let mut c = CTRL1000_FULL | CTRL1000_HALF;
        if phy.is_ksz9021() && cfg.ksz9021_force_master {
            c |= CTRL1000_MS_MANUAL | CTRL1000_MASTER;
        }
        mdio.write(a, CTRL1000, c)?;
    }
    mdio.write(a, BMCR, BMCR_ANENABLE | BMCR_ANRESTART)?;
    Ok(())
}

/// Write KSZ9021 extended register `reg` (write 0x8000 | reg to 0x0b, then
/// the value to 0x0c; KSZ9021RN data sheet, "Extended Register" access).
pub fn ksz9021_ext_write(mdio: &mut impl Mdio, phy: u8, reg: u16, value: u16) -> Result<(), MdioTimeout> {
    mdio.write(phy, KSZ_EXT_CTRL, 0x8000 | reg)?;
    mdio.write(phy, KSZ_EXT_WRITE, value)
}

/// KSZ9021 extended register read data (reg 0x0d).
pub const KSZ_EXT_READ: u8 = 0x0d;

/// Read KSZ9021 extended register `reg` (write `reg` without the write
/// bit to 0x0b, then read 0x0d; KSZ9021RN data sheet, "Extended Register"
/// access; U-Boot's `ksz9021_phy_extended_read` does the same).
pub fn ksz9021_ext_read(mdio: &mut impl Mdio, phy: u8, reg: u16) -> Result<u16, MdioTimeout> {
    mdio.write(phy, KSZ_EXT_CTRL, reg)?;
    mdio.read(phy, KSZ_EXT_READ)
}

/// The KSZ9021's three RGMII pad skew registers as they are: 0x104
/// (clock and control), 0x105 (RX data), 0x106 (TX data), for the boot
/// log. The board writes 0x104 and 0x105 ([`PhyConfig::ksz9021_skews`]);
/// 0x106 keeps its reset value, as U-Boot and Linux leave it for a device
/// tree without `txd*-skew-ps` (the DE1-SoC's: docs/platform.md).
pub fn ksz9021_skews(mdio: &mut impl Mdio, phy: u8) -> Result<[u16; 3], MdioTimeout> {
    Ok([ksz9021_ext_read(mdio, phy, 0x104)?, ksz9021_ext_read(mdio, phy, 0x105)?, ksz9021_ext_read(mdio, phy, 0x106)?])
}

/// The link, if it is up and negotiated.
pub fn link_status(mdio: &mut impl Mdio, phy: PhyId) -> Result<Option<Link>, MdioTimeout> {
    let a = phy.addr;
    // Link status latches low: the second read is the current state.
    let _ = mdio.read(a, BMSR)?;
    let bmsr = mdio.read(a, BMSR)?;
    if bmsr & BMSR_LSTATUS == 0 || bmsr & BMSR_ANEGCOMPLETE == 0 {
        return Ok(None);
    }
    if phy.is_ksz9021() {
        return Ok(Some(ksz9021_resolve(mdio.read(a, KSZ_PHY_CTRL)?)));
    }
    let ctrl1000 = if bmsr & BMSR_ESTATEN != 0 { mdio.read(a, CTRL1000)? } else { 0 };
    let stat1000 = if bmsr & BMSR_ESTATEN != 0 { mdio.read(a, STAT1000)? } else { 0 };
    let anar = mdio.read(a, ANAR)?;
    let anlpar = mdio.read(a, ANLPAR)?;
    let bmcr = mdio.read(a, BMCR)?;
    Ok(Some(resolve(ctrl1000, stat1000, anar, anlpar, bmcr)))
}

/// Microseconds between two BMCR reads while a PHY resets.
pub const RESET_POLL_INTERVAL_US: u32 = 10_000;
/// BMCR reads after the first before a reset counts as stuck (0.5 s).
pub const RESET_POLLS: u32 = 50;

/// How often [`LinkMonitor`] reads the PHY: about once a second, as Linux's
/// phylib state machine does (`PHY_STATE_TIME`, `drivers/net/phy/phy.c`).
pub const LINK_POLL_INTERVAL_US: u64 = 1_000_000;

/// Watches one PHY's link from the main loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkMonitor {
    phy: PhyId,
    link: Option<Link>,
    next_poll_us: u64,
    mdio_errors: u32,
}

impl LinkMonitor {
    /// A monitor for `phy` whose link is not up yet; the first
    /// [`poll`](Self::poll) reads it.
    pub const fn new(phy: PhyId) -> LinkMonitor {
        LinkMonitor { phy, link: None, next_poll_us: 0, mdio_errors: 0 }
    }

    /// The link as last read.
    pub const fn link(&self) -> Option<Link> {
        self.link
    }

    /// MDIO accesses that timed out while polling (the link state is kept).
    pub const fn mdio_errors(&self) -> u32 {
        self.mdio_errors
    }

    /// Read the PHY if [`LINK_POLL_INTERVAL_US`] has passed since the last
    /// read (`now_us` from a monotonic clock). Returns the new state when the
    /// link came up, went down, or changed speed or duplex: the caller then
    /// reprograms the MAC ([`crate::Dwmac::set_link`]).
    pub fn poll(&mut self, now_us: u64, mdio: &mut impl Mdio) -> Option<Option<Link>> {
        if now_us < self.next_poll_us {
            return None;
        }
        self.next_poll_us = now_us.saturating_add(LINK_POLL_INTERVAL_US);
        match link_status(mdio, self.phy) {
            Ok(link) if link != self.link => {
                self.link = link;
                Some(link)
            }
            Ok(_) => None,
            Err(MdioTimeout) => {
                self.mdio_errors = self.mdio_errors.saturating_add(1);
                None
            }
        }
    }
}

/// KSZ9021 PHY control register 0x1f: bit 6 1000, bit 5 100, bit 3 full
/// duplex (KSZ9021RN data sheet, register 0x1f "PHY Control").
pub const fn ksz9021_resolve(reg1f: u16) -> Link {
    let speed = if reg1f & (1 << 6) != 0 {
        Speed::M1000
    } else if reg1f & (1 << 5) != 0 {
        Speed::M100
    } else {
        Speed::M10
    };
    Link { speed, full_duplex: reg1f & (1 << 3) != 0 }
}

/// Generic resolution: the best mode both ends advertise (IEEE 802.3
/// annex 28B.3 priority), else what BMCR says.
pub const fn resolve(ctrl1000: u16, stat1000: u16, anar: u16, anlpar: u16, bmcr: u16) -> Link {
    if ctrl1000 & CTRL1000_FULL != 0 && stat1000 & STAT1000_LP_FULL != 0 {
        return Link { speed: Speed::M1000, full_duplex: true };
    }
    if ctrl1000 & CTRL1000_HALF != 0 && stat1000 & STAT1000_LP_HALF != 0 {
        return Link { speed: Speed::M1000, full_duplex: false };
    }
    let common = anar & anlpar;
    if common & (1 << 8) != 0 {
        return Link { speed: Speed::M100, full_duplex: true };
    }
    if common & (1 << 7) != 0 {
        return Link { speed: Speed::M100, full_duplex: false };
    }
    if common & (1 << 6) != 0 {
        return Link { speed: Speed::M10, full_duplex: true };
    }
    if common & (1 << 5) != 0 {
        return Link { speed: Speed::M10, full_duplex: false };
    }
    let speed = if bmcr & BMCR_SPEED1000 != 0 && bmcr & BMCR_SPEED100 == 0 {
        Speed::M1000
    } else if bmcr & BMCR_SPEED100 != 0 {
        Speed::M100
    } else {
        Speed::M10
    };
    Link { speed, full_duplex: bmcr & BMCR_FULLDPLX != 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// PHYs at some addresses, registers as a table, writes logged.
    struct FakeBus {
        regs: [[u16; 32]; 32],
        present: u32,
        writes: Vec<(u8, u8, u16)>,
        reset_sticks: bool,
        delayed_ns: u64,
    }

    impl DelayNs for FakeBus {
        fn delay_ns(&mut self, ns: u32) {
            self.delayed_ns += u64::from(ns);
        }
    }

    impl FakeBus {
        fn with_phy(addr: u8, id1: u16, id2: u16) -> Self {
            let mut regs = [[0xffff; 32]; 32];
            regs[addr as usize] = [0; 32];
            regs[addr as usize][PHYID1 as usize] = id1;
            regs[addr as usize][PHYID2 as usize] = id2;
            regs[addr as usize][BMSR as usize] = BMSR_ESTATEN | BMSR_LSTATUS | BMSR_ANEGCOMPLETE;
            FakeBus { regs, present: 1 << addr, writes: vec![], reset_sticks: false, delayed_ns: 0 }
        }
    }

    impl Mdio for FakeBus {
        fn read(&mut self, phy: u8, reg: u8) -> Result<u16, MdioTimeout> {
            Ok(self.regs[phy as usize][reg as usize])
        }
        fn write(&mut self, phy: u8, reg: u8, value: u16) -> Result<(), MdioTimeout> {
            self.writes.push((phy, reg, value));
            if self.present & (1 << phy) != 0 {
                let v = if reg == BMCR && !self.reset_sticks { value & !BMCR_RESET } else { value };
                self.regs[phy as usize][reg as usize] = v;
            }
            Ok(())
        }
    }

    const NO_SKEWS: PhyConfig = PhyConfig { ksz9021_skews: None, ksz9021_force_master: false };

    #[test]
    fn scan_finds_the_first_real_id() {
        let mut bus = FakeBus::with_phy(3, 0x0022, 0x1611);
        // Address 1 reads all zeros: not a PHY.
        bus.regs[1] = [0; 32];
        let phy = scan(&mut bus).unwrap();
        assert_eq!(phy, PhyId { addr: 3, id1: 0x0022, id2: 0x1611 });
        assert!(phy.is_ksz9021());
        let qemu = FakeBus::with_phy(0, 0x0362, 0x5e6a);
        let mut qemu = qemu;
        let p = scan(&mut qemu).unwrap();
        assert_eq!(p.addr, 0);
        assert!(!p.is_ksz9021());
        let mut empty = FakeBus::with_phy(0, 0, 0);
        empty.regs[0] = [0; 32];
        assert_eq!(scan(&mut empty), Err(PhyError::NotFound));
    }

    #[test]
    fn ksz9021_gets_skews_and_master_mode() {
        let mut bus = FakeBus::with_phy(1, 0x0022, 0x1611);
        let phy = scan(&mut bus).unwrap();
        let cfg = PhyConfig { ksz9021_skews: Some((0xe3f0, 0x3333)), ksz9021_force_master: true };
        configure(&mut bus, phy, &cfg).unwrap();
        let w = &bus.writes;
        assert_eq!(w[0], (1, BMCR, BMCR_RESET));
        assert_eq!(&w[1..5], &[(1, 0x0b, 0x8104), (1, 0x0c, 0xe3f0), (1, 0x0b, 0x8105), (1, 0x0c, 0x3333)]);
        assert!(w.contains(&(1, CTRL1000, CTRL1000_FULL | CTRL1000_HALF | CTRL1000_MS_MANUAL | CTRL1000_MASTER)));
        assert_eq!(*w.last().unwrap(), (1, BMCR, BMCR_ANENABLE | BMCR_ANRESTART));
    }

    #[test]
    fn ksz9021_skews_are_read_back_through_the_extended_register_window() {
        /// A bus whose extended registers answer through 0x0b / 0x0d.
        struct Ext {
            bus: FakeBus,
            selected: u16,
        }
        impl Mdio for Ext {
            fn read(&mut self, phy: u8, reg: u8) -> Result<u16, MdioTimeout> {
                if reg == KSZ_EXT_READ {
                    return Ok(match self.selected {
                        0x104 => 0xe3f0,
                        0x105 => 0x3333,
                        0x106 => 0x0000,
                        _ => 0xdead,
                    });
                }
                self.bus.read(phy, reg)
            }
            fn write(&mut self, phy: u8, reg: u8, value: u16) -> Result<(), MdioTimeout> {
                if reg == KSZ_EXT_CTRL {
                    self.selected = value;
                }
                self.bus.write(phy, reg, value)
            }
        }
        impl DelayNs for Ext {
            fn delay_ns(&mut self, ns: u32) {
                self.bus.delay_ns(ns)
            }
        }
        let mut ext = Ext { bus: FakeBus::with_phy(1, 0x0022, 0x1611), selected: 0 };
        assert_eq!(ksz9021_skews(&mut ext, 1), Ok([0xe3f0, 0x3333, 0x0000]));
        assert_eq!(
            ext.bus.writes,
            [(1, KSZ_EXT_CTRL, 0x104), (1, KSZ_EXT_CTRL, 0x105), (1, KSZ_EXT_CTRL, 0x106)],
            "each register selected for reading (bit 15 clear), in order"
        );
    }

    #[test]
    fn generic_phy_gets_no_ksz_writes() {
        let mut bus = FakeBus::with_phy(0, 0x0362, 0x5e6a);
        let phy = scan(&mut bus).unwrap();
        let cfg = PhyConfig { ksz9021_skews: Some((1, 2)), ksz9021_force_master: true };
        configure(&mut bus, phy, &cfg).unwrap();
        assert!(bus.writes.iter().all(|&(_, r, _)| r != 0x0b && r != 0x0c));
        assert!(bus.writes.contains(&(0, CTRL1000, CTRL1000_FULL | CTRL1000_HALF)));
        assert!(bus.writes.contains(&(0, ANAR, ANAR_ALL_10_100)));
    }

    #[test]
    fn a_phy_stuck_in_reset_times_out() {
        let mut bus = FakeBus::with_phy(0, 0x0362, 0x5e6a);
        bus.reset_sticks = true;
        let phy = scan(&mut bus).unwrap();
        assert_eq!(configure(&mut bus, phy, &NO_SKEWS), Err(PhyError::ResetTimeout));
        assert_eq!(bus.delayed_ns, u64::from(RESET_POLLS * RESET_POLL_INTERVAL_US) * 1000, "waited 0.5 s");
    }

    #[test]
    fn link_monitor_follows_the_cable_once_a_second() {
        let mut bus = FakeBus::with_phy(0, 0x0362, 0x5e6a);
        bus.regs[0][BMSR as usize] = BMSR_ESTATEN; // no cable yet
        bus.regs[0][CTRL1000 as usize] = CTRL1000_FULL;
        let phy = scan(&mut bus).unwrap();
        let mut mon = LinkMonitor::new(phy);
        assert_eq!(mon.poll(0, &mut bus), None, "down, as it started");
        // The cable arrives; nothing is read before a second has passed.
        bus.regs[0][BMSR as usize] = BMSR_ESTATEN | BMSR_LSTATUS | BMSR_ANEGCOMPLETE;
        bus.regs[0][STAT1000 as usize] = STAT1000_LP_FULL;
        assert_eq!(mon.poll(999_999, &mut bus), None);
        let gig = Link { speed: Speed::M1000, full_duplex: true };
        assert_eq!(mon.poll(1_000_000, &mut bus), Some(Some(gig)), "link up");
        assert_eq!(mon.poll(2_000_000, &mut bus), None, "no change, no event");
        // The partner renegotiates to 100 Mbit/s full duplex.
        bus.regs[0][STAT1000 as usize] = 0;
        bus.regs[0][ANAR as usize] = ANAR_ALL_10_100;
        bus.regs[0][ANLPAR as usize] = 1 << 8;
        let fast = Link { speed: Speed::M100, full_duplex: true };
        assert_eq!(mon.poll(3_000_000, &mut bus), Some(Some(fast)), "speed change");
        bus.regs[0][BMSR as usize] = BMSR_ESTATEN;
        assert_eq!(mon.poll(4_000_000, &mut bus), Some(None), "cable pulled");
        assert_eq!(mon.link(), None);
    }

    #[test]
    fn qemu_like_phy_resolves_gigabit_full() {
        // QEMU npcm-gmac: CTRL1000 full, STAT1000 LP full, ANLPAR zeroed.
        let mut bus = FakeBus::with_phy(0, 0x0362, 0x5e6a);
        bus.regs[0][STAT1000 as usize] = STAT1000_LP_FULL;
        let phy = scan(&mut bus).unwrap();
        configure(&mut bus, phy, &NO_SKEWS).unwrap();
        let link = link_status(&mut bus, phy).unwrap().expect("link up");
        assert_eq!(link, Link { speed: Speed::M1000, full_duplex: true });
        assert_eq!(link.to_string(), "1000 Mbit/s full duplex");
    }

    #[test]
    fn resolution_priorities() {
        assert_eq!(resolve(0, 0, ANAR_ALL_10_100, 1 << 7 | 1 << 6, 0), Link { speed: Speed::M100, full_duplex: false });
        assert_eq!(resolve(0, 0, ANAR_ALL_10_100, 1 << 8, 0), Link { speed: Speed::M100, full_duplex: true });
        assert_eq!(resolve(CTRL1000_HALF, STAT1000_LP_HALF, 0, 0, 0), Link { speed: Speed::M1000, full_duplex: false });
        assert_eq!(resolve(0, 0, 0, 0, BMCR_SPEED100 | BMCR_FULLDPLX), Link { speed: Speed::M100, full_duplex: true });
        assert_eq!(ksz9021_resolve(1 << 6 | 1 << 3), Link { speed: Speed::M1000, full_duplex: true });
        assert_eq!(ksz9021_resolve(1 << 5), Link { speed: Speed::M100, full_duplex: false });
        assert_eq!(ksz9021_resolve(0), Link { speed: Speed::M10, full_duplex: false });
    }
}
