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
//! service keeps its sockets between connections with a [`Listener`]:
//! listening again once closed, TIME-WAIT dropped at once, and a handshake
//! still unfinished after [`REQUEST_LIMIT`] dropped, so SYNs that are
//! never completed hold a socket seconds, not for ever (smoltcp alone
//! would keep retransmitting its SYN-ACK until [`TIMEOUT`]).

use core::fmt::Write;

use smoltcp::iface::{SocketHandle, SocketSet};
use smoltcp::socket::tcp;
use smoltcp::time::Duration;
use smoltcp::wire::IpEndpoint;

use crate::time::{Instant, REQUEST_LIMIT};

/// Keep-alive probes on an idle connection (a viewer between frames, a
/// seed client waiting for its render): a peer that is gone stops
/// answering them, and [`TIMEOUT`] then resets the connection.
pub const KEEP_ALIVE: Duration = Duration::from_secs(10);

/// A connection whose peer acknowledges nothing (data, keep-alive probes,
/// a SYN-ACK) for this long is reset by smoltcp.
pub const TIMEOUT: Duration = Duration::from_secs(30);

/// Set the services' policy on `socket` (module docs).
pub fn configure(socket: &mut tcp::Socket<'_>) {
    socket.set_keep_alive(Some(KEEP_ALIVE));
    socket.set_timeout(Some(TIMEOUT));
    socket.set_nagle_enabled(false);
}

/// One service socket's upkeep between connections, the same for every
/// service (module docs): the port it listens on, and its handshake
/// watched. Each poll a service calls [`reclaim`](Self::reclaim), then
/// [`accept`](Self::accept), which listens again once the socket closed and
/// names a client that connected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Listener {
    /// What the log calls the socket (`seed[2]`, `web[0]`, `rtsp:`).
    name: &'static str,
    index: Option<usize>,
    port: u16,
    /// When the handshake in progress began, if one is.
    since: Option<Instant>,
}

impl Listener {
    /// A socket listening on `port`, named in the log as `name`, or
    /// `name[index]` when there are several alike.
    pub const fn new(name: &'static str, index: Option<usize>, port: u16) -> Listener {
        Listener { name, index, port, since: None }
    }

    /// The port it listens on.
    pub const fn port(&self) -> u16 {
        self.port
    }

    /// Take back at `now` what no client will finish (every poll): a
    /// socket in TIME-WAIT (our FIN was acknowledged and the client's
    /// received; smoltcp would refuse clients on it for 10 s, its
    /// `CLOSE_DELAY`), and a handshake unfinished for [`REQUEST_LIMIT`].
    /// Returns whether a handshake was dropped.
    pub fn reclaim(&mut self, socket: &mut tcp::Socket<'_>, now: Instant, log: &mut impl Write) -> bool {
        if socket.state() == tcp::State::TimeWait {
            socket.abort();
        }
        if socket.state() != tcp::State::SynReceived {
            self.since = None;
            return false;
        }
        let since = *self.since.get_or_insert(now);
        if now < since + REQUEST_LIMIT {
            return false;
        }
        socket.abort();
        self.since = None;
        let _ = writeln!(log, "{self} a handshake never finished; socket taken back");
        true
    }

    /// For a socket that holds no connection of the service's: listen
    /// again if it is closed; return the client when one is connected and
    /// has something to be read (Established, or CloseWait: a client that
    /// sent its request and its FIN at once still gets its answer).
    pub fn accept(&self, socket: &mut tcp::Socket<'_>, log: &mut impl Write) -> Option<IpEndpoint> {
        if !socket.is_open() {
            if let Err(e) = socket.listen(self.port) {
                let _ = writeln!(log, "{self} listen on {} failed: {e:?}", self.port);
            }
            return None;
        }
        if matches!(socket.state(), tcp::State::Established | tcp::State::CloseWait) {
            return socket.remote_endpoint();
        }
        None
    }
}

impl core::fmt::Display for Listener {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.index {
            Some(i) => write!(f, "{}[{i}]", self.name),
            None => f.write_str(self.name),
        }
    }
}

/// How many of `handles`' sockets in `sockets` are listening for a client.
pub fn listening(sockets: &SocketSet<'_>, handles: impl Iterator<Item = SocketHandle>) -> usize {
    handles.filter(|&h| sockets.get::<tcp::Socket>(h).state() == tcp::State::Listen).count()
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
