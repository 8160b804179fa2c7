//! The board as a network camera, from the client's side: an RTSP/1.0
//! client (RFC 2326) for `rt_services::camera::rtsp`'s server, and the RTP/RTCP
//! sockets feeding `rt_services::camera::receiver`.
//!
//! [`Response::parse`] and the header helpers are pure (tested on canned
//! answers); [`RtspClient`] adds the TCP connection, [`RtpStream`] the two
//! UDP sockets, the receiver and the keep-alive. Everything the server
//! sends is checked: a refusal shows its status line, a malformed or
//! oversized answer is an error, nothing panics, every wait has a timeout.

use std::fmt;
use std::io::{self, Read, Write};
use std::net::{IpAddr, SocketAddr, TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use model::Light;
use rt_services::camera::receiver::{Quality, ReceivedFrame, Receiver, ReceiverConfig, ReceiverCounts, MAX_NACK_BYTES};
use rt_services::camera::rtsp::RTSP_PORT;
use rt_services::camera::wire::rtcp;
use rt_services::camera::wire::rtp::PACKET_BYTES;

/// How long the server may take to answer a request.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(10);
/// How long the stream may go without a packet before the client gives up.
pub const STREAM_TIMEOUT: Duration = Duration::from_secs(5);
/// The longest header block accepted from the server.
const MAX_HEADER_BYTES: usize = 16 * 1024;
/// The longest body accepted from the server (an SDP is well under 1 KB).
const MAX_BODY_BYTES: usize = 64 * 1024;
/// A keep-alive this often: well inside the server's 60 s session timeout
/// (`rt_services::camera::rtsp::SESSION_TIMEOUT`), even if it announces less.
const KEEPALIVE: Duration = Duration::from_secs(20);
/// Our SSRC in NACKs; the server keys sessions on our address, not this.
const CLIENT_SSRC: u32 = 0x7274_636c; // "rtcl"

/// A receiver report this often (RFC 3550's 5 s minimum, halved: reports
/// are small, and the server takes a player that falls silent for 20 s
/// as gone).
const REPORT_EVERY: Duration = Duration::from_millis(2_500);

/// Why an RTSP exchange or stream failed, worded for one terminal line.
#[derive(Debug)]
pub enum RtspError {
    /// A socket operation failed.
    Io(String, io::Error),
    /// The server answered a request with a non-2xx status.
    Refused {
        /// The request's method.
        method: &'static str,
        /// The answer's status line, as sent.
        status_line: String,
    },
    /// The server's answer broke the protocol.
    Protocol(String),
    /// No packet for [`STREAM_TIMEOUT`].
    Stalled(Duration),
}

impl fmt::Display for RtspError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RtspError::Io(what, e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                write!(f, "{what}: no answer from the server within {} s", ANSWER_TIMEOUT.as_secs())
            }
            RtspError::Io(what, e) if e.kind() == io::ErrorKind::ConnectionRefused => {
                write!(f, "{what}: connection refused: is the server's RTSP port open?")
            }
            RtspError::Io(what, e) => write!(f, "{what}: {e}"),
            RtspError::Refused { method, status_line } => write!(f, "the server refused {method}: {status_line}"),
            RtspError::Protocol(why) => write!(f, "RTSP: {why}"),
            RtspError::Stalled(d) => write!(f, "no RTP packet for {:.1} s: the stream stalled", d.as_secs_f64()),
        }
    }
}

impl std::error::Error for RtspError {}

fn io_error(what: impl Into<String>) -> impl FnOnce(io::Error) -> RtspError {
    let what = what.into();
    move |e| RtspError::Io(what, e)
}

// ---- Answers ---------------------------------------------------------------------

/// One RTSP answer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Response {
    /// The status line (`RTSP/1.0 200 OK`).
    pub status_line: String,
    /// The status code.
    pub status: u16,
    headers: Vec<(String, String)>,
    /// The body (`Content-Length` bytes; UTF-8, lossily).
    pub body: String,
}

impl Response {
    /// The first answer in `buf`: `Ok(None)` while it is incomplete,
    /// otherwise the answer and the bytes it took.
    pub fn parse(buf: &[u8]) -> Result<Option<(Response, usize)>, RtspError> {
        let Some(head_end) = buf.windows(4).position(|w| w == b"\r\n\r\n") else {
            return if buf.len() > MAX_HEADER_BYTES {
                Err(RtspError::Protocol(format!("an answer's header block exceeds {MAX_HEADER_BYTES} bytes")))
            } else {
                Ok(None)
            };
        };
        let head = String::from_utf8_lossy(&buf[..head_end]);
        let mut lines = head.split("\r\n");
        let status_line = lines.next().unwrap_or_default().to_string();
        let mut parts = status_line.splitn(3, ' ');
        let version = parts.next().unwrap_or_default();
        let code = parts.next().unwrap_or_default();
        if version != "RTSP/1.0" || code.len() != 3 || !code.bytes().all(|b| b.is_ascii_digit()) {
            return Err(RtspError::Protocol(format!("not an RTSP/1.0 status line: {:?}", clip(&status_line))));
        }
        let status = code.parse().map_err(|_| RtspError::Protocol("bad status code".into()))?;
        let mut headers = Vec::new();
        for line in lines {
            let (name, value) = line
                .split_once(':')
                .ok_or_else(|| RtspError::Protocol(format!("malformed header line {:?}", clip(line))))?;
            headers.push((name.trim().to_string(), value.trim().to_string()));
        }
        let mut response = Response { status_line, status, headers, body: String::new() };
        let length = match response.header("Content-Length") {
            None => 0,
            Some(v) => v
                .parse::<usize>()
                .ok()
                .filter(|&n| n <= MAX_BODY_BYTES)
                .ok_or_else(|| RtspError::Protocol(format!("bad Content-Length {:?}", clip(v))))?,
        };
        let body_start = head_end + 4;
        let Some(body) = buf.get(body_start..body_start + length) else {
            return Ok(None);
        };
        response.body = String::from_utf8_lossy(body).into_owned();
        Ok(Some((response, body_start + length)))
    }

    /// The value of header `name` (any case), if present.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }

    /// The `CSeq`, if present and a number.
    pub fn cseq(&self) -> Option<u32> {
        self.header("CSeq")?.parse().ok()
    }
}

/// The first 80 characters of peer text, for error messages.
fn clip(s: &str) -> String {
    s.chars().take(80).collect()
}

/// The session identifier of a `Session` header (`ID;timeout=60` → `ID`).
pub fn session_id(value: &str) -> Option<&str> {
    let id = value.split(';').next()?.trim();
    (!id.is_empty() && id.bytes().all(|b| b.is_ascii_graphic())).then_some(id)
}

/// The `timeout=` of a `Session` header, if it announces one.
pub fn session_timeout(value: &str) -> Option<Duration> {
    value.split(';').skip(1).find_map(|p| p.trim().strip_prefix("timeout=")?.parse().ok()).map(Duration::from_secs)
}

/// The `server_port=a-b` of a `Transport` header.
pub fn server_ports(transport: &str) -> Option<(u16, u16)> {
    let spec = transport.split(';').find_map(|p| p.trim().strip_prefix("server_port="))?;
    let (a, b) = spec.split_once('-')?;
    Some((a.parse().ok()?, b.parse().ok()?))
}

/// The `ssrc=` of a `Transport` header (hexadecimal).
pub fn transport_ssrc(transport: &str) -> Option<u32> {
    let hex = transport.split(';').find_map(|p| p.trim().strip_prefix("ssrc="))?;
    u32::from_str_radix(hex, 16).ok()
}

/// Where a `PLAY` starts: the `seq` and `rtptime` of an `RTP-Info` header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RtpInfo {
    /// The first packet's sequence number (low 16 bits).
    pub seq: u16,
    /// The first frame's RTP timestamp.
    pub rtptime: u32,
}

/// The first stream's `seq` and `rtptime` in an `RTP-Info` header.
///
/// Streams are separated by commas, but a stream URL may hold commas too
/// (`/light/3,4,-2`), so the first `seq=` and `rtptime=` are taken, each
/// ending where its digits do.
pub fn rtp_info(value: &str) -> Option<RtpInfo> {
    let field = |name: &str| {
        let v = value.split(';').find_map(|p| p.trim().strip_prefix(name))?;
        Some(v.find(|c: char| !c.is_ascii_digit()).map_or(v, |end| &v[..end]))
    };
    Some(RtpInfo { seq: field("seq=")?.parse().ok()?, rtptime: field("rtptime=")?.parse().ok()? })
}

/// The URL to `SETUP`: the SDP's `a=control` (absolute, or relative to
/// `base`), else `base` itself.
pub fn control_url(base: &str, sdp: &str) -> String {
    match sdp.lines().find_map(|l| l.trim().strip_prefix("a=control:")) {
        Some(c) if c.contains("://") => c.to_string(),
        Some("*") | None => base.to_string(),
        Some(c) => format!("{}/{c}", base.trim_end_matches('/')),
    }
}

/// The `SET_PARAMETER` body moving a live stream's light, world units.
pub fn light_body(light: &Light) -> String {
    let [x, y, z] = light.raw().map(|r| f64::from(r) / 1024.0);
    format!("light: {x},{y},{z}\r\n")
}

// ---- URLs ---------------------------------------------------------------------------

/// The RTSP server of a `--server HOST:PORT` frame port: the same host,
/// port [`RTSP_PORT`].
pub fn rtsp_addr_of(frame_addr: SocketAddr) -> SocketAddr {
    SocketAddr::new(frame_addr.ip(), RTSP_PORT)
}

/// `rtsp://ADDR` + `path`, with an IPv6 host bracketed.
pub fn stream_url(addr: SocketAddr, path: &str) -> String {
    format!("rtsp://{addr}{path}")
}

// ---- The control connection -------------------------------------------------------------

/// An RTSP control connection with at most one session.
pub struct RtspClient {
    stream: TcpStream,
    buf: Vec<u8>,
    cseq: u32,
    session: Option<String>,
    /// The server's announced session timeout.
    pub timeout: Option<Duration>,
}

/// What `SETUP` agreed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setup {
    /// The server's RTP and RTCP ports.
    pub server_ports: (u16, u16),
    /// The stream's SSRC, if announced.
    pub ssrc: Option<u32>,
}

impl RtspClient {
    /// Connect to the RTSP server at `addr`.
    pub fn connect(addr: SocketAddr) -> Result<RtspClient, RtspError> {
        let what = format!("connecting to RTSP server {addr}");
        let stream = TcpStream::connect_timeout(&addr, ANSWER_TIMEOUT).map_err(io_error(what.clone()))?;
        stream.set_read_timeout(Some(ANSWER_TIMEOUT)).map_err(io_error(what.clone()))?;
        stream.set_write_timeout(Some(ANSWER_TIMEOUT)).map_err(io_error(what))?;
        let _ = stream.set_nodelay(true);
        Ok(RtspClient { stream, buf: Vec::new(), cseq: 0, session: None, timeout: None })
    }

    /// The peer's address.
    pub fn peer(&self) -> Result<SocketAddr, RtspError> {
        self.stream.peer_addr().map_err(io_error("RTSP connection"))
    }

    /// Send `method` for `url` with extra header lines `headers` (each
    /// ending in CRLF) and an optional `(content type, body)`; the answer
    /// if it is 2xx.
    pub fn request(
        &mut self,
        method: &'static str,
        url: &str,
        headers: &str,
        body: Option<(&str, &str)>,
    ) -> Result<Response, RtspError> {
        self.cseq += 1;
        let mut req = format!("{method} {url} RTSP/1.0\r\nCSeq: {}\r\nUser-Agent: rt-client\r\n", self.cseq);
        if let Some(s) = &self.session {
            req.push_str(&format!("Session: {s}\r\n"));
        }
        req.push_str(headers);
        match body {
            Some((ctype, b)) => {
                req.push_str(&format!("Content-Type: {ctype}\r\nContent-Length: {}\r\n\r\n{b}", b.len()))
            }
            None => req.push_str("\r\n"),
        }
        self.stream.write_all(req.as_bytes()).map_err(io_error(format!("sending {method}")))?;
        let answer = self.read_answer(method)?;
        if answer.cseq() != Some(self.cseq) {
            return Err(RtspError::Protocol(format!(
                "the answer to {method} has CSeq {:?}, not {}",
                answer.cseq(),
                self.cseq
            )));
        }
        if !(200..300).contains(&answer.status) {
            return Err(RtspError::Refused { method, status_line: clip(&answer.status_line) });
        }
        if let Some(s) = answer.header("Session") {
            self.timeout = session_timeout(s).or(self.timeout);
        }
        Ok(answer)
    }

    fn read_answer(&mut self, method: &'static str) -> Result<Response, RtspError> {
        let mut chunk = [0u8; 4096];
        loop {
            if let Some((answer, used)) = Response::parse(&self.buf)? {
                self.buf.drain(..used);
                return Ok(answer);
            }
            match self.stream.read(&mut chunk) {
                Ok(0) => {
                    return Err(RtspError::Protocol(format!(
                        "the server closed the connection before answering {method}"
                    )))
                }
                Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(RtspError::Io(format!("waiting for the answer to {method}"), e)),
            }
            if self.buf.len() > MAX_HEADER_BYTES + MAX_BODY_BYTES {
                return Err(RtspError::Protocol(format!("the answer to {method} is too long")));
            }
        }
    }

    /// `OPTIONS`: the methods the server offers.
    pub fn options(&mut self, url: &str) -> Result<String, RtspError> {
        Ok(self.request("OPTIONS", url, "", None)?.header("Public").unwrap_or_default().to_string())
    }

    /// `DESCRIBE`: the stream's SDP.
    pub fn describe(&mut self, url: &str) -> Result<String, RtspError> {
        Ok(self.request("DESCRIBE", url, "Accept: application/sdp\r\n", None)?.body)
    }

    /// `SETUP` unicast UDP to our `rtp_port` and `rtp_port + 1`; keeps the
    /// session for the requests after.
    pub fn setup(&mut self, url: &str, rtp_port: u16) -> Result<Setup, RtspError> {
        let transport = format!("Transport: RTP/AVP;unicast;client_port={}-{}\r\n", rtp_port, rtp_port + 1);
        let answer = self.request("SETUP", url, &transport, None)?;
        let session = answer
            .header("Session")
            .and_then(session_id)
            .ok_or_else(|| RtspError::Protocol("SETUP was answered without a Session".into()))?;
        self.session = Some(session.to_string());
        let t = answer.header("Transport").unwrap_or_default();
        let server_ports = server_ports(t)
            .ok_or_else(|| RtspError::Protocol(format!("SETUP's Transport has no server_port: {:?}", clip(t))))?;
        Ok(Setup { server_ports, ssrc: transport_ssrc(t) })
    }

    /// `SETUP` RTP and RTCP inside this connection (RFC 2326 section
    /// 10.12) on channels 0 and 1; keeps the session for the requests
    /// after.
    pub fn setup_interleaved(&mut self, url: &str) -> Result<(), RtspError> {
        let answer = self.request("SETUP", url, "Transport: RTP/AVP/TCP;unicast;interleaved=0-1\r\n", None)?;
        let session = answer
            .header("Session")
            .and_then(session_id)
            .ok_or_else(|| RtspError::Protocol("SETUP was answered without a Session".into()))?;
        self.session = Some(session.to_string());
        Ok(())
    }

    /// The next packet inside the connection (after an interleaved
    /// `PLAY`): its channel and bytes. Waits at most the answer timeout.
    pub fn interleaved_packet(&mut self) -> Result<(u8, Vec<u8>), RtspError> {
        let mut chunk = [0u8; 16 * 1024];
        loop {
            if self.buf.len() >= 4 && self.buf[0] == b'$' {
                let len = usize::from(u16::from_be_bytes([self.buf[2], self.buf[3]]));
                if self.buf.len() >= 4 + len {
                    let channel = self.buf[1];
                    let packet = self.buf[4..4 + len].to_vec();
                    self.buf.drain(..4 + len);
                    return Ok((channel, packet));
                }
            } else if !self.buf.is_empty() && self.buf[0] != b'$' {
                // An RTSP message from the server (a request or a late
                // answer): taken and dropped whole.
                match Response::parse(&self.buf)? {
                    Some((_, used)) => {
                        self.buf.drain(..used);
                        continue;
                    }
                    None if self.buf.len() > MAX_HEADER_BYTES + MAX_BODY_BYTES => {
                        return Err(RtspError::Protocol("neither RTP nor RTSP inside the connection".into()))
                    }
                    None => {}
                }
            }
            match self.stream.read(&mut chunk) {
                Ok(0) => return Err(RtspError::Protocol("the server closed the connection".into())),
                Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(RtspError::Io("waiting for RTP inside the connection".into(), e)),
            }
        }
    }

    /// `PLAY`: where the stream starts, if announced.
    pub fn play(&mut self, url: &str) -> Result<Option<RtpInfo>, RtspError> {
        Ok(self.request("PLAY", url, "Range: npt=0-\r\n", None)?.header("RTP-Info").and_then(rtp_info))
    }

    /// `SET_PARAMETER light: x,y,z` (a `/live` stream's light).
    pub fn set_light(&mut self, url: &str, light: &Light) -> Result<(), RtspError> {
        self.request("SET_PARAMETER", url, "", Some(("text/parameters", &light_body(light)))).map(drop)
    }

    /// An empty `GET_PARAMETER`: keeps the session alive.
    pub fn keep_alive(&mut self, url: &str) -> Result<(), RtspError> {
        self.request("GET_PARAMETER", url, "", None).map(drop)
    }

    /// `TEARDOWN` the session.
    pub fn teardown(&mut self, url: &str) -> Result<(), RtspError> {
        let r = self.request("TEARDOWN", url, "", None).map(drop);
        self.session = None;
        r
    }
}

// ---- The stream --------------------------------------------------------------------------

/// The RTP socket's receive buffer asked for: two frames' 720 packets
/// (about 2.3 KB each in the kernel's accounting). Linux caps it at
/// `net.core.rmem_max` (208 KiB by default: about a third of a frame, so
/// bursts then lose rows for the NACKs to repair); GStreamer's rtspsrc asks
/// for 512 KiB the same way.
pub const RTP_RECEIVE_BUFFER: usize = 2 << 20;

/// A UDP socket on `ip:port` with a receive buffer of
/// [`RTP_RECEIVE_BUFFER`] (as much of it as the kernel grants).
fn bind_rtp(ip: IpAddr, port: u16) -> std::io::Result<UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let addr = std::net::SocketAddr::new(ip, port);
    let socket = Socket::new(Domain::for_address(addr), Type::DGRAM, Some(Protocol::UDP))?;
    // Best effort: a smaller buffer still works, with more repairs.
    let _ = socket.set_recv_buffer_size(RTP_RECEIVE_BUFFER);
    socket.bind(&addr.into())?;
    Ok(socket.into())
}

/// Two UDP sockets on consecutive ports (RTP even by convention, RTCP the
/// next), bound on `ip`.
fn bind_pair(ip: IpAddr) -> Result<(UdpSocket, UdpSocket), RtspError> {
    for _ in 0..32 {
        let rtp = bind_rtp(ip, 0).map_err(io_error("binding the RTP socket"))?;
        let port = rtp.local_addr().map_err(io_error("binding the RTP socket"))?.port();
        if port == u16::MAX {
            continue;
        }
        if let Ok(rtcp) = UdpSocket::bind((ip, port + 1)) {
            return Ok((rtp, rtcp));
        }
    }
    Err(RtspError::Protocol("no two consecutive free UDP ports".into()))
}

/// A playing stream: the control connection, the RTP and RTCP sockets and
/// the receiver reassembling frames.
pub struct RtpStream {
    client: RtspClient,
    url: String,
    rtp: UdpSocket,
    rtcp: UdpSocket,
    server_rtcp: SocketAddr,
    server_ip: IpAddr,
    receiver: Receiver<Vec<u8>, FRAME_BUFFERS>,
    origin: Instant,
    last_packet: Instant,
    last_keepalive: Instant,
    datagram: Vec<u8>,
    /// The SSRC the SETUP answer announced.
    media_ssrc: u32,
    /// When the last receiver report went.
    last_report: Instant,
    /// The last sender report's LSR and when it arrived.
    last_sr: Option<(u32, Instant)>,
}

impl RtpStream {
    /// OPTIONS, DESCRIBE, SETUP and PLAY `url` on the RTSP server at
    /// `addr`.
    pub fn open(addr: SocketAddr, url: &str) -> Result<RtpStream, RtspError> {
        let mut client = RtspClient::connect(addr)?;
        client.options(url)?;
        let sdp = client.describe(url)?;
        let control = control_url(url, &sdp);
        let local = client.stream.local_addr().map_err(io_error("RTSP connection"))?.ip();
        let (rtp, rtcp) = bind_pair(local)?;
        let rtp_port = rtp.local_addr().map_err(io_error("RTP socket"))?.port();
        let setup = client.setup(&control, rtp_port)?;
        let server_ip = client.peer()?.ip();
        client.play(url)?;
        let receiver = new_receiver()?;
        let now = Instant::now();
        Ok(RtpStream {
            client,
            url: url.to_string(),
            rtp,
            rtcp,
            server_rtcp: SocketAddr::new(server_ip, setup.server_ports.1),
            server_ip,
            receiver,
            origin: now,
            last_packet: now,
            last_keepalive: now,
            datagram: vec![0; PACKET_BYTES + 64],
            media_ssrc: setup.ssrc.unwrap_or(0),
            last_report: now,
            last_sr: None,
        })
    }

    /// Counts of frames and packets so far.
    pub fn counts(&self) -> ReceiverCounts {
        self.receiver.counts()
    }

    /// How long repairs took to come after a NACK, as the receiver
    /// estimates it (none before the first repair).
    pub fn repair_delay(&self) -> Option<std::time::Duration> {
        self.receiver.repair_delay()
    }

    fn clock(&self) -> rt_services::Instant {
        rt_services::Instant::from_millis(self.origin.elapsed().as_millis() as u64)
    }

    /// Receive until at least one frame was handed to `on_frame` (or
    /// `wait` passed: then `Ok(0)`); returns the frames handed over. NACKs
    /// and keep-alives go out meanwhile.
    pub fn receive(&mut self, wait: Duration, mut on_frame: impl FnMut(ReceivedFrame<'_>)) -> Result<usize, RtspError> {
        let until = Instant::now() + wait;
        let mut frames = 0;
        let mut nack = [0u8; MAX_NACK_BYTES];
        while frames == 0 {
            let now = Instant::now();
            if now >= until {
                break;
            }
            if now.duration_since(self.last_keepalive) >= KEEPALIVE.min(self.client.timeout.unwrap_or(KEEPALIVE) / 2) {
                self.last_keepalive = now;
                self.client.keep_alive(&self.url)?;
            }
            let t = self.clock();
            let timer = self.receiver.deadline().map(|d| Duration::from_millis(d.millis().saturating_sub(t.millis())));
            let timeout = timer.unwrap_or(Duration::from_millis(100)).min(until - now).max(Duration::from_millis(1));
            self.rtp.set_read_timeout(Some(timeout)).map_err(io_error("RTP socket"))?;
            match self.rtp.recv_from(&mut self.datagram) {
                Ok((n, from)) if from.ip() == self.server_ip => {
                    self.last_packet = Instant::now();
                    let t = self.clock();
                    self.receiver.receive(t, &self.datagram[..n], |f| {
                        frames += 1;
                        on_frame(f)
                    });
                }
                Ok(_) => {} // a stray datagram from elsewhere
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                    ) =>
                {
                    let stalled = self.last_packet.elapsed();
                    if stalled >= STREAM_TIMEOUT {
                        return Err(RtspError::Stalled(stalled));
                    }
                }
                Err(e) => return Err(RtspError::Io("receiving RTP".into(), e)),
            }
            let t = self.clock();
            self.receiver.poll(t, |f| {
                frames += 1;
                on_frame(f)
            });
            while let Some(n) = self.receiver.write_nack(t, &mut nack) {
                // A lost NACK is lost repair, not an error.
                let _ = self.rtcp.send_to(&nack[..n], self.server_rtcp);
            }
            self.report();
        }
        Ok(frames)
    }

    /// Take the server's sender reports in, and send a receiver report
    /// when one is due: it tells the server this player is alive and lets
    /// it measure the round trip (its repairs' pace).
    fn report(&mut self) {
        let mut sr = [0u8; 256];
        let _ = self.rtcp.set_nonblocking(true);
        while let Ok((n, from)) = self.rtcp.recv_from(&mut sr) {
            if let (true, Some(lsr)) = (from.ip() == self.server_ip, rtcp::sender_report_lsr(&sr[..n], self.media_ssrc))
            {
                self.last_sr = Some((lsr, Instant::now()));
            }
        }
        if self.last_report.elapsed() < REPORT_EVERY {
            return;
        }
        self.last_report = Instant::now();
        let (lsr, dlsr) =
            self.last_sr.map_or((0, 0), |(lsr, at)| (lsr, (at.elapsed().as_micros() * 65_536 / 1_000_000) as u32));
        let mut rr = [0u8; rtcp::RECEIVER_REPORT_BYTES];
        if rtcp::write_receiver_report(CLIENT_SSRC, self.media_ssrc, lsr, dlsr, &mut rr).is_ok() {
            let _ = self.rtcp.send_to(&rr, self.server_rtcp);
        }
    }

    /// Move a `/live` stream's light.
    pub fn set_light(&mut self, light: &Light) -> Result<(), RtspError> {
        self.client.set_light(&self.url, light)
    }

    /// Tear the session down (also done, best effort, on drop).
    pub fn close(mut self) -> Result<(), RtspError> {
        self.client.teardown(&self.url)
    }
}

impl Drop for RtpStream {
    fn drop(&mut self) {
        if self.client.session.is_some() {
            let _ = self.client.teardown(&self.url);
        }
    }
}

/// One whole frame of `url` over RTP/UDP from the server at `addr`
/// within `wait` (lost rows asked for again), then `TEARDOWN`.
pub fn fetch_udp_frame(addr: SocketAddr, url: &str, wait: Duration) -> Result<Vec<u8>, RtspError> {
    let mut stream = RtpStream::open(addr, url)?;
    let until = Instant::now() + wait;
    let mut frame = None;
    while frame.is_none() {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break;
        }
        match stream.receive(left, |f| {
            if f.quality != Quality::Damaged {
                frame = Some(f.pixels.to_vec());
            }
        }) {
            Ok(_) => {}
            Err(RtspError::Stalled(_)) => break,
            Err(e) => return Err(e),
        }
    }
    let _ = stream.close();
    frame.ok_or_else(|| RtspError::Protocol(format!("no whole frame over RTP/UDP in {} s", wait.as_secs())))
}

/// Frame buffers of the receiver: seven frames in progress and the last
/// one handed over (4 MB). A frame then waits for its repairs while six
/// newer ones arrive: a board that renders its next frames before it
/// reads the NACK (the emulated board does, on its CPU) answers late, and
/// with two buffers the frame was given up before the repair came.
pub const FRAME_BUFFERS: usize = 8;

/// The receiver every RTP path of the client takes frames from.
fn new_receiver() -> Result<Receiver<Vec<u8>, FRAME_BUFFERS>, RtspError> {
    Receiver::new(ReceiverConfig::new(CLIENT_SSRC), core::array::from_fn(|_| vec![0; model::FRAME_BYTES]))
        .map_err(|e| RtspError::Protocol(e.to_string()))
}

/// One whole frame of `url` over RTP inside the RTSP connection to `addr`
/// within `wait`; the connection is closed after it (the server then ends
/// the session).
pub fn fetch_interleaved_frame(addr: SocketAddr, url: &str, wait: Duration) -> Result<Vec<u8>, RtspError> {
    let mut client = RtspClient::connect(addr)?;
    client.options(url)?;
    let sdp = client.describe(url)?;
    let control = control_url(url, &sdp);
    client.setup_interleaved(&control)?;
    client.play(url)?;
    let mut receiver = new_receiver()?;
    let start = Instant::now();
    let mut frame = None;
    while frame.is_none() && start.elapsed() < wait {
        // No read waits past `wait` (a server that goes silent ends it).
        let left = wait.saturating_sub(start.elapsed()).max(Duration::from_millis(1));
        client.stream.set_read_timeout(Some(left)).map_err(io_error("RTSP connection"))?;
        let (channel, packet) = match client.interleaved_packet() {
            Ok(p) => p,
            Err(RtspError::Io(_, e)) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                break;
            }
            Err(e) => return Err(e),
        };
        if channel != 0 {
            continue;
        }
        let t = rt_services::Instant::from_millis(start.elapsed().as_millis() as u64);
        receiver.receive(t, &packet, |f| {
            if f.quality != Quality::Damaged {
                frame = Some(f.pixels.to_vec());
            }
        });
    }
    frame.ok_or_else(|| {
        RtspError::Protocol(format!("no whole frame inside the RTSP connection in {} s", wait.as_secs()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SETUP_ANSWER: &str = "RTSP/1.0 200 OK\r\nCSeq: 3\r\n\
         Transport: RTP/AVP;unicast;client_port=6000-6001;server_port=5004-5005;ssrc=33333333\r\n\
         Session: 1111111122222222;timeout=60\r\n\r\n";

    #[test]
    fn a_setup_answer_yields_session_ports_and_ssrc() {
        let (r, used) = Response::parse(SETUP_ANSWER.as_bytes()).unwrap().unwrap();
        assert_eq!(used, SETUP_ANSWER.len());
        assert_eq!((r.status, r.cseq()), (200, Some(3)));
        let s = r.header("session").unwrap();
        assert_eq!(session_id(s), Some("1111111122222222"));
        assert_eq!(session_timeout(s), Some(Duration::from_secs(60)));
        let t = r.header("Transport").unwrap();
        assert_eq!(server_ports(t), Some((5004, 5005)));
        assert_eq!(transport_ssrc(t), Some(0x3333_3333));
    }

    #[test]
    fn a_describe_answer_is_read_to_its_content_length_and_no_further() {
        let sdp = "v=0\r\nm=video 0 RTP/AVP 96\r\na=control:rtsp://10.0.0.2:8554/live\r\n";
        let text = format!(
            "RTSP/1.0 200 OK\r\nCSeq: 2\r\nContent-Type: application/sdp\r\nContent-Length: {}\r\n\r\n{sdp}RTSP/1.0 200",
            sdp.len()
        );
        let bytes = text.as_bytes();
        for cut in 0..bytes.len() - 12 {
            assert_eq!(Response::parse(&bytes[..cut]).unwrap(), None, "cut at {cut}");
        }
        let (r, used) = Response::parse(bytes).unwrap().unwrap();
        assert_eq!((r.body.as_str(), used), (sdp, bytes.len() - 12));
        assert_eq!(control_url("rtsp://10.0.0.2:8554/live", &r.body), "rtsp://10.0.0.2:8554/live");
        assert_eq!(control_url("rtsp://h/live/", "a=control:trackID=0\r\n"), "rtsp://h/live/trackID=0");
        assert_eq!(control_url("rtsp://h/live", "a=control:*\r\n"), "rtsp://h/live");
    }

    #[test]
    fn a_play_answer_yields_the_rtp_info() {
        let text = "RTSP/1.0 200 OK\r\nCSeq: 4\r\nSession: 1111111122222222;timeout=60\r\n\
                    RTP-Info: url=rtsp://192.168.1.10:8554/light/3,4,-2;seq=17476;rtptime=1431655765\r\n\r\n";
        let (r, _) = Response::parse(text.as_bytes()).unwrap().unwrap();
        assert_eq!(rtp_info(r.header("RTP-Info").unwrap()), Some(RtpInfo { seq: 17476, rtptime: 1431655765 }));
        assert_eq!(rtp_info("url=x;seq=70000;rtptime=1"), None);
        assert_eq!(rtp_info("url=a;seq=1;rtptime=2,url=b;seq=3;rtptime=4"), Some(RtpInfo { seq: 1, rtptime: 2 }));
    }

    #[test]
    fn refusals_and_garbage_are_errors_not_panics() {
        let (r, _) = Response::parse(b"RTSP/1.0 454 Session Not Found\r\nCSeq: 9\r\n\r\n").unwrap().unwrap();
        assert_eq!((r.status, r.status_line.as_str()), (454, "RTSP/1.0 454 Session Not Found"));
        for bad in [
            &b"HTTP/1.1 200 OK\r\n\r\n"[..],
            b"RTSP/1.0 2000 OK\r\n\r\n",
            b"RTSP/1.0\r\n\r\n",
            b"RTSP/1.0 200 OK\r\nno colon\r\n\r\n",
            b"RTSP/1.0 200 OK\r\nContent-Length: -1\r\n\r\n",
            b"RTSP/1.0 200 OK\r\nContent-Length: 99999999999999999999\r\n\r\n",
        ] {
            assert!(Response::parse(bad).is_err(), "{:?}", String::from_utf8_lossy(bad));
        }
        assert!(Response::parse(&vec![b'x'; MAX_HEADER_BYTES + 1]).is_err());
        assert_eq!(session_id(";timeout=5"), None);
        assert_eq!(server_ports("RTP/AVP;unicast;server_port=5004"), None);
        assert_eq!(server_ports("RTP/AVP;unicast;server_port=x-5005"), None);
    }

    #[test]
    fn the_light_body_is_in_world_units() {
        let l = Light::from_world(3.0, 4.0, -2.5).unwrap();
        assert_eq!(light_body(&l), "light: 3,4,-2.5\r\n");
    }

    #[test]
    fn urls_derive_from_the_frame_port() {
        let frame: SocketAddr = "10.0.0.2:7878".parse().unwrap();
        assert_eq!(stream_url(rtsp_addr_of(frame), "/live"), "rtsp://10.0.0.2:8554/live");
        let v6: SocketAddr = "[::1]:7878".parse().unwrap();
        assert_eq!(stream_url(rtsp_addr_of(v6), "/live"), "rtsp://[::1]:8554/live");
    }

    /// A canned server: answers each request in turn with `answers` (CSeq
    /// filled in), recording the requests.
    fn canned(answers: Vec<String>) -> (SocketAddr, std::thread::JoinHandle<Vec<String>>) {
        canned_then(answers, |_, _| {})
    }

    /// [`canned`], calling `after(i, request)` once answer `i` is sent.
    fn canned_then(
        answers: Vec<String>,
        mut after: impl FnMut(usize, &str) + Send + 'static,
    ) -> (SocketAddr, std::thread::JoinHandle<Vec<String>>) {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let handle = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let mut seen = vec![];
            let mut buf = vec![];
            for (i, a) in answers.into_iter().enumerate() {
                while !buf.windows(4).any(|w| w == b"\r\n\r\n") {
                    let mut chunk = [0u8; 1024];
                    let n = s.read(&mut chunk).unwrap();
                    if n == 0 {
                        return seen;
                    }
                    buf.extend_from_slice(&chunk[..n]);
                }
                let end = buf.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
                let req = String::from_utf8_lossy(&buf[..end]).into_owned();
                let body_len: usize = req
                    .lines()
                    .find_map(|l| l.strip_prefix("Content-Length: "))
                    .map_or(0, |v| v.trim().parse().unwrap());
                while buf.len() < end + body_len {
                    let mut chunk = [0u8; 1024];
                    let n = s.read(&mut chunk).unwrap();
                    buf.extend_from_slice(&chunk[..n]);
                }
                seen.push(String::from_utf8_lossy(&buf[..end + body_len]).into_owned());
                buf.drain(..end + body_len);
                s.write_all(a.replace("CSeq: N", &format!("CSeq: {}", i + 1)).as_bytes()).unwrap();
                after(i, seen.last().unwrap());
            }
            seen
        });
        (addr, handle)
    }

    #[test]
    fn the_client_speaks_rtsp_and_shows_refusals() {
        let ok = "RTSP/1.0 200 OK\r\nCSeq: N\r\nSession: 00000000000000AB;timeout=60\r\n\r\n".to_string();
        let (addr, server) = canned(vec![
            "RTSP/1.0 200 OK\r\nCSeq: N\r\nPublic: OPTIONS, SETUP\r\n\r\n".into(),
            SETUP_ANSWER.replace("CSeq: 3", "CSeq: N"),
            ok.clone(),
            "RTSP/1.0 451 Parameter Not Understood\r\nCSeq: N\r\n\r\n".into(),
            "RTSP/1.0 200 OK\r\nCSeq: 99\r\n\r\n".into(),
        ]);
        let mut c = RtspClient::connect(addr).unwrap();
        let url = "rtsp://127.0.0.1:8554/live";
        assert_eq!(c.options(url).unwrap(), "OPTIONS, SETUP");
        assert_eq!(c.setup(url, 6000).unwrap().server_ports, (5004, 5005));
        c.set_light(url, &Light::from_world(1.0, 2.0, 3.0).unwrap()).unwrap();
        let e = c.set_light(url, &Light::from_world(1.0, 2.0, 3.0).unwrap()).unwrap_err();
        assert_eq!(e.to_string(), "the server refused SET_PARAMETER: RTSP/1.0 451 Parameter Not Understood");
        assert!(c.keep_alive(url).unwrap_err().to_string().contains("CSeq"));
        drop(c);
        let seen = server.join().unwrap();
        assert!(seen[1].contains("Transport: RTP/AVP;unicast;client_port=6000-6001\r\n"), "{}", seen[1]);
        assert!(!seen[1].contains("Session:"));
        assert!(seen[2].starts_with("SET_PARAMETER rtsp://127.0.0.1:8554/live RTSP/1.0\r\nCSeq: 3\r\n"));
        assert!(seen[2].contains("Session: 1111111122222222\r\n"), "{}", seen[2]);
        assert!(seen[2].ends_with("Content-Type: text/parameters\r\nContent-Length: 14\r\n\r\nlight: 1,2,3\r\n"));
    }

    /// Two frames over real sockets from a fake camera that drops row 10
    /// of the first and answers NACKs: the stream asks, and the frame comes
    /// out repaired and whole.
    #[test]
    fn a_stream_repairs_a_dropped_row_over_udp() {
        use rt_services::camera::packetiser::Packetiser;
        use rt_services::camera::wire::rtcp::NackRequests;
        let camera_rtp = UdpSocket::bind("127.0.0.1:0").unwrap();
        let camera_rtcp = UdpSocket::bind("127.0.0.1:0").unwrap();
        let rtcp_port = camera_rtcp.local_addr().unwrap().port();
        let rtp_port = camera_rtp.local_addr().unwrap().port();
        let ok = "RTSP/1.0 200 OK\r\nCSeq: N\r\n\r\n".to_string();
        let setup = format!(
            "RTSP/1.0 200 OK\r\nCSeq: N\r\nTransport: RTP/AVP;unicast;client_port=1-2;server_port={rtp_port}-{rtcp_port}\r\n\
             Session: 00000000000000AB;timeout=60\r\n\r\n"
        );
        let sdp = "v=0\r\na=control:*\r\n";
        let describe = format!("RTSP/1.0 200 OK\r\nCSeq: N\r\nContent-Length: {}\r\n\r\n{sdp}", sdp.len());
        let mut client_rtp = None;
        let (addr, server) = canned_then(vec![ok.clone(), describe, setup, ok.clone(), ok], move |i, req| {
            if i == 2 {
                let ports = req.split("client_port=").nth(1).unwrap();
                client_rtp = Some(ports.split('-').next().unwrap().parse::<u16>().unwrap());
            }
            if i != 3 {
                return;
            }
            let to = SocketAddr::from(([127, 0, 0, 1], client_rtp.unwrap()));
            let (rtp, rtcp) = (camera_rtp.try_clone().unwrap(), camera_rtcp.try_clone().unwrap());
            std::thread::spawn(move || {
                let mut p = Packetiser::new(0xabcd, 0xfff0, 0);
                let mut sent = vec![];
                for k in 0..2u8 {
                    let f = p.begin_frame(u64::from(k) * 3_000);
                    for y in 0..360 {
                        let packet = p.next_packet(f, y).unwrap();
                        let mut d = vec![k * 100 + (y % 100) as u8; PACKET_BYTES];
                        p.emit(&packet, &mut d).unwrap();
                        if (k, y) != (0, 10) {
                            rtp.send_to(&d, to).unwrap();
                        }
                        sent.push(d);
                        if y % 20 == 0 {
                            std::thread::sleep(Duration::from_millis(1));
                        }
                    }
                }
                rtcp.set_read_timeout(Some(Duration::from_millis(500))).unwrap();
                let mut buf = [0u8; 1500];
                while let Ok(n) = rtcp.recv(&mut buf) {
                    for seq in NackRequests::new(&buf[..n], 0xabcd, p.highest_seq()) {
                        rtp.send_to(&sent[seq.wrapping_sub(0xfff0) as usize], to).unwrap();
                    }
                }
            });
        });
        let url = "rtsp://127.0.0.1:8554/light/3,4,-2";
        let mut stream = RtpStream::open(addr, url).unwrap();
        let mut got = vec![];
        while got.len() < 2 {
            let n = stream
                .receive(Duration::from_secs(3), |f| got.push((f.quality, f.pixels[10 * 1_440], f.pixels.to_vec())))
                .unwrap();
            assert!(n > 0, "no frame within 3 s");
        }
        assert_eq!(got[0].0, rt_services::camera::receiver::Quality::Repaired);
        assert_eq!(got[0].1, 10, "row 10 came by NACK");
        for (k, (_, _, pixels)) in got.iter().enumerate() {
            for y in 0..360 {
                assert_eq!(pixels[y * 1_440], k as u8 * 100 + (y % 100) as u8, "frame {k} row {y}");
            }
        }
        assert!(stream.counts().nacks >= 1);
        stream.close().unwrap();
        let seen = server.join().unwrap();
        assert!(seen[4].starts_with("TEARDOWN rtsp://127.0.0.1:8554/light/3,4,-2 RTSP/1.0"), "{}", seen[4]);
        assert!(seen[3].starts_with("PLAY "));
    }
}
