//! A fake frame source the camera's fuzz harnesses share.

use model::Light;
use rt_services::camera::sender::SlotSource;
use rt_services::frames::ROWS;
use rt_services::FrameSource;

/// Frames that take a slot each and land at once, counting what is held;
/// no memory behind them (what is fuzzed is the bookkeeping, not pixels).
/// A row can be read while its slot is begun or held, as from the ring.
#[derive(Default)]
pub struct Slots {
    /// Slots of frames begun and not ended.
    pub begun: u32,
    /// Slots the camera holds for repairs.
    pub held: u32,
    /// The most slots in use at once.
    pub high: u32,
}

impl FrameSource for Slots {
    type Frame = usize;
    type Error = &'static str;
    fn begin(&mut self, _: &Light) -> Result<Option<usize>, &'static str> {
        let Some(slot) = (0..32).find(|&s| (self.begun | self.held) & (1 << s) == 0) else { return Ok(None) };
        self.begun |= 1 << slot;
        self.high = self.high.max((self.begun | self.held).count_ones());
        Ok(Some(slot))
    }
    fn rows_ready(&mut self, frame: usize) -> Result<u16, &'static str> {
        Ok(if self.begun & (1 << frame) != 0 { ROWS } else { 0 })
    }
    fn copy_row(&mut self, frame: usize, _: u16, _: usize, out: &mut [u8]) -> usize {
        if (self.begun | self.held) & (1 << frame) != 0 {
            out.len()
        } else {
            0
        }
    }
    fn end(&mut self, frame: usize) {
        self.begun &= !(1 << frame);
    }
}

impl SlotSource for Slots {
    fn set_held(&mut self, mask: u32) {
        self.held = mask;
        self.high = self.high.max((self.begun | self.held).count_ones());
    }
}
