//! The firmware's sizes in one place: sockets per service and frame slots
//! of the ring they share. Below every other module (it imports nothing
//! of the binary), so the services (`net`) and the frames (`render`) both take
//! their sizes from here rather than from one another.
//!
//! # The ring's slots
//!
//! Four kinds of user share the ring (`rt_services::frames::share`), each
//! with a bound of its own, and the ring holds the sum, so none can starve
//! another (docs/streaming.md, "Slot arithmetic"):
//!
//! | user | slots | why |
//! |---|---|---|
//! | VGA display | [`DISPLAY_SLOTS`] = 2 | the frame on screen and the one waiting for vertical blanking |
//! | seed frame server | [`SEED_FRAMES`] = 4 | one being sent and three rendering ahead (its quota) |
//! | network camera | [`CAMERA_SLOTS`] = 8 | per stream the frame being sent and the one before it, for repairs; up to four streams |
//! | web page | [`WEB_FRAMES`] = 2 | the frames its viewers' messages carry (its quota), two of its four viewers at once |
//!
//! 16 slots of 518,400 bytes, 8,294,400 bytes, in the 8 MiB (8,388,608
//! bytes) `.frames` region (memory.x): the ring cannot grow further without
//! a bigger region.
//!
//! # The web page's sockets
//!
//! [`WEB_SOCKETS`] = 8 on port 80: up to [`WEB_VIEWERS`] = 4 hold a
//! viewer's WebSocket each; the other four (at least) answer the page's
//! files and `/status`, each answer closing its connection, so a browser
//! loading the page (three files at once, then the status each second) is
//! never refused for want of a socket. Eight sockets of 66 KiB buffers are
//! 528 KiB of RAM.

pub use rt_services::camera::sender::CAMERA_SLOTS;

/// TCP sockets of the frame service: [`FRAME_PORT_SOCKETS`] on the seed
/// port, the rest on the persistent port. A socket holds one client; the
/// frame ring renders [`SEED_FRAMES`] frames at a time for them, so up to
/// 14 seed-port clients wait their turn beyond those four
/// (docs/reliability.md#overload), and one more arriving while all are
/// taken is refused.
pub const SOCKETS: usize = rt_services::seed::SEED_SOCKETS;

/// Sockets on the seed port.
pub const FRAME_PORT_SOCKETS: usize = 18;

/// Slots the VGA display keeps out of reuse (`rt_services::monitor`).
pub const DISPLAY_SLOTS: usize = 2;

/// Frames the seed frame server holds at once (its quota).
pub use rt_services::seed::SEED_FRAMES;

/// Frames the web page's viewers hold at once (their quota).
pub use rt_services::web::WEB_FRAMES;

pub use rt_services::web::WEB_VIEWERS;

/// TCP sockets of the web page (module docs).
pub use rt_services::web::WEB_SOCKETS;

/// Frame slots of the ring: the sum of its users' bounds (module docs).
pub const RING_SLOTS: usize = DISPLAY_SLOTS + SEED_FRAMES + CAMERA_SLOTS + WEB_FRAMES;

/// Row frames in row mode: one per seed-port socket.
pub const ROW_FRAMES: usize = SOCKETS;
