//! Host side of the ray tracer workspace: the root package.
//!
//! * [`hps_sim`]: the simulated board (the firmware's frame server on std TCP
//!   with hal-avalon's simulated accelerator), used by the `hps-sim` binary,
//!   the integration tests in `tests/` and the client's in-process mode.
#![warn(missing_docs)]

pub mod hps_sim;
