//! The MMIO register block over ordinary memory: every register and
//! line-buffer word lands at the offset of the register map, and the driver
//! runs unchanged over it.

use hal_avalon::map::{line_word_offset, Csr, ID_VALUE, LINE_WORDS, STATUS_DONE};
use hal_avalon::mmio::RegisterBlock;
use hal_avalon::{Accelerator, MmioPort, PollTimeout, RegisterPort};

/// Words covering the whole register block.
const WORDS: usize = core::mem::size_of::<RegisterBlock>() / 4;

struct NoDelay;

impl embedded_hal::delay::DelayNs for NoDelay {
    fn delay_ns(&mut self, _ns: u32) {}
}

/// A leaked, zeroed memory range standing in for the bridge window.
fn fake_window() -> (*mut u32, MmioPort) {
    let mem: &'static mut [u32] = Vec::leak(vec![0u32; WORDS]);
    let base = mem.as_mut_ptr();
    // SAFETY: `base` is 4-byte aligned, `WORDS` words long and leaked (lives
    // for the rest of the test); the test touches it only through volatile
    // accesses via `MmioPort` and `word`/`set_word`.
    let mmio = unsafe { MmioPort::new(base as usize) };
    (base, mmio)
}

fn word(base: *mut u32, offset: usize) -> u32 {
    assert!(offset / 4 < WORDS);
    // SAFETY: in bounds of the leaked range (checked above).
    unsafe { base.add(offset / 4).read_volatile() }
}

fn set_word(base: *mut u32, offset: usize, value: u32) {
    assert!(offset / 4 < WORDS);
    // SAFETY: in bounds of the leaked range (checked above).
    unsafe { base.add(offset / 4).write_volatile(value) }
}

#[test]
fn register_block_size_ends_with_the_line_buffer() {
    assert_eq!(WORDS * 4, line_word_offset(LINE_WORDS));
}

#[test]
fn writes_land_at_their_offsets() {
    let (base, mut mmio) = fake_window();
    let writable = [Csr::Control, Csr::RowY, Csr::LightX, Csr::LightY, Csr::LightZ, Csr::FrameBase, Csr::FrameControl];
    for (i, csr) in writable.into_iter().enumerate() {
        let value = 0x1111_0000 + i as u32;
        mmio.write(csr, value);
        assert_eq!(word(base, csr.offset()), value, "{csr:?}");
    }
    // Read-only registers are not written.
    for csr in [Csr::Status, Csr::Id, Csr::FrameStatus, Csr::RowsDone] {
        mmio.write(csr, 0xDEAD);
        assert_eq!(word(base, csr.offset()), 0, "{csr:?}");
    }
}

#[test]
fn reads_come_from_their_offsets() {
    let (base, mut mmio) = fake_window();
    for csr in Csr::ALL {
        set_word(base, csr.offset(), 0xA000_0000 | csr.offset() as u32);
    }
    for csr in Csr::ALL {
        let write_only = matches!(csr, Csr::Control | Csr::FrameControl);
        let expected = if write_only { 0 } else { 0xA000_0000 | csr.offset() as u32 };
        assert_eq!(mmio.read(csr), expected, "{csr:?}");
    }
    for x in 0..LINE_WORDS {
        set_word(base, line_word_offset(x), 0x0010_0000 + x as u32);
    }
    let mut line = [0; LINE_WORDS];
    mmio.read_line(&mut line);
    for (x, w) in line.iter().enumerate() {
        assert_eq!(*w, 0x0010_0000 + x as u32);
    }
}

#[test]
fn driver_runs_over_mmio() {
    let (base, mmio) = fake_window();
    let light = model::Light::from_raw(-3 << 10, 5 << 10, 2 << 10).expect("in range");
    let mut expected = [0; LINE_WORDS];
    model::render_row(77, &light, &mut expected);
    // Memory does not render: pose as a device that has just finished row 77.
    set_word(base, Csr::Id.offset(), ID_VALUE);
    set_word(base, Csr::Status.offset(), STATUS_DONE);
    for (x, w) in expected.iter().enumerate() {
        set_word(base, line_word_offset(x), *w);
    }
    let mut accel = Accelerator::new(mmio, NoDelay, PollTimeout::DEFAULT);
    let mut row = [0; LINE_WORDS];
    accel.run_row(77, &light, &mut row).expect("row");
    assert_eq!(row, expected);
    assert_eq!(word(base, Csr::RowY.offset()), 77);
    assert_eq!(word(base, Csr::LightX.offset()), 0x00FF_F400);
    assert_eq!(word(base, Csr::LightY.offset()), 5 << 10);
    // The last CONTROL write was the start.
    assert_eq!(word(base, Csr::Control.offset()), 1);
}
