//! One web connection as a sans-IO state machine: bytes in, actions out,
//! like the seed server's [`Session`](crate::seed::server::Session).
//!
//! A connection reads one request head. A page file, `/status` or an
//! error is answered and the connection closes. A WebSocket handshake on
//! `/ws`, when a viewer's place is free, turns the connection into a
//! viewer: each binary message from the page is a 12-byte request (the
//! seed protocol's: the light as three big-endian Q13.10 words), answered
//! with one binary message of the frame's 518,400 bytes, its rows copied
//! from the frame source straight into the transport. The page asks for the
//! next frame when it has drawn the last, so frames never queue on the
//! board; a request that arrives while a frame goes out waits, and a newer
//! one replaces it.
//!
//! # Bad input and deadlines
//!
//! * A head not complete within [`REQUEST_LIMIT`]: 408 and close.
//! * Heads beyond the caps of [`super::http`]: 414, 431; other
//!   methods 405; a body 413; anything else unparsable 400; no place for a
//!   viewer 503.
//! * A client frame against RFC 6455 (unmasked, reserved bits or opcodes,
//!   a bad control frame): close 1002; a text message 1003; a fragmented
//!   message 1008; a binary message longer than a request 1009 (without
//!   reading it), shorter 1007, as is a light out of range.
//! * A ping is answered with a pong, a close with a close, each after the
//!   frame going out (a frame's bytes cannot be interrupted).
//! * A viewer that asks for nothing for [`VIEWER_IDLE`]: close 1001.
//! * No byte leaving for [`SEND_TIMEOUT`] while there is something to send:
//!   the client stopped reading; the connection is dropped.

use core::time::Duration;

use heapless::Vec;
use model::{Light, FRAME_BYTES, ROW_BYTES};

use super::assets;
use super::guard;
use super::http::{self, Method, Out, Parsed, Status, Upgrade, HEAD_BYTES};
use super::status::{BoardStatus, LogTail};
use super::websocket::{self, CloseCode, Opcode, CONTROL_PAYLOAD, MAX_HEAD};
use crate::frames::{FrameSource, ROWS};
use crate::seed::wire::{decode_request, REQUEST_BYTES};
use crate::time::{Instant, REQUEST_LIMIT};

/// How long output may wait for the client to take a byte.
/// Also how long a frame may wait for its rows: far beyond any render time,
/// even the software renderer's on the board (as the seed server's).
pub const SEND_TIMEOUT: Duration = Duration::from_secs(30);

/// How long a viewer may go without asking for a frame (the page asks at
/// least once a second at its slowest rate).
pub const VIEWER_IDLE: Duration = Duration::from_secs(30);

/// How long one frame may take to go out whole (its slot is held
/// meanwhile): 518,400 bytes in 20 s is 0.2 Mbit/s, far below any
/// browser on a LAN or the emulated board's pace. A reader slower than that is
/// dropped rather than keep a slot other viewers wait for (the send
/// deadline alone restarts on every byte).
pub const FRAME_LIMIT: Duration = Duration::from_secs(20);

/// The page's content security policy: its own files only, its WebSocket
/// and `/status` on its own origin (`connect-src 'self'`, which covers
/// `ws:` to the same host in CSP Level 3), never inside another site's
/// frame (`frame-ancestors 'none'`); `data:` for the icon and a saved PNG.
pub const PAGE_POLICY: &str =
    "default-src 'self'; connect-src 'self'; img-src 'self' data: blob:; frame-ancestors 'none'; base-uri 'none'; form-action 'none'";

/// Why a connection ended.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Closed {
    /// An HTTP response went out (`Status`), or a viewer's close handshake
    /// ended (`None`).
    Answered(Option<Status>),
    /// The viewer was closed with this code.
    Viewer(CloseCode),
    /// The client closed its side (no request, or a viewer leaving).
    ClientLeft,
    /// Nothing left for [`SEND_TIMEOUT`] though something was to send.
    Stalled,
}

impl Closed {
    /// Whether the connection can be closed in order (its last bytes sent),
    /// rather than dropped.
    pub const fn graceful(self) -> bool {
        !matches!(self, Closed::Stalled)
    }
}

impl core::fmt::Display for Closed {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Closed::Answered(Some(s)) => write!(f, "answered {} {}", s.code(), s.reason()),
            Closed::Answered(None) => f.write_str("viewer closed"),
            Closed::Viewer(c) => write!(f, "viewer closed with {} ({c:?})", c.code()),
            Closed::ClientLeft => f.write_str("client left"),
            Closed::Stalled => write!(f, "client took nothing for {} s", SEND_TIMEOUT.as_secs()),
        }
    }
}

/// What the adapter should do next ([`drive`] carries these out).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Action<F> {
    /// Hand [`Connection::output`] to the transport and report how much
    /// it took with [`Connection::wrote`].
    Write,
    /// Ask the source for a frame for `light`; report with
    /// [`Connection::begun`].
    Begin {
        /// The request's light.
        light: Light,
    },
    /// Ask how many rows of `frame` are ready; report with
    /// [`Connection::rows_ready`].
    Progress {
        /// The frame going out.
        frame: F,
    },
    /// Copy bytes `offset..` of row `row` of `frame` into the transport;
    /// report with [`Connection::sent`].
    Send {
        /// The frame going out.
        frame: F,
        /// Its row.
        row: u16,
        /// The first byte of the row not sent.
        offset: usize,
    },
    /// Give `frame` back to the source.
    End {
        /// The frame.
        frame: F,
    },
    /// Nothing to do until input, room in the transport, or `deadline`.
    Wait {
        /// When the connection next has something to do on its own.
        deadline: Option<Instant>,
    },
    /// Close the connection (every frame was ended before).
    Close(Closed),
}

/// What the board tells a connection on each poll.
#[derive(Clone, Copy, Debug)]
pub struct Context<'a> {
    /// Now.
    pub now: Instant,
    /// Whether a viewer's place is free (for a handshake).
    pub room: bool,
    /// The board's status, for `/status`.
    pub status: &'a BoardStatus<'a>,
    /// The board's host name (mDNS, without `.local`): the one name besides
    /// `localhost` that a request's `Host` may carry ([`guard`]).
    pub name: &'a str,
    /// Whether it is this viewer's turn to begin a frame ([`Turns`]); a
    /// viewer whose turn it is not waits with its request.
    pub may_begin: bool,
    /// The board's log, for `/log`.
    pub log: &'a dyn LogTail,
}

/// The most of the log `/log` answers with: its newest whole lines (about
/// fifty).
pub const LOG_BYTES: usize = 4096;

/// Whose turn it is to begin a frame among `N` connections sharing a few
/// frame slots: the viewers waiting for one, first come first served. A
/// viewer that has just sent a frame and asks for the next one queues
/// behind those already waiting, so two that always keep a request queued
/// cannot hold both slots while others wait (they had, polled first).
#[derive(Debug, Default)]
pub struct Turns<const N: usize> {
    waiting: heapless::Deque<u8, N>,
}

impl<const N: usize> Turns<N> {
    /// Nobody waiting.
    pub const fn new() -> Turns<N> {
        Turns { waiting: heapless::Deque::new() }
    }

    /// Whether connection `i` may begin a frame now: nobody waits, or it
    /// waits first.
    pub fn may_begin(&self, i: usize) -> bool {
        self.waiting.front().is_none_or(|&w| usize::from(w) == i)
    }

    /// After connection `i` was served: whether it still wants a frame
    /// begun (it waits its turn) or not (it began one, or left).
    pub fn served(&mut self, i: usize, wants: bool) {
        let Ok(i8) = u8::try_from(i) else { return };
        let queued = self.waiting.iter().any(|&w| w == i8);
        if wants && !queued {
            let _ = self.waiting.push_back(i8);
        } else if !wants && queued {
            let mut kept = heapless::Deque::new();
            for w in self.waiting.iter().copied().filter(|&w| w != i8) {
                // No more than were there.
                let _ = kept.push_back(w);
            }
            self.waiting = kept;
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct Sending<F> {
    frame: F,
    row: u16,
    offset: usize,
    ready: u16,
    begun_at: Instant,
}

#[derive(Debug)]
struct Viewer<F> {
    /// A client frame's head and (short) payload, as received.
    input: Vec<u8, { MAX_HEAD + CONTROL_PAYLOAD }>,
    /// The newest request not begun yet.
    wanted: Option<Light>,
    sending: Option<Sending<F>>,
    /// A pong to send (its payload) after the frame going out.
    pong: Option<Vec<u8, CONTROL_PAYLOAD>>,
    /// A close to send after the frame going out, and the connection's end.
    close: Option<(u16, Closed)>,
    /// When a request was last seen waiting (the upgrade, before the
    /// first).
    asked_at: Instant,
    frames: u32,
}

// A connection lives in its socket's slot for its whole life (no moves
// worth saving), and there is no allocator to box the viewer's buffers.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
enum State<F> {
    Head,
    /// Writing a response, then closing (or becoming a viewer).
    Respond {
        then_viewer: bool,
        closed: Closed,
    },
    Viewer(Viewer<F>),
    Closed(Closed),
}

/// One web connection, holding frames of type `F`.
#[derive(Debug)]
pub struct Connection<F> {
    state: State<F>,
    head: Vec<u8, HEAD_BYTES>,
    /// Bytes of `head` that were the request head (the rest: a viewer's).
    head_used: usize,
    since: Instant,
    /// Output not yet taken: `small[small_sent..]`, then
    /// `text[text_sent..]`, then `body[body_sent..]`.
    small: Out,
    small_sent: usize,
    /// The log's tail for `/log`, copied when it was asked for.
    text: Vec<u8, LOG_BYTES>,
    text_sent: usize,
    body: &'static [u8],
    body_sent: usize,
    /// The last time output moved (or became due).
    moved_at: Instant,
    /// The transport's write position mod 4, as far as known
    /// ([`transport_at`](Self::transport_at), then every byte written).
    align: u8,
    eof: bool,
    /// The request was a HEAD: answers go without their body.
    head_only: bool,
    /// Closing, once the frame going out has been given back.
    dropping: Option<Closed>,
}

impl<F: Copy> Connection<F> {
    /// A connection accepted at `now`.
    pub fn new(now: Instant) -> Connection<F> {
        Connection {
            state: State::Head,
            head: Vec::new(),
            head_used: 0,
            since: now,
            small: Out::new(),
            small_sent: 0,
            text: Vec::new(),
            text_sent: 0,
            body: &[],
            body_sent: 0,
            moved_at: now,
            align: 0,
            eof: false,
            head_only: false,
            dropping: None,
        }
    }

    /// Whether the connection is a WebSocket viewer.
    pub fn is_viewer(&self) -> bool {
        matches!(self.state, State::Viewer(_)) || matches!(self.state, State::Respond { then_viewer: true, .. })
    }

    /// Whether the connection is a viewer with a request waiting for a
    /// frame to begin ([`Turns`]).
    pub fn wants_frame(&self) -> bool {
        matches!(&self.state, State::Viewer(v) if v.sending.is_none() && v.wanted.is_some() && v.close.is_none())
    }

    /// Frames a viewer has been sent whole.
    pub fn frames_sent(&self) -> u32 {
        match &self.state {
            State::Viewer(v) => v.frames,
            _ => 0,
        }
    }

    /// Take received bytes; returns how many were used (fewer: offer the
    /// rest later, when the frame going out is done).
    pub fn receive(&mut self, data: &[u8]) -> usize {
        match &mut self.state {
            State::Head => {
                // What does not fit stays with the transport: a head that
                // fills the buffer is refused, and bytes after a complete
                // one are a viewer's first frames (or dropped with the
                // answer, which closes).
                let take = data.len().min(HEAD_BYTES - self.head.len());
                // Room checked above.
                let _ = self.head.extend_from_slice(&data[..take]);
                take
            }
            State::Viewer(v) => receive_frames(v, data),
            // An answer is going out and the connection closes after it.
            State::Respond { .. } | State::Closed(_) => data.len(),
        }
    }

    /// The client closed its sending side.
    pub fn receive_eof(&mut self) {
        self.eof = true;
    }

    /// Output for [`Action::Write`].
    pub fn output(&self) -> &[u8] {
        match (self.small.get(self.small_sent..), self.text.get(self.text_sent..)) {
            (Some(s), _) if !s.is_empty() => s,
            (_, Some(t)) if !t.is_empty() => t,
            _ => self.body.get(self.body_sent..).unwrap_or(&[]),
        }
    }

    /// The transport's next byte goes to an address `align` mod 4 (its
    /// buffer's write position): a frame's head is then laid out so that
    /// its rows land word aligned (a frame's 518,400 bytes are copied in
    /// whole words; at 2 mod 4, as a bare 10-byte head leaves them half
    /// the time, the copies cost 60% more instructions). An adapter that
    /// does not know leaves it; alignment is then counted from the start.
    pub fn transport_at(&mut self, align: usize) {
        self.align = (align % 4) as u8;
    }

    fn advance(&mut self, n: usize) {
        self.align = ((usize::from(self.align) + n) % 4) as u8;
    }

    /// The transport took `n` bytes of [`output`](Self::output) at `now`.
    pub fn wrote(&mut self, now: Instant, n: usize) {
        if n == 0 {
            return;
        }
        self.advance(n);
        self.moved_at = now;
        let small_left = self.small.len() - self.small_sent;
        let text_left = self.text.len() - self.text_sent;
        if small_left > 0 {
            self.small_sent += n.min(small_left);
        } else if text_left > 0 {
            self.text_sent += n.min(text_left);
        } else {
            self.body_sent = (self.body_sent + n).min(self.body.len());
        }
    }

    fn output_pending(&self) -> bool {
        !self.output().is_empty()
    }

    fn respond(&mut self, now: Instant, status: Status, extra: &[(&str, &str)]) {
        self.small.clear();
        self.small_sent = 0;
        self.text.clear();
        self.text_sent = 0;
        let text = status.reason();
        let mut body = Out::new();
        let _ = body.extend_from_slice(text.as_bytes());
        let _ = body.push(b'\n');
        let _ = http::head(&mut self.small, status, Some(body.len()), extra);
        if !self.head_only {
            let _ = self.small.extend_from_slice(&body);
        }
        self.body = &[];
        self.body_sent = 0;
        self.moved_at = now;
        self.state = State::Respond { then_viewer: false, closed: Closed::Answered(Some(status)) };
    }

    /// Answer 200 with `text` as the body (none for HEAD), never cached.
    fn answer_text(&mut self, now: Instant, method: Method, content_type: &str) -> Action<F> {
        self.small.clear();
        self.small_sent = 0;
        let extra = [("Content-Type", content_type), ("Cache-Control", "no-store")];
        let _ = http::head(&mut self.small, Status::Ok, Some(self.text.len()), &extra);
        if method != Method::Get {
            self.text.clear();
        }
        self.body = &[];
        self.moved_at = now;
        self.state = State::Respond { then_viewer: false, closed: Closed::Answered(Some(Status::Ok)) };
        Action::Write
    }

    /// The next action.
    pub fn poll(&mut self, cx: &Context<'_>) -> Action<F> {
        let now = cx.now;
        if let Some(closed) = self.dropping.take() {
            return self.close(closed);
        }
        // Output first: it goes out before anything else happens.
        if self.output_pending() {
            if now >= self.moved_at + SEND_TIMEOUT || self.frame_overdue(now) {
                return self.close(Closed::Stalled);
            }
            return Action::Write;
        }
        match &mut self.state {
            State::Closed(c) => Action::Close(*c),
            State::Head => self.poll_head(cx),
            State::Respond { then_viewer, closed } => {
                if *then_viewer {
                    let mut viewer = Viewer {
                        input: Vec::new(),
                        wanted: None,
                        sending: None,
                        pong: None,
                        close: None,
                        asked_at: now,
                        frames: 0,
                    };
                    receive_frames(&mut viewer, self.head.get(self.head_used..).unwrap_or(&[]));
                    self.head.clear();
                    self.state = State::Viewer(viewer);
                    self.moved_at = now;
                    self.poll(cx)
                } else {
                    let c = *closed;
                    self.close(c)
                }
            }
            State::Viewer(_) => self.poll_viewer(now, cx.may_begin),
        }
    }

    /// Whether a frame going out has taken [`FRAME_LIMIT`] already.
    fn frame_overdue(&self, now: Instant) -> bool {
        matches!(&self.state, State::Viewer(Viewer { sending: Some(s), .. }) if now >= s.begun_at + FRAME_LIMIT)
    }

    fn close(&mut self, closed: Closed) -> Action<F> {
        if let State::Viewer(v) = &mut self.state {
            if let Some(s) = v.sending.take() {
                // The frame goes back first; the next poll closes.
                self.dropping = Some(closed);
                return Action::End { frame: s.frame };
            }
        }
        self.state = State::Closed(closed);
        Action::Close(closed)
    }

    fn poll_head(&mut self, cx: &Context<'_>) -> Action<F> {
        let now = cx.now;
        let full = self.head.len() == HEAD_BYTES;
        let request = match http::parse(&self.head, full) {
            Parsed::Partial => {
                if self.eof {
                    return self.close(Closed::ClientLeft);
                }
                let deadline = self.since + REQUEST_LIMIT;
                if now >= deadline {
                    self.respond(now, Status::RequestTimeout, &[]);
                    return Action::Write;
                }
                return Action::Wait { deadline: Some(deadline) };
            }
            Parsed::Refuse(status) => {
                let extra: &[(&str, &str)] = match status {
                    Status::MethodNotAllowed => &[("Allow", "GET, HEAD")],
                    Status::UpgradeRequired => &[("Sec-WebSocket-Version", "13"), ("Upgrade", "websocket")],
                    _ => &[],
                };
                self.respond(now, status, extra);
                return Action::Write;
            }
            Parsed::Request(r) => r,
        };
        self.head_only = request.method == Method::Head;
        if !guard::host_is_ours(request.host, cx.name) {
            self.respond(now, Status::Forbidden, &[]);
            return Action::Write;
        }
        match (request.path, request.upgrade) {
            ("/ws", Upgrade::WebSocket(key)) => {
                if !guard::origin_is_ours(request.origin, request.host) {
                    self.respond(now, Status::Forbidden, &[]);
                    return Action::Write;
                }
                if !cx.room {
                    self.respond(now, Status::ServiceUnavailable, &[("Retry-After", "2")]);
                    return Action::Write;
                }
                let accept = websocket::accept_key(&key);
                let accept = core::str::from_utf8(&accept).unwrap_or("");
                self.small.clear();
                self.small_sent = 0;
                let _ = http::head(
                    &mut self.small,
                    Status::SwitchingProtocols,
                    None,
                    &[("Upgrade", "websocket"), ("Connection", "Upgrade"), ("Sec-WebSocket-Accept", accept)],
                );
                self.moved_at = now;
                self.state = State::Respond { then_viewer: true, closed: Closed::Answered(None) };
                // Bytes after the head belong to the viewer.
                self.head_used = request.len;
                Action::Write
            }
            ("/ws", Upgrade::None) => {
                self.respond(
                    now,
                    Status::UpgradeRequired,
                    &[("Sec-WebSocket-Version", "13"), ("Upgrade", "websocket")],
                );
                Action::Write
            }
            (_, Upgrade::WebSocket(_)) => {
                self.respond(now, Status::NotFound, &[]);
                Action::Write
            }
            ("/log", Upgrade::None) => {
                self.text.clear();
                self.text_sent = 0;
                let _ = self.text.resize(LOG_BYTES, 0);
                let n = cx.log.tail(&mut self.text);
                self.text.truncate(n);
                self.answer_text(now, request.method, "text/plain; charset=utf-8")
            }
            ("/status", Upgrade::None) => {
                // The JSON in the larger text buffer (`/log`'s): with the
                // longest values it is about 930 bytes.
                self.text.clear();
                self.text_sent = 0;
                let _ = cx.status.write_json(&mut http::Writer(&mut self.text));
                self.answer_text(now, request.method, "application/json")
            }
            (path, Upgrade::None) => {
                let Some(asset) = assets::find(path) else {
                    self.respond(now, Status::NotFound, &[]);
                    return Action::Write;
                };
                // `no-cache` with an entity tag: a browser asks again on
                // every visit (a new firmware's page is never stale) and is
                // answered 304 with no body while its copy is current.
                let fresh = request.if_none_match.is_some_and(|tags| http::etag_listed(tags, asset.etag));
                let status = if fresh { Status::NotModified } else { Status::Ok };
                let body = if request.accepts_gzip { asset.gzip } else { asset.raw };
                let mut extra: Vec<(&str, &str), 6> = Vec::new();
                let _ = extra.push(("Content-Type", asset.content_type));
                let _ = extra.push(("Cache-Control", "no-cache"));
                let _ = extra.push(("ETag", asset.etag));
                let _ = extra.push(("Vary", "Accept-Encoding"));
                let _ = extra.push(("Content-Security-Policy", PAGE_POLICY));
                if request.accepts_gzip && !fresh {
                    let _ = extra.push(("Content-Encoding", "gzip"));
                }
                self.small.clear();
                self.small_sent = 0;
                let length = (!fresh).then_some(body.len());
                let _ = http::head(&mut self.small, status, length, &extra);
                self.body = if request.method == Method::Get && !fresh { body } else { &[] };
                self.body_sent = 0;
                self.moved_at = now;
                self.state = State::Respond { then_viewer: false, closed: Closed::Answered(Some(status)) };
                Action::Write
            }
        }
    }

    fn poll_viewer(&mut self, now: Instant, may_begin: bool) -> Action<F> {
        let State::Viewer(v) = &mut self.state else { return Action::Wait { deadline: None } };
        if let Some(s) = &mut v.sending {
            if s.row == ROWS {
                let frame = s.frame;
                v.sending = None;
                v.frames = v.frames.wrapping_add(1);
                return Action::End { frame };
            }
            if now >= self.moved_at + SEND_TIMEOUT || now >= s.begun_at + FRAME_LIMIT {
                return self.close(Closed::Stalled);
            }
            if s.row < s.ready {
                return Action::Send { frame: s.frame, row: s.row, offset: s.offset };
            }
            return Action::Progress { frame: s.frame };
        }
        // Between frames: control replies, then the close, then requests.
        if let Some(payload) = v.pong.take() {
            self.queue_frame(now, Opcode::Pong, &payload);
            return Action::Write;
        }
        let State::Viewer(v) = &mut self.state else { return Action::Wait { deadline: None } };
        if let Some((code, closed)) = v.close.take() {
            self.queue_frame(now, Opcode::Close, &code.to_be_bytes());
            self.state = State::Respond { then_viewer: false, closed };
            return Action::Write;
        }
        if let Some(light) = v.wanted {
            // A request waiting is a viewer asking: the idle deadline
            // counts from the last one seen.
            v.asked_at = now;
            if !may_begin {
                return Action::Wait { deadline: None };
            }
            return Action::Begin { light };
        }
        if self.eof {
            return self.close(Closed::ClientLeft);
        }
        let deadline = v.asked_at + VIEWER_IDLE;
        if now >= deadline {
            v.close = Some((CloseCode::GoingAway.code(), Closed::Viewer(CloseCode::GoingAway)));
            return self.poll_viewer(now, may_begin);
        }
        Action::Wait { deadline: Some(deadline) }
    }

    fn queue_frame(&mut self, now: Instant, opcode: Opcode, payload: &[u8]) {
        let (head, n) = websocket::server_head(opcode, payload.len() as u64);
        self.small.clear();
        self.small_sent = 0;
        let _ = self.small.extend_from_slice(&head[..n]);
        let _ = self.small.extend_from_slice(payload);
        self.body = &[];
        self.body_sent = 0;
        self.moved_at = now;
    }

    /// The answer to [`Action::Begin`]: the frame, or `None` while the
    /// source has no room.
    pub fn begun(&mut self, now: Instant, frame: Option<F>) {
        let Some(frame) = frame else { return };
        if let State::Viewer(v) = &mut self.state {
            v.wanted = None;
            v.sending = Some(Sending { frame, row: 0, offset: 0, ready: 0, begun_at: now });
            let (head, n) = websocket::server_head(Opcode::Binary, FRAME_BYTES as u64);
            self.small.clear();
            self.small_sent = 0;
            let at = usize::from(self.align);
            if (at + n) % 4 != 0 && (at + 2 + n) % 4 == 0 {
                // Two bytes of an empty first fragment put the rows on a
                // word; the frame follows as its continuation.
                let (cont, k) = websocket::server_head(Opcode::Continuation, FRAME_BYTES as u64);
                let _ = self.small.extend_from_slice(&websocket::EMPTY_FIRST_FRAGMENT);
                let _ = self.small.extend_from_slice(&cont[..k]);
            } else {
                let _ = self.small.extend_from_slice(&head[..n]);
            }
            self.moved_at = now;
        }
    }

    /// The answer to [`Action::Progress`].
    pub fn rows_ready(&mut self, rows: u16) {
        if let State::Viewer(Viewer { sending: Some(s), .. }) = &mut self.state {
            s.ready = rows.min(ROWS);
        }
    }

    /// The answer to [`Action::Send`]: `n` bytes went out.
    pub fn sent(&mut self, now: Instant, n: usize) {
        self.advance(n);
        if let State::Viewer(Viewer { sending: Some(s), .. }) = &mut self.state {
            if n > 0 {
                self.moved_at = now;
                s.offset += n;
                if s.offset >= ROW_BYTES {
                    s.offset = 0;
                    s.row += 1;
                }
            }
        }
    }

    /// The source failed to render a frame: the viewer is closed with
    /// 1011, or dropped if part of the frame's message went out (no close
    /// frame can follow it); returns the frame to end, if one was held.
    pub fn render_failed(&mut self) -> Option<F> {
        let State::Viewer(v) = &mut self.state else { return None };
        let closed = Closed::Viewer(CloseCode::InternalError);
        match v.sending.take() {
            Some(s) => {
                self.small.clear();
                self.small_sent = 0;
                self.state = State::Closed(closed);
                Some(s.frame)
            }
            None => {
                v.wanted = None;
                v.close = Some((CloseCode::InternalError.code(), closed));
                None
            }
        }
    }

    #[cfg(test)]
    fn take_frame_for_test(&self) -> Option<F> {
        match &self.state {
            State::Viewer(Viewer { sending: Some(s), .. }) => Some(s.frame),
            _ => None,
        }
    }

    /// End the frame the connection holds, for an adapter that drops it
    /// without driving it to its close.
    pub fn abandon<S: FrameSource<Frame = F>>(&mut self, source: &mut S) {
        if let State::Viewer(Viewer { sending, .. }) = &mut self.state {
            if let Some(s) = sending.take() {
                source.end(s.frame);
            }
        }
    }
}

/// Read client frames into `v`: requests, pings, closes; a frame the
/// protocol or the page refuses sets the close.
fn receive_frames<F>(v: &mut Viewer<F>, data: &[u8]) -> usize {
    let mut used = 0;
    while used < data.len() && v.close.is_none() {
        // Hold at most one frame: a head, then its payload.
        let want = match websocket::parse_head(&v.input) {
            Err(code) => {
                v.close = Some((code.code(), Closed::Viewer(code)));
                break;
            }
            Ok(None) => v.input.len() + 1,
            Ok(Some(head)) => {
                if let Some(code) = refuse(&head) {
                    v.close = Some((code.code(), Closed::Viewer(code)));
                    break;
                }
                head.head_len + head.len as usize
            }
        };
        if v.input.len() < want {
            let take = (want - v.input.len()).min(data.len() - used);
            let _ = v.input.extend_from_slice(&data[used..used + take]);
            used += take;
        }
        if let Ok(Some(head)) = websocket::parse_head(&v.input) {
            if v.input.len() == head.head_len + head.len as usize {
                take_message(v, head);
                v.input.clear();
            }
        }
    }
    // Input after a close is dropped: the connection ends.
    data.len().max(used)
}

/// The close code for a frame the page's channel does not take (before
/// reading its payload), if any.
fn refuse(head: &websocket::FrameHead) -> Option<CloseCode> {
    match head.opcode {
        Opcode::Close | Opcode::Ping | Opcode::Pong => None,
        Opcode::Text => Some(CloseCode::UnsupportedData),
        _ if head.len > REQUEST_BYTES as u64 => Some(CloseCode::MessageTooBig),
        Opcode::Continuation => Some(CloseCode::PolicyViolation),
        Opcode::Binary if !head.fin => Some(CloseCode::PolicyViolation),
        Opcode::Binary if head.len < REQUEST_BYTES as u64 => Some(CloseCode::InvalidPayload),
        Opcode::Binary => None,
    }
}

fn take_message<F>(v: &mut Viewer<F>, head: websocket::FrameHead) {
    let payload = &mut v.input[head.head_len..];
    websocket::unmask(payload, head.mask);
    match head.opcode {
        Opcode::Binary => match payload.try_into().map(|r: [u8; REQUEST_BYTES]| decode_request(&r)) {
            Ok(Ok(light)) => v.wanted = Some(light),
            _ => v.close = Some((CloseCode::InvalidPayload.code(), Closed::Viewer(CloseCode::InvalidPayload))),
        },
        Opcode::Ping => v.pong = Vec::from_slice(payload).ok(),
        Opcode::Close => {
            v.close = Some(match close_reply(payload) {
                Ok(code) => (code, Closed::Answered(None)),
                Err(refused) => (refused.code(), Closed::Viewer(refused)),
            });
        }
        Opcode::Pong | Opcode::Text | Opcode::Continuation => {}
    }
}

/// The code to answer a client's close with (section 5.5.1: echo it), or
/// the code to fail the connection with: a body of one byte, a code no
/// endpoint may send (section 7.4: below 1000, 1004-1006, 1015, 1016-2999
/// unassigned) 1002, a reason that is not UTF-8 1007 (section 8.1). No
/// body: 1000 (1005 means "none" and is never sent).
fn close_reply(body: &[u8]) -> Result<u16, CloseCode> {
    let [a, b, reason @ ..] = body else {
        return if body.is_empty() { Ok(CloseCode::Normal.code()) } else { Err(CloseCode::ProtocolError) };
    };
    let code = u16::from_be_bytes([*a, *b]);
    let sendable = matches!(code, 1000..=1003 | 1007..=1014 | 3000..=4999);
    if !sendable {
        return Err(CloseCode::ProtocolError);
    }
    if core::str::from_utf8(reason).is_err() {
        return Err(CloseCode::InvalidPayload);
    }
    Ok(code)
}

/// Carry out `connection`'s actions with `source` until it must wait (for
/// input, room in the transport, rows, a slot) or closes. `send` offers
/// the transport's free buffer, as in the seed server's `drive`. Frames
/// sent whole are counted in `frames_sent`.
pub fn drive<S: FrameSource>(
    connection: &mut Connection<S::Frame>,
    cx: &Context<'_>,
    source: &mut S,
    mut send: impl FnMut(&mut dyn FnMut(&mut [u8]) -> usize) -> usize,
    log: &mut impl core::fmt::Write,
) -> Action<S::Frame> {
    loop {
        let action = connection.poll(cx);
        match action {
            Action::Write => {
                let n = send(&mut |buf| {
                    let out = connection.output();
                    let n = out.len().min(buf.len());
                    buf[..n].copy_from_slice(&out[..n]);
                    n
                });
                if n == 0 {
                    return action;
                }
                connection.wrote(cx.now, n);
            }
            Action::Begin { light } => match source.begin(&light) {
                Ok(frame) => {
                    let waiting = frame.is_none();
                    connection.begun(cx.now, frame);
                    if waiting {
                        return action;
                    }
                }
                Err(e) => {
                    let _ = writeln!(log, "web: frame not begun: {e}");
                    if let Some(frame) = connection.render_failed() {
                        source.end(frame);
                    }
                }
            },
            Action::Progress { frame } => {
                let before = match &connection.state {
                    State::Viewer(Viewer { sending: Some(s), .. }) => s.ready,
                    _ => 0,
                };
                match source.rows_ready(frame) {
                    Ok(rows) => {
                        connection.rows_ready(rows);
                        if rows <= before {
                            return action;
                        }
                    }
                    Err(e) => {
                        let _ = writeln!(log, "web: row {before}: render failed: {e}");
                        if let Some(frame) = connection.render_failed() {
                            source.end(frame);
                        }
                    }
                }
            }
            Action::Send { frame, row, offset } => {
                let n = send(&mut |buf| source.copy_row(frame, row, offset, buf));
                if n == 0 {
                    return action;
                }
                connection.sent(cx.now, n);
            }
            Action::End { frame } => source.end(frame),
            Action::Wait { .. } | Action::Close(_) => return action,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::{FrameRing, RowEngine, SliceMemory, SoftwareRenderer};
    use crate::web::status::{Health, Identity, NoLog, Viewers};

    type Source = FrameRing<SliceMemory<'static>, RowEngine<SoftwareRenderer>, 2>;

    fn source() -> Source {
        let memory = Box::leak(vec![0u8; 2 * FRAME_BYTES].into_boxed_slice());
        FrameRing::new(SliceMemory::new(0, memory), RowEngine::new(SoftwareRenderer))
    }

    const STATUS: BoardStatus<'static> = BoardStatus {
        uptime_s: 5,
        renderer: "simulated",
        link: "up",
        frames_rendered: 9,
        frames_sent: 8,
        viewers: Viewers { web: 0, web_max: 4, seed: 0, rtsp: 0 },
        rtsp_port: 8554,
        identity: Identity {
            version: "0.1.0",
            name: "raytracer",
            address: None,
            address_from: "none",
            mac: None,
            mac_from: "none",
            mac_clashes: 0,
        },
        health: Health {
            self_test: "pass",
            self_test_detail: "",
            mode: "frames",
            register_map: None,
            fpga_build: None,
            bridges: "not a board",
            vga: "off",
            code: "ok",
        },
    };

    /// A log of three lines.
    struct ThreeLines;

    impl LogTail for ThreeLines {
        fn tail(&self, out: &mut [u8]) -> usize {
            crate::web::status::copy_tail([b"boot\nself-test: PASS\n", b"net: address 10.0.2.15\n"], false, out)
        }
    }

    const UPGRADE: &[u8] = b"GET /ws HTTP/1.1\r\nHost: raytracer\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";

    /// A client frame, masked with a fixed key.
    fn client_frame(b0: u8, payload: &[u8]) -> std::vec::Vec<u8> {
        let mask = [1, 2, 3, 4];
        let mut f = vec![b0];
        match payload.len() {
            n if n < 126 => f.push(0x80 | n as u8),
            n if n < 65536 => {
                f.push(0x80 | 126);
                f.extend_from_slice(&(n as u16).to_be_bytes());
            }
            n => {
                f.push(0x80 | 127);
                f.extend_from_slice(&(n as u64).to_be_bytes());
            }
        }
        f.extend_from_slice(&mask);
        f.extend(payload.iter().enumerate().map(|(i, b)| b ^ mask[i % 4]));
        f
    }

    fn request(raw: [i32; 3]) -> std::vec::Vec<u8> {
        client_frame(0x82, &crate::seed::wire::encode_raw_request(raw))
    }

    struct Peer {
        c: Connection<usize>,
        src: Source,
        out: std::vec::Vec<u8>,
        now: Instant,
        room: bool,
        tail: &'static dyn LogTail,
    }

    impl Peer {
        fn new() -> Peer {
            Peer {
                c: Connection::new(Instant::ZERO),
                src: source(),
                out: vec![],
                now: Instant::ZERO,
                room: true,
                tail: &NoLog,
            }
        }

        fn send(&mut self, bytes: &[u8]) {
            let mut at = 0;
            while at < bytes.len() {
                let n = self.c.receive(&bytes[at..]);
                at += n;
                if n == 0 {
                    self.step();
                }
            }
        }

        fn step(&mut self) -> Action<usize> {
            let cx = Context {
                now: self.now,
                room: self.room,
                status: &STATUS,
                name: "raytracer",
                may_begin: true,
                log: self.tail,
            };
            let out = &mut self.out;
            drive(
                &mut self.c,
                &cx,
                &mut self.src,
                |fill| {
                    let mut buf = vec![0u8; 4096];
                    let n = fill(&mut buf);
                    out.extend_from_slice(&buf[..n]);
                    n
                },
                &mut String::new(),
            )
        }

        fn text(&self) -> String {
            String::from_utf8_lossy(&self.out).into_owned()
        }
    }

    fn answer(request: &str) -> (String, Action<usize>) {
        let mut p = Peer::new();
        p.send(request.as_bytes());
        let a = p.step();
        (p.text(), a)
    }

    #[test]
    fn the_page_is_served_compressed_to_a_browser_that_takes_it_and_plain_otherwise() {
        let asset = assets::find("/").unwrap();
        let (gz, a) = answer("GET / HTTP/1.1\r\nHost: raytracer\r\nAccept-Encoding: gzip, br\r\n\r\n");
        assert_eq!(a, Action::Close(Closed::Answered(Some(Status::Ok))));
        assert!(gz.starts_with("HTTP/1.1 200 OK\r\n"), "{gz}");
        assert!(gz.contains("Content-Encoding: gzip\r\n"));
        assert!(gz.contains(&format!("Content-Length: {}\r\n", asset.gzip.len())));
        let (plain, _) = answer("GET /?light=3,4,-2 HTTP/1.0\r\n\r\n");
        assert!(plain.ends_with(core::str::from_utf8(asset.raw).unwrap()));
        assert!(!plain.contains("Content-Encoding"));
        let (head, _) = answer("HEAD /page.js HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        assert!(head.ends_with("\r\n\r\n") && head.contains("text/javascript"), "{head}");
    }

    #[test]
    fn the_log_is_its_newest_lines_as_text() {
        let mut p = Peer::new();
        p.tail = &ThreeLines;
        p.send(b"GET /log HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        assert_eq!(p.step(), Action::Close(Closed::Answered(Some(Status::Ok))));
        let text = p.text();
        assert!(text.starts_with("HTTP/1.1 200 OK\r\n") && text.contains("text/plain"), "{text}");
        assert!(text.ends_with("\r\n\r\nboot\nself-test: PASS\nnet: address 10.0.2.15\n"), "{text}");
        let mut p = Peer::new();
        p.tail = &ThreeLines;
        p.send(b"HEAD /log HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        p.step();
        let head = p.text();
        assert!(head.ends_with("\r\n\r\n") && head.contains("Content-Length: 44\r\n"), "{head}");
    }

    #[test]
    fn the_longest_status_goes_out_whole() {
        // The longest values the firmware can give (BootFacts: a 240-byte
        // self-test line, 96 bytes of bridges; a 63-byte name).
        let (name, detail, bridges) = ("n".repeat(63), "d".repeat(240), "b".repeat(96));
        let status = BoardStatus {
            uptime_s: u64::MAX,
            renderer: "software",
            link: "1000 Mbit/s full duplex",
            frames_rendered: u64::MAX,
            frames_sent: u64::MAX,
            viewers: Viewers { web: 99, web_max: 99, seed: 99, rtsp: 99 },
            rtsp_port: 65535,
            identity: Identity {
                version: "0.1.0",
                name: &name,
                address: Some(core::net::Ipv4Addr::new(255, 255, 255, 255)),
                address_from: "link-local",
                mac: None,
                mac_from: "none",
                mac_clashes: 0,
            },
            health: Health {
                self_test: "skipped",
                self_test_detail: &detail,
                mode: "software",
                register_map: Some(u16::MAX),
                fpga_build: Some(u32::MAX),
                bridges: &bridges,
                vga: "off: the FPGA's frame DMA is not used (self-test), and the scan-out needs it",
                code: "E7",
            },
        };
        let mut c: Connection<usize> = Connection::new(Instant::ZERO);
        c.receive(b"GET /status HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        let cx = Context {
            now: Instant::ZERO,
            room: true,
            status: &status,
            name: "raytracer",
            may_begin: true,
            log: &NoLog,
        };
        let mut out = std::vec::Vec::new();
        let mut src = source();
        drive(
            &mut c,
            &cx,
            &mut src,
            |fill| {
                let mut buf = vec![0u8; 4096];
                let n = fill(&mut buf);
                out.extend_from_slice(&buf[..n]);
                n
            },
            &mut String::new(),
        );
        let text = String::from_utf8(out).unwrap();
        let (head, body) = text.split_once("\r\n\r\n").unwrap();
        let length: usize = head.lines().find_map(|l| l.strip_prefix("Content-Length: ")).unwrap().parse().unwrap();
        assert_eq!(body.len(), length, "{text}");
        assert!(body.starts_with("{\"uptime_s\":") && body.ends_with("\"code\":\"E7\"}"), "{body}");
    }

    #[test]
    fn status_is_json_and_errors_have_their_codes() {
        let (s, _) = answer("GET /status HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        assert!(s.contains("application/json") && s.contains("\"rtsp_port\":8554,\"version\":\"0.1.0\",\"name\":\"raytracer\",\"address\":null,\"address_from\":\"none\","), "{s}");
        assert!(s.ends_with(",\"mode\":\"frames\",\"register_map\":null,\"fpga_build\":null,\"bridges\":\"not a board\",\"vga\":\"off\",\"code\":\"ok\"}"), "{s}");
        for (req, code) in [
            ("GET /nope HTTP/1.1\r\nHost: raytracer\r\n\r\n", "404"),
            ("DELETE / HTTP/1.1\r\nHost: raytracer\r\n\r\n", "405"),
            ("GET / HTTP/1.1\r\nHost: raytracer\r\nContent-Length: 5\r\n\r\n", "413"),
            ("GET /ws HTTP/1.1\r\nHost: raytracer\r\n\r\n", "426"),
            ("\x00\x01garbage\r\n\r\n", "400"),
        ] {
            let (text, a) = answer(req);
            assert!(text.starts_with(&format!("HTTP/1.1 {code} ")), "{req:?}: {text}");
            assert!(matches!(a, Action::Close(Closed::Answered(Some(_)))));
        }
        let (allow, _) = answer("PUT / HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        assert!(allow.contains("Allow: GET, HEAD\r\n"));
    }

    #[test]
    fn a_head_that_does_not_come_in_time_is_answered_408() {
        let mut p = Peer::new();
        p.send(b"GET / HTTP/1.1\r\n");
        assert_eq!(p.step(), Action::Wait { deadline: Some(Instant::ZERO + REQUEST_LIMIT) });
        p.now = Instant::ZERO + REQUEST_LIMIT;
        assert!(matches!(p.step(), Action::Close(_)));
        assert!(p.text().starts_with("HTTP/1.1 408 "));
    }

    #[test]
    fn a_client_that_reads_nothing_is_dropped() {
        let mut p = Peer::new();
        p.send(b"GET / HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        let cx = Context {
            now: Instant::ZERO,
            room: true,
            status: &STATUS,
            name: "raytracer",
            may_begin: true,
            log: &NoLog,
        };
        assert_eq!(p.c.poll(&cx), Action::Write);
        let later = Context { now: Instant::ZERO + SEND_TIMEOUT, ..cx };
        assert_eq!(p.c.poll(&later), Action::Close(Closed::Stalled));
    }

    fn viewer() -> Peer {
        let mut p = Peer::new();
        p.send(UPGRADE);
        assert!(matches!(p.step(), Action::Wait { .. }));
        let text = p.text();
        assert!(text.starts_with("HTTP/1.1 101 Switching Protocols\r\n"), "{text}");
        assert!(text.contains("Sec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"));
        assert!(p.c.is_viewer());
        p.out.clear();
        p
    }

    /// Server frames in `bytes`: (opcode, payload).
    fn server_frames(mut bytes: &[u8]) -> std::vec::Vec<(u8, std::vec::Vec<u8>)> {
        let mut frames = vec![];
        while !bytes.is_empty() {
            let (len, at) = match bytes[1] {
                126 => (u16::from_be_bytes([bytes[2], bytes[3]]) as usize, 4),
                127 => (u64::from_be_bytes(bytes[2..10].try_into().unwrap()) as usize, 10),
                n => (n as usize, 2),
            };
            assert_eq!(bytes[0] & 0x80, 0x80, "unfragmented");
            assert_eq!(bytes[1] & 0x80, 0, "a server never masks");
            frames.push((bytes[0] & 0x0f, bytes[at..at + len].to_vec()));
            bytes = &bytes[at + len..];
        }
        frames
    }

    /// Drive with a transport that takes `chunks` buffers of 1,000 bytes.
    fn step_limited(p: &mut Peer, mut chunks: usize) {
        let cx = Context { now: p.now, room: true, status: &STATUS, name: "raytracer", may_begin: true, log: &NoLog };
        let out = &mut p.out;
        drive(
            &mut p.c,
            &cx,
            &mut p.src,
            |fill| {
                if chunks == 0 {
                    return 0;
                }
                chunks -= 1;
                let mut buf = [0u8; 1000];
                let n = fill(&mut buf);
                out.extend_from_slice(&buf[..n]);
                n
            },
            &mut String::new(),
        );
    }

    #[test]
    fn a_viewer_gets_the_models_frame_for_each_request_and_a_pong_after_the_frame_going_out() {
        let mut p = viewer();
        p.send(&request([3072, 4096, -2048]));
        step_limited(&mut p, 3);
        p.send(&client_frame(0x89, b"hi"));
        while p.c.frames_sent() < 1 {
            p.step();
        }
        p.step();
        p.send(&request([0, 8192, 0]));
        while p.c.frames_sent() < 2 {
            p.step();
        }
        let frames = server_frames(&p.out);
        assert_eq!(frames.len(), 3);
        assert_eq!(frames[0].0, 2);
        assert!(frames[0].1 == model::render_frame(&Light::from_raw(3072, 4096, -2048).unwrap()));
        assert_eq!(frames[1], (10, b"hi".to_vec()), "the pong after the frame");
        assert!(frames[2].1 == model::render_frame(&Light::from_raw(0, 8192, 0).unwrap()));
        assert_eq!(p.src.free_slots(), 2, "both frames ended");
    }

    #[test]
    fn a_newer_request_replaces_one_waiting_behind_the_frame_going_out() {
        let mut p = viewer();
        p.send(&request([3072, 4096, -2048]));
        step_limited(&mut p, 1);
        p.send(&request([1024, 4096, 0]));
        p.send(&request([0, 8192, 0]));
        while p.c.frames_sent() < 2 {
            p.step();
        }
        let frames = server_frames(&p.out);
        assert_eq!(frames.len(), 2);
        assert!(frames[1].1 == model::render_frame(&Light::from_raw(0, 8192, 0).unwrap()));
    }

    #[test]
    fn frames_that_arrive_with_the_handshake_are_the_viewers() {
        let mut p = Peer::new();
        let mut bytes = UPGRADE.to_vec();
        bytes.extend(request([3072, 4096, -2048]));
        p.send(&bytes);
        while p.c.frames_sent() < 1 {
            p.step();
        }
        let text = p.text();
        let body = &p.out[text.find("\r\n\r\n").unwrap() + 4..];
        assert_eq!(server_frames(body)[0].1.len(), FRAME_BYTES);
    }

    fn closed_with(bytes: &[u8]) -> (Closed, std::vec::Vec<(u8, std::vec::Vec<u8>)>) {
        let mut p = viewer();
        p.send(bytes);
        loop {
            if let Action::Close(c) = p.step() {
                return (c, server_frames(&p.out));
            }
        }
    }

    #[test]
    fn frames_the_channel_refuses_close_it_with_their_codes() {
        for (what, bytes, code) in [
            ("unmasked", vec![0x82, 12, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], CloseCode::ProtocolError),
            ("text", client_frame(0x81, b"hello"), CloseCode::UnsupportedData),
            ("1 MB", client_frame(0x82, &vec![0; 1 << 20])[..20].to_vec(), CloseCode::MessageTooBig),
            ("fragment", client_frame(0x02, &[0; 6]), CloseCode::PolicyViolation),
            ("short", client_frame(0x82, &[0; 6]), CloseCode::InvalidPayload),
            ("out of range", request([1 << 23, 0, 0]), CloseCode::InvalidPayload),
            ("reserved opcode", client_frame(0x83, &[]), CloseCode::ProtocolError),
        ] {
            let (closed, frames) = closed_with(&bytes);
            assert_eq!(closed, Closed::Viewer(code), "{what}");
            assert_eq!(frames, vec![(8, code.code().to_be_bytes().to_vec())], "{what}");
        }
    }

    #[test]
    fn a_close_is_echoed_and_ends_the_connection() {
        let (closed, frames) = closed_with(&client_frame(0x88, &1001u16.to_be_bytes()));
        assert_eq!(closed, Closed::Answered(None));
        assert_eq!(frames, vec![(8, 1001u16.to_be_bytes().to_vec())]);
    }

    #[test]
    fn an_idle_viewer_is_closed_going_away() {
        let mut p = viewer();
        assert_eq!(p.step(), Action::Wait { deadline: Some(Instant::ZERO + VIEWER_IDLE) });
        p.now = Instant::ZERO + VIEWER_IDLE;
        assert_eq!(p.step(), Action::Close(Closed::Viewer(CloseCode::GoingAway)));
    }

    #[test]
    fn a_viewer_asking_every_second_is_never_closed() {
        let mut p = viewer();
        for s in 1..=40u64 {
            p.now = Instant::ZERO + Duration::from_secs(s);
            p.send(&request([3072, 4096, -2048]));
            let before = p.c.frames_sent();
            while p.c.frames_sent() == before {
                let a = p.step();
                assert!(!matches!(a, Action::Close(_)), "closed at {s} s: {a:?}");
            }
            let a = p.step();
            assert!(matches!(a, Action::Wait { .. }), "at {s} s: {a:?}");
        }
        assert_eq!(p.c.frames_sent(), 40);
        let closes = server_frames(&p.out).iter().filter(|(op, _)| *op == 8).count();
        assert_eq!(closes, 0, "no close frame went out");
    }

    #[test]
    fn a_close_with_a_code_no_endpoint_may_send_is_answered_1002_and_a_bad_reason_1007() {
        for (what, body, reply) in [
            ("1005", 1005u16.to_be_bytes().to_vec(), 1002u16),
            ("1006", 1006u16.to_be_bytes().to_vec(), 1002),
            ("1015", 1015u16.to_be_bytes().to_vec(), 1002),
            ("999", 999u16.to_be_bytes().to_vec(), 1002),
            ("2000", 2000u16.to_be_bytes().to_vec(), 1002),
            ("one byte", vec![3], 1002),
            ("not UTF-8", [&1000u16.to_be_bytes()[..], &[0xff, 0xfe]].concat(), 1007),
        ] {
            let (closed, frames) = closed_with(&client_frame(0x88, &body));
            assert_eq!(frames, vec![(8, reply.to_be_bytes().to_vec())], "{what}");
            assert!(matches!(closed, Closed::Viewer(_)), "{what}: {closed:?}");
        }
        for (body, echo) in [(vec![], 1000u16), (b"\x0b\xb8bye".to_vec(), 3000), (b"\x03\xe9".to_vec(), 1001)] {
            let (closed, frames) = closed_with(&client_frame(0x88, &body));
            assert_eq!((closed, frames), (Closed::Answered(None), vec![(8, echo.to_be_bytes().to_vec())]));
        }
    }

    #[test]
    fn head_answers_have_no_body_and_every_answer_says_nosniff() {
        for req in [
            "HEAD /nope HTTP/1.1\r\nHost: raytracer\r\n\r\n",
            "HEAD /status HTTP/1.1\r\nHost: raytracer\r\n\r\n",
            "HEAD / HTTP/1.1\r\nHost: raytracer\r\n\r\n",
        ] {
            let (text, _) = answer(req);
            assert!(text.ends_with("\r\n\r\n"), "{req:?}: {text}");
            assert!(text.contains("X-Content-Type-Options: nosniff\r\n"), "{req:?}: {text}");
        }
        let (page, _) = answer("GET / HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        assert!(page.contains("Content-Security-Policy: default-src 'self'; connect-src 'self';"), "{page}");
        assert!(page.contains("frame-ancestors 'none'"));
    }

    #[test]
    fn a_page_file_the_browser_holds_is_answered_304_by_its_entity_tag() {
        let asset = assets::find("/page.js").unwrap();
        let (first, _) = answer("GET /page.js HTTP/1.1\r\nHost: raytracer\r\n\r\n");
        assert!(first.contains(&format!("ETag: {}\r\n", asset.etag)) && first.contains("Cache-Control: no-cache"));
        let (again, a) = answer(&format!(
            "GET /page.js HTTP/1.1\r\nHost: raytracer\r\nIf-None-Match: W/\"x\", {}\r\n\r\n",
            asset.etag
        ));
        assert!(again.starts_with("HTTP/1.1 304 Not Modified\r\n") && again.ends_with("\r\n\r\n"), "{again}");
        assert!(!again.contains("Content-Length") && !again.contains("Content-Encoding"), "{again}");
        assert_eq!(a, Action::Close(Closed::Answered(Some(Status::NotModified))));
        let (stale, _) = answer("GET /page.js HTTP/1.1\r\nHost: raytracer\r\nIf-None-Match: \"0\"\r\n\r\n");
        assert!(stale.starts_with("HTTP/1.1 200 OK\r\n") && stale.ends_with(core::str::from_utf8(asset.raw).unwrap()));
    }

    #[test]
    fn another_sites_websocket_and_a_foreign_host_are_refused_403() {
        let upgrade = |host: &str, origin: Option<&str>| {
            let origin = origin.map(|o| format!("Origin: {o}\r\n")).unwrap_or_default();
            format!("GET /ws HTTP/1.1\r\nHost: {host}\r\n{origin}Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n")
        };
        for (host, origin, code) in [
            ("raytracer.local", Some("http://evil.example"), "403"),
            ("raytracer.local", Some("null"), "403"),
            ("evil.example", Some("http://evil.example"), "403"),
            ("raytracer.local", Some("http://raytracer.local"), "101"),
            ("127.0.0.1:8080", Some("http://127.0.0.1:8080"), "101"),
            ("10.0.2.15", None, "101"),
        ] {
            let (text, _) = answer(&upgrade(host, origin));
            assert!(text.starts_with(&format!("HTTP/1.1 {code} ")), "{host} {origin:?}: {text}");
        }
        let (status, _) = answer("GET /status HTTP/1.1\r\nHost: rebound.evil.example\r\n\r\n");
        assert!(status.starts_with("HTTP/1.1 403 Forbidden\r\n") && !status.contains("uptime"), "{status}");
        let (page, _) = answer("GET / HTTP/1.1\r\nHost: RAYTRACER.local:80\r\n\r\n");
        assert!(page.starts_with("HTTP/1.1 200 OK\r\n"), "{page}");
    }

    /// Rows are copied in whole words: wherever the transport's next byte
    /// goes, the frame's head is laid out so that its first row starts on
    /// a word (an empty first fragment moves it by two), and the message
    /// is the model's frame either way.
    #[test]
    fn a_frames_rows_land_word_aligned_in_the_transport() {
        for (align, padded) in [(0usize, true), (2, false)] {
            let mut p = viewer();
            p.c.transport_at(align);
            p.send(&request([3072, 4096, -2048]));
            while p.c.frames_sent() < 1 {
                p.step();
            }
            let head = if padded { 12 } else { 10 };
            assert_eq!((align + head) % 4, 0);
            assert_eq!(&p.out[..2], if padded { &[0x02, 0x00][..] } else { &[0x82, 127][..] }, "at {align}");
            if padded {
                assert_eq!(&p.out[2..4], &[0x80, 127], "the continuation, final");
            }
            let body = &p.out[head..];
            assert!(body == model::render_frame(&Light::from_raw(3072, 4096, -2048).unwrap()), "at {align}");
        }
    }

    /// Four viewers over two frame slots, two of them greedy (a request
    /// always queued behind the frame going out): with [`Turns`] each gets
    /// a fair share; without, the two polled first keep both slots.
    #[test]
    fn viewers_over_too_few_slots_take_turns() {
        let run = |fair: bool| {
            let mut src = source();
            let mut viewers: std::vec::Vec<Connection<usize>> = (0..4).map(|_| viewer().c).collect();
            let mut turns = Turns::<4>::new();
            let mut frames = [0u32; 4];
            for ms in 0..1_000u64 {
                let now = Instant::ZERO + Duration::from_millis(ms);
                for (i, c) in viewers.iter_mut().enumerate() {
                    let greedy = i < 2;
                    // A greedy viewer asks again as soon as a frame begins;
                    // the others once the last frame arrived.
                    if !c.wants_frame() && (greedy || c.take_frame_for_test().is_none()) {
                        let _ = c.receive(&request([3072, 4096, -2048 + i as i32]));
                    }
                    let may_begin = !fair || turns.may_begin(i);
                    let cx = Context { now, room: true, status: &STATUS, name: "raytracer", may_begin, log: &NoLog };
                    let before = c.frames_sent();
                    // A link of 100 KB a millisecond.
                    let mut budget = 100_000usize;
                    drive(
                        c,
                        &cx,
                        &mut src,
                        |fill| {
                            let mut buf = [0u8; 1440];
                            let n = fill(&mut buf[..budget.min(1440)]);
                            budget -= n;
                            n
                        },
                        &mut String::new(),
                    );
                    frames[i] += c.frames_sent() - before;
                    turns.served(i, c.wants_frame());
                }
            }
            frames
        };
        let fair = run(true);
        let total: u32 = fair.iter().sum();
        assert!(fair.iter().all(|&f| f * 5 >= total), "each at least a fifth of {total}: {fair:?}");
        let unfair = run(false);
        std::eprintln!("frames each: with turns {fair:?}, without {unfair:?}");
        assert!(
            unfair[2] + unfair[3] < (unfair[0] + unfair[1]) / 4,
            "without turns the greedy two take it: {unfair:?}"
        );
    }

    /// A reader that takes a byte a second keeps the send deadline fresh
    /// for ever; the frame's own limit drops it and frees its slot.
    #[test]
    fn a_reader_too_slow_for_a_frame_is_dropped_at_the_frame_limit() {
        let mut p = viewer();
        p.send(&request([3072, 4096, -2048]));
        let mut closed = None;
        for s in 0..=FRAME_LIMIT.as_secs() {
            p.now = Instant::ZERO + Duration::from_secs(s);
            let cx =
                Context { now: p.now, room: true, status: &STATUS, name: "raytracer", may_begin: true, log: &NoLog };
            let mut one = 1usize;
            let a = drive(
                &mut p.c,
                &cx,
                &mut p.src,
                |fill| {
                    let mut buf = [0u8; 1];
                    let n = if one > 0 { fill(&mut buf) } else { 0 };
                    one -= n;
                    n
                },
                &mut String::new(),
            );
            if let Action::Close(c) = a {
                closed = Some((s, c));
                break;
            }
        }
        assert_eq!(closed, Some((FRAME_LIMIT.as_secs(), Closed::Stalled)));
        assert_eq!(p.c.take_frame_for_test(), None, "its frame was given back");
    }

    #[test]
    fn no_place_for_a_viewer_is_503() {
        let mut p = Peer::new();
        p.room = false;
        p.send(UPGRADE);
        p.step();
        assert!(p.text().starts_with("HTTP/1.1 503 Service Unavailable\r\n") && p.text().contains("Retry-After: 2"));
        assert!(!p.c.is_viewer());
    }

    #[test]
    fn a_viewer_dropped_mid_frame_ends_its_frame() {
        let mut p = viewer();
        p.send(&request([3072, 4096, -2048]));
        step_limited(&mut p, 3);
        let frame = p.c.take_frame_for_test();
        assert!(frame.is_some(), "a frame was going out");
        p.c.abandon(&mut p.src);
        assert_eq!(p.c.take_frame_for_test(), None, "abandon ended it");
    }

    proptest::proptest! {
        #[test]
        fn no_bytes_after_a_handshake_make_a_viewer_panic(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..600)) {
            let mut p = viewer();
            let _ = p.c.receive(&bytes);
            for _ in 0..4 {
                if let Action::Close(_) = p.step() { break; }
            }
        }
    }
}
