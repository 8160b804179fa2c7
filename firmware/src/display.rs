//! The board on its own (map version 3): the VGA monitor showing the newest
//! frame, attract mode (its first seconds captioned with the board's name
//! and address), keys, switches, LEDs and 7-segment displays. The
//! policy is `rt_services::monitor` (host-tested); this module only puts
//! the frame ring and the accelerator's board I/O block together as the
//! device the policy works on, and logs its report once a second:
//!
//! `display: 59 frames shown, 120 refreshes, layout full, 30 fps, attract on, on screen: light (3072, 4096, 0) from attract mode`

use core::fmt::Write;

use hal_avalon::board::has_board_io;
use hal_avalon::map::Csr;
use hal_avalon::ring_panel::RingPanel;
use hal_avalon::RegisterPort;
use rt_services::monitor::{Monitor, Status};
use rt_services::Instant;

use crate::render::{Frames, Ring, RingEngine};

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
            self.monitor.poll_panel(now, &mut RingPanel::new(ring, engine_port::<P>), status);
            return;
        }
        if let Some(report) = self.monitor.poll(now, &mut RingPanel::new(ring, engine_port::<P>), requests, status) {
            let _ = writeln!(log, "{report}");
        }
    }
}

/// The accelerator's port behind the ring's engine, switched off or not
/// (or the one rendering the ring's rows in row mode), without the
/// bus-access counting (the bench's figures are the frames').
fn engine_port<P: RegisterPort>(engine: &mut RingEngine<P>) -> Option<&mut P> {
    if engine.primary_kept().is_none() {
        // Kept after rows are switched off too (E3 on the displays).
        let rows = engine.fallback().rows().primary_kept()?;
        return Some(rows.inner().accelerator().port_mut().inner_mut());
    }
    let engine = engine.primary_kept()?;
    Some(engine.inner().engine().port_mut().inner_mut())
}

/// The accelerator's port behind the ring ([`engine_port`]).
fn port<P: RegisterPort>(ring: &mut Ring<P>) -> Option<&mut P> {
    engine_port(ring.engine())
}
