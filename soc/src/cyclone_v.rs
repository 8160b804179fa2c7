//! Cyclone V HPS system peripherals: reset, system, clock and FPGA
//! managers, and the L3 interconnect's remap register.
//!
//! Addresses and bits: Cyclone V Hard Processor System Technical Reference
//! Manual (Intel, cv_5v4), the chapters and register maps of each manager;
//! cross-checked with U-Boot `arch/arm/mach-socfpga/include/mach/`
//! (`reset_manager_gen5.h`, `system_manager_gen5.h`, `clock_manager_gen5.h`,
//! `fpga_manager_gen5.h`) and `misc_gen5.c`. Collected in
//! docs/platform.md#cyclone-v-system-managers.

use core::mem::offset_of;
use core::ptr::NonNull;

use arbitrary_int::{u13, u6, u9};
use bitbybit::{bitenum, bitfield};
use embedded_hal::delay::DelayNs;
use volatile_register::{RO, RW, WO};

/// Reset manager base.
pub const RSTMGR_BASE: usize = 0xffd0_5000;
/// System manager base.
pub const SYSMGR_BASE: usize = 0xffd0_8000;
/// Clock manager base.
pub const CLKMGR_BASE: usize = 0xffd0_4000;
/// FPGA manager register base.
pub const FPGAMGR_BASE: usize = 0xff70_6000;
/// L3 (NIC-301) GPV base: the remap register at offset 0.
pub const L3_BASE: usize = 0xff80_0000;

/// The DE1-SoC's HPS oscillator (osc1): 25 MHz (DE1-SoC schematic,
/// HPS_CLOCK_25; U-Boot `board/terasic/de1-soc/qts/pll_config.h` derives its
/// PLL settings from it).
pub const DE1_SOC_OSC1_HZ: u32 = 25_000_000;

// ---- Reset manager -----------------------------------------------------------

/// `permodrst` (0x14): peripheral module resets (1 = held in reset).
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct PerModRst {
    /// GPIO1, which drives the DE1-SoC's HPS LED (U-Boot's
    /// `dt-bindings/reset/altr,rst-mgr.h`: `GPIO1_RESET` = bank 1, bit 26;
    /// SPL holds it in reset unless a U-Boot driver probed the GPIO).
    #[bit(26, rw)]
    pub gpio1: bool,
    /// L4 watchdog 0 (the boot ROM starts it).
    #[bit(6, rw)]
    pub l4wd0: bool,
    /// EMAC1.
    #[bit(1, rw)]
    pub emac1: bool,
    /// EMAC0.
    #[bit(0, rw)]
    pub emac0: bool,
}

/// `brgmodrst` (0x1c): bridge resets (1 = held in reset).
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct BrgModRst {
    /// FPGA-to-HPS bridge.
    #[bit(2, rw)]
    pub fpga2hps: bool,
    /// Lightweight HPS-to-FPGA bridge (the accelerator's registers).
    #[bit(1, rw)]
    pub lwhps2fpga: bool,
    /// HPS-to-FPGA bridge.
    #[bit(0, rw)]
    pub hps2fpga: bool,
}

/// Reset manager registers used.
#[repr(C)]
pub struct RstMgr {
    _r0: [u32; 5],
    /// 0x14 permodrst.
    pub permodrst: RW<PerModRst>,
    _r1: [u32; 1],
    /// 0x1c brgmodrst.
    pub brgmodrst: RW<BrgModRst>,
}

const _: () = {
    assert!(offset_of!(RstMgr, permodrst) == 0x14);
    assert!(offset_of!(RstMgr, brgmodrst) == 0x1c);
};

// ---- System manager ------------------------------------------------------------

/// PHY interface of an EMAC (`emacgrp_ctrl.physel_*`).
#[bitenum(u2, exhaustive = true)]
#[derive(Debug, PartialEq, Eq)]
pub enum PhySel {
    /// GMII or MII.
    GmiiMii = 0,
    /// RGMII (the DE1-SoC's KSZ9021RN).
    Rgmii = 1,
    /// RMII.
    Rmii = 2,
    /// Reserved.
    Reserved = 3,
}

/// `emacgrp_ctrl` (0x60).
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct EmacCtrl {
    /// EMAC1 PHY interface.
    #[bits(2..=3, rw)]
    pub physel_1: PhySel,
    /// EMAC0 PHY interface.
    #[bits(0..=1, rw)]
    pub physel_0: PhySel,
}

/// `fpgaintfgrp_module` (0x28): 1 = the module's signals go through the
/// FPGA fabric instead of the HPS pins.
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct FpgaIntfModule {
    /// EMAC1.
    #[bit(3, rw)]
    pub emac_1: bool,
    /// EMAC0.
    #[bit(2, rw)]
    pub emac_0: bool,
}

/// System manager registers used.
#[repr(C)]
pub struct SysMgr {
    _r0: [u32; 10],
    /// 0x28 fpgaintfgrp module.
    pub fpgaintf_module: RW<FpgaIntfModule>,
    _r1: [u32; 13],
    /// 0x60 emacgrp ctrl.
    pub emac_ctrl: RW<EmacCtrl>,
}

const _: () = {
    assert!(offset_of!(SysMgr, fpgaintf_module) == 0x28);
    assert!(offset_of!(SysMgr, emac_ctrl) == 0x60);
};

// ---- Clock manager -------------------------------------------------------------

/// `bypass` (0x04).
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct Bypass {
    /// The main PLL is bypassed: its outputs run at osc1.
    #[bit(0, r)]
    pub mainpll: bool,
}

/// `mainpllgrp_vco` (0x40): VCO = osc1 x (numer + 1) / (denom + 1).
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct MainPllVco {
    /// Denominator - 1.
    #[bits(16..=21, r)]
    pub denom: u6,
    /// Numerator - 1.
    #[bits(3..=15, r)]
    pub numer: u13,
}

/// A counter register (`mainpllgrp_mpuclk` 0x48, `alteragrp_mpuclk` 0xe0):
/// the clock is its input divided by `cnt + 1`.
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct Counter {
    /// Divider - 1.
    #[bits(0..=8, r)]
    pub cnt: u9,
}

/// Clock manager registers used.
#[repr(C)]
pub struct ClkMgr {
    _r0: [u32; 1],
    /// 0x04 bypass.
    pub bypass: RO<Bypass>,
    _r1: [u32; 14],
    /// 0x40 main PLL VCO.
    pub mainpll_vco: RO<MainPllVco>,
    _r2: [u32; 1],
    /// 0x48 main PLL MPU clock counter.
    pub mainpll_mpuclk: RO<Counter>,
    _r3: [u32; 37],
    /// 0xe0 Altera group MPU clock divider.
    pub altera_mpuclk: RO<Counter>,
}

const _: () = {
    assert!(offset_of!(ClkMgr, bypass) == 0x04);
    assert!(offset_of!(ClkMgr, mainpll_vco) == 0x40);
    assert!(offset_of!(ClkMgr, mainpll_mpuclk) == 0x48);
    assert!(offset_of!(ClkMgr, altera_mpuclk) == 0xe0);
};

/// The MPU clock from the clock manager's settings: osc1 when the main PLL
/// is bypassed, else osc1 x (numer + 1) / (denom + 1) / (altera mpuclk + 1)
/// / (mpuclk + 1). The formula of U-Boot's `cm_get_mpu_clk_hz`
/// (`arch/arm/mach-socfpga/clock_manager_gen5.c`) and Linux's
/// `drivers/clk/socfpga/clk-pll.c` / `clk-periph.c`.
pub fn mpu_clock_hz(osc1_hz: u32, bypass: Bypass, vco: MainPllVco, mpuclk: Counter, altera_mpuclk: Counter) -> u32 {
    if bypass.mainpll() {
        return osc1_hz;
    }
    let numer = u64::from(vco.numer().value()) + 1;
    let denom = u64::from(vco.denom().value()) + 1;
    let div = (u64::from(altera_mpuclk.cnt().value()) + 1) * (u64::from(mpuclk.cnt().value()) + 1);
    u32::try_from(u64::from(osc1_hz) * numer / denom / div).unwrap_or(u32::MAX)
}

/// The Cortex-A9 private and global timers' clock, `mpu_periph_clk`: the MPU
/// clock divided by 4 (Cyclone V TRM, clock manager, "MPU clock group";
/// Linux `socfpga.dtsi`, fixed-factor clock `mpu_periph_clk`, div 4).
pub const fn periph_clock_hz(mpu_hz: u32) -> u32 {
    mpu_hz / 4
}

// ---- FPGA manager --------------------------------------------------------------

/// `stat.mode` (bits 2:0).
#[bitenum(u3, exhaustive = false)]
#[derive(Debug, PartialEq, Eq)]
pub enum FpgaMode {
    /// Powered off.
    PowerOff = 0,
    /// In reset.
    Reset = 1,
    /// Being configured.
    Configuring = 2,
    /// Initialising.
    Init = 3,
    /// User mode: configured and running.
    User = 4,
}

/// `stat` (0x00).
#[bitfield(u32)]
#[derive(Debug, PartialEq, Eq)]
pub struct FpgaStat {
    /// Mode (`Err(raw)`: an undefined encoding).
    #[bits(0..=2, r)]
    pub mode: Option<FpgaMode>,
}

/// FPGA manager registers used.
#[repr(C)]
pub struct FpgaMgr {
    /// 0x00 stat.
    pub stat: RO<FpgaStat>,
}

// ---- L3 remap ------------------------------------------------------------------

/// The L3 `remap` register (write-only): which bridges the MPU and L3
/// masters see.
#[bitfield(u32, default = 0)]
#[derive(Debug, PartialEq, Eq)]
pub struct Remap {
    /// The lightweight HPS-to-FPGA bridge is visible.
    #[bit(4, w)]
    pub lwhps2fpga: bool,
    /// The HPS-to-FPGA bridge is visible.
    #[bit(3, w)]
    pub hps2fpga: bool,
    /// On-chip RAM at address 0 (the boot ROM's map).
    #[bit(0, w)]
    pub mpuzero: bool,
}

/// The value U-Boot's `bridge enable` writes (0x19: both HPS-to-FPGA bridges
/// and on-chip RAM at 0; `misc_gen5.c`, `do_bridge_reset`).
pub const REMAP_HANDOFF: Remap = Remap::DEFAULT.with_lwhps2fpga(true).with_hps2fpga(true).with_mpuzero(true);

/// L3 registers used.
#[repr(C)]
pub struct L3 {
    /// 0x00 remap.
    pub remap: WO<Remap>,
}

/// How long EMAC1 stays in reset before and after its PHY interface select
/// is written: 2 us. No public source names a minimum (U-Boot and Linux
/// write the select between assert and release with no delay at all); this
/// is a margin of hundreds of cycles of any HPS clock, so that the EMAC
/// holds the select settled, in reset, on both sides of the write.
pub const EMAC_RESET_HOLD_NS: u32 = 2_000;

/// Read-backs (1 us apart) after the release until the reset bit reads
/// clear: 1 ms (U-Boot allows 500 ms; the bit is a plain register bit).
pub const EMAC_RELEASE_POLLS: u32 = 1_000;

/// EMAC1's reset bit still read set after the release.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmacResetTimeout;

impl core::fmt::Display for EmacResetTimeout {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("EMAC1 reset bit still set after the release")
    }
}

// ---- The handle ----------------------------------------------------------------

/// The Cyclone V system managers, for the board set-up at start-up.
pub struct Managers {
    rstmgr: NonNull<RstMgr>,
    sysmgr: NonNull<SysMgr>,
    clkmgr: NonNull<ClkMgr>,
    fpgamgr: NonNull<FpgaMgr>,
    l3: NonNull<L3>,
}

impl Managers {
    /// The managers at their Cyclone V addresses.
    ///
    /// # Safety
    ///
    /// Only on a Cyclone V HPS with those regions mapped Device (or the MMU
    /// off), by one owner at a time.
    pub unsafe fn cyclone_v() -> Managers {
        // SAFETY: forwarded to the caller.
        unsafe {
            Managers::at(
                RSTMGR_BASE as *mut RstMgr,
                SYSMGR_BASE as *mut SysMgr,
                CLKMGR_BASE as *mut ClkMgr,
                FPGAMGR_BASE as *mut FpgaMgr,
                L3_BASE as *mut L3,
            )
        }
    }

    /// The managers at the given register blocks (host tests pass memory).
    ///
    /// # Safety
    ///
    /// Each pointer is non-null and points to that manager's registers, or
    /// to memory laid out as them that outlives the value; nothing else
    /// writes them meanwhile.
    pub unsafe fn at(
        rstmgr: *mut RstMgr,
        sysmgr: *mut SysMgr,
        clkmgr: *mut ClkMgr,
        fpgamgr: *mut FpgaMgr,
        l3: *mut L3,
    ) -> Managers {
        let nn = |p: *mut u8| NonNull::new(p).unwrap_or(NonNull::dangling());
        Managers {
            rstmgr: nn(rstmgr.cast()).cast(),
            sysmgr: nn(sysmgr.cast()).cast(),
            clkmgr: nn(clkmgr.cast()).cast(),
            fpgamgr: nn(fpgamgr.cast()).cast(),
            l3: nn(l3.cast()).cast(),
        }
    }

    fn rst(&self) -> &RstMgr {
        // SAFETY: `at`'s contract; volatile cells only.
        unsafe { self.rstmgr.as_ref() }
    }

    fn sys(&self) -> &SysMgr {
        // SAFETY: as above.
        unsafe { self.sysmgr.as_ref() }
    }

    /// Hold L4 watchdog 0 in reset, so the watchdog the boot ROM started
    /// (and U-Boot SPL leaves running) cannot reset the board.
    pub fn stop_watchdog(&self) {
        let r = self.rst();
        // SAFETY: holding the watchdog in reset only stops it.
        unsafe { r.permodrst.write(r.permodrst.read().with_l4wd0(true)) }
    }

    /// Whether L4 watchdog 0 is held in reset.
    pub fn watchdog_stopped(&self) -> bool {
        self.rst().permodrst.read().l4wd0()
    }

    /// Put EMAC1 on RGMII at the HPS pins: hold it in reset, select RGMII,
    /// route it away from the FPGA, release it. The order is U-Boot's
    /// (`drivers/net/dwmac_socfpga.c` `dwmac_socfpga_probe`: reset asserted,
    /// `emacgrp_ctrl` physel written, reset released; Linux
    /// `dwmac-socfpga.c` `socfpga_gen5_set_phy_mode` likewise: the EMAC
    /// samples the PHY interface select when its reset is released). Each
    /// step is made to have arrived before the next: `dsb` (the `barrier`
    /// the caller passes) and a read-back of the register written, then
    /// [`EMAC_RESET_HOLD_NS`] on each side of the select write. After the
    /// release the reset bit is read back until it is clear, as U-Boot's
    /// `socfpga_reset_deassert` does (`drivers/reset/reset-socfpga.c`,
    /// `wait_for_bit_le32`), bounded by [`EMAC_RELEASE_POLLS`].
    pub fn emac1_rgmii(&self, delay: &mut impl DelayNs, barrier: impl Fn()) -> Result<(), EmacResetTimeout> {
        let (r, s) = (self.rst(), self.sys());
        // SAFETY: EMAC1's reset, interface select and routing affect only
        // EMAC1, which nothing uses yet.
        unsafe { r.permodrst.write(r.permodrst.read().with_emac1(true)) };
        barrier();
        let _ = r.permodrst.read();
        delay.delay_ns(EMAC_RESET_HOLD_NS);
        // SAFETY: as above; EMAC1 is held in reset.
        unsafe {
            s.emac_ctrl.write(s.emac_ctrl.read().with_physel_1(PhySel::Rgmii));
            s.fpgaintf_module.write(s.fpgaintf_module.read().with_emac_1(false));
        }
        barrier();
        let _ = s.emac_ctrl.read();
        delay.delay_ns(EMAC_RESET_HOLD_NS);
        // SAFETY: as above.
        unsafe { r.permodrst.write(r.permodrst.read().with_emac1(false)) };
        barrier();
        for _ in 0..EMAC_RELEASE_POLLS {
            if !r.permodrst.read().emac1() {
                return Ok(());
            }
            delay.delay_ns(1_000);
        }
        Err(EmacResetTimeout)
    }

    /// The bridges' reset state.
    pub fn bridges(&self) -> BrgModRst {
        self.rst().brgmodrst.read()
    }

    /// The FPGA's mode, or the raw value of an undefined one.
    pub fn fpga_mode(&self) -> Result<FpgaMode, u8> {
        // SAFETY: `at`'s contract; volatile cells only.
        unsafe { self.fpgamgr.as_ref() }.stat.read().mode().map_err(|raw| raw.value())
    }

    /// Make the HPS-to-FPGA bridges visible (the handoff value).
    pub fn remap_bridges(&self) {
        // SAFETY: `at`'s contract; making the bridges visible changes only
        // what the bridge windows decode to.
        unsafe { self.l3.as_ref().remap.write(REMAP_HANDOFF) }
    }

    /// The MPU clock, from the main PLL settings and `osc1_hz`.
    pub fn mpu_clock_hz(&self, osc1_hz: u32) -> u32 {
        // SAFETY: `at`'s contract; volatile cells only.
        let c = unsafe { self.clkmgr.as_ref() };
        mpu_clock_hz(osc1_hz, c.bypass.read(), c.mainpll_vco.read(), c.mainpll_mpuclk.read(), c.altera_mpuclk.read())
    }
}

// ---- The SDRAM controller's FPGA ports ---------------------------------------------

/// The SDRAM controller's `ctrlgrp.fpgaportrst` (Cyclone V HPS register
/// map, SDR module at 0xFFC2_0000, offset 0x5080): bits 3:0 read ports,
/// 7:4 write ports, 13:8 command ports; a port runs while its bit is 1
/// (docs/frame-dma.md, "The FPGA-to-SDRAM port").
pub const FPGAPORTRST: usize = 0xffc2_5080;

/// The value U-Boot writes for this project's FPGA image (read port 0,
/// write port 0, command ports 0 and 1: the frame DMA and the VGA reader),
/// docs/flash-and-boot.md.
pub const FPGAPORTRST_RELEASED: u32 = 0x311;

/// Read `fpgaportrst`.
///
/// # Safety
///
/// Only on a Cyclone V HPS with the SDRAM controller's registers mapped
/// Device (or the MMU off).
pub unsafe fn fpgaportrst() -> u32 {
    // SAFETY: forwarded to the caller; a read has no side effect.
    unsafe { core::ptr::read_volatile(FPGAPORTRST as *const u32) }
}

// ---- The HPS LED -------------------------------------------------------------------

/// GPIO1 (Synopsys DesignWare APB GPIO), Cyclone V HPS register map, "GPIO
/// Module Address Map": `gpio_swporta_dr` at 0x0, `gpio_swporta_ddr` at
/// 0x4 (1 = output).
pub const GPIO1_BASE: usize = 0xff70_9000;

/// The DE1-SoC's HPS LED: HPS_GPIO53, GPIO1 bit 24 (29 lines per bank),
/// lit by a 1 (the DE0-Nano-SoC device tree's `gpio-leds` node, which
/// uses the same line; not yet checked against Terasic's schematic:
/// docs/board-bring-up.md). U-Boot SPL's DE1-SoC pin-mux table makes the
/// pin a GPIO (`GPLMUX53` = 1).
pub const HPS_LED_BIT: u32 = 1 << 24;

/// GPIO1's data and direction registers.
#[repr(C)]
pub struct Gpio {
    /// `gpio_swporta_dr`: output levels.
    pub dr: RW<u32>,
    /// `gpio_swporta_ddr`: 1 = output.
    pub ddr: RW<u32>,
}

impl Managers {
    /// Take GPIO1 out of reset (SPL leaves it held), so that the HPS LED
    /// can be driven.
    pub fn release_gpio1(&self) {
        // SAFETY: `at`'s contract; releasing GPIO1 touches nothing else.
        unsafe { self.rst().permodrst.modify(|r| r.with_gpio1(false)) }
    }
}

/// The HPS LED on GPIO1.
pub struct HpsLed {
    gpio: NonNull<Gpio>,
}

impl HpsLed {
    /// The LED on the GPIO block at `gpio` (nothing written yet).
    ///
    /// # Safety
    ///
    /// `gpio` points to GPIO1's registers (mapped Device, out of reset) or
    /// to memory laid out as them; only `HpsLed`s write the LED's bit.
    pub unsafe fn at(gpio: *mut Gpio) -> Option<HpsLed> {
        Some(HpsLed { gpio: NonNull::new(gpio)? })
    }

    /// Make the LED's line an output, dark; the other lines keep their
    /// level and direction.
    pub fn make_output(&mut self) {
        // SAFETY: `at`'s contract; only the LED's bit changes.
        unsafe {
            let g = self.gpio.as_ref();
            g.dr.modify(|v| v & !HPS_LED_BIT);
            g.ddr.modify(|v| v | HPS_LED_BIT);
        }
    }

    /// Light the LED or not.
    pub fn set(&mut self, on: bool) {
        // SAFETY: `at`'s contract; only the LED's bit changes.
        unsafe {
            self.gpio.as_ref().dr.modify(|v| if on { v | HPS_LED_BIT } else { v & !HPS_LED_BIT });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vco(numer: u32, denom: u32) -> MainPllVco {
        MainPllVco::new_with_raw_value(numer << 3 | denom << 16 | 0b10)
    }
    fn cnt(c: u32) -> Counter {
        Counter::new_with_raw_value(c)
    }
    const RUNNING: Bypass = Bypass::new_with_raw_value(0);

    #[test]
    fn mpu_clock_of_the_de1_soc_preloader_is_800_mhz() {
        // U-Boot board/terasic/de1-soc/qts/pll_config.h: VCO numer 63,
        // denom 0, MPUCLK_CNT 0; altera mpuclk 1 (reset value).
        let mpu = mpu_clock_hz(DE1_SOC_OSC1_HZ, RUNNING, vco(63, 0), cnt(0), cnt(1));
        assert_eq!(mpu, 800_000_000);
        assert_eq!(periph_clock_hz(mpu), 200_000_000, "global timer");
    }

    #[test]
    fn a_925_mhz_part_gives_231_25_mhz_and_bypass_gives_osc1() {
        let mpu = mpu_clock_hz(DE1_SOC_OSC1_HZ, RUNNING, vco(73, 0), cnt(0), cnt(1));
        assert_eq!((mpu, periph_clock_hz(mpu)), (925_000_000, 231_250_000));
        let bypassed = Bypass::new_with_raw_value(1);
        assert_eq!(mpu_clock_hz(DE1_SOC_OSC1_HZ, bypassed, vco(63, 0), cnt(0), cnt(1)), 25_000_000);
        assert_eq!(mpu_clock_hz(DE1_SOC_OSC1_HZ, RUNNING, vco(79, 1), cnt(0), cnt(1)), 500_000_000, "denominator");
    }

    /// Manager registers in plain memory.
    struct Fake {
        rst: Box<[u32; 8]>,
        sys: Box<[u32; 25]>,
        clk: Box<[u32; 57]>,
        fpga: Box<[u32; 1]>,
        l3: Box<[u32; 1]>,
    }

    impl Fake {
        fn new() -> Fake {
            Fake {
                rst: Box::new([0; 8]),
                sys: Box::new([0; 25]),
                clk: Box::new([0; 57]),
                fpga: Box::new([0; 1]),
                l3: Box::new([0; 1]),
            }
        }
        fn managers(&mut self) -> Managers {
            // SAFETY: each boxed array covers its manager's registers and
            // outlives the handle.
            unsafe {
                Managers::at(
                    self.rst.as_mut_ptr().cast(),
                    self.sys.as_mut_ptr().cast(),
                    self.clk.as_mut_ptr().cast(),
                    self.fpga.as_mut_ptr().cast(),
                    self.l3.as_mut_ptr().cast(),
                )
            }
        }
    }

    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _: u32) {}
    }

    /// What the EMAC saw at each barrier and delay: (event, EMAC1 held in
    /// reset, EMAC1's PHY select, EMAC1 routed to the FPGA).
    type Seen = (&'static str, bool, u32, bool);

    /// Snapshots the fake's reset and select registers on every barrier and
    /// delay.
    struct Watch {
        permodrst: *const u32,
        emac_ctrl: *const u32,
        module: *const u32,
        log: std::cell::RefCell<Vec<Seen>>,
        /// Delays seen, in ns.
        delays: std::cell::RefCell<Vec<u32>>,
    }

    impl Watch {
        fn snap(&self, what: &'static str) {
            // SAFETY: the pointers point into the test's live fake registers.
            let (r, c, m) = unsafe { (*self.permodrst, *self.emac_ctrl, *self.module) };
            self.log.borrow_mut().push((what, r & 2 != 0, (c >> 2) & 3, m & 8 != 0));
        }
    }

    impl DelayNs for &Watch {
        fn delay_ns(&mut self, ns: u32) {
            self.delays.borrow_mut().push(ns);
            self.snap("delay");
        }
    }

    #[test]
    fn emac1_is_held_in_reset_around_the_phy_select_with_barriers_and_holds() {
        let mut f = Fake::new();
        f.sys[0x60 / 4] = 0b10_00; // EMAC1 RMII
        f.sys[0x28 / 4] = 0b1000; // EMAC1 through the FPGA
        let w = Watch {
            permodrst: &f.rst[0x14 / 4],
            emac_ctrl: &f.sys[0x60 / 4],
            module: &f.sys[0x28 / 4],
            log: Default::default(),
            delays: Default::default(),
        };
        let m = f.managers();
        assert_eq!(m.emac1_rgmii(&mut &w, || w.snap("dsb")), Ok(()));
        let hold = EMAC_RESET_HOLD_NS;
        assert!(hold >= 2_000);
        assert_eq!(
            *w.log.borrow(),
            [
                ("dsb", true, 2, true),    // reset asserted, old select
                ("delay", true, 2, true),  // held before the select
                ("dsb", true, 1, false),   // RGMII, HPS pins, still in reset
                ("delay", true, 1, false), // held after the select
                ("dsb", false, 1, false),  // released last
            ]
        );
        assert_eq!(*w.delays.borrow(), [hold, hold]);
    }

    #[test]
    fn gpio1_leaves_reset_and_the_hps_led_moves_only_its_own_bit() {
        let mut f = Fake::new();
        f.rst[0x14 / 4] = 0x3fff_ffff; // permodrst's reset value
        f.managers().release_gpio1();
        assert_eq!(f.rst[0x14 / 4], 0x3fff_ffff & !(1 << 26));
        let mut regs = [0x0000_0005u32, 0x0000_0001];
        // SAFETY: `regs` is laid out as `Gpio` and outlives `led`.
        let mut led = unsafe { HpsLed::at(regs.as_mut_ptr().cast()) }.expect("non-null");
        led.make_output();
        assert_eq!(regs, [0x5, 0x1 | HPS_LED_BIT], "an output, dark");
        led.set(true);
        assert_eq!(regs[0], 0x5 | (1 << 24));
        led.set(false);
        assert_eq!(regs[0], 0x5);
    }

    #[test]
    fn a_reset_bit_that_stays_set_after_the_release_is_reported() {
        let mut f = Fake::new();
        let permodrst: *mut u32 = &mut f.rst[0x14 / 4];
        let m = f.managers();
        // SAFETY: points into the live fake; the "hardware" sets the bit
        // again behind every barrier.
        let stuck = || unsafe { *permodrst |= 2 };
        assert_eq!(m.emac1_rgmii(&mut NoDelay, stuck), Err(EmacResetTimeout));
    }

    #[test]
    fn board_setup_writes_the_documented_bits() {
        let mut f = Fake::new();
        f.sys[0x60 / 4] = 0b10_01; // EMAC1 RMII, EMAC0 RGMII
        f.sys[0x28 / 4] = 0b1100; // both EMACs through the FPGA
        f.fpga[0] = 4;
        f.clk[0x40 / 4] = 63 << 3;
        f.clk[0xe0 / 4] = 1;
        let m = f.managers();
        m.stop_watchdog();
        m.emac1_rgmii(&mut NoDelay, || ()).expect("the fake's reset bit reads back clear");
        m.remap_bridges();
        assert!(m.watchdog_stopped());
        assert_eq!(m.fpga_mode(), Ok(FpgaMode::User));
        assert_eq!(m.mpu_clock_hz(DE1_SOC_OSC1_HZ), 800_000_000);
        assert_eq!(f.rst[0x14 / 4], 1 << 6, "watchdog held, EMAC1 released");
        assert_eq!(f.sys[0x60 / 4], 0b01_01, "EMAC1 RGMII, EMAC0 untouched");
        assert_eq!(f.sys[0x28 / 4], 0b0100, "EMAC1 on the HPS pins, EMAC0 untouched");
        assert_eq!(f.l3[0], 0x19);
    }
}
