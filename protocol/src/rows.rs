//! Where rows come from: [`RowSource`], anything that renders one row of a
//! frame, and [`SoftwareRenderer`], the model on the CPU. At the bottom of
//! the crate: the frame server ([`crate::server`]), the frame sources
//! ([`crate::frames`]) and the fallback ([`crate::fallback`]) all build on
//! it without importing one another for it.

use model::{Light, WIDTH};

/// Anything that renders one row of line-buffer words: the model on the CPU,
/// the accelerator through hal-avalon's driver, the simulated accelerator.
pub trait RowSource {
    /// Why a row could not be rendered.
    type Error: core::fmt::Debug;

    /// Render row `y` (`0..360`) for `light` into `out` (`0x00RRGGBB` words).
    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Self::Error>;
}

/// The software renderer: the bit-exact model running on the CPU.
#[derive(Clone, Copy, Debug, Default)]
pub struct SoftwareRenderer;

impl RowSource for SoftwareRenderer {
    type Error = core::convert::Infallible;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Self::Error> {
        model::render_row(y, light, out);
        Ok(())
    }
}
