//! `hps-linux`: the ray tracer board's services as a Linux program on the
//! DE1-SoC's HPS, for boards that already boot Linux (docs/linux.md).
//!
//! * [`window`]: the lightweight bridge mapped through UIO or /dev/mem,
//!   and the accelerator's registers on it ([`window::MappedPort`], the
//!   same hal-avalon [`MmioPort`](hal_avalon::MmioPort) as on bare metal).
//! * [`preflight`]: the FPGA configured, the bridge out of reset, the ray
//!   tracer answering with a known register map, before the first access;
//!   each refusal names its cause.

pub mod preflight;
pub mod window;
