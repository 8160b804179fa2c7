//! The row driver over the simulated accelerator: whole frames against the
//! model, the protocol on the bus, every error path and its bound.

use hal_avalon::map::{line_word_offset, Csr, CONTROL_START, ID_VERSION, LINE_WORDS, ROWS, STATUS_BUSY};
use hal_avalon::sim::{CountingDelay, Fault, SimAccelerator, LINE_POISON};
use hal_avalon::{Accelerator, Capabilities, Error, PollTimeout, RegisterPort};
use model::light::Axis;
use model::Light;

type SimDriver = Accelerator<SimAccelerator, CountingDelay>;

const MAX_POLLS: u32 = 40;
const INTERVAL_NS: u32 = 1_500;

fn driver(busy_polls: u32) -> SimDriver {
    Accelerator::new(
        SimAccelerator::with_busy_polls(busy_polls),
        CountingDelay::default(),
        PollTimeout::new(MAX_POLLS, INTERVAL_NS),
    )
}

fn model_row(y: u16, l: &Light) -> [u32; LINE_WORDS] {
    let mut row = [0; LINE_WORDS];
    model::render_row(y, l, &mut row);
    row
}

fn light(x: i32, y: i32, z: i32) -> Light {
    Light::from_raw(x, y, z).expect("test light in range")
}

/// Lights with every sign in the LIGHT registers, near and far.
fn lights() -> [Light; 3] {
    [
        light(3 << 10, 4 << 10, -(2 << 10)),
        light(-(5 << 10) - 317, 6 << 10, 7 << 10),
        light(-8_000_000, 8_388_607, -8_388_608),
    ]
}

#[test]
fn every_row_of_several_frames_matches_the_model() {
    let mut accel = driver(0);
    let mut row = [0; LINE_WORDS];
    let mut rows_run = 0;
    for (i, l) in lights().iter().enumerate() {
        for y in 0..ROWS {
            // Vary how long the device stays busy: 0..=4 polls.
            accel.port_mut().set_busy_polls((u32::from(y) + i as u32) % 5);
            row.fill(0x5A5A_5A5A);
            accel.run_row(y, l, &mut row).unwrap_or_else(|e| panic!("row {y}: {e}"));
            assert!(row == model_row(y, l), "light {i} row {y} differs from the model");
            rows_run += 1;
        }
    }
    assert_eq!(accel.port().starts(), rows_run);
    assert_eq!(accel.port().rows_finished(), rows_run);
}

#[test]
fn raw_lights_are_checked_then_rendered() {
    let mut accel = driver(2);
    let mut row = [0; LINE_WORDS];
    for (raw, axis) in [
        ([1 << 23, 0, 0], Axis::X),
        ([0, -(1 << 23) - 1, 0], Axis::Y),
        ([0, 0, i32::MAX], Axis::Z),
        ([i32::MIN, i32::MIN, i32::MIN], Axis::X),
    ] {
        match accel.run_row_raw(10, raw, &mut row) {
            Err(Error::LightOutOfRange(e)) => assert_eq!(e.axis, axis, "{raw:?}"),
            other => panic!("{raw:?}: {other:?}"),
        }
    }
    // Nothing reached the device.
    assert_eq!(accel.port_mut().read(Csr::LightZ), 0);
    assert_eq!((accel.port().status_reads(), accel.port().starts()), (0, 0));

    let raw = [-(1 << 23), (1 << 23) - 1, -1];
    accel.run_row_raw(301, raw, &mut row).unwrap();
    assert_eq!(row, model_row(301, &light(raw[0], raw[1], raw[2])));
}

#[test]
fn rows_past_the_frame_are_refused_before_any_access() {
    let mut accel = driver(2);
    let mut row = [7; LINE_WORDS];
    for y in [ROWS, 361, 511, 512, u16::MAX] {
        assert_eq!(accel.run_row(y, &lights()[0], &mut row), Err(Error::RowOutOfRange { row_y: y }));
        assert_eq!(accel.run_row_raw(y, [1 << 30, 0, 0], &mut row), Err(Error::RowOutOfRange { row_y: y }));
    }
    assert_eq!(row, [7; LINE_WORDS]);
    assert_eq!((accel.port().status_reads(), accel.port().starts()), (0, 0));
    assert_eq!(accel.port_mut().read(Csr::RowY), 0);
}

#[test]
fn absent_device_is_not_present_and_rows_fail_without_writes() {
    let mut accel = driver(2);
    accel.port_mut().set_fault(Some(Fault::Absent));
    let mut row = [0; LINE_WORDS];
    assert_eq!(accel.probe(), Err(Error::NotPresent { id: 0xFFFF_FFFF }));
    // No ID read per row: the vanished device shows in STATUS, before any write.
    assert_eq!(
        accel.run_row(5, &lights()[1], &mut row),
        Err(Error::BusFault { offset: Csr::Status.offset(), value: 0xFFFF_FFFF })
    );
    assert_eq!(accel.port().status_reads(), 1);
    assert_eq!(accel.delay().calls, 0);
    // Once the fabric is configured, the same driver works.
    accel.port_mut().set_fault(None);
    assert_eq!(accel.probe(), Ok(Capabilities { version: ID_VERSION }));
    accel.run_row(5, &lights()[1], &mut row).unwrap();
    assert_eq!(row, model_row(5, &lights()[1]));
    assert_eq!(accel.port().starts(), 1, "the failed row never started");
}

/// A port that reads a different ID: another design, or another version.
struct OtherId(SimAccelerator, u32);

impl RegisterPort for OtherId {
    fn read(&mut self, csr: Csr) -> u32 {
        match csr {
            Csr::Id => self.1,
            _ => self.0.read(csr),
        }
    }
    fn write(&mut self, csr: Csr, value: u32) {
        self.0.write(csr, value)
    }
    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        self.0.read_line(out)
    }
}

#[test]
fn id_mismatch_is_not_present_and_version_1_has_no_frames() {
    for id in [0, 0x5254_0000, 0x5255_0001, 0x0001_5254, 0xFFFF_FFFF] {
        let mut accel =
            Accelerator::new(OtherId(SimAccelerator::new(), id), CountingDelay::default(), PollTimeout::DEFAULT);
        assert_eq!(accel.probe(), Err(Error::NotPresent { id }));
        assert_eq!(accel.port().0.status_reads(), 0);
        assert_eq!(accel.port_mut().0.read(Csr::RowY), 0, "nothing written");
    }
    let mut v1 =
        Accelerator::new(OtherId(SimAccelerator::new(), 0x5254_0001), CountingDelay::default(), PollTimeout::DEFAULT);
    let caps = v1.probe().unwrap();
    assert_eq!((caps.version, caps.frames()), (1, false));
    assert_eq!(v1.start_frame(0x1000, &lights()[0]), Err(Error::NoFrameMode { version: 1 }));
    let mut row = [0; LINE_WORDS];
    v1.run_row(7, &lights()[0], &mut row).unwrap();
    assert_eq!(row, model_row(7, &lights()[0]), "version 1 still renders rows");
}

#[test]
fn stuck_busy_times_out_within_the_bound_and_recovers() {
    let mut accel = driver(5);
    let mut row = [0; LINE_WORDS];
    accel.port_mut().set_fault(Some(Fault::StuckBusy));

    // One idle check, then MAX_POLLS polls for done, MAX_POLLS - 1 delays between them.
    let l = lights()[0];
    assert_eq!(accel.run_row(100, &l, &mut row), Err(Error::Timeout { status: STATUS_BUSY }));
    assert_eq!(accel.port().status_reads(), 1 + MAX_POLLS);
    assert_eq!(accel.delay().calls, MAX_POLLS - 1);
    assert_eq!(accel.delay().total_ns, u64::from((MAX_POLLS - 1) * INTERVAL_NS));
    assert_eq!(accel.port().starts(), 1);

    // Still stuck: the driver waits for the old row, bounded, and does not
    // start over it.
    assert_eq!(accel.run_row(200, &l, &mut row), Err(Error::Timeout { status: STATUS_BUSY }));
    assert_eq!(accel.port().status_reads(), 1 + 2 * MAX_POLLS);
    assert_eq!(accel.port().starts(), 1);

    // The device recovers with the old row (100) still in progress: the next
    // call must deliver its own row, not the old one.
    accel.port_mut().set_fault(None);
    accel.run_row(200, &l, &mut row).unwrap();
    assert_eq!(row, model_row(200, &l));
    assert_ne!(row, model_row(100, &l));
    assert_eq!(accel.port().starts(), 2);
}

#[test]
fn slow_device_times_out_then_the_next_call_works() {
    let mut accel = driver(MAX_POLLS + 10);
    let mut row = [0; LINE_WORDS];
    let l = lights()[2];
    assert_eq!(accel.run_row(7, &l, &mut row), Err(Error::Timeout { status: STATUS_BUSY }));
    accel.port_mut().set_busy_polls(3);
    accel.run_row(8, &l, &mut row).unwrap();
    assert_eq!(row, model_row(8, &l));
}

#[test]
fn done_never_set_times_out_within_the_bound_and_recovers() {
    let mut accel = driver(4);
    let mut row = [0; LINE_WORDS];
    let l = lights()[1];
    accel.port_mut().set_fault(Some(Fault::DoneNeverSet));
    // Busy clears after 4 polls but done never comes.
    assert_eq!(accel.run_row(50, &l, &mut row), Err(Error::Timeout { status: 0 }));
    assert_eq!(accel.port().status_reads(), 1 + MAX_POLLS);
    assert_eq!(accel.delay().calls, MAX_POLLS - 1);
    assert_eq!(accel.port().rows_finished(), 1);

    accel.port_mut().set_fault(None);
    accel.run_row(51, &l, &mut row).unwrap();
    assert_eq!(row, model_row(51, &l));
}

#[test]
fn smallest_timeout_is_one_poll() {
    assert_eq!(PollTimeout::new(0, 5).max_polls(), 1);
    let mut accel =
        Accelerator::new(SimAccelerator::with_busy_polls(1), CountingDelay::default(), PollTimeout::new(0, 5));
    let mut row = [0; LINE_WORDS];
    assert_eq!(accel.run_row(1, &lights()[0], &mut row), Err(Error::Timeout { status: STATUS_BUSY }));
    assert_eq!(accel.port().status_reads(), 2);
    assert_eq!(accel.delay().calls, 0);
    // A device that is done on its first poll fits in one poll.
    accel.port_mut().set_busy_polls(0);
    accel.run_row(2, &lights()[0], &mut row).unwrap();
    assert_eq!(row, model_row(2, &lights()[0]));
}

/// Records every register access in order; optionally turns the device
/// absent right after a start, or corrupts one line-buffer word.
struct Probe {
    sim: SimAccelerator,
    log: Vec<(char, Csr, u32)>,
    vanish_after_start: bool,
    corrupt_word: Option<(usize, u32)>,
}

impl Probe {
    fn new(sim: SimAccelerator) -> Probe {
        Probe { sim, log: Vec::new(), vanish_after_start: false, corrupt_word: None }
    }
}

impl RegisterPort for Probe {
    fn read(&mut self, csr: Csr) -> u32 {
        let v = self.sim.read(csr);
        self.log.push(('R', csr, v));
        v
    }
    fn write(&mut self, csr: Csr, value: u32) {
        self.log.push(('W', csr, value));
        self.sim.write(csr, value);
        if self.vanish_after_start && csr == Csr::Control && value & CONTROL_START != 0 {
            self.sim.set_fault(Some(Fault::Absent));
        }
    }
    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        self.sim.read_line(out);
        if let Some((x, v)) = self.corrupt_word {
            out[x] = v;
        }
    }
}

#[test]
fn protocol_on_the_bus() {
    let mut accel = Accelerator::new(
        Probe::new(SimAccelerator::with_busy_polls(2)),
        CountingDelay::default(),
        PollTimeout::DEFAULT,
    );
    let l = light(-1, 1 << 10, -(1 << 23));
    let mut row = [0; LINE_WORDS];
    accel.run_row(359, &l, &mut row).unwrap();
    use Csr::*;
    // No ID read: the driver probes once, not per row.
    let expected = [
        ('R', Status, 0),
        ('W', RowY, 359),
        ('W', LightX, 0x00FF_FFFF),
        ('W', LightY, 0x0000_0400),
        ('W', LightZ, 0x0080_0000),
        ('W', Control, CONTROL_START),
        ('R', Status, STATUS_BUSY),
        ('R', Status, STATUS_BUSY),
        ('R', Status, hal_avalon::map::STATUS_DONE),
    ];
    assert_eq!(accel.port().log, expected);
    assert_eq!(row, model_row(359, &l));
    assert_eq!(accel.delay().calls, 2);

    // A second row of the same light starts with done still set from the
    // first: ROW_Y and the start (which clears done) only, no light writes,
    // and the new row (not the stale one) comes back.
    accel.port_mut().log.clear();
    accel.run_row(0, &l, &mut row).unwrap();
    assert_eq!(
        accel.port().log[..3],
        [('R', Status, hal_avalon::map::STATUS_DONE), ('W', RowY, 0), ('W', Control, CONTROL_START)]
    );
    assert_eq!(row, model_row(0, &l));

    // A new light is written; after an error it is written again.
    let other = light(5, 6, 7);
    accel.port_mut().log.clear();
    accel.run_row(1, &other, &mut row).unwrap();
    assert_eq!(accel.port().log.iter().filter(|(rw, ..)| *rw == 'W').count(), 5, "ROW_Y, 3 lights, start");
    accel.port_mut().sim.set_fault(Some(hal_avalon::sim::Fault::StuckBusy));
    assert!(accel.run_row(2, &other, &mut row).is_err());
    accel.port_mut().sim.set_fault(None);
    accel.port_mut().sim.reset();
    accel.port_mut().log.clear();
    accel.run_row(2, &other, &mut row).unwrap();
    assert_eq!(
        accel.port().log.iter().filter(|(rw, ..)| *rw == 'W').count(),
        5,
        "light written again after the timeout"
    );
    assert_eq!(row, model_row(2, &other));
}

#[test]
fn device_vanishing_mid_row_is_a_bus_fault() {
    let mut probe = Probe::new(SimAccelerator::with_busy_polls(2));
    probe.vanish_after_start = true;
    let mut accel = Accelerator::new(probe, CountingDelay::default(), PollTimeout::DEFAULT);
    let mut row = [0; LINE_WORDS];
    assert_eq!(accel.run_row(3, &lights()[0], &mut row), Err(Error::BusFault { offset: 0x04, value: 0xFFFF_FFFF }));
    // It stopped at the first bad STATUS: no polling on garbage.
    assert_eq!(accel.port().sim.status_reads(), 2);
    assert_eq!(accel.delay().calls, 0);
}

#[test]
fn corrupt_line_word_is_a_bus_fault() {
    let mut probe = Probe::new(SimAccelerator::with_busy_polls(1));
    probe.corrupt_word = Some((17, 0xFFFF_FFFF));
    let mut accel = Accelerator::new(probe, CountingDelay::default(), PollTimeout::DEFAULT);
    let mut row = [0; LINE_WORDS];
    assert_eq!(
        accel.run_row(3, &lights()[0], &mut row),
        Err(Error::BusFault { offset: line_word_offset(17), value: 0xFFFF_FFFF })
    );
}

/// Hardware (or a driver) that reports done too early: the STATUS read is
/// faked as done while the device is still busy.
struct DoneTooEarly(SimAccelerator);

impl RegisterPort for DoneTooEarly {
    fn read(&mut self, csr: Csr) -> u32 {
        let v = self.0.read(csr);
        match csr {
            Csr::Status if v & STATUS_BUSY != 0 => hal_avalon::map::STATUS_DONE,
            _ => v,
        }
    }
    fn write(&mut self, csr: Csr, value: u32) {
        self.0.write(csr, value)
    }
    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        self.0.read_line(out)
    }
}

#[test]
fn premature_line_buffer_read_is_caught_by_the_poison() {
    let l = lights()[0];

    // A protocol that forgets to wait reads poison, never the row.
    let mut sim = SimAccelerator::with_busy_polls(3);
    sim.write(Csr::RowY, 150);
    sim.write(Csr::Control, CONTROL_START);
    let mut early = [0; LINE_WORDS];
    sim.read_line(&mut early);
    let expected = model_row(150, &l);
    for (x, (got, good)) in early.iter().zip(expected.iter()).enumerate() {
        assert_eq!(*got, LINE_POISON | x as u32);
        assert_ne!(got, good, "poison equals the model at x = {x}");
    }

    // Through the driver, a done that comes too early is reported, not
    // returned as a row.
    let mut accel = Accelerator::new(
        DoneTooEarly(SimAccelerator::with_busy_polls(3)),
        CountingDelay::default(),
        PollTimeout::DEFAULT,
    );
    let mut row = [0; LINE_WORDS];
    assert_eq!(
        accel.run_row(150, &l, &mut row),
        Err(Error::BusFault { offset: line_word_offset(0), value: LINE_POISON })
    );
}

#[test]
fn errors_display() {
    let e = Error::NotPresent { id: 0xFFFF_FFFF };
    assert!(e.to_string().contains("0xffffffff"), "{e}");
    assert!(Error::RowOutOfRange { row_y: 360 }.to_string().contains("360"));
    assert!(Error::Timeout { status: 1 }.to_string().contains("timed out"));
}
