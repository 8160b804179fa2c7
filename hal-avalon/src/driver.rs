//! The row driver: render one row on the accelerator and copy it out.

use core::fmt;

use embedded_hal::delay::DelayNs;
use model::{Light, LightError};

use crate::map::{
    light_to_register, line_word_offset, Csr, CONTROL_CLEAR_DONE, CONTROL_START, CSR_OFFSET, ID_VALUE, LINE_WORDS,
    PIXEL_RESERVED_MASK, ROWS, STATUS_BUSY, STATUS_DONE, STATUS_MASK,
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
    /// STATUS did not show the awaited state within the [`PollTimeout`]:
    /// busy still set (a stuck row) or, with busy clear, done never set.
    /// The next call starts over and works once the device recovers.
    Timeout {
        /// The last STATUS value read.
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

impl From<LightError> for Error {
    fn from(e: LightError) -> Error {
        Error::LightOutOfRange(e)
    }
}

/// The row driver over a register port `P`, polling with delay `D`.
///
/// The same code drives the MMIO block on the board and the simulated
/// device on the host.
pub struct Accelerator<P, D> {
    port: P,
    delay: D,
    timeout: PollTimeout,
}

impl<P: RegisterPort, D: DelayNs> Accelerator<P, D> {
    /// A driver for the accelerator behind `port`. Touches nothing yet.
    pub fn new(port: P, delay: D, timeout: PollTimeout) -> Accelerator<P, D> {
        Accelerator { port, delay, timeout }
    }

    /// Check that a ray tracer of the supported version answers: the ID
    /// register reads [`ID_VALUE`]. Only reads ID.
    pub fn probe(&mut self) -> Result<(), Error> {
        match self.port.read(Csr::Id) {
            ID_VALUE => Ok(()),
            id => Err(Error::NotPresent { id }),
        }
    }

    /// Render row `row_y` lit by `light` and copy its 480 `0x00RRGGBB` words
    /// into `out`, equal to `model::render_row(row_y, light, out)`.
    ///
    /// The protocol: check ID; wait until no row is in progress; write
    /// ROW_Y and LIGHT_X/Y/Z; clear a stale done; start; poll STATUS until
    /// done; copy the line buffer and check its reserved bits. Every wait
    /// is bounded by the [`PollTimeout`]. On error `out` is unspecified.
    pub fn run_row(&mut self, row_y: u16, light: &Light, out: &mut [u32; LINE_WORDS]) -> Result<(), Error> {
        if row_y >= ROWS {
            return Err(Error::RowOutOfRange { row_y });
        }
        self.probe()?;

        // A start while busy would be ignored and the old row reported as
        // this one: let a row still running (say after a timeout) finish.
        self.poll_status(|s| s & STATUS_BUSY == 0)?;

        let [x, y, z] = light.raw();
        self.port.write(Csr::RowY, u32::from(row_y));
        self.port.write(Csr::LightX, light_to_register(x));
        self.port.write(Csr::LightY, light_to_register(y));
        self.port.write(Csr::LightZ, light_to_register(z));
        self.port.write(Csr::Control, CONTROL_CLEAR_DONE);
        self.port.write(Csr::Control, CONTROL_START);

        self.poll_status(|s| s & STATUS_DONE != 0)?;

        self.port.read_line(out);
        match (0..).zip(out.iter()).find(|(_, w)| **w & PIXEL_RESERVED_MASK != 0) {
            Some((x, &value)) => Err(Error::BusFault { offset: line_word_offset(x), value }),
            None => Ok(()),
        }
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
        let mut polls_left = self.timeout.max_polls;
        loop {
            let status = self.port.read(Csr::Status);
            if status & !STATUS_MASK != 0 {
                let offset = CSR_OFFSET + Csr::Status.offset();
                return Err(Error::BusFault { offset, value: status });
            }
            if ready(status) {
                return Ok(());
            }
            // `PollTimeout` keeps `max_polls >= 1`: this is a real read's count.
            polls_left = polls_left.saturating_sub(1);
            if polls_left == 0 {
                return Err(Error::Timeout { status });
            }
            self.delay.delay_ns(self.timeout.poll_interval_ns);
        }
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
