//! The firmware's sizes in one place: sockets per service and frame slots
//! of the ring they share. Below every other module (it imports nothing of
//! the binary), so the services (`net`) and the frames (`render`) both take
//! their sizes from here rather than from one another.

/// TCP sockets of the frame service: [`FRAME_PORT_SOCKETS`] on the seed
/// port, the rest on the persistent port. A socket holds one client; the
/// frame ring renders four frames at a time for sessions (six without a
/// VGA display, which keeps two slots), so up to 14 seed-port clients wait
/// their turn beyond those four (docs/reliability.md#overload), and one
/// more arriving while all are taken is refused.
pub const SOCKETS: usize = 24;

/// Sockets on the seed port.
pub const FRAME_PORT_SOCKETS: usize = 18;

/// Frame slots of the ring: four for sessions (one being sent and three to
/// render ahead, for up to four sessions at once) and two the VGA display
/// keeps out of reuse (the frame on screen and the one waiting for vertical
/// blanking, `rt_services::monitor`). Six frames, 3,110,400 bytes, fill the
/// 3 MiB `.frames` region (memory.x).
pub const RING_SLOTS: usize = 6;

/// Row frames in row mode: one per seed-port socket.
pub const ROW_FRAMES: usize = SOCKETS;
