//! The SoC peripherals the firmware touches, as typed register blocks with
//! compile-time offset checks, and the logic around them that the host can
//! test: everything except the start-up code, which lives in the firmware.
//!
//! ARM IP, on both boards (Cyclone V HPS and QEMU's NPCM750):
//!
//! * [`global_timer`]: the Cortex-A9 MPCore global timer, the firmware's
//!   clock.
//! * [`l2c310`]: the L2 cache controller (enable, maintenance by way and
//!   by line, cache sync), and [`cache`]: the order of by-address
//!   maintenance on both levels for memory a device shares.
//! * [`uart16550`]: the log UART, and [`log`]: a ring buffer that drains it
//!   without waiting.
//! * [`mmu`]: the short-descriptor section table of the flat map.
//! * [`abort`]: decoding data aborts, and the recovery rule for the
//!   accelerator probe.
//!
//! Cyclone V HPS only ([`cyclone_v`]): reset, system, clock and FPGA
//! managers and the L3 remap register.
//!
//! Every register handle holds a raw pointer, never a reference with a
//! lifetime, and is created by an `unsafe` constructor whose contract names
//! the register block it must point to.
#![cfg_attr(not(test), no_std)]

pub mod abort;
pub mod cache;
pub mod cyclone_v;
pub mod global_timer;
pub mod l2c310;
pub mod log;
pub mod mmu;
pub mod uart16550;
