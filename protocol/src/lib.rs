//! The ray tracer's wire protocol, once for every server and client.
//!
//! * [`wire`]: the 12-byte request (light x, y, z as big-endian signed
//!   32-bit Q13.10), its encoder and decoder, and the two TCP ports
//!   ([`wire::FRAME_PORT`], and the persistent port one above it).
//! * [`time`]: [`time::Instant`], the millisecond clock the server runs on.
//! * [`server`]: the sans-IO frame-server state machine: bytes in, actions
//!   out. It knows no sockets, clocks or renderers.
//! * [`frames`]: where frames come from: rendered a row at a time (row
//!   mode), or whole frames in a ring of slots filled by an engine (frame
//!   mode), the same streaming code for both.
//! * [`rtp`]: frames as an RTP stream (RFC 3550, RFC 4175: one row a
//!   packet) with RTCP sender reports, NACK parsing (RFC 4585) and the
//!   bookkeeping to resend lost rows from the frame ring.
//! * [`monitor`]: the board on its own: the VGA display following the
//!   newest frame, attract mode, keys, switches, LEDs and 7-segment text.
//! * [`orbit`]: the light orbiting the sphere, the path `rt-client orbit`
//!   takes, by frame or by time.
//! * [`rtsp`]: the board as a network camera: the sans-IO RTSP/1.0 server
//!   (port [`rtsp::RTSP_PORT`]): stream URLs, sessions, SDP, actions for the
//!   RTP sender.
//! * [`camera`]: the RTP sender behind the RTSP server: per playing
//!   session, frames paced from a frame ring, rows handed to the caller's
//!   sink, NACKs answered from the repair window, sender reports.
//! * [`receiver`]: the client's end of the RTP stream: datagrams to whole
//!   frames (exact, repaired or damaged), lost frames counted, NACKs out.
//! * [`rows`]: where rows come from ([`RowSource`], the software
//!   renderer), below the server, the frame sources and the fallback.
//! * [`fallback`]: a row source that falls back to another where it fails,
//!   and switches a wedged one off.
//! * `service` (feature `smoltcp`): the server bound to smoltcp TCP sockets,
//!   as the firmware runs it.
//! * `camera_service` (feature `smoltcp`): the network camera bound to
//!   smoltcp (RTSP on TCP, RTCP on UDP) with rows leaving through a
//!   zero-copy transmitter beside smoltcp.
//!
//! The answer to a request is one frame of 518,400 bytes: 480 x 360 RGB888,
//! row-major, top row first ([`model::FRAME_BYTES`]).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]

pub mod camera;
#[cfg(feature = "smoltcp")]
pub mod camera_service;
pub mod fallback;
pub mod frames;
pub mod monitor;
pub mod orbit;
pub mod receiver;
pub mod rows;
pub mod rtp;
pub mod rtsp;
pub mod server;
#[cfg(feature = "smoltcp")]
pub mod service;
pub mod time;
pub mod wire;

pub use frames::{
    Completed, EngineError, FallbackEngine, FrameEngine, FrameMemory, FrameRing, FrameSource, RowEngine, RowFrames,
    SliceMemory, Watchdog, WatchdogError,
};
pub use rows::{RowSource, SoftwareRenderer};
pub use server::{Action, Closed, Mode, Session};
pub use time::Instant;
pub use wire::{
    decode_request, encode_raw_request, encode_request, persistent_port, FRAME_PORT, PERSISTENT_PORT, REQUEST_BYTES,
};
