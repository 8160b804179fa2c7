//! The board on its own (map version 3): the VGA monitor showing the newest
//! frame, attract mode (its first seconds captioned with the board's name
//! and address), keys, switches, LEDs and 7-segment displays. The
//! policy is `rt_services::monitor` (host-tested); this module only puts
//! the frame ring and the accelerator's board I/O block together as the
//! device the policy works on, and logs its report once a second:
//!
//! `display: 59 frames shown, 120 refreshes, layout full, 30 fps, attract on, on screen: light (3072, 4096, 0) from attract mode`

use core::fmt::Write;

use hal_avalon::board::{has_board_io, BoardIo};
use hal_avalon::map::Csr;
use hal_avalon::RegisterPort;
use model::display::Layout;
use model::{Light, ROW_BYTES};
use rt_services::frames::Completed;
use rt_services::monitor::{Inputs, Monitor, Panel, Refreshes, Screen, Status};
use rt_services::{FrameSource, Instant};

use crate::render::{Frames, Ring};

/// The display policy, on a board whose accelerator has the VGA block.
pub struct Display {
    monitor: Monitor,
    /// The frame DMA renders (the scan-out reads the same memory); when it
    /// failed its self-test only the LEDs and 7-segment displays run.
    scan_out: bool,
}

impl Display {
    /// The display, if the frames come from a frame ring whose accelerator
    /// reports map version 3 or later (the version is read once, here);
    /// never in the `bench` build.
    pub fn probe<P: RegisterPort>(frames: &mut Frames<P>, log: &mut impl Write) -> Option<Display> {
        let Frames::Ring(ring) = frames else { return None };
        // The scan-out runs where the frame DMA renders (it reads the same
        // memory); an accelerator kept only for its board I/O (it failed
        // its self-test) or rendering rows gets the LEDs and displays.
        let scan_out = ring.engine().primary_active();
        let port = port(ring)?;
        let id = port.read(Csr::Id);
        if !has_board_io(id) {
            return None;
        }
        if cfg!(feature = "bench") {
            // Attract frames would be counted as the client's cost.
            let _ = writeln!(log, "display: off in the bench build (its figures are the clients' frames alone)");
            return None;
        }
        if scan_out {
            let _ = writeln!(
                log,
                "display: VGA scan-out and board I/O (register map version {}): attract mode on until a client asks for a frame",
                id & 0xffff
            );
        } else {
            let _ = writeln!(
                log,
                "display: LEDs and 7-segment displays only (register map version {}): VGA off, the frame DMA failed its self-test",
                id & 0xffff
            );
        }
        Some(Display { monitor: Monitor::new(), scan_out })
    }

    /// The VGA output in words, for `/status`.
    pub fn vga(&self) -> &'static str {
        match (self.scan_out, self.monitor.scanout().enabled(), self.monitor.scanout().port_fault()) {
            (false, _, _) => "off: the FPGA's frame DMA is not used (self-test), and the scan-out needs it",
            (true, _, true) => "on, memory port fault (check fpgaportrst)",
            (true, true, false) => "on",
            (true, false, false) => "starting",
        }
    }

    /// Whether the scan-out reported a memory fault.
    pub fn vga_fault(&self) -> bool {
        self.monitor.scanout().port_fault()
    }

    /// One step of the main loop: `requests` counts the clients' frame
    /// requests so far, `status` what the LEDs show. Logs the report when
    /// one is due.
    pub fn poll<P: RegisterPort>(
        &mut self,
        now: Instant,
        frames: &mut Frames<P>,
        requests: u32,
        status: &Status,
        log: &mut impl Write,
    ) {
        let Frames::Ring(ring) = frames else { return };
        if !self.scan_out {
            self.monitor.poll_panel(now, &mut Device { ring }, status);
            return;
        }
        if let Some(report) = self.monitor.poll(now, &mut Device { ring }, requests, status) {
            let _ = writeln!(log, "{report}");
        }
    }
}

/// The accelerator's port behind the ring, switched off or not (or the
/// one rendering the ring's rows in row mode), without the bus-access
/// counting (the bench's figures are the frames').
fn port<P: RegisterPort>(ring: &mut Ring<P>) -> Option<&mut P> {
    if ring.engine().primary_kept().is_none() {
        // Kept after rows are switched off too (E3 on the displays).
        let rows = ring.engine().fallback().rows().primary_kept()?;
        return Some(rows.inner().accelerator().port_mut().inner_mut());
    }
    let engine = ring.engine().primary_kept()?;
    Some(engine.inner().engine().port_mut().inner_mut())
}

/// The ring and its accelerator's board I/O as one device.
struct Device<'a, P: RegisterPort> {
    ring: &'a mut Ring<P>,
}

impl<P: RegisterPort> Device<'_, P> {
    fn io(&mut self) -> Option<BoardIo<&mut P>> {
        port(self.ring).map(BoardIo::checked)
    }
}

impl<P: RegisterPort> FrameSource for Device<'_, P> {
    type Frame = usize;
    type Error = <Ring<P> as FrameSource>::Error;

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

impl<P: RegisterPort> Screen for Device<'_, P> {
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

impl<P: RegisterPort> Panel for Device<'_, P> {
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
