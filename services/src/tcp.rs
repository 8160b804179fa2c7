//! What the smoltcp services share (feature `smoltcp`): the buffers a
//! caller lends each TCP socket, and one policy for every service's
//! sockets against peers that stop answering.
//!
//! A lab network has phones that leave WiFi mid-connect, laptops that
//! sleep with a viewer open and scanners that send a SYN and nothing more.
//! Every service's socket is made by [`SocketBuffers::socket`], which
//! sets smoltcp's keep-alive ([`KEEP_ALIVE`]) and timeout ([`TIMEOUT`]: a
//! peer that acknowledges nothing for that long is reset) and turns Nagle
//! off (the services write whole answers and rows; Nagle would hold a
//! frame's last partial segment back for an acknowledgement), and each
//! service watches its sockets' handshakes with [`Handshake`]: one still
//! unfinished after [`HANDSHAKE_LIMIT`] is dropped and the socket listens
//! again, so SYNs that are never completed hold a socket seconds, not for
//! ever (smoltcp alone would keep retransmitting its SYN-ACK until
//! [`TIMEOUT`]).

use smoltcp::socket::tcp;
use smoltcp::time::Duration;

use crate::time::Instant;

/// Keep-alive probes on an idle connection (a viewer between frames, a
/// seed client waiting for its render): a peer that is gone stops
/// answering them, and [`TIMEOUT`] then resets the connection.
pub const KEEP_ALIVE: Duration = Duration::from_secs(10);

/// A connection whose peer acknowledges nothing (data, keep-alive probes,
/// a SYN-ACK) for this long is reset by smoltcp.
pub const TIMEOUT: Duration = Duration::from_secs(30);

/// A handshake (SYN received, SYN-ACK sent) not finished within this is
/// dropped: a client on any network answers a SYN-ACK within a few round
/// trips, and smoltcp retransmits it three times in this span
/// ([`crate::time::REQUEST_LIMIT`], the services' one limit on unfinished
/// work).
pub const HANDSHAKE_LIMIT: core::time::Duration = crate::time::REQUEST_LIMIT;

/// Set the services' policy on `socket` (module docs).
pub fn configure(socket: &mut tcp::Socket<'_>) {
    socket.set_keep_alive(Some(KEEP_ALIVE));
    socket.set_timeout(Some(TIMEOUT));
    socket.set_nagle_enabled(false);
}

/// Watches one socket's handshake (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Handshake {
    since: Option<Instant>,
}

impl Handshake {
    /// No handshake seen.
    pub const fn new() -> Handshake {
        Handshake { since: None }
    }

    /// Look at `socket` at `now` (every poll): a handshake unfinished for
    /// [`HANDSHAKE_LIMIT`] is dropped (the socket aborted, to be listened
    /// on again by its service). Returns whether it was.
    pub fn check(&mut self, socket: &mut tcp::Socket<'_>, now: Instant) -> bool {
        if socket.state() != tcp::State::SynReceived {
            self.since = None;
            return false;
        }
        let since = *self.since.get_or_insert(now);
        if now < since + HANDSHAKE_LIMIT {
            return false;
        }
        socket.abort();
        self.since = None;
        true
    }
}

/// The buffers of one TCP socket: `TX` bytes to transmit, `RX` to receive.
/// The transmit buffer comes first and is cache-line aligned: the services
/// copy rows into it a whole number of words at a time, so the copies stay
/// word aligned. Each service names its sizes (`seed::service`,
/// `web::service`).
#[repr(C, align(32))]
pub struct SocketBuffers<const TX: usize, const RX: usize> {
    tx: [u8; TX],
    rx: [u8; RX],
}

impl<const TX: usize, const RX: usize> SocketBuffers<TX, RX> {
    /// Zeroed buffers (usable in a `static`).
    pub const fn new() -> Self {
        SocketBuffers { tx: [0; TX], rx: [0; RX] }
    }

    /// A TCP socket on these buffers, with the services' policy
    /// ([`configure`]).
    pub fn socket(&mut self) -> tcp::Socket<'_> {
        let mut socket =
            tcp::Socket::new(tcp::SocketBuffer::new(&mut self.rx[..]), tcp::SocketBuffer::new(&mut self.tx[..]));
        configure(&mut socket);
        socket
    }
}

impl<const TX: usize, const RX: usize> Default for SocketBuffers<TX, RX> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_services_socket_has_the_policy() {
        let mut b: Box<SocketBuffers<64, 8>> = Box::default();
        let s = b.socket();
        assert_eq!((s.keep_alive(), s.timeout(), s.nagle_enabled()), (Some(KEEP_ALIVE), Some(TIMEOUT), false));
    }

    #[test]
    fn the_transmit_buffer_is_first_and_cache_line_aligned() {
        let b: Box<SocketBuffers<64, 8>> = Box::default();
        assert_eq!(core::mem::align_of::<SocketBuffers<64, 8>>(), 32);
        assert_eq!(b.tx.as_ptr() as usize, &*b as *const _ as usize);
        assert_eq!(b.rx.as_ptr() as usize, b.tx.as_ptr() as usize + 64);
    }
}
