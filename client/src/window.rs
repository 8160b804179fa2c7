//! The live window (`--show`): frames appear as they arrive.

use minifb::{Key, Window, WindowOptions};
use model::{HEIGHT, WIDTH};

/// One RGB888 pixel as minifb's 0RGB word.
pub fn pack_rgb(c: &[u8]) -> u32 {
    u32::from(c[0]) << 16 | u32::from(c[1]) << 8 | u32::from(c[2])
}

/// A window showing 480 x 360 frames.
pub struct LiveWindow {
    window: Window,
    pixels: Vec<u32>,
}

impl LiveWindow {
    /// Open the window (needs a display: X11 or Xvfb).
    pub fn open(title: &str) -> Result<LiveWindow, String> {
        let window = Window::new(title, WIDTH, HEIGHT, WindowOptions::default())
            .map_err(|e| format!("cannot open a window (is DISPLAY set?): {e}"))?;
        Ok(LiveWindow { window, pixels: vec![0; WIDTH * HEIGHT] })
    }

    /// Show an RGB888 frame; `false` once the user closed the window or
    /// pressed Escape.
    pub fn show(&mut self, rgb: &[u8]) -> bool {
        for (px, c) in self.pixels.iter_mut().zip(rgb.chunks_exact(3)) {
            *px = pack_rgb(c);
        }
        self.is_open() && self.window.update_with_buffer(&self.pixels, WIDTH, HEIGHT).is_ok()
    }

    /// Whether the user still wants the window.
    pub fn is_open(&self) -> bool {
        self.window.is_open() && !self.window.is_key_down(Key::Escape)
    }
}
