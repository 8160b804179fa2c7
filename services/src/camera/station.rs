//! The RTSP server and the RTP sender wired together, once for every
//! binding: the board's smoltcp service (`service`, feature `smoltcp`) and
//! the std sockets of hps-sim and hps-linux own the sockets and call this
//! for what a request, a closed connection, an RTCP datagram and the
//! passing of time do to both, with the log lines they write.

use core::fmt::Write;
use core::net::SocketAddr;

use super::rtsp::{ConnId, Connection, Random, Reply, Server, MAX_RESPONSE_BYTES};
use super::sender::{Bound, RtpSink, SlotSource};

/// The server, and the sender with its frames at one instant (what the
/// server asks of it, [`Bound`]).
pub struct Station<'a, 'b, S, const N: usize> {
    /// The RTSP server.
    pub server: &'a mut Server<N>,
    /// The sender, its frames and the time.
    pub streams: Bound<'b, S, N>,
}

impl<S: SlotSource, const N: usize> Station<'_, '_, S, N> {
    /// Answer the first complete request buffered in `conn` into `out`
    /// ([`Server::handle`], the sender as its streams) and log the status
    /// with the sessions now open. `None`: no complete request.
    pub fn answer(
        &mut self,
        conn: &mut Connection,
        rng: &mut impl Random,
        out: &mut [u8; MAX_RESPONSE_BYTES],
        log: &mut impl Write,
    ) -> Option<Reply> {
        let reply = self.server.handle(conn, self.streams.now, rng, &mut self.streams, out)?;
        let sessions = self.server.sessions().len();
        let _ = writeln!(log, "rtsp: {} {} ({sessions} sessions)", reply.status.code(), reply.status.reason());
        Some(reply)
    }

    /// Connection `id` is gone: the sessions inside it end (RTP over UDP
    /// lives on, RFC 2326 section 3.1).
    pub fn connection_closed(&mut self, id: ConnId, log: &mut impl Write) {
        let ended = self.server.connection_closed(id, &mut self.streams);
        if ended > 0 {
            let _ = writeln!(log, "rtsp: connection {id} gone: {ended} interleaved session(s) end");
        }
    }

    /// Sessions whose clients went quiet past their timeout end.
    pub fn expire_sessions(&mut self, log: &mut impl Write) {
        while let Some(session) = self.server.poll(self.streams.now, &mut self.streams) {
            let _ = writeln!(log, "rtsp: session {session} timed out");
        }
    }

    /// An RTCP datagram from `from`: one from a session's client keeps the
    /// session alive and goes to the sender (round trips, NACKs answered
    /// through `sink`). Returns whether it was a session's.
    pub fn rtcp(&mut self, from: SocketAddr, datagram: &[u8], sink: &mut impl RtpSink) -> bool {
        let Bound { camera, source, now, wall } = &mut self.streams;
        if self.server.rtcp_received(*now, from.ip(), from.port(), datagram).is_none() {
            return false;
        }
        camera.rtcp_received(from, datagram, *now, *wall, *source, sink);
        true
    }

    /// Sessions the sender ended itself (its client unreachable or silent)
    /// leave the server too.
    pub fn forget_ended(&mut self, log: &mut impl Write) {
        while let Some((session, why)) = self.streams.camera.take_ended() {
            self.server.remove(session);
            let _ = writeln!(log, "rtsp: session {session} ends: {why}");
        }
    }
}
