//! The board's application: the services it offers on the network and the
//! frames they share, as sans-IO state machines that the firmware binds to
//! smoltcp and `hps-sim` to std sockets; and the client ends of the same
//! protocols.
//!
//! * [`address`]: the board's IPv4 address on any network: the settings
//!   file on the card, DHCP, an RFC 3927 link-local address.
//! * [`frames`]: where every service's frames come from: the ring of frame
//!   slots the FPGA (or the software renderer) fills, row mode, the engines'
//!   fallback and watchdog, and the rules by which services share slots.
//! * [`seed`]: the seed protocol's frame server (TCP 7878, and the
//!   persistent port 7879): 12 bytes in, one frame out.
//! * [`camera`]: the network camera: RTSP sessions (TCP 8554), their RTP
//!   streams (RFC 4175, one row a packet) with NACK repair, and the
//!   receiver clients use.
//! * [`mdns`]: the board found by name: `NAME.local` and its services
//!   (RFC 6762 mDNS, RFC 6763 DNS-SD).
//! * [`monitor`]: the board on its own: the VGA display following the
//!   newest frame, attract mode, keys, switches, LEDs and 7-segment text.
//! * [`orbit`]: the light orbiting the sphere, by frame or by time.
//! * [`web`]: the board's web page (HTTP 80): the live picture in a browser,
//!   frames over a WebSocket, the board's status as JSON.
//! * `snoop` (feature `smoltcp`): a device wrapper that shows received
//!   frames to the camera's peer table and the link-local claim.
//! * `tcp` (feature `smoltcp`): what the smoltcp services share, the
//!   buffers lent to each socket.
//! * [`time`]: [`time::Instant`], the millisecond clock the services run on.
//!
//! A frame is 518,400 bytes: 480 x 360 RGB888, row-major, top row first
//! ([`model::FRAME_BYTES`]).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]

pub mod address;
pub mod camera;
pub mod frames;
pub mod mdns;
pub mod monitor;
pub mod multicast;
pub mod orbit;
pub mod seed;
#[cfg(feature = "smoltcp")]
pub mod snoop;
#[cfg(feature = "smoltcp")]
pub mod tcp;
pub mod time;
pub mod web;

pub use frames::{
    Completed, EngineError, FallbackEngine, FrameEngine, FrameMemory, FrameRing, FrameSource, RowEngine, RowFrames,
    RowSource, SliceMemory, SoftwareRenderer, Watchdog, WatchdogError,
};
pub use seed::server::{Action, Closed, Mode, Session};
pub use seed::wire::{
    decode_request, encode_raw_request, encode_request, persistent_port, FRAME_PORT, PERSISTENT_PORT, REQUEST_BYTES,
};
pub use time::Instant;

/// The board's host name unless its card names another: `raytracer.local`
/// by mDNS, and the one name its web page answers to besides addresses and
/// `localhost` ([`web::guard`]).
pub const DEFAULT_HOST_NAME: &str = "raytracer";
