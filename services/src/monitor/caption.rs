//! The board's name and address drawn onto the VGA picture, so that a
//! person in front of the monitor reads where to point a browser or a
//! player ([`Caption`]): two lines in the bottom-left corner, white on a
//! darkened box, on attract mode's own frames for [`CAPTION_FOR`] after the
//! board reaches a new address (the monitor's policy, [`super::Monitor`]).
//!
//! The text is drawn once, with embedded-graphics' 10x20 mono font, into a
//! one-bit mask of the rows it covers; stamping a frame then only blends
//! those rows ([`Caption::stamp_row`]). A client's frame is never stamped:
//! clients get the model's picture, byte for byte.

use core::convert::Infallible;
use core::fmt::Write as _;
use core::time::Duration;

use embedded_graphics::mono_font::ascii::FONT_10X20;
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::pixelcolor::BinaryColor;
use embedded_graphics::prelude::{DrawTarget, OriginDimensions, Point, Size};
use embedded_graphics::text::{Baseline, Text};
use embedded_graphics::{Drawable, Pixel};
use model::{ROW_BYTES, WIDTH};

use crate::frames::ROWS;

/// How long the caption stays on attract frames after a new address.
pub const CAPTION_FOR: Duration = Duration::from_secs(30);

/// Glyph size of the font (FONT_10X20).
const GLYPH_W: usize = 10;
const GLYPH_H: usize = 20;
/// Space between the box's edge and the text, and between the box and the
/// picture's edge.
const PAD: usize = 4;
const MARGIN: usize = 8;
/// Rows the box covers: two lines and the padding.
pub const BOX_ROWS: usize = 2 * GLYPH_H + 2 * PAD;
/// Characters a line holds inside the box; a longer name is cut.
pub const LINE_CHARS: usize = (WIDTH - 2 * MARGIN - 2 * PAD) / GLYPH_W;
/// First row of the box (the box ends 8 rows above the bottom).
pub const FIRST_ROW: u16 = (ROWS as usize - MARGIN - BOX_ROWS) as u16;

/// Bytes of the longest name [`fitting`] returns.
pub const NAME_BYTES: usize = LINE_CHARS * 4;

/// `name` cut to the characters a line holds.
pub fn fitting(name: &str) -> &str {
    &name[..name.char_indices().nth(LINE_CHARS).map_or(name.len(), |(i, _)| i)]
}

const WORDS_PER_ROW: usize = WIDTH.div_ceil(32);

/// The caption's text drawn as a mask of the box's rows.
#[derive(Clone, Debug)]
pub struct Caption {
    /// Bit `x % 32` of word `row * WORDS_PER_ROW + x / 32`: a text pixel.
    mask: [u32; WORDS_PER_ROW * BOX_ROWS],
    /// Pixels `MARGIN..box_end` of the box's rows are darkened; 0: no
    /// caption.
    box_end: usize,
}

impl Default for Caption {
    fn default() -> Caption {
        Caption::new()
    }
}

impl Caption {
    /// No caption: [`stamp_row`](Self::stamp_row) changes nothing.
    pub const fn new() -> Caption {
        Caption { mask: [0; WORDS_PER_ROW * BOX_ROWS], box_end: 0 }
    }

    /// The caption for the board named `name` (its mDNS host name, e.g.
    /// `raytracer`) at `address`: `name.local` on the first line, the
    /// dotted address on the second.
    pub fn draw(&mut self, name: &str, address: [u8; 4]) {
        self.mask.fill(0);
        let mut dotted = heapless::String::<15>::new();
        let [a, b, c, d] = address;
        // 15 characters at most: cannot fail.
        let _ = write!(dotted, "{a}.{b}.{c}.{d}");
        let mut full = heapless::String::<{ NAME_BYTES + 6 }>::new();
        // The name is cut to the line first, so it fits.
        let _ = write!(full, "{}.local", fitting(name));
        let name = fitting(&full);
        let style = MonoTextStyle::new(&FONT_10X20, BinaryColor::On);
        let mut mask = Mask { bits: &mut self.mask };
        for (line, text) in [name, dotted.as_str()].into_iter().enumerate() {
            let at = Point::new((MARGIN + PAD) as i32, (PAD + line * GLYPH_H) as i32);
            // The mask draws infallibly; text past its edge is clipped.
            let _ = Text::with_baseline(text, at, style, Baseline::Top).draw(&mut mask);
        }
        let chars = name.chars().count().max(dotted.len());
        self.box_end = MARGIN + 2 * PAD + chars * GLYPH_W;
    }

    /// Remove the caption.
    pub fn clear(&mut self) {
        self.box_end = 0;
    }

    /// Whether there is a caption to stamp.
    pub fn is_drawn(&self) -> bool {
        self.box_end != 0
    }

    /// The rows [`stamp_row`](Self::stamp_row) changes.
    pub fn rows(&self) -> core::ops::Range<u16> {
        if self.is_drawn() {
            FIRST_ROW..FIRST_ROW + BOX_ROWS as u16
        } else {
            0..0
        }
    }

    /// Blend the caption into row `y` of a frame (RGB888): the box's
    /// pixels at a quarter of their brightness, the text's white.
    pub fn stamp_row(&self, y: u16, row: &mut [u8; ROW_BYTES]) {
        if !self.rows().contains(&y) {
            return;
        }
        let r = usize::from(y - FIRST_ROW);
        let words = &self.mask[r * WORDS_PER_ROW..(r + 1) * WORDS_PER_ROW];
        for x in MARGIN..self.box_end.min(WIDTH - MARGIN) {
            let px = &mut row[3 * x..3 * x + 3];
            if words[x / 32] & (1 << (x % 32)) != 0 {
                px.fill(0xff);
            } else {
                px.iter_mut().for_each(|c| *c /= 4);
            }
        }
    }
}

/// The caption's mask as an embedded-graphics target.
struct Mask<'a> {
    bits: &'a mut [u32; WORDS_PER_ROW * BOX_ROWS],
}

impl OriginDimensions for Mask<'_> {
    fn size(&self) -> Size {
        Size::new(WIDTH as u32, BOX_ROWS as u32)
    }
}

impl DrawTarget for Mask<'_> {
    type Color = BinaryColor;
    type Error = Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Infallible>
    where
        I: IntoIterator<Item = Pixel<BinaryColor>>,
    {
        for Pixel(p, color) in pixels {
            let (Ok(x), Ok(y)) = (usize::try_from(p.x), usize::try_from(p.y)) else { continue };
            if x < WIDTH && y < BOX_ROWS && color == BinaryColor::On {
                self.bits[y * WORDS_PER_ROW + x / 32] |= 1 << (x % 32);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text_pixels(c: &Caption) -> u32 {
        c.mask.iter().map(|w| w.count_ones()).sum()
    }

    #[test]
    fn the_box_sits_in_the_bottom_left_corner_and_holds_both_lines() {
        let mut c = Caption::new();
        assert!(c.rows().is_empty());
        c.draw("raytracer", [192, 168, 1, 57]);
        assert_eq!(c.rows(), 304..352, "48 rows ending 8 above the bottom");
        // "raytracer.local" is the longer line: 15 characters.
        assert_eq!(c.box_end, 8 + 8 + 150);
        assert!(text_pixels(&c) > 300, "both lines drawn");
        // Each line's pixels lie in its own band of rows.
        let rows_with_text: usize = (0..BOX_ROWS)
            .filter(|r| c.mask[r * WORDS_PER_ROW..(r + 1) * WORDS_PER_ROW].iter().any(|w| *w != 0))
            .count();
        assert!(rows_with_text > 20, "{rows_with_text} rows hold text");
    }

    #[test]
    fn stamping_darkens_the_box_whitens_the_text_and_leaves_the_rest() {
        let mut c = Caption::new();
        c.draw("b", [10, 0, 0, 7]);
        let grey = [0x80u8; ROW_BYTES];
        let mut above = grey;
        c.stamp_row(FIRST_ROW - 1, &mut above);
        assert_eq!(above, grey, "a row above the box is untouched");
        // The first line's middle row has text pixels.
        let y = FIRST_ROW + (PAD + GLYPH_H / 2) as u16;
        let mut row = grey;
        c.stamp_row(y, &mut row);
        let px = |x: usize| [row[3 * x], row[3 * x + 1], row[3 * x + 2]];
        assert_eq!(px(MARGIN - 1), [0x80; 3], "left of the box");
        assert_eq!(px(MARGIN + 1), [0x20; 3], "the box's padding is darkened");
        assert_eq!(px(c.box_end), [0x80; 3], "right of the box");
        assert!((MARGIN..c.box_end).any(|x| px(x) == [0xff; 3]), "text is white");
        c.clear();
        let mut row = grey;
        c.stamp_row(y, &mut row);
        assert_eq!(row, grey, "no caption, no change");
    }

    #[test]
    fn a_long_name_is_cut_to_the_line() {
        let mut c = Caption::new();
        let long = "a-board-name-that-is-much-longer-than-the-line-holds";
        c.draw(long, [169, 254, 12, 34]);
        assert_eq!(c.box_end, MARGIN + 2 * PAD + LINE_CHARS * GLYPH_W);
        assert!(c.box_end <= WIDTH - MARGIN);
        // Nothing drawn right of the box.
        for r in 0..BOX_ROWS {
            for x in c.box_end..WIDTH {
                assert_eq!(c.mask[r * WORDS_PER_ROW + x / 32] & (1 << (x % 32)), 0, "row {r} x {x}");
            }
        }
    }
}
