//! The board's web page: `http://<board>/` shows the live picture and lets
//! a visitor with nothing but a browser move the light.
//!
//! * [`assets`]: the page's files (`services/web/`), compiled in, served
//!   gzip-compressed to browsers that take it.
//! * [`guard`]: the `Host` and `Origin` checks that keep other web sites
//!   (cross-site WebSockets, DNS rebinding) out.
//! * [`http`]: request heads (httparse) within fixed caps, response heads.
//! * [`websocket`]: RFC 6455's handshake key and frame heads.
//! * [`status`]: `/status`, the board's figures as JSON.
//! * [`server`]: one connection, sans-IO: a file, the status, an error, or
//!   a WebSocket viewer that asks for frames by light and gets each as one
//!   binary message of the exact 518,400 bytes.
//! * `service` (feature `smoltcp`): the connections on smoltcp sockets, as
//!   the firmware runs them.
//!
//! docs/web.md has the protocol, the caps and why these crates.

pub mod assets;
pub mod guard;
pub mod http;
pub mod server;
#[cfg(feature = "smoltcp")]
pub mod service;
pub mod status;
pub mod websocket;

/// The page's TCP port on the board.
pub const WEB_PORT: u16 = 80;

/// TCP sockets of the web page on the board: up to [`WEB_VIEWERS`] hold a
/// viewer each, the others answer the page's files and `/status` (the
/// firmware's `limits` module has the arithmetic); hps-sim serves as many
/// connections at once.
pub const WEB_SOCKETS: usize = 8;

/// WebSocket viewers at once: each holds a frame slot while its frame is
/// rendered and sent (within the ring's web quota), and a socket; more are
/// answered 503 and the page retries.
pub const WEB_VIEWERS: usize = 4;

/// Frames the web page's viewers hold at once on the board's frame ring
/// (their quota): more viewers take turns, each frame being rendered and
/// sent in about a frame time.
pub const WEB_FRAMES: usize = 2;
