//! The composition root of each board: which renderer it runs (the FPGA
//! after its self-test, or software) over the frames, the self-test and
//! the CPU set-up, which the board's facts (`crate::platform`, below
//! everything else) do not know. Exactly one board is built in, chosen by
//! cargo feature ([`crate::platform::Active`]); the compiler checks both
//! (`cargo xtask test` builds both).

use core::fmt::Write;

use hal_avalon::RegisterPort;
use soc::global_timer::GlobalTimer;

use crate::cpu::Caches;
use crate::health::BootFacts;
use crate::platform::Board;
use crate::render::Frames;

#[cfg(feature = "de1-soc")]
mod de1_soc;
#[cfg(feature = "qemu-npcm750")]
mod qemu_npcm750;

/// How a board renders: its accelerator's port and the frames (above the
/// renderer, the self-test and the CPU set-up, which [`Board`] is below).
pub trait Renderer: Board {
    /// How the accelerator's registers are reached.
    type Port: RegisterPort;

    /// The frames: the FPGA accelerator's if one answers and passes the
    /// boot self-test (`crate::selftest`; frame mode when its register map
    /// has the frame DMA, else row mode; its rows into the ring when only
    /// the frame path failed), else the software renderer's. `caches`
    /// maintains the frame ring; `facts` keeps what was found.
    fn renderer(
        log: &mut impl Write,
        timer: &'static GlobalTimer,
        caches: Caches,
        facts: &mut BootFacts,
    ) -> Frames<Self::Port>;
}
