//! Terasic DE1-SoC: Cyclone V SoC 5CSEMA5F31C6 (2x Cortex-A9), EMAC1 over
//! RGMII to a Micrel KSZ9021RN, the ray tracer behind the lightweight
//! HPS-to-FPGA bridge.
//!
//! Constants: `shared/PLATFORM.md` ("Two targets, one firmware", "Minimal
//! MAC bring-up", "DE1-SoC boot without Linux"), which cites the Cyclone V
//! HPS Technical Reference Manual (cv_5v4); register names below are the
//! TRM's. Nothing here was checked on a board yet: where a comment says
//! "verify on the board", the board is the judge.

use core::fmt::Write;

use firmware::drivers::global_timer::GlobalTimer;
use firmware::drivers::mmio::Mmio;
use firmware::drivers::phy::PhyConfig;

use crate::render::Renderer;

/// Printed at start-up.
pub const NAME: &str = "de1-soc (Terasic DE1-SoC, Cyclone V HPS)";
/// UART0 (DesignWare 16550, 32-bit registers, stride 4), set to 115200 8N1
/// by the preloader.
pub const UART0_BASE: usize = 0xffc0_2000;
/// MPCore PERIPHBASE.
pub const PERIPHBASE: usize = 0xfffe_c000;
/// Global timer rate = MPU clock / 4. The DE1-SoC preloader runs the MPU at
/// 800 MHz (PLATFORM.md: 200-231 MHz depending on the MPU clock; verify on
/// the board against the preloader's handoff `mpu_clk`).
pub const GLOBAL_TIMER_HZ: u32 = 200_000_000;
/// L2C-310.
pub const L2C_BASE: usize = 0xfffe_f000;
/// EMAC1 (Synopsys DWMAC 3.70a, enhanced descriptors).
pub const EMAC_BASE: usize = 0xff70_2000;
/// DRAM: 1 GiB DDR3 at 0.
pub const DRAM_MIB: u32 = 1024;
/// A locally administered address (bit 1 of the first octet set): the board
/// has no factory MAC the firmware can read.
pub const MAC_ADDR: [u8; 6] = [0x02, 0xde, 0x1c, 0x50, 0xc0, 0x01];
/// Default address on a home or lab LAN; override at build time with
/// `FW_IPV4=a.b.c.d/len FW_GATEWAY=a.b.c.d`.
pub const DEFAULT_IPV4: &str = "192.168.1.200/24";
/// Default gateway (only used for peers outside the subnet).
pub const DEFAULT_GATEWAY: &str = "192.168.1.1";
/// KSZ9021 RGMII skews: extended register 0x104 (clock and control pad
/// skew) 0xe3f0, 0x105 (RX data pad skew) 0x3333, per PLATFORM.md step 7.
/// The values differ between U-Boot versions: verify on the board. Master
/// mode is forced as U-Boot does for a chip erratum.
pub const PHY: PhyConfig = PhyConfig { ksz9021_skews: Some((0xe3f0, 0x3333)), ksz9021_force_master: true };
/// Auto-negotiation on copper takes about 3 s; allow 10.
pub const LINK_TIMEOUT_US: u64 = 10_000_000;

/// Reset manager `permodrst` (peripheral module reset).
const RSTMGR_PERMODRST: usize = 0xffd0_5014;
/// `permodrst` bit 1: EMAC1.
const PERMODRST_EMAC1: u32 = 1 << 1;
/// `permodrst` bit 6: L4 watchdog 0 (the one the preloader may start).
const PERMODRST_L4WD0: u32 = 1 << 6;
/// Reset manager `brgmodrst` (bridge reset): bit 0 HPS-to-FPGA, bit 1
/// lightweight HPS-to-FPGA, bit 2 FPGA-to-HPS.
const RSTMGR_BRGMODRST: usize = 0xffd0_501c;
/// `brgmodrst` bit 1: the lightweight bridge is held in reset.
const BRGMODRST_LWHPS2FPGA: u32 = 1 << 1;
/// System manager `emacgrp ctrl`: bits 3:2 EMAC1 PHY interface select.
const SYSMGR_EMAC_CTRL: usize = 0xffd0_8060;
/// EMAC1 PHY select field (bits 3:2) and its RGMII value (1).
const EMAC1_PHYSEL_MASK: u32 = 0b11 << 2;
const EMAC1_PHYSEL_RGMII: u32 = 1 << 2;
/// System manager `fpgaintfgrp module`: bit 3 routes EMAC1 through the FPGA.
const SYSMGR_FPGAINTF_MODULE: usize = 0xffd0_8028;
const FPGAINTF_EMAC1: u32 = 1 << 3;
/// FPGA manager `stat` (FPGA manager base 0xff70_6000, offset 0): bits 2:0
/// mode, 4 = user mode (TRM, FPGA Manager, `stat.mode`).
const FPGAMGR_STAT: usize = 0xff70_6000;
const FPGAMGR_MODE_MASK: u32 = 0b111;
const FPGAMGR_MODE_USER: u32 = 4;
/// L3 interconnect `remap` (write-only): the handoff value 0x19 makes the
/// lightweight bridge (bit 4), the HPS-to-FPGA bridge (bit 3) and on-chip
/// RAM at 0 (bit 0) visible (PLATFORM.md; TRM, L3 interconnect `remap`).
const L3_REMAP: usize = 0xff80_0000;
const L3_REMAP_HANDOFF: u32 = 0x19;

fn reg(addr: usize) -> Mmio {
    // SAFETY: every address passed here is a Cyclone V HPS system register
    // (reset manager, system manager, FPGA manager, L3 remap) mapped as
    // device memory by the firmware's MMU table; only this board module uses
    // them, at start-up, on one core.
    unsafe { Mmio::new(addr) }
}

/// Stop the L4 watchdog the preloader may have started (hold it in reset),
/// then put EMAC1 into RGMII mode: hold it in reset, select RGMII, clear
/// the FPGA-interface routing, release it (PLATFORM.md bring-up step 1).
pub fn init(log: &mut impl Write) {
    reg(RSTMGR_PERMODRST).modify(0, |v| v | PERMODRST_L4WD0);
    let _ = writeln!(log, "board: L4 watchdog 0 held in reset");
    reg(RSTMGR_PERMODRST).modify(0, |v| v | PERMODRST_EMAC1);
    reg(SYSMGR_EMAC_CTRL).modify(0, |v| (v & !EMAC1_PHYSEL_MASK) | EMAC1_PHYSEL_RGMII);
    reg(SYSMGR_FPGAINTF_MODULE).modify(0, |v| v & !FPGAINTF_EMAC1);
    reg(RSTMGR_PERMODRST).modify(0, |v| v & !PERMODRST_EMAC1);
    let _ = writeln!(log, "board: EMAC1 reset, RGMII selected");
}

/// Why the FPGA path is not used.
#[derive(Debug)]
enum NoFpga {
    NotUserMode(u32),
    BridgeInReset,
    Probe(hal_avalon::Error),
}

/// The FPGA accelerator when the fabric is in user mode, the lightweight
/// bridge is out of reset and visible, and the ID register matches; the
/// software renderer otherwise, with the reason on the UART.
pub fn renderer(log: &mut impl Write, timer: &'static GlobalTimer) -> Renderer {
    match fpga(timer) {
        Ok(r) => {
            let _ = writeln!(log, "renderer: FPGA accelerator (ID {:#010x})", hal_avalon::map::ID_VALUE);
            r
        }
        Err(why) => {
            let _ = match why {
                NoFpga::NotUserMode(mode) => writeln!(log, "FPGA: not in user mode (FPGA manager mode {mode})"),
                NoFpga::BridgeInReset => writeln!(log, "FPGA: lightweight bridge held in reset"),
                NoFpga::Probe(e) => writeln!(log, "FPGA: {e}"),
            };
            let _ = writeln!(log, "renderer: software (model on the A9)");
            Renderer::software()
        }
    }
}

fn fpga(timer: &'static GlobalTimer) -> Result<Renderer, NoFpga> {
    let mode = reg(FPGAMGR_STAT).read(0) & FPGAMGR_MODE_MASK;
    if mode != FPGAMGR_MODE_USER {
        return Err(NoFpga::NotUserMode(mode));
    }
    if reg(RSTMGR_BRGMODRST).read(0) & BRGMODRST_LWHPS2FPGA != 0 {
        return Err(NoFpga::BridgeInReset);
    }
    reg(L3_REMAP).write(0, L3_REMAP_HANDOFF);
    // SAFETY: the fabric is in user mode and the bridge is out of reset and
    // visible (checked just above), so reads of the window complete; the
    // window is mapped device memory and only the accelerator driver uses it.
    let port = unsafe { hal_avalon::Mmio::lightweight_bridge() };
    let mut accel = hal_avalon::Accelerator::new(port, crate::render::TimerDelay(timer), hal_avalon::PollTimeout::DEFAULT);
    accel.probe().map_err(NoFpga::Probe)?;
    Ok(Renderer::fpga(accel))
}
