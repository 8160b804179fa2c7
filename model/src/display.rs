//! What a VGA monitor on the board shows: the 640 x 480 display and how its
//! pixels map onto the 480 x 360 frame. The RTL's scan-out, the simulated
//! monitor and every test take the mapping from here.
//!
//! 480 x 360 is exactly 3/4 of 640 x 480 each way, so two layouts need no
//! filtering:
//!
//! * [`Layout::FullScreen`]: display pixel `(x, y)` shows frame pixel
//!   `(floor(3x/4), floor(3y/4))`: every fourth display column and line
//!   repeats its neighbour.
//! * [`Layout::Letterbox`]: the frame 1:1 in the middle, display pixels
//!   `[80, 560) x [60, 420)`; black around it.
//!
//! Timing: 640 x 480 at 60 Hz, 800 x 525 pixel clocks per frame (VESA DMT
//! 640x480@60; the Intel University Program's `altera_up_avalon_video_vga_timing`
//! uses the same numbers), at a 25.000 MHz pixel clock as the DE1-SoC's own
//! designs do (Terasic DE1-SoC User Manual, VGA section).

use crate::{HEIGHT, WIDTH};

/// Visible display pixels per line.
pub const DISPLAY_WIDTH: usize = 640;
/// Visible display lines.
pub const DISPLAY_HEIGHT: usize = 480;
/// Bytes of one RGB888 display picture.
pub const DISPLAY_BYTES: usize = DISPLAY_WIDTH * DISPLAY_HEIGHT * 3;

/// One axis of the VGA timing, in pixel clocks (horizontal) or lines
/// (vertical): visible, front porch, sync pulse, back porch. Both syncs of
/// 640x480@60 are active low.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Axis {
    /// Visible pixels or lines.
    pub visible: u16,
    /// Front porch.
    pub front_porch: u16,
    /// Sync pulse width.
    pub sync: u16,
    /// Back porch.
    pub back_porch: u16,
}

impl Axis {
    /// Pixels or lines per period.
    pub const fn total(&self) -> u16 {
        self.visible + self.front_porch + self.sync + self.back_porch
    }
}

/// Horizontal timing of 640x480@60: 640 + 16 + 96 + 48 = 800 pixel clocks.
pub const H_TIMING: Axis = Axis { visible: 640, front_porch: 16, sync: 96, back_porch: 48 };
/// Vertical timing of 640x480@60: 480 + 10 + 2 + 33 = 525 lines.
pub const V_TIMING: Axis = Axis { visible: 480, front_porch: 10, sync: 2, back_porch: 33 };
/// The pixel clock: 25.000 MHz (a clock enable of every second 50 MHz
/// fabric clock), so a frame lasts 800 x 525 / 25 MHz = 16.8 ms.
pub const PIXEL_HZ: u32 = 25_000_000;

const _: () = assert!(H_TIMING.visible as usize == DISPLAY_WIDTH && V_TIMING.visible as usize == DISPLAY_HEIGHT);
const _: () = assert!(H_TIMING.total() == 800 && V_TIMING.total() == 525);
const _: () = assert!(4 * WIDTH == 3 * DISPLAY_WIDTH && 4 * HEIGHT == 3 * DISPLAY_HEIGHT);

/// How the frame sits on the display.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Layout {
    /// The frame scaled by 4/3 to fill the display (the default).
    #[default]
    FullScreen,
    /// The frame 1:1 in the middle, black around it.
    Letterbox,
}

/// Left edge of the letterboxed frame on the display.
pub const LETTERBOX_X: u16 = ((DISPLAY_WIDTH - WIDTH) / 2) as u16;
/// Top edge of the letterboxed frame on the display.
pub const LETTERBOX_Y: u16 = ((DISPLAY_HEIGHT - HEIGHT) / 2) as u16;

/// The frame pixel `(x, y)` that display pixel `(dx, dy)` shows, or `None`
/// where the display is black (outside the letterbox, or outside the
/// visible display).
pub const fn frame_pixel(layout: Layout, dx: u16, dy: u16) -> Option<(u16, u16)> {
    if dx as usize >= DISPLAY_WIDTH || dy as usize >= DISPLAY_HEIGHT {
        return None;
    }
    match layout {
        Layout::FullScreen => Some((3 * dx / 4, 3 * dy / 4)),
        Layout::Letterbox => {
            let (w, h) = (WIDTH as u16, HEIGHT as u16);
            if dx >= LETTERBOX_X && dx < LETTERBOX_X + w && dy >= LETTERBOX_Y && dy < LETTERBOX_Y + h {
                Some((dx - LETTERBOX_X, dy - LETTERBOX_Y))
            } else {
                None
            }
        }
    }
}

/// The 640 x 480 RGB888 picture the display shows for `frame` (480 x 360
/// RGB888 wire bytes, [`crate::FRAME_BYTES`] long), into `out`
/// ([`DISPLAY_BYTES`] long). Black is 0, 0, 0.
pub fn display_picture(frame: &[u8], layout: Layout, out: &mut [u8]) {
    for (i, px) in out.chunks_exact_mut(3).take(DISPLAY_WIDTH * DISPLAY_HEIGHT).enumerate() {
        let (dx, dy) = ((i % DISPLAY_WIDTH) as u16, (i / DISPLAY_WIDTH) as u16);
        let rgb = match frame_pixel(layout, dx, dy) {
            Some((x, y)) => {
                let at = (usize::from(y) * WIDTH + usize::from(x)) * 3;
                frame.get(at..at + 3)
            }
            None => None,
        };
        match rgb {
            Some(src) => px.copy_from_slice(src),
            None => px.fill(0),
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn full_screen_covers_every_frame_pixel_and_repeats_every_fourth() {
        assert_eq!(frame_pixel(Layout::FullScreen, 0, 0), Some((0, 0)));
        assert_eq!(frame_pixel(Layout::FullScreen, 3, 3), Some((2, 2)));
        assert_eq!(frame_pixel(Layout::FullScreen, 4, 4), Some((3, 3)));
        assert_eq!(frame_pixel(Layout::FullScreen, 639, 479), Some((479, 359)));
        assert_eq!(frame_pixel(Layout::FullScreen, 640, 0), None);
        let mut seen = [false; WIDTH];
        for dx in 0..DISPLAY_WIDTH as u16 {
            if let Some((x, _)) = frame_pixel(Layout::FullScreen, dx, 0) {
                seen[usize::from(x)] = true;
            }
        }
        assert!(seen.iter().all(|s| *s), "every frame column is shown");
    }

    #[test]
    fn letterbox_is_the_frame_one_to_one_in_the_middle() {
        assert_eq!((LETTERBOX_X, LETTERBOX_Y), (80, 60));
        assert_eq!(frame_pixel(Layout::Letterbox, 79, 200), None);
        assert_eq!(frame_pixel(Layout::Letterbox, 80, 60), Some((0, 0)));
        assert_eq!(frame_pixel(Layout::Letterbox, 559, 419), Some((479, 359)));
        assert_eq!(frame_pixel(Layout::Letterbox, 560, 419), None);
        assert_eq!(frame_pixel(Layout::Letterbox, 300, 420), None);
    }

    #[test]
    fn the_picture_follows_the_mapping() {
        let frame: std::vec::Vec<u8> = (0..crate::FRAME_BYTES).map(|i| (i * 7 % 251) as u8).collect();
        let mut out = std::vec![0xAAu8; DISPLAY_BYTES];
        display_picture(&frame, Layout::Letterbox, &mut out);
        assert_eq!(&out[..3], &[0, 0, 0], "black outside");
        let at = (60 * DISPLAY_WIDTH + 80) * 3;
        assert_eq!(&out[at..at + 3], &frame[..3]);
        display_picture(&frame, Layout::FullScreen, &mut out);
        let at = (479 * DISPLAY_WIDTH + 639) * 3;
        assert_eq!(&out[at..at + 3], &frame[crate::FRAME_BYTES - 3..]);
    }
}
