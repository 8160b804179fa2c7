//! Firmware library: everything of the firmware that can be built and tested
//! on the host. The Cortex-A9 binary (`src/main.rs`) adds start-up and boards.
//!
//! * [`server`]: the sans-IO frame-server state machine (bytes in, actions out).
//! * [`service`]: binds sessions to smoltcp TCP sockets on ports 7878 / 7879.
//! * [`drivers`]: UART, global timer, DesignWare MAC + smoltcp device, PHY.
//! * [`arch`]: barriers and the MMU's section-table encoding.
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]

pub mod arch;
pub mod drivers;
pub mod server;
pub mod service;
