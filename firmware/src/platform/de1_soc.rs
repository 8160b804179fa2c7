//! Terasic DE1-SoC: Cyclone V SoC 5CSEMA5F31C6 (2x Cortex-A9), EMAC1 over
//! RGMII to a Micrel KSZ9021RN, the ray tracer behind the lightweight
//! HPS-to-FPGA bridge.
//!
//! Addresses: Cyclone V HPS Technical Reference Manual (cv_5v4), "HPS
//! Address Map"; register names are the TRM's (docs/platform.md). Nothing
//! here was checked on a board yet: docs/board-bring-up.md lists what to
//! verify first.

use core::fmt::Write;
use core::ops::Range;

use dwmac::phy::PhyConfig;
use hal_avalon::map::LW_BRIDGE_BASE;
use soc::cyclone_v::{periph_clock_hz, Gpio, HpsLed, Managers, DE1_SOC_OSC1_HZ, GPIO1_BASE};
use soc::global_timer::TimerDelay;
use soc::mmu::{sections_of, MemType, PagedSection};

use super::{Board, TIMER};

/// The Terasic DE1-SoC.
pub enum De1Soc {}

/// The Cyclone V managers; only the board set-up uses them, at start-up.
pub(crate) fn managers() -> Managers {
    // SAFETY: this is a Cyclone V HPS (this board's build), the managers are
    // mapped Device by the firmware's table (or the MMU is off), and only
    // this module touches them, one call at a time on core 0.
    unsafe { Managers::cyclone_v() }
}

/// The HPS LED on GPIO1.
fn hps_led() -> Option<HpsLed> {
    // SAFETY: GPIO1's registers on this board, mapped Device by the
    // firmware's table; only this module writes the LED's bit, on core 0.
    unsafe { HpsLed::at(GPIO1_BASE as *mut Gpio) }
}

impl Board for De1Soc {
    const NAME: &'static str = "de1-soc (Terasic DE1-SoC, Cyclone V HPS)";
    /// UART0 (DesignWare 16550), 115200 8N1 from the boot loader.
    const UART0: usize = 0xffc0_2000;
    /// MPCore PERIPHBASE (TRM, "MPU subsystem": `mpu` private region).
    const PERIPHBASE: usize = 0xfffe_c000;
    /// MPU clock / 4 for an 800 MHz MPU, until `timer_hz` has read the PLL.
    const TIMER_HZ: u32 = 200_000_000;
    /// L2C-310 (TRM address map, `L2`).
    const L2C: usize = 0xfffe_f000;
    /// EMAC1 (Synopsys DWMAC 3.70a, enhanced descriptors).
    const EMAC: usize = 0xff70_2000;
    /// 1 GiB DDR3 at 0.
    const DRAM_MIB: u32 = 1024;
    /// The lightweight HPS-to-FPGA bridge, 2 MiB at 0xFF20_0000.
    const STRONGLY_ORDERED: &'static [Range<u32>] =
        &[sections_of(LW_BRIDGE_BASE..LW_BRIDGE_BASE + hal_avalon::map::LW_BRIDGE_SIZE)];
    /// The bridge's first MiB page by page, every page Strongly-ordered at
    /// first, the line-buffer page (0xFF20_1000) included: Normal memory may
    /// be read speculatively (ARM ARM DDI 0406C A3.5.7, B3.10.1), and a read
    /// of the bridge with nothing behind it is an external abort or a hang.
    /// Only once a row-mode accelerator has answered the probe does
    /// the renderer (`crate::boards`) map the line-buffer page Normal non-cacheable,
    /// where the driver's `ldm` reads it in bursts (docs/frame-dma.md#row-mode).
    const PAGED: Option<PagedSection<'static>> =
        Some(PagedSection { section: (LW_BRIDGE_BASE >> 20) as u32, default: MemType::StronglyOrdered, pages: &[] });
    /// A locally administered address (bit 1 of the first octet): the board
    /// has no factory MAC address the firmware can read. Only used when the
    /// card's raytracer.txt names none (`cargo xtask sdcard` writes a random
    /// one there, so two boards' cards differ): every board would have it.
    const MAC_ADDR: [u8; 6] = [0x02, 0xde, 0x1c, 0x50, 0xc0, 0x01];
    /// KSZ9021 RGMII skews: extended register 0x104 (clock and control pad
    /// skew) 0xe3f0 and 0x105 (RX data pad skew) 0x3333, what mainline
    /// U-Boot writes for the DE1-SoC device tree today
    /// (docs/platform.md#phy; the values differ between U-Boot versions:
    /// verify on the board). Master mode forced, as U-Boot does for the
    /// KSZ9021's erratum.
    const PHY: PhyConfig = PhyConfig { ksz9021_skews: Some((0xe3f0, 0x3333)), ksz9021_force_master: true };

    /// The HPS LED (GPIO1 bit 24, soc::cyclone_v::HPS_LED_BIT), made an
    /// output by `init`.
    fn status_led(on: bool) {
        if let Some(mut led) = hps_led() {
            led.set(on);
        }
    }

    fn timer_hz(log: &mut impl Write) -> u32 {
        let mpu = managers().mpu_clock_hz(DE1_SOC_OSC1_HZ);
        let _ = writeln!(log, "clock: MPU {} MHz from the main PLL (osc1 25 MHz)", mpu / 1_000_000);
        periph_clock_hz(mpu)
    }

    /// Stop the L4 watchdog (the boot ROM starts it and U-Boot SPL leaves it
    /// running), then put EMAC1 on RGMII (reset held around the select,
    /// with `dsb`, read-backs and 2 us holds: soc::cyclone_v).
    fn init(log: &mut impl Write) {
        let m = managers();
        m.stop_watchdog();
        let _ = writeln!(log, "board: L4 watchdog 0 held in reset");
        m.release_gpio1();
        if let Some(mut led) = hps_led() {
            led.make_output();
            let _ =
                writeln!(log, "board: GPIO1 out of reset, HPS LED (GPIO53) an output: its blinks say the fault code");
        }
        match m.emac1_rgmii(&mut TimerDelay(&TIMER), aarch32_cpu::asm::dsb) {
            Ok(()) => {
                let _ = writeln!(log, "board: EMAC1 reset, RGMII selected");
            }
            Err(e) => {
                let _ = writeln!(log, "board: {e}");
            }
        }
    }
}
