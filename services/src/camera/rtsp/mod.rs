//! The board as a network camera: an RTSP/1.0 server (RFC 2326) as a sans-IO
//! state machine. Bytes in, responses out; what a session's stream does is
//! the RTP sender's business, which the server asks through [`Streams`]
//! while it answers. It knows no sockets, clocks or renderers, and holds no
//! more than [`MAX_SESSIONS`] sessions and [`MAX_REQUEST_BYTES`] of input
//! per connection.
//!
//! # Streams
//!
//! A stream is named by its URL ([`StreamSpec::parse`]), on [`RTSP_PORT`]:
//!
//! | URL | light |
//! |---|---|
//! | `rtsp://HOST:8554/light/X,Y,Z` (or `X/Y/Z`, the control URL's form) | fixed at `X,Y,Z` world units (as `rt-client --light`) |
//! | `rtsp://HOST:8554/orbit?radius=R&height=H&period=S` | orbiting as `rt-client orbit` moves it, one turn per `S` seconds ([`crate::orbit`]; each parameter optional, defaults 3, 4, 2) |
//! | `rtsp://HOST:8554/live` | set by `SET_PARAMETER` (`light: x,y,z`), the sender's first light until then |
//!
//! Each takes `fps=N` (frames per second, `1..=`[`MAX_FPS`], default
//! [`DEFAULT_FPS`]) or `fps=max` (as fast as frames come) in its query, for
//! example `rtsp://HOST:8554/light/3,4,-2?fps=60`, and `multicast`, which
//! makes the description name the stream's multicast group. A trailing `/`
//! and a trailing `/trackID=0` (a client resolving a relative control URL
//! by concatenation) are ignored.
//!
//! # A session
//!
//! `DESCRIBE` answers the SDP ([`super::sdp`]); `SETUP` makes a session
//! (Ready) with one of three transports ([`Transport`]): RTP over UDP to
//! the client's ports, RTP inside this RTSP connection (`interleaved`), or
//! RTP to the stream's multicast group. `PLAY` starts it (Playing), `PAUSE`
//! holds it, `TEARDOWN` ends it. `SETUP` again on a session that is not
//! playing applies its new stream and transport. `SET_PARAMETER` with body
//! `light: x,y,z` moves a live stream's light. A session not heard of (a
//! request naming it, or an RTCP packet from its client,
//! [`Server::rtcp_received`]) for [`SESSION_TIMEOUT`] ends ([`Server::poll`]),
//! one never played after [`UNPLAYED_TIMEOUT`]; with every session taken, a
//! new `SETUP` takes the place of the never-played one heard of longest ago
//! (at least [`RECLAIM_AFTER`] ago), so that set-up sessions alone cannot
//! keep viewers out; an interleaved session ends with its connection
//! ([`Server::connection_closed`]).
//!
//! A session belongs to the address that set it up: requests naming it from
//! any other address are answered 454 as if it did not exist, and its
//! unicast stream goes only to that address.
//!
//! # Connections
//!
//! Per TCP connection a [`Connection`] buffers the bytes received
//! ([`Connection::receive`]); [`Server::handle`] takes one complete request
//! from it at a time (or one interleaved RTCP packet, which goes to the
//! sender), writes the response into the caller's buffer and returns a
//! [`Reply`]: send `len` bytes, close the connection after them if `close`.
//! Call it until it returns `None` (pipelined requests are answered in
//! order). A connection is closed by the caller once
//! [`Server::connection_expired`] says so: a request left unfinished for
//! [`crate::time::REQUEST_LIMIT`], or no session of its own and no request for
//! [`IDLE_DEADLINE`]. Sessions outlive their connection (RFC 2326 section
//! 3.1), but for interleaved ones.
//!
//! # Errors
//!
//! | status | when |
//! |---|---|
//! | 400 Bad Request | malformed request line or header, no valid `CSeq`, URL beyond [`MAX_URL_BYTES`], bad stream parameter or body, no `Transport` in `SETUP`; a header block beyond [`MAX_HEADER_BYTES`] or a body beyond [`MAX_BODY_BYTES`] also closes the connection |
//! | 404 Not Found | `DESCRIBE` or `SETUP` of an unknown stream path |
//! | 451 Parameter Not Understood | `SET_PARAMETER` of anything but `light`, or of `light` for a stream that is not live |
//! | 453 Not Enough Bandwidth | `SETUP` of a new session with [`MAX_SESSIONS`] open, or one the sender has no room for |
//! | 454 Session Not Found | a `Session` header naming no session of the requesting address |
//! | 455 Method Not Valid in This State | `PLAY`, `PAUSE`, `TEARDOWN` or a non-empty `SET_PARAMETER` without a session (state Init); `SETUP` of a playing session |
//! | 461 Unsupported Transport | `SETUP` asking for recording, no client ports, unicast to another address (a `destination` that is the client's own is taken), one port or channel for both RTP and RTCP, or multicast where the sender has no group |
//! | 501 Not Implemented | any other method (`ANNOUNCE`, `RECORD`, ...) |
//! | 551 Option not supported | any request with `Require` (no option is supported), the options named in `Unsupported` |
//! | 505 RTSP Version Not Supported | any version but `RTSP/1.0` |
//!
//! No peer input panics; a buffer of [`MAX_RESPONSE_BYTES`] holds every
//! response.

use core::fmt::{self, Write};
use core::net::{IpAddr, Ipv4Addr};
use core::time::Duration;

use heapless::String;
use model::Light;

mod connection;
mod message;

pub use connection::Connection;
use connection::Framing;
pub use message::Transport;
use message::{bare_answer, parse_request, parse_transport, status_line, Out, Request};

use super::sdp::{self, Description};
pub use super::sdp::{Group, Profile};
pub use super::url::{ControlUrl, Fps, LightSource, StreamSpec, UrlError, DEFAULT_FPS, MAX_FPS};
use crate::time::Instant;

/// TCP port of the RTSP server.
pub const RTSP_PORT: u16 = 8554;

/// The server's RTP port (UDP), announced as `server_port` in `SETUP`
/// ([`Config::rtp_port`]); RTCP is one above it (RFC 3551's 5004/5005).
pub const SERVER_RTP_PORT: u16 = 5004;

/// Sessions open at once; `SETUP` of one more is answered 453.
pub const MAX_SESSIONS: usize = 4;

/// RTSP connections a server should accept at once: one for each session's
/// player (players keep their connection while they play) and two spares,
/// so a player arriving when every session is taken gets its 453 instead
/// of a refused connection, and one more can set up while a connection
/// nobody uses waits for its deadline.
pub const CONNECTIONS: usize = MAX_SESSIONS + 2;

/// Sessions one address may hold: one place always stays for another
/// host (a host that sets up sessions it never plays, or plays every
/// stream, keeps nobody else out).
pub const SESSIONS_PER_ADDRESS: usize = MAX_SESSIONS - 1;

/// RTSP connections one address may hold ([`admits`]): a player per
/// session it may hold and one spare, so two places stay for other hosts.
pub const CONNECTIONS_PER_ADDRESS: usize = SESSIONS_PER_ADDRESS + 1;

/// Whether a new connection from `peer` may stay, given the peers of the
/// connections already open (`open`): at most [`CONNECTIONS_PER_ADDRESS`]
/// from one address. The binding closes one refused.
pub fn admits(open: impl IntoIterator<Item = IpAddr>, peer: IpAddr) -> bool {
    open.into_iter().filter(|&a| a == peer).count() < CONNECTIONS_PER_ADDRESS
}

/// A session not heard of for this long ends; announced as `timeout=60` in
/// the `Session` header.
pub const SESSION_TIMEOUT: Duration = Duration::from_secs(60);

/// A session that was set up and never played ends after this long
/// unheard of, not [`SESSION_TIMEOUT`]: players send `PLAY` within
/// milliseconds of their `SETUP`, and a session that only holds a place
/// keeps other viewers out.
pub const UNPLAYED_TIMEOUT: Duration = Duration::from_secs(15);

/// With every session taken, a new `SETUP` takes the place of the session
/// that never played and was heard of longest ago, if that was at least
/// this long ago (a player between its `SETUP` and its `PLAY` keeps its
/// place).
pub const RECLAIM_AFTER: Duration = Duration::from_secs(2);

/// A connection that owns no session and has made no request for this
/// long is closed (players set up within milliseconds of connecting).
pub const IDLE_DEADLINE: Duration = Duration::from_secs(10);

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

/// A connection's number, given by the caller ([`Connection::new`]).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub struct ConnId(pub u32);

impl fmt::Display for ConnId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "#{}", self.0)
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

/// Who a session belongs to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Client {
    /// The address that set it up: requests naming it come from there,
    /// and a unicast stream goes there.
    pub addr: IpAddr,
    /// The connection that set it up (or named it last): an interleaved
    /// stream goes through it.
    pub conn: ConnId,
}

/// Random values for a stream the sender may start (RFC 3550 asks for a
/// random SSRC, first sequence number and timestamp origin): a sender that
/// joins the session to a stream already running uses that stream's.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Fresh {
    /// The SSRC.
    pub ssrc: u32,
    /// The first packet's sequence number.
    pub seq: u16,
    /// The RTP timestamp of media time 0.
    pub rtptime: u32,
}

/// What the sender answers to a `SETUP`.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct SetUp {
    /// The SSRC of the session's packets.
    pub ssrc: u32,
    /// Where a multicast session's stream goes.
    pub group: Option<Group>,
}

/// Where a played session's stream starts: the sequence number and RTP
/// timestamp announced in `RTP-Info` (the first packet the session gets
/// carries that number; its timestamp is no earlier), and the media time
/// that timestamp stands for, announced in `Range` (RFC 2326 section
/// 12.33: `rtptime` is the timestamp of the range's start), so a client
/// joining a running stream knows each frame's media time.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Position {
    /// The first packet's sequence number.
    pub seq: u16,
    /// The RTP timestamp of `media_ticks`.
    pub rtptime: u32,
    /// The stream's media time now, in 90 kHz ticks since its first `PLAY`.
    pub media_ticks: u64,
}

/// Why a session ended.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum EndReason {
    /// `TEARDOWN`.
    Teardown,
    /// Not heard of for [`SESSION_TIMEOUT`].
    Timeout,
    /// The connection its interleaved stream went through closed.
    ConnectionClosed,
    /// Never played, and its place given to a new session
    /// ([`RECLAIM_AFTER`]).
    Reclaimed,
}

impl fmt::Display for EndReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            EndReason::Teardown => "teardown",
            EndReason::Timeout => "timeout",
            EndReason::ConnectionClosed => "connection closed",
            EndReason::Reclaimed => "never played, place reclaimed",
        })
    }
}

/// The RTP sender as the RTSP server sees it: what only the sender knows
/// (which stream a session joins, where it starts) is asked while the
/// response is written. Implemented over `camera::sender::Camera`; the
/// tests implement it with a recorder.
pub trait Streams {
    /// Set `session` up (a new one, or one that is not playing, again) for
    /// `spec` over `transport` as the client asked with `profile`: join
    /// the stream of that spec if one runs, else start one with `fresh`.
    /// The error is the status to answer (453: no room; 461: no such
    /// transport here).
    fn setup(
        &mut self,
        session: SessionId,
        spec: &StreamSpec,
        transport: Transport,
        profile: Profile,
        client: Client,
        fresh: Fresh,
    ) -> Result<SetUp, Status>;

    /// Start (or resume) sending to `session`.
    fn play(&mut self, session: SessionId) -> Result<Position, Status>;

    /// Stop sending to `session`; it may play again.
    fn pause(&mut self, session: SessionId);

    /// `session` is over: stop, say goodbye (RTCP BYE), forget it.
    fn end(&mut self, session: SessionId, why: EndReason);

    /// A live stream's light moved.
    fn set_light(&mut self, session: SessionId, light: Light);

    /// An RTCP packet from `session`'s client arrived inside its RTSP
    /// connection (interleaved).
    fn rtcp(&mut self, session: SessionId, datagram: &[u8]);

    /// The multicast group `spec`'s stream goes (or would go) to, for a
    /// description; `None` where the sender sends no multicast.
    fn group(&self, spec: &StreamSpec) -> Option<Group>;
}

/// One session's state.
#[derive(Clone, Debug)]
pub struct Session {
    id: SessionId,
    state: State,
    spec: StreamSpec,
    url: String<MAX_URL_BYTES>,
    client: Client,
    transport: Transport,
    profile: Profile,
    ssrc: u32,
    group: Option<Group>,
    last_heard: Instant,
    /// Whether it was ever played.
    played: bool,
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

    /// Its client.
    pub fn client(&self) -> Client {
        self.client
    }

    /// How its stream travels.
    pub fn transport(&self) -> Transport {
        self.transport
    }

    /// The SSRC of its stream.
    pub fn ssrc(&self) -> u32 {
        self.ssrc
    }

    /// When it times out unless heard of before.
    pub fn expires(&self) -> Instant {
        self.last_heard + if self.played { SESSION_TIMEOUT } else { UNPLAYED_TIMEOUT }
    }
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
    /// 551 Option not supported: a `Require` the server does not meet.
    OptionNotSupported,
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
            Status::OptionNotSupported => 551,
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
            Status::OptionNotSupported => "Option not supported",
            Status::VersionNotSupported => "RTSP Version Not Supported",
        }
    }
}

/// The answer to one request: the response is `out[..len]`.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Reply {
    /// Bytes of the response written to the caller's buffer.
    pub len: usize,
    /// Its status.
    pub status: Status,
    /// Close the connection once the response is sent: the input could not
    /// be framed (a header block beyond [`MAX_HEADER_BYTES`], a bad or too
    /// long `Content-Length`), so nothing after it can be read.
    pub close: bool,
}

/// Random numbers for session identifiers, SSRCs and the first sequence
/// numbers and timestamps (RFC 3550 wants them unpredictable; the board's
/// is a ChaCha20 generator, `camera::random`). Any `FnMut() -> u32` is one.
pub trait Random {
    /// The next 32 random bits.
    fn next_u32(&mut self) -> u32;
}

impl<F: FnMut() -> u32> Random for F {
    fn next_u32(&mut self) -> u32 {
        self()
    }
}

/// The server's own address and ports.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Config {
    /// The server's address, in the SDP's `o=` line.
    pub server_ip: Ipv4Addr,
    /// The UDP port RTP leaves from ([`SERVER_RTP_PORT`]); RTCP uses the
    /// next one. Announced as `server_port` in `SETUP`.
    pub rtp_port: u16,
    /// Whether RTP goes over UDP (unicast or multicast) at all; `false`: a
    /// `SETUP` for either is answered 461 and only RTP inside the RTSP
    /// connection is served (hps-sim's `--fault refuse-udp`, for clients'
    /// fallback tests).
    pub udp: bool,
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

    /// The board's address changed (a new lease): new descriptions and
    /// streams name this one.
    pub fn set_server_ip(&mut self, ip: Ipv4Addr) {
        self.config.server_ip = ip;
    }

    /// The open sessions.
    pub fn sessions(&self) -> &[Session] {
        &self.sessions
    }

    /// The session `id`, if open.
    pub fn session(&self, id: SessionId) -> Option<&Session> {
        self.sessions.iter().find(|s| s.id == id)
    }

    /// Answer the first complete request buffered in `conn` at `now`,
    /// asking `streams` what only the sender knows: the response goes into
    /// `out`, the [`Reply`] says how long it is. Interleaved RTCP packets
    /// before it go to `streams`. `None`: no complete request (wait for
    /// bytes).
    pub fn handle(
        &mut self,
        conn: &mut Connection,
        now: Instant,
        rng: &mut impl Random,
        streams: &mut impl Streams,
        out: &mut [u8; MAX_RESPONSE_BYTES],
    ) -> Option<Reply> {
        let mut w = Out { buf: out, len: 0, overflow: false };
        loop {
            if conn.closed {
                return None;
            }
            let (head, body) = match conn.frame() {
                Framing::Incomplete => return None,
                Framing::Fatal => {
                    conn.close();
                    bare_answer(&mut w, Status::BadRequest, None);
                    return Some(Reply { len: w.len, status: Status::BadRequest, close: true });
                }
                Framing::Interleaved { channel, len } => {
                    self.interleaved(conn, channel, 4..4 + len, now, streams);
                    conn.consume(4 + len, now);
                    continue;
                }
                Framing::Request { head, body } => (head, body),
            };
            let peer = Client { addr: conn.peer(), conn: conn.id() };
            let status = match parse_request(conn.bytes(0..head)) {
                Err((status, cseq)) => bare_answer(&mut w, status, cseq),
                Ok(req) => self.answer(&req, conn.bytes(head..head + body), peer, now, rng, streams, &mut w),
            };
            conn.consume(head + body, now);
            if w.overflow {
                // Never expected (MAX_RESPONSE_BYTES bounds every response); a
                // truncated response must not go out.
                w.len = 0;
                w.overflow = false;
                bare_answer(&mut w, Status::InternalServerError, None);
                return Some(Reply { len: w.len, status: Status::InternalServerError, close: false });
            }
            return Some(Reply { len: w.len, status, close: false });
        }
    }

    /// Interleaved data from the client: RTCP on a session's RTCP channel
    /// keeps it alive and goes to the sender; anything else is dropped.
    fn interleaved(
        &mut self,
        conn: &Connection,
        channel: u8,
        data: core::ops::Range<usize>,
        now: Instant,
        streams: &mut impl Streams,
    ) {
        let found = self.sessions.iter_mut().find(|s| {
            s.client.conn == conn.id()
                && matches!(s.transport, Transport::Interleaved { rtcp_channel, .. } if rtcp_channel == channel)
        });
        if let Some(s) = found {
            s.last_heard = now;
            streams.rtcp(s.id, conn.bytes(data));
        }
    }

    /// End the sessions not heard of for [`SESSION_TIMEOUT`] at `now`,
    /// telling `streams`; returns the first one ended (call until `None`,
    /// at the latest by [`Server::next_deadline`]).
    pub fn poll(&mut self, now: Instant, streams: &mut impl Streams) -> Option<SessionId> {
        let i = self.sessions.iter().position(|s| now >= s.expires())?;
        let s = self.sessions.swap_remove(i);
        streams.end(s.id, EndReason::Timeout);
        Some(s.id)
    }

    /// When [`Server::poll`] next has a session to end.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.sessions.iter().map(Session::expires).min()
    }

    /// A datagram arrived at the RTCP port from `from:port`: if it is RTCP
    /// (a well-formed compound packet; anything else refreshes nothing),
    /// the session whose client sent it stays alive and is returned: the
    /// unicast session with that RTCP port, else one from that address (a
    /// NAT may have given its reports another port; the sender takes them
    /// by address too), or a multicast session's member, whose reports may
    /// come from any port.
    pub fn rtcp_received(&mut self, now: Instant, from: IpAddr, port: u16, datagram: &[u8]) -> Option<SessionId> {
        if !crate::camera::wire::rtcp::valid_compound(datagram) {
            return None;
        }
        let exact = |s: &Session| {
            s.client.addr == from && matches!(s.transport, Transport::Udp { rtcp_port, .. } if rtcp_port == port)
        };
        let by_addr =
            |s: &Session| s.client.addr == from && matches!(s.transport, Transport::Udp { .. } | Transport::Multicast);
        let i = self.sessions.iter().position(exact).or_else(|| self.sessions.iter().position(by_addr))?;
        let s = &mut self.sessions[i];
        s.last_heard = now;
        Some(s.id)
    }

    /// Forget a session without telling the sender (the sender ended it:
    /// its client went away). `false` if it was gone.
    pub fn remove(&mut self, session: SessionId) -> bool {
        match self.sessions.iter().position(|s| s.id == session) {
            Some(i) => {
                self.sessions.swap_remove(i);
                true
            }
            None => false,
        }
    }

    /// The connection `conn` closed: the sessions whose stream went through
    /// it end (telling `streams`); the others live on (RFC 2326 section
    /// 3.1). Returns how many ended.
    pub fn connection_closed(&mut self, conn: ConnId, streams: &mut impl Streams) -> usize {
        let mut ended = 0;
        while let Some(i) = self
            .sessions
            .iter()
            .position(|s| s.client.conn == conn && matches!(s.transport, Transport::Interleaved { .. }))
        {
            let s = self.sessions.swap_remove(i);
            streams.end(s.id, EndReason::ConnectionClosed);
            ended += 1;
        }
        ended
    }

    /// Whether the caller should close `conn` at `now`: a request has been
    /// left unfinished for [`crate::time::REQUEST_LIMIT`], or the connection owns no
    /// session that has played and made no request for [`IDLE_DEADLINE`]
    /// (or a reply closed it). A session set up and never played keeps no
    /// connection open: it would let one host hold sockets with sessions
    /// it never plays.
    pub fn connection_expired(&self, conn: &Connection, now: Instant) -> bool {
        let owns = self.sessions.iter().any(|s| s.client.conn == conn.id() && s.played);
        conn.closed || conn.progress().expired(now, (!owns).then_some(IDLE_DEADLINE))
    }

    /// When [`connection_expired`](Self::connection_expired) may next turn
    /// true for `conn` (nothing arriving meanwhile).
    pub fn connection_deadline(&self, conn: &Connection) -> Instant {
        conn.progress().deadline(IDLE_DEADLINE)
    }

    /// The session that never played and was heard of longest ago, at
    /// least [`RECLAIM_AFTER`] ago (of `owner`'s, if given): the place a new
    /// `SETUP` may take.
    fn reclaimable(&self, now: Instant, owner: Option<IpAddr>) -> Option<usize> {
        self.sessions
            .iter()
            .enumerate()
            .filter(|(_, s)| owner.is_none_or(|a| s.client.addr == a))
            .filter(|(_, s)| !s.played && now.saturating_duration_since(s.last_heard) >= RECLAIM_AFTER)
            .min_by_key(|(_, s)| s.last_heard)
            .map(|(i, _)| i)
    }

    /// The index of the session a `Session` header names, if `peer` owns it.
    fn find(&self, header: &str, peer: IpAddr) -> Option<usize> {
        let id = SessionId::parse(header)?;
        self.sessions.iter().position(|s| s.id == id && s.client.addr == peer)
    }

    /// Answer a well-formed request.
    #[allow(clippy::too_many_arguments)]
    fn answer(
        &mut self,
        req: &Request<'_>,
        body: &[u8],
        peer: Client,
        now: Instant,
        rng: &mut impl Random,
        streams: &mut impl Streams,
        out: &mut Out<'_>,
    ) -> Status {
        let cseq = Some(req.cseq);
        let fail = |out: &mut Out<'_>, status: Status| bare_answer(out, status, cseq);
        // The session the request names, refreshed: `Ok(None)` without a
        // `Session` header, `Err` if it names none of the peer's.
        let session = match req.session {
            None => Ok(None),
            Some(h) => match self.find(h, peer.addr) {
                Some(i) => {
                    let s = &mut self.sessions[i];
                    s.last_heard = now;
                    if !matches!(s.transport, Transport::Interleaved { .. }) {
                        // The connection that names it owns it now (a
                        // player that reconnected).
                        s.client.conn = peer.conn;
                    }
                    Ok(Some(i))
                }
                None => Err(()),
            },
        };
        if let Some(options) = req.require {
            // RFC 2326 section 12.32: an option required and not supported
            // is 551, naming it in `Unsupported`.
            status_line(out, Status::OptionNotSupported, cseq);
            let _ = write!(out, "Unsupported: {options}\r\n\r\n");
            return Status::OptionNotSupported;
        }
        match req.method {
            "OPTIONS" => {
                status_line(out, Status::Ok, cseq);
                let _ = write!(out, "Public: {PUBLIC_METHODS}\r\n\r\n");
                Status::Ok
            }
            "DESCRIBE" => {
                let spec = match StreamSpec::parse(req.url) {
                    Ok(s) => s,
                    Err(e) => return fail(out, e.into()),
                };
                let group = if spec.multicast { streams.group(&spec) } else { None };
                let mut sdp: String<MAX_SDP_BYTES> = String::new();
                let description = Description {
                    session_id: rng.next_u32(),
                    server_ip: self.config.server_ip,
                    fps: spec.fps,
                    profile: OFFERED_PROFILE,
                    group,
                    control: req.url,
                };
                let _ = sdp::write(&mut sdp, &description);
                status_line(out, Status::Ok, cseq);
                let slash = if req.url.ends_with('/') { "" } else { "/" };
                let _ = write!(
                    out,
                    "Content-Base: {}{slash}\r\nContent-Type: application/sdp\r\nContent-Length: {}\r\n\r\n{sdp}",
                    req.url,
                    sdp.len()
                );
                Status::Ok
            }
            "SETUP" => self.setup(req, session, peer, now, rng, streams, out),
            "PLAY" | "PAUSE" | "TEARDOWN" => {
                let i = match session {
                    Ok(Some(i)) => i,
                    Ok(None) => return fail(out, Status::MethodNotValidInThisState),
                    Err(()) => return fail(out, Status::SessionNotFound),
                };
                let s = &mut self.sessions[i];
                let id = s.id;
                let mut position = None;
                match (req.method, s.state) {
                    ("PLAY", State::Ready) => match streams.play(id) {
                        Ok(p) => {
                            s.state = State::Playing;
                            s.played = true;
                            position = Some(p);
                        }
                        Err(status) => return fail(out, status),
                    },
                    ("PAUSE", State::Playing) => {
                        s.state = State::Ready;
                        streams.pause(id);
                    }
                    ("TEARDOWN", _) => streams.end(id, EndReason::Teardown),
                    _ => {}
                }
                status_line(out, Status::Ok, cseq);
                match req.method {
                    "PLAY" => {
                        session_header(out, id);
                        if let Some(p) = position {
                            // Microseconds recover the ticks exactly (a
                            // tick is 11.1 us).
                            let us = p.media_ticks * 100 / 9;
                            let _ = write!(out, "Range: npt={}.{:06}-\r\n", us / 1_000_000, us % 1_000_000);
                            // The URL the player set the stream up with,
                            // as it compares it (the SDP's control URL).
                            let url = ControlUrl(&s.url);
                            let _ = write!(out, "RTP-Info: url={url};seq={};rtptime={}\r\n", p.seq, p.rtptime);
                        }
                    }
                    "PAUSE" => session_header(out, id),
                    _ => {
                        self.sessions.swap_remove(i);
                    }
                }
                let _ = out.write_str("\r\n");
                Status::Ok
            }
            "GET_PARAMETER" => match session {
                Err(()) => fail(out, Status::SessionNotFound),
                Ok(i) => {
                    status_line(out, Status::Ok, cseq);
                    if let Some(i) = i {
                        session_header(out, self.sessions[i].id);
                    }
                    let _ = out.write_str("\r\n");
                    Status::Ok
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
                if let (Some(i), Some(light)) = (i, light) {
                    let s = &self.sessions[i];
                    if s.spec.light != LightSource::Live {
                        return fail(out, Status::ParameterNotUnderstood);
                    }
                    streams.set_light(s.id, light);
                }
                status_line(out, Status::Ok, cseq);
                if let Some(i) = i {
                    session_header(out, self.sessions[i].id);
                }
                let _ = out.write_str("\r\n");
                Status::Ok
            }
            _ => fail(out, Status::NotImplemented),
        }
    }

    /// `SETUP`: a new session, or a new stream and transport for a session
    /// not playing.
    #[allow(clippy::too_many_arguments)]
    fn setup(
        &mut self,
        req: &Request<'_>,
        session: Result<Option<usize>, ()>,
        peer: Client,
        now: Instant,
        rng: &mut impl Random,
        streams: &mut impl Streams,
        out: &mut Out<'_>,
    ) -> Status {
        let cseq = Some(req.cseq);
        let fail = |out: &mut Out<'_>, status: Status| bare_answer(out, status, cseq);
        let spec = match StreamSpec::parse(req.url) {
            Ok(s) => s,
            Err(e) => return fail(out, e.into()),
        };
        let Some(transport) = req.transport else { return fail(out, Status::BadRequest) };
        let Some((mut transport, profile)) = parse_transport(transport, peer.addr) else {
            return fail(out, Status::UnsupportedTransport);
        };
        // Inside the connection nothing is lost, so no feedback is needed,
        // and an AVPF answer does harm: GStreamer 1.22's rtspsrc then turns
        // its jitter buffer's retransmission on (it needs the answer's
        // AVPF and the description's rtx map, gstrtspsrc.c
        // `add_retransmission`), whose timers declare lost the rows a slow
        // TCP reader only got late, and drop them when they come: frames
        // with rows missing (the suite's many-viewers test, 2 runs in 3).
        let profile = if matches!(transport, Transport::Interleaved { .. }) { Profile::Avp } else { profile };
        if !self.config.udp && !matches!(transport, Transport::Interleaved { .. }) {
            return fail(out, Status::UnsupportedTransport);
        }
        if let Transport::Interleaved { rtp_channel, rtcp_channel } = &mut transport {
            // Channels another session of this connection uses are moved on.
            let own = session.ok().flatten();
            let taken = |c: u8| {
                self.sessions.iter().enumerate().any(|(j, s)| {
                    Some(j) != own
                        && s.client.conn == peer.conn
                        && matches!(s.transport, Transport::Interleaved { rtp_channel: a, rtcp_channel: b } if a == c || b == c)
                })
            };
            if taken(*rtp_channel) || taken(*rtcp_channel) {
                let Some(free) = (0..=254u8).step_by(2).find(|&c| !taken(c) && !taken(c + 1)) else {
                    return fail(out, Status::UnsupportedTransport);
                };
                (*rtp_channel, *rtcp_channel) = (free, free + 1);
            }
        }
        let mut url: String<MAX_URL_BYTES> = String::new();
        // The request line's URL is at most MAX_URL_BYTES (parse_request).
        let _ = url.push_str(req.url);
        let fresh = Fresh { ssrc: rng.next_u32(), seq: rng.next_u32() as u16, rtptime: rng.next_u32() };
        let i = match session {
            Err(()) => return fail(out, Status::SessionNotFound),
            Ok(Some(i)) => {
                let s = &mut self.sessions[i];
                if s.state == State::Playing {
                    return fail(out, Status::MethodNotValidInThisState);
                }
                let set = match streams.setup(s.id, &spec, transport, profile, peer, fresh) {
                    Ok(set) => set,
                    Err(status) => return fail(out, status),
                };
                (s.spec, s.url, s.transport, s.profile, s.ssrc, s.group) =
                    (spec, url, transport, profile, set.ssrc, set.group);
                s.client = peer;
                i
            }
            Ok(None) => {
                // Over the address's cap, a place of its own is taken back;
                // with every place taken, anyone's.
                let own = self.sessions.iter().filter(|s| s.client.addr == peer.addr).count();
                let reclaim = if own >= SESSIONS_PER_ADDRESS {
                    Some(self.reclaimable(now, Some(peer.addr)))
                } else if self.sessions.is_full() {
                    Some(self.reclaimable(now, None))
                } else {
                    None
                };
                if let Some(place) = reclaim {
                    let Some(oldest) = place else { return fail(out, Status::NotEnoughBandwidth) };
                    let gone = self.sessions.swap_remove(oldest);
                    streams.end(gone.id, EndReason::Reclaimed);
                }
                // 64 random bits; a source that keeps repeating itself gets
                // no session rather than a shared one.
                let fresh_id = (0..8)
                    .map(|_| SessionId(u64::from(rng.next_u32()) << 32 | u64::from(rng.next_u32())))
                    .find(|id| id.0 != 0 && self.sessions.iter().all(|s| s.id != *id));
                let Some(id) = fresh_id else { return fail(out, Status::NotEnoughBandwidth) };
                let set = match streams.setup(id, &spec, transport, profile, peer, fresh) {
                    Ok(set) => set,
                    Err(status) => return fail(out, status),
                };
                let session = Session {
                    id,
                    state: State::Ready,
                    spec,
                    url,
                    client: peer,
                    transport,
                    profile,
                    ssrc: set.ssrc,
                    group: set.group,
                    last_heard: now,
                    played: false,
                };
                if self.sessions.push(session).is_err() {
                    streams.end(id, EndReason::Teardown);
                    return fail(out, Status::NotEnoughBandwidth);
                }
                self.sessions.len() - 1
            }
        };
        let s = &self.sessions[i];
        status_line(out, Status::Ok, cseq);
        let profile = s.profile.name();
        let _ = match (s.transport, s.group) {
            (Transport::Udp { rtp_port, rtcp_port }, _) => {
                let server = self.config.rtp_port;
                write!(
                    out,
                    "Transport: {profile};unicast;client_port={rtp_port}-{rtcp_port};server_port={server}-{};ssrc={:08X}\r\n",
                    server.wrapping_add(1),
                    s.ssrc
                )
            }
            (Transport::Interleaved { rtp_channel, rtcp_channel }, _) => write!(
                out,
                "Transport: {profile}/TCP;unicast;interleaved={rtp_channel}-{rtcp_channel};ssrc={:08X}\r\n",
                s.ssrc
            ),
            // server_port too: where a receiver sends its NACKs (unicast:
            // the board joins no group, so RTCP to the group never reaches it).
            (Transport::Multicast, Some(g)) => write!(
                out,
                "Transport: {profile};multicast;destination={};port={}-{};ttl={};server_port={}-{};ssrc={:08X}\r\n",
                g.addr,
                g.port,
                g.port.wrapping_add(1),
                g.ttl,
                self.config.rtp_port,
                self.config.rtp_port.wrapping_add(1),
                s.ssrc
            ),
            // The sender gives a multicast session its group.
            (Transport::Multicast, None) => write!(out, "Transport: {profile};multicast;ssrc={:08X}\r\n", s.ssrc),
        };
        session_header(out, s.id);
        let _ = out.write_str("\r\n");
        Status::Ok
    }
}

/// The profile the description offers: RTP/AVPF, so that `a=rtcp-fb`
/// (generic NACK) and `a=rtcp-rsize` are defined (RFC 4585, RFC 5506).
/// Tried here: GStreamer 1.22's rtspsrc then asks for `RTP/AVPF` (and
/// sends its NACKs early, as AVPF allows); FFmpeg 5.1 reads the same
/// description and asks for `RTP/AVP/UDP` or `RTP/AVP/TCP`, which the
/// server takes too.
pub const OFFERED_PROFILE: Profile = Profile::Avpf;

fn session_header(out: &mut impl Write, id: SessionId) {
    let _ = write!(out, "Session: {id};timeout={}\r\n", SESSION_TIMEOUT.as_secs());
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
mod tests;
