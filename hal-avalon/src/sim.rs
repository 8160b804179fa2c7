//! A simulated accelerator, bit-exact at the register level (feature `sim`).
//!
//! [`SimAccelerator`] answers the bridge window the way the RTL does, with
//! the behaviour documented in [`crate::map`], and renders rows with
//! [`model::render_row`]. Two deliberate differences from real hardware make
//! tests sharper, not looser:
//!
//! * Time is counted in STATUS reads: a row stays busy for
//!   [`busy_polls`](SimAccelerator::busy_polls) reads after its start and
//!   finishes on the next one.
//! * While busy, line-buffer words read [`LINE_POISON`]` | x` (bits 31:24
//!   set, which a finished row never has), so a premature read cannot pass
//!   for a row.
//!
//! Frame mode writes each row's RGB888 bytes into a [`DmaTarget`] (host
//! memory in hps-sim, the firmware's frame ring under QEMU) before counting
//! it in ROWS_DONE, as the RTL counts a row only after its write responses;
//! each FRAME_STATUS, ROWS_DONE or STATUS read lets
//! [`frame_rows_per_poll`](SimAccelerator::frame_rows_per_poll) more rows
//! land.
//!
//! A memory whose [`DmaTarget::answers`] is `false` takes no write: the
//! frame stalls, and after [`FRAME_STALL_POLLS`] status reads without
//! progress it stops with error and aborted set, as the RTL does after
//! [`FRAME_STALL_CYCLES`](crate::map::FRAME_STALL_CYCLES) clocks. An abort
//! stops a frame at once.
//!
//! [`Fault`] injects the failures the driver must survive. No `std`, no
//! allocation.

use embedded_hal::delay::DelayNs;
use model::Light;

use crate::map::{
    light_from_register, Csr, BUS_ALL_ONES, CONTROL_CLEAR_DONE, CONTROL_START, CSR_OFFSET, CSR_WINDOW, FRAME_BASE_MASK,
    FRAME_CONTROL_ABORT, FRAME_CONTROL_CLEAR_DONE, FRAME_CONTROL_START, FRAME_ROW_BYTES, FRAME_STATUS_ABORTED,
    FRAME_STATUS_BUSY, FRAME_STATUS_DONE, FRAME_STATUS_ERROR, HEX_HI_MASK, HEX_LO_MASK, ID_VALUE, KEYS_DOWN,
    KEYS_PRESSED, KEY_DEBOUNCE_CLOCKS, LEDS_MASK, LIGHT_MASK, LINE_BUFFER_OFFSET, LINE_WORDS, ROWS, ROW_Y_MASK,
    STATUS_BUSY, STATUS_DONE, SWITCHES_MASK, VGA_CONTROL_ENABLE, VGA_CONTROL_MASK, VGA_FRAME_CLOCKS, VGA_STATUS_FLAGS,
    VGA_STATUS_FRAMES,
};
use crate::port::RegisterPort;

/// What a line-buffer word `x` reads while a row is in progress:
/// `LINE_POISON | x`.
pub const LINE_POISON: u32 = 0xBAD0_0000;

/// STATUS reads a row stays busy for unless configured otherwise.
pub const DEFAULT_BUSY_POLLS: u32 = 3;

/// Rows of a frame that land per status read unless configured otherwise.
pub const DEFAULT_FRAME_ROWS_PER_POLL: u16 = 12;

/// Status reads without progress after which a frame whose memory does not
/// answer stops (the simulated device's time is counted in status reads).
pub const FRAME_STALL_POLLS: u32 = 64;

/// Memory the simulated frame DMA writes into.
pub trait DmaTarget {
    /// Write `bytes` at bus address `addr`; `false` if no memory answers
    /// there (the RTL's bus error).
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool;

    /// Read `out.len()` bytes at bus address `addr` (the VGA scan-out's
    /// reads); `false` if no memory answers there. By default nothing does.
    fn read(&mut self, addr: u32, out: &mut [u8]) -> bool {
        let _ = (addr, out);
        false
    }

    /// Whether the memory takes writes at all. `false`: every write waits
    /// for ever (an FPGA-to-SDRAM port held in reset, a lost write
    /// response), so a frame stalls until it is aborted or hits the stall
    /// limit.
    fn answers(&self) -> bool {
        true
    }
}

/// No memory behind the DMA: every frame write fails.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct NoMemory;

impl DmaTarget for NoMemory {
    fn write(&mut self, _addr: u32, _bytes: &[u8]) -> bool {
        false
    }
}

impl<T: DmaTarget + ?Sized> DmaTarget for &mut T {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        (**self).write(addr, bytes)
    }

    fn read(&mut self, addr: u32, out: &mut [u8]) -> bool {
        (**self).read(addr, out)
    }

    fn answers(&self) -> bool {
        (**self).answers()
    }
}

/// An injected failure.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Fault {
    /// A row or frame in progress never finishes: busy stays set. Clearing
    /// the fault lets it run on from where it stopped.
    StuckBusy,
    /// Nothing answers: every read returns all ones, writes are lost (an
    /// empty fabric or a bridge that fails reads).
    Absent,
    /// Rows and frames finish (busy clears, the line buffer or memory is
    /// written) but done is never set.
    DoneNeverSet,
}

/// The simulated accelerator, its frame DMA writing into `M`.
#[derive(Clone, Debug)]
pub struct SimAccelerator<M = NoMemory> {
    /// ROW_Y as stored (9 bits).
    row_y: u32,
    /// LIGHT_X/Y/Z as stored (24 bits each).
    light: [u32; 3],
    /// ROW_Y and LIGHT_* latched by the last accepted start.
    latched_row_y: u32,
    latched_light: [u32; 3],
    busy: bool,
    done: bool,
    /// STATUS reads the row in progress still reports busy for.
    polls_left: u32,
    busy_polls: u32,
    line: [u32; LINE_WORDS],
    frame: FrameState,
    frame_rows_per_poll: u16,
    mem: M,
    /// VGA and board I/O registers as stored (map version 3).
    board: BoardRegs,
    fault: Option<Fault>,
    /// `(row, x)`: that pixel comes out inverted (self-test fault injection).
    wrong_pixel: Option<(u16, u16)>,
    /// BUILD_ID (0 unless set: a bitstream built without one).
    build_id: u32,
    status_reads: u32,
    starts: u32,
    rows_finished: u32,
    frames_started: u32,
}

/// The VGA and board I/O registers (map version 3), as stored, and the
/// board's pins and time as the simulated device sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoardRegs {
    /// Keys held down on the pins (bit n: KEYn pressed).
    pub key_pins: u8,
    /// Fabric clocks the key pins have held their level.
    pub key_stable: u32,
    /// Fabric clocks since the last VGA frame began counting.
    pub vga_clocks: u32,
    /// VGA_CONTROL.
    pub vga_control: u32,
    /// VGA_BASE.
    pub vga_base: u32,
    /// VGA_STATUS.
    pub vga_status: u32,
    /// KEYS.
    pub keys: u32,
    /// SWITCHES.
    pub switches: u32,
    /// LEDS.
    pub leds: u32,
    /// HEX_LO.
    pub hex_lo: u32,
    /// HEX_HI.
    pub hex_hi: u32,
}

/// Frame mode's registers and progress.
#[derive(Clone, Copy, Debug, Default)]
struct FrameState {
    /// FRAME_BASE as stored.
    base: u32,
    latched_base: u32,
    latched_light: [u32; 3],
    busy: bool,
    done: bool,
    error: bool,
    aborted: bool,
    /// Status reads in a row without progress (the memory not answering).
    stalled_polls: u32,
    /// Rows rendered (and written) so far.
    next_row: u16,
    /// Rows that landed before any failure.
    rows_done: u16,
}

impl Default for SimAccelerator {
    fn default() -> SimAccelerator {
        SimAccelerator::new()
    }
}

impl SimAccelerator {
    /// A device just out of reset, busy for [`DEFAULT_BUSY_POLLS`] polls per
    /// row, no fault, no memory behind its frame DMA.
    pub const fn new() -> SimAccelerator {
        SimAccelerator::with_busy_polls(DEFAULT_BUSY_POLLS)
    }

    /// A device just out of reset whose rows stay busy for `busy_polls`
    /// STATUS reads (0: done on the first read after the start).
    pub const fn with_busy_polls(busy_polls: u32) -> SimAccelerator {
        SimAccelerator::with_memory(NoMemory, busy_polls)
    }
}

impl<M: DmaTarget> SimAccelerator<M> {
    /// A device just out of reset whose frame DMA writes into `mem` and whose
    /// rows stay busy for `busy_polls` STATUS reads.
    pub const fn with_memory(mem: M, busy_polls: u32) -> SimAccelerator<M> {
        SimAccelerator {
            row_y: 0,
            light: [0; 3],
            latched_row_y: 0,
            latched_light: [0; 3],
            busy: false,
            done: false,
            polls_left: 0,
            busy_polls,
            line: [0; LINE_WORDS],
            frame: FrameState {
                base: 0,
                latched_base: 0,
                latched_light: [0; 3],
                busy: false,
                done: false,
                error: false,
                aborted: false,
                stalled_polls: 0,
                next_row: 0,
                rows_done: 0,
            },
            frame_rows_per_poll: DEFAULT_FRAME_ROWS_PER_POLL,
            mem,
            board: BoardRegs {
                key_pins: 0,
                key_stable: 0,
                vga_clocks: 0,
                vga_control: 0,
                vga_base: 0,
                vga_status: 0,
                keys: 0,
                switches: 0,
                leds: 0,
                hex_lo: 0,
                hex_hi: 0,
            },
            fault: None,
            wrong_pixel: None,
            build_id: 0,
            status_reads: 0,
            starts: 0,
            rows_finished: 0,
            frames_started: 0,
        }
    }

    /// Reset every register and the line buffer to the power-on state; the
    /// configuration (busy polls, rows per poll, fault), the memory and the
    /// counters are kept.
    pub fn reset(&mut self) {
        self.row_y = 0;
        self.light = [0; 3];
        self.latched_row_y = 0;
        self.latched_light = [0; 3];
        self.busy = false;
        self.done = false;
        self.polls_left = 0;
        self.line = [0; LINE_WORDS];
        self.frame = FrameState::default();
        self.board = BoardRegs::default();
    }

    /// The VGA and board I/O registers as stored.
    pub fn board(&self) -> &BoardRegs {
        &self.board
    }

    /// A scan-out fault as the RTL reports it: `flags` (of
    /// [`VGA_STATUS_FLAGS`]) set in VGA_STATUS until cleared. The simulated
    /// reader itself never fails.
    pub fn report_vga_fault(&mut self, flags: u32) {
        self.board.vga_status |= flags & VGA_STATUS_FLAGS;
    }

    /// The board's inputs as the pins carry them: `keys` held down (bit n:
    /// KEYn pressed), `switches` (bit n: SWn up). Switches show at once
    /// (synchronised); keys only after they held the new level for
    /// [`KEY_DEBOUNCE_CLOCKS`] of [`pass_clocks`](Self::pass_clocks).
    pub fn set_board_inputs(&mut self, keys: u8, switches: u16) {
        let keys = keys & KEYS_DOWN as u8;
        if keys != self.board.key_pins {
            self.board.key_pins = keys;
            self.board.key_stable = 0;
        }
        self.board.switches = u32::from(switches) & SWITCHES_MASK;
    }

    /// Let `clocks` fabric clocks pass: keys that held their level long
    /// enough show in KEYS; an enabled VGA port counts a frame every
    /// [`VGA_FRAME_CLOCKS`].
    pub fn pass_clocks(&mut self, clocks: u32) {
        let b = &mut self.board;
        b.key_stable = b.key_stable.saturating_add(clocks);
        let down = u32::from(b.key_pins);
        if b.key_stable >= KEY_DEBOUNCE_CLOCKS && down != b.keys & KEYS_DOWN {
            let went_down = down & !(b.keys & KEYS_DOWN);
            b.keys = (b.keys & KEYS_PRESSED) | (went_down << 4) | down;
        }
        if b.vga_control & VGA_CONTROL_ENABLE != 0 {
            let total = u64::from(b.vga_clocks) + u64::from(clocks);
            let frames = (total / u64::from(VGA_FRAME_CLOCKS)) as u32;
            b.vga_clocks = (total % u64::from(VGA_FRAME_CLOCKS)) as u32;
            let count = (b.vga_status & VGA_STATUS_FRAMES).wrapping_add(frames) & VGA_STATUS_FRAMES;
            b.vga_status = (b.vga_status & !VGA_STATUS_FRAMES) | count;
        }
    }

    /// STATUS reads a row stays busy for.
    pub fn busy_polls(&self) -> u32 {
        self.busy_polls
    }

    /// Change how many STATUS reads later rows stay busy for (the row in
    /// progress keeps its count).
    pub fn set_busy_polls(&mut self, busy_polls: u32) {
        self.busy_polls = busy_polls;
    }

    /// Rows of a frame that land per status read.
    pub fn frame_rows_per_poll(&self) -> u16 {
        self.frame_rows_per_poll
    }

    /// Change how many rows of a frame land per status read (at least 1).
    pub fn set_frame_rows_per_poll(&mut self, rows: u16) {
        self.frame_rows_per_poll = rows.max(1);
    }

    /// The memory behind the frame DMA.
    pub fn memory(&self) -> &M {
        &self.mem
    }

    /// The memory behind the frame DMA, mutably.
    pub fn memory_mut(&mut self) -> &mut M {
        &mut self.mem
    }

    /// The injected fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// Inject a fault, or recover with `None`.
    pub fn set_fault(&mut self, fault: Option<Fault>) {
        self.fault = fault;
    }

    /// The build id BUILD_ID reads, as a bitstream's synthesis parameter
    /// sets it (0: none recorded, the default).
    pub fn set_build_id(&mut self, id: u32) {
        self.build_id = id;
    }

    /// Make pixel `x` of row `y` come out wrong (RGB inverted) in row and
    /// frame mode from now on, or right again with `None`: a computing
    /// error, as opposed to the bus and timing [`Fault`]s.
    pub fn set_wrong_pixel(&mut self, at: Option<(u16, u16)>) {
        self.wrong_pixel = at;
    }

    /// STATUS reads so far (including unanswered ones).
    pub fn status_reads(&self) -> u32 {
        self.status_reads
    }

    /// Row starts accepted so far (a start while busy is not counted).
    pub fn starts(&self) -> u32 {
        self.starts
    }

    /// Rows finished so far (row mode).
    pub fn rows_finished(&self) -> u32 {
        self.rows_finished
    }

    /// Frame starts accepted so far.
    pub fn frames_started(&self) -> u32 {
        self.frames_started
    }

    /// Whether a row or a frame is in progress (without counting as a poll).
    pub fn is_busy(&self) -> bool {
        self.busy || self.frame.busy
    }

    /// A 32-bit read at byte offset `offset` of the bridge window (low two
    /// bits ignored). Offsets outside the eleven registers and the 480
    /// line-buffer words read 0.
    pub fn bus_read(&mut self, offset: usize) -> u32 {
        let offset = offset & !3;
        if offset == CSR_OFFSET + Csr::Status.offset() {
            self.status_reads = self.status_reads.wrapping_add(1);
        }
        if self.fault == Some(Fault::Absent) {
            return BUS_ALL_ONES;
        }
        if let Some(rel) = csr_relative(offset) {
            return match Csr::at_offset(rel) {
                Some(csr) => self.read_csr(csr),
                None => 0,
            };
        }
        match line_word_index(offset) {
            Some(x) if self.busy => LINE_POISON | x as u32,
            Some(x) => self.line[x],
            None => 0,
        }
    }

    /// A 32-bit write at byte offset `offset` of the bridge window (low two
    /// bits ignored). Only CONTROL, ROW_Y, LIGHT_*, FRAME_BASE and
    /// FRAME_CONTROL take writes.
    pub fn bus_write(&mut self, offset: usize, value: u32) {
        if self.fault == Some(Fault::Absent) {
            return;
        }
        let Some(csr) = csr_relative(offset & !3).and_then(Csr::at_offset) else {
            return;
        };
        match csr {
            Csr::Control => self.control(value),
            Csr::RowY => self.row_y = value & ROW_Y_MASK,
            Csr::LightX => self.light[0] = value & LIGHT_MASK,
            Csr::LightY => self.light[1] = value & LIGHT_MASK,
            Csr::LightZ => self.light[2] = value & LIGHT_MASK,
            Csr::FrameBase => self.frame.base = value & FRAME_BASE_MASK,
            Csr::FrameControl => self.frame_control(value),
            Csr::VgaControl => {
                // Enable clears the counter and the underrun.
                if value & VGA_CONTROL_ENABLE != 0 && self.board.vga_control & VGA_CONTROL_ENABLE == 0 {
                    self.board.vga_status = 0;
                    self.board.vga_clocks = 0;
                }
                self.board.vga_control = value & VGA_CONTROL_MASK;
            }
            Csr::VgaBase => self.board.vga_base = value & FRAME_BASE_MASK,
            Csr::VgaStatus => self.board.vga_status &= !(value & VGA_STATUS_FLAGS),
            Csr::Keys => self.board.keys &= !(value & KEYS_PRESSED),
            Csr::Leds => self.board.leds = value & LEDS_MASK,
            Csr::HexLo => self.board.hex_lo = value & HEX_LO_MASK,
            Csr::HexHi => self.board.hex_hi = value & HEX_HI_MASK,
            Csr::Status | Csr::Id | Csr::FrameStatus | Csr::RowsDone | Csr::Switches | Csr::BuildId => {}
        }
    }

    fn read_csr(&mut self, csr: Csr) -> u32 {
        match csr {
            Csr::Control | Csr::FrameControl => 0,
            Csr::Status => {
                self.advance_frame();
                self.poll_status()
            }
            Csr::RowY => self.row_y,
            Csr::LightX => light_from_register(self.light[0]) as u32,
            Csr::LightY => light_from_register(self.light[1]) as u32,
            Csr::LightZ => light_from_register(self.light[2]) as u32,
            Csr::Id => ID_VALUE,
            Csr::FrameBase => self.frame.base,
            Csr::FrameStatus => {
                self.advance_frame();
                let f = &self.frame;
                (if f.busy { FRAME_STATUS_BUSY } else { 0 })
                    | (if f.done { FRAME_STATUS_DONE } else { 0 })
                    | (if f.error { FRAME_STATUS_ERROR } else { 0 })
                    | (if f.aborted { FRAME_STATUS_ABORTED } else { 0 })
            }
            Csr::RowsDone => {
                self.advance_frame();
                u32::from(self.frame.rows_done)
            }
            Csr::VgaControl => self.board.vga_control,
            Csr::VgaBase => self.board.vga_base,
            Csr::VgaStatus => self.board.vga_status,
            Csr::Keys => self.board.keys,
            Csr::Switches => self.board.switches,
            Csr::Leds => self.board.leds,
            Csr::HexLo => self.board.hex_lo,
            Csr::HexHi => self.board.hex_hi,
            Csr::BuildId => self.build_id,
        }
    }

    /// A CONTROL write: start wins over clear_done; a start while busy (a
    /// row or a frame) is ignored; done is always 0 while busy, so
    /// clear_done needs no busy check.
    fn control(&mut self, value: u32) {
        if value & CONTROL_START != 0 {
            if !self.is_busy() {
                self.latched_row_y = self.row_y;
                self.latched_light = self.light;
                self.busy = true;
                self.done = false;
                self.polls_left = self.busy_polls;
                self.starts = self.starts.wrapping_add(1);
            }
        } else if value & CONTROL_CLEAR_DONE != 0 {
            self.done = false;
        }
    }

    /// A FRAME_CONTROL write: abort the frame in progress, start a frame
    /// when idle, or clear frame done; abort wins.
    fn frame_control(&mut self, value: u32) {
        if value & FRAME_CONTROL_ABORT != 0 {
            // A wedged device (StuckBusy) ignores the abort too.
            if self.frame.busy && self.fault != Some(Fault::StuckBusy) {
                self.stop_frame();
            }
        } else if value & FRAME_CONTROL_START != 0 {
            if !self.is_busy() {
                self.frame = FrameState {
                    base: self.frame.base,
                    latched_base: self.frame.base,
                    latched_light: self.light,
                    busy: true,
                    done: false,
                    error: false,
                    aborted: false,
                    stalled_polls: 0,
                    next_row: 0,
                    rows_done: 0,
                };
                self.frames_started = self.frames_started.wrapping_add(1);
            }
        } else if value & FRAME_CONTROL_CLEAR_DONE != 0 {
            self.frame.done = false;
        }
    }

    /// One status read's worth of frame progress: up to
    /// `frame_rows_per_poll` rows rendered, written to memory, then counted.
    fn advance_frame(&mut self) {
        if !self.frame.busy || self.fault == Some(Fault::StuckBusy) {
            return;
        }
        if !self.mem.answers() {
            self.frame.stalled_polls += 1;
            if self.frame.stalled_polls >= FRAME_STALL_POLLS {
                self.frame.error = true;
                self.stop_frame();
            }
            return;
        }
        self.frame.stalled_polls = 0;
        let [x, y, z] = self.frame.latched_light.map(light_from_register);
        // A sign-extended 24-bit value is always a valid word; should that
        // ever fail, the frame ends in an error instead of a panic.
        let light = Light::from_raw(x, y, z).ok();
        let mut words = [0u32; LINE_WORDS];
        let mut bytes = [0u8; model::ROW_BYTES];
        for _ in 0..self.frame_rows_per_poll {
            let y = self.frame.next_row;
            if y >= ROWS {
                break;
            }
            let addr = self.frame.latched_base.wrapping_add(u32::from(y) * FRAME_ROW_BYTES);
            let landed = match &light {
                Some(l) => {
                    model::render_row(y, l, &mut words);
                    spoil(self.wrong_pixel, y, &mut words);
                    model::row_to_rgb888(&words, &mut bytes);
                    self.mem.write(addr, &bytes)
                }
                None => false,
            };
            if !landed {
                self.frame.error = true;
            } else if !self.frame.error {
                self.frame.rows_done += 1;
            }
            self.frame.next_row = y + 1;
        }
        if self.frame.next_row >= ROWS {
            self.frame.busy = false;
            self.frame.done = !self.frame.error && self.fault != Some(Fault::DoneNeverSet);
        }
    }

    /// The frame stops before its end: nothing more lands, `ROWS_DONE`
    /// keeps its count.
    fn stop_frame(&mut self) {
        self.frame.busy = false;
        self.frame.done = false;
        self.frame.aborted = true;
    }

    /// One STATUS read: time passes for the row in progress.
    fn poll_status(&mut self) -> u32 {
        if self.busy && self.fault != Some(Fault::StuckBusy) {
            if self.polls_left == 0 {
                self.finish_row();
            } else {
                self.polls_left -= 1;
            }
        }
        (if self.is_busy() { STATUS_BUSY } else { 0 }) | (if self.done { STATUS_DONE } else { 0 })
    }

    fn finish_row(&mut self) {
        let [x, y, z] = self.latched_light.map(light_from_register);
        // A sign-extended 24-bit value is always a valid word, so `from_raw`
        // cannot fail; should it ever, the row stays poisoned instead of
        // panicking.
        match Light::from_raw(x, y, z) {
            Ok(light) => {
                model::render_row(self.latched_row_y as u16, &light, &mut self.line);
                spoil(self.wrong_pixel, self.latched_row_y as u16, &mut self.line);
            }
            Err(_) => {
                for (x, word) in (0u32..).zip(self.line.iter_mut()) {
                    *word = LINE_POISON | x;
                }
            }
        }
        self.busy = false;
        self.done = self.fault != Some(Fault::DoneNeverSet);
        self.rows_finished = self.rows_finished.wrapping_add(1);
    }
}

/// Invert the RGB of the wrong pixel if it lies in row `y`.
fn spoil(at: Option<(u16, u16)>, y: u16, words: &mut [u32; LINE_WORDS]) {
    if let Some(w) = at.filter(|(row, _)| *row == y).and_then(|(_, x)| words.get_mut(usize::from(x))) {
        *w ^= 0x00ff_ffff;
    }
}

/// `offset` relative to the CSR block, if it falls inside it.
fn csr_relative(offset: usize) -> Option<usize> {
    offset.checked_sub(CSR_OFFSET).filter(|rel| *rel < CSR_WINDOW)
}

/// The line-buffer word at `offset`, if there is one.
fn line_word_index(offset: usize) -> Option<usize> {
    offset.checked_sub(LINE_BUFFER_OFFSET).map(|rel| rel / 4).filter(|x| *x < LINE_WORDS)
}

impl<M: DmaTarget> RegisterPort for SimAccelerator<M> {
    fn read(&mut self, csr: Csr) -> u32 {
        self.bus_read(CSR_OFFSET + csr.offset())
    }

    fn write(&mut self, csr: Csr, value: u32) {
        self.bus_write(CSR_OFFSET + csr.offset(), value)
    }

    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        for (x, word) in out.iter_mut().enumerate() {
            *word = self.bus_read(crate::map::line_word_offset(x));
        }
    }
}

/// A [`DelayNs`] that only adds up the time it was asked to wait, for host
/// tests and host simulations.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct CountingDelay {
    /// Number of delay calls.
    pub calls: u32,
    /// Nanoseconds asked for in total.
    pub total_ns: u64,
}

impl DelayNs for CountingDelay {
    fn delay_ns(&mut self, ns: u32) {
        self.calls = self.calls.wrapping_add(1);
        self.total_ns = self.total_ns.saturating_add(u64::from(ns));
    }
}
