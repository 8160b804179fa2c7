//! One register-semantics suite for every device behind the register map:
//! the simulated accelerator ([`crate::sim`]) and the Verilated RTL (the
//! `rtl-port` crate) run these same checks, so the two can only agree or
//! fail a test. Raw bus accesses, no driver.
//!
//! A device implements [`Device`]; [`conformance_tests!`] expands to one
//! `#[test]` per check. The checks hold for any timing: they poll STATUS
//! or FRAME_STATUS until a row or frame is over, and only ask for what the
//! register map promises (src/map.rs), never for the simulated device's
//! poll counts or poison patterns.
//!
//! Frame checks write into a [`TestMemory`] window at [`MEMORY_BASE`].

extern crate std;

use std::vec;
use std::vec::Vec;

use model::{Light, FRAME_BYTES, ROW_BYTES};

use crate::map::*;
use crate::sim::DmaTarget;

/// What the suite needs from a device.
pub trait Device {
    /// A 32-bit read at byte `offset` of the bridge window.
    fn bus_read(&mut self, offset: usize) -> u32;
    /// A 32-bit write at byte `offset` of the bridge window.
    fn bus_write(&mut self, offset: usize, value: u32);
    /// The frame DMA's memory.
    fn memory(&mut self) -> &mut TestMemory;
    /// Drive the board's input pins: `keys` held down (bit n: KEYn
    /// pressed), `switches` (bit n: SWn up).
    fn set_board_inputs(&mut self, keys: u8, switches: u16);
    /// The board's output pins: LEDR9..0 (1 = lit) and each 7-segment
    /// display's segment pins (active low: 0 = lit), HEX0 first.
    fn board_outputs(&mut self) -> BoardPins;
    /// Let `clocks` fabric clocks pass with the bus idle.
    fn pass_clocks(&mut self, clocks: u32);
}

/// The board's output pins as a [`Device`] drives them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardPins {
    /// LEDR9..LEDR0, 1 = lit.
    pub ledr: u16,
    /// HEX0..HEX5 segment pins, bit s = segment s, active low.
    pub hex_n: [u8; 6],
}

impl BoardPins {
    /// The pins as the registers say they should be: LEDS as is, HEX_LO
    /// and HEX_HI inverted (1 = lit in the registers, 0 = lit on the pins).
    pub fn from_registers(leds: u32, hex_lo: u32, hex_hi: u32) -> BoardPins {
        let seg = |word: u32, n: u32| !((word >> (8 * n)) as u8) & 0x7F;
        BoardPins {
            ledr: (leds & LEDS_MASK) as u16,
            hex_n: [seg(hex_lo, 0), seg(hex_lo, 1), seg(hex_lo, 2), seg(hex_lo, 3), seg(hex_hi, 0), seg(hex_hi, 1)],
        }
    }
}

/// Where the test memory starts on the bus.
pub const MEMORY_BASE: u32 = 0x0100_0000;

/// A memory window behind the frame DMA: one frame and a little more,
/// filled with a marker byte; writes outside it, or all writes while
/// `refuse` is set, fail (the bus error the RTL turns into FRAME_STATUS
/// error); while `silent` is set it takes no write at all (a port held in
/// reset: no handshake, no response).
#[derive(Clone, Debug)]
pub struct TestMemory {
    /// The window's bytes, from [`MEMORY_BASE`].
    pub bytes: Vec<u8>,
    /// Fail every write.
    pub refuse: bool,
    /// Answer nothing.
    pub silent: bool,
}

/// The marker the window is filled with.
pub const MARKER: u8 = 0x5A;

impl Default for TestMemory {
    fn default() -> TestMemory {
        TestMemory { bytes: vec![MARKER; FRAME_BYTES + 4096], refuse: false, silent: false }
    }
}

impl DmaTarget for TestMemory {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        let Some(off) = addr.checked_sub(MEMORY_BASE).map(|o| o as usize) else { return false };
        if self.refuse || off + bytes.len() > self.bytes.len() {
            return false;
        }
        self.bytes[off..off + bytes.len()].copy_from_slice(bytes);
        true
    }

    fn read(&mut self, addr: u32, out: &mut [u8]) -> bool {
        let Some(off) = addr.checked_sub(MEMORY_BASE).map(|o| o as usize) else { return false };
        match self.bytes.get(off..off + out.len()) {
            Some(src) if !self.silent => {
                out.copy_from_slice(src);
                true
            }
            _ => false,
        }
    }

    fn answers(&self) -> bool {
        !self.silent
    }
}

const CONTROL: usize = CSR_OFFSET;
const STATUS: usize = CSR_OFFSET + 0x04;
const ROW_Y: usize = CSR_OFFSET + 0x08;
const LIGHT: [usize; 3] = [CSR_OFFSET + 0x0C, CSR_OFFSET + 0x10, CSR_OFFSET + 0x14];
const ID: usize = CSR_OFFSET + 0x18;
const FRAME_BASE: usize = CSR_OFFSET + 0x1C;
const FRAME_CONTROL: usize = CSR_OFFSET + 0x20;
const FRAME_STATUS: usize = CSR_OFFSET + 0x24;
const ROWS_DONE: usize = CSR_OFFSET + 0x28;

/// Polls before a row or a frame counts as hung (a frame is about 174,000
/// clocks of the RTL; every read is at least one).
const MAX_POLLS: u32 = 2_000_000;

fn light(x: i32, y: i32, z: i32) -> Light {
    match Light::from_raw(x, y, z) {
        Ok(l) => l,
        Err(e) => panic!("test light: {e}"),
    }
}

fn model_row(y: u16, l: &Light) -> [u32; LINE_WORDS] {
    let mut row = [0; LINE_WORDS];
    model::render_row(y, l, &mut row);
    row
}

fn read_line(d: &mut impl Device) -> [u32; LINE_WORDS] {
    let mut row = [0; LINE_WORDS];
    for (x, w) in row.iter_mut().enumerate() {
        *w = d.bus_read(line_word_offset(x));
    }
    row
}

fn program(d: &mut impl Device, y: u32, l: &Light) {
    d.bus_write(ROW_Y, y);
    for (off, raw) in LIGHT.into_iter().zip(l.raw()) {
        d.bus_write(off, light_to_register(raw));
    }
}

/// Poll STATUS until not busy; the final status.
fn run_to_idle(d: &mut impl Device) -> u32 {
    for _ in 0..MAX_POLLS {
        let s = d.bus_read(STATUS);
        assert_eq!(s & !STATUS_MASK, 0, "reserved STATUS bits read {s:#x}");
        assert_ne!(s, STATUS_BUSY | STATUS_DONE, "busy and done both set");
        if s & STATUS_BUSY == 0 {
            return s;
        }
    }
    panic!("the row never finished");
}

/// A device that has finished one row and holds done.
fn with_done(d: &mut impl Device) {
    program(d, 10, &light(0, 4096, 0));
    d.bus_write(CONTROL, CONTROL_START);
    assert_eq!(d.bus_read(STATUS), STATUS_BUSY, "busy right after the start");
    assert_eq!(run_to_idle(d), STATUS_DONE);
}

/// After reset every register reads 0 except ID.
pub fn reset_state(d: &mut impl Device) {
    for off in [CONTROL, STATUS, ROW_Y, FRAME_BASE, FRAME_CONTROL, FRAME_STATUS, ROWS_DONE] {
        assert_eq!(d.bus_read(off), 0, "offset {off:#x}");
    }
    for off in LIGHT {
        assert_eq!(d.bus_read(off), 0, "offset {off:#x}");
    }
    assert_eq!(d.bus_read(ID), ID_VALUE);
}

/// ID is fixed: magic and map version, writes ignored.
pub fn id_is_fixed(d: &mut impl Device) {
    d.bus_write(ID, 0);
    d.bus_write(ID, 0xFFFF_FFFF);
    assert_eq!(d.bus_read(ID), ID_VALUE);
    assert_eq!(d.bus_read(ID) >> 16, u32::from(ID_MAGIC));
}

/// BUILD_ID ignores writes. The devices under test are built without a
/// build id, so it reads 0, as on a bitstream from before the register
/// (an unmapped offset then): the value that says "none recorded".
pub fn build_id_is_read_only(d: &mut impl Device) {
    let at = Csr::BuildId.offset();
    let id = d.bus_read(at);
    d.bus_write(at, !id);
    assert_eq!(d.bus_read(at), id);
    assert_eq!(id, 0, "these test builds record no build id");
}

/// Unmapped offsets of the CSR block and past the line buffer read 0 and
/// ignore writes.
pub fn unmapped_offsets_read_zero(d: &mut impl Device) {
    with_done(d);
    let line = read_line(d);
    for off in (0x50..CSR_WINDOW).step_by(4).chain([line_word_offset(LINE_WORDS), 0x1FFC]) {
        d.bus_write(off, 0xFFFF_FFFF);
        assert_eq!(d.bus_read(off), 0, "offset {off:#x}");
    }
    assert_eq!(d.bus_read(STATUS), STATUS_DONE, "no start, no clear");
    assert_eq!(read_line(d), line);
}

/// The two low address bits select nothing (32-bit registers, no byte
/// lanes).
pub fn low_address_bits_are_ignored(d: &mut impl Device) {
    d.bus_write(ROW_Y + 3, 77);
    assert_eq!(d.bus_read(ROW_Y + 1), 77);
    assert_eq!(d.bus_read(ID + 2), ID_VALUE);
}

/// CONTROL and FRAME_CONTROL read 0; STATUS, FRAME_STATUS and ROWS_DONE
/// ignore writes.
pub fn command_registers_read_zero(d: &mut impl Device) {
    for v in [CONTROL_CLEAR_DONE, 0xFFFF_FFFC, 0x1234_5678 & !3] {
        d.bus_write(CONTROL, v);
        assert_eq!(d.bus_read(CONTROL), 0);
        d.bus_write(FRAME_CONTROL, v);
        assert_eq!(d.bus_read(FRAME_CONTROL), 0);
    }
    for off in [STATUS, FRAME_STATUS, ROWS_DONE] {
        d.bus_write(off, 0xFFFF_FFFF);
        assert_eq!(d.bus_read(off), 0, "offset {off:#x}");
    }
}

/// ROW_Y stores bits 8:0.
pub fn row_y_stores_nine_bits(d: &mut impl Device) {
    for bit in 0..32 {
        d.bus_write(ROW_Y, 1 << bit);
        assert_eq!(d.bus_read(ROW_Y), if bit < 9 { 1 << bit } else { 0 }, "bit {bit}");
    }
    d.bus_write(ROW_Y, 0x2AB);
    assert_eq!(d.bus_read(ROW_Y), 0x0AB);
}

/// LIGHT_* store bits 23:0 and read back sign-extended, independently.
pub fn light_registers_sign_extend(d: &mut impl Device) {
    for off in LIGHT {
        for bit in 0..32 {
            d.bus_write(off, 1 << bit);
            let expected = match bit {
                0..=22 => 1 << bit,
                23 => 0xFF80_0000,
                _ => 0,
            };
            assert_eq!(d.bus_read(off), expected, "offset {off:#x} bit {bit}");
        }
        d.bus_write(off, 0xFF12_3456);
        assert_eq!(d.bus_read(off), 0x0012_3456);
        d.bus_write(off, 0x00AB_CDEF);
        assert_eq!(d.bus_read(off), 0xFFAB_CDEF);
    }
    d.bus_write(LIGHT[0], 1);
    d.bus_write(LIGHT[1], 2);
    d.bus_write(LIGHT[2], 3);
    assert_eq!(LIGHT.map(|o| d.bus_read(o)), [1, 2, 3]);
}

/// FRAME_BASE stores an 8-byte aligned address.
pub fn frame_base_is_eight_byte_aligned(d: &mut impl Device) {
    d.bus_write(FRAME_BASE, 0xFFFF_FFFF);
    assert_eq!(d.bus_read(FRAME_BASE), 0xFFFF_FFF8);
    d.bus_write(FRAME_BASE, 0x0410_0007);
    assert_eq!(d.bus_read(FRAME_BASE), 0x0410_0000);
}

/// A row: busy, then done with the model's row in the line buffer; done is
/// sticky across reads and register writes.
pub fn a_row_matches_the_model_and_done_is_sticky(d: &mut impl Device) {
    let l = light(3072, 4096, -2048);
    program(d, 200, &l);
    d.bus_write(CONTROL, CONTROL_START);
    assert_eq!(run_to_idle(d), STATUS_DONE);
    assert_eq!(read_line(d), model_row(200, &l));
    for _ in 0..20 {
        assert_eq!(d.bus_read(STATUS), STATUS_DONE);
    }
    program(d, 300, &light(-5, 6, -7));
    d.bus_write(CONTROL, 0);
    assert_eq!(d.bus_read(STATUS), STATUS_DONE);
}

/// clear_done clears done and starts nothing.
pub fn clear_done_clears_and_does_not_start(d: &mut impl Device) {
    with_done(d);
    d.bus_write(CONTROL, CONTROL_CLEAR_DONE);
    assert_eq!(d.bus_read(STATUS), 0);
    d.bus_write(CONTROL, CONTROL_CLEAR_DONE);
    assert_eq!(d.bus_read(STATUS), 0);
}

/// A start clears a latched done; with both bits set the start wins and the
/// row ends with done set.
pub fn start_clears_done_and_wins_over_clear(d: &mut impl Device) {
    with_done(d);
    d.bus_write(CONTROL, CONTROL_START);
    assert_eq!(d.bus_read(STATUS), STATUS_BUSY);
    assert_eq!(run_to_idle(d), STATUS_DONE);
    d.bus_write(CONTROL, CONTROL_START | CONTROL_CLEAR_DONE);
    assert_eq!(d.bus_read(STATUS), STATUS_BUSY);
    assert_eq!(run_to_idle(d), STATUS_DONE);
}

/// CONTROL bits other than start and clear_done do nothing.
pub fn other_control_bits_are_ignored(d: &mut impl Device) {
    with_done(d);
    d.bus_write(CONTROL, !(CONTROL_START | CONTROL_CLEAR_DONE));
    assert_eq!(d.bus_read(STATUS), STATUS_DONE, "neither start nor clear");
    d.bus_write(CONTROL, !CONTROL_START);
    assert_eq!(d.bus_read(STATUS), 0, "a clear");
    d.bus_write(CONTROL, !CONTROL_CLEAR_DONE);
    assert_eq!(d.bus_read(STATUS), STATUS_BUSY, "a start");
    assert_eq!(run_to_idle(d), STATUS_DONE);
}

/// ROW_Y and LIGHT_* are latched at the start: writes while busy change
/// the read-back only; the next start takes them.
pub fn registers_are_latched_at_start(d: &mut impl Device) {
    let (first, second) = (light(2048, 3072, -4096), light(-7000, 100, 9000));
    program(d, 123, &first);
    d.bus_write(CONTROL, CONTROL_START);
    program(d, 45, &second);
    assert_eq!(d.bus_read(ROW_Y), 45);
    assert_eq!(LIGHT.map(|o| light_from_register(d.bus_read(o))), second.raw());
    assert_eq!(run_to_idle(d), STATUS_DONE);
    assert_eq!(read_line(d), model_row(123, &first));
    d.bus_write(CONTROL, CONTROL_START);
    run_to_idle(d);
    assert_eq!(read_line(d), model_row(45, &second));
}

/// A start while busy is ignored: the row in progress is the one delivered.
pub fn start_while_busy_is_ignored(d: &mut impl Device) {
    let l = light(1024, 5120, -1024);
    program(d, 201, &l);
    d.bus_write(CONTROL, CONTROL_START);
    assert_eq!(d.bus_read(STATUS), STATUS_BUSY);
    program(d, 17, &light(0, 0, 0));
    d.bus_write(CONTROL, CONTROL_START);
    d.bus_write(CONTROL, CONTROL_START | CONTROL_CLEAR_DONE);
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_START);
    assert_eq!(run_to_idle(d), STATUS_DONE);
    assert_eq!(read_line(d), model_row(201, &l));
    assert_eq!(d.bus_read(FRAME_STATUS), 0, "no frame started behind the row");
}

/// clear_done while busy leaves busy alone.
pub fn clear_done_while_busy_leaves_busy(d: &mut impl Device) {
    d.bus_write(CONTROL, CONTROL_START);
    d.bus_write(CONTROL, CONTROL_CLEAR_DONE);
    assert_eq!(d.bus_read(STATUS), STATUS_BUSY);
    assert_eq!(run_to_idle(d), STATUS_DONE);
}

/// ROW_Y 360..511 renders the model's extrapolated 9-bit row.
pub fn rows_past_the_frame_follow_the_model(d: &mut impl Device) {
    let l = light(3072, 4096, -2048);
    for written in [360u32, 437, 511, 0x3FF, 0x200 | 5] {
        program(d, written, &l);
        d.bus_write(CONTROL, CONTROL_START);
        run_to_idle(d);
        let row = (written & ROW_Y_MASK) as u16;
        assert_eq!(read_line(d), model_row(row, &l), "ROW_Y written {written:#x}");
    }
}

/// The line buffer ignores writes.
pub fn line_buffer_ignores_writes(d: &mut impl Device) {
    with_done(d);
    let before = read_line(d);
    for x in (0..LINE_WORDS).step_by(7) {
        d.bus_write(line_word_offset(x), 0x00AB_CDEF);
    }
    assert_eq!(read_line(d), before);
}

/// Poll FRAME_STATUS until not busy, checking that ROWS_DONE never goes
/// down nor past 360 and that STATUS.busy covers the frame; the final
/// FRAME_STATUS and ROWS_DONE.
fn run_frame(d: &mut impl Device) -> (u32, u32) {
    let mut rows = 0;
    for _ in 0..MAX_POLLS {
        // STATUS first: if the frame is still busy at the later read, it
        // was busy at this one.
        let row_status = d.bus_read(STATUS);
        let s = d.bus_read(FRAME_STATUS);
        assert_eq!(s & !FRAME_STATUS_MASK, 0, "reserved FRAME_STATUS bits read {s:#x}");
        let r = d.bus_read(ROWS_DONE);
        assert!(r >= rows && r <= u32::from(ROWS), "ROWS_DONE {r} after {rows}");
        rows = r;
        if s & FRAME_STATUS_BUSY == 0 {
            return (s, d.bus_read(ROWS_DONE));
        }
        assert_eq!(row_status & STATUS_BUSY, STATUS_BUSY, "STATUS.busy while the frame runs");
    }
    panic!("the frame never finished");
}

fn start_frame(d: &mut impl Device, base: u32, l: &Light) {
    program(d, 0, l);
    d.bus_write(FRAME_BASE, base);
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_START);
}

fn model_frame(l: &Light) -> Vec<u8> {
    let mut f = vec![0u8; FRAME_BYTES];
    for y in 0..ROWS {
        let mut row = [0u8; ROW_BYTES];
        model::row_to_rgb888(&model_row(y, l), &mut row);
        f[usize::from(y) * ROW_BYTES..][..ROW_BYTES].copy_from_slice(&row);
    }
    f
}

/// A frame: busy, ROWS_DONE rising to 360, done; the memory holds the
/// model's frame as wire bytes at FRAME_BASE and nothing else changed.
pub fn a_frame_lands_in_memory_as_the_model_renders_it(d: &mut impl Device) {
    let l = light(3072, 4096, -2048);
    let offset = 0x238; // 8-byte aligned, not row or line aligned
    start_frame(d, MEMORY_BASE + offset as u32, &l);
    assert_eq!(d.bus_read(FRAME_STATUS) & FRAME_STATUS_BUSY, FRAME_STATUS_BUSY);
    assert_eq!(run_frame(d), (FRAME_STATUS_DONE, u32::from(ROWS)));
    let want = model_frame(&l);
    let mem = &d.memory().bytes;
    assert!(mem[..offset].iter().all(|b| *b == MARKER), "bytes before FRAME_BASE untouched");
    assert!(mem[offset..offset + FRAME_BYTES] == want[..], "the frame's bytes equal the model's");
    assert!(mem[offset + FRAME_BYTES..].iter().all(|b| *b == MARKER), "bytes after the frame untouched");
    assert_eq!(d.bus_read(STATUS) & STATUS_BUSY, 0);
    // Done is sticky; clear_done clears it; a start clears it too.
    assert_eq!(d.bus_read(FRAME_STATUS), FRAME_STATUS_DONE);
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_CLEAR_DONE);
    assert_eq!(d.bus_read(FRAME_STATUS), 0);
    assert_eq!(d.bus_read(ROWS_DONE), u32::from(ROWS), "ROWS_DONE holds until the next start");
}

/// A frame start while a frame or a row runs is ignored; a row start while
/// a frame runs too.
pub fn starts_while_a_frame_runs_are_ignored(d: &mut impl Device) {
    let l = light(-4096, 6144, -3072);
    start_frame(d, MEMORY_BASE, &l);
    d.bus_write(FRAME_BASE, MEMORY_BASE + 8);
    program(d, 5, &light(1, 2, 3));
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_START);
    d.bus_write(CONTROL, CONTROL_START);
    assert_eq!(run_frame(d), (FRAME_STATUS_DONE, u32::from(ROWS)));
    assert_eq!(d.bus_read(STATUS), 0, "no row ran");
    assert!(d.memory().bytes[..FRAME_BYTES] == model_frame(&l)[..], "the first frame, at the first base");
}

/// A refused write: error set (sticky), ROWS_DONE frozen below 360, busy
/// still clears, done not set; the next start clears the error.
pub fn a_bus_error_is_reported_and_the_frame_still_ends(d: &mut impl Device) {
    let l = light(512, 205, -1024);
    d.memory().refuse = true;
    start_frame(d, MEMORY_BASE, &l);
    let (status, rows) = run_frame(d);
    assert_eq!(status, FRAME_STATUS_ERROR, "error, not done");
    assert!(rows < u32::from(ROWS), "ROWS_DONE {rows} frozen");
    assert_eq!(d.bus_read(FRAME_STATUS), FRAME_STATUS_ERROR, "sticky");
    d.memory().refuse = false;
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_START);
    assert_eq!(run_frame(d), (FRAME_STATUS_DONE, u32::from(ROWS)));
    assert!(d.memory().bytes[..FRAME_BYTES] == model_frame(&l)[..]);
}

/// Poll until ROWS_DONE shows at least one landed row of the frame in
/// progress; the count.
fn wait_for_a_row(d: &mut impl Device) -> u32 {
    for _ in 0..MAX_POLLS {
        let r = d.bus_read(ROWS_DONE);
        if r > 0 {
            return r;
        }
    }
    panic!("no row landed");
}

/// An abort stops a frame: busy clears with aborted set and done clear,
/// ROWS_DONE keeps the rows that landed (and they hold the model's bytes),
/// nothing lands after busy clears, row mode works at once, and the next
/// frame clears aborted and completes.
pub fn an_abort_stops_a_frame_and_nothing_lands_after_it(d: &mut impl Device) {
    let l = light(3072, 4096, -2048);
    start_frame(d, MEMORY_BASE, &l);
    let before = wait_for_a_row(d);
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_ABORT);
    let (status, rows) = run_frame(d);
    assert_eq!(status, FRAME_STATUS_ABORTED, "aborted, neither done nor error");
    assert!(rows >= before && rows < u32::from(ROWS), "ROWS_DONE {rows} kept (was {before})");
    let snapshot = d.memory().bytes.clone();
    let landed = rows as usize * ROW_BYTES;
    assert!(snapshot[..landed] == model_frame(&l)[..landed], "the landed rows hold the model's bytes");
    for _ in 0..1000 {
        assert_eq!(d.bus_read(FRAME_STATUS), FRAME_STATUS_ABORTED, "sticky, and idle");
    }
    assert!(d.memory().bytes == snapshot, "nothing of the frame landed after busy cleared");
    // Row mode is not blocked.
    let rl = light(0, 4096, 0);
    program(d, 20, &rl);
    d.bus_write(CONTROL, CONTROL_START);
    assert_eq!(run_to_idle(d), STATUS_DONE);
    assert_eq!(read_line(d), model_row(20, &rl));
    // The next frame starts clean.
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_START);
    assert_eq!(d.bus_read(FRAME_STATUS) & FRAME_STATUS_ABORTED, 0, "a start clears aborted");
    assert_eq!(run_frame(d), (FRAME_STATUS_DONE, u32::from(ROWS)));
    assert!(d.memory().bytes[..FRAME_BYTES] == model_frame(&rl)[..]);
}

/// An abort while idle does nothing; a write with the abort bit set never
/// starts a frame.
pub fn an_abort_while_idle_does_nothing(d: &mut impl Device) {
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_ABORT);
    assert_eq!(d.bus_read(FRAME_STATUS), 0);
    program(d, 0, &light(1, 2, 3));
    d.bus_write(FRAME_BASE, MEMORY_BASE);
    d.bus_write(FRAME_CONTROL, FRAME_CONTROL_ABORT | FRAME_CONTROL_START);
    for _ in 0..100 {
        assert_eq!(d.bus_read(FRAME_STATUS), 0, "no frame started");
        assert_eq!(d.bus_read(STATUS), 0);
    }
    assert!(d.memory().bytes.iter().all(|b| *b == MARKER), "nothing written");
}

/// A memory that answers nothing (the FPGA-to-SDRAM port held in reset):
/// the frame ends by itself within the stall limit with error and aborted
/// set and no row counted; row mode works; once the memory answers again
/// the next frame completes.
pub fn a_frame_whose_memory_never_answers_ends_with_an_error(d: &mut impl Device) {
    let l = light(-1024, 3072, -2048);
    d.memory().silent = true;
    start_frame(d, MEMORY_BASE, &l);
    assert_eq!(run_frame(d), (FRAME_STATUS_ERROR | FRAME_STATUS_ABORTED, 0));
    let rl = light(512, 4096, 0);
    program(d, 300, &rl);
    d.bus_write(CONTROL, CONTROL_START);
    assert_eq!(run_to_idle(d), STATUS_DONE, "row mode not blocked");
    assert_eq!(read_line(d), model_row(300, &rl));
    d.memory().silent = false;
    start_frame(d, MEMORY_BASE, &l);
    assert_eq!(run_frame(d), (FRAME_STATUS_DONE, u32::from(ROWS)));
    assert!(d.memory().bytes[..FRAME_BYTES] == model_frame(&l)[..]);
}

// ---- VGA scan-out and board I/O (map version 3) ---------------------------

fn csr(c: Csr) -> usize {
    CSR_OFFSET + c.offset()
}

/// The VGA and board I/O registers after reset, their widths and readback,
/// and the pins dark.
pub fn vga_and_board_registers_store_their_bits(d: &mut impl Device) {
    for c in
        [Csr::VgaControl, Csr::VgaBase, Csr::VgaStatus, Csr::Keys, Csr::Switches, Csr::Leds, Csr::HexLo, Csr::HexHi]
    {
        assert_eq!(d.bus_read(csr(c)), 0, "{c:?} after reset");
    }
    assert_eq!(d.board_outputs(), BoardPins::from_registers(0, 0, 0), "pins dark after reset");
    // Letterbox without enable: stored, nothing scanned.
    d.bus_write(csr(Csr::VgaControl), !VGA_CONTROL_ENABLE);
    assert_eq!(d.bus_read(csr(Csr::VgaControl)), VGA_CONTROL_LETTERBOX);
    d.bus_write(csr(Csr::VgaControl), 0);
    d.bus_write(csr(Csr::VgaBase), 0x1234_5677);
    assert_eq!(d.bus_read(csr(Csr::VgaBase)), 0x1234_5670);
    d.bus_write(csr(Csr::VgaStatus), 0xFFFF_FFFF);
    assert_eq!(d.bus_read(csr(Csr::VgaStatus)), 0, "nothing to clear, counter read-only");
    d.bus_write(csr(Csr::Keys), 0xFFFF_FFFF);
    assert_eq!(d.bus_read(csr(Csr::Keys)), 0);
    d.bus_write(csr(Csr::Switches), 0xFFFF_FFFF);
    assert_eq!(d.bus_read(csr(Csr::Switches)), 0, "SWITCHES ignores writes");
    d.bus_write(csr(Csr::Leds), 0xFFFF_FFFF);
    d.bus_write(csr(Csr::HexLo), 0xFFFF_FFFF);
    d.bus_write(csr(Csr::HexHi), 0xFFFF_FFFF);
    assert_eq!(d.bus_read(csr(Csr::Leds)), LEDS_MASK);
    assert_eq!(d.bus_read(csr(Csr::HexLo)), HEX_LO_MASK);
    assert_eq!(d.bus_read(csr(Csr::HexHi)), HEX_HI_MASK);
}

/// LEDs and 7-segment pins follow the registers (HEX inverted on the
/// pins); switches show in SWITCHES.
pub fn board_pins_follow_the_registers(d: &mut impl Device) {
    for (leds, lo, hi) in [(0x155, 0x0102_0408, 0x1234), (0x2AA, 0x7F00_3F06, 0x5B4F), (0, 0, 0)] {
        d.bus_write(csr(Csr::Leds), leds);
        d.bus_write(csr(Csr::HexLo), lo);
        d.bus_write(csr(Csr::HexHi), hi);
        assert_eq!(d.board_outputs(), BoardPins::from_registers(leds, lo, hi), "LEDS {leds:#x} HEX {lo:#x} {hi:#x}");
    }
    for sw in [0x2A5u16, 0x15A, 0x3FF, 0] {
        d.set_board_inputs(0, sw);
        d.pass_clocks(4);
        assert_eq!(d.bus_read(csr(Csr::Switches)), u32::from(sw));
    }
}

/// A key shows only once it has held its new level for the debounce time:
/// a shorter press never shows; a longer one shows with its sticky bit,
/// which only a write of 1 clears; the release is debounced too.
pub fn keys_are_debounced(d: &mut impl Device) {
    d.set_board_inputs(0b0100, 0);
    d.pass_clocks(KEY_DEBOUNCE_CLOCKS / 2);
    assert_eq!(d.bus_read(csr(Csr::Keys)), 0, "half the debounce time");
    d.set_board_inputs(0, 0);
    d.pass_clocks(KEY_DEBOUNCE_CLOCKS + 64);
    assert_eq!(d.bus_read(csr(Csr::Keys)), 0, "a short press never shows");
    d.set_board_inputs(0b0100, 0);
    d.pass_clocks(KEY_DEBOUNCE_CLOCKS + 64);
    assert_eq!(d.bus_read(csr(Csr::Keys)), 0x44, "held: down and went down");
    d.bus_write(csr(Csr::Keys), 0x0F);
    assert_eq!(d.bus_read(csr(Csr::Keys)), 0x44, "down bits are not cleared by writes");
    d.bus_write(csr(Csr::Keys), 0x40);
    assert_eq!(d.bus_read(csr(Csr::Keys)), 0x04, "W1C clears the sticky bit");
    d.set_board_inputs(0, 0);
    d.pass_clocks(KEY_DEBOUNCE_CLOCKS / 2);
    assert_eq!(d.bus_read(csr(Csr::Keys)), 0x04, "release not yet debounced");
    d.pass_clocks(KEY_DEBOUNCE_CLOCKS / 2 + 64);
    assert_eq!(d.bus_read(csr(Csr::Keys)), 0, "released");
}

/// Enabled, the frame counter counts one frame per [`VGA_FRAME_CLOCKS`]
/// (read in the middle of a frame time, so a device may count at any
/// phase within one frame of enable); writes of 1 to the counter's bits
/// do nothing; enabling again clears it. Scanning the test memory never
/// underruns.
pub fn the_vga_counts_frames_once_enabled(d: &mut impl Device) {
    let status = csr(Csr::VgaStatus);
    d.bus_write(csr(Csr::VgaBase), MEMORY_BASE);
    d.pass_clocks(VGA_FRAME_CLOCKS);
    assert_eq!(d.bus_read(status), 0, "disabled: no count");
    d.bus_write(csr(Csr::VgaControl), VGA_CONTROL_ENABLE);
    d.pass_clocks(VGA_FRAME_CLOCKS / 2);
    assert_eq!(d.bus_read(status), 0, "half a frame after enable");
    d.pass_clocks(VGA_FRAME_CLOCKS);
    assert_eq!(d.bus_read(status), 1, "one frame and a half");
    d.bus_write(status, VGA_STATUS_FRAMES);
    assert_eq!(d.bus_read(status), 1, "the counter is not W1C");
    d.pass_clocks(2 * VGA_FRAME_CLOCKS);
    assert_eq!(d.bus_read(status), 3, "three frames and a half");
    d.bus_write(csr(Csr::VgaControl), VGA_CONTROL_ENABLE | VGA_CONTROL_LETTERBOX);
    assert_eq!(d.bus_read(status) & VGA_STATUS_FRAMES, 3, "a layout change keeps counting");
    d.bus_write(csr(Csr::VgaControl), 0);
    d.pass_clocks(VGA_FRAME_CLOCKS);
    d.bus_write(csr(Csr::VgaControl), VGA_CONTROL_ENABLE);
    assert_eq!(d.bus_read(status), 0, "enable clears VGA_STATUS");
    d.pass_clocks(VGA_FRAME_CLOCKS / 2);
    assert_eq!(d.bus_read(status), 0);
    d.bus_write(csr(Csr::VgaControl), 0);
}

/// One `#[test]` per check of [`crate::conformance`] for the device that
/// `$make` (an expression) builds afresh each time.
#[macro_export]
macro_rules! conformance_tests {
    ($make:expr) => {
        $crate::conformance_tests!(@each $make;
            reset_state, id_is_fixed, build_id_is_read_only, unmapped_offsets_read_zero, low_address_bits_are_ignored,
            command_registers_read_zero, row_y_stores_nine_bits, light_registers_sign_extend,
            frame_base_is_eight_byte_aligned, a_row_matches_the_model_and_done_is_sticky,
            clear_done_clears_and_does_not_start, start_clears_done_and_wins_over_clear,
            other_control_bits_are_ignored, registers_are_latched_at_start, start_while_busy_is_ignored,
            clear_done_while_busy_leaves_busy, rows_past_the_frame_follow_the_model, line_buffer_ignores_writes,
            a_frame_lands_in_memory_as_the_model_renders_it, starts_while_a_frame_runs_are_ignored,
            a_bus_error_is_reported_and_the_frame_still_ends, an_abort_stops_a_frame_and_nothing_lands_after_it,
            an_abort_while_idle_does_nothing, a_frame_whose_memory_never_answers_ends_with_an_error,
            vga_and_board_registers_store_their_bits, board_pins_follow_the_registers, keys_are_debounced,
            the_vga_counts_frames_once_enabled);
    };
    (@each $make:expr; $($check:ident),* $(,)?) => {
        $(
            #[test]
            fn $check() {
                let mut device = $make;
                $crate::conformance::$check(&mut device);
            }
        )*
    };
}

impl Device for crate::sim::SimAccelerator<TestMemory> {
    fn bus_read(&mut self, offset: usize) -> u32 {
        crate::sim::SimAccelerator::bus_read(self, offset)
    }

    fn bus_write(&mut self, offset: usize, value: u32) {
        crate::sim::SimAccelerator::bus_write(self, offset, value)
    }

    fn memory(&mut self) -> &mut TestMemory {
        self.memory_mut()
    }

    fn set_board_inputs(&mut self, keys: u8, switches: u16) {
        crate::sim::SimAccelerator::set_board_inputs(self, keys, switches)
    }

    fn board_outputs(&mut self) -> BoardPins {
        let b = *self.board();
        BoardPins::from_registers(b.leds, b.hex_lo, b.hex_hi)
    }

    fn pass_clocks(&mut self, clocks: u32) {
        crate::sim::SimAccelerator::pass_clocks(self, clocks)
    }
}
