//! The register port: the only way software touches the accelerator.
//!
//! The [`crate::Accelerator`] driver is generic over [`RegisterPort`]; on
//! the board the port is [`crate::mmio::MmioPort`], on the host the simulated
//! device (`sim::SimAccelerator`, feature `sim`).

use crate::map::{Csr, LINE_WORDS};

/// Word access to the CSR block and the line buffer of one accelerator.
///
/// The methods take `&mut self` because reads have side effects on real
/// hardware and in the simulation (polling STATUS advances the simulated
/// device). Implementations perform at most one bus access per register
/// access, in program order, and never fail: a bus that does not answer shows
/// up in the values read (for example all ones), which the driver checks.
pub trait RegisterPort {
    /// Read one CSR register.
    fn read(&mut self, csr: Csr) -> u32;

    /// Write one CSR register.
    fn write(&mut self, csr: Csr, value: u32);

    /// Read the whole line buffer, word `x` into `out[x]`, in address order.
    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]);
}

impl<P: RegisterPort + ?Sized> RegisterPort for &mut P {
    fn read(&mut self, csr: Csr) -> u32 {
        (**self).read(csr)
    }

    fn write(&mut self, csr: Csr, value: u32) {
        (**self).write(csr, value)
    }

    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        (**self).read_line(out)
    }
}

/// A port that counts its bus accesses (bench builds and cost models).
/// Single register reads and line-buffer words are counted apart: on the
/// board one is a full round trip over the bridge, the other part of a
/// burst.
#[derive(Debug, Default)]
pub struct Counted<P> {
    port: P,
    /// Registers read.
    pub reads: u32,
    /// Line-buffer words read ([`LINE_WORDS`] per line).
    pub line_words: u32,
    /// Registers written.
    pub writes: u32,
}

impl<P> Counted<P> {
    /// Count the accesses to `port`.
    pub fn new(port: P) -> Counted<P> {
        Counted { port, reads: 0, line_words: 0, writes: 0 }
    }

    /// The port.
    pub fn inner(&self) -> &P {
        &self.port
    }

    /// The port, mutably.
    pub fn inner_mut(&mut self) -> &mut P {
        &mut self.port
    }
}

impl<P: RegisterPort> RegisterPort for Counted<P> {
    fn read(&mut self, csr: Csr) -> u32 {
        self.reads = self.reads.wrapping_add(1);
        self.port.read(csr)
    }

    fn write(&mut self, csr: Csr, value: u32) {
        self.writes = self.writes.wrapping_add(1);
        self.port.write(csr, value)
    }

    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        self.line_words = self.line_words.wrapping_add(LINE_WORDS as u32);
        self.port.read_line(out)
    }
}
