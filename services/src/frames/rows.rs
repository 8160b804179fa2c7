//! Where rows come from: [`RowSource`], anything that renders one row of a
//! frame, and [`SoftwareRenderer`], the model on the CPU; and row mode,
//! [`RowFrames`]: frames rendered a row at a time as their session sends them.

use core::fmt;

use model::{row_to_rgb888, Light, ROW_BYTES, WIDTH};

use super::{FrameSource, ROWS};

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

/// One frame of [`RowFrames`]: its light and its newest row.
struct RowSlot {
    light: Light,
    rendered: u16,
    bytes: [u8; ROW_BYTES],
}

/// Row mode: frames rendered a row at a time by `R`, each holding only its
/// newest row (1,440 bytes), for up to `N` frames at once.
pub struct RowFrames<R, const N: usize> {
    rows: R,
    slots: [Option<RowSlot>; N],
    words: [u32; WIDTH],
}

impl<R: RowSource, const N: usize> RowFrames<R, N> {
    /// Frames rendered by `rows`.
    pub fn new(rows: R) -> RowFrames<R, N> {
        RowFrames { rows, slots: [const { None }; N], words: [0; WIDTH] }
    }

    /// The row source.
    pub fn rows(&mut self) -> &mut R {
        &mut self.rows
    }
}

impl<R: RowSource, const N: usize> FrameSource for RowFrames<R, N>
where
    R::Error: fmt::Display,
{
    type Frame = usize;
    type Error = R::Error;

    fn begin(&mut self, light: &Light) -> Result<Option<usize>, R::Error> {
        let Some(i) = self.slots.iter().position(Option::is_none) else {
            return Ok(None);
        };
        self.slots[i] = Some(RowSlot { light: *light, rendered: 0, bytes: [0; ROW_BYTES] });
        Ok(Some(i))
    }

    /// Renders the next row when asked: a session asks once it has sent
    /// every row rendered so far, so the single row buffer is free again.
    fn rows_ready(&mut self, frame: usize) -> Result<u16, R::Error> {
        let Some(slot) = self.slots.get_mut(frame).and_then(Option::as_mut) else {
            return Ok(0);
        };
        if slot.rendered < ROWS {
            self.rows.render_row(slot.rendered, &slot.light, &mut self.words)?;
            row_to_rgb888(&self.words, &mut slot.bytes);
            slot.rendered += 1;
        }
        Ok(slot.rendered)
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        match self.slots.get(frame).and_then(Option::as_ref) {
            Some(slot) if slot.rendered == y + 1 => copy_from(&slot.bytes, offset, out),
            _ => 0,
        }
    }

    fn end(&mut self, frame: usize) {
        if let Some(s) = self.slots.get_mut(frame) {
            *s = None;
        }
    }
}

/// Copy `row[offset..]` into the front of `out`; bytes copied.
fn copy_from(row: &[u8], offset: usize, out: &mut [u8]) -> usize {
    let src = row.get(offset..).unwrap_or(&[]);
    let n = src.len().min(out.len());
    out[..n].copy_from_slice(&src[..n]);
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(x: f64) -> Light {
        Light::from_world(x, 4.0, -2.0).unwrap()
    }

    #[test]
    fn row_frames_hold_one_row_per_frame() {
        let mut frames = RowFrames::<SoftwareRenderer, 2>::new(SoftwareRenderer);
        let l = light(-2.0);
        let a = frames.begin(&l).unwrap().unwrap();
        assert!(frames.begin(&l).unwrap().is_some());
        assert_eq!(frames.begin(&l).unwrap(), None, "two frames at most");
        assert_eq!(frames.copy_row(a, 0, 0, &mut [0; 4]), 0, "nothing rendered yet");
        assert_eq!(frames.rows_ready(a).unwrap(), 1);
        let mut row = vec![0u8; ROW_BYTES];
        assert_eq!(frames.copy_row(a, 0, 0, &mut row), ROW_BYTES);
        assert_eq!(row, model::render_frame(&l)[..ROW_BYTES]);
        assert_eq!(frames.rows_ready(a).unwrap(), 2);
        assert_eq!(frames.copy_row(a, 0, 0, &mut row), 0, "row 0 is gone once row 1 is rendered");
        frames.end(a);
        assert!(frames.begin(&l).unwrap().is_some());
    }
}
