//! The board found by name: an mDNS responder (RFC 6762) for `NAME.local`
//! and DNS-SD (RFC 6763) records for its three services (the page,
//! `_http._tcp`; the camera, `_rtsp._tcp`; the seed protocol,
//! `_raytracer._tcp`), so that `http://raytracer.local/` opens the page and
//! a browser of services (avahi-browse, Bonjour, python-zeroconf,
//! `rt-client discover`) lists the board.
//!
//! * [`wire`]: the DNS message format, as far as the responder needs it.
//! * [`responder`]: probing, announcing, answering, conflicts; sans-IO.
//! * `service` (feature `smoltcp`): the responder on a smoltcp UDP socket
//!   at 224.0.0.251:5353.

pub mod responder;
#[cfg(feature = "smoltcp")]
pub mod service;
pub mod wire;
