//! The two boards. Exactly one is compiled in, chosen by cargo feature, and
//! re-exported as `board`; everything outside this folder is shared.
//!
//! Each board module provides the same items:
//!
//! | item | meaning |
//! |---|---|
//! | `NAME` | printed at start-up |
//! | `UART0_BASE` | 16550 log UART |
//! | `PERIPHBASE` | Cortex-A9 MPCore private region (global timer at +0x200) |
//! | `GLOBAL_TIMER_HZ` | global timer rate (PERIPHCLK) |
//! | `L2C_BASE` | L2C-310 cache controller |
//! | `EMAC_BASE` | the DesignWare MAC used |
//! | `DRAM_MIB` | DRAM mapped cacheable from address 0 |
//! | `MAC_ADDR` | the interface's Ethernet address |
//! | `DEFAULT_IPV4`, `DEFAULT_GATEWAY` | network defaults (build-time overridable) |
//! | `PHY` | PHY settings (KSZ9021 skews) |
//! | `LINK_TIMEOUT_US` | how long to wait for the link |
//! | `init` | board set-up before the MAC (resets, watchdog, pin mux) |
//! | `renderer` | the row source: FPGA if usable, else software |

#[cfg(all(feature = "qemu-npcm750", feature = "de1-soc"))]
compile_error!("select exactly one board feature: qemu-npcm750 or de1-soc");
#[cfg(not(any(feature = "qemu-npcm750", feature = "de1-soc")))]
compile_error!("select a board: --features qemu-npcm750 or --features de1-soc");

#[cfg(feature = "de1-soc")]
pub mod de1_soc;
#[cfg(feature = "qemu-npcm750")]
pub mod qemu_npcm750;

#[cfg(feature = "de1-soc")]
pub use de1_soc as board;
#[cfg(all(feature = "qemu-npcm750", not(feature = "de1-soc")))]
pub use qemu_npcm750 as board;
