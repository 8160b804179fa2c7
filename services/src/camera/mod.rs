//! The board as a network camera: RTSP sessions, their RTP streams, and
//! the receiving end clients use.
//!
//! Formats apart from behaviour, as smoltcp keeps `wire` apart from its
//! sockets:
//!
//! * [`rtp`]: the RTP packet of one row (RFC 3550, RFC 4175) and its
//!   numbering ([`rtp::Packetiser`]).
//! * [`frame_header`]: the whole 62-byte header the board's zero-copy path
//!   puts in front of a row (Ethernet, IPv4, UDP, RTP).
//! * [`rtcp`]: sender reports, SDES, the receivers' generic NACKs (RFC 4585).
//! * [`repair`]: which slot and row each recent packet came from, so a
//!   NACKed packet can be sent again unchanged.
//! * [`rtsp`]: the sans-IO RTSP/1.0 server (RFC 2326): stream URLs,
//!   sessions, SDP, actions for the sender.
//! * [`sender`]: the RTP sender behind it: frames paced from the frame
//!   ring, rows handed to the caller's sink, NACKs answered.
//! * `service` (feature `smoltcp`): all of it on smoltcp sockets, rows out
//!   through a zero-copy transmitter, as the firmware runs it; `snoop`
//!   (feature `smoltcp`): what the received frames tell it (next hops,
//!   ICMP port unreachable).
//! * [`receiver`]: the client's end: datagrams to whole frames, NACKs out.

pub mod frame_header;
pub mod random;
pub mod receiver;
pub mod repair;
pub mod rtcp;
pub mod rtp;
pub mod rtsp;
pub mod sdp;
pub mod sender;
#[cfg(feature = "smoltcp")]
pub mod service;
#[cfg(feature = "smoltcp")]
pub mod snoop;
pub mod url;
