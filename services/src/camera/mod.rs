//! The board as a network camera: RTSP sessions, their RTP streams, and
//! the receiving end clients use.
//!
//! Formats apart from behaviour, as smoltcp keeps `wire` apart from its
//! sockets:
//!
//! * [`wire`]: the formats, with no state: [`wire::rtp`], the RTP packet
//!   of one row (RFC 3550, RFC 4175) and the interleaved head (RFC 2326
//!   section 10.12); [`wire::rtcp`], sender reports, SDES, BYE, receiver
//!   reports and the receivers' generic NACKs (RFC 4585).
//! * [`packetiser`]: one RTP session's numbering, stamps and counts.
//! * [`report_timer`]: when a stream's sender reports go out.
//! * [`frame_header`]: the whole 62-byte header the board's zero-copy path
//!   puts in front of a row (Ethernet, IPv4, UDP, RTP).
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
//! * [`station`]: the server and the sender wired together, once for the
//!   board's service and the std bindings alike.
//! * [`receiver`]: the client's end: datagrams to whole frames, NACKs out.

pub mod frame_header;
pub mod packetiser;
pub mod random;
pub mod receiver;
pub mod repair;
pub mod report_timer;
pub mod rtsp;
pub mod sdp;
pub mod sender;
#[cfg(feature = "smoltcp")]
pub mod service;
#[cfg(feature = "smoltcp")]
pub mod snoop;
pub mod station;
pub mod url;
pub mod wire;
