//! The board as a network camera: an RTSP/1.0 server (RFC 2326) as a sans-IO
//! state machine. Bytes in, responses and actions out; it knows no sockets,
//! clocks or renderers, and holds no more than [`MAX_SESSIONS`] sessions and
//! [`MAX_REQUEST_BYTES`] of input per connection.
//!
//! # Streams
//!
//! A stream is named by its URL ([`StreamSpec::parse`]), on [`RTSP_PORT`]:
//!
//! | URL | light |
//! |---|---|
//! | `rtsp://HOST:8554/light/X,Y,Z` | fixed at `X,Y,Z` world units (as `rt-client --light`) |
//! | `rtsp://HOST:8554/orbit?radius=R&height=H&period=S` | orbiting as `rt-client orbit` moves it, one turn per `S` seconds ([`crate::orbit`]; each parameter optional, defaults 3, 4, 2) |
//! | `rtsp://HOST:8554/live` | set by `SET_PARAMETER` (`light: x,y,z`), [`Config::live_light`] until then |
//!
//! Each takes `fps=N` (frames per second, `1..=`[`MAX_FPS`], default
//! [`DEFAULT_FPS`]) or `fps=max` (as fast as frames come) in its query, for
//! example `rtsp://HOST:8554/light/3,4,-2?fps=60`. A trailing `/` and a
//! trailing `/trackID=0` (a client resolving a relative control URL by
//! concatenation) are ignored.
//!
//! # A session
//!
//! `DESCRIBE` answers the SDP (RTP/AVP payload type 96, uncompressed RGB
//! video per RFC 4175, 90 kHz clock); `SETUP` with
//! `Transport: RTP/AVP;unicast;client_port=a-b` makes a session (Ready),
//! `PLAY` starts it (Playing: [`Action::Play`]), `PAUSE` holds it
//! ([`Action::Pause`]), `TEARDOWN` ends it ([`Action::Stop`]).
//! `SET_PARAMETER` with body `light: x,y,z` moves a live stream's light
//! ([`Action::SetLight`]). A session not heard of (a request naming it, or
//! an RTCP packet from its client, [`Server::rtcp_received`]) for
//! [`SESSION_TIMEOUT`] ends ([`Action::Timeout`], from [`Server::poll`]).
//!
//! A session belongs to the address that set it up: requests naming it from
//! any other address are answered 454 as if it did not exist, and its
//! stream goes only to that address ([`Action::Play`]'s `client_addr`).
//!
//! # The caller
//!
//! Per TCP connection a [`Connection`] buffers the bytes received
//! ([`Connection::receive`]); [`Server::handle`] takes one complete request
//! from it at a time, writes the response into the caller's buffer and
//! returns a [`Reply`]: send `len` bytes, carry out the action, close the
//! connection after the response if `close`. Call it until it returns
//! `None` (pipelined requests are answered in order). Sessions outlive
//! their connection (RFC 2326 section 3.1); [`Server::poll`] ends idle ones.
//!
//! # Errors
//!
//! | status | when |
//! |---|---|
//! | 400 Bad Request | malformed request line or header, no valid `CSeq`, URL beyond [`MAX_URL_BYTES`], bad stream parameter or body, no `Transport` in `SETUP`; a header block beyond [`MAX_HEADER_BYTES`] or a body beyond [`MAX_BODY_BYTES`] also closes the connection |
//! | 404 Not Found | `DESCRIBE` or `SETUP` of an unknown stream path |
//! | 451 Parameter Not Understood | `SET_PARAMETER` of anything but `light`, or of `light` for a stream that is not live |
//! | 453 Not Enough Bandwidth | `SETUP` of a new session with [`MAX_SESSIONS`] open |
//! | 454 Session Not Found | a `Session` header naming no session of the requesting address |
//! | 455 Method Not Valid in This State | `PLAY`, `PAUSE`, `TEARDOWN` or a non-empty `SET_PARAMETER` without a session (state Init); `SETUP` changing a playing session's transport |
//! | 461 Unsupported Transport | `SETUP` asking for TCP (interleaved), multicast, recording or no client ports |
//! | 501 Not Implemented | any other method (`ANNOUNCE`, `RECORD`, ...) |
//! | 505 RTSP Version Not Supported | any version but `RTSP/1.0` |
//!
//! No peer input panics; a buffer of [`MAX_RESPONSE_BYTES`] holds every
//! response.

use core::fmt::{self, Write};
use core::net::{IpAddr, Ipv4Addr};
use core::time::Duration;

use heapless::String;
use model::{Light, HEIGHT, WIDTH};

pub use super::url::{Fps, Stream, StreamSpec, UrlError, DEFAULT_FPS, MAX_FPS};
use crate::time::Instant;

/// TCP port of the RTSP server.
pub const RTSP_PORT: u16 = 8554;

/// The server's RTP port (UDP), announced as `server_port` in `SETUP`
/// ([`Config::rtp_port`]); RTCP is one above it (RFC 3551's 5004/5005).
pub const SERVER_RTP_PORT: u16 = 5004;

/// Sessions open at once; `SETUP` of one more is answered 453.
pub const MAX_SESSIONS: usize = 4;

/// A session not heard of for this long ends ([`Action::Timeout`]);
/// announced as `timeout=60` in the `Session` header.
pub const SESSION_TIMEOUT: Duration = Duration::from_secs(60);

/// The longest header block (request line, headers, blank line).
pub const MAX_HEADER_BYTES: usize = 2048;

/// The longest body (`Content-Length`).
pub const MAX_BODY_BYTES: usize = 256;

/// Bytes a [`Connection`] buffers: one whole request at most.
pub const MAX_REQUEST_BYTES: usize = MAX_HEADER_BYTES + MAX_BODY_BYTES;

/// The longest request URL.
pub const MAX_URL_BYTES: usize = 256;

/// The response buffer [`Server::handle`] writes into: every response fits.
pub const MAX_RESPONSE_BYTES: usize = 1280;

/// The RTP clock of the video payload (RFC 4175), Hz.
pub const RTP_CLOCK_HZ: u32 = 90_000;

/// The RTP payload type announced in the SDP.
pub const PAYLOAD_TYPE: u8 = 96;

/// The methods announced in the `Public` header of `OPTIONS`.
pub const PUBLIC_METHODS: &str = "OPTIONS, DESCRIBE, SETUP, PLAY, PAUSE, TEARDOWN, GET_PARAMETER, SET_PARAMETER";

/// The longest SDP body.
const MAX_SDP_BYTES: usize = 640;

// ---- Sessions -----------------------------------------------------------------------

/// A session's identifier: 64 random bits, written as 16 hexadecimal digits.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub struct SessionId(pub u64);

impl SessionId {
    /// The identifier in a `Session` header's value (`ID` or
    /// `ID;timeout=...`): 16 hexadecimal digits, either case.
    pub fn parse(header: &str) -> Option<SessionId> {
        let id = header.split(';').next().unwrap_or("").trim();
        if id.len() != 16 || !id.bytes().all(|b| b.is_ascii_hexdigit()) {
            return None;
        }
        u64::from_str_radix(id, 16).ok().map(SessionId)
    }
}

impl fmt::Display for SessionId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:016X}", self.0)
    }
}

/// Where a session is (RFC 2326 appendix A.2).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum State {
    /// No session: the state of a request without a `Session` header. Only
    /// `SETUP` leaves it.
    Init,
    /// Set up, not sending.
    Ready,
    /// Sending.
    Playing,
}

/// One session's state.
#[derive(Clone, Debug)]
pub struct Session {
    id: SessionId,
    state: State,
    spec: StreamSpec,
    url: String<MAX_URL_BYTES>,
    client_addr: IpAddr,
    rtp_port: u16,
    rtcp_port: u16,
    ssrc: u32,
    seq: u16,
    rtptime: u32,
    live: Light,
    last_heard: Instant,
}

impl Session {
    /// The identifier.
    pub fn id(&self) -> SessionId {
        self.id
    }

    /// Ready or Playing.
    pub fn state(&self) -> State {
        self.state
    }

    /// The stream it was set up for.
    pub fn spec(&self) -> &StreamSpec {
        &self.spec
    }

    /// The URL of its `SETUP` (echoed in `RTP-Info`).
    pub fn url(&self) -> &str {
        &self.url
    }

    /// The address that set it up: its stream goes there only.
    pub fn client_addr(&self) -> IpAddr {
        self.client_addr
    }

    /// The client's RTP port.
    pub fn rtp_port(&self) -> u16 {
        self.rtp_port
    }

    /// The client's RTCP port.
    pub fn rtcp_port(&self) -> u16 {
        self.rtcp_port
    }

    /// The stream's RTP SSRC.
    pub fn ssrc(&self) -> u32 {
        self.ssrc
    }

    /// The sequence number the next `PLAY` starts at ([`Server::set_position`]).
    pub fn seq(&self) -> u16 {
        self.seq
    }

    /// The RTP timestamp the next `PLAY` starts at ([`Server::set_position`]).
    pub fn rtptime(&self) -> u32 {
        self.rtptime
    }

    /// The live light: [`Config::live_light`] until a `SET_PARAMETER`.
    pub fn live_light(&self) -> Light {
        self.live
    }

    /// When it times out unless heard of before.
    pub fn expires(&self) -> Instant {
        self.last_heard + SESSION_TIMEOUT
    }
}

/// What the caller must do besides sending the response. Each names the
/// session; the RTP sender keys its streams by it.
#[derive(Clone, Copy, PartialEq, Debug)]
pub enum Action {
    /// Start (or resume) sending the stream: RTP packets from
    /// [`Config::rtp_port`] to `client_addr:rtp_port`, RTCP to
    /// `client_addr:rtcp_port`, with `ssrc`, the first packet's sequence
    /// number `seq` and its timestamp `rtptime` (90 kHz), the values the
    /// `RTP-Info` header announced. The light of each frame is
    /// [`StreamSpec::light_at`] of the media time since the first `PLAY`
    /// (the timestamp's advance, so an orbit resumes where it paused);
    /// frames go at `spec.fps`.
    Play {
        /// The session.
        session: SessionId,
        /// The stream.
        spec: StreamSpec,
        /// The address that set the session up.
        client_addr: IpAddr,
        /// The client's RTP port.
        rtp_port: u16,
        /// The client's RTCP port.
        rtcp_port: u16,
        /// The RTP SSRC.
        ssrc: u32,
        /// The first packet's sequence number.
        seq: u16,
        /// The first packet's RTP timestamp.
        rtptime: u32,
        /// The live light so far ([`Stream::Live`]).
        live: Light,
    },
    /// Stop sending, keep the stream's position; report where it stopped
    /// with [`Server::set_position`] so the next `PLAY` continues the
    /// sequence numbers and timestamps.
    Pause {
        /// The session.
        session: SessionId,
    },
    /// `TEARDOWN`: stop sending and forget the stream (send an RTCP BYE if
    /// the sender does). The session is gone.
    Stop {
        /// The session.
        session: SessionId,
    },
    /// A live stream's light moved: render the next frames with `light`.
    /// It may come while the session is Ready (not sending): a sender
    /// without the stream can drop it, the next [`Action::Play`] carries
    /// the light as `live`.
    SetLight {
        /// The session.
        session: SessionId,
        /// The new light.
        light: Light,
    },
    /// Nothing was heard of the session for [`SESSION_TIMEOUT`]: stop
    /// sending and forget it, as for [`Action::Stop`]. The session is gone.
    Timeout {
        /// The session.
        session: SessionId,
    },
}

/// A response status.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Status {
    /// 200 OK.
    Ok,
    /// 400 Bad Request.
    BadRequest,
    /// 404 Not Found.
    NotFound,
    /// 451 Parameter Not Understood.
    ParameterNotUnderstood,
    /// 453 Not Enough Bandwidth.
    NotEnoughBandwidth,
    /// 454 Session Not Found.
    SessionNotFound,
    /// 455 Method Not Valid in This State.
    MethodNotValidInThisState,
    /// 461 Unsupported Transport.
    UnsupportedTransport,
    /// 500 Internal Server Error (a response that did not fit
    /// [`MAX_RESPONSE_BYTES`]: a bug, never expected).
    InternalServerError,
    /// 501 Not Implemented.
    NotImplemented,
    /// 505 RTSP Version Not Supported.
    VersionNotSupported,
}

impl From<UrlError> for Status {
    /// The answer to a request for a URL that names no stream.
    fn from(e: UrlError) -> Status {
        match e {
            UrlError::NotFound => Status::NotFound,
            UrlError::BadParameter => Status::BadRequest,
        }
    }
}

impl Status {
    /// The status code.
    pub fn code(self) -> u16 {
        match self {
            Status::Ok => 200,
            Status::BadRequest => 400,
            Status::NotFound => 404,
            Status::ParameterNotUnderstood => 451,
            Status::NotEnoughBandwidth => 453,
            Status::SessionNotFound => 454,
            Status::MethodNotValidInThisState => 455,
            Status::UnsupportedTransport => 461,
            Status::InternalServerError => 500,
            Status::NotImplemented => 501,
            Status::VersionNotSupported => 505,
        }
    }

    /// The reason phrase (RFC 2326 section 7.1.1).
    pub fn reason(self) -> &'static str {
        match self {
            Status::Ok => "OK",
            Status::BadRequest => "Bad Request",
            Status::NotFound => "Not Found",
            Status::ParameterNotUnderstood => "Parameter Not Understood",
            Status::NotEnoughBandwidth => "Not Enough Bandwidth",
            Status::SessionNotFound => "Session Not Found",
            Status::MethodNotValidInThisState => "Method Not Valid in This State",
            Status::UnsupportedTransport => "Unsupported Transport",
            Status::InternalServerError => "Internal Server Error",
            Status::NotImplemented => "Not Implemented",
            Status::VersionNotSupported => "RTSP Version Not Supported",
        }
    }
}

/// The answer to one request: the response is `out[..len]`.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Reply {
    /// Bytes of the response written to the caller's buffer.
    pub len: usize,
    /// Its status.
    pub status: Status,
    /// What to do besides sending it.
    pub action: Option<Action>,
    /// Close the connection once the response is sent: the input could not
    /// be framed (a header block beyond [`MAX_HEADER_BYTES`], a bad or too
    /// long `Content-Length`), so nothing after it can be read.
    pub close: bool,
}

/// Random numbers for session identifiers, SSRCs and the first sequence
/// numbers and timestamps (RFC 3550 wants them unpredictable). Any
/// `FnMut() -> u32` is one.
pub trait Random {
    /// The next 32 random bits.
    fn next_u32(&mut self) -> u32;
}

impl<F: FnMut() -> u32> Random for F {
    fn next_u32(&mut self) -> u32 {
        self()
    }
}

/// The server's side of the addresses and the live stream's first light.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Config {
    /// The server's address, in the SDP's `o=` line.
    pub server_ip: Ipv4Addr,
    /// The UDP port RTP leaves from ([`SERVER_RTP_PORT`]); RTCP uses the
    /// next one. Announced as `server_port` in `SETUP`.
    pub rtp_port: u16,
    /// A live stream's light before its first `SET_PARAMETER`.
    pub live_light: Light,
}

// ---- Connections ----------------------------------------------------------------------

/// One TCP connection's input: the bytes of requests not answered yet, and
/// the peer's address (which owns the sessions it sets up).
#[derive(Clone, Debug)]
pub struct Connection {
    peer: IpAddr,
    buf: [u8; MAX_REQUEST_BYTES],
    len: usize,
    closed: bool,
}

impl Connection {
    /// A connection from `peer`.
    pub fn new(peer: IpAddr) -> Connection {
        Connection { peer, buf: [0; MAX_REQUEST_BYTES], len: 0, closed: false }
    }

    /// The peer's address.
    pub fn peer(&self) -> IpAddr {
        self.peer
    }

    /// Take received bytes; returns how many were taken. Fewer than
    /// `data.len()` means the buffer is full: call [`Server::handle`], then
    /// offer the rest. After a reply that closes, everything is taken and
    /// dropped.
    pub fn receive(&mut self, data: &[u8]) -> usize {
        if self.closed {
            return data.len();
        }
        let n = data.len().min(MAX_REQUEST_BYTES - self.len);
        self.buf[self.len..self.len + n].copy_from_slice(&data[..n]);
        self.len += n;
        n
    }

    /// Bytes buffered, not answered yet.
    pub fn buffered(&self) -> usize {
        self.len
    }

    /// Whether a reply closed the connection (input is no longer read).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Drop the first `n` buffered bytes.
    fn consume(&mut self, n: usize) {
        let n = n.min(self.len);
        self.buf.copy_within(n..self.len, 0);
        self.len -= n;
    }

    /// Where the first request ends, if it is all here.
    fn frame(&mut self) -> Framing {
        // Empty lines between requests are allowed (RFC 2326 section 15.1).
        let blank = self.buf[..self.len].iter().take_while(|&&b| b == b'\r' || b == b'\n').count();
        self.consume(blank);
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
                    Framing::Complete { head, body }
                } else {
                    Framing::Incomplete
                }
            }
            _ => Framing::Fatal,
        }
    }
}

/// The state of a connection's first request.
enum Framing {
    /// More bytes needed.
    Incomplete,
    /// The header block is `..head`, the body the next `body` bytes.
    Complete { head: usize, body: usize },
    /// Cannot be framed: answer 400 and close.
    Fatal,
}

/// The `Content-Length` of a header block: 0 if absent, `None` if malformed,
/// beyond 9 digits or given twice with different values.
fn content_length(head: &[u8]) -> Option<usize> {
    let mut found: Option<usize> = None;
    for line in head.split(|&b| b == b'\n').skip(1) {
        let Some(colon) = line.iter().position(|&b| b == b':') else { continue };
        if !line[..colon].trim_ascii().eq_ignore_ascii_case(b"content-length") {
            continue;
        }
        let value = line[colon + 1..].trim_ascii();
        if value.is_empty() || value.len() > 9 || !value.iter().all(u8::is_ascii_digit) {
            return None;
        }
        let n = value.iter().fold(0usize, |n, d| n * 10 + usize::from(d - b'0'));
        if found.is_some_and(|f| f != n) {
            return None;
        }
        found = Some(n);
    }
    Some(found.unwrap_or(0))
}

// ---- Requests -----------------------------------------------------------------------

/// A request's fields the server reads.
struct Request<'a> {
    method: &'a str,
    url: &'a str,
    cseq: &'a str,
    session: Option<&'a str>,
    transport: Option<&'a str>,
}

/// Parse a header block; the error is the status to answer and the `CSeq`
/// to echo, if it was readable.
fn parse_request(head: &[u8]) -> Result<Request<'_>, (Status, Option<&str>)> {
    let text = core::str::from_utf8(head).map_err(|_| (Status::BadRequest, None))?;
    let mut lines = text.split('\n').map(|l| l.strip_suffix('\r').unwrap_or(l));
    let request_line = lines.next().unwrap_or("");
    let (mut cseq, mut session, mut transport) = (None, None, None);
    let mut malformed = false;
    for line in lines {
        if line.is_empty() {
            break;
        }
        let Some((name, value)) = line.split_once(':') else {
            malformed = true;
            continue;
        };
        if name.is_empty() || !name.bytes().all(is_token_byte) {
            malformed = true;
            continue;
        }
        let value = value.trim_matches([' ', '\t']);
        let slot = if name.eq_ignore_ascii_case("cseq") {
            &mut cseq
        } else if name.eq_ignore_ascii_case("session") {
            &mut session
        } else if name.eq_ignore_ascii_case("transport") {
            &mut transport
        } else {
            continue;
        };
        if slot.is_none() {
            *slot = Some(value);
        }
    }
    let cseq = cseq.filter(|c| !c.is_empty() && c.len() <= 10 && c.bytes().all(|b| b.is_ascii_digit()));
    let Some(cseq) = cseq else { return Err((Status::BadRequest, None)) };
    let bad = Err((Status::BadRequest, Some(cseq)));
    if malformed {
        return bad;
    }
    let mut parts = request_line.splitn(3, ' ');
    let (Some(method), Some(url), Some(version)) = (parts.next(), parts.next(), parts.next()) else { return bad };
    if method.is_empty()
        || !method.bytes().all(is_token_byte)
        || url.is_empty()
        || url.len() > MAX_URL_BYTES
        || !url.bytes().all(|b| b.is_ascii_graphic())
    {
        return bad;
    }
    if version != "RTSP/1.0" {
        let other_version = version
            .strip_prefix("RTSP/")
            .is_some_and(|v| !v.is_empty() && v.bytes().all(|b| b.is_ascii_digit() || b == b'.') && v.contains('.'));
        return Err((if other_version { Status::VersionNotSupported } else { Status::BadRequest }, Some(cseq)));
    }
    Ok(Request { method, url, cseq, session, transport })
}

fn is_token_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b"!#$%&'*+-.^_`|~".contains(&b)
}

/// The client's ports of an acceptable transport, or `None`.
fn parse_transport(header: &str) -> Option<(u16, u16)> {
    header.split(',').find_map(|spec| {
        let mut params = spec.split(';').map(str::trim);
        let protocol = params.next()?;
        if !protocol.eq_ignore_ascii_case("RTP/AVP") && !protocol.eq_ignore_ascii_case("RTP/AVP/UDP") {
            return None;
        }
        let mut ports = None;
        for p in params {
            let (name, value) = p.split_once('=').unwrap_or((p, ""));
            if name.eq_ignore_ascii_case("multicast") || name.eq_ignore_ascii_case("interleaved") {
                return None;
            }
            if name.eq_ignore_ascii_case("mode") && !value.trim_matches('"').eq_ignore_ascii_case("play") {
                return None;
            }
            if name.eq_ignore_ascii_case("client_port") {
                let port = |s: &str| s.parse::<u16>().ok().filter(|&p| p != 0);
                ports = Some(match value.split_once('-') {
                    Some((a, b)) => (port(a)?, port(b)?),
                    None => {
                        let a = port(value)?;
                        (a, a.checked_add(1)?)
                    }
                });
            }
        }
        ports
    })
}

// ---- Responses ----------------------------------------------------------------------

/// A `fmt::Write` into a byte slice that remembers running out of room.
struct Out<'a> {
    buf: &'a mut [u8],
    len: usize,
    overflow: bool,
}

impl Write for Out<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let end = self.len + s.len();
        if end > self.buf.len() {
            self.overflow = true;
            return Err(fmt::Error);
        }
        self.buf[self.len..end].copy_from_slice(s.as_bytes());
        self.len = end;
        Ok(())
    }
}

/// Status line and `CSeq`. Write errors are caught by `Out::overflow`.
fn status_line(out: &mut impl Write, status: Status, cseq: Option<&str>) {
    let _ = write!(out, "RTSP/1.0 {} {}\r\n", status.code(), status.reason());
    if let Some(c) = cseq {
        let _ = write!(out, "CSeq: {c}\r\n");
    }
}

/// An answer of the status line and CSeq alone, as every error answer is.
fn bare_answer(out: &mut impl Write, status: Status, cseq: Option<&str>) -> (Status, Option<Action>) {
    status_line(out, status, cseq);
    let _ = out.write_str("\r\n");
    (status, None)
}

fn session_header(out: &mut impl Write, id: SessionId) {
    let _ = write!(out, "Session: {id};timeout={}\r\n", SESSION_TIMEOUT.as_secs());
}

/// The SDP of a stream (module docs; `exactframerate` is left out for
/// `fps=max`).
pub fn write_sdp(
    out: &mut impl Write,
    sdp_session: u32,
    server_ip: Ipv4Addr,
    client: IpAddr,
    fps: Fps,
    control: &str,
) -> fmt::Result {
    let client = match client {
        IpAddr::V4(a) => a,
        IpAddr::V6(_) => Ipv4Addr::UNSPECIFIED,
    };
    write!(out, "v=0\r\no=- {sdp_session} 1 IN IP4 {server_ip}\r\ns=raytracer\r\nc=IN IP4 {client}\r\nt=0 0\r\n")?;
    write!(out, "m=video 0 RTP/AVP {PAYLOAD_TYPE}\r\na=rtpmap:{PAYLOAD_TYPE} raw/{RTP_CLOCK_HZ}\r\n")?;
    write!(out, "a=fmtp:{PAYLOAD_TYPE} sampling=RGB; width={WIDTH}; height={HEIGHT}; depth=8; colorimetry=BT709")?;
    if let Fps::Rate(n) = fps {
        write!(out, "; exactframerate={n}")?;
    }
    write!(out, "\r\na=rtcp-fb:{PAYLOAD_TYPE} nack\r\na=control:{control}\r\n")
}

// ---- The server -----------------------------------------------------------------------

/// The RTSP server: the sessions of every connection, up to `N`.
#[derive(Debug)]
pub struct Server<const N: usize = MAX_SESSIONS> {
    config: Config,
    sessions: heapless::Vec<Session, N>,
}

impl<const N: usize> Server<N> {
    /// A server with no sessions.
    pub fn new(config: Config) -> Server<N> {
        Server { config, sessions: heapless::Vec::new() }
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The open sessions.
    pub fn sessions(&self) -> &[Session] {
        &self.sessions
    }

    /// The session `id`, if open.
    pub fn session(&self, id: SessionId) -> Option<&Session> {
        self.sessions.iter().find(|s| s.id == id)
    }

    /// Answer the first complete request buffered in `conn` at `now`:
    /// the response goes into `out`, the [`Reply`] says how long it is and
    /// what else to do. `None`: no complete request (wait for bytes).
    pub fn handle(
        &mut self,
        conn: &mut Connection,
        now: Instant,
        rng: &mut impl Random,
        out: &mut [u8; MAX_RESPONSE_BYTES],
    ) -> Option<Reply> {
        if conn.closed {
            return None;
        }
        let mut w = Out { buf: out, len: 0, overflow: false };
        let (head, body) = match conn.frame() {
            Framing::Incomplete => return None,
            Framing::Fatal => {
                conn.closed = true;
                conn.len = 0;
                bare_answer(&mut w, Status::BadRequest, None);
                return Some(Reply { len: w.len, status: Status::BadRequest, action: None, close: true });
            }
            Framing::Complete { head, body } => (head, body),
        };
        let peer = conn.peer;
        let (status, action) = match parse_request(&conn.buf[..head]) {
            Err((status, cseq)) => bare_answer(&mut w, status, cseq),
            Ok(req) => self.answer(&req, &conn.buf[head..head + body], peer, now, rng, &mut w),
        };
        conn.consume(head + body);
        if w.overflow {
            // Never expected (MAX_RESPONSE_BYTES bounds every response); a
            // truncated response must not go out.
            w.len = 0;
            w.overflow = false;
            bare_answer(&mut w, Status::InternalServerError, None);
            return Some(Reply { len: w.len, status: Status::InternalServerError, action, close: false });
        }
        Some(Reply { len: w.len, status, action, close: false })
    }

    /// End the first session not heard of for [`SESSION_TIMEOUT`] at `now`
    /// ([`Action::Timeout`]); `None` if none has. Call it until `None`,
    /// at the latest by [`Server::next_deadline`].
    pub fn poll(&mut self, now: Instant) -> Option<Action> {
        let i = self.sessions.iter().position(|s| now >= s.expires())?;
        let s = self.sessions.swap_remove(i);
        Some(Action::Timeout { session: s.id })
    }

    /// When [`Server::poll`] next has a session to end.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.sessions.iter().map(Session::expires).min()
    }

    /// An RTCP packet arrived from `from:port`: the session whose client
    /// that is stays alive. Returns it.
    pub fn rtcp_received(&mut self, now: Instant, from: IpAddr, port: u16) -> Option<SessionId> {
        let s = self.sessions.iter_mut().find(|s| s.client_addr == from && s.rtcp_port == port)?;
        s.last_heard = now;
        Some(s.id)
    }

    /// Where a paused stream stopped: the next `PLAY` announces and starts
    /// at sequence number `seq` and timestamp `rtptime`. `false` if the
    /// session is gone.
    pub fn set_position(&mut self, session: SessionId, seq: u16, rtptime: u32) -> bool {
        match self.sessions.iter_mut().find(|s| s.id == session) {
            Some(s) => {
                s.seq = seq;
                s.rtptime = rtptime;
                true
            }
            None => false,
        }
    }

    /// Forget a session without an action (the sender could not reach its
    /// client). `false` if it was gone.
    pub fn remove(&mut self, session: SessionId) -> bool {
        match self.sessions.iter().position(|s| s.id == session) {
            Some(i) => {
                self.sessions.swap_remove(i);
                true
            }
            None => false,
        }
    }

    /// The index of the session a `Session` header names, if `peer` owns it.
    fn find(&self, header: &str, peer: IpAddr) -> Option<usize> {
        let id = SessionId::parse(header)?;
        self.sessions.iter().position(|s| s.id == id && s.client_addr == peer)
    }

    /// Answer a well-formed request.
    fn answer(
        &mut self,
        req: &Request<'_>,
        body: &[u8],
        peer: IpAddr,
        now: Instant,
        rng: &mut impl Random,
        out: &mut Out<'_>,
    ) -> (Status, Option<Action>) {
        let cseq = Some(req.cseq);
        let fail = |out: &mut Out<'_>, status: Status| bare_answer(out, status, cseq);
        // The session the request names, refreshed: `Ok(None)` without a
        // `Session` header, `Err` if it names none of the peer's.
        let session = match req.session {
            None => Ok(None),
            Some(h) => match self.find(h, peer) {
                Some(i) => {
                    self.sessions[i].last_heard = now;
                    Ok(Some(i))
                }
                None => Err(()),
            },
        };
        match req.method {
            "OPTIONS" => {
                status_line(out, Status::Ok, cseq);
                let _ = write!(out, "Public: {PUBLIC_METHODS}\r\n\r\n");
                (Status::Ok, None)
            }
            "DESCRIBE" => {
                let spec = match StreamSpec::parse(req.url) {
                    Ok(s) => s,
                    Err(e) => return fail(out, Status::from(e)),
                };
                let mut sdp: String<MAX_SDP_BYTES> = String::new();
                let _ = write_sdp(&mut sdp, rng.next_u32(), self.config.server_ip, peer, spec.fps, req.url);
                status_line(out, Status::Ok, cseq);
                let slash = if req.url.ends_with('/') { "" } else { "/" };
                let _ = write!(
                    out,
                    "Content-Base: {}{slash}\r\nContent-Type: application/sdp\r\nContent-Length: {}\r\n\r\n{sdp}",
                    req.url,
                    sdp.len()
                );
                (Status::Ok, None)
            }
            "SETUP" => self.setup(req, session, peer, now, rng, out),
            "PLAY" | "PAUSE" | "TEARDOWN" => {
                let i = match session {
                    Ok(Some(i)) => i,
                    Ok(None) => return fail(out, Status::MethodNotValidInThisState),
                    Err(()) => return fail(out, Status::SessionNotFound),
                };
                let s = &mut self.sessions[i];
                let id = s.id;
                let action = match (req.method, s.state) {
                    ("PLAY", State::Ready) => {
                        s.state = State::Playing;
                        Some(Action::Play {
                            session: id,
                            spec: s.spec,
                            client_addr: s.client_addr,
                            rtp_port: s.rtp_port,
                            rtcp_port: s.rtcp_port,
                            ssrc: s.ssrc,
                            seq: s.seq,
                            rtptime: s.rtptime,
                            live: s.live,
                        })
                    }
                    ("PAUSE", State::Playing) => {
                        s.state = State::Ready;
                        Some(Action::Pause { session: id })
                    }
                    ("TEARDOWN", _) => Some(Action::Stop { session: id }),
                    _ => None,
                };
                status_line(out, Status::Ok, cseq);
                match req.method {
                    "PLAY" => {
                        session_header(out, id);
                        let _ = write!(out, "RTP-Info: url={};seq={};rtptime={}\r\n", s.url, s.seq, s.rtptime);
                    }
                    "PAUSE" => session_header(out, id),
                    _ => {
                        self.sessions.swap_remove(i);
                    }
                }
                let _ = out.write_str("\r\n");
                (Status::Ok, action)
            }
            "GET_PARAMETER" => match session {
                Err(()) => fail(out, Status::SessionNotFound),
                Ok(i) => {
                    status_line(out, Status::Ok, cseq);
                    if let Some(i) = i {
                        session_header(out, self.sessions[i].id);
                    }
                    let _ = out.write_str("\r\n");
                    (Status::Ok, None)
                }
            },
            "SET_PARAMETER" => {
                let light = match parse_parameters(body) {
                    Ok(l) => l,
                    Err(status) => return fail(out, status),
                };
                let i = match (session, light) {
                    (Err(()), _) => return fail(out, Status::SessionNotFound),
                    (Ok(None), Some(_)) => return fail(out, Status::MethodNotValidInThisState),
                    (Ok(i), _) => i,
                };
                let mut action = None;
                if let (Some(i), Some(light)) = (i, light) {
                    let s = &mut self.sessions[i];
                    if s.spec.stream != Stream::Live {
                        return fail(out, Status::ParameterNotUnderstood);
                    }
                    s.live = light;
                    action = Some(Action::SetLight { session: s.id, light });
                }
                status_line(out, Status::Ok, cseq);
                if let Some(i) = i {
                    session_header(out, self.sessions[i].id);
                }
                let _ = out.write_str("\r\n");
                (Status::Ok, action)
            }
            _ => fail(out, Status::NotImplemented),
        }
    }

    /// `SETUP`: a new session, or new client ports for a session not playing.
    fn setup(
        &mut self,
        req: &Request<'_>,
        session: Result<Option<usize>, ()>,
        peer: IpAddr,
        now: Instant,
        rng: &mut impl Random,
        out: &mut Out<'_>,
    ) -> (Status, Option<Action>) {
        let cseq = Some(req.cseq);
        let fail = |out: &mut Out<'_>, status: Status| bare_answer(out, status, cseq);
        let spec = match StreamSpec::parse(req.url) {
            Ok(s) => s,
            Err(e) => return fail(out, Status::from(e)),
        };
        let Some(transport) = req.transport else { return fail(out, Status::BadRequest) };
        let Some((rtp_port, rtcp_port)) = parse_transport(transport) else {
            return fail(out, Status::UnsupportedTransport);
        };
        let mut url: String<MAX_URL_BYTES> = String::new();
        // The request line's URL is at most MAX_URL_BYTES (parse_request).
        let _ = url.push_str(req.url);
        let i = match session {
            Err(()) => return fail(out, Status::SessionNotFound),
            Ok(Some(i)) => {
                let s = &mut self.sessions[i];
                if s.state == State::Playing {
                    return fail(out, Status::MethodNotValidInThisState);
                }
                (s.spec, s.url, s.rtp_port, s.rtcp_port) = (spec, url, rtp_port, rtcp_port);
                i
            }
            Ok(None) => {
                if self.sessions.is_full() {
                    return fail(out, Status::NotEnoughBandwidth);
                }
                // 64 random bits; a source that keeps repeating itself gets
                // no session rather than a shared one.
                let fresh = (0..8)
                    .map(|_| SessionId(u64::from(rng.next_u32()) << 32 | u64::from(rng.next_u32())))
                    .find(|id| id.0 != 0 && self.sessions.iter().all(|s| s.id != *id));
                let Some(id) = fresh else { return fail(out, Status::NotEnoughBandwidth) };
                let session = Session {
                    id,
                    state: State::Ready,
                    spec,
                    url,
                    client_addr: peer,
                    rtp_port,
                    rtcp_port,
                    ssrc: rng.next_u32(),
                    seq: rng.next_u32() as u16,
                    rtptime: rng.next_u32(),
                    live: self.config.live_light,
                    last_heard: now,
                };
                if self.sessions.push(session).is_err() {
                    return fail(out, Status::NotEnoughBandwidth);
                }
                self.sessions.len() - 1
            }
        };
        let s = &self.sessions[i];
        status_line(out, Status::Ok, cseq);
        let server = self.config.rtp_port;
        let _ = write!(
            out,
            "Transport: RTP/AVP;unicast;client_port={}-{};server_port={}-{};ssrc={:08X}\r\n",
            s.rtp_port,
            s.rtcp_port,
            server,
            server.wrapping_add(1),
            s.ssrc
        );
        session_header(out, s.id);
        let _ = out.write_str("\r\n");
        (Status::Ok, None)
    }
}

/// The light a `SET_PARAMETER` body sets (`light: x,y,z` lines, the last
/// one counting), `None` for an empty body (a keep-alive); the status to
/// answer if the body is not that.
fn parse_parameters(body: &[u8]) -> Result<Option<Light>, Status> {
    let text = core::str::from_utf8(body).map_err(|_| Status::BadRequest)?;
    let mut light = None;
    for line in text.split('\n').map(str::trim).filter(|l| !l.is_empty()) {
        let (name, value) = line.split_once(':').ok_or(Status::BadRequest)?;
        if !name.trim().eq_ignore_ascii_case("light") {
            return Err(Status::ParameterNotUnderstood);
        }
        light = Some(value.trim().parse::<Light>().map_err(|_| Status::BadRequest)?);
    }
    Ok(light)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SERVER_IP: Ipv4Addr = Ipv4Addr::new(192, 168, 1, 10);
    const CLIENT: IpAddr = IpAddr::V4(Ipv4Addr::new(192, 168, 1, 20));
    const OTHER: IpAddr = IpAddr::V4(Ipv4Addr::new(192, 168, 1, 21));
    const URL: &str = "rtsp://192.168.1.10:8554/light/3,4,-2";

    /// A predictable "random" source: 0x11111111, 0x22222222, ...
    struct Counter(u32);

    impl Random for Counter {
        fn next_u32(&mut self) -> u32 {
            self.0 = self.0.wrapping_add(1);
            self.0.wrapping_mul(0x1111_1111)
        }
    }

    fn light(x: f64, y: f64, z: f64) -> Light {
        Light::from_world(x, y, z).unwrap()
    }

    fn config() -> Config {
        Config { server_ip: SERVER_IP, rtp_port: SERVER_RTP_PORT, live_light: light(3.0, 4.0, -2.0) }
    }

    fn at(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    /// A server, one connection per address, a clock and the random source.
    struct Rig {
        server: Server,
        conns: Vec<Connection>,
        rng: Counter,
        now: Instant,
    }

    /// One answered request.
    #[derive(Debug)]
    struct Answer {
        text: std::string::String,
        status: Status,
        action: Option<Action>,
        close: bool,
    }

    impl Rig {
        fn new() -> Rig {
            Rig { server: Server::new(config()), conns: vec![Connection::new(CLIENT)], rng: Counter(0), now: at(0) }
        }

        /// Bytes from connection `c`; every complete request answered.
        fn send_on(&mut self, c: usize, bytes: &[u8]) -> Vec<Answer> {
            let mut answers = Vec::new();
            let mut fed = 0;
            let mut out = [0u8; MAX_RESPONSE_BYTES];
            loop {
                fed += self.conns[c].receive(&bytes[fed..]);
                let Some(r) = self.server.handle(&mut self.conns[c], self.now, &mut self.rng, &mut out) else {
                    if fed == bytes.len() {
                        return answers;
                    }
                    continue;
                };
                let text = std::string::String::from_utf8(out[..r.len].to_vec()).unwrap();
                answers.push(Answer { text, status: r.status, action: r.action, close: r.close });
            }
        }

        /// One request on the first connection, exactly one answer.
        fn ask(&mut self, request: &str) -> Answer {
            let mut a = self.send_on(0, request.as_bytes());
            assert_eq!(a.len(), 1, "one answer to {request:?}: {a:?}");
            a.pop().unwrap()
        }

        /// SETUP of `url` from the first connection; the new session.
        fn setup(&mut self, url: &str) -> SessionId {
            let a = self.ask(&format!(
                "SETUP {url} RTSP/1.0\r\nCSeq: 3\r\nTransport: RTP/AVP;unicast;client_port=6000-6001\r\n\r\n"
            ));
            assert_eq!(a.status, Status::Ok, "{}", a.text);
            let line = a.text.lines().find(|l| l.starts_with("Session: ")).unwrap();
            SessionId::parse(&line["Session: ".len()..]).unwrap()
        }
    }

    fn request(method: &str, url: &str, cseq: u32, headers: &str) -> std::string::String {
        format!("{method} {url} RTSP/1.0\r\nCSeq: {cseq}\r\n{headers}\r\n")
    }

    fn with_session(method: &str, id: SessionId, cseq: u32) -> std::string::String {
        request(method, URL, cseq, &format!("Session: {id}\r\n"))
    }

    // ---- URLs ----

    // ---- Methods ----

    #[test]
    fn options_lists_the_methods_and_echoes_cseq() {
        let a = Rig::new().ask("OPTIONS * RTSP/1.0\r\nCSeq: 1\r\nUser-Agent: test\r\n\r\n");
        let want = "RTSP/1.0 200 OK\r\nCSeq: 1\r\n\
                    Public: OPTIONS, DESCRIBE, SETUP, PLAY, PAUSE, TEARDOWN, GET_PARAMETER, SET_PARAMETER\r\n\r\n";
        assert_eq!(a.text, want);
        assert_eq!((a.action, a.close), (None, false));
        let a = Rig::new().ask("OPTIONS rtsp://h/live RTSP/1.0\r\ncseq:  4294967296 \r\n\r\n");
        assert!(a.text.starts_with("RTSP/1.0 200 OK\r\nCSeq: 4294967296\r\n"), "{}", a.text);
    }

    #[test]
    fn describe_answers_the_sdp_exactly() {
        let a = Rig::new().ask(&request("DESCRIBE", URL, 2, "Accept: application/sdp\r\n"));
        let sdp = "v=0\r\n\
                   o=- 286331153 1 IN IP4 192.168.1.10\r\n\
                   s=raytracer\r\n\
                   c=IN IP4 192.168.1.20\r\n\
                   t=0 0\r\n\
                   m=video 0 RTP/AVP 96\r\n\
                   a=rtpmap:96 raw/90000\r\n\
                   a=fmtp:96 sampling=RGB; width=480; height=360; depth=8; colorimetry=BT709; exactframerate=30\r\n\
                   a=rtcp-fb:96 nack\r\n\
                   a=control:rtsp://192.168.1.10:8554/light/3,4,-2\r\n";
        let want = format!(
            "RTSP/1.0 200 OK\r\nCSeq: 2\r\nContent-Base: {URL}/\r\nContent-Type: application/sdp\r\n\
             Content-Length: {}\r\n\r\n{sdp}",
            sdp.len()
        );
        assert_eq!(a.text, want);
        // fps=max announces no exact frame rate; an IPv6 client gets 0.0.0.0.
        let mut r = Rig::new();
        r.conns.push(Connection::new(IpAddr::V6(core::net::Ipv6Addr::LOCALHOST)));
        let a = r.send_on(1, request("DESCRIBE", "rtsp://h/orbit?fps=max", 2, "").as_bytes());
        assert!(a[0].text.contains("c=IN IP4 0.0.0.0\r\n"), "{}", a[0].text);
        assert!(a[0].text.contains("colorimetry=BT709\r\na=rtcp-fb:96 nack\r\n"), "{}", a[0].text);
        let a = Rig::new().ask(&request("DESCRIBE", "rtsp://h/live?fps=60", 2, ""));
        assert!(a.text.contains("; exactframerate=60\r\n"));
    }

    #[test]
    fn a_whole_session_setup_play_pause_play_teardown() {
        let mut r = Rig::new();
        r.now = at(1_000);
        let a = r.ask(&request("SETUP", URL, 3, "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n"));
        // Random draws: the id (two), then SSRC, sequence number, timestamp.
        let id = SessionId(0x1111_1111_2222_2222);
        assert_eq!(
            a.text,
            "RTSP/1.0 200 OK\r\nCSeq: 3\r\n\
             Transport: RTP/AVP;unicast;client_port=6000-6001;server_port=5004-5005;ssrc=33333333\r\n\
             Session: 1111111122222222;timeout=60\r\n\r\n"
        );
        assert_eq!(a.action, None);
        let s = r.server.session(id).unwrap();
        assert_eq!((s.state(), s.ssrc(), s.seq(), s.rtptime()), (State::Ready, 0x3333_3333, 0x4444, 0x5555_5555));
        assert_eq!((s.client_addr(), s.rtp_port(), s.rtcp_port(), s.url()), (CLIENT, 6000, 6001, URL));

        let a = r.ask(&with_session("PLAY", id, 4));
        assert_eq!(
            a.text,
            format!(
                "RTSP/1.0 200 OK\r\nCSeq: 4\r\nSession: 1111111122222222;timeout=60\r\n\
                 RTP-Info: url={URL};seq=17476;rtptime=1431655765\r\n\r\n"
            )
        );
        let play = Action::Play {
            session: id,
            spec: StreamSpec::parse(URL).unwrap(),
            client_addr: CLIENT,
            rtp_port: 6000,
            rtcp_port: 6001,
            ssrc: 0x3333_3333,
            seq: 0x4444,
            rtptime: 0x5555_5555,
            live: light(3.0, 4.0, -2.0),
        };
        assert_eq!(a.action, Some(play));
        assert_eq!(r.server.session(id).unwrap().state(), State::Playing);
        // PLAY while playing: answered, nothing new to do.
        assert_eq!(r.ask(&with_session("PLAY", id, 5)).action, None);

        let a = r.ask(&with_session("PAUSE", id, 6));
        assert_eq!(a.text, "RTSP/1.0 200 OK\r\nCSeq: 6\r\nSession: 1111111122222222;timeout=60\r\n\r\n");
        assert_eq!(a.action, Some(Action::Pause { session: id }));
        assert_eq!(r.ask(&with_session("PAUSE", id, 7)).action, None, "paused already");
        // The sender reports where it stopped; PLAY resumes there.
        assert!(r.server.set_position(id, 0x4500, 0x5555_9999));
        let a = r.ask(&with_session("PLAY", id, 8));
        assert!(a
            .text
            .contains("RTP-Info: url=rtsp://192.168.1.10:8554/light/3,4,-2;seq=17664;rtptime=1431673241\r\n"));
        assert!(matches!(a.action, Some(Action::Play { seq: 0x4500, rtptime: 0x5555_9999, .. })));

        let a = r.ask(&with_session("TEARDOWN", id, 9));
        assert_eq!(a.text, "RTSP/1.0 200 OK\r\nCSeq: 9\r\n\r\n");
        assert_eq!(a.action, Some(Action::Stop { session: id }));
        assert!(r.server.sessions().is_empty());
        assert!(!r.server.set_position(id, 0, 0));
        assert_eq!(r.ask(&with_session("PLAY", id, 10)).status, Status::SessionNotFound);
    }

    #[test]
    fn setup_again_changes_the_ports_of_a_session_not_playing() {
        let mut r = Rig::new();
        let id = r.setup(URL);
        let h = format!("Session: {id}\r\nTransport: RTP/AVP/UDP;unicast;client_port=7000\r\n");
        let a = r.ask(&request("SETUP", "rtsp://h/live/trackID=0", 4, &h));
        assert!(a.text.contains("client_port=7000-7001;server_port=5004-5005;ssrc=33333333\r\n"), "{}", a.text);
        let s = r.server.session(id).unwrap();
        assert_eq!((s.rtp_port(), s.spec().stream, s.url()), (7000, Stream::Live, "rtsp://h/live/trackID=0"));
        assert_eq!(r.server.sessions().len(), 1);
        r.ask(&with_session("PLAY", id, 5));
        assert_eq!(r.ask(&request("SETUP", URL, 6, &h)).status, Status::MethodNotValidInThisState);
    }

    #[test]
    fn get_parameter_keeps_a_session_alive() {
        let mut r = Rig::new();
        let a = r.ask(&request("GET_PARAMETER", URL, 2, ""));
        assert_eq!(a.text, "RTSP/1.0 200 OK\r\nCSeq: 2\r\n\r\n");
        let id = r.setup(URL);
        r.now = at(59_000);
        let a = r.ask(&with_session("GET_PARAMETER", id, 4));
        assert_eq!(a.text, "RTSP/1.0 200 OK\r\nCSeq: 4\r\nSession: 1111111122222222;timeout=60\r\n\r\n");
        assert_eq!(r.server.next_deadline(), Some(at(119_000)));
        assert_eq!(r.server.poll(at(118_999)), None);
        assert_eq!(r.server.poll(at(119_000)), Some(Action::Timeout { session: id }));
    }

    #[test]
    fn set_parameter_moves_a_live_light() {
        let mut r = Rig::new();
        let id = r.setup("rtsp://h/live");
        let body = "light: 1.5,6,-2.25\r\n";
        let h = format!("Session: {id}\r\nContent-Type: text/parameters\r\nContent-Length: {}\r\n", body.len());
        let a = r.ask(&format!("{}{body}", request("SET_PARAMETER", "rtsp://h/live", 4, &h)));
        assert_eq!(a.text, "RTSP/1.0 200 OK\r\nCSeq: 4\r\nSession: 1111111122222222;timeout=60\r\n\r\n");
        assert_eq!(a.action, Some(Action::SetLight { session: id, light: light(1.5, 6.0, -2.25) }));
        assert_eq!(r.server.session(id).unwrap().live_light(), light(1.5, 6.0, -2.25));
        // PLAY carries the light so far.
        assert!(
            matches!(r.ask(&with_session("PLAY", id, 5)).action, Some(Action::Play { live, .. }) if live == light(1.5, 6.0, -2.25))
        );
        // An empty body is a keep-alive, with or without a session.
        let a = r.ask(&request("SET_PARAMETER", "rtsp://h/live", 6, "Content-Length: 0\r\n"));
        assert_eq!((a.status, a.action), (Status::Ok, None));
        let set = |id: Option<SessionId>, body: &str| {
            let s = id.map(|id| format!("Session: {id}\r\n")).unwrap_or_default();
            format!(
                "SET_PARAMETER rtsp://h/live RTSP/1.0\r\nCSeq: 7\r\n{s}Content-Length: {}\r\n\r\n{body}",
                body.len()
            )
        };
        assert_eq!(r.ask(&set(Some(id), "colour: red\r\n")).status, Status::ParameterNotUnderstood);
        assert_eq!(r.ask(&set(Some(id), "light: 1,2\r\n")).status, Status::BadRequest);
        assert_eq!(r.ask(&set(Some(id), "light: 9000,0,0\r\n")).status, Status::BadRequest);
        assert_eq!(r.ask(&set(Some(id), "light\r\n")).status, Status::BadRequest);
        assert_eq!(r.ask(&set(Some(id), "light: \u{0}")).status, Status::BadRequest);
        assert_eq!(r.ask(&set(None, "light: 1,2,3")).status, Status::MethodNotValidInThisState);
        assert_eq!(r.ask(&set(Some(SessionId(7)), "light: 1,2,3")).status, Status::SessionNotFound);
        // Only a live stream has a light to set.
        let fixed = r.setup(URL);
        assert_eq!(r.ask(&set(Some(fixed), "light: 1,2,3")).status, Status::ParameterNotUnderstood);
        assert_eq!(r.server.session(id).unwrap().live_light(), light(1.5, 6.0, -2.25), "unchanged by the failures");
    }

    // ---- Errors ----

    /// The status of one request on a fresh server.
    fn status_of(request: &str) -> (Status, std::string::String) {
        let a = Rig::new().ask(request);
        (a.status, a.text)
    }

    #[test]
    fn malformed_requests_are_400() {
        for req in [
            "OPTIONS * RTSP/1.0\r\n\r\n",                      // no CSeq
            "OPTIONS * RTSP/1.0\r\nCSeq: x1\r\n\r\n",          // CSeq not a number
            "OPTIONS * RTSP/1.0\r\nCSeq: 12345678901\r\n\r\n", // beyond 10 digits
            "OPTIONS * RTSP/1.0\r\nCSeq:\r\n\r\n",             // empty
        ] {
            let (status, text) = status_of(req);
            assert_eq!(status, Status::BadRequest, "{req:?}");
            assert_eq!(text, "RTSP/1.0 400 Bad Request\r\n\r\n", "no CSeq to echo: {req:?}");
        }
        let mut bytes = b"OPTIONS * RTSP/1.0\r\nCSeq: 1\r\nX: \xff\xfe\r\n\r\n".to_vec();
        let mut r = Rig::new();
        assert_eq!(r.send_on(0, &bytes)[0].text, "RTSP/1.0 400 Bad Request\r\n\r\n", "not UTF-8");
        bytes.clear();
        for req in [
            "OPTIONS *  RTSP/1.0\r\nCSeq: 5\r\n\r\n",      // two spaces: an empty URL
            "OPTIONS * RTSP/1.0 x\r\nCSeq: 5\r\n\r\n",     // a fourth part
            "OPTIONS\r\nCSeq: 5\r\n\r\n",                  // no URL
            "OPT(IONS * RTSP/1.0\r\nCSeq: 5\r\n\r\n",      // not a token
            "\u{ff}OPTIONS * RTSP/1.0\r\nCSeq: 5\r\n\r\n", // not ASCII (still UTF-8)
            "OPTIONS \u{e9} RTSP/1.0\r\nCSeq: 5\r\n\r\n",  // nor the URL
            "OPTIONS * HTTP/1.1\r\nCSeq: 5\r\n\r\n",       // not RTSP
            "OPTIONS * RTSP/1.0\r\nCSeq: 5\r\nNo colon\r\n\r\n",
            "OPTIONS * RTSP/1.0\r\nCSeq: 5\r\n folded\r\n\r\n",
            "OPTIONS * RTSP/1.0\r\nCSeq: 5\r\nBad Name: x\r\n\r\n",
            "SETUP rtsp://h/live RTSP/1.0\r\nCSeq: 5\r\n\r\n", // no Transport
            "DESCRIBE rtsp://h/live?fps=0 RTSP/1.0\r\nCSeq: 5\r\n\r\n",
        ] {
            let (status, text) = status_of(req);
            assert_eq!(status, Status::BadRequest, "{req:?}");
            assert_eq!(text, "RTSP/1.0 400 Bad Request\r\nCSeq: 5\r\n\r\n", "{req:?}");
        }
        let long = format!("rtsp://h/light/3,4,-2?fps=30{}", "&fps=30".repeat(40));
        assert!(long.len() > MAX_URL_BYTES);
        assert_eq!(status_of(&request("DESCRIBE", &long, 1, "")).0, Status::BadRequest);
    }

    #[test]
    fn each_error_status_is_answered() {
        let transport = "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n";
        let cases = [
            (request("DESCRIBE", "rtsp://h/nothing", 1, ""), "404 Not Found"),
            (request("SETUP", "rtsp://h/nothing", 1, transport), "404 Not Found"),
            (request("PLAY", URL, 1, "Session: 0123456789ABCDEF\r\n"), "454 Session Not Found"),
            (request("PLAY", URL, 1, "Session: junk\r\n"), "454 Session Not Found"),
            (request("GET_PARAMETER", URL, 1, "Session: 0123456789abcdef\r\n"), "454 Session Not Found"),
            (request("TEARDOWN", URL, 1, "Session: 0123456789abcdef;timeout=60\r\n"), "454 Session Not Found"),
            (request("PLAY", URL, 1, ""), "455 Method Not Valid in This State"),
            (request("PAUSE", URL, 1, ""), "455 Method Not Valid in This State"),
            (request("TEARDOWN", URL, 1, ""), "455 Method Not Valid in This State"),
            (
                request("SETUP", URL, 1, "Transport: RTP/AVP/TCP;unicast;interleaved=0-1\r\n"),
                "461 Unsupported Transport",
            ),
            (request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;interleaved=0-1\r\n"), "461 Unsupported Transport"),
            (
                request("SETUP", URL, 1, "Transport: RTP/AVP;multicast;client_port=6000-6001\r\n"),
                "461 Unsupported Transport",
            ),
            (request("SETUP", URL, 1, "Transport: RTP/AVP;unicast\r\n"), "461 Unsupported Transport"),
            (request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=0-1\r\n"), "461 Unsupported Transport"),
            (request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=65535\r\n"), "461 Unsupported Transport"),
            (
                request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=6000-6001;mode=record\r\n"),
                "461 Unsupported Transport",
            ),
            (request("SETUP", URL, 1, "Transport: RAW/RAW/UDP;client_port=6000-6001\r\n"), "461 Unsupported Transport"),
            (request("ANNOUNCE", URL, 1, ""), "501 Not Implemented"),
            (request("RECORD", URL, 1, ""), "501 Not Implemented"),
            (request("options", "*", 1, ""), "501 Not Implemented"),
            ("OPTIONS * RTSP/2.0\r\nCSeq: 1\r\n\r\n".into(), "505 RTSP Version Not Supported"),
            ("PLAY * RTSP/1.1\r\nCSeq: 1\r\n\r\n".into(), "505 RTSP Version Not Supported"),
        ];
        for (req, status) in cases {
            let (_, text) = status_of(&req);
            assert_eq!(text, format!("RTSP/1.0 {status}\r\nCSeq: 1\r\n\r\n"), "{req:?}");
        }
        // The first acceptable transport of a list is taken.
        let list = "Transport: RTP/AVP/TCP;interleaved=0-1,RTP/AVP;unicast;client_port=5000-5001;mode=\"PLAY\"\r\n";
        let (status, text) = status_of(&request("SETUP", URL, 1, list));
        assert_eq!(status, Status::Ok);
        assert!(text.contains("client_port=5000-5001;"));
    }

    #[test]
    fn a_session_belongs_to_the_address_that_set_it_up() {
        let mut r = Rig::new();
        let id = r.setup(URL);
        r.conns.push(Connection::new(OTHER));
        for method in ["PLAY", "PAUSE", "TEARDOWN", "GET_PARAMETER"] {
            let a = r.send_on(1, with_session(method, id, 9).as_bytes());
            assert_eq!(a[0].status, Status::SessionNotFound, "{method} from elsewhere");
        }
        // Another connection from the same address may use it.
        r.conns.push(Connection::new(CLIENT));
        let a = r.send_on(2, with_session("PLAY", id, 10).as_bytes());
        assert!(matches!(a[0].action, Some(Action::Play { client_addr: CLIENT, .. })));
    }

    #[test]
    fn the_session_cap_answers_453() {
        let mut r = Rig::new();
        let ids: Vec<SessionId> = (0..MAX_SESSIONS).map(|_| r.setup(URL)).collect();
        let transport = "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n";
        let a = r.ask(&request("SETUP", URL, 7, transport));
        assert_eq!(a.text, "RTSP/1.0 453 Not Enough Bandwidth\r\nCSeq: 7\r\n\r\n");
        assert_eq!(r.server.sessions().len(), MAX_SESSIONS);
        // Re-SETUP of an open session is no new one.
        assert_eq!(r.ask(&request("SETUP", URL, 8, &format!("{transport}Session: {}\r\n", ids[1]))).status, Status::Ok);
        r.ask(&with_session("TEARDOWN", ids[0], 9));
        assert_eq!(r.ask(&request("SETUP", URL, 10, transport)).status, Status::Ok);
        // A const generic sets another cap; ids stay distinct.
        let mut one: Server<1> = Server::new(config());
        let mut conn = Connection::new(CLIENT);
        let mut rng = Counter(0);
        let mut out = [0u8; MAX_RESPONSE_BYTES];
        let req = request("SETUP", URL, 1, transport);
        let mut statuses = vec![];
        for _ in 0..2 {
            conn.receive(req.as_bytes());
            statuses.push(one.handle(&mut conn, at(0), &mut rng, &mut out).unwrap().status);
        }
        assert_eq!(statuses, [Status::Ok, Status::NotEnoughBandwidth]);
        let ids: std::collections::HashSet<_> = r.server.sessions().iter().map(Session::id).collect();
        assert_eq!(ids.len(), MAX_SESSIONS);
    }

    #[test]
    fn a_random_source_stuck_on_one_value_gives_no_shared_session() {
        let mut server: Server = Server::new(config());
        let mut conn = Connection::new(CLIENT);
        let mut stuck = || 7u32;
        let mut out = [0u8; MAX_RESPONSE_BYTES];
        let req = request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n");
        let mut statuses = vec![];
        for _ in 0..2 {
            conn.receive(req.as_bytes());
            statuses.push(server.handle(&mut conn, at(0), &mut stuck, &mut out).unwrap().status);
        }
        assert_eq!(statuses, [Status::Ok, Status::NotEnoughBandwidth]);
    }

    // ---- Time ----

    #[test]
    fn sessions_time_out_after_60_s_unheard() {
        let mut r = Rig::new();
        r.now = at(10_000);
        let a = r.setup(URL);
        r.now = at(20_000);
        let b = r.setup("rtsp://h/live");
        assert_eq!(r.server.next_deadline(), Some(at(70_000)));
        // Requests naming a session and RTCP from its client refresh it.
        r.now = at(69_999);
        r.ask(&with_session("OPTIONS", a, 5));
        assert_eq!(r.server.rtcp_received(at(75_000), CLIENT, 6001), Some(a));
        assert_eq!(r.server.rtcp_received(at(75_000), OTHER, 6001), None, "not its client");
        assert_eq!(r.server.rtcp_received(at(75_000), CLIENT, 6000), None, "not its RTCP port");
        assert_eq!(r.server.poll(at(79_999)), None);
        assert_eq!(r.server.poll(at(80_000)), Some(Action::Timeout { session: b }));
        assert_eq!(r.server.poll(at(80_000)), None);
        assert_eq!(r.server.next_deadline(), Some(at(135_000)));
        assert_eq!(r.server.poll(at(135_000)), Some(Action::Timeout { session: a }));
        assert_eq!(r.server.next_deadline(), None);
        assert_eq!(r.ask(&with_session("PLAY", a, 6)).status, Status::SessionNotFound);
        // The binding may drop a session itself (its client is unreachable).
        let c = r.setup(URL);
        assert!(r.server.remove(c));
        assert!(!r.server.remove(c));
        assert_eq!(r.server.poll(at(u64::MAX)), None);
    }

    // ---- Framing ----

    #[test]
    fn pipelined_requests_are_answered_in_order() {
        let mut r = Rig::new();
        let body = "light: 1,2,3";
        let bytes = format!(
            "{}\r\n{}{}{body}{}",
            request("OPTIONS", "*", 1, ""),
            request("DESCRIBE", "rtsp://h/live", 2, ""),
            request("SET_PARAMETER", "rtsp://h/live", 3, &format!("Content-Length: {}\r\n", body.len())),
            request("BREW", "*", 4, ""),
        );
        let answers = r.send_on(0, bytes.as_bytes());
        let got: Vec<(Status, bool)> =
            answers.iter().map(|a| (a.status, a.text.contains(&format!("CSeq: {}\r\n", 1)))).collect();
        assert_eq!(got.len(), 4, "{answers:?}");
        for (k, a) in answers.iter().enumerate() {
            assert!(a.text.contains(&format!("\r\nCSeq: {}\r\n", k + 1)), "{k}: {}", a.text);
        }
        let statuses: Vec<Status> = answers.iter().map(|a| a.status).collect();
        assert_eq!(statuses, [Status::Ok, Status::Ok, Status::MethodNotValidInThisState, Status::NotImplemented]);
        assert_eq!(r.conns[0].buffered(), 0);
    }

    #[test]
    fn requests_split_across_reads_are_put_together() {
        let body = "light: 1,2,3\n";
        let mut r = Rig::new();
        let id = r.setup("rtsp://h/live");
        let h = format!("Session: {id}\r\nContent-Length: {}\r\n", body.len());
        // LF-only line ends are accepted too.
        let text = format!("{}{body}", request("SET_PARAMETER", "rtsp://h/live", 4, &h)).replace("\r\n", "\n");
        let mut answers = vec![];
        for b in text.as_bytes() {
            answers.extend(r.send_on(0, &[*b]));
        }
        assert_eq!(answers.len(), 1);
        assert_eq!(answers[0].action, Some(Action::SetLight { session: id, light: light(1.0, 2.0, 3.0) }));
        assert_eq!(r.conns[0].buffered(), 0);
    }

    #[test]
    fn oversized_input_is_answered_400_and_closed() {
        // A header block without an end within MAX_HEADER_BYTES.
        let mut r = Rig::new();
        let mut bytes = b"OPTIONS * RTSP/1.0\r\nCSeq: 1\r\n".to_vec();
        bytes.resize(MAX_HEADER_BYTES + 500, b'a');
        let answers = r.send_on(0, &bytes);
        assert_eq!(answers.len(), 1);
        assert_eq!((answers[0].text.as_str(), answers[0].close), ("RTSP/1.0 400 Bad Request\r\n\r\n", true));
        assert!(r.conns[0].is_closed());
        let more = b"OPTIONS * RTSP/1.0\r\nCSeq: 2\r\n\r\n";
        assert_eq!(r.conns[0].receive(more), more.len(), "taken and dropped");
        assert!(r.send_on(0, b"").is_empty());
        // A body beyond MAX_BODY_BYTES, a bad or an ambiguous Content-Length.
        for h in ["Content-Length: 257\r\n", "Content-Length: -1\r\n", "Content-Length: 1\r\nContent-Length: 2\r\n"] {
            let answers = Rig::new().send_on(0, request("SET_PARAMETER", "*", 1, h).as_bytes());
            assert_eq!(answers.len(), 1, "{h}");
            assert!(answers[0].close && answers[0].status == Status::BadRequest, "{h}");
        }
        // A header block of exactly MAX_HEADER_BYTES is fine.
        let pad = MAX_HEADER_BYTES - request("OPTIONS", "*", 1, "X: \r\n").len();
        let a = Rig::new().ask(&request("OPTIONS", "*", 1, &format!("X: {}\r\n", "p".repeat(pad))));
        assert_eq!((a.status, a.close), (Status::Ok, false));
    }

    #[test]
    fn the_longest_responses_fit() {
        let mut url = std::string::String::from("rtsp://255.255.255.255:8554/orbit?fps=1000&radius=1.");
        while url.len() < MAX_URL_BYTES {
            url.push('0');
        }
        assert_eq!(url.len(), MAX_URL_BYTES);
        let mut r = Rig::new();
        r.server = Server::new(Config { server_ip: Ipv4Addr::BROADCAST, ..config() });
        r.rng = Counter(u32::MAX / 0x1111_1111 - 1);
        let a = r.ask(&request("DESCRIBE", &url, 1_234_567_890, ""));
        assert_eq!(a.status, Status::Ok, "{}", a.text);
        let id = r.setup(&url);
        let a = r.ask(&request("PLAY", &url, 1_234_567_890, &format!("Session: {id}\r\n")));
        assert_eq!(a.status, Status::Ok, "{}", a.text);
    }
}
