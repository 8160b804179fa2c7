//! A frame ring and its accelerator's board I/O block as one device for
//! the monitor policy (`rt_services::monitor`): the ring gives the frames
//! and what is on screen, the block behind the ring's engine the display,
//! keys, switches, LEDs and 7-segment displays. The firmware's display and
//! hps-linux's panel both run the policy on it.

use model::display::Layout;
use model::{Light, ROW_BYTES};
use rt_services::frames::{Completed, FrameEngine, FrameMemory, FrameRing};
use rt_services::monitor::{Inputs, Panel, Refreshes, Screen};
use rt_services::FrameSource;

use crate::board::BoardIo;
use crate::port::RegisterPort;

/// How the accelerator's port is reached through the ring's engine (none:
/// the engine has no accelerator, or has let it go).
pub type PortOf<E, P> = for<'e> fn(&'e mut E) -> Option<&'e mut P>;

/// `ring` and the board I/O block behind its engine, lent for one step of
/// the policy.
pub struct RingPanel<'a, M: FrameMemory, E: FrameEngine<M>, P, const N: usize> {
    ring: &'a mut FrameRing<M, E, N>,
    port: PortOf<E, P>,
}

impl<'a, M: FrameMemory, E: FrameEngine<M>, P: RegisterPort, const N: usize> RingPanel<'a, M, E, P, N> {
    /// `ring`, its engine's accelerator port reached with `port`.
    pub fn new(ring: &'a mut FrameRing<M, E, N>, port: PortOf<E, P>) -> RingPanel<'a, M, E, P, N> {
        RingPanel { ring, port }
    }

    fn io(&mut self) -> Option<BoardIo<&mut P>> {
        (self.port)(self.ring.engine()).map(BoardIo::checked)
    }
}

impl<M: FrameMemory, E: FrameEngine<M>, P, const N: usize> FrameSource for RingPanel<'_, M, E, P, N> {
    type Frame = usize;
    type Error = <FrameRing<M, E, N> as FrameSource>::Error;

    fn begin(&mut self, light: &Light) -> Result<Option<usize>, Self::Error> {
        self.ring.begin(light)
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, Self::Error> {
        self.ring.rows_ready(frame)
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        self.ring.copy_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: usize) {
        self.ring.end(frame)
    }
}

impl<M: FrameMemory, E: FrameEngine<M>, P, const N: usize> Screen for RingPanel<'_, M, E, P, N> {
    fn newest_complete(&self) -> Option<Completed> {
        self.ring.newest_complete()
    }

    fn pin(&mut self, slot: usize) {
        self.ring.pin(slot)
    }

    fn unpin(&mut self, slot: usize) {
        self.ring.unpin(slot)
    }

    fn slot_address(&self, slot: usize) -> u32 {
        self.ring.slot_address(slot)
    }

    fn edit_row(&mut self, slot: usize, y: u16, edit: &mut dyn FnMut(&mut [u8; ROW_BYTES])) {
        self.ring.edit_row(slot, y, edit)
    }
}

/// Without a block (no port), the display and inputs are idle and
/// nothing is shown.
impl<M: FrameMemory, E: FrameEngine<M>, P: RegisterPort, const N: usize> Panel for RingPanel<'_, M, E, P, N> {
    fn refreshes(&mut self) -> Refreshes {
        self.io().map(|mut io| Panel::refreshes(&mut io)).unwrap_or_default()
    }

    fn show(&mut self, base: u32) {
        if let Some(mut io) = self.io() {
            io.show(base);
        }
    }

    fn scan_out(&mut self, layout: Layout) {
        if let Some(mut io) = self.io() {
            io.enable(layout);
        }
    }

    fn inputs(&mut self) -> Inputs {
        self.io().map(|mut io| Panel::inputs(&mut io)).unwrap_or_default()
    }

    fn set_leds(&mut self, leds: u16) {
        if let Some(mut io) = self.io() {
            io.set_leds(leds);
        }
    }

    fn set_text(&mut self, text: [u8; 6]) {
        if let Some(mut io) = self.io() {
            io.set_text(text);
        }
    }
}
