//! `hps-linux`: the ray tracer board's services as a Linux program on the
//! DE1-SoC's HPS, for boards that already boot Linux (docs/linux.md).
//!
//! * [`window`]: the lightweight bridge mapped through UIO or /dev/mem,
//!   and the accelerator's registers on it ([`window::MappedPort`], the
//!   same hal-avalon [`MmioPort`](hal_avalon::MmioPort) as on bare metal).
//! * [`preflight`]: the FPGA configured, the bridge out of reset, the ray
//!   tracer answering with a known register map, before the first access;
//!   each refusal names its cause.
//! * [`frame_memory`]: the contiguous buffer frame mode renders into
//!   ([`DmaRing`](frame_memory::DmaRing), mapped non-cached), or why there
//!   is none.
//! * [`panel`]: the VGA monitor, keys, switches, LEDs and displays, as on
//!   bare metal (the firmware's policy), on the board's ring.
//! * [`serve`]: the board the services draw from (rt-services-std's
//!   [`Board`](rt_services_std::board::Board): one engine, one ring, every service
//!   within its quota): the FPGA's frames (or rows, saying why), the
//!   simulated accelerator, or software when told to.

pub mod frame_memory;
pub mod panel;
pub mod preflight;
pub mod serve;
pub mod window;
