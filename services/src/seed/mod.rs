//! The seed protocol: 12 bytes in (the light), one 518,400-byte frame out.
//!
//! * [`wire`]: the request codec and the two TCP ports.
//! * [`server`]: the sans-IO frame server: bytes in, actions out.
//! * `service` (feature `smoltcp`): the server on smoltcp TCP sockets, as
//!   the firmware runs it.

pub mod server;
#[cfg(feature = "smoltcp")]
pub mod service;
pub mod wire;
