//! The request on the wire and the two ports.
//!
//! A request is 12 bytes: light x, y, z as big-endian signed 32-bit Q13.10
//! words, each valid in `[-2^23, 2^23)`. Values outside that range are
//! rejected by the server, never wrapped.

use model::{Light, LightError};

/// Bytes of one request.
pub const REQUEST_BYTES: usize = 12;

/// TCP port of the seed protocol: one request, one frame, close.
pub const FRAME_PORT: u16 = 7878;

/// TCP port of the persistent protocol: pipelined requests, frames in order.
pub const PERSISTENT_PORT: u16 = match persistent_port(FRAME_PORT) {
    Some(p) => p,
    None => panic!("FRAME_PORT + 1 is a port"),
};

/// The persistent port that goes with a frame port: the next one up, or
/// `None` for port 65535 (which has no successor).
pub const fn persistent_port(frame_port: u16) -> Option<u16> {
    frame_port.checked_add(1)
}

/// The request for `light`.
pub fn encode_request(light: &Light) -> [u8; REQUEST_BYTES] {
    encode_raw_request(light.raw())
}

/// A request with raw components `[x, y, z]`, in range or not (tests and
/// tools send out-of-range lights on purpose).
pub fn encode_raw_request(raw: [i32; 3]) -> [u8; REQUEST_BYTES] {
    let mut out = [0u8; REQUEST_BYTES];
    for (chunk, v) in out.chunks_exact_mut(4).zip(raw) {
        chunk.copy_from_slice(&v.to_be_bytes());
    }
    out
}

/// The light of a request, or which component is out of range.
pub fn decode_request(bytes: &[u8; REQUEST_BYTES]) -> Result<Light, LightError> {
    let [x, y, z] = raw_components(bytes);
    Light::from_raw(x, y, z)
}

/// The three big-endian `i32` of a request, unchecked.
pub fn raw_components(bytes: &[u8; REQUEST_BYTES]) -> [i32; 3] {
    let word = |i: usize| i32::from_be_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    [word(0), word(4), word(8)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::light::Axis;

    #[test]
    fn requests_round_trip_big_endian() {
        let l = Light::from_world(3.0, 4.0, -2.0).unwrap();
        let w = encode_request(&l);
        assert_eq!(w, [0, 0, 0x0c, 0x00, 0, 0, 0x10, 0x00, 0xff, 0xff, 0xf8, 0x00]);
        assert_eq!(decode_request(&w), Ok(l));
        assert_eq!(raw_components(&w), [3072, 4096, -2048]);
    }

    #[test]
    fn out_of_range_components_are_rejected_not_wrapped() {
        let bad = encode_raw_request([1 << 23, 0, 0]);
        assert_eq!(bad[..4], [0x00, 0x80, 0, 0]);
        assert_eq!(decode_request(&bad).unwrap_err().axis, Axis::X);
        assert_eq!(decode_request(&encode_raw_request([0, 0, -(1 << 23) - 1])).unwrap_err().axis, Axis::Z);
        assert!(decode_request(&encode_raw_request([-(1 << 23), (1 << 23) - 1, 0])).is_ok());
    }

    #[test]
    fn the_persistent_port_is_the_next_one() {
        assert_eq!((FRAME_PORT, PERSISTENT_PORT), (7878, 7879));
        assert_eq!(persistent_port(40_000), Some(40_001));
        assert_eq!(persistent_port(u16::MAX), None);
    }
}
