//! The frame-server protocol as a sans-IO state machine: bytes in, actions
//! out. It knows nothing of sockets, clocks or renderers; adapters (smoltcp in
//! the firmware, std TCP in `hps-sim`) feed it received bytes and the time,
//! and carry out what [`Session::poll`] asks for.
//!
//! # Protocol
//!
//! A request is 12 bytes: light x, y, z as big-endian signed 32-bit Q13.10
//! words, each in `[-2^23, 2^23)`. The answer is one frame of 518,400 bytes
//! (480 x 360 RGB888, row-major, top row first).
//!
//! * [`Mode::Single`] ([`FRAME_PORT`], the seed protocol): one request, one
//!   frame, then the server closes. Bytes after the first request are ignored.
//! * [`Mode::Persistent`] ([`PERSISTENT_PORT`]): any number of pipelined requests,
//!   frames returned in order, until the client closes its sending side and
//!   every complete request before that has been answered.
//!
//! Frames come from a [`FrameSource`]: the session asks it for a frame per
//! request, and for a persistent connection begins the next request's frame
//! while the current one is still being sent, so the source can render
//! frame n + 1 while frame n goes out. Row bytes go from the source straight
//! into the transport's buffer; the session holds no pixel data.
//!
//! # Bad input
//!
//! * A light outside the word range closes the connection when that request
//!   is reached, with zero bytes of its frame ([`Closed::BadLight`]); frames
//!   of earlier requests are complete.
//! * A request cut short by end of stream is dropped ([`Closed::ShortRequest`]).
//! * A partial request idle for [`REQUEST_LIMIT`] is dropped
//!   ([`Closed::RequestTimeout`]), and so is a seed-port client that sends
//!   nothing for as long after connecting.
//! * A client vanishing mid-frame is the adapter's to notice (the socket
//!   fails); it drops the session, which holds nothing else.

use core::time::Duration;

use heapless::Deque;
use model::{Light, LightError, ROW_BYTES};

use crate::frames::{FrameSource, ROWS};
use crate::seed::wire::{decode_request, REQUEST_BYTES};
#[cfg(doc)]
use crate::seed::wire::{FRAME_PORT, PERSISTENT_PORT};
use crate::time::{Instant, REQUEST_LIMIT};

/// How long a frame may go without a byte leaving before the session gives
/// up on the client (it stopped reading; its socket is needed by others).
/// Far beyond any frame's render time, even in software on the board.
pub const SEND_TIMEOUT: Duration = Duration::from_secs(30);

/// How many complete requests a persistent session queues beyond the frame in
/// progress. When the queue is full the session stops taking input, so TCP
/// flow control holds back a client that pipelines faster than frames go out.
pub const PIPELINE_DEPTH: usize = 4;

/// Which of the two protocols a connection speaks.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Mode {
    /// [`FRAME_PORT`]: one request, one frame, close.
    Single,
    /// [`PERSISTENT_PORT`]: pipelined requests, frames in order, until the
    /// client closes.
    Persistent,
}

/// Why a session ended.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Closed {
    /// Every request was answered (single mode: the one frame is sent;
    /// persistent mode: the client closed and all frames are sent).
    Done,
    /// A request carried a light outside `[-2^23, 2^23)`; no byte of its
    /// frame was sent.
    BadLight(LightError),
    /// The stream ended inside a request (`received` of 12 bytes).
    ShortRequest {
        /// Bytes of the incomplete request.
        received: u8,
    },
    /// A partial request (or, on the seed port, no request at all) sat idle
    /// for [`REQUEST_LIMIT`].
    RequestTimeout {
        /// Bytes of the incomplete request.
        received: u8,
    },
    /// The client closed before sending any request.
    NoRequest,
    /// No byte of the frame in progress left for [`SEND_TIMEOUT`]: the
    /// client stopped reading (or the source stopped producing rows).
    Stalled {
        /// The row the frame was at.
        row: u16,
    },
    /// The frame source failed (for example the accelerator timed out); the
    /// frame in progress is abandoned, and the close tells the client its
    /// frame is short.
    RenderFailed {
        /// The first row that could not be delivered.
        row: u16,
    },
}

impl core::fmt::Display for Closed {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Closed::Done => f.write_str("done"),
            Closed::BadLight(e) => write!(f, "bad request: {e}"),
            Closed::ShortRequest { received } => {
                write!(f, "request cut short by end of stream ({received} of 12 bytes)")
            }
            Closed::RequestTimeout { received } => {
                write!(f, "partial request idle for {} ms ({received} of 12 bytes)", REQUEST_LIMIT.as_millis())
            }
            Closed::NoRequest => f.write_str("client closed without a request"),
            Closed::Stalled { row } => {
                write!(f, "no progress for {} s at row {row}: client not reading", SEND_TIMEOUT.as_secs())
            }
            Closed::RenderFailed { row } => write!(f, "rendering row {row} failed"),
        }
    }
}

/// What the adapter should do next ([`drive`] carries these out with a
/// [`FrameSource`]).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Action<F> {
    /// Ask the source for a frame for `light` and report it with
    /// [`Session::begun`] (`None` when the source has no room yet).
    Begin {
        /// The request's light.
        light: Light,
    },
    /// Ask the source how many rows of `frame` are ready and report it with
    /// [`Session::rows_ready`].
    Progress {
        /// The frame being sent.
        frame: F,
    },
    /// Copy bytes `offset..` of row `row` of `frame` into the transport and
    /// report how many with [`Session::sent`].
    Send {
        /// The frame being sent.
        frame: F,
        /// Its row, `0..360`.
        row: u16,
        /// The first byte of the row not sent yet.
        offset: usize,
    },
    /// Give `frame` back to the source.
    End {
        /// The frame the session is done with.
        frame: F,
    },
    /// Nothing to do until more bytes arrive, the stream ends, or the time
    /// reaches `deadline` (when given).
    Wait {
        /// When [`Session::poll`] will next have something to do on its own.
        deadline: Option<Instant>,
    },
    /// Close the connection (gracefully: queued bytes were all handed out).
    /// Every frame the session held was ended before.
    Close(Closed),
}

/// A complete request: a valid light or the reason it is not.
type Request = Result<Light, LightError>;

/// The frame a session is sending.
#[derive(Clone, Copy, Debug)]
struct Sending<F> {
    frame: F,
    row: u16,
    offset: usize,
    ready: u16,
    /// The first poll since the position above last moved (or the frame
    /// started); `None` until that poll.
    moved_at: Option<Instant>,
}

/// One connection's protocol state, holding frames of type `F` (the
/// source's handles).
#[derive(Debug)]
pub struct Session<F> {
    mode: Mode,
    partial: [u8; REQUEST_BYTES],
    partial_len: u8,
    /// Time of the last byte added to `partial` (the connection's start
    /// until one arrives).
    partial_since: Instant,
    requests_seen: u32,
    /// Requests not begun yet.
    queue: Deque<Request, PIPELINE_DEPTH>,
    sending: Option<Sending<F>>,
    /// The frame of the front request, begun while `sending` goes out.
    ahead: Option<F>,
    /// The row of `sending` at which the source last refused a frame ahead.
    ahead_refused_at: Option<u16>,
    eof: bool,
    closed: Option<Closed>,
}

impl<F: Copy> Session<F> {
    /// A new session for a connection accepted at `now`.
    pub fn new(mode: Mode, now: Instant) -> Session<F> {
        Session {
            mode,
            partial: [0; REQUEST_BYTES],
            partial_len: 0,
            partial_since: now,
            requests_seen: 0,
            queue: Deque::new(),
            sending: None,
            ahead: None,
            ahead_refused_at: None,
            eof: false,
            closed: None,
        }
    }

    /// The session's protocol.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Take received bytes; returns how many were consumed. Fewer than
    /// `data.len()` means the request queue is full: offer the rest later.
    pub fn receive(&mut self, now: Instant, data: &[u8]) -> usize {
        let mut used = 0;
        while used < data.len() && self.closed.is_none() {
            if !self.wants_requests() {
                // Single mode after its request: the rest is ignored.
                return data.len();
            }
            if self.queue.is_full() {
                break;
            }
            let need = REQUEST_BYTES - self.partial_len as usize;
            let take = need.min(data.len() - used);
            let start = self.partial_len as usize;
            self.partial[start..start + take].copy_from_slice(&data[used..used + take]);
            self.partial_len += take as u8;
            self.partial_since = now;
            used += take;
            if self.partial_len as usize == REQUEST_BYTES {
                self.partial_len = 0;
                self.requests_seen += 1;
                // The queue had room: checked above.
                let _ = self.queue.push_back(decode_request(&self.partial));
            }
        }
        used
    }

    /// The client closed its sending side: no more requests will come.
    pub fn receive_eof(&mut self) {
        self.eof = true;
    }

    /// Whether the session still reads requests (single mode reads one).
    pub fn wants_requests(&self) -> bool {
        match self.mode {
            Mode::Single => self.requests_seen == 0,
            Mode::Persistent => !self.eof,
        }
    }

    /// The next action at time `now`.
    pub fn poll(&mut self, now: Instant) -> Action<F> {
        if let Some(reason) = self.closed {
            if let Some(frame) = self.ahead.take() {
                return Action::End { frame };
            }
            if let Some(s) = self.sending.take() {
                return Action::End { frame: s.frame };
            }
            return Action::Close(reason);
        }
        if let Some(s) = &mut self.sending {
            match s.moved_at {
                Some(at) if now >= at + SEND_TIMEOUT => {
                    self.closed = Some(Closed::Stalled { row: s.row });
                    return self.poll(now);
                }
                Some(_) => {}
                None => s.moved_at = Some(now),
            }
        }
        if let Some(s) = self.sending {
            if s.row == ROWS {
                self.sending = None;
                self.ahead_refused_at = None;
                if self.mode == Mode::Single {
                    self.closed = Some(Closed::Done);
                }
                return Action::End { frame: s.frame };
            }
            // Begin the next request's frame early (once per row if the
            // source has no room), so it renders while this one is sent.
            if self.ahead.is_none() && self.ahead_refused_at != Some(s.row) {
                if let Some(Ok(light)) = self.queue.front() {
                    return Action::Begin { light: *light };
                }
            }
            if s.row < s.ready {
                return Action::Send { frame: s.frame, row: s.row, offset: s.offset };
            }
            return Action::Progress { frame: s.frame };
        }
        if let Some(frame) = self.ahead.take() {
            self.sending = Some(Sending { frame, row: 0, offset: 0, ready: 0, moved_at: None });
            return Action::Progress { frame };
        }
        match self.queue.front() {
            Some(Ok(light)) => return Action::Begin { light: *light },
            Some(Err(e)) => {
                let reason = Closed::BadLight(*e);
                self.closed = Some(reason);
                return Action::Close(reason);
            }
            None => {}
        }
        let received = self.partial_len;
        if self.eof {
            let reason = match (received, self.requests_seen) {
                (0, 0) => Closed::NoRequest,
                (0, _) => Closed::Done,
                _ => Closed::ShortRequest { received },
            };
            self.closed = Some(reason);
            return Action::Close(reason);
        }
        // A partial request, or a seed-port client that has sent nothing yet
        // (it would hold a socket that another client could use).
        if received > 0 || (self.mode == Mode::Single && self.requests_seen == 0) {
            let deadline = self.partial_since + REQUEST_LIMIT;
            if now >= deadline {
                let reason = Closed::RequestTimeout { received };
                self.closed = Some(reason);
                return Action::Close(reason);
            }
            return Action::Wait { deadline: Some(deadline) };
        }
        Action::Wait { deadline: None }
    }

    /// The answer to [`Action::Begin`]: the frame for the front request, or
    /// `None` if the source had no room (the session asks again later).
    pub fn begun(&mut self, frame: Option<F>) {
        let Some(frame) = frame else {
            if let Some(s) = self.sending {
                self.ahead_refused_at = Some(s.row);
            }
            return;
        };
        let _ = self.queue.pop_front();
        if self.sending.is_none() {
            self.sending = Some(Sending { frame, row: 0, offset: 0, ready: 0, moved_at: None });
        } else {
            self.ahead = Some(frame);
        }
    }

    /// The answer to [`Action::Progress`]: rows `0..rows` of the frame being
    /// sent can be copied.
    pub fn rows_ready(&mut self, rows: u16) {
        if let Some(s) = &mut self.sending {
            s.ready = rows.min(ROWS);
        }
    }

    /// The answer to [`Action::Send`]: `n` bytes went out.
    pub fn sent(&mut self, n: usize) {
        if let Some(s) = self.sending.as_mut().filter(|_| n > 0) {
            s.moved_at = None;
            s.offset += n;
            if s.offset >= ROW_BYTES {
                s.offset = 0;
                s.row += 1;
            }
        }
    }

    /// The frame being sent could not be delivered: close, ending its frames.
    pub fn render_failed(&mut self) {
        let row = self.sending.map_or(0, |s| s.row);
        self.closed = Some(Closed::RenderFailed { row });
    }

    /// End every frame the session holds, for an adapter that drops the
    /// session without driving it to its close (the client vanished): else
    /// their slots in `source` stay taken.
    pub fn abandon<S: FrameSource<Frame = F>>(&mut self, source: &mut S) {
        for frame in [self.sending.take().map(|s| s.frame), self.ahead.take()].into_iter().flatten() {
            source.end(frame);
        }
    }

    /// Whether bytes of a frame went out and the frame is not complete (a
    /// close now would cut it short).
    pub fn mid_frame(&self) -> bool {
        self.sending.is_some_and(|s| s.row > 0 || s.offset > 0)
    }
}

/// Carry out [`Session::poll`]'s actions with `source` until the session
/// must wait: for input ([`Action::Wait`]), for room in the transport
/// ([`Action::Send`]: `send` took nothing), for rows ([`Action::Progress`]:
/// none new), for a free slot ([`Action::Begin`]: refused), or because it
/// closed ([`Action::Close`]).
///
/// `send` offers the transport's free buffer: it calls its argument with a
/// writable slice and returns how many bytes of it the transport took
/// (0: no room). Each new frame's request is written to `log` as one line,
/// each render failure too.
pub fn drive<S: FrameSource>(
    session: &mut Session<S::Frame>,
    now: Instant,
    source: &mut S,
    mut send: impl FnMut(&mut dyn FnMut(&mut [u8]) -> usize) -> usize,
    log: &mut impl core::fmt::Write,
) -> Action<S::Frame> {
    loop {
        let action = session.poll(now);
        match action {
            Action::Begin { light } => match source.begin(&light) {
                Ok(Some(frame)) => {
                    let [x, y, z] = light.raw();
                    // A log sink that fails must not stop the frame.
                    let _ = writeln!(log, "request light raw ({x}, {y}, {z}) on {:?}", session.mode());
                    session.begun(Some(frame));
                }
                Ok(None) => {
                    let waiting = session.sending.is_none();
                    session.begun(None);
                    if waiting {
                        return action;
                    }
                }
                Err(e) => {
                    let _ = writeln!(log, "frame not begun: {e}");
                    session.render_failed();
                }
            },
            Action::Progress { frame } => {
                let before = session.sending.map_or(0, |s| s.ready);
                match source.rows_ready(frame) {
                    Ok(rows) => {
                        session.rows_ready(rows);
                        if rows <= before {
                            return action;
                        }
                    }
                    Err(e) => {
                        let _ = writeln!(log, "row {before}: render failed: {e}");
                        session.render_failed();
                    }
                }
            }
            Action::Send { frame, row, offset } => {
                let n = send(&mut |buf| source.copy_row(frame, row, offset, buf));
                if n == 0 {
                    return action;
                }
                session.sent(n);
            }
            Action::End { frame } => source.end(frame),
            Action::Wait { .. } | Action::Close(_) => return action,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::rows::{RowSource, SoftwareRenderer};
    use crate::frames::RowFrames;
    use model::{FRAME_BYTES, WIDTH};

    type Source = RowFrames<SoftwareRenderer, 2>;

    fn request(x: i32, y: i32, z: i32) -> [u8; 12] {
        crate::seed::wire::encode_raw_request([x, y, z])
    }

    fn at(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    fn expected(x: i32, y: i32, z: i32) -> Vec<u8> {
        model::render_frame(&Light::from_raw(x, y, z).expect("test light in range"))
    }

    /// `drive` with a transport taking at most `chunk` bytes per call into `out`.
    fn step(
        s: &mut Session<usize>,
        src: &mut Source,
        chunk: usize,
        out: &mut Vec<u8>,
        log: &mut String,
    ) -> Action<usize> {
        drive(
            s,
            Instant::ZERO,
            src,
            |fill| {
                let mut buf = vec![0u8; chunk];
                let n = fill(&mut buf);
                out.extend_from_slice(&buf[..n]);
                n
            },
            log,
        )
    }

    /// Run a session to its close, collecting output.
    fn run(session: &mut Session<usize>, chunk: usize) -> (Vec<u8>, Closed) {
        let mut src = Source::new(SoftwareRenderer);
        let mut out = Vec::new();
        loop {
            match step(session, &mut src, chunk, &mut out, &mut String::new()) {
                Action::Close(c) => return (out, c),
                Action::Wait { .. } => session.receive_eof(),
                Action::Progress { .. } | Action::Begin { .. } => {}
                a => panic!("unexpected {a:?}"),
            }
        }
    }

    #[test]
    fn single_request_answers_one_frame_then_closes() {
        let mut s = Session::new(Mode::Single, at(0));
        let req = request(3 << 10, 4 << 10, -2 << 10);
        // Byte by byte, then trailing garbage that is ignored.
        for b in req {
            assert_eq!(s.receive(at(0), &[b]), 1);
        }
        assert_eq!(s.receive(at(0), &[1, 2, 3]), 3);
        let mut src = Source::new(SoftwareRenderer);
        let (mut out, mut log) = (Vec::new(), String::new());
        let last = loop {
            match step(&mut s, &mut src, 1000, &mut out, &mut log) {
                Action::Progress { .. } => {}
                other => break other,
            }
        };
        assert_eq!(log, "request light raw (3072, 4096, -2048) on Single\n");
        assert_eq!(last, Action::Close(Closed::Done));
        assert_eq!(out, expected(3 << 10, 4 << 10, -2 << 10));
        assert_eq!(src.begin(&Light::from_raw(0, 0, 0).unwrap()).unwrap(), Some(0), "the frame was ended");
    }

    #[test]
    fn persistent_frames_come_in_order() {
        let mut s = Session::new(Mode::Persistent, at(0));
        let lights = [(1024, 4096, 0), (-3072, 2048, 1024), (0, 8 << 10, -4096)];
        let mut bytes = Vec::new();
        for (x, y, z) in lights {
            bytes.extend_from_slice(&request(x, y, z));
        }
        assert_eq!(s.receive(at(0), &bytes), bytes.len());
        let (out, closed) = run(&mut s, 4096);
        assert_eq!(closed, Closed::Done);
        let want: Vec<u8> = lights.iter().flat_map(|&(x, y, z)| expected(x, y, z)).collect();
        assert_eq!(out.len(), 3 * FRAME_BYTES);
        assert!(out == want, "frames differ from the model");
    }

    #[test]
    fn the_next_frame_is_begun_while_the_current_one_is_sent() {
        let mut s = Session::new(Mode::Persistent, at(0));
        s.receive(at(0), &request(1024, 4096, 0));
        s.receive(at(0), &request(-1024, 4096, 0));
        assert_eq!(s.poll(at(0)), Action::Begin { light: Light::from_raw(1024, 4096, 0).unwrap() });
        s.begun(Some(7));
        assert_eq!(s.poll(at(0)), Action::Begin { light: Light::from_raw(-1024, 4096, 0).unwrap() }, "ahead");
        s.begun(Some(8));
        assert_eq!(s.poll(at(0)), Action::Progress { frame: 7 });
        s.rows_ready(2);
        assert_eq!(s.poll(at(0)), Action::Send { frame: 7, row: 0, offset: 0 });
        s.sent(1000);
        assert_eq!(s.poll(at(0)), Action::Send { frame: 7, row: 0, offset: 1000 });
        s.sent(ROW_BYTES - 1000);
        assert_eq!(s.poll(at(0)), Action::Send { frame: 7, row: 1, offset: 0 });
        assert!(s.mid_frame());
        // A source with no room for the frame ahead is asked once per row.
        let mut t = Session::new(Mode::Persistent, at(0));
        t.receive(at(0), &request(1, 2, 3));
        t.receive(at(0), &request(4, 5, 6));
        assert!(matches!(t.poll(at(0)), Action::Begin { .. }));
        t.begun(Some(1));
        assert!(matches!(t.poll(at(0)), Action::Begin { .. }));
        t.begun(None);
        assert_eq!(t.poll(at(0)), Action::Progress { frame: 1 });
        t.rows_ready(1);
        assert_eq!(t.poll(at(0)), Action::Send { frame: 1, row: 0, offset: 0 });
        t.sent(ROW_BYTES);
        assert!(matches!(t.poll(at(0)), Action::Begin { .. }), "asked again on the next row");
    }

    #[test]
    fn a_closing_session_ends_every_frame_it_holds() {
        let mut s = Session::new(Mode::Persistent, at(0));
        s.receive(at(0), &request(1024, 4096, 0));
        s.receive(at(0), &request(-1024, 4096, 0));
        s.poll(at(0));
        s.begun(Some(3));
        s.poll(at(0));
        s.begun(Some(4));
        s.render_failed();
        let mut ended = vec![];
        let closed = loop {
            match s.poll(at(0)) {
                Action::End { frame } => ended.push(frame),
                Action::Close(c) => break c,
                a => panic!("unexpected {a:?}"),
            }
        };
        ended.sort();
        assert_eq!(ended, [3, 4]);
        assert_eq!(closed, Closed::RenderFailed { row: 0 });
    }

    #[test]
    fn pipeline_queue_applies_backpressure() {
        let mut s: Session<usize> = Session::new(Mode::Persistent, at(0));
        let many: Vec<u8> = (0..10).flat_map(|i| request(i << 10, 3 << 10, 0)).collect();
        assert_eq!(s.receive(at(0), &many), PIPELINE_DEPTH * 12, "queue holds PIPELINE_DEPTH");
        // Beginning a frame frees a slot.
        assert!(matches!(s.poll(at(0)), Action::Begin { .. }));
        s.begun(Some(0));
        assert_eq!(s.receive(at(0), &many[PIPELINE_DEPTH * 12..]), 12);
    }

    #[test]
    fn bad_light_closes_with_no_frame_bytes() {
        let mut s = Session::new(Mode::Single, at(0));
        s.receive(at(0), &request(0, 1 << 23, 0));
        let (out, closed) = run(&mut s, 4096);
        assert!(out.is_empty());
        assert!(matches!(closed, Closed::BadLight(e) if e.axis == model::light::Axis::Y));
    }

    #[test]
    fn bad_light_after_good_ones_keeps_earlier_frames() {
        let mut s = Session::new(Mode::Persistent, at(0));
        let mut bytes = request(1024, 4096, 0).to_vec();
        bytes.extend_from_slice(&request(-(1 << 23) - 1, 0, 0));
        bytes.extend_from_slice(&request(1024, 4096, 0));
        s.receive(at(0), &bytes);
        let (out, closed) = run(&mut s, 4096);
        assert_eq!(out.len(), FRAME_BYTES, "exactly the first frame");
        assert!(matches!(closed, Closed::BadLight(e) if e.axis == model::light::Axis::X));
    }

    #[test]
    fn short_request_at_eof_is_dropped() {
        for mode in [Mode::Single, Mode::Persistent] {
            let mut s: Session<usize> = Session::new(mode, at(0));
            s.receive(at(0), &[0, 0, 4]);
            s.receive_eof();
            assert_eq!(s.poll(at(0)), Action::Close(Closed::ShortRequest { received: 3 }));
        }
        let mut s: Session<usize> = Session::new(Mode::Single, at(0));
        s.receive_eof();
        assert_eq!(s.poll(at(0)), Action::Close(Closed::NoRequest));
    }

    #[test]
    fn persistent_eof_after_complete_requests_finishes_them() {
        let mut s = Session::new(Mode::Persistent, at(0));
        s.receive(at(0), &request(0, 4096, 0));
        s.receive(at(0), &[9, 9]); // a partial second request
        s.receive_eof();
        let (out, closed) = run(&mut s, 100_000);
        assert_eq!(out.len(), FRAME_BYTES);
        assert_eq!(closed, Closed::ShortRequest { received: 2 });
    }

    #[test]
    fn partial_request_times_out() {
        let mut s: Session<usize> = Session::new(Mode::Single, at(1_000));
        s.receive(at(2_000), &[0; 5]);
        assert_eq!(s.poll(at(2_000)), Action::Wait { deadline: Some(at(7_000)) });
        s.receive(at(3_000), &[0; 2]); // more bytes restart the clock
        assert_eq!(s.poll(at(7_999)), Action::Wait { deadline: Some(at(8_000)) });
        assert_eq!(s.poll(at(8_000)), Action::Close(Closed::RequestTimeout { received: 7 }));
        // An idle connection without a partial request does not time out.
        let mut idle: Session<usize> = Session::new(Mode::Persistent, at(0));
        assert_eq!(idle.poll(at(1_000_000)), Action::Wait { deadline: None });
    }

    #[test]
    fn render_failure_closes_mid_frame() {
        struct Failing;
        impl RowSource for Failing {
            type Error = &'static str;
            fn render_row(&mut self, y: u16, _: &Light, out: &mut [u32; WIDTH]) -> Result<(), &'static str> {
                out.fill(0);
                if y == 5 {
                    Err("row 5 broke")
                } else {
                    Ok(())
                }
            }
        }
        let mut s = Session::new(Mode::Single, at(0));
        s.receive(at(0), &request(0, 4096, 0));
        let mut src = RowFrames::<Failing, 1>::new(Failing);
        let (mut sent, mut log) = (0, String::new());
        let a = loop {
            let a = drive(
                &mut s,
                Instant::ZERO,
                &mut src,
                |fill| {
                    let mut buf = [0u8; 4096];
                    let n = fill(&mut buf);
                    sent += n;
                    n
                },
                &mut log,
            );
            if !matches!(a, Action::Progress { .. }) {
                break a;
            }
        };
        assert!(log.ends_with("row 5: render failed: row 5 broke\n"), "{log}");
        assert_eq!(a, Action::Close(Closed::RenderFailed { row: 5 }));
        assert_eq!(sent, 5 * ROW_BYTES);
        assert!(!s.mid_frame());
        assert_eq!(src.begin(&Light::from_raw(0, 0, 0).unwrap()).unwrap(), Some(0), "the frame was ended");
    }

    #[test]
    fn send_with_no_room_pauses() {
        let mut s = Session::new(Mode::Single, at(0));
        s.receive(at(0), &request(0, 4096, 0));
        let mut src = Source::new(SoftwareRenderer);
        let a = drive(&mut s, Instant::ZERO, &mut src, |_| 0, &mut String::new());
        assert_eq!(a, Action::Send { frame: 0, row: 0, offset: 0 });
        assert!(!s.mid_frame(), "nothing sent yet");
    }

    // The two ways the fuzz harness (tests/fuzz_server.rs) first found to
    // hold a socket for ever.

    #[test]
    fn a_seed_port_client_that_sends_nothing_times_out() {
        let mut s: Session<usize> = Session::new(Mode::Single, at(1_000));
        assert_eq!(s.poll(at(5_999)), Action::Wait { deadline: Some(at(6_000)) });
        assert_eq!(s.poll(at(6_000)), Action::Close(Closed::RequestTimeout { received: 0 }));
    }

    #[test]
    fn a_client_that_stops_reading_is_closed_after_the_send_timeout() {
        let mut s = Session::new(Mode::Single, at(0));
        s.receive(at(0), &request(0, 4096, 0));
        let mut src = Source::new(SoftwareRenderer);
        let mut stuck = |now| drive(&mut s, now, &mut src, |_| 0, &mut String::new());
        assert_eq!(stuck(at(0)), Action::Send { frame: 0, row: 0, offset: 0 });
        let last_chance = at(SEND_TIMEOUT.as_millis() as u64 - 1);
        assert!(matches!(stuck(last_chance), Action::Send { .. }));
        assert_eq!(stuck(at(0) + SEND_TIMEOUT), Action::Close(Closed::Stalled { row: 0 }));
        assert_eq!(src.begin(&Light::from_raw(0, 0, 0).unwrap()).unwrap(), Some(0), "the frame was ended");
    }
}
