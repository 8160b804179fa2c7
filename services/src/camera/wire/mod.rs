//! The camera's packet formats, apart from any state or clock (as
//! smoltcp's `wire` is apart from its sockets): what goes on the wire and
//! how to read it back, byte for byte.

pub mod rtcp;
pub mod rtp;
