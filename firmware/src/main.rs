//! The ray tracer's board binary for the Cortex-A9: boots on the Terasic
//! DE1-SoC or QEMU's `npcm750-evb` (cargo feature `de1-soc` /
//! `qemu-npcm750`) and serves frames on the protocol's two TCP ports, as a
//! network camera (RTSP/RTP) and on its web page (HTTP, port 80).
//!
//! Build: `cargo build --release -p firmware --target armv7a-none-eabi
//! --features qemu-npcm750`; `cargo xtask qemu` boots it, `cargo xtask
//! image` packs the DE1-SoC build for U-Boot. Bring-up on a board:
//! docs/board-bring-up.md.
//!
//! Start-up on core 0: the reset entry ([`start`]) cleans and turns off any
//! caches a boot loader left on, then aarch32-rt sets up stacks, `.data`
//! and `.bss` and calls `main` below: timer, MMU and caches, board set-up,
//! renderer (FPGA after its self-test, or software), network bring-up, main
//! loop. A failure is
//! reported on the UART before the core halts.
#![no_std]
#![no_main]

mod bench;
mod boards;
mod camera;
mod cpu;
mod display;
mod health;
mod limits;
mod log;
mod mem;
mod net;
mod platform;
mod render;
mod selftest;
mod settings;
mod start;

use core::fmt::Write;

use soc::l2c310::L2c310;
use static_cell::StaticCell;

use crate::boards::Renderer;
use crate::platform::{Active, Board, TIMER};

#[aarch32_rt::entry]
fn main() -> ! {
    log::init(Active::UART0);
    let mut log = log::Log;
    let _ = writeln!(log, "\n\nraytracer firmware {} on {}", env!("CARGO_PKG_VERSION"), Active::NAME);
    let _ = writeln!(log, "build: features {}", env!("FIRMWARE_FEATURES"));
    let _ = writeln!(log, "core 0 up; core 1 parked; vectors at VBAR");
    let _ = writeln!(log, "entry: {}", start::entry_state());
    TIMER.start();
    let hz = Active::timer_hz(&mut log);
    TIMER.set_rate(hz);
    let _ = writeln!(log, "timer: global timer at {hz} Hz");
    log::flush();
    static L2: StaticCell<L2c310> = StaticCell::new();
    let l2: &'static L2c310 = L2.init(cpu::enable_mmu_and_caches::<Active>(&mut log));
    log::flush();
    #[cfg(feature = "reentry-test")]
    reentry_test::maybe_reenter(&mut log);
    Active::init(&mut log);
    let caches = cpu::Caches { l2 };
    let board_settings = settings::load(&mut log);
    let mut facts = health::BootFacts::new();
    let mut frames = Active::renderer(&mut log, &TIMER, caches, &mut facts);
    log::flush();
    match net::run::<Active, _>(&TIMER, caches, &mut frames, &board_settings, &facts) {
        Ok(never) => match never {},
        Err(why) => {
            let _ = writeln!(log, "network not started: {why}");
            log::flush();
            start::halt()
        }
    }
}

/// Test build (`reentry-test`, used by `cargo xtask qemu-test`): the first
/// boot turns the MMU and caches on, as U-Boot leaves them, and jumps back to
/// the reset entry, so the emulated board exercises the entry's cache-off
/// path with translation and the L2C-310 on.
#[cfg(feature = "reentry-test")]
mod reentry_test {
    use core::fmt::Write;
    use core::sync::atomic::{AtomicU32, Ordering};

    /// Survives the second start-up (`.uninit` is neither loaded nor zeroed).
    #[unsafe(link_section = ".uninit.REENTERED")]
    static REENTERED: AtomicU32 = AtomicU32::new(0);
    const MAGIC: u32 = 0x5245_454e; // "REEN"

    pub fn maybe_reenter(log: &mut impl Write) {
        if REENTERED.swap(MAGIC, Ordering::SeqCst) == MAGIC {
            REENTERED.store(0, Ordering::SeqCst);
            let _ = writeln!(log, "reentry-test: second start-up, continuing");
            return;
        }
        let _ = writeln!(log, "reentry-test: MMU and caches on; jumping back to the reset entry");
        crate::log::flush();
        unsafe extern "C" {
            fn _start() -> !;
        }
        // SAFETY: `_start` is the reset entry; it takes no arguments, uses no
        // stack and resets every piece of state the firmware has.
        unsafe { _start() }
    }
}
