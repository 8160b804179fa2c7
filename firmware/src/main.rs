//! The bare-metal Cortex-A9 firmware: boots on QEMU's `npcm750-evb` or the
//! DE1-SoC (cargo feature `qemu-npcm750` / `de1-soc`) and serves rendered
//! frames over TCP ports 7878 and 7879.
//!
//! Build: `cargo build --release -p firmware --target armv7a-none-eabi
//! --features qemu-npcm750` leaves the ELF at
//! `target/armv7a-none-eabi/release/firmware`; `cargo xtask qemu` boots it.
//!
//! # Host builds
//!
//! The binary is only meaningful on `armv7a-none-eabi` (`target_os =
//! "none"`). There it is `#![no_std]`/`#![no_main]` and every module below
//! is compiled; on any other target (`cargo build --workspace` and `cargo
//! test --workspace` on the host) the crate attribute and the modules are
//! configured out and a tiny `main` explains how to build and run the
//! firmware. This keeps the workspace commands working without special
//! flags, while the library (`firmware::*`) with all the driver logic is
//! built and unit-tested on the host as usual.
//!
//! # Start-up order (core 0)
//!
//! aarch32-rt's reset code (see `start`) → `kmain`: global timer, MMU and
//! caches, board set-up, renderer choice (FPGA or software), network, main
//! loop. Any failure is reported on the UART before the core halts.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod boards;
#[cfg(target_os = "none")]
mod log;
#[cfg(target_os = "none")]
mod mmu;
#[cfg(target_os = "none")]
mod net;
#[cfg(target_os = "none")]
mod render;
#[cfg(target_os = "none")]
mod start;

#[cfg(target_os = "none")]
mod kmain {
    use core::fmt::Write;

    use firmware::drivers::global_timer::GlobalTimer;
    use firmware::drivers::mmio::Mmio;

    use crate::boards::board;
    use crate::log::Log;

    /// The global timer: the firmware's clock (smoltcp's `Instant`).
    // SAFETY: PERIPHBASE + 0x200 is the MPCore global timer of the board
    // (ARM DDI 0407 4.3); only this value accesses it.
    pub static TIMER: GlobalTimer = GlobalTimer::new(unsafe { Mmio::new(board::PERIPHBASE + 0x200) }, board::GLOBAL_TIMER_HZ);

    #[aarch32_rt::entry]
    fn main() -> ! {
        let mut log = Log;
        let _ = writeln!(log, "\n\nraytracer firmware {} on {}", env!("CARGO_PKG_VERSION"), board::NAME);
        let _ = writeln!(log, "core 0 up; core 1 parked; vectors at VBAR");
        TIMER.start();
        crate::mmu::enable(board::DRAM_MIB, board::L2C_BASE, &TIMER, &mut log);
        let _ = writeln!(log, "timer: global timer at {} Hz", board::GLOBAL_TIMER_HZ);
        board::init(&mut log);
        let mut rows = board::renderer(&mut log, &TIMER);
        match crate::net::run(&TIMER, &mut rows) {
            Ok(never) => match never {},
            Err(why) => {
                let _ = writeln!(log, "network not started: {why}");
                crate::start::halt()
            }
        }
    }
}

/// On the host there is no firmware to run: say how to build it.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "The firmware runs on the Cortex-A9 only. Build it with\n  \
         cargo build --release -p firmware --target armv7a-none-eabi --features qemu-npcm750\n\
         and boot it in QEMU with `cargo xtask qemu` (or `cargo run` with that target)."
    );
    std::process::exit(2);
}
