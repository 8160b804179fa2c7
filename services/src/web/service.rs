//! The web page on smoltcp (feature `smoltcp`): `N` TCP sockets listening
//! on [`WEB_PORT`], one [`Connection`] per connected socket, at most
//! [`WEB_VIEWERS`] of them WebSocket viewers.
//!
//! A browser opens a few connections at once for the page's files and
//! `/status`, and keeps one for the picture; every answer but the picture's
//! closes its connection, so sockets come back quickly. The caller lends the
//! buffers, as for the seed service.

use core::fmt::Write;
use core::time::Duration;

use smoltcp::iface::{SocketHandle, SocketSet};
use smoltcp::socket::tcp;
use smoltcp::time::Instant;

use super::http::HEAD_BYTES;
use super::server::{drive, Action, Connection, Context, Turns};
use super::status::{BoardStatus, LogTail};
use super::{WEB_PORT, WEB_VIEWERS};
use crate::frames::FrameSource;
use crate::tcp::{self as service_tcp, Listener};
use crate::time;

/// Receive buffer of one socket: a whole request head.
pub const RX_BUFFER_BYTES: usize = HEAD_BYTES;

/// Transmit buffer of one socket: 64 KiB, as the seed service's (a frame
/// streams through it at line rate on a LAN; docs/reliability.md).
pub const TX_BUFFER_BYTES: usize = 64 * 1024;

/// How long a closed connection may take to finish closing (our FIN sent,
/// the peer's not come) before its socket is taken back: a half-open
/// client would otherwise keep it from listening.
pub const CLOSE_LINGER: Duration = Duration::from_secs(5);

/// The buffers of one socket of this service (see
/// [`crate::tcp::SocketBuffers`]).
pub type SocketBuffers = crate::tcp::SocketBuffers<TX_BUFFER_BYTES, RX_BUFFER_BYTES>;

struct Slot<F> {
    handle: SocketHandle,
    connection: Option<Connection<F>>,
    /// When the last connection was closed, while its socket finishes.
    closing_since: Option<time::Instant>,
    listener: Listener,
}

/// The page on `N` smoltcp TCP sockets, serving frames whose handles are
/// `F`.
pub struct WebService<F, const N: usize> {
    slots: [Slot<F>; N],
    frames_sent: u64,
    turns: Turns<N>,
    /// Every socket listening and no connection at the end of the last poll.
    quiet: bool,
}

impl<F: Copy, const N: usize> WebService<F, N> {
    /// Add `N` TCP sockets, listening on [`WEB_PORT`], to `sockets`.
    pub fn new<'a>(sockets: &mut SocketSet<'a>, buffers: &'a mut [SocketBuffers; N]) -> Self {
        let mut i = 0;
        let slots = buffers.each_mut().map(|b| {
            let socket = b.socket();
            let listener = Listener::new("web", Some(i), WEB_PORT);
            i += 1;
            Slot { handle: sockets.add(socket), connection: None, closing_since: None, listener }
        });
        WebService { slots, frames_sent: 0, turns: Turns::new(), quiet: false }
    }

    /// Whether the last [`poll`](Self::poll) left every socket listening
    /// and no connection open: until the interface reports a socket's
    /// state may have changed (`PollResult::SocketStateChanged`), another
    /// poll would do nothing, and the main loop may skip it.
    pub fn quiet(&self) -> bool {
        self.quiet
    }

    /// Sockets listening, of `N`.
    pub fn listening(&self, sockets: &SocketSet<'_>) -> usize {
        service_tcp::listening(sockets, self.slots.iter().map(|s| s.handle))
    }

    /// Open connections.
    pub fn connections(&self) -> usize {
        self.slots.iter().filter(|s| s.connection.is_some()).count()
    }

    /// WebSocket viewers now.
    pub fn viewers(&self) -> usize {
        self.slots.iter().filter(|s| s.connection.as_ref().is_some_and(Connection::is_viewer)).count()
    }

    /// Frames sent whole to viewers since start.
    pub fn frames_sent(&self) -> u64 {
        self.frames_sent
    }

    /// Serve every socket once: accept, read, answer, stream frames from
    /// `frames`, close, re-listen. Call it after each `Interface::poll`.
    // What the board is (status, name, log) comes as three borrows of
    // three owners in the firmware's loop.
    #[allow(clippy::too_many_arguments)]
    pub fn poll<S: FrameSource<Frame = F>>(
        &mut self,
        now: Instant,
        sockets: &mut SocketSet<'_>,
        frames: &mut S,
        status: &BoardStatus<'_>,
        name: &str,
        tail: &dyn LogTail,
        log: &mut impl Write,
    ) {
        let now = time::Instant::from_millis(u64::try_from(now.total_millis()).unwrap_or(0));
        for index in 0..N {
            let room = self.viewers() < WEB_VIEWERS;
            let cx = Context { now, room, status, name, may_begin: self.turns.may_begin(index), log: tail };
            let slot = &mut self.slots[index];
            let socket = sockets.get_mut::<tcp::Socket>(slot.handle);
            self.frames_sent += u64::from(serve_slot(index, slot, socket, &cx, frames, log));
            let wants = slot.connection.as_ref().is_some_and(Connection::wants_frame);
            self.turns.served(index, wants);
        }
        self.quiet = self.slots.iter().all(|slot| {
            slot.connection.is_none()
                && slot.closing_since.is_none()
                && sockets.get::<tcp::Socket>(slot.handle).state() == tcp::State::Listen
        });
    }
}

/// Serve one socket; returns the frames it sent whole.
fn serve_slot<S: FrameSource>(
    index: usize,
    slot: &mut Slot<S::Frame>,
    socket: &mut tcp::Socket<'_>,
    cx: &Context<'_>,
    frames: &mut S,
    log: &mut impl Write,
) -> u32 {
    let Some(connection) = &mut slot.connection else {
        slot.listener.reclaim(socket, cx.now, log);
        if let Some(since) = slot.closing_since {
            if socket.is_open() && cx.now < since + CLOSE_LINGER {
                return 0;
            }
            if socket.is_open() {
                let _ = writeln!(log, "web[{index}] peer never finished closing; socket taken back");
                socket.abort();
            }
            slot.closing_since = None;
        }
        if slot.listener.accept(socket, log).is_some() {
            slot.connection = Some(Connection::new(cx.now));
        }
        return 0;
    };

    if !socket.is_active() || !socket.may_send() {
        if connection.is_viewer() {
            let _ = writeln!(log, "web[{index}] viewer went away");
        }
        connection.abandon(frames);
        socket.abort();
        slot.connection = None;
        return 0;
    }
    let before = connection.frames_sent();
    while socket.can_recv() {
        match socket.recv(|buf| {
            let n = connection.receive(buf);
            (n, n)
        }) {
            Ok(n) if n > 0 => {}
            _ => break,
        }
    }
    if !socket.may_recv() && socket.recv_queue() == 0 {
        connection.receive_eof();
    }
    let was_viewer = connection.is_viewer();
    // Where the socket's next byte goes (an empty send shows it), so that
    // a frame's rows are laid out word aligned in the buffer.
    if let Ok(align) = socket.send(|buf| (0, buf.as_ptr() as usize % 4)) {
        connection.transport_at(align);
    }
    let action = drive(connection, cx, frames, |fill| socket.send(|buf| take_words(buf, fill)).unwrap_or(0), log);
    let sent = connection.frames_sent().wrapping_sub(before);
    if !was_viewer && connection.is_viewer() {
        if let Some(peer) = socket.remote_endpoint() {
            let _ = writeln!(log, "web[{index}] viewer {peer}");
        }
    }
    if let Action::Close(reason) = action {
        if was_viewer || !reason.graceful() {
            let _ = writeln!(log, "web[{index}] {reason}");
        }
        if reason.graceful() {
            socket.close();
            slot.closing_since = Some(cx.now);
        } else {
            socket.abort();
        }
        slot.connection = None;
    }
    sent
}

/// Fill the free space `buf` that smoltcp offers at its transmit ring's
/// write position: whole words (rows are 1,440 bytes, so a copy that starts
/// word aligned stays so), but the last one to three bytes before the
/// ring's end too. The WebSocket head (10 bytes) leaves the write position
/// at 2 mod 4, so the ring's end is reached with 2 bytes free; smoltcp
/// offers only the bytes up to the end until something is written there,
/// and left unwritten they held the frame until every byte queued had been
/// acknowledged (the ring then starts again at 0).
fn take_words(buf: &mut [u8], fill: &mut dyn FnMut(&mut [u8]) -> usize) -> (usize, usize) {
    let n = match buf.len() {
        0 => 0,
        len @ 1..=3 => fill(&mut buf[..len]),
        len => fill(&mut buf[..len & !3]),
    };
    (n, n)
}

#[cfg(test)]
mod tests {
    use super::take_words;

    #[test]
    fn the_rings_last_bytes_are_written_and_otherwise_whole_words() {
        let mut taken = Vec::new();
        let mut fill = |b: &mut [u8]| {
            taken.push(b.len());
            b.len()
        };
        for len in [0usize, 2, 3, 4, 6, 1_443] {
            let mut buf = vec![0u8; len];
            take_words(&mut buf, &mut fill);
        }
        assert_eq!(taken, [2, 3, 4, 4, 1_440], "nothing asked of 0 bytes; 2 and 3 whole; words of the rest");
    }
}
