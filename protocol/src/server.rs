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
//! Rows go out as they are rendered: the session holds one row of output
//! (1,440 bytes), never a frame.
//!
//! # Bad input
//!
//! * A light outside the word range closes the connection when that request
//!   is reached, with zero bytes of its frame ([`Closed::BadLight`]); frames
//!   of earlier requests are complete.
//! * A request cut short by end of stream is dropped ([`Closed::ShortRequest`]).
//! * A partial request idle for [`REQUEST_TIMEOUT`] is dropped
//!   ([`Closed::RequestTimeout`]).
//! * A client vanishing mid-frame is the adapter's to notice (the socket
//!   fails); it drops the session, which holds nothing else.

use core::time::Duration;

use heapless::Deque;
use model::{row_to_rgb888, Light, LightError, HEIGHT, ROW_BYTES, WIDTH};

use crate::time::Instant;
use crate::wire::{decode_request, REQUEST_BYTES};
#[cfg(doc)]
use crate::wire::{FRAME_PORT, PERSISTENT_PORT};

/// How long a partially received request may sit idle before it is dropped.
pub const REQUEST_TIMEOUT: Duration = Duration::from_secs(5);

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
    /// A partial request sat idle for [`REQUEST_TIMEOUT`].
    RequestTimeout {
        /// Bytes of the incomplete request.
        received: u8,
    },
    /// The client closed before sending any request.
    NoRequest,
    /// The row source failed (for example the accelerator timed out); the
    /// frame in progress is abandoned.
    RenderFailed {
        /// The row that could not be rendered.
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
                write!(f, "partial request idle for {} ms ({received} of 12 bytes)", REQUEST_TIMEOUT.as_millis())
            }
            Closed::NoRequest => f.write_str("client closed without a request"),
            Closed::RenderFailed { row } => write!(f, "rendering row {row} failed"),
        }
    }
}

/// What the adapter should do next.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Action {
    /// Render row `y` for `light` and hand it to [`Session::row_rendered`]
    /// (or report [`Session::render_failed`]). `y == 0` starts a new frame.
    Render {
        /// Row to render, `0..360`.
        y: u16,
        /// The request's light.
        light: Light,
    },
    /// Send (a prefix of) [`Session::outgoing`], then call [`Session::sent`].
    Send,
    /// Nothing to do until more bytes arrive, the stream ends, or the time
    /// reaches `deadline` (when given).
    Wait {
        /// When [`Session::poll`] will next have something to do on its own.
        deadline: Option<Instant>,
    },
    /// Close the connection (gracefully: queued bytes were all handed out).
    Close(Closed),
}

/// A complete request: a valid light or the reason it is not.
type Request = Result<Light, LightError>;

/// One connection's protocol state.
#[derive(Debug)]
pub struct Session {
    mode: Mode,
    partial: [u8; REQUEST_BYTES],
    partial_len: u8,
    /// Time of the last byte added to `partial`.
    partial_since: Instant,
    requests_seen: u32,
    queue: Deque<Request, PIPELINE_DEPTH>,
    /// The frame being sent and its next row to render.
    frame: Option<(Light, u16)>,
    out: [u8; ROW_BYTES],
    out_start: usize,
    out_end: usize,
    eof: bool,
    closed: Option<Closed>,
}

impl Session {
    /// A new session for a connection accepted at `now`.
    pub fn new(mode: Mode, now: Instant) -> Session {
        Session {
            mode,
            partial: [0; REQUEST_BYTES],
            partial_len: 0,
            partial_since: now,
            requests_seen: 0,
            queue: Deque::new(),
            frame: None,
            out: [0; ROW_BYTES],
            out_start: 0,
            out_end: 0,
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
    pub fn poll(&mut self, now: Instant) -> Action {
        if let Some(reason) = self.closed {
            return Action::Close(reason);
        }
        if self.out_start < self.out_end {
            return Action::Send;
        }
        if let Some((light, y)) = self.frame {
            if (y as usize) < HEIGHT {
                return Action::Render { y, light };
            }
            self.frame = None;
            if self.mode == Mode::Single {
                return self.close(Closed::Done);
            }
        }
        match self.queue.pop_front() {
            Some(Ok(light)) => {
                self.frame = Some((light, 0));
                return Action::Render { y: 0, light };
            }
            Some(Err(e)) => return self.close(Closed::BadLight(e)),
            None => {}
        }
        let received = self.partial_len;
        if self.eof {
            return self.close(match (received, self.requests_seen) {
                (0, 0) => Closed::NoRequest,
                (0, _) => Closed::Done,
                _ => Closed::ShortRequest { received },
            });
        }
        if received > 0 {
            let deadline = self.partial_since + REQUEST_TIMEOUT;
            if now >= deadline {
                return self.close(Closed::RequestTimeout { received });
            }
            return Action::Wait { deadline: Some(deadline) };
        }
        Action::Wait { deadline: None }
    }

    /// The row asked for by the last [`Action::Render`] is in `row`.
    pub fn row_rendered(&mut self, row: &[u32; WIDTH]) {
        if let Some((_, y)) = &mut self.frame {
            row_to_rgb888(row, &mut self.out);
            self.out_start = 0;
            self.out_end = ROW_BYTES;
            *y += 1;
        }
    }

    /// The row asked for by the last [`Action::Render`] could not be rendered.
    pub fn render_failed(&mut self) {
        let row = self.frame.map_or(0, |(_, y)| y);
        self.close(Closed::RenderFailed { row });
    }

    /// Bytes waiting to be sent.
    pub fn outgoing(&self) -> &[u8] {
        &self.out[self.out_start..self.out_end]
    }

    /// `n` bytes of [`Session::outgoing`] were sent.
    pub fn sent(&mut self, n: usize) {
        self.out_start = (self.out_start + n).min(self.out_end);
    }

    /// Whether a frame is partly sent (a close now would cut it short).
    pub fn mid_frame(&self) -> bool {
        self.frame.is_some() || self.out_start < self.out_end
    }

    fn close(&mut self, reason: Closed) -> Action {
        self.closed = Some(reason);
        self.frame = None;
        self.out_start = 0;
        self.out_end = 0;
        Action::Close(reason)
    }
}

/// Anything that renders one row of line-buffer words: the model on the CPU,
/// the accelerator through hal-avalon's driver, the simulated accelerator.
pub trait RowSource {
    /// Why a row could not be rendered.
    type Error: core::fmt::Debug;

    /// Render row `y` (`0..360`) for `light` into `out` (`0x00RRGGBB` words).
    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Self::Error>;
}

/// The software renderer: the bit-exact model running on the CPU.
#[derive(Clone, Copy, Debug, Default)]
pub struct SoftwareRenderer;

impl RowSource for SoftwareRenderer {
    type Error = core::convert::Infallible;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Self::Error> {
        model::render_row(y, light, out);
        Ok(())
    }
}

/// Carry out [`Session::poll`]'s actions until the session must wait for
/// I/O: render rows with `rows` and hand output to `send` (which returns how
/// many bytes it took; 0 means "no room now"). Each new frame's request is
/// written to `log` as one line. Returns the last action: [`Action::Wait`],
/// [`Action::Send`] (output pending, no room), or [`Action::Close`].
pub fn drive<R: RowSource>(
    session: &mut Session,
    now: Instant,
    rows: &mut R,
    row: &mut [u32; WIDTH],
    mut send: impl FnMut(&[u8]) -> usize,
    log: &mut impl core::fmt::Write,
) -> Action {
    loop {
        match session.poll(now) {
            Action::Render { y, light } => {
                if y == 0 {
                    let [x, y, z] = light.raw();
                    // A log sink that fails must not stop the frame.
                    let _ = writeln!(log, "request light raw ({x}, {y}, {z}) on {:?}", session.mode());
                }
                match rows.render_row(y, &light, row) {
                    Ok(()) => session.row_rendered(row),
                    Err(e) => {
                        let _ = writeln!(log, "row {y}: render failed: {e:?}");
                        session.render_failed();
                    }
                }
            }
            Action::Send => {
                let n = send(session.outgoing());
                if n == 0 {
                    return Action::Send;
                }
                session.sent(n);
            }
            other => return other,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::FRAME_BYTES;

    fn request(x: i32, y: i32, z: i32) -> [u8; 12] {
        crate::wire::encode_raw_request([x, y, z])
    }

    fn at(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    fn expected(x: i32, y: i32, z: i32) -> Vec<u8> {
        model::render_frame(&Light::from_raw(x, y, z).expect("test light in range"))
    }

    /// Run a session to its close, collecting output; `chunk` limits how much
    /// each send takes, to exercise partial sends.
    fn run(session: &mut Session, chunk: usize) -> (Vec<u8>, Closed) {
        let mut out = Vec::new();
        let mut row = [0u32; WIDTH];
        loop {
            match drive(
                session,
                Instant::ZERO,
                &mut SoftwareRenderer,
                &mut row,
                |b| {
                    let n = b.len().min(chunk);
                    out.extend_from_slice(&b[..n]);
                    n
                },
                &mut String::new(),
            ) {
                Action::Close(c) => return (out, c),
                Action::Wait { .. } => session.receive_eof(),
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
        let mut row = [0u32; WIDTH];
        let mut out = Vec::new();
        let mut log = String::new();
        let last = drive(
            &mut s,
            Instant::ZERO,
            &mut SoftwareRenderer,
            &mut row,
            |b| {
                out.extend_from_slice(&b[..b.len().min(1000)]);
                b.len().min(1000)
            },
            &mut log,
        );
        assert_eq!(log, "request light raw (3072, 4096, -2048) on Single\n");
        assert_eq!(last, Action::Close(Closed::Done));
        assert_eq!(out, expected(3 << 10, 4 << 10, -2 << 10));
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
    fn pipeline_queue_applies_backpressure() {
        let mut s = Session::new(Mode::Persistent, at(0));
        let many: Vec<u8> = (0..10).flat_map(|i| request(i << 10, 3 << 10, 0)).collect();
        assert_eq!(s.receive(at(0), &many), PIPELINE_DEPTH * 12, "queue holds PIPELINE_DEPTH");
        // Starting a frame frees a slot.
        assert!(matches!(s.poll(at(0)), Action::Render { y: 0, .. }));
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
            let mut s = Session::new(mode, at(0));
            s.receive(at(0), &[0, 0, 4]);
            s.receive_eof();
            assert_eq!(s.poll(at(0)), Action::Close(Closed::ShortRequest { received: 3 }));
        }
        let mut s = Session::new(Mode::Single, at(0));
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
        let mut s = Session::new(Mode::Single, at(1_000));
        s.receive(at(2_000), &[0; 5]);
        assert_eq!(s.poll(at(2_000)), Action::Wait { deadline: Some(at(7_000)) });
        s.receive(at(3_000), &[0; 2]); // more bytes restart the clock
        assert_eq!(s.poll(at(7_999)), Action::Wait { deadline: Some(at(8_000)) });
        assert_eq!(s.poll(at(8_000)), Action::Close(Closed::RequestTimeout { received: 7 }));
        // An idle connection without a partial request does not time out.
        let mut idle = Session::new(Mode::Persistent, at(0));
        assert_eq!(idle.poll(at(1_000_000)), Action::Wait { deadline: None });
    }

    #[test]
    fn render_failure_closes_mid_frame() {
        struct Failing;
        impl RowSource for Failing {
            type Error = ();
            fn render_row(&mut self, y: u16, _: &Light, out: &mut [u32; WIDTH]) -> Result<(), ()> {
                out.fill(0);
                if y == 5 {
                    Err(())
                } else {
                    Ok(())
                }
            }
        }
        let mut s = Session::new(Mode::Single, at(0));
        s.receive(at(0), &request(0, 4096, 0));
        let mut sent = 0;
        let mut row = [0u32; WIDTH];
        let mut log = String::new();
        let a = drive(
            &mut s,
            Instant::ZERO,
            &mut Failing,
            &mut row,
            |b| {
                sent += b.len();
                b.len()
            },
            &mut log,
        );
        assert!(log.ends_with("row 5: render failed: ()\n"), "{log}");
        assert_eq!(a, Action::Close(Closed::RenderFailed { row: 5 }));
        assert_eq!(sent, 5 * ROW_BYTES);
        assert!(!s.mid_frame());
    }

    #[test]
    fn send_with_no_room_pauses() {
        let mut s = Session::new(Mode::Single, at(0));
        s.receive(at(0), &request(0, 4096, 0));
        let mut row = [0u32; WIDTH];
        let a = drive(&mut s, Instant::ZERO, &mut SoftwareRenderer, &mut row, |_| 0, &mut String::new());
        assert_eq!(a, Action::Send);
        assert!(s.mid_frame());
        assert_eq!(s.outgoing().len(), ROW_BYTES, "one row rendered, none sent");
    }
}
