//! The accelerator behind the frame server (feature `services`): a
//! [`RowSource`] in row mode, a [`FrameEngine`] in frame mode.

use embedded_hal::delay::DelayNs;
use model::{Light, WIDTH};
use rt_services::{FrameEngine, FrameMemory, RowSource};

use crate::driver::{Accelerator, Error};
use crate::map::ROWS;
use crate::port::RegisterPort;

impl<P: RegisterPort, D: DelayNs> RowSource for Accelerator<P, D> {
    type Error = Error;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Error> {
        self.run_row(y, light, out)
    }
}

/// Frame mode: the accelerator's frame DMA writes the slot at its bus
/// address; progress is its rows-done counter.
impl<P: RegisterPort, D: DelayNs, M: FrameMemory> FrameEngine<M> for Accelerator<P, D> {
    type Error = Error;

    fn start(&mut self, mem: &mut M, slot: usize, light: &Light) -> Result<(), Error> {
        self.start_frame(mem.slot_address(slot), light)
    }

    fn progress(&mut self, _mem: &mut M) -> Result<u16, Error> {
        self.frame_progress().map(|p| p.rows)
    }

    fn abort(&mut self, _mem: &mut M) -> Result<(), Error> {
        self.abort_frame()
    }
}

/// Row mode with the next row started before the current one is used:
/// after copying row `y` out of the line buffer it starts row `y + 1` of the
/// same light, so the accelerator renders it while the CPU sends row `y`.
/// A row asked for that was not started ahead (another client's, another
/// light) is started then; the one in progress is let finish first.
pub struct PipelinedRows<P, D> {
    accel: Accelerator<P, D>,
    ahead: Option<(u16, Light)>,
}

impl<P: RegisterPort, D: DelayNs> PipelinedRows<P, D> {
    /// Rows from `accel`.
    pub fn new(accel: Accelerator<P, D>) -> PipelinedRows<P, D> {
        PipelinedRows { accel, ahead: None }
    }

    /// The driver.
    pub fn accelerator(&mut self) -> &mut Accelerator<P, D> {
        &mut self.accel
    }
}

impl<P: RegisterPort, D: DelayNs> RowSource for PipelinedRows<P, D> {
    type Error = Error;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Error> {
        let started = self.ahead.take() == Some((y, *light));
        if !started {
            self.accel.start_row(y, light)?;
        }
        self.accel.finish_row(out)?;
        if y + 1 < ROWS && self.accel.start_row(y + 1, light).is_ok() {
            self.ahead = Some((y + 1, *light));
        }
        Ok(())
    }
}
