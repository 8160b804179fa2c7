//! WebSocket (RFC 6455) as the page's frame channel uses it: the opening
//! handshake's accept key, the client's frame heads checked as section 5
//! requires of a server, and the server's frame heads.
//!
//! Why not a WebSocket crate: embedded-websocket 0.9 (the no_std one) reads
//! unmasked client frames without a word (section 5.1 requires the server
//! to close on them), ignores the reserved bits, and writes a message only
//! from one slice it copies, where a frame's 518,400 bytes go from the
//! ring's slot straight into the socket; it would also bring second copies
//! of heapless and rand_core. What is left is a frame head: ten lines
//! each way, checked here against the RFC's examples and in the host
//! tests against tungstenite, a client written by others. The handshake's
//! hash and encoding do come from crates (sha1, base64).

use base64::Engine;
use sha1::{Digest, Sha1};

/// The GUID of the accept key (RFC 6455, section 1.3).
const ACCEPT_GUID: &[u8] = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11";

/// The most payload of a control frame (section 5.5).
pub const CONTROL_PAYLOAD: usize = 125;

/// The longest client frame head: 2 bytes, 8 of length, 4 of mask.
pub const MAX_HEAD: usize = 14;

/// `Sec-WebSocket-Accept` for a `Sec-WebSocket-Key`: base64 of the SHA-1 of
/// the key and the GUID (section 4.2.2, item 5.4).
pub fn accept_key(key: &[u8; 24]) -> [u8; 28] {
    let digest = Sha1::new().chain_update(key).chain_update(ACCEPT_GUID).finalize();
    let mut out = [0u8; 28];
    // 20 bytes encode to exactly 28 characters.
    let _ = base64::engine::general_purpose::STANDARD.encode_slice(digest, &mut out);
    out
}

/// A frame's opcode (section 5.2).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Opcode {
    /// 0: a later fragment of a message.
    Continuation,
    /// 1: UTF-8 text.
    Text,
    /// 2: binary data.
    Binary,
    /// 8: the closing handshake.
    Close,
    /// 9.
    Ping,
    /// 10.
    Pong,
}

impl Opcode {
    fn from_bits(bits: u8) -> Option<Opcode> {
        Some(match bits {
            0 => Opcode::Continuation,
            1 => Opcode::Text,
            2 => Opcode::Binary,
            8 => Opcode::Close,
            9 => Opcode::Ping,
            10 => Opcode::Pong,
            _ => return None,
        })
    }

    /// Close, ping or pong.
    pub const fn is_control(self) -> bool {
        matches!(self, Opcode::Close | Opcode::Ping | Opcode::Pong)
    }
}

/// Close status codes the server sends (section 7.4.1).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum CloseCode {
    /// 1000: done.
    Normal,
    /// 1001: the server is going away from this connection (idle).
    GoingAway,
    /// 1002: a frame against the protocol (unmasked, reserved bits or
    /// opcodes, a bad control frame).
    ProtocolError,
    /// 1003: a kind of data not accepted (text).
    UnsupportedData,
    /// 1007: a message inconsistent with its type (not a 12-byte request, or
    /// a light out of range).
    InvalidPayload,
    /// 1008: against the page's protocol (a fragmented message).
    PolicyViolation,
    /// 1009: a message too big to take.
    MessageTooBig,
    /// 1011: the server could not go on (the renderer failed).
    InternalError,
}

impl CloseCode {
    /// The code on the wire.
    pub const fn code(self) -> u16 {
        match self {
            CloseCode::Normal => 1000,
            CloseCode::GoingAway => 1001,
            CloseCode::ProtocolError => 1002,
            CloseCode::UnsupportedData => 1003,
            CloseCode::InvalidPayload => 1007,
            CloseCode::PolicyViolation => 1008,
            CloseCode::MessageTooBig => 1009,
            CloseCode::InternalError => 1011,
        }
    }
}

/// A client frame's head, checked.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct FrameHead {
    /// The last frame of its message.
    pub fin: bool,
    /// Its opcode.
    pub opcode: Opcode,
    /// The masking key (every client frame has one).
    pub mask: [u8; 4],
    /// Payload bytes.
    pub len: u64,
    /// Bytes of the head itself.
    pub head_len: usize,
}

/// Parse the head at the start of `buf`: `Ok(None)` until it is complete,
/// an error for a head a server must refuse (section 5.1: unmasked; 5.2:
/// reserved bits without an extension, reserved opcodes, a length with its
/// top bit set; 5.5: a fragmented or long control frame).
pub fn parse_head(buf: &[u8]) -> Result<Option<FrameHead>, CloseCode> {
    let [b0, b1, ..] = *buf else { return Ok(None) };
    if b0 & 0x70 != 0 {
        return Err(CloseCode::ProtocolError);
    }
    let opcode = Opcode::from_bits(b0 & 0x0f).ok_or(CloseCode::ProtocolError)?;
    let fin = b0 & 0x80 != 0;
    if b1 & 0x80 == 0 {
        return Err(CloseCode::ProtocolError);
    }
    let (len, at) = match b1 & 0x7f {
        126 => match buf.get(2..4) {
            Some(b) => (u64::from(u16::from_be_bytes([b[0], b[1]])), 4),
            None => return Ok(None),
        },
        127 => match buf.get(2..10) {
            Some(b) => {
                let mut n = [0u8; 8];
                n.copy_from_slice(b);
                (u64::from_be_bytes(n), 10)
            }
            None => return Ok(None),
        },
        n => (u64::from(n), 2),
    };
    if len >> 63 != 0 {
        return Err(CloseCode::ProtocolError);
    }
    if opcode.is_control() && (!fin || len > CONTROL_PAYLOAD as u64) {
        return Err(CloseCode::ProtocolError);
    }
    let Some(m) = buf.get(at..at + 4) else { return Ok(None) };
    Ok(Some(FrameHead { fin, opcode, mask: [m[0], m[1], m[2], m[3]], len, head_len: at + 4 }))
}

/// Unmask `payload` in place with `mask` (section 5.3); `payload` starts at
/// the frame's first payload byte.
pub fn unmask(payload: &mut [u8], mask: [u8; 4]) {
    for (i, b) in payload.iter_mut().enumerate() {
        *b ^= mask[i % 4];
    }
}

/// The head of an unfragmented, unmasked server frame with `len` payload
/// bytes: the bytes and how many of them are used (2, 4 or 10).
pub fn server_head(opcode: Opcode, len: u64) -> ([u8; 10], usize) {
    server_head_fin(opcode, len, true)
}

/// A first fragment of a binary message with no payload (section 5.4: FIN
/// clear, opcode 2, length 0): two bytes that move what follows by two, so
/// that a frame's rows after its 10-byte head land word aligned in the
/// transport (`server::Connection`). The message goes on in a
/// continuation frame; browsers join the fragments.
pub const EMPTY_FIRST_FRAGMENT: [u8; 2] = [0x02, 0x00];

/// A server frame head with FIN as given.
fn server_head_fin(opcode: Opcode, len: u64, fin: bool) -> ([u8; 10], usize) {
    let bits = match opcode {
        Opcode::Continuation => 0,
        Opcode::Text => 1,
        Opcode::Binary => 2,
        Opcode::Close => 8,
        Opcode::Ping => 9,
        Opcode::Pong => 10,
    };
    let mut head = [0u8; 10];
    head[0] = if fin { 0x80 } else { 0 } | bits;
    if len < 126 {
        head[1] = len as u8;
        (head, 2)
    } else if let Ok(short) = u16::try_from(len) {
        head[1] = 126;
        head[2..4].copy_from_slice(&short.to_be_bytes());
        (head, 4)
    } else {
        head[1] = 127;
        head[2..10].copy_from_slice(&len.to_be_bytes());
        (head, 10)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_accept_key_is_the_rfcs_example() {
        // RFC 6455, section 1.3.
        assert_eq!(&accept_key(b"dGhlIHNhbXBsZSBub25jZQ=="), b"s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
    }

    #[test]
    fn the_rfcs_masked_hello_parses_and_unmasks() {
        // Section 5.7: a single-frame masked text message "Hello".
        let mut frame = [0x81, 0x85, 0x37, 0xfa, 0x21, 0x3d, 0x7f, 0x9f, 0x4d, 0x51, 0x58];
        let head = parse_head(&frame).unwrap().unwrap();
        assert_eq!((head.fin, head.opcode, head.len, head.head_len), (true, Opcode::Text, 5, 6));
        unmask(&mut frame[6..], head.mask);
        assert_eq!(&frame[6..], b"Hello");
    }

    #[test]
    fn a_head_arriving_a_byte_at_a_time_is_partial_until_whole() {
        let frame = [0x82, 0xfe, 0x01, 0x00, 1, 2, 3, 4];
        for n in 0..frame.len() {
            assert_eq!(parse_head(&frame[..n]), Ok(None), "{n} bytes");
        }
        assert_eq!(parse_head(&frame).unwrap().unwrap().len, 256);
    }

    #[test]
    fn heads_a_server_must_refuse_are_refused() {
        // Section 5.7's unmasked "Hello", from a client: 5.1.
        assert_eq!(parse_head(&[0x81, 0x05, b'H']), Err(CloseCode::ProtocolError));
        assert_eq!(parse_head(&[0xc2, 0x80, 0, 0, 0, 0]), Err(CloseCode::ProtocolError), "RSV1");
        assert_eq!(parse_head(&[0x83, 0x80, 0, 0, 0, 0]), Err(CloseCode::ProtocolError), "opcode 3");
        assert_eq!(parse_head(&[0x09, 0x80, 0, 0, 0, 0]), Err(CloseCode::ProtocolError), "fragmented ping");
        assert_eq!(parse_head(&[0x89, 0xfe, 0, 126, 0, 0, 0, 0]), Err(CloseCode::ProtocolError), "long ping");
        let huge = [0x82, 0xff, 0x80, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(parse_head(&huge), Err(CloseCode::ProtocolError), "63-bit length");
    }

    #[test]
    fn server_heads_use_the_shortest_length() {
        assert_eq!(server_head(Opcode::Pong, 5).0[..2], [0x8a, 5]);
        assert_eq!(server_head(Opcode::Binary, 256).0[..4], [0x82, 126, 1, 0]);
        let (head, n) = server_head(Opcode::Binary, 518_400);
        assert_eq!(&head[..n], &[0x82, 127, 0, 0, 0, 0, 0, 0x07, 0xe9, 0x00]);
    }
}
