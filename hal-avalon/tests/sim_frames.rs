//! Frame mode of the simulated accelerator and of the driver: the bytes in
//! memory, the rows-done counter against the data, errors, and what a frame
//! does to the row registers.

use hal_avalon::map::*;
use hal_avalon::sim::{CountingDelay, DmaTarget, Fault, SimAccelerator};
use hal_avalon::{Accelerator, Error, FrameProgress, PollTimeout, RegisterPort};
use model::Light;

/// Host memory at a bus address, recording how many bytes of each frame
/// row were written (to check the counter against the data), with an
/// optional hole that fails writes.
struct Memory {
    base: u32,
    bytes: Vec<u8>,
    hole: Option<std::ops::Range<u32>>,
}

impl Memory {
    fn new(base: u32, len: usize) -> Memory {
        Memory { base, bytes: vec![0xa5; len], hole: None }
    }
    /// Rows 0..n of a frame at `frame` whose bytes are no longer the fill.
    fn rows_written(&self, frame: u32) -> u16 {
        let start = (frame - self.base) as usize;
        let row = FRAME_ROW_BYTES as usize;
        (0..ROWS).take_while(|y| self.bytes[start + *y as usize * row..][..row].iter().any(|b| *b != 0xa5)).count()
            as u16
    }
}

impl DmaTarget for Memory {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        let end = addr + bytes.len() as u32;
        if self.hole.as_ref().is_some_and(|h| addr < h.end && end > h.start) {
            return false;
        }
        let Some(off) = addr.checked_sub(self.base).map(|o| o as usize) else { return false };
        match self.bytes.get_mut(off..off + bytes.len()) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                true
            }
            None => false,
        }
    }
}

const BASE: u32 = 0x0800_0000;

fn light(x: f64, y: f64, z: f64) -> Light {
    Light::from_world(x, y, z).expect("in range")
}

fn start(sim: &mut SimAccelerator<Memory>, base: u32, l: &Light) {
    for (csr, raw) in [Csr::LightX, Csr::LightY, Csr::LightZ].into_iter().zip(l.raw()) {
        sim.write(csr, light_to_register(raw));
    }
    sim.write(Csr::FrameBase, base);
    sim.write(Csr::FrameControl, FRAME_CONTROL_START);
}

#[test]
fn a_frame_lands_as_the_models_wire_bytes_and_the_counter_never_runs_ahead() {
    for (l, frame) in [(light(3.0, 4.0, -2.0), BASE + 8), (light(-4.0, 6.0, -3.0), BASE + 0x10_0000)] {
        let mut sim = SimAccelerator::with_memory(Memory::new(BASE, 2 << 20), 3);
        sim.set_frame_rows_per_poll(7);
        start(&mut sim, frame, &l);
        assert_eq!(sim.read(Csr::FrameStatus), FRAME_STATUS_BUSY);
        assert_eq!(sim.read(Csr::Status) & STATUS_BUSY, STATUS_BUSY, "STATUS busy during a frame");
        let mut last = 0;
        loop {
            let status = sim.read(Csr::FrameStatus);
            let rows = sim.read(Csr::RowsDone) as u16;
            assert!(rows <= sim.memory().rows_written(frame), "counter ahead of the data");
            assert!(rows >= last, "counter went back");
            last = rows;
            if status & FRAME_STATUS_BUSY == 0 {
                assert_eq!(status, FRAME_STATUS_DONE);
                break;
            }
        }
        assert_eq!(last, ROWS);
        let off = (frame - BASE) as usize;
        let got = &sim.memory().bytes[off..off + FRAME_BYTES as usize];
        assert!(got == &model::render_frame(&l)[..], "frame bytes equal the model's");
        assert_eq!(sim.memory().bytes[off - 1], 0xa5, "nothing before the frame");
        assert_eq!(sim.memory().bytes[off + FRAME_BYTES as usize], 0xa5, "nothing after it");
    }
}

#[test]
fn frame_registers_read_back_and_ignore_what_they_must() {
    let mut sim = SimAccelerator::with_memory(Memory::new(BASE, 1 << 20), 3);
    sim.write(Csr::FrameBase, 0x1234_567f);
    assert_eq!(sim.read(Csr::FrameBase), 0x1234_5678, "bits 2:0 read 0");
    sim.write(Csr::FrameStatus, !0);
    sim.write(Csr::RowsDone, !0);
    assert_eq!((sim.read(Csr::FrameStatus), sim.read(Csr::RowsDone)), (0, 0));
    assert_eq!(sim.read(Csr::FrameControl), 0);
}

#[test]
fn starts_while_busy_are_ignored_and_clear_done_clears() {
    let mut sim = SimAccelerator::with_memory(Memory::new(BASE, 2 << 20), 3);
    let l = light(3.0, 4.0, -2.0);
    start(&mut sim, BASE, &l);
    // Another frame start, elsewhere, and a row start: both ignored.
    sim.write(Csr::FrameBase, BASE + 0x10_0000);
    sim.write(Csr::FrameControl, FRAME_CONTROL_START);
    sim.write(Csr::Control, CONTROL_START);
    while sim.read(Csr::FrameStatus) & FRAME_STATUS_BUSY != 0 {}
    assert_eq!((sim.frames_started(), sim.starts()), (1, 0));
    assert_eq!(sim.memory().rows_written(BASE + 0x10_0000), 0);
    assert_eq!(sim.read(Csr::Status), 0, "no row ran, row done untouched");
    sim.write(Csr::FrameControl, FRAME_CONTROL_CLEAR_DONE);
    assert_eq!(sim.read(Csr::FrameStatus), 0);
    // A row still works after a frame.
    sim.write(Csr::RowY, 12);
    sim.write(Csr::Control, CONTROL_START);
    while sim.read(Csr::Status) & STATUS_BUSY != 0 {}
    let mut line = [0; LINE_WORDS];
    sim.read_line(&mut line);
    let mut want = [0; LINE_WORDS];
    model::render_row(12, &l, &mut want);
    assert_eq!(line, want);
}

#[test]
fn a_failed_write_sets_error_and_freezes_the_count() {
    let mut sim = SimAccelerator::with_memory(Memory::new(BASE, 1 << 20), 3);
    sim.memory_mut().hole = Some(BASE + 100 * FRAME_ROW_BYTES + 10..BASE + 100 * FRAME_ROW_BYTES + 11);
    start(&mut sim, BASE, &light(1.0, 5.0, -1.0));
    while sim.read(Csr::FrameStatus) & FRAME_STATUS_BUSY != 0 {}
    assert_eq!(sim.read(Csr::FrameStatus), FRAME_STATUS_ERROR, "error, not done");
    assert_eq!(sim.read(Csr::RowsDone), 100, "rows before the failure");
    // The next frame clears the error.
    sim.memory_mut().hole = None;
    sim.write(Csr::FrameControl, FRAME_CONTROL_START);
    assert_eq!(sim.read(Csr::FrameStatus) & FRAME_STATUS_ERROR, 0);
}

fn driver(mem: Memory) -> Accelerator<SimAccelerator<Memory>, CountingDelay> {
    Accelerator::new(SimAccelerator::with_memory(mem, 2), CountingDelay::default(), PollTimeout::DEFAULT)
}

#[test]
fn the_driver_runs_frames_and_reports_progress() {
    let mut accel = driver(Memory::new(BASE, 1 << 20));
    assert!(accel.probe().unwrap().frames());
    let l = light(2.0, 1.0, -2.5);
    assert_eq!(accel.start_frame(BASE + 4, &l), Err(Error::FrameBaseMisaligned { base: BASE + 4 }));
    accel.start_frame(BASE, &l).unwrap();
    let mut seen = Vec::new();
    let done = loop {
        let p = accel.frame_progress().unwrap();
        seen.push(p.rows);
        if p.done {
            break p;
        }
        assert!(seen.len() < 1000, "the frame finishes");
    };
    assert_eq!(done, FrameProgress { rows: 360, done: true });
    assert!(seen.windows(2).all(|w| w[0] <= w[1]));
    assert!(accel.port().memory().bytes[..FRAME_BYTES as usize] == model::render_frame(&l)[..]);
}

#[test]
fn the_driver_reports_dma_errors_and_vanished_devices() {
    let mut mem = Memory::new(BASE, 1 << 20);
    mem.hole = Some(BASE + 200 * FRAME_ROW_BYTES..BASE + 200 * FRAME_ROW_BYTES + 1);
    let mut accel = driver(mem);
    accel.start_frame(BASE, &light(3.0, 4.0, -2.0)).unwrap();
    let err = loop {
        match accel.frame_progress() {
            Ok(p) => assert!(!p.done),
            Err(e) => break e,
        }
    };
    assert_eq!(err, Error::DmaError { rows: 200 });

    let mut accel = driver(Memory::new(BASE, 1 << 20));
    accel.start_frame(BASE, &light(3.0, 4.0, -2.0)).unwrap();
    accel.port_mut().set_fault(Some(Fault::Absent));
    assert!(matches!(accel.frame_progress(), Err(Error::BusFault { value: 0xFFFF_FFFF, .. })));
    // A stuck frame makes the next start wait, bounded.
    accel.port_mut().set_fault(Some(Fault::StuckBusy));
    assert!(matches!(accel.start_frame(BASE, &light(3.0, 4.0, -2.0)), Err(Error::Timeout { .. })));
}

#[test]
fn the_driver_aborts_a_frame_and_waits_for_idle_bounded() {
    let mut accel = driver(Memory::new(BASE, 1 << 20));
    assert_eq!(accel.abort_frame(), Ok(()), "nothing to stop");
    let l = light(3.0, 4.0, -2.0);
    accel.start_frame(BASE, &l).unwrap();
    let rows = accel.frame_progress().unwrap().rows;
    assert!(rows > 0 && rows < 360);
    assert_eq!(accel.abort_frame(), Ok(()));
    assert_eq!(accel.port_mut().read(Csr::FrameStatus), FRAME_STATUS_ABORTED, "idle, aborted");
    let Err(Error::FrameAborted { rows: kept }) = accel.frame_progress() else { panic!("aborted") };
    assert!(kept >= rows && kept < 360, "ROWS_DONE {kept} kept");
    assert_eq!(accel.port().memory().rows_written(BASE), kept, "nothing landed after the abort");
    // A device that ignores the abort: a bounded wait, then a timeout.
    accel.start_frame(BASE, &l).unwrap();
    accel.port_mut().set_fault(Some(Fault::StuckBusy));
    assert!(matches!(accel.abort_frame(), Err(Error::Timeout { .. })));
    accel.port_mut().set_fault(None);
    assert_eq!(accel.abort_frame(), Ok(()), "works once the device recovers");
}

#[test]
fn pipelined_rows_start_the_next_row_before_returning_this_one() {
    use hal_avalon::sources::PipelinedRows;
    use rt_services::RowSource;
    let accel = Accelerator::new(
        hal_avalon::Counted::new(SimAccelerator::new()),
        CountingDelay::default(),
        PollTimeout::DEFAULT,
    );
    let mut rows = PipelinedRows::new(accel);
    let (a, b) = (light(3.0, 4.0, -2.0), light(-1.0, 2.0, 1.0));
    let (mut got, mut want) = ([0u32; LINE_WORDS], [0u32; LINE_WORDS]);
    for y in 0..5 {
        rows.render_row(y, &a, &mut got).unwrap();
        model::render_row(y, &a, &mut want);
        assert_eq!(got, want, "row {y}");
        assert!(rows.accelerator().port().inner().is_busy(), "row {} already started", y + 1);
    }
    assert_eq!(rows.accelerator().port().inner().starts(), 6, "rows 0..=5 started, each once");
    // On the bus: the light once, then ROW_Y and a start per row; each line
    // read in one burst of 480 words; a few STATUS reads, no ID probe.
    let port = rows.accelerator().port();
    assert_eq!(port.writes, 3 + 2 * 6, "light once, two writes per row");
    assert_eq!(port.line_words, 5 * 480);
    // STATUS: one "not busy" read per start, then the finish polls until
    // done (the simulated row stays busy for DEFAULT_BUSY_POLLS reads).
    let per_finish = hal_avalon::sim::DEFAULT_BUSY_POLLS + 1;
    assert_eq!(port.reads, 6 + 5 * per_finish, "STATUS reads only");
    // Another light: the row started ahead is let finish, then this one runs.
    rows.render_row(9, &b, &mut got).unwrap();
    model::render_row(9, &b, &mut want);
    assert_eq!(got, want);
    // The last row starts nothing after it.
    rows.render_row(359, &b, &mut got).unwrap();
    assert!(!rows.accelerator().port().inner().is_busy());
}
