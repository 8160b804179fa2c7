//! The two boards. Exactly one is built in, chosen by cargo feature, as
//! [`Active`]; what every board must provide is the [`Board`] trait
//! (`crate::board`, below everything else) and, on top of the renderer,
//! the [`Renderer`] trait, so the compiler checks both (`cargo xtask test`
//! builds both).

use core::fmt::Write;

use hal_avalon::RegisterPort;
use soc::global_timer::GlobalTimer;

pub use crate::board::Board;
use crate::cpu::Caches;
use crate::render::Frames;

#[cfg(all(feature = "qemu-npcm750", feature = "de1-soc"))]
compile_error!("select exactly one board feature: qemu-npcm750 or de1-soc");
#[cfg(not(any(feature = "qemu-npcm750", feature = "de1-soc")))]
compile_error!("select a board: --features qemu-npcm750 or --features de1-soc");

#[cfg(feature = "de1-soc")]
mod de1_soc;
#[cfg(feature = "qemu-npcm750")]
mod qemu_npcm750;

/// The board this build runs on.
#[cfg(feature = "de1-soc")]
pub type Active = de1_soc::De1Soc;
/// The board this build runs on.
#[cfg(all(feature = "qemu-npcm750", not(feature = "de1-soc")))]
pub type Active = qemu_npcm750::QemuNpcm750;

/// How a board renders: its accelerator's port and the frames (above the
/// renderer, the self-test and the CPU set-up, which [`Board`] is below).
pub trait Renderer: Board {
    /// How the accelerator's registers are reached.
    type Port: RegisterPort;

    /// The frames: the FPGA accelerator's if one answers and passes the
    /// boot self-test (`crate::selftest`; frame mode when its register map
    /// has the frame DMA, else row mode), else the software renderer's.
    /// `caches` maintains the frame ring.
    fn renderer(log: &mut impl Write, timer: &'static GlobalTimer, caches: Caches) -> Frames<Self::Port>;
}
