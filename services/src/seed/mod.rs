//! The seed protocol: 12 bytes in (the light), one 518,400-byte frame out.
//!
//! * [`wire`]: the request codec and the two TCP ports.
//! * [`server`]: the sans-IO frame server: bytes in, actions out.
//! * `service` (feature `smoltcp`): the server on smoltcp TCP sockets, as
//!   the firmware runs it.

pub mod server;

/// TCP sockets of the frame service on the board (both ports; the
/// firmware's `limits` module splits them): a client beyond them is
/// refused. hps-sim serves as many connections at once.
pub const SEED_SOCKETS: usize = 24;

/// Frames the seed frame server holds at once on the board's frame ring
/// (its quota), among all its clients; the others wait their turn.
pub const SEED_FRAMES: usize = 4;

#[cfg(feature = "smoltcp")]
pub mod service;
pub mod wire;
