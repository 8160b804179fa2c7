//! The frame server on smoltcp (feature `smoltcp`): TCP listeners on
//! [`FRAME_PORT`] and [`PERSISTENT_PORT`], one [`Session`] per connected
//! socket.
//!
//! The service owns no buffers: the caller lends it [`SocketBuffers`] for
//! `N` sockets, split between the two ports. While one socket of a port is
//! serving, the others keep listening, so a second client is served too (its
//! rows interleave with the first's, one poll apiece) instead of refused.

use core::fmt::Write;

use smoltcp::iface::{SocketHandle, SocketSet};
use smoltcp::socket::tcp;
use smoltcp::time::Instant;

use crate::frames::FrameSource;
use crate::seed::server::{drive, Action, Closed, Mode, Session};
use crate::seed::wire::{FRAME_PORT, PERSISTENT_PORT};
use crate::tcp::{self as service_tcp, Listener};
use crate::time;

/// Receive buffer of one socket: room for 42 pipelined requests.
pub const RX_BUFFER_BYTES: usize = 512;
/// Transmit buffer of one socket: 64 KiB, about 45 segments in flight. On a
/// lossy link a hole then has enough segments behind it for the three
/// duplicate ACKs of smoltcp's fast retransmit, where 16 KiB (11 segments)
/// mostly left a retransmission timeout (at least 1 s in smoltcp 0.14); see
/// docs/reliability.md for the figures.
pub const TX_BUFFER_BYTES: usize = 64 * 1024;

/// The buffers of one TCP socket of this service (see
/// [`crate::tcp::SocketBuffers`]).
pub type SocketBuffers = crate::tcp::SocketBuffers<TX_BUFFER_BYTES, RX_BUFFER_BYTES>;

struct Slot<F> {
    handle: SocketHandle,
    mode: Mode,
    session: Option<Session<F>>,
    listener: Listener,
}

/// The frame server bound to `N` smoltcp TCP sockets, serving frames whose
/// handles are `F` (a [`FrameSource`]'s).
pub struct FrameService<F, const N: usize> {
    slots: [Slot<F>; N],
    /// Every socket listening and no session at the end of the last poll.
    quiet: bool,
}

impl<F: Copy, const N: usize> FrameService<F, N> {
    /// Add `N` TCP sockets to `sockets`: the first `frame_port` listen on
    /// [`FRAME_PORT`], the rest on [`PERSISTENT_PORT`]. Each socket holds
    /// one client: a port accepts as many at once as it has sockets, and
    /// those beyond the frames being rendered wait their turn.
    pub fn new<'a>(sockets: &mut SocketSet<'a>, buffers: &'a mut [SocketBuffers; N], frame_port: usize) -> Self {
        let mut i = 0;
        let slots = buffers.each_mut().map(|b| {
            let socket = b.socket();
            let (mode, port) =
                if i < frame_port { (Mode::Single, FRAME_PORT) } else { (Mode::Persistent, PERSISTENT_PORT) };
            let listener = Listener::new("seed", Some(i), port);
            i += 1;
            Slot { handle: sockets.add(socket), mode, session: None, listener }
        });
        FrameService { slots, quiet: false }
    }

    /// Whether the last [`poll`](Self::poll) left every socket listening
    /// and no session open: until the interface reports a socket's state
    /// may have changed (`PollResult::SocketStateChanged`: a packet taken
    /// in or sent), another poll would do nothing, and the main loop may
    /// skip it (24 sockets looked at, on every turn of a board that
    /// streams over RTP).
    pub fn quiet(&self) -> bool {
        self.quiet
    }

    /// Sockets listening for a client, of `N`.
    pub fn listening(&self, sockets: &SocketSet<'_>) -> usize {
        service_tcp::listening(sockets, self.slots.iter().map(|s| s.handle))
    }

    /// Number of sessions currently open.
    pub fn active_sessions(&self) -> usize {
        self.slots.iter().filter(|s| s.session.is_some()).count()
    }

    /// Serve every socket once: accept, read requests, copy rows from
    /// `frames` into the socket while it takes them, close finished
    /// sessions, re-listen. Call it after each `Interface::poll`.
    pub fn poll<S: FrameSource<Frame = F>>(
        &mut self,
        now: Instant,
        sockets: &mut SocketSet<'_>,
        frames: &mut S,
        log: &mut impl Write,
    ) {
        let now = time::Instant::from_millis(u64::try_from(now.total_millis()).unwrap_or(0));
        let mut quiet = true;
        for (index, slot) in self.slots.iter_mut().enumerate() {
            let socket = sockets.get_mut::<tcp::Socket>(slot.handle);
            serve_slot(index, slot, socket, now, frames, log);
            quiet &= slot.session.is_none() && socket.state() == tcp::State::Listen;
        }
        self.quiet = quiet;
    }
}

fn serve_slot<S: FrameSource>(
    index: usize,
    slot: &mut Slot<S::Frame>,
    socket: &mut tcp::Socket<'_>,
    now: time::Instant,
    frames: &mut S,
    log: &mut impl Write,
) {
    let Some(session) = &mut slot.session else {
        slot.listener.reclaim(socket, now, log);
        if let Some(peer) = slot.listener.accept(socket, log) {
            let _ = writeln!(log, "[{index}] port {}: client {peer}", slot.listener.port());
            slot.session = Some(Session::new(slot.mode, now));
        }
        return;
    };

    if !socket.is_active() || !socket.may_send() {
        // Reset, or closed both ways before we finished: nothing to send to.
        let what = if session.mid_frame() { "vanished mid-frame; frame aborted" } else { "went away" };
        let _ = writeln!(log, "[{index}] client {what}");
        session.abandon(frames);
        socket.abort();
        slot.session = None;
        return;
    }

    while socket.can_recv() && session.wants_requests() {
        match socket.recv(|buf| {
            let n = session.receive(now, buf);
            (n, n)
        }) {
            Ok(n) if n > 0 => {}
            _ => break,
        }
    }
    if !socket.may_recv() && socket.recv_queue() == 0 {
        session.receive_eof();
    }

    // Rows are copied by the source straight into the socket's buffer, a
    // whole number of words at a time: rows are 1,440 bytes, so every copy
    // then starts word aligned in both the frame and the buffer (the write
    // position only moves by what is queued). Fewer than four free bytes
    // wait for the next ACK.
    let action = drive(
        session,
        now,
        frames,
        |fill| {
            socket
                .send(|buf| {
                    let words = buf.len() & !3;
                    let n = if words == 0 { 0 } else { fill(&mut buf[..words]) };
                    (n, n)
                })
                .unwrap_or(0)
        },
        log,
    );
    if let Action::Close(reason) = action {
        match reason {
            Closed::Done => {
                let _ = writeln!(log, "[{index}] done");
            }
            other => {
                let _ = writeln!(log, "[{index}] closing: {other}");
            }
        }
        // Graceful close: queued rows still go out before the FIN.
        socket.close();
        slot.session = None;
    }
}
