use super::*;
use std::format;
use std::string::String as Text;
use std::vec;
use std::vec::Vec;

const SERVER_IP: Ipv4Addr = Ipv4Addr::new(192, 168, 1, 10);
const CLIENT: IpAddr = IpAddr::V4(Ipv4Addr::new(192, 168, 1, 20));
const OTHER: IpAddr = IpAddr::V4(Ipv4Addr::new(192, 168, 1, 21));
const URL: &str = "rtsp://192.168.1.10:8554/light/3,4,-2";
const GROUP: Group = Group { addr: Ipv4Addr::new(239, 255, 42, 1), port: 5006, ttl: 1 };

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
    Config { server_ip: SERVER_IP, rtp_port: SERVER_RTP_PORT, udp: true }
}

fn at(ms: u64) -> Instant {
    Instant::from_millis(ms)
}

/// What the server asked of the sender.
#[derive(Clone, Debug, PartialEq)]
enum Call {
    Setup(SessionId, StreamSpec, Transport, Profile, Client, Fresh),
    Play(SessionId),
    Pause(SessionId),
    End(SessionId, EndReason),
    SetLight(SessionId, Light),
    Rtcp(SessionId, Vec<u8>),
}

/// A sender that records every call: SSRC as fresh, position from
/// `position`, multicast to [`GROUP`], refusals on demand.
#[derive(Default)]
struct Recorder {
    calls: Vec<Call>,
    refuse_setup: Option<Status>,
    position: Option<Position>,
}

impl Streams for Recorder {
    fn setup(
        &mut self,
        session: SessionId,
        spec: &StreamSpec,
        transport: Transport,
        profile: Profile,
        client: Client,
        fresh: Fresh,
    ) -> Result<SetUp, Status> {
        if let Some(s) = self.refuse_setup {
            return Err(s);
        }
        self.calls.push(Call::Setup(session, *spec, transport, profile, client, fresh));
        Ok(SetUp { ssrc: fresh.ssrc, group: (transport == Transport::Multicast).then_some(GROUP) })
    }
    fn play(&mut self, session: SessionId) -> Result<Position, Status> {
        self.calls.push(Call::Play(session));
        Ok(self.position.unwrap_or(Position { seq: 0x4444, rtptime: 0x5555_5555, media_ticks: 0 }))
    }
    fn pause(&mut self, session: SessionId) {
        self.calls.push(Call::Pause(session));
    }
    fn end(&mut self, session: SessionId, why: EndReason) {
        self.calls.push(Call::End(session, why));
    }
    fn set_light(&mut self, session: SessionId, light: Light) {
        self.calls.push(Call::SetLight(session, light));
    }
    fn rtcp(&mut self, session: SessionId, datagram: &[u8]) {
        self.calls.push(Call::Rtcp(session, datagram.to_vec()));
    }
    fn group(&self, _: &StreamSpec) -> Option<Group> {
        Some(GROUP)
    }
}

/// A server, connections, a clock, the random source and the sender.
struct Rig {
    server: Server,
    conns: Vec<Connection>,
    rng: Counter,
    streams: Recorder,
    now: Instant,
}

/// One answered request.
#[derive(Debug)]
struct Answer {
    text: Text,
    status: Status,
    close: bool,
}

impl Rig {
    fn new() -> Rig {
        Rig {
            server: Server::new(config()),
            conns: vec![Connection::new(ConnId(0), CLIENT, at(0))],
            rng: Counter(0),
            streams: Recorder::default(),
            now: at(0),
        }
    }

    /// A new connection from `peer`; its index.
    fn connect(&mut self, peer: IpAddr) -> usize {
        self.conns.push(Connection::new(ConnId(self.conns.len() as u32), peer, self.now));
        self.conns.len() - 1
    }

    /// Bytes from connection `c`; every complete request answered.
    fn send_on(&mut self, c: usize, bytes: &[u8]) -> Vec<Answer> {
        let mut answers = Vec::new();
        let mut fed = 0;
        let mut out = [0u8; MAX_RESPONSE_BYTES];
        loop {
            fed += self.conns[c].receive(self.now, &bytes[fed..]);
            let reply = self.server.handle(&mut self.conns[c], self.now, &mut self.rng, &mut self.streams, &mut out);
            let Some(r) = reply else {
                if fed == bytes.len() {
                    return answers;
                }
                continue;
            };
            let text = Text::from_utf8(out[..r.len].to_vec()).unwrap();
            answers.push(Answer { text, status: r.status, close: r.close });
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
        session_of(&a.text)
    }

    /// SETUP of `url` from a new connection of a host of its own (the
    /// `k`th: 192.168.1.100 + k); the new session.
    fn setup_from_host(&mut self, k: u8, url: &str) -> SessionId {
        let c = self.connect(IpAddr::V4(Ipv4Addr::new(192, 168, 1, 100 + k)));
        let t = "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n";
        let a = self.send_on(c, request("SETUP", url, 3, t).as_bytes());
        assert_eq!(a[0].status, Status::Ok, "{}", a[0].text);
        session_of(&a[0].text)
    }

    /// The calls since the last look.
    fn calls(&mut self) -> Vec<Call> {
        core::mem::take(&mut self.streams.calls)
    }
}

fn session_of(text: &str) -> SessionId {
    let line = text.lines().find(|l| l.starts_with("Session: ")).unwrap();
    SessionId::parse(&line["Session: ".len()..]).unwrap()
}

fn request(method: &str, url: &str, cseq: u32, headers: &str) -> Text {
    format!("{method} {url} RTSP/1.0\r\nCSeq: {cseq}\r\n{headers}\r\n")
}

fn with_session(method: &str, id: SessionId, cseq: u32) -> Text {
    request(method, URL, cseq, &format!("Session: {id}\r\n"))
}

// ---- Methods ----

#[test]
fn options_lists_the_methods_and_echoes_cseq() {
    let mut r = Rig::new();
    let a = r.ask("OPTIONS * RTSP/1.0\r\nCSeq: 1\r\nUser-Agent: test\r\n\r\n");
    let want = "RTSP/1.0 200 OK\r\nCSeq: 1\r\n\
                Public: OPTIONS, DESCRIBE, SETUP, PLAY, PAUSE, TEARDOWN, GET_PARAMETER, SET_PARAMETER\r\n\r\n";
    assert_eq!(a.text, want);
    assert!(!a.close && r.calls().is_empty());
    let a = Rig::new().ask("OPTIONS rtsp://h/live RTSP/1.0\r\ncseq:  4294967296 \r\n\r\n");
    assert!(a.text.starts_with("RTSP/1.0 200 OK\r\nCSeq: 4294967296\r\n"), "{}", a.text);
}

#[test]
fn describe_answers_the_sdp_exactly() {
    let a = Rig::new().ask(&request("DESCRIBE", URL, 2, "Accept: application/sdp\r\n"));
    let sdp = "v=0\r\n\
               o=- 286331153 1 IN IP4 192.168.1.10\r\n\
               s=raytracer\r\n\
               c=IN IP4 0.0.0.0\r\n\
               t=0 0\r\n\
               m=video 0 RTP/AVPF 96 97\r\n\
               a=rtpmap:96 raw/90000\r\n\
               a=fmtp:96 sampling=RGB; width=480; height=360; depth=8; colorimetry=BT709-2; exactframerate=30\r\n\
               a=rtcp-fb:96 nack\r\n\
               a=rtcp-rsize\r\n\
               a=rtpmap:97 rtx/90000\r\n\
               a=fmtp:97 apt=96\r\n\
               a=control:rtsp://192.168.1.10:8554/light/3/4/-2\r\n";
    let want = format!(
        "RTSP/1.0 200 OK\r\nCSeq: 2\r\nContent-Base: {URL}/\r\nContent-Type: application/sdp\r\n\
         Content-Length: {}\r\n\r\n{sdp}",
        sdp.len()
    );
    assert_eq!(a.text, want);
    let a = Rig::new().ask(&request("DESCRIBE", "rtsp://h/orbit?fps=max", 2, ""));
    assert!(a.text.contains("colorimetry=BT709-2\r\na=rtcp-fb"), "fps=max: no exact rate: {}", a.text);
    let a = Rig::new().ask(&request("DESCRIBE", "rtsp://h/live?fps=60", 2, ""));
    assert!(a.text.contains("; exactframerate=60\r\n"));
    // A multicast URL names the group the sender gives.
    let a = Rig::new().ask(&request("DESCRIBE", "rtsp://h/orbit?multicast", 2, ""));
    assert!(a.text.contains("c=IN IP4 239.255.42.1/1\r\nt=0 0\r\nm=video 5006 RTP/AVPF 96 97\r\n"), "{}", a.text);
}

#[test]
fn a_whole_session_setup_play_pause_play_teardown() {
    let mut r = Rig::new();
    r.now = at(1_000);
    let a = r.ask(&request("SETUP", URL, 3, "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n"));
    // Random draws: the fresh SSRC, sequence number, timestamp, then the id (two).
    let id = SessionId(0x4444_4444_5555_5555);
    assert_eq!(
        a.text,
        "RTSP/1.0 200 OK\r\nCSeq: 3\r\n\
         Transport: RTP/AVP;unicast;client_port=6000-6001;server_port=5004-5005;ssrc=11111111\r\n\
         Session: 4444444455555555;timeout=60\r\n\r\n"
    );
    let client = Client { addr: CLIENT, conn: ConnId(0) };
    let udp = Transport::Udp { rtp_port: 6000, rtcp_port: 6001 };
    let fresh = Fresh { ssrc: 0x1111_1111, seq: 0x2222, rtptime: 0x3333_3333 };
    assert_eq!(r.calls(), [Call::Setup(id, StreamSpec::parse(URL).unwrap(), udp, Profile::Avp, client, fresh)]);
    let s = r.server.session(id).unwrap();
    assert_eq!(
        (s.state(), s.ssrc(), s.client(), s.transport(), s.url()),
        (State::Ready, 0x1111_1111, client, udp, URL)
    );

    let a = r.ask(&with_session("PLAY", id, 4));
    assert_eq!(
        a.text,
        "RTSP/1.0 200 OK\r\nCSeq: 4\r\nSession: 4444444455555555;timeout=60\r\nRange: npt=0.000000-\r\n\
         RTP-Info: url=rtsp://192.168.1.10:8554/light/3/4/-2;seq=17476;rtptime=1431655765\r\n\r\n",
        "the light's commas are slashes in RTP-Info, as in the control URL"
    );
    assert_eq!(r.calls(), [Call::Play(id)]);
    assert_eq!(r.server.session(id).unwrap().state(), State::Playing);
    // PLAY while playing: answered, nothing new to do.
    r.ask(&with_session("PLAY", id, 5));
    assert_eq!(r.calls(), []);

    let a = r.ask(&with_session("PAUSE", id, 6));
    assert_eq!(a.text, "RTSP/1.0 200 OK\r\nCSeq: 6\r\nSession: 4444444455555555;timeout=60\r\n\r\n");
    assert_eq!(r.calls(), [Call::Pause(id)]);
    r.ask(&with_session("PAUSE", id, 7));
    assert_eq!(r.calls(), [], "paused already");
    // PLAY again: the sender says where the stream goes on.
    r.streams.position = Some(Position { seq: 0x4500, rtptime: 0x5555_9999, media_ticks: 90_001 });
    let a = r.ask(&with_session("PLAY", id, 8));
    assert!(a.text.contains("Range: npt=1.000011-\r\n"), "media ticks to the microsecond: {}", a.text);
    assert!(a.text.contains("RTP-Info: url=rtsp://192.168.1.10:8554/light/3/4/-2;seq=17664;rtptime=1431673241\r\n"));

    let a = r.ask(&with_session("TEARDOWN", id, 9));
    assert_eq!(a.text, "RTSP/1.0 200 OK\r\nCSeq: 9\r\n\r\n");
    assert_eq!(r.calls(), [Call::Play(id), Call::End(id, EndReason::Teardown)]);
    assert!(r.server.sessions().is_empty());
    assert_eq!(r.ask(&with_session("PLAY", id, 10)).status, Status::SessionNotFound);
}

#[test]
fn setup_again_applies_a_new_stream_and_transport_to_a_session_not_playing() {
    let mut r = Rig::new();
    let id = r.setup(URL);
    r.ask(&with_session("PLAY", id, 4));
    r.ask(&with_session("PAUSE", id, 5));
    r.calls();
    let h = format!("Session: {id}\r\nTransport: RTP/AVP/TCP;unicast;interleaved=2-3\r\n");
    let a = r.ask(&request("SETUP", "rtsp://h/orbit?fps=10/trackID=0", 6, &h));
    assert!(a.text.contains("Transport: RTP/AVP/TCP;unicast;interleaved=2-3;ssrc="), "{}", a.text);
    let tcp = Transport::Interleaved { rtp_channel: 2, rtcp_channel: 3 };
    assert!(matches!(r.calls()[..], [Call::Setup(s, spec, t, ..)] if s == id && t == tcp && spec.fps == Fps::Rate(10)));
    let s = r.server.session(id).unwrap();
    assert_eq!((s.transport(), s.url()), (tcp, "rtsp://h/orbit?fps=10/trackID=0"));
    assert_eq!(r.server.sessions().len(), 1);
    // A sender that cannot take it: the answer is its status, the session keeps what it had.
    r.streams.refuse_setup = Some(Status::NotEnoughBandwidth);
    let h = format!("Session: {id}\r\nTransport: RTP/AVP;multicast\r\n");
    assert_eq!(r.ask(&request("SETUP", URL, 7, &h)).status, Status::NotEnoughBandwidth);
    assert_eq!(r.server.session(id).unwrap().transport(), tcp);
    r.streams.refuse_setup = None;
    r.ask(&with_session("PLAY", id, 8));
    let h = format!("Session: {id}\r\nTransport: RTP/AVP;unicast;client_port=7000\r\n");
    assert_eq!(r.ask(&request("SETUP", URL, 9, &h)).status, Status::MethodNotValidInThisState, "playing");
}

#[test]
fn interleaved_and_multicast_setups_are_answered_with_their_parameters() {
    let mut r = Rig::new();
    let a = r.ask(&request("SETUP", URL, 1, "Transport: RTP/AVP/TCP;unicast;interleaved=0-1\r\n"));
    assert!(a.text.contains("Transport: RTP/AVP/TCP;unicast;interleaved=0-1;ssrc=11111111\r\n"), "{}", a.text);
    // A second interleaved session on the same connection gets other channels.
    let a = r.ask(&request("SETUP", "rtsp://h/orbit", 2, "Transport: RTP/AVP/TCP;unicast;interleaved=0-1\r\n"));
    assert!(a.text.contains("interleaved=2-3;"), "{}", a.text);
    let a = r.ask(&request("SETUP", URL, 3, "Transport: RTP/AVP;multicast;ttl=127\r\n"));
    assert!(
        a.text.contains(
            "Transport: RTP/AVP;multicast;destination=239.255.42.1;port=5006-5007;ttl=1;server_port=5004-5005;ssrc="
        ),
        "the sender's group, whatever the client asked: {}",
        a.text
    );
    // (From another host: one address holds SESSIONS_PER_ADDRESS.)
    let other = r.connect(OTHER);
    let a =
        r.send_on(other, request("SETUP", URL, 4, "Transport: RTP/AVPF;unicast;client_port=9000-9001\r\n").as_bytes());
    assert!(a[0].text.contains("Transport: RTP/AVPF;unicast;client_port=9000-9001;"), "{}", a[0].text);
}

/// Inside the connection the answer is plain AVP, whatever the client
/// asked: an AVPF answer turns GStreamer's retransmission timers on, which
/// drop rows a slow TCP reader only got late.
#[test]
fn an_interleaved_setup_is_answered_with_the_avp_profile() {
    let mut r = Rig::new();
    let a = r.ask(&request("SETUP", URL, 1, "Transport: RTP/AVPF/TCP;unicast;interleaved=0-1\r\n"));
    assert!(a.text.contains("Transport: RTP/AVP/TCP;unicast;interleaved=0-1;"), "{}", a.text);
}

#[test]
fn interleaved_rtcp_goes_to_its_session_and_keeps_it_alive() {
    let mut r = Rig::new();
    let a = r.ask(&request("SETUP", URL, 1, "Transport: RTP/AVP/TCP;interleaved=4-5\r\n"));
    let id = session_of(&a.text);
    r.calls();
    r.now = at(50_000);
    let mut bytes = b"$\x05\x00\x08RRRRRRRR$\x04\x00\x02xx".to_vec();
    bytes.extend_from_slice(with_session("PLAY", id, 2).as_bytes());
    let answers = r.send_on(0, &bytes);
    assert_eq!(answers.len(), 1, "the PLAY after the binary data");
    assert_eq!(r.calls(), [Call::Rtcp(id, b"RRRRRRRR".to_vec()), Call::Play(id)], "RTP on channel 4 is dropped");
    assert_eq!(r.server.next_deadline(), Some(at(110_000)));
    // The session ends with its connection; a UDP one would live on.
    let udp = r.setup(URL);
    r.calls();
    assert_eq!(r.server.connection_closed(ConnId(0), &mut r.streams), 1);
    assert_eq!(r.calls(), [Call::End(id, EndReason::ConnectionClosed)]);
    assert!(r.server.session(udp).is_some());
}

#[test]
fn get_parameter_keeps_a_session_alive() {
    let mut r = Rig::new();
    let a = r.ask(&request("GET_PARAMETER", URL, 2, ""));
    assert_eq!(a.text, "RTSP/1.0 200 OK\r\nCSeq: 2\r\n\r\n");
    let id = r.setup(URL);
    r.ask(&with_session("PLAY", id, 3));
    r.now = at(59_000);
    let a = r.ask(&with_session("GET_PARAMETER", id, 4));
    assert_eq!(a.text, format!("RTSP/1.0 200 OK\r\nCSeq: 4\r\nSession: {id};timeout=60\r\n\r\n"));
    assert_eq!(r.server.next_deadline(), Some(at(119_000)));
    assert_eq!(r.server.poll(at(118_999), &mut r.streams), None);
    assert_eq!(r.server.poll(at(119_000), &mut r.streams), Some(id));
    assert_eq!(r.calls().last(), Some(&Call::End(id, EndReason::Timeout)));
}

#[test]
fn set_parameter_moves_a_live_light() {
    let mut r = Rig::new();
    let id = r.setup("rtsp://h/live");
    r.calls();
    let body = "light: 1.5,6,-2.25\r\n";
    let h = format!("Session: {id}\r\nContent-Type: text/parameters\r\nContent-Length: {}\r\n", body.len());
    let a = r.ask(&format!("{}{body}", request("SET_PARAMETER", "rtsp://h/live", 4, &h)));
    assert_eq!(a.text, format!("RTSP/1.0 200 OK\r\nCSeq: 4\r\nSession: {id};timeout=60\r\n\r\n"));
    assert_eq!(r.calls(), [Call::SetLight(id, light(1.5, 6.0, -2.25))]);
    // An empty body is a keep-alive, with or without a session.
    let a = r.ask(&request("SET_PARAMETER", "rtsp://h/live", 6, "Content-Length: 0\r\n"));
    assert_eq!(a.status, Status::Ok);
    let set = |id: Option<SessionId>, body: &str| {
        let s = id.map(|id| format!("Session: {id}\r\n")).unwrap_or_default();
        format!("SET_PARAMETER rtsp://h/live RTSP/1.0\r\nCSeq: 7\r\n{s}Content-Length: {}\r\n\r\n{body}", body.len())
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
    assert!(!r.calls().iter().any(|c| matches!(c, Call::SetLight(..))), "no light moved by the failures");
}

// ---- Errors ----

/// The status of one request on a fresh server.
fn status_of(request: &str) -> (Status, Text) {
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
    let bytes = b"OPTIONS * RTSP/1.0\r\nCSeq: 1\r\nX: \xff\xfe\r\n\r\n".to_vec();
    let mut r = Rig::new();
    assert_eq!(r.send_on(0, &bytes)[0].text, "RTSP/1.0 400 Bad Request\r\n\r\n", "not UTF-8");
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
        (request("SETUP", URL, 1, "Transport: RTP/AVP;unicast\r\n"), "461 Unsupported Transport"),
        (request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=0-1\r\n"), "461 Unsupported Transport"),
        (request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=65535\r\n"), "461 Unsupported Transport"),
        (
            request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=6000-6001;mode=record\r\n"),
            "461 Unsupported Transport",
        ),
        (
            request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=6000;destination=10.1.1.1\r\n"),
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
    // The sender's refusal is the answer.
    let mut r = Rig::new();
    r.streams.refuse_setup = Some(Status::UnsupportedTransport);
    assert_eq!(
        r.ask(&request("SETUP", URL, 1, "Transport: RTP/AVP;multicast\r\n")).status,
        Status::UnsupportedTransport
    );
    assert!(r.server.sessions().is_empty());
}

#[test]
fn a_server_without_udp_offers_rtp_inside_the_connection_only() {
    let mut r = Rig::new();
    r.server = Server::new(Config { udp: false, ..config() });
    for transport in ["RTP/AVP;unicast;client_port=6000-6001", "RTP/AVP;multicast"] {
        let a = r.ask(&request("SETUP", URL, 1, &format!("Transport: {transport}\r\n")));
        assert_eq!(a.status, Status::UnsupportedTransport, "{transport}");
    }
    assert!(r.streams.calls.is_empty(), "the sender was never asked");
    let a = r.ask(&request("SETUP", URL, 2, "Transport: RTP/AVP/TCP;interleaved=0-1\r\n"));
    assert_eq!(a.status, Status::Ok, "{}", a.text);
}

#[test]
fn a_session_belongs_to_the_address_that_set_it_up() {
    let mut r = Rig::new();
    let id = r.setup(URL);
    let other = r.connect(OTHER);
    for method in ["PLAY", "PAUSE", "TEARDOWN", "GET_PARAMETER"] {
        let a = r.send_on(other, with_session(method, id, 9).as_bytes());
        assert_eq!(a[0].status, Status::SessionNotFound, "{method} from elsewhere");
    }
    // Another connection from the same address may use it, and owns it then.
    let again = r.connect(CLIENT);
    assert_eq!(r.send_on(again, with_session("PLAY", id, 10).as_bytes())[0].status, Status::Ok);
    assert_eq!(r.server.session(id).unwrap().client().conn, ConnId(again as u32));
}

#[test]
fn the_session_cap_answers_453() {
    let mut r = Rig::new();
    let mut ids: Vec<SessionId> = (0..SESSIONS_PER_ADDRESS).map(|_| r.setup(URL)).collect();
    ids.push(r.setup_from_host(0, URL));
    assert_eq!(ids.len(), MAX_SESSIONS);
    let transport = "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n";
    let c = r.connect(OTHER);
    let a = r.send_on(c, request("SETUP", URL, 7, transport).as_bytes());
    assert_eq!(a[0].text, "RTSP/1.0 453 Not Enough Bandwidth\r\nCSeq: 7\r\n\r\n");
    assert_eq!(r.server.sessions().len(), MAX_SESSIONS);
    // Re-SETUP of an open session is no new one.
    assert_eq!(r.ask(&request("SETUP", URL, 8, &format!("{transport}Session: {}\r\n", ids[1]))).status, Status::Ok);
    r.ask(&with_session("TEARDOWN", ids[0], 9));
    assert_eq!(r.ask(&request("SETUP", URL, 10, transport)).status, Status::Ok);
    let distinct: std::collections::HashSet<_> = r.server.sessions().iter().map(Session::id).collect();
    assert_eq!(distinct.len(), MAX_SESSIONS);
}

#[test]
fn a_random_source_stuck_on_one_value_gives_no_shared_session() {
    let mut server: Server = Server::new(config());
    let mut conn = Connection::new(ConnId(0), CLIENT, at(0));
    let mut stuck = || 7u32;
    let mut streams = Recorder::default();
    let mut out = [0u8; MAX_RESPONSE_BYTES];
    let req = request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n");
    let mut statuses = vec![];
    for _ in 0..2 {
        conn.receive(at(0), req.as_bytes());
        statuses.push(server.handle(&mut conn, at(0), &mut stuck, &mut streams, &mut out).unwrap().status);
    }
    assert_eq!(statuses, [Status::Ok, Status::NotEnoughBandwidth]);
}

// ---- Time ----

#[test]
fn sessions_time_out_after_60_s_unheard() {
    let mut r = Rig::new();
    r.now = at(10_000);
    let a = r.setup(URL);
    r.ask(&with_session("PLAY", a, 4));
    r.now = at(20_000);
    let b = r.setup("rtsp://h/live");
    r.ask(&with_session("PLAY", b, 4));
    assert_eq!(r.server.next_deadline(), Some(at(70_000)));
    // Requests naming a session and RTCP from its client refresh it.
    r.now = at(69_999);
    r.ask(&with_session("OPTIONS", a, 5));
    let rr = [0x80, 201, 0, 1, 0, 0, 0, 1];
    assert_eq!(r.server.rtcp_received(at(74_000), CLIENT, 6001, b"\x80not RTCP"), None, "not RTCP: no refresh");
    assert_eq!(r.server.rtcp_received(at(74_000), CLIENT, 6001, &rr[..6]), None, "cut short");
    assert_eq!(r.server.rtcp_received(at(75_000), CLIENT, 6001, &rr), Some(a));
    assert_eq!(r.server.rtcp_received(at(75_000), OTHER, 6001, &rr), None, "not its client");
    assert_eq!(r.server.rtcp_received(at(75_000), CLIENT, 40_123, &rr), Some(a), "a port a NAT gave it");
    assert_eq!(r.server.poll(at(79_999), &mut r.streams), None);
    assert_eq!(r.server.poll(at(80_000), &mut r.streams), Some(b));
    assert_eq!(r.server.poll(at(80_000), &mut r.streams), None);
    assert_eq!(r.server.next_deadline(), Some(at(135_000)));
    assert_eq!(r.server.poll(at(135_000), &mut r.streams), Some(a));
    assert_eq!(r.server.next_deadline(), None);
    assert_eq!(r.ask(&with_session("PLAY", a, 6)).status, Status::SessionNotFound);
    // The binding may drop a session itself (its client is gone).
    let c = r.setup(URL);
    assert!(r.server.remove(c));
    assert!(!r.server.remove(c));
    assert_eq!(r.server.poll(at(u64::MAX), &mut r.streams), None);
}

#[test]
fn an_unfinished_request_and_an_idle_connection_without_a_session_expire() {
    let mut r = Rig::new();
    // Half a request at 1 s: closed 5 s later.
    r.now = at(1_000);
    r.send_on(0, b"OPTIONS * RTSP/1.0\r\nCSe");
    assert!(!r.server.connection_expired(&r.conns[0], at(5_999)));
    assert_eq!(r.server.connection_deadline(&r.conns[0]), at(6_000));
    assert!(r.server.connection_expired(&r.conns[0], at(6_000)));
    // Finished in time: no longer unfinished, but idle without a session.
    r.send_on(0, b"q: 1\r\n\r\n");
    assert!(!r.server.connection_expired(&r.conns[0], at(10_999)));
    assert!(r.server.connection_expired(&r.conns[0], at(11_000)), "10 s after its last request");
    // A connection that owns a session is not idle; it ends with the session.
    let c = r.connect(CLIENT);
    let a = r.send_on(c, request("SETUP", URL, 1, "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n").as_bytes());
    let id = session_of(&a[0].text);
    r.send_on(c, with_session("PLAY", id, 2).as_bytes());
    assert!(!r.server.connection_expired(&r.conns[c], at(50_000)));
    r.server.remove(id);
    assert!(r.server.connection_expired(&r.conns[c], at(50_000)));
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
    assert_eq!(answers.len(), 4, "{answers:?}");
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
    r.calls();
    let h = format!("Session: {id}\r\nContent-Length: {}\r\n", body.len());
    // LF-only line ends are accepted too.
    let text = format!("{}{body}", request("SET_PARAMETER", "rtsp://h/live", 4, &h)).replace("\r\n", "\n");
    let mut answers = vec![];
    for b in text.as_bytes() {
        answers.extend(r.send_on(0, &[*b]));
    }
    assert_eq!(answers.len(), 1);
    assert_eq!(r.calls(), [Call::SetLight(id, light(1.0, 2.0, 3.0))]);
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
    assert!(r.server.connection_expired(&r.conns[0], r.now), "the caller closes it");
    let more = b"OPTIONS * RTSP/1.0\r\nCSeq: 2\r\n\r\n";
    assert_eq!(r.conns[0].receive(at(0), more), more.len(), "taken and dropped");
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
    let mut url = Text::from("rtsp://255.255.255.255:8554/orbit?multicast&fps=1000&radius=1.");
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
    r.streams.position = Some(Position { seq: u16::MAX, rtptime: u32::MAX, media_ticks: u64::MAX / 100 });
    let a = r.ask(&request("PLAY", &url, 1_234_567_890, &format!("Session: {id}\r\n")));
    assert_eq!(a.status, Status::Ok, "{}", a.text);
    let a = r.ask(&request("SETUP", &url, 1_234_567_890, "Transport: RTP/AVPF;multicast\r\n"));
    assert_eq!(a.status, Status::Ok, "{}", a.text);
}

/// GStreamer and FFmpeg take `seq` and `rtptime` from `RTP-Info` only when
/// its `url` is, byte for byte, the URL they set the stream up with: the
/// SDP's `a=control`. Neither percent-decodes, so that URL must need no
/// escaping in the header (no `,` or `;`).
#[test]
fn rtp_info_names_the_stream_by_the_sdps_control_url_byte_for_byte() {
    for url in [
        URL,
        "rtsp://192.168.1.10:8554/light/1.5,-2,0.25?fps=max",
        "rtsp://h/orbit?fps=10&radius=3",
        "rtsp://h/light/3%2C4%2C-2",
    ] {
        let mut r = Rig::new();
        let a = r.ask(&request("DESCRIBE", url, 1, ""));
        let control = a.text.lines().find_map(|l| l.strip_prefix("a=control:")).expect("a=control").to_string();
        assert!(!control.contains([',', ';', '%', ' ']), "{url}: {control} needs escaping");
        let a = r.ask(&request("SETUP", &control, 2, "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n"));
        assert!(a.text.starts_with("RTSP/1.0 200 OK\r\n"), "{url}: SETUP {control}: {}", a.text);
        let id =
            SessionId::parse(a.text.lines().find_map(|l| l.strip_prefix("Session: ")).expect("Session")).expect("id");
        let a = r.ask(&request("PLAY", &control, 3, &format!("Session: {id}\r\n")));
        let info = a.text.lines().find_map(|l| l.strip_prefix("RTP-Info: url=")).expect("RTP-Info");
        let info_url = info.split(';').next().expect("url");
        assert_eq!(info_url, control, "{url}");
        assert_eq!(
            StreamSpec::parse(&control).expect("the control URL parses"),
            StreamSpec::parse(url).expect("the URL parses"),
            "{url}: the control URL names the same stream"
        );
    }
}

/// RFC 2326 section 12.32: a `Require` the server does not support is
/// answered 551 with the options in `Unsupported`, and nothing is done.
#[test]
fn a_required_option_is_refused_551_and_named() {
    let mut r = Rig::new();
    let a = r.ask(&request(
        "SETUP",
        URL,
        5,
        "Require: com.example.thing\r\nTransport: RTP/AVP;unicast;client_port=6000-6001\r\n",
    ));
    assert_eq!(a.text, "RTSP/1.0 551 Option not supported\r\nCSeq: 5\r\nUnsupported: com.example.thing\r\n\r\n");
    assert!(r.calls().is_empty(), "no session set up");
}

/// One address that sets up every session and plays none cannot keep
/// others out: a session never played ends 15 s after it was last heard
/// of, and with every place taken a new SETUP takes the place of the one
/// heard of longest ago, once it is 2 s old.
#[test]
fn sessions_set_up_and_never_played_give_their_places_to_a_new_viewer() {
    let mut r = Rig::new();
    let hoarded: Vec<SessionId> = (0..MAX_SESSIONS as u64)
        .map(|k| {
            r.now = at(k * 100);
            r.setup_from_host(k as u8, URL)
        })
        .collect();
    r.calls();
    r.now = at(1_000);
    let a = r.ask(&request("SETUP", URL, 9, "Transport: RTP/AVP;unicast;client_port=7000-7001\r\n"));
    assert_eq!(a.status, Status::NotEnoughBandwidth, "a player between SETUP and PLAY keeps its place");
    r.now = at(2_500);
    let a = r.ask(&request("SETUP", URL, 10, "Transport: RTP/AVP;unicast;client_port=7000-7001\r\n"));
    assert_eq!(a.status, Status::Ok, "{}", a.text);
    let calls = r.calls();
    assert_eq!(calls.first(), Some(&Call::End(hoarded[0], EndReason::Reclaimed)), "the oldest: {calls:?}");
    assert!(r.server.session(hoarded[0]).is_none());
    // A session that plays is never reclaimed, and one never played times
    // out in 15 s.
    let fresh = session_of(&a.text);
    r.ask(&with_session("PLAY", fresh, 11));
    assert_eq!(r.server.next_deadline(), Some(at(100) + UNPLAYED_TIMEOUT), "the next oldest never played");
    r.now = at(20_000);
    for k in 0..3 {
        r.setup_from_host(10 + k, URL);
    }
    let c = r.connect(OTHER);
    let a =
        &r.send_on(c, request("SETUP", URL, 20, "Transport: RTP/AVP;unicast;client_port=7004-7005\r\n").as_bytes())[0];
    assert_eq!(a.status, Status::NotEnoughBandwidth, "the playing one keeps its place; the rest are new");
    assert!(r.server.session(fresh).is_some());
}

/// Issue 34, item 10: one host cannot hold every place. Four SETUPs with
/// no PLAY from one address take [`SESSIONS_PER_ADDRESS`] places at most
/// (the one over its cap takes the place of that address's own oldest
/// never-played session, or gets 453), so a SETUP from another address
/// gets 200 at once.
#[test]
fn one_address_holds_at_most_its_cap_of_sessions() {
    let mut r = Rig::new();
    let transport = "Transport: RTP/AVP;unicast;client_port=6000-6001\r\n";
    let statuses: Vec<Status> = (0..4).map(|k| r.ask(&request("SETUP", URL, 1 + k, transport)).status).collect();
    assert_eq!(statuses, [Status::Ok, Status::Ok, Status::Ok, Status::NotEnoughBandwidth]);
    assert_eq!(r.server.sessions().len(), SESSIONS_PER_ADDRESS);
    let other = r.connect(OTHER);
    let a = r.send_on(other, request("SETUP", URL, 1, transport).as_bytes());
    assert_eq!(a[0].status, Status::Ok, "{}", a[0].text);
    // Over its cap once its own oldest never-played session is old enough:
    // that one gives its place, the other address's session stays.
    let first = r.server.sessions().iter().find(|s| s.client().addr == CLIENT).unwrap().id();
    r.calls();
    r.now = at(RECLAIM_AFTER.as_millis() as u64);
    assert_eq!(r.ask(&request("SETUP", URL, 9, transport)).status, Status::Ok);
    assert_eq!(r.calls().first(), Some(&Call::End(first, EndReason::Reclaimed)));
    let from = |addr| r.server.sessions().iter().filter(|s| s.client().addr == addr).count();
    assert_eq!((from(CLIENT), from(OTHER)), (SESSIONS_PER_ADDRESS, 1));
}

/// Connections too: an address with [`CONNECTIONS_PER_ADDRESS`] open gets
/// no more, another address does.
#[test]
fn one_address_holds_at_most_its_cap_of_connections() {
    let open = [CLIENT; CONNECTIONS_PER_ADDRESS];
    assert!(admits(open[1..].iter().copied(), CLIENT));
    assert!(!admits(open.iter().copied(), CLIENT));
    assert!(admits(open.iter().copied(), OTHER));
}

/// Owning a session that never played keeps no connection past its idle
/// deadline (an address could hold sockets with sessions it never plays);
/// one whose session played is kept while the session lives.
#[test]
fn only_a_played_session_keeps_its_connection_past_the_idle_deadline() {
    let mut r = Rig::new();
    let id = r.setup(URL);
    assert!(r.server.connection_expired(&r.conns[0], at(IDLE_DEADLINE.as_millis() as u64)));
    r.ask(&with_session("PLAY", id, 4));
    assert!(!r.server.connection_expired(&r.conns[0], at(50_000)));
}
