//! One RTSP connection's input: bytes buffered until they frame a request
//! or an interleaved packet (RFC 2326 sections 4 and 10.12), and when the
//! connection last made progress, for the server's deadlines
//! ([`super::Server::connection_expired`]).

use core::net::IpAddr;

use super::message::content_length;
use super::{ConnId, MAX_BODY_BYTES, MAX_HEADER_BYTES, MAX_REQUEST_BYTES};
use crate::time::{Instant, REQUEST_LIMIT};

/// One TCP connection's input: the bytes not yet answered, the peer's
/// address, and when it last made progress (for the server's deadlines,
/// [`super::Server::connection_expired`]).
#[derive(Clone, Debug)]
pub struct Connection {
    id: ConnId,
    peer: IpAddr,
    buf: [u8; MAX_REQUEST_BYTES],
    len: usize,
    /// Bytes still to drop of an interleaved frame too long to buffer.
    skip: usize,
    pub(super) closed: bool,
    /// When it last made progress.
    progress: Progress,
}

impl Connection {
    /// Connection `id` from `peer`, opened at `now`. The caller numbers
    /// its connections; the id binds sessions that carry their RTP on
    /// this connection (`interleaved`).
    pub fn new(id: ConnId, peer: IpAddr, now: Instant) -> Connection {
        Connection {
            id,
            peer,
            buf: [0; MAX_REQUEST_BYTES],
            len: 0,
            skip: 0,
            closed: false,
            progress: Progress { last_request: now, partial_since: None },
        }
    }

    /// The connection's id.
    pub fn id(&self) -> ConnId {
        self.id
    }

    /// The peer's address.
    pub fn peer(&self) -> IpAddr {
        self.peer
    }

    /// Take bytes received at `now`; returns how many were taken. Fewer
    /// than `data.len()` means the buffer is full: call
    /// [`super::Server::handle`], then offer the rest. After a reply that
    /// closes, everything is taken and dropped.
    pub fn receive(&mut self, now: Instant, data: &[u8]) -> usize {
        if self.closed {
            return data.len();
        }
        let skipped = data.len().min(self.skip);
        self.skip -= skipped;
        if skipped > 0 && self.skip == 0 && self.len == 0 {
            // The long interleaved frame is over.
            self.progress.partial_since = None;
        }
        let data = &data[skipped..];
        let n = data.len().min(MAX_REQUEST_BYTES - self.len);
        if n > 0 && self.len == 0 && self.progress.partial_since.is_none() {
            self.progress.partial_since = Some(now);
        }
        self.buf[self.len..self.len + n].copy_from_slice(&data[..n]);
        self.len += n;
        skipped + n
    }

    /// Bytes buffered, not answered yet.
    pub fn buffered(&self) -> usize {
        self.len
    }

    /// Whether nothing is under way: no bytes buffered, no long
    /// interleaved frame being dropped, not closed.
    pub fn is_idle(&self) -> bool {
        self.len == 0 && self.skip == 0 && !self.closed
    }

    /// When it last made progress, for the server's deadlines.
    pub(super) fn progress(&self) -> &Progress {
        &self.progress
    }

    /// Whether a reply closed the connection (input is no longer read).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The bytes of the first `n` buffered.
    pub(super) fn bytes(&self, range: core::ops::Range<usize>) -> &[u8] {
        &self.buf[range]
    }

    /// Drop the first `n` buffered bytes; at `now` a request (or frame)
    /// was complete.
    pub(super) fn consume(&mut self, n: usize, now: Instant) {
        let n = n.min(self.len);
        self.buf.copy_within(n..self.len, 0);
        self.len -= n;
        self.progress.last_request = now;
        // What is left is the start of the next one: its time runs from now.
        self.progress.partial_since = (self.len > 0).then_some(now);
    }

    /// Drop everything and read nothing more (the input cannot be framed).
    pub(super) fn close(&mut self) {
        self.closed = true;
        self.len = 0;
        self.progress.partial_since = None;
    }

    /// Where the first message ends, if it is all here.
    pub(super) fn frame(&mut self) -> Framing {
        // Empty lines between requests are allowed (RFC 2326 section 15.1).
        let blank = self.buf[..self.len].iter().take_while(|&&b| b == b'\r' || b == b'\n').count();
        if blank > 0 {
            let (last, partial) = (self.progress.last_request, self.progress.partial_since);
            self.consume(blank, last);
            self.progress.partial_since = partial.filter(|_| self.len > 0);
        }
        if self.buf[..self.len].first() == Some(&b'$') {
            // RFC 2326 section 10.12: `$`, channel, 16-bit length, data.
            let Some(&[_, channel, hi, lo]) = self.buf[..self.len].first_chunk::<4>() else {
                return Framing::Incomplete;
            };
            let len = usize::from(u16::from_be_bytes([hi, lo]));
            if 4 + len > MAX_REQUEST_BYTES {
                // Longer than anything a client sends us (RTCP): dropped.
                let here = self.len - 4;
                self.skip = len - here;
                let (last, partial) = (self.progress.last_request, self.progress.partial_since);
                self.consume(self.len, last);
                // Still unfinished: its deadline runs on.
                self.progress.partial_since = partial;
                return Framing::Incomplete;
            }
            return if self.len >= 4 + len { Framing::Interleaved { channel, len } } else { Framing::Incomplete };
        }
        let window = &self.buf[..self.len.min(MAX_HEADER_BYTES)];
        let mut end = None;
        for i in 0..window.len() {
            if window[i] != b'\n' {
                continue;
            }
            match window.get(i + 1..) {
                Some([b'\n', ..]) => end = Some(i + 2),
                Some([b'\r', b'\n', ..]) => end = Some(i + 3),
                _ => {}
            }
            if end.is_some() {
                break;
            }
        }
        let Some(head) = end else {
            return if self.len >= MAX_HEADER_BYTES { Framing::Fatal } else { Framing::Incomplete };
        };
        match content_length(&self.buf[..head]) {
            Some(body) if body <= MAX_BODY_BYTES => {
                if self.len >= head + body {
                    Framing::Request { head, body }
                } else {
                    Framing::Incomplete
                }
            }
            _ => Framing::Fatal,
        }
    }
}

/// The state of a connection's first message.
pub(super) enum Framing {
    /// More bytes needed.
    Incomplete,
    /// A request: the header block is `..head`, the body the next `body`
    /// bytes.
    Request { head: usize, body: usize },
    /// Interleaved data (RFC 2326 section 10.12): `len` bytes of
    /// `channel` after the 4-byte header.
    Interleaved { channel: u8, len: usize },
    /// Cannot be framed: answer 400 and close.
    Fatal,
}

/// When a connection last made progress: the two times its deadlines run
/// from.
#[derive(Clone, Copy, Debug)]
pub(super) struct Progress {
    /// When its last complete request (or interleaved frame) was taken, or
    /// when it opened.
    last_request: Instant,
    /// Since when bytes of an unfinished request wait.
    partial_since: Option<Instant>,
}

impl Progress {
    /// Whether at `now` a request has been left unfinished for
    /// [`REQUEST_LIMIT`], or no request came for `idle_limit`.
    pub(super) fn expired(&self, now: Instant, idle_limit: Option<core::time::Duration>) -> bool {
        let unfinished = self.partial_since.is_some_and(|t| now.saturating_duration_since(t) >= REQUEST_LIMIT);
        let idle = idle_limit.is_some_and(|limit| now.saturating_duration_since(self.last_request) >= limit);
        unfinished || idle
    }

    /// When [`expired`](Self::expired) may next turn true, nothing
    /// arriving meanwhile.
    pub(super) fn deadline(&self, idle_limit: core::time::Duration) -> Instant {
        let idle = self.last_request + idle_limit;
        match self.partial_since {
            Some(t) => (t + REQUEST_LIMIT).min(idle),
            None => idle,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interleaved_frames_are_told_from_requests() {
        let t0 = Instant::from_millis(0);
        let mut c = Connection::new(ConnId(1), IpAddr::V4(core::net::Ipv4Addr::LOCALHOST), t0);
        c.receive(t0, b"$\x01\x00\x03abcOPTIONS");
        assert!(matches!(c.frame(), Framing::Interleaved { channel: 1, len: 3 }));
        assert_eq!(c.bytes(4..7), b"abc");
        c.consume(7, t0);
        assert!(matches!(c.frame(), Framing::Incomplete));
        c.receive(t0, b" * RTSP/1.0\r\nCSeq: 1\r\n\r\n");
        assert!(matches!(c.frame(), Framing::Request { .. }));
    }

    #[test]
    fn an_interleaved_frame_too_long_to_buffer_is_skipped() {
        let t0 = Instant::from_millis(0);
        let mut c = Connection::new(ConnId(1), IpAddr::V4(core::net::Ipv4Addr::LOCALHOST), t0);
        let mut data = std::vec![b'$', 0, 0x27, 0x10];
        data.extend(std::iter::repeat_n(b'x', 10_000));
        data.extend_from_slice(b"OPTIONS * RTSP/1.0\r\nCSeq: 1\r\n\r\n");
        let mut fed = 0;
        let mut requests = 0;
        while fed < data.len() {
            fed += c.receive(t0, &data[fed..]);
            loop {
                match c.frame() {
                    Framing::Request { head, body } => {
                        requests += 1;
                        c.consume(head + body, t0);
                    }
                    Framing::Incomplete => break,
                    other => panic!("{}", matches!(other, Framing::Fatal)),
                }
            }
        }
        assert_eq!(requests, 1, "the request after it is read");
    }
}
