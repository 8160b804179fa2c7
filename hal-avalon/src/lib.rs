//! Hardware access to the FPGA ray-tracing accelerator.
//!
//! The accelerator sits behind the Cyclone V lightweight HPS-to-FPGA bridge:
//! a small CSR block starts one row at a time, a line buffer returns it.
//!
//! * [`map`]: the register map, the single source of truth for every
//!   address and bit (`fpga/` implements the same numbers).
//! * [`port`]: [`RegisterPort`], the one trait through which software touches
//!   the accelerator.
//! * [`mmio`]: [`MmioPort`], the memory-mapped port on the board (the crate's
//!   only raw-pointer code).
//! * [`board`]: [`BoardIo`], the VGA scan-out, keys, switches, LEDs and
//!   7-segment displays (map version 3), and the 7-segment font.
//! * [`driver`]: [`Accelerator`], the row driver generic over the port, with
//!   bounded polling ([`PollTimeout`], an `embedded-hal` [`DelayNs`]) and
//!   [`Error`]s instead of hangs or panics.
//! * `sim` (feature `sim`): `SimAccelerator`, a simulated device built from
//!   [`model`], bit-exact at the register level, with fault injection.
//! * `sources` (feature `services`): the accelerator as the frame server's
//!   row source (row mode) and frame engine (frame mode).
//! * `selftest` (feature `services`): the boot-time self-test, rows and a
//!   frame compared with the model.
//! * `ring_panel` (feature `services`): a frame ring and the board I/O
//!   block behind its engine as the monitor policy's device.
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # #[cfg(feature = "sim")] {
//! use hal_avalon::sim::{CountingDelay, SimAccelerator};
//! use hal_avalon::{Accelerator, PollTimeout};
//!
//! let mut accel = Accelerator::new(SimAccelerator::new(), CountingDelay::default(), PollTimeout::DEFAULT);
//! let light = model::Light::from_raw(3 << 10, 4 << 10, -(2 << 10))?;
//! let mut row = [0u32; 480];
//! accel.run_row(200, &light, &mut row)?;
//!
//! let mut expected = [0u32; 480];
//! model::render_row(200, &light, &mut expected);
//! assert_eq!(row, expected);
//! # }
//! # Ok(())
//! # }
//! ```
//!
//! [`DelayNs`]: embedded_hal::delay::DelayNs
#![no_std]
#![warn(missing_docs)]
#![deny(unsafe_op_in_unsafe_fn)]

pub mod board;
#[cfg(feature = "conformance")]
pub mod conformance;
pub mod driver;
pub mod map;
pub mod mmio;
pub mod port;
#[cfg(feature = "services")]
pub mod ring_panel;
#[cfg(feature = "services")]
pub mod selftest;
#[cfg(feature = "sim")]
pub mod sim;
#[cfg(feature = "services")]
pub mod sources;

pub use board::BoardIo;
pub use driver::{Accelerator, Capabilities, Error, FrameProgress, PollTimeout};
pub use map::Csr;
pub use mmio::MmioPort;
pub use port::{Counted, RegisterPort};
