//! Hostile input for the network camera's connection lifecycle: the
//! sans-IO RTSP server with the real RTP sender behind it (over a frame
//! source that only counts slots), well-formed requests of every method
//! (naming real, foreign, stale and made-up sessions; every transport),
//! the same requests mutated byte by byte, junk and interleaved binary
//! data, over three connections from two addresses, cut at random points,
//! with random pauses (past the deadlines and the session timeout), RTCP
//! packets, ICMP port unreachable, connections closing and the sender
//! polled. Checked: no panic; every response is well-formed and fits; a
//! well-formed request on an idle connection gets exactly one response,
//! echoing its CSeq; the sessions stay within the cap and within their
//! owners, and the sender's sessions are the server's; a connection with
//! half a request past its deadline is expired; the frame source never
//! holds more slots than the camera may; every session ends exactly once
//! (TEARDOWN, timeout, its connection, or the sender), and at the end
//! nothing is held.
//!
//! `cargo test -p rt-services --test fuzz_rtsp` runs proptest's default 256
//! cases (the suite's short run); `cargo xtask fuzz` runs a million
//! (release build).

mod common;

use common::Slots;
use std::collections::HashSet;
use std::net::{IpAddr, Ipv4Addr};

use model::Light;
use proptest::prelude::*;
use rt_services::camera::packetiser::Packetiser;
use rt_services::camera::rtsp::{
    Client, Config, ConnId, Connection, EndReason, Fresh, Group, Position, Profile, Random, Server, SessionId, SetUp,
    State, Status, StreamSpec, Streams, Transport, MAX_REQUEST_BYTES, MAX_RESPONSE_BYTES, MAX_SESSIONS,
    SERVER_RTP_PORT, SESSION_TIMEOUT,
};
use rt_services::camera::sender::{self, Bound, Camera, Dest, Multicast, RtpSink, CAMERA_SLOTS};
use rt_services::camera::wire::rtp::RowPacket;
use rt_services::time::REQUEST_LIMIT;
use rt_services::{FrameSource, Instant};

const PEERS: [IpAddr; 3] = [
    IpAddr::V4(Ipv4Addr::new(10, 0, 0, 1)),
    IpAddr::V4(Ipv4Addr::new(10, 0, 0, 1)),
    IpAddr::V4(Ipv4Addr::new(10, 0, 0, 2)),
];

/// xorshift64*: the server's random source, seeded per case.
struct Xorshift(u64);

impl Random for Xorshift {
    fn next_u32(&mut self) -> u32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 32) as u32
    }
}

/// Which session a request names.
#[derive(Clone, Debug)]
enum SessionRef {
    None,
    /// The k-th newest session id the server handed out (mod their number).
    Seen(usize),
    /// A made-up id.
    Made(u64),
    /// Arbitrary text.
    Text(String),
}

/// A request before its session id is known.
#[derive(Clone, Debug)]
struct Req {
    method: String,
    url: String,
    version: &'static str,
    cseq: Option<String>,
    session: SessionRef,
    transport: Option<String>,
    body: Option<String>,
    lf_only: bool,
}

#[derive(Clone, Debug)]
enum Mutation {
    Flip(usize, u8),
    Insert(usize, u8),
    Delete(usize),
    Truncate(usize),
}

#[derive(Clone, Debug)]
enum Piece {
    /// A request as written, on a connection.
    Clean(usize, Req),
    /// A request damaged, on a connection.
    Mutated(usize, Req, Vec<Mutation>),
    /// Arbitrary bytes on a connection.
    Junk(usize, Vec<u8>),
    /// An RTCP packet from peer `.0`, port `.1` (a NACK for the stream's
    /// SSRC or random bytes).
    Rtcp(usize, u16, bool),
    /// ICMP port unreachable about a packet to peer `.0`, port `.1`, quoting
    /// the SSRC of the server's session `.2` (none: an SSRC of no stream).
    Unreachable(usize, u16, usize),
    /// Connection `.0` closes (its peer went away).
    Close(usize),
    /// The sender is polled this many times.
    Send(u8),
    /// Time passes.
    Wait(u64),
}

const METHODS: &[&str] = &[
    "OPTIONS",
    "DESCRIBE",
    "SETUP",
    "SETUP",
    "SETUP",
    "SETUP",
    "SETUP",
    "PLAY",
    "PLAY",
    "PLAY",
    "PAUSE",
    "PAUSE",
    "TEARDOWN",
    "GET_PARAMETER",
    "SET_PARAMETER",
    "SET_PARAMETER",
    "ANNOUNCE",
    "RECORD",
    "options",
];

/// The first [`GOOD_URLS`] name streams.
const URLS: &[&str] = &[
    "rtsp://10.0.0.9:8554/light/3,4,-2",
    "rtsp://10.0.0.9:8554/light/3,4,-2?fps=60",
    "rtsp://10.0.0.9:8554/light/3%2C4%2C-2/trackID=0",
    "rtsp://10.0.0.9:8554/orbit",
    "rtsp://10.0.0.9:8554/orbit?radius=5&height=2&period=8&fps=max",
    "rtsp://10.0.0.9:8554/live",
    "rtsp://10.0.0.9:8554/live?fps=5",
    "rtsp://10.0.0.9:8554/live/trackID=0",
    "rtsp://10.0.0.9:8554/nothing",
    "rtsp://10.0.0.9:8554/light/9000,0,0",
    "rtsp://10.0.0.9:8554/orbit?period=0",
    "rtsp://10.0.0.9:8554/live?fps=0",
    "*",
];

const GOOD_URLS: usize = 8;

/// The first [`GOOD_TRANSPORTS`] are accepted.
const TRANSPORTS: &[&str] = &[
    "RTP/AVP;unicast;client_port=6000-6001",
    "RTP/AVP/UDP;unicast;client_port=6002",
    "RTP/AVP;unicast;client_port=6004-6005;mode=\"PLAY\"",
    "RTP/AVP/TCP;unicast;interleaved=0-1",
    "RTP/AVP;multicast;client_port=6000-6001",
    "RTP/AVPF;unicast;client_port=6006-6007",
    "RTP/AVP;unicast",
    "RTP/AVP;unicast;client_port=0-1",
    "RTP/AVP/TCP;interleaved=0-1,RTP/AVP;unicast;client_port=7000-7001",
];

const GOOD_TRANSPORTS: usize = 6;

const BODIES: &[&str] = &["", "light: 1,2,3", "light: 1.5, 6, -2.25\r\n", "light: 9000,0,0", "colour: red", "light"];

/// A request: mostly a plausible next step of a client (`sane`: a good
/// stream URL and transport, the session it would name, a light to set),
/// otherwise any combination of good and bad fields.
fn req() -> impl Strategy<Value = Req> {
    let method = prop_oneof![8 => prop::sample::select(METHODS).prop_map(String::from), 1 => "[A-Z_]{1,12}"];
    let url = prop_oneof![6 => prop::sample::select(URLS).prop_map(String::from), 1 => "[!-~]{1,60}"];
    let version = prop::sample::select(&["RTSP/1.0", "RTSP/1.0", "RTSP/1.0", "RTSP/1.0", "RTSP/2.0", "HTTP/1.1"][..]);
    let cseq = prop_oneof![
        8 => (0u32..100_000).prop_map(|n| Some(n.to_string())),
        1 => Just(None),
        1 => "[ -~]{0,12}".prop_map(Some),
    ];
    let session = prop_oneof![
        3 => Just(SessionRef::None),
        6 => (0usize..8).prop_map(SessionRef::Seen),
        1 => any::<u64>().prop_map(SessionRef::Made),
        1 => "[ -~]{0,20}".prop_map(SessionRef::Text),
    ];
    let transport = prop_oneof![
        1 => Just(None),
        6 => prop::sample::select(TRANSPORTS).prop_map(|t| Some(t.to_string())),
        1 => "[ -~]{0,60}".prop_map(Some),
    ];
    let body = prop_oneof![
        2 => Just(None),
        4 => prop::sample::select(BODIES).prop_map(|b| Some(b.to_string())),
        1 => "[ -~\r\n]{0,200}".prop_map(Some),
    ];
    let sane = (
        prop::bool::weighted(0.75),
        0usize..GOOD_URLS,
        0usize..GOOD_TRANSPORTS,
        0usize..3,
        [-40i32..40, -40i32..40, -40i32..40],
    );
    (method, url, version, cseq, session, transport, body, prop::bool::weighted(0.1), sane).prop_map(
        |(method, url, version, cseq, session, transport, body, lf_only, (sane, u, t, k, xyz))| {
            let mut r = Req { method, url, version, cseq, session, transport, body, lf_only };
            if sane {
                r.version = "RTSP/1.0";
                r.cseq = Some(format!("{}", k + u * 10 + t * 100));
                r.url = URLS[u].to_string();
                r.transport = None;
                r.body = None;
                r.session = SessionRef::Seen(k);
                match r.method.as_str() {
                    "OPTIONS" | "DESCRIBE" => r.session = SessionRef::None,
                    "SETUP" => {
                        r.transport = Some(TRANSPORTS[t].to_string());
                        if k > 0 {
                            r.session = SessionRef::None;
                        }
                    }
                    "SET_PARAMETER" => {
                        let [x, y, z] = xyz.map(|v| f64::from(v) / 4.0);
                        r.body = Some(format!("light: {x},{y},{z}\r\n"));
                    }
                    _ => {}
                }
            }
            r
        },
    )
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(p, b)| Mutation::Flip(p, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(p, b)| Mutation::Insert(p, b)),
        any::<usize>().prop_map(Mutation::Delete),
        any::<usize>().prop_map(Mutation::Truncate),
    ]
}

fn piece() -> impl Strategy<Value = Piece> {
    let conn = 0usize..PEERS.len();
    prop_oneof![
        10 => (conn.clone(), req()).prop_map(|(c, r)| Piece::Clean(c, r)),
        3 => (conn.clone(), req(), prop::collection::vec(mutation(), 1..4)).prop_map(|(c, r, m)| Piece::Mutated(c, r, m)),
        1 => (conn.clone(), prop::collection::vec(any::<u8>(), 0..40)).prop_map(|(c, j)| Piece::Junk(c, j)),
        1 => (conn.clone(), prop::collection::vec(any::<u8>(), 0..40)).prop_map(|(c, mut j)| { j.insert(0, b'$'); Piece::Junk(c, j) }),
        1 => (0usize..PEERS.len(), prop_oneof![Just(6001u16), Just(7001u16), any::<u16>()], any::<bool>())
            .prop_map(|(p, port, nack)| Piece::Rtcp(p, port, nack)),
        1 => (0usize..PEERS.len(), prop_oneof![Just(6000u16), Just(6002u16), any::<u16>()], 0usize..4).prop_map(|(p, port, s)| Piece::Unreachable(p, port, s)),
        1 => (0usize..PEERS.len()).prop_map(Piece::Close),
        3 => (1u8..20).prop_map(Piece::Send),
        2 => prop_oneof![0u64..5_000, Just(REQUEST_LIMIT.as_millis() as u64), Just(SESSION_TIMEOUT.as_millis() as u64 + 1_000)].prop_map(Piece::Wait),
    ]
}

#[derive(Clone, Debug)]
struct Case {
    seed: u64,
    pieces: Vec<Piece>,
    cuts: Vec<usize>,
}

fn case() -> impl Strategy<Value = Case> {
    (any::<u64>(), prop::collection::vec(piece(), 0..32), prop::collection::vec(1usize..200, 1..6))
        .prop_map(|(seed, pieces, cuts)| Case { seed: seed | 1, pieces, cuts })
}

/// The bytes of `r`, naming one of `seen` where it refers to one.
fn render(r: &Req, seen: &[SessionId]) -> Vec<u8> {
    let mut t = format!("{} {} {}\r\n", r.method, r.url, r.version);
    if let Some(c) = &r.cseq {
        t += &format!("CSeq: {c}\r\n");
    }
    match &r.session {
        SessionRef::None => {}
        SessionRef::Seen(k) => match seen.len() {
            0 => t += "Session: 0000000000000001\r\n",
            n => t += &format!("Session: {};timeout=60\r\n", seen[n - 1 - k % n]),
        },
        SessionRef::Made(id) => t += &format!("Session: {}\r\n", SessionId(*id)),
        SessionRef::Text(s) => t += &format!("Session: {s}\r\n"),
    }
    if let Some(tr) = &r.transport {
        t += &format!("Transport: {tr}\r\n");
    }
    if let Some(b) = &r.body {
        t += &format!("Content-Type: text/parameters\r\nContent-Length: {}\r\n", b.len());
    }
    t += "\r\n";
    if let Some(b) = &r.body {
        t += b;
    }
    if r.lf_only {
        t = t.replace("\r\n", "\n");
        // The body's length changed with its line ends: fix the header.
        if let Some(b) = &r.body {
            let nb = b.replace("\r\n", "\n");
            t = t.replace(&format!("Content-Length: {}\n", b.len()), &format!("Content-Length: {}\n", nb.len()));
        }
    }
    t.into_bytes()
}

fn mutate(mut bytes: Vec<u8>, ms: &[Mutation]) -> Vec<u8> {
    for m in ms {
        let n = bytes.len().max(1);
        match *m {
            Mutation::Flip(p, b) => {
                if let Some(x) = bytes.get_mut(p % n) {
                    *x = b;
                }
            }
            Mutation::Insert(p, b) => bytes.insert(p % (bytes.len() + 1), b),
            Mutation::Delete(p) => {
                if !bytes.is_empty() {
                    bytes.remove(p % n);
                }
            }
            Mutation::Truncate(p) => bytes.truncate(p % n),
        }
    }
    bytes
}

/// A response is a status line, headers, a blank line and exactly its
/// `Content-Length` of body; returns its CSeq.
fn check_response(bytes: &[u8], status: Status) -> Result<Option<String>, TestCaseError> {
    let text = std::str::from_utf8(bytes).map_err(|_| TestCaseError::fail("response not UTF-8"))?;
    let want = format!("RTSP/1.0 {} {}\r\n", status.code(), status.reason());
    prop_assert!(text.starts_with(&want), "status line of {text:?}");
    let (head, body) = text.split_once("\r\n\r\n").ok_or_else(|| TestCaseError::fail("no blank line"))?;
    let mut cseq = None;
    let mut length = 0;
    for line in head.split("\r\n").skip(1) {
        let (name, value) = line.split_once(": ").ok_or_else(|| TestCaseError::fail(format!("header {line:?}")))?;
        match name {
            "CSeq" => cseq = Some(value.to_string()),
            "Content-Length" => length = value.parse().map_err(|_| TestCaseError::fail("length"))?,
            _ => {}
        }
    }
    prop_assert_eq!(body.len(), length, "body of {:?}", text);
    Ok(cseq)
}

/// A sink that takes every packet and counts them.
#[derive(Default)]
struct Count {
    rows: u64,
    rtcp: u64,
}

impl RtpSink for Count {
    fn send_rows<S: FrameSource<Frame = usize>>(
        &mut self,
        _: &Dest,
        _: &Packetiser,
        _: &RowPacket,
        n: u16,
        _: usize,
        _: &mut S,
    ) -> u16 {
        self.rows += u64::from(n);
        n
    }
    fn send_rtcp(&mut self, _: &Dest, _: &[u8]) -> bool {
        self.rtcp += 1;
        true
    }
}

/// The sender as the server sees it, checking each call against the
/// server's state and noting the sessions it ends.
struct Checked<'a> {
    inner: Bound<'a, Slots>,
    ended: &'a mut Vec<SessionId>,
    calls: &'a mut Vec<(&'static str, SessionId)>,
}

impl Streams for Checked<'_> {
    fn setup(
        &mut self,
        s: SessionId,
        spec: &StreamSpec,
        t: Transport,
        p: Profile,
        c: Client,
        f: Fresh,
    ) -> Result<SetUp, Status> {
        self.calls.push(("setup", s));
        self.inner.setup(s, spec, t, p, c, f)
    }
    fn play(&mut self, s: SessionId) -> Result<Position, Status> {
        self.calls.push(("play", s));
        self.inner.play(s)
    }
    fn pause(&mut self, s: SessionId) {
        self.calls.push(("pause", s));
        self.inner.pause(s)
    }
    fn end(&mut self, s: SessionId, why: EndReason) {
        self.calls.push(("end", s));
        self.ended.push(s);
        self.inner.end(s, why)
    }
    fn set_light(&mut self, s: SessionId, l: Light) {
        self.calls.push(("light", s));
        self.inner.set_light(s, l)
    }
    fn rtcp(&mut self, s: SessionId, d: &[u8]) {
        self.calls.push(("rtcp", s));
        self.inner.rtcp(s, d)
    }
    fn group(&self, spec: &StreamSpec) -> Option<Group> {
        self.inner.group(spec)
    }
}

/// A generic NACK for `ssrc`, packets `pid..pid + 17`.
fn nack(ssrc: u32, pid: u16) -> Vec<u8> {
    let mut d = vec![0x81, 205, 0, 3, 0, 0, 0, 9];
    d.extend_from_slice(&ssrc.to_be_bytes());
    d.extend_from_slice(&pid.to_be_bytes());
    d.extend_from_slice(&[0xff, 0xff]);
    d
}

fn run(c: &Case) -> Result<(), TestCaseError> {
    let mut server: Server =
        Server::new(Config { server_ip: Ipv4Addr::new(10, 0, 0, 9), rtp_port: SERVER_RTP_PORT, udp: true });
    let mut camera: Box<Camera> = Box::new(Camera::new());
    let live = Light::from_world(3.0, 4.0, -2.0).unwrap();
    let multicast = Some(Multicast { group: Ipv4Addr::new(239, 255, 42, 1), base_port: 5006, ttl: 1 });
    camera.configure(sender::Config {
        live_light: live,
        multicast,
        cname: sender::Cname::for_address(std::net::Ipv4Addr::new(10, 0, 0, 1)),
    });
    let mut source = Slots::default();
    let mut sink = Count::default();
    let mut next_conn = 0u32;
    let mut conns: Vec<Connection> = PEERS
        .iter()
        .map(|&p| {
            next_conn += 1;
            Connection::new(ConnId(next_conn), p, Instant::from_millis(0))
        })
        .collect();
    let mut rng = Xorshift(c.seed);
    let mut out = [0u8; MAX_RESPONSE_BYTES];
    let mut now = 0u64;
    let mut seen: Vec<SessionId> = Vec::new();
    let mut ended: Vec<SessionId> = Vec::new();
    let mut calls = Vec::new();
    let mut step = 0usize;

    macro_rules! streams {
        () => {
            Checked {
                inner: Bound {
                    camera: &mut camera,
                    source: &mut source,
                    now: Instant::from_millis(now),
                    wall: now << 16,
                },
                ended: &mut ended,
                calls: &mut calls,
            }
        };
    }

    for p in &c.pieces {
        // Sessions that time out meanwhile, and connections past a deadline.
        while server.poll(Instant::from_millis(now), &mut streams!()).is_some() {}
        for k in 0..conns.len() {
            if server.connection_expired(&conns[k], Instant::from_millis(now)) {
                server.connection_closed(conns[k].id(), &mut streams!());
                next_conn += 1;
                conns[k] = Connection::new(ConnId(next_conn), PEERS[k], Instant::from_millis(now));
            }
        }
        let (conn, bytes, clean) = match p {
            Piece::Clean(k, r) => (*k, render(r, &seen), Some(r)),
            Piece::Mutated(k, r, ms) => (*k, mutate(render(r, &seen), ms), None),
            Piece::Junk(k, j) => (*k, j.clone(), None),
            Piece::Rtcp(peer, port, is_nack) => {
                let at = Instant::from_millis(now);
                let ssrc = server.sessions().first().map_or(0, |s| s.ssrc());
                let d = if *is_nack { nack(ssrc, (now % 65_536) as u16) } else { vec![0x80, 201, 0, 1, 0, 0, 0, 1] };
                if server.rtcp_received(at, PEERS[*peer], *port, &d).is_some() {
                    camera.rtcp_received(
                        std::net::SocketAddr::new(PEERS[*peer], *port),
                        &d,
                        at,
                        now << 16,
                        &mut source,
                        &mut sink,
                    );
                }
                continue;
            }
            Piece::Unreachable(peer, port, s) => {
                // Quoting the SSRC of the server's session `s`, if there is one.
                let ssrc = server.sessions().get(*s).map_or(0xdead_beef, |s| s.ssrc());
                camera.unreachable(PEERS[*peer], *port, ssrc, Instant::from_millis(now), &mut source);
                while let Some((s, _)) = camera.take_ended() {
                    prop_assert!(server.remove(s), "the sender ended a session the server did not have");
                    ended.push(s);
                }
                continue;
            }
            Piece::Close(k) => {
                server.connection_closed(conns[*k].id(), &mut streams!());
                next_conn += 1;
                conns[*k] = Connection::new(ConnId(next_conn), PEERS[*k], Instant::from_millis(now));
                continue;
            }
            Piece::Send(n) => {
                for _ in 0..*n {
                    camera.poll(Instant::from_millis(now), now << 16, &mut source, &mut sink);
                }
                while let Some((s, _)) = camera.take_ended() {
                    prop_assert!(server.remove(s), "the sender ended a session the server did not have");
                    ended.push(s);
                }
                prop_assert!(source.high <= CAMERA_SLOTS as u32 + MAX_SESSIONS as u32, "slots held: {}", source.high);
                continue;
            }
            Piece::Wait(ms) => {
                now += ms;
                continue;
            }
        };
        let idle = conns[conn].is_idle();
        let mut replies = Vec::new();
        let mut fed = 0;
        while fed < bytes.len() {
            let cut = c.cuts[step % c.cuts.len()];
            step += 1;
            let chunk = &bytes[fed..(fed + cut).min(bytes.len())];
            let mut taken = 0;
            loop {
                taken += conns[conn].receive(Instant::from_millis(now), &chunk[taken..]);
                let mut answered = false;
                loop {
                    let reply =
                        server.handle(&mut conns[conn], Instant::from_millis(now), &mut rng, &mut streams!(), &mut out);
                    let Some(r) = reply else { break };
                    answered = true;
                    prop_assert!(r.status != Status::InternalServerError, "a response did not fit");
                    let cseq = check_response(&out[..r.len], r.status)?;
                    for s in server.sessions() {
                        if !seen.contains(&s.id()) {
                            seen.push(s.id());
                        }
                    }
                    prop_assert!(!r.close || conns[conn].is_closed());
                    replies.push((r.status, cseq));
                }
                prop_assert!(conns[conn].buffered() <= MAX_REQUEST_BYTES);
                if taken == chunk.len() || conns[conn].is_closed() {
                    break;
                }
                prop_assert!(answered, "input stuck: buffer full, nothing answered");
            }
            fed += chunk.len();
        }
        // The sender's calls match the server's states.
        for (what, s) in calls.drain(..) {
            let state = server.session(s).map(|s| s.state());
            match what {
                "play" => prop_assert!(matches!(state, Some(State::Playing) | Some(State::Ready))),
                "end" => prop_assert!(state.is_none(), "ended session still open"),
                _ => {}
            }
        }
        // Bounded state: the cap, owners, distinct ids, the sender agrees.
        let ids: HashSet<SessionId> = server.sessions().iter().map(|s| s.id()).collect();
        prop_assert!(server.sessions().len() <= MAX_SESSIONS);
        prop_assert_eq!(ids.len(), server.sessions().len(), "duplicate session ids");
        prop_assert!(server.sessions().iter().all(|s| PEERS.contains(&s.client().addr)));
        let sending: HashSet<SessionId> = camera.sessions().map(|(s, _)| s).collect();
        prop_assert_eq!(&sending, &ids, "the sender's sessions are the server's");
        // A well-formed request on an idle connection: one response, its CSeq.
        if let (Some(r), true) = (clean, idle) {
            prop_assert_eq!(replies.len(), 1, "responses to {:?}", r);
            let echoed = r
                .cseq
                .as_deref()
                .map(|c| c.trim_matches([' ', '\t']))
                .filter(|c| !c.is_empty() && c.len() <= 10 && c.bytes().all(|b| b.is_ascii_digit()));
            prop_assert_eq!(replies[0].1.as_deref(), echoed, "CSeq of {:?}", r);
            if r.version == "RTSP/1.0" && echoed.is_some() && r.method == "OPTIONS" && r.url.is_ascii() {
                prop_assert_eq!(replies[0].0, Status::Ok);
            }
        }
        // Half a request is never kept past its deadline.
        if !conns[conn].is_idle() && !conns[conn].is_closed() {
            let late = Instant::from_millis(now + REQUEST_LIMIT.as_millis() as u64);
            prop_assert!(server.connection_expired(&conns[conn], late));
        }
    }
    // Every session ends: by TEARDOWN, its connection, the sender, or
    // unheard of for the timeout; then nothing is held.
    now += SESSION_TIMEOUT.as_millis() as u64;
    while server.poll(Instant::from_millis(now), &mut streams!()).is_some() {}
    prop_assert!(server.sessions().is_empty(), "sessions left after the timeout");
    let ends: HashSet<SessionId> = ended.iter().copied().collect();
    prop_assert_eq!(ends.len(), ended.len(), "a session ended twice");
    prop_assert_eq!(seen.iter().copied().collect::<HashSet<_>>(), ends, "every session ended once");
    prop_assert_eq!((camera.streams(), camera.outputs()), (0, 0));
    now += 2_000;
    camera.poll(Instant::from_millis(now), now << 16, &mut source, &mut sink);
    prop_assert_eq!((source.begun, source.held), (0, 0), "every slot let go");
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn the_rtsp_server_survives_hostile_clients(c in case()) {
        run(&c)?;
    }
}
