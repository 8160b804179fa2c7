//! The wire format of a frame: 480 x 360 RGB888, row-major, top row first.

use crate::colour::Rgb;
use crate::light::Light;
use crate::scene::{HEIGHT, WIDTH};
use crate::trace::render_row;

/// Bytes of one row on the wire (480 x 3).
pub const ROW_BYTES: usize = WIDTH * 3;
/// Bytes of one frame on the wire (518,400).
pub const FRAME_BYTES: usize = ROW_BYTES * HEIGHT;

/// Convert one line-buffer row (`0x00RRGGBB` words) to its wire bytes.
pub fn row_to_rgb888(row: &[u32; WIDTH], out: &mut [u8; ROW_BYTES]) {
    for (word, rgb) in row.iter().zip(out.chunks_exact_mut(3)) {
        let c = Rgb::from_word(*word);
        rgb.copy_from_slice(&[c.r, c.g, c.b]);
    }
}

/// Render a whole frame into its 518,400-byte wire format.
pub fn render_frame_rgb888(light: &Light, out: &mut [u8; FRAME_BYTES]) {
    let mut row = [0u32; WIDTH];
    let (rows, _) = out.as_chunks_mut::<ROW_BYTES>();
    for (y, bytes) in (0u16..).zip(rows) {
        render_row(y, light, &mut row);
        row_to_rgb888(&row, bytes);
    }
}

/// A whole frame in its wire format, in a new vector (host builds).
#[cfg(feature = "std")]
pub fn render_frame(light: &Light) -> Vec<u8> {
    let mut frame = vec![0u8; FRAME_BYTES];
    let (whole, _) = frame.as_chunks_mut::<FRAME_BYTES>();
    for f in whole {
        render_frame_rgb888(light, f);
    }
    frame
}
