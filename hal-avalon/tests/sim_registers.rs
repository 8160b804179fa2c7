//! What only the simulated accelerator has: its timing (busy for exactly
//! the configured polls), the poisoned line buffer, fault injection and
//! reset keeping the configuration. The register semantics every device
//! shares are `hal_avalon::conformance` (tests/conformance_sim.rs).

use hal_avalon::map::*;
use hal_avalon::sim::{Fault, SimAccelerator, LINE_POISON};
use hal_avalon::RegisterPort;
use model::Light;

const CONTROL: usize = CSR_OFFSET; // + 0x00
const STATUS: usize = CSR_OFFSET + 0x04;
const ROW_Y: usize = CSR_OFFSET + 0x08;
const LIGHT: [usize; 3] = [CSR_OFFSET + 0x0C, CSR_OFFSET + 0x10, CSR_OFFSET + 0x14];
const ID: usize = CSR_OFFSET + 0x18;

fn light(x: i32, y: i32, z: i32) -> Light {
    Light::from_raw(x, y, z).expect("test light in range")
}

fn model_row(y: u16, l: &Light) -> [u32; LINE_WORDS] {
    let mut row = [0; LINE_WORDS];
    model::render_row(y, l, &mut row);
    row
}

fn read_line(sim: &mut SimAccelerator) -> [u32; LINE_WORDS] {
    let mut row = [0; LINE_WORDS];
    for (x, w) in row.iter_mut().enumerate() {
        *w = sim.bus_read(line_word_offset(x));
    }
    row
}

fn program(sim: &mut SimAccelerator, y: u32, l: &Light) {
    sim.bus_write(ROW_Y, y);
    for (off, raw) in LIGHT.into_iter().zip(l.raw()) {
        sim.bus_write(off, raw as u32);
    }
}

/// Poll STATUS until it is not busy; returns (busy reads seen, final status).
fn run_to_idle(sim: &mut SimAccelerator) -> (u32, u32) {
    let mut busy_reads = 0;
    loop {
        let s = sim.bus_read(STATUS);
        assert_eq!(s & !STATUS_MASK, 0, "reserved STATUS bits read {s:#x}");
        assert_ne!(s, STATUS_BUSY | STATUS_DONE, "busy and done both set");
        if s & STATUS_BUSY == 0 {
            return (busy_reads, s);
        }
        busy_reads += 1;
        assert!(busy_reads < 10_000, "never finished");
    }
}

/// A device that has finished one row and holds done.
fn device_with_done() -> SimAccelerator {
    let mut sim = SimAccelerator::with_busy_polls(2);
    program(&mut sim, 10, &light(0, 4096, 0));
    sim.bus_write(CONTROL, CONTROL_START);
    assert_eq!(run_to_idle(&mut sim), (2, STATUS_DONE));
    sim
}

#[test]
fn line_buffer_reads_zero_after_reset() {
    let mut sim = SimAccelerator::new();
    assert_eq!(read_line(&mut sim), [0; LINE_WORDS]);
}

#[test]
fn start_sets_busy_for_exactly_the_configured_polls_then_done() {
    for polls in [0, 1, 2, 7, 50] {
        let mut sim = SimAccelerator::with_busy_polls(polls);
        sim.bus_write(CONTROL, CONTROL_START);
        assert!(sim.is_busy());
        assert_eq!(run_to_idle(&mut sim), (polls, STATUS_DONE), "busy polls {polls}");
        assert_eq!((sim.starts(), sim.rows_finished()), (1, 1));
    }
}

#[test]
fn status_reserved_bits_read_zero_and_writes_are_ignored() {
    let mut sim = SimAccelerator::with_busy_polls(3);
    sim.bus_write(STATUS, 0xFFFF_FFFF);
    assert_eq!(sim.bus_read(STATUS), 0);
    sim.bus_write(CONTROL, CONTROL_START);
    sim.bus_write(STATUS, 0);
    assert_eq!(sim.bus_read(STATUS), STATUS_BUSY);
    assert_eq!(run_to_idle(&mut sim), (2, STATUS_DONE));
    sim.bus_write(STATUS, 0);
    assert_eq!(sim.bus_read(STATUS), STATUS_DONE);
}

#[test]
fn start_while_busy_is_ignored_completely() {
    let l = light(1024, 5120, -1024);
    let mut sim = SimAccelerator::with_busy_polls(6);
    program(&mut sim, 200, &l);
    sim.bus_write(CONTROL, CONTROL_START);
    assert_eq!(sim.bus_read(STATUS), STATUS_BUSY); // 1 of 6
    assert_eq!(sim.bus_read(STATUS), STATUS_BUSY); // 2 of 6
    program(&mut sim, 17, &light(0, 0, 0));
    sim.bus_write(CONTROL, CONTROL_START);
    sim.bus_write(CONTROL, CONTROL_START | CONTROL_CLEAR_DONE);
    assert_eq!(sim.starts(), 1);
    // No restart: the row finishes after its original 6 busy polls.
    assert_eq!(run_to_idle(&mut sim), (4, STATUS_DONE));
    assert_eq!(sim.rows_finished(), 1);
    assert_eq!(read_line(&mut sim), model_row(200, &l));
}

#[test]
fn line_buffer_is_poisoned_while_busy() {
    let l = light(-3000, 2000, 1000);
    let mut sim = SimAccelerator::with_busy_polls(2);
    program(&mut sim, 180, &l);
    sim.bus_write(CONTROL, CONTROL_START);
    for _ in 0..3 {
        let line = read_line(&mut sim);
        for (x, w) in line.iter().enumerate() {
            assert_eq!(*w, LINE_POISON | x as u32);
            assert_ne!(*w & PIXEL_RESERVED_MASK, 0);
        }
        // Advance one poll; the third round reads after done.
        if sim.bus_read(STATUS) & STATUS_BUSY == 0 {
            break;
        }
    }
    assert_eq!(run_to_idle(&mut sim).1, STATUS_DONE);
    let line = read_line(&mut sim);
    assert_eq!(line, model_row(180, &l));
    assert!(line.iter().all(|w| w & PIXEL_RESERVED_MASK == 0));
}

#[test]
fn absent_device_reads_all_ones_and_loses_writes() {
    let mut sim = SimAccelerator::new();
    sim.set_fault(Some(Fault::Absent));
    for off in [CONTROL, STATUS, ROW_Y, ID, 0x1C, line_word_offset(0), line_word_offset(479)] {
        assert_eq!(sim.bus_read(off), 0xFFFF_FFFF, "offset {off:#x}");
    }
    sim.bus_write(ROW_Y, 5);
    sim.bus_write(CONTROL, CONTROL_START);
    sim.set_fault(None);
    assert_eq!(sim.bus_read(ROW_Y), 0);
    assert_eq!(sim.bus_read(STATUS), 0);
    assert_eq!(sim.starts(), 0);
}

#[test]
fn stuck_busy_holds_until_cleared_then_runs_on() {
    let mut sim = SimAccelerator::with_busy_polls(3);
    sim.bus_write(CONTROL, CONTROL_START);
    assert_eq!(sim.bus_read(STATUS), STATUS_BUSY); // 1 of 3 counted
    sim.set_fault(Some(Fault::StuckBusy));
    for _ in 0..1000 {
        assert_eq!(sim.bus_read(STATUS), STATUS_BUSY);
    }
    sim.set_fault(None);
    assert_eq!(run_to_idle(&mut sim), (2, STATUS_DONE));
}

#[test]
fn done_never_set_still_finishes_the_row() {
    let l = light(0, 8192, 0);
    let mut sim = SimAccelerator::with_busy_polls(2);
    sim.set_fault(Some(Fault::DoneNeverSet));
    program(&mut sim, 90, &l);
    sim.bus_write(CONTROL, CONTROL_START);
    assert_eq!(run_to_idle(&mut sim), (2, 0));
    assert_eq!(sim.bus_read(STATUS), 0);
    assert_eq!(read_line(&mut sim), model_row(90, &l));
}

#[test]
fn reset_restores_power_on_state_and_keeps_configuration() {
    let mut sim = device_with_done();
    sim.set_busy_polls(9);
    program(&mut sim, 44, &light(1, 2, 3));
    sim.reset();
    assert_eq!(sim.bus_read(STATUS), 0);
    assert_eq!(sim.bus_read(ROW_Y), 0);
    assert_eq!(LIGHT.map(|o| sim.bus_read(o)), [0; 3]);
    assert_eq!(read_line(&mut sim), [0; LINE_WORDS]);
    assert_eq!(sim.busy_polls(), 9);
    sim.bus_write(CONTROL, CONTROL_START);
    assert_eq!(run_to_idle(&mut sim), (9, STATUS_DONE));
}

#[test]
fn build_id_reads_what_the_bitstream_was_built_with_and_ignores_writes() {
    let mut sim = SimAccelerator::new();
    assert_eq!(sim.read(Csr::BuildId), 0, "none recorded");
    sim.set_build_id(0x0012_3abc);
    sim.write(Csr::BuildId, 0);
    assert_eq!(sim.read(Csr::BuildId), 0x0012_3abc);
    sim.reset();
    assert_eq!(sim.read(Csr::BuildId), 0x0012_3abc, "a synthesis parameter survives reset");
}
