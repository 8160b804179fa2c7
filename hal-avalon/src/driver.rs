//! The driver: rows (render one row, copy it out of the line buffer) and
//! frames (render a whole frame into memory, watch the rows land).

use core::fmt;

use embedded_hal::delay::DelayNs;
use model::{Light, LightError};

use crate::map::{
    light_to_register, line_word_offset, Csr, CONTROL_START, CSR_OFFSET, FRAME_BASE_MASK, FRAME_CONTROL_ABORT,
    FRAME_CONTROL_START, FRAME_STATUS_ABORTED, FRAME_STATUS_BUSY, FRAME_STATUS_DONE, FRAME_STATUS_ERROR,
    FRAME_STATUS_MASK, ID_MAGIC, ID_VALUE, ID_VERSION_FRAMES, LINE_WORDS, PIXEL_RESERVED_MASK, ROWS, STATUS_BUSY,
    STATUS_DONE, STATUS_MASK,
};
use crate::port::RegisterPort;

/// How long the driver polls STATUS before giving up.
///
/// [`Accelerator::run_row`] waits twice: for a previous row to finish, then
/// for its own. Each wait reads STATUS at most
/// [`max_polls`](Self::max_polls) times, [`poll_interval_ns`](Self::poll_interval_ns)
/// apart, so a call returns within about
/// `2 * max_polls * (poll_interval_ns + one bus read)`.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct PollTimeout {
    max_polls: u32,
    poll_interval_ns: u32,
}

impl PollTimeout {
    /// The default bound: 10,000 polls 1 us apart, at least 10 ms. A row
    /// takes the hardware tens of microseconds; a frame at 24 frames/s
    /// leaves 115 us per row.
    pub const DEFAULT: PollTimeout = PollTimeout::new(10_000, 1_000);

    /// At most `max_polls` STATUS reads per wait (at least 1),
    /// `poll_interval_ns` apart (0: back to back).
    pub const fn new(max_polls: u32, poll_interval_ns: u32) -> PollTimeout {
        PollTimeout { max_polls: if max_polls == 0 { 1 } else { max_polls }, poll_interval_ns }
    }

    /// STATUS reads allowed per wait.
    pub const fn max_polls(&self) -> u32 {
        self.max_polls
    }

    /// Delay between two STATUS reads, in nanoseconds.
    pub const fn poll_interval_ns(&self) -> u32 {
        self.poll_interval_ns
    }
}

impl Default for PollTimeout {
    fn default() -> PollTimeout {
        PollTimeout::DEFAULT
    }
}

/// Why a row could not be rendered. The driver returns one of these instead
/// of hanging or panicking.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Error {
    /// The frame buffer address is not 8-byte aligned; nothing was
    /// accessed.
    FrameBaseMisaligned {
        /// The rejected bus address.
        base: u32,
    },
    /// A write of the frame DMA failed (FRAME_STATUS error): rows `0..rows`
    /// landed, the rest of the frame is not to be trusted.
    DmaError {
        /// Rows that landed before the failure.
        rows: u16,
    },
    /// The frame was stopped before its end by an abort
    /// ([`Accelerator::abort_frame`]): rows `0..rows` landed.
    FrameAborted {
        /// Rows that landed before the abort.
        rows: u16,
    },
    /// A frame was asked of an accelerator whose map version has no frame
    /// DMA (version 1).
    NoFrameMode {
        /// The map version it reports.
        version: u16,
    },
    /// `row_y` is not a row of the frame (`>= 360`); nothing was accessed.
    RowOutOfRange {
        /// The rejected row.
        row_y: u16,
    },
    /// A raw light component does not fit a Q13.10 word; nothing was
    /// accessed.
    LightOutOfRange(LightError),
    /// The ID register does not hold [`ID_VALUE`]: no ray tracer (or another
    /// version) is configured. `0xFFFF_FFFF` means nothing answers on the
    /// bus. Nothing was written.
    NotPresent {
        /// What the ID register read.
        id: u32,
    },
    /// STATUS (or FRAME_STATUS, while aborting a frame) did not show the
    /// awaited state within the [`PollTimeout`]: busy still set (a stuck row
    /// or frame) or, with busy clear, done never set. The next call starts
    /// over and works once the device recovers.
    Timeout {
        /// The last status value read.
        status: u32,
    },
    /// A read returned bits the device always reads as 0 (for example all
    /// ones from a bridge that stopped answering mid-row).
    BusFault {
        /// Offset of the read inside the bridge window.
        offset: usize,
        /// The value read.
        value: u32,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::FrameBaseMisaligned { base } => write!(f, "frame base {base:#010x} is not 8-byte aligned"),
            Error::DmaError { rows } => write!(f, "frame DMA write failed after {rows} rows"),
            Error::FrameAborted { rows } => write!(f, "frame aborted after {rows} rows"),
            Error::NoFrameMode { version } => {
                write!(f, "register map version {version} has no frame mode (needs {ID_VERSION_FRAMES})")
            }
            Error::RowOutOfRange { row_y } => {
                write!(f, "row {row_y} is out of range (0..{ROWS})")
            }
            Error::LightOutOfRange(e) => write!(f, "{e}"),
            Error::NotPresent { id } => {
                write!(f, "accelerator not present: ID reads {id:#010x}, expected {ID_VALUE:#010x}")
            }
            Error::Timeout { status } => {
                write!(f, "accelerator timed out (STATUS {status:#x})")
            }
            Error::BusFault { offset, value } => {
                write!(f, "bus fault: offset {offset:#x} read {value:#010x}")
            }
        }
    }
}

impl core::error::Error for Error {}

impl From<LightError> for Error {
    fn from(e: LightError) -> Error {
        Error::LightOutOfRange(e)
    }
}

/// What [`Accelerator::probe`] found.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Capabilities {
    /// The register-map version (ID bits 15:0).
    pub version: u16,
}

impl Capabilities {
    /// Whether the frame DMA registers exist (map version 2 or later).
    pub const fn frames(&self) -> bool {
        self.version >= ID_VERSION_FRAMES
    }
}

/// Progress of a frame in frame mode.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct FrameProgress {
    /// Rows `0..rows` have landed in memory.
    pub rows: u16,
    /// Every row landed and the accelerator is idle.
    pub done: bool,
}

/// The row and frame driver over a register port `P`, polling with delay `D`.
///
/// The same code drives the MMIO block on the board and the simulated
/// device on the host.
pub struct Accelerator<P, D> {
    port: P,
    delay: D,
    timeout: PollTimeout,
    caps: Option<Capabilities>,
    /// The LIGHT_* values last written, if they are known to be in the
    /// registers: rows and frames of one light write them once. Forgotten
    /// on any error, so a reset or reconfigured accelerator gets them again.
    light_written: Option<[u32; 3]>,
}

impl<P: RegisterPort, D: DelayNs> Accelerator<P, D> {
    /// A driver for the accelerator behind `port`. Touches nothing yet.
    pub fn new(port: P, delay: D, timeout: PollTimeout) -> Accelerator<P, D> {
        Accelerator { port, delay, timeout, caps: None, light_written: None }
    }

    /// Check that a ray tracer answers: the ID register holds the magic
    /// [`ID_MAGIC`] and a map version from 1 on. Only reads ID. Call it once
    /// before the first row or frame (the row and frame calls do not read
    /// ID again; a device that vanishes later shows up in STATUS, which then
    /// reads all ones: [`Error::BusFault`]).
    pub fn probe(&mut self) -> Result<Capabilities, Error> {
        let id = self.port.read(Csr::Id);
        let version = (id & 0xffff) as u16;
        if id >> 16 == u32::from(ID_MAGIC) && version >= 1 {
            let caps = Capabilities { version };
            self.caps = Some(caps);
            Ok(caps)
        } else {
            Err(Error::NotPresent { id })
        }
    }

    /// Render row `row_y` lit by `light` and copy its 480 `0x00RRGGBB` words
    /// into `out`, equal to `model::render_row(row_y, light, out)`:
    /// [`start_row`](Self::start_row) then [`finish_row`](Self::finish_row).
    /// On error `out` is unspecified.
    pub fn run_row(&mut self, row_y: u16, light: &Light, out: &mut [u32; LINE_WORDS]) -> Result<(), Error> {
        self.start_row(row_y, light)?;
        self.finish_row(out)
    }

    /// Start row `row_y` lit by `light`: wait until nothing is in progress
    /// (a start while busy would be ignored and the old row reported as this
    /// one), write ROW_Y and LIGHT_X/Y/Z, clear a stale done, start. Bounded
    /// by the [`PollTimeout`].
    pub fn start_row(&mut self, row_y: u16, light: &Light) -> Result<(), Error> {
        if row_y >= ROWS {
            return Err(Error::RowOutOfRange { row_y });
        }
        self.poll_status(|s| s & STATUS_BUSY == 0)?;
        self.port.write(Csr::RowY, u32::from(row_y));
        self.write_light(light);
        // A start also clears a latched done (register map): one write.
        self.port.write(Csr::Control, CONTROL_START);
        Ok(())
    }

    /// Wait for the row [`start_row`](Self::start_row) began, copy the line
    /// buffer into `out` and check its reserved bits. Bounded by the
    /// [`PollTimeout`]. The accelerator is idle again on return, so the next
    /// row can start before this one is used.
    pub fn finish_row(&mut self, out: &mut [u32; LINE_WORDS]) -> Result<(), Error> {
        self.poll_status(|s| s & STATUS_DONE != 0)?;
        self.port.read_line(out);
        match (0..).zip(out.iter()).find(|(_, w)| **w & PIXEL_RESERVED_MASK != 0) {
            Some((x, &value)) => self.fail(Error::BusFault { offset: line_word_offset(x), value }),
            None => Ok(()),
        }
    }

    /// Start rendering a whole frame lit by `light` into the frame buffer at
    /// bus address `base` (8-byte aligned; [`FRAME_BYTES`](crate::map::FRAME_BYTES)
    /// long): wait until nothing is in progress, write FRAME_BASE and
    /// LIGHT_*, start. Then poll [`frame_progress`](Self::frame_progress).
    /// Needs map version 2 ([`Capabilities::frames`]; refused if
    /// [`probe`](Self::probe) found version 1).
    pub fn start_frame(&mut self, base: u32, light: &Light) -> Result<(), Error> {
        if let Some(caps) = self.caps.filter(|c| !c.frames()) {
            return Err(Error::NoFrameMode { version: caps.version });
        }
        if base & !FRAME_BASE_MASK != 0 {
            return Err(Error::FrameBaseMisaligned { base });
        }
        self.poll_status(|s| s & STATUS_BUSY == 0)?;
        self.write_light(light);
        self.port.write(Csr::FrameBase, base);
        self.port.write(Csr::FrameControl, FRAME_CONTROL_START);
        Ok(())
    }

    /// How far the frame [`start_frame`](Self::start_frame) began has come:
    /// the rows whose bytes have landed in memory (read them after a `dmb`),
    /// and whether the frame is done. A failed DMA write is
    /// [`Error::DmaError`]; a value no accelerator reports (reserved bits,
    /// more than 360 rows) is [`Error::BusFault`]. One FRAME_STATUS and one
    /// ROWS_DONE read; never waits.
    pub fn frame_progress(&mut self) -> Result<FrameProgress, Error> {
        let status = self.port.read(Csr::FrameStatus);
        if status & !FRAME_STATUS_MASK != 0 {
            return self.fail(Error::BusFault { offset: CSR_OFFSET + Csr::FrameStatus.offset(), value: status });
        }
        let rows = self.port.read(Csr::RowsDone);
        if rows > u32::from(ROWS) {
            return self.fail(Error::BusFault { offset: CSR_OFFSET + Csr::RowsDone.offset(), value: rows });
        }
        let rows = rows as u16;
        if status & FRAME_STATUS_ERROR != 0 {
            return self.fail(Error::DmaError { rows });
        }
        if status & FRAME_STATUS_ABORTED != 0 {
            return self.fail(Error::FrameAborted { rows });
        }
        Ok(FrameProgress { rows, done: status & FRAME_STATUS_DONE != 0 && status & FRAME_STATUS_BUSY == 0 })
    }

    /// Stop the frame in progress, if any, and wait until the accelerator is
    /// idle: on `Ok` nothing more of that frame lands in memory and its
    /// buffer may be reused (register map, "Stopping a frame"). Bounded by
    /// the [`PollTimeout`]; [`Error::Timeout`] if busy never clears (the
    /// buffer must then stay out of use).
    pub fn abort_frame(&mut self) -> Result<(), Error> {
        let busy = |s: u32| s & FRAME_STATUS_BUSY != 0;
        if !busy(self.read_checked(Csr::FrameStatus, FRAME_STATUS_MASK)?) {
            return Ok(());
        }
        self.port.write(Csr::FrameControl, FRAME_CONTROL_ABORT);
        self.poll(Csr::FrameStatus, FRAME_STATUS_MASK, |s| !busy(s))
    }

    fn write_light(&mut self, light: &Light) {
        let words = light.raw().map(light_to_register);
        if self.light_written == Some(words) {
            return;
        }
        self.port.write(Csr::LightX, words[0]);
        self.port.write(Csr::LightY, words[1]);
        self.port.write(Csr::LightZ, words[2]);
        self.light_written = Some(words);
    }

    /// [`run_row`](Self::run_row) with the light as raw Q13.10 components
    /// `[x, y, z]`, as they arrive on the wire; a component outside
    /// `[-2^23, 2^23)` is [`Error::LightOutOfRange`].
    pub fn run_row_raw(&mut self, row_y: u16, light: [i32; 3], out: &mut [u32; LINE_WORDS]) -> Result<(), Error> {
        if row_y >= ROWS {
            return Err(Error::RowOutOfRange { row_y });
        }
        let light = Light::from_raw(light[0], light[1], light[2])?;
        self.run_row(row_y, &light, out)
    }

    /// Read STATUS until `ready` holds, at most `max_polls` times.
    fn poll_status(&mut self, ready: impl Fn(u32) -> bool) -> Result<(), Error> {
        self.poll(Csr::Status, STATUS_MASK, ready)
    }

    /// Read `csr` (whose bits outside `mask` always read 0).
    fn read_checked(&mut self, csr: Csr, mask: u32) -> Result<u32, Error> {
        let value = self.port.read(csr);
        if value & !mask != 0 {
            return self.fail(Error::BusFault { offset: CSR_OFFSET + csr.offset(), value });
        }
        Ok(value)
    }

    /// Read `csr` until `ready` holds, at most `max_polls` times.
    fn poll(&mut self, csr: Csr, mask: u32, ready: impl Fn(u32) -> bool) -> Result<(), Error> {
        let mut polls_left = self.timeout.max_polls;
        loop {
            let status = self.read_checked(csr, mask)?;
            if ready(status) {
                return Ok(());
            }
            // `PollTimeout` keeps `max_polls >= 1`: this is a real read's count.
            polls_left = polls_left.saturating_sub(1);
            if polls_left == 0 {
                return self.fail(Error::Timeout { status });
            }
            self.delay.delay_ns(self.timeout.poll_interval_ns);
        }
    }

    /// An error: the accelerator's state is unknown from here on, so the
    /// light is written again next time.
    fn fail<T>(&mut self, e: Error) -> Result<T, Error> {
        self.light_written = None;
        Err(e)
    }

    /// The polling bound in use.
    pub fn timeout(&self) -> PollTimeout {
        self.timeout
    }

    /// Change the polling bound.
    pub fn set_timeout(&mut self, timeout: PollTimeout) {
        self.timeout = timeout;
    }

    /// The register port.
    pub fn port(&self) -> &P {
        &self.port
    }

    /// The register port, mutably (tests inject faults through it).
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// The delay provider.
    pub fn delay(&self) -> &D {
        &self.delay
    }

    /// Give back the port and the delay.
    pub fn release(self) -> (P, D) {
        (self.port, self.delay)
    }
}
