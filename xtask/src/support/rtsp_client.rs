//! A small RTSP/RTP client for the suite's checks of the network camera
//! (the emulated board, the lossy relay, hps-sim): it sets a stream up as a
//! player does, over UDP, inside the RTSP connection (interleaved) or from
//! a multicast group, and takes its frames from the product's receiver
//! (`rt_services::camera::receiver`, rt-client's, with as many frame
//! buffers), which asks for missing rows with generic NACKs (RFC 4585)
//! and counts what came by repair: the suite tests the receiver users run.
//! Strict: anything off-spec in a packet is an error.

use std::collections::{BTreeMap, VecDeque};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{Ipv4Addr, SocketAddr, TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use rt_services::camera::receiver::{
    Quality, ReceivedFrame, Receiver, ReceiverConfig, ReceiverCounts, Verdict, MAX_NACK_BYTES,
};
use rt_services::camera::wire::rtp::HEADER_BYTES;

use super::Result;

/// Frame buffers of the receiver: rt-client's (`rt_client::rtsp::FRAME_BUFFERS`,
/// a binary crate the suite cannot import): seven frames in progress.
pub const FRAME_BUFFERS: usize = 8;

/// The SSRC this client's RTCP (reports, NACKs) goes out with.
const OUR_SSRC: u32 = 0x0bad_cafe;

/// A whole frame (exact, or repaired by NACK).
pub struct Frame {
    /// Its RTP timestamp.
    pub timestamp: u32,
    /// 518,400 bytes.
    pub bytes: Vec<u8>,
    /// The rows that came after a NACK asked for them.
    pub repaired: Vec<usize>,
}

/// What the receiver counted so far, in the suite's words.
#[derive(Clone, Copy, Debug, Default)]
pub struct Tally {
    /// Rows that came after a NACK asked for them.
    pub repaired_rows: usize,
    /// Frames given up with rows still missing (handed over damaged, and
    /// not returned by [`RtspSession::next_frame`]).
    pub given_up: usize,
    /// Packets of frames already handed over: a repair asked for twice, or
    /// a row that came after its frame was given up.
    pub stale: usize,
    /// A line to ignore the first time it arrives (a loss made on
    /// purpose, for the repair to fill).
    pub drop_once: Option<usize>,
}

impl Tally {
    fn update(&mut self, c: &ReceiverCounts) {
        self.repaired_rows = c.rows_repaired as usize;
        self.given_up = c.damaged as usize;
        self.stale = c.late as usize;
    }
}

/// How the stream's packets come.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// UDP to our ports.
    Udp,
    /// Inside the RTSP connection (`RTP/AVP/TCP;interleaved=0-1`).
    Tcp,
    /// From the stream's multicast group, joined on the interface with this
    /// address (NACKs go to the server's RTCP port, unicast).
    Multicast(Ipv4Addr),
}

/// An RTSP session playing one stream.
pub struct RtspSession {
    ctrl: TcpStream,
    reader: BufReader<TcpStream>,
    cseq: u32,
    url: String,
    session: String,
    transport: Transport,
    rtp: UdpSocket,
    rtcp: UdpSocket,
    server_rtcp: SocketAddr,
    /// The SSRC the SETUP answer announced.
    pub ssrc: u32,
    /// RTP-Info's `rtptime`: the timestamp of the media time `Range` starts
    /// at ([`npt_ticks`](Self::npt_ticks)).
    pub rtptime: u32,
    /// `Range`'s start, in 90 kHz ticks of media time (0 for a stream this
    /// session started).
    pub npt_ticks: u64,
    /// The multicast group and port, for a multicast session.
    pub group: Option<SocketAddr>,
    /// When the last receiver report went (they keep the session alive,
    /// as a player's do).
    last_report: Instant,
    /// When the session began: the receiver's clock counts from it.
    started: Instant,
    /// Datagrams on a multicast group that were not this stream's.
    pub foreign: usize,
    /// The product's receiver: frames put together, repairs asked for.
    receiver: Receiver<Vec<u8>, FRAME_BUFFERS>,
    /// Whole frames handed over and not yet returned.
    ready: VecDeque<Frame>,
    /// The newest extended sequence number received.
    highest: Option<u32>,
    /// What the receiver counted.
    pub frames: Tally,
    /// NACK datagrams sent.
    pub nacks: usize,
}

type Headers = BTreeMap<String, String>;

impl RtspSession {
    /// Set up and play `path` (e.g. `/light/3,4,-2?fps=10`) on the RTSP
    /// server at `rtsp`. `rtcp` overrides where RTCP goes (a forwarded
    /// port); by default the announced `server_port` on the server's
    /// address.
    pub fn open(rtsp: SocketAddr, path: &str, rtcp: Option<SocketAddr>) -> Result<RtspSession> {
        RtspSession::open_with(rtsp, path, rtcp, Transport::Udp)
    }

    /// [`open`](Self::open) over `transport`.
    pub fn open_with(
        rtsp: SocketAddr,
        path: &str,
        rtcp: Option<SocketAddr>,
        transport: Transport,
    ) -> Result<RtspSession> {
        RtspSession::open_from(rtsp, path, rtcp, transport, None)
    }

    /// [`open_with`](Self::open_with) from the local address `local` (its
    /// RTSP connection and its UDP ports): on loopback, where all of
    /// 127.0.0.0/8 is this host's, viewers that look like hosts of their
    /// own to a server with per-address caps.
    pub fn open_from(
        rtsp: SocketAddr,
        path: &str,
        rtcp: Option<SocketAddr>,
        transport: Transport,
        local: Option<Ipv4Addr>,
    ) -> Result<RtspSession> {
        // A server with every connection taken refuses more for a moment:
        // try again for up to 10 s, as a user would.
        let deadline = Instant::now() + Duration::from_secs(10);
        let ctrl = loop {
            match connect_from(local, rtsp) {
                Ok(c) => break c,
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused && Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(200))
                }
                Err(e) => return Err(format!("RTSP {rtsp}: {e}")),
            }
        };
        ctrl.set_read_timeout(Some(Duration::from_secs(20))).map_err(|e| e.to_string())?;
        let reader = BufReader::new(ctrl.try_clone().map_err(|e| e.to_string())?);
        let (rtp, rtcp_sock) = udp_pair(local.unwrap_or(Ipv4Addr::UNSPECIFIED))?;
        let mut s = RtspSession {
            ctrl,
            reader,
            cseq: 0,
            url: format!("rtsp://{rtsp}{path}"),
            session: String::new(),
            transport,
            rtp,
            rtcp: rtcp_sock,
            server_rtcp: rtsp,
            ssrc: 0,
            rtptime: 0,
            npt_ticks: 0,
            group: None,
            last_report: Instant::now(),
            started: Instant::now(),
            foreign: 0,
            receiver: Receiver::new(
                ReceiverConfig::new(OUR_SSRC),
                core::array::from_fn(|_| vec![0; model::FRAME_BYTES]),
            )
            .map_err(|e| e.to_string())?,
            ready: VecDeque::new(),
            highest: None,
            frames: Tally::default(),
            nacks: 0,
        };
        let url = s.url.clone();
        let (_, sdp) = s.request("DESCRIBE", &url, &[("Accept", "application/sdp")], "")?;
        for needed in ["a=rtpmap:96 raw/90000", "sampling=RGB; width=480; height=360; depth=8", "a=rtcp-fb:96 nack"] {
            if !sdp.contains(needed) {
                return Err(format!("the SDP lacks {needed:?}:\n{sdp}"));
            }
        }
        let port = s.rtp.local_addr().map_err(|e| e.to_string())?.port();
        let asked = match transport {
            Transport::Udp => format!("RTP/AVP;unicast;client_port={port}-{}", port + 1),
            Transport::Tcp => "RTP/AVP/TCP;unicast;interleaved=0-1".to_string(),
            Transport::Multicast(_) => "RTP/AVP;multicast".to_string(),
        };
        let (h, _) = s.request("SETUP", &format!("{url}/trackID=0"), &[("Transport", &asked)], "")?;
        s.session = field(&h, "session")?.split(';').next().unwrap_or_default().to_string();
        let answer = field(&h, "transport")?;
        let param = |name: &str| answer.split(';').find_map(|p| p.strip_prefix(name)).map(str::to_string);
        s.ssrc = param("ssrc=").and_then(|x| u32::from_str_radix(&x, 16).ok()).ok_or("no ssrc in Transport")?;
        match transport {
            Transport::Udp => {
                let ports = param("server_port=").ok_or(format!("no server_port in {answer:?}"))?;
                let rtcp_port: u16 = ports.split('-').nth(1).and_then(|p| p.parse().ok()).ok_or("bad server_port")?;
                s.server_rtcp = rtcp.unwrap_or(SocketAddr::new(rtsp.ip(), rtcp_port));
            }
            Transport::Tcp => {
                if param("interleaved=").as_deref() != Some("0-1") {
                    return Err(format!("not interleaved on 0-1: {answer:?}"));
                }
            }
            Transport::Multicast(iface) => {
                let group: Ipv4Addr =
                    param("destination=").and_then(|d| d.parse().ok()).ok_or(format!("no destination: {answer:?}"))?;
                let port: u16 = param("port=")
                    .and_then(|p| p.split('-').next().and_then(|p| p.parse().ok()))
                    .ok_or(format!("no port: {answer:?}"))?;
                s.rtp = join_group(group, port, iface)?;
                s.group = Some(SocketAddr::new(group.into(), port));
                // Repairs are asked for unicast, at the server's RTCP port.
                let ports = param("server_port=").ok_or(format!("no server_port in {answer:?}"))?;
                let rtcp_port: u16 = ports.split('-').nth(1).and_then(|p| p.parse().ok()).ok_or("bad server_port")?;
                s.server_rtcp = rtcp.unwrap_or(SocketAddr::new(rtsp.ip(), rtcp_port));
            }
        }
        let session = s.session.clone();
        let (h, _) = s.request("PLAY", &url, &[("Session", &session)], "")?;
        let info = field(&h, "rtp-info")?;
        s.rtptime = info
            .split(';')
            .find_map(|p| p.strip_prefix("rtptime="))
            .and_then(|t| t.parse().ok())
            .ok_or(format!("no rtptime in RTP-Info {info:?}"))?;
        // `Range: npt=S.UUUUUU-`: the media time rtptime stands for.
        let npt = field(&h, "range").unwrap_or_default();
        let start = npt.strip_prefix("npt=").and_then(|r| r.split('-').next()).unwrap_or("0");
        let (secs, frac) = start.split_once('.').unwrap_or((start, "0"));
        let micros =
            secs.parse::<u64>().unwrap_or(0) * 1_000_000 + format!("{frac:0<6}")[..6].parse::<u64>().unwrap_or(0);
        s.npt_ticks = (micros * 9 + 50) / 100;
        if transport == Transport::Tcp {
            // The connection carries the packets from now on.
            s.ctrl.set_read_timeout(Some(Duration::from_millis(50))).map_err(|e| e.to_string())?;
        }
        Ok(s)
    }

    /// Send RTCP (reports, NACKs) to the multicast group's RTCP port, as
    /// standard players do (GStreamer's rtspsrc), not to the server's.
    pub fn send_rtcp_to_group(&mut self) {
        if let Some(g) = self.group {
            self.server_rtcp = SocketAddr::new(g.ip(), g.port().wrapping_add(1));
        }
    }

    /// A second handle on this session's RTCP socket, and where its
    /// reports go: for a test that sends RTCP as this player would (or as
    /// someone spoofing it would).
    pub fn rtcp_endpoint(&self) -> Result<(UdpSocket, SocketAddr)> {
        Ok((self.rtcp.try_clone().map_err(|e| e.to_string())?, self.server_rtcp))
    }

    /// The newest extended sequence number received.
    pub fn highest_seq(&self) -> u32 {
        self.highest.unwrap_or(0)
    }

    fn request(&mut self, method: &str, url: &str, headers: &[(&str, &str)], body: &str) -> Result<(Headers, String)> {
        self.cseq += 1;
        let mut req = format!("{method} {url} RTSP/1.0\r\nCSeq: {}\r\n", self.cseq);
        for (k, v) in headers {
            req += &format!("{k}: {v}\r\n");
        }
        if !body.is_empty() {
            req += &format!("Content-Length: {}\r\n", body.len());
        }
        req += "\r\n";
        req += body;
        self.ctrl.write_all(req.as_bytes()).map_err(|e| format!("{method}: {e}"))?;
        if self.transport == Transport::Tcp {
            self.skip_interleaved().map_err(|e| format!("{method}: {e}"))?;
        }
        let mut status = String::new();
        self.reader.read_line(&mut status).map_err(|e| format!("{method}: {e}"))?;
        let mut h = Headers::new();
        loop {
            let mut line = String::new();
            self.reader.read_line(&mut line).map_err(|e| format!("{method}: {e}"))?;
            let line = line.trim_end();
            if line.is_empty() {
                break;
            }
            if let Some((k, v)) = line.split_once(':') {
                h.insert(k.trim().to_ascii_lowercase(), v.trim().to_string());
            }
        }
        let len: usize = h.get("content-length").and_then(|v| v.parse().ok()).unwrap_or(0);
        let mut body = vec![0; len];
        self.reader.read_exact(&mut body).map_err(|e| format!("{method} body: {e}"))?;
        if self.transport == Transport::Tcp {
            // Back to the short waits `next_frame` polls with.
            self.reader.get_ref().set_read_timeout(Some(Duration::from_millis(50))).map_err(|e| e.to_string())?;
        }
        if !status.starts_with("RTSP/1.0 200") {
            return Err(format!("{method} {url}: {}", status.trim_end()));
        }
        Ok((h, String::from_utf8_lossy(&body).into_owned()))
    }

    /// Move a live stream's light (`SET_PARAMETER`, world units).
    pub fn set_light(&mut self, x: f64, y: f64, z: f64) -> Result<()> {
        let (url, session) = (self.url.clone(), self.session.clone());
        let headers = [("Session", session.as_str()), ("Content-Type", "text/parameters")];
        self.request("SET_PARAMETER", &url, &headers, &format!("light: {x},{y},{z}\r\n")).map(|_| ())
    }

    /// The session id the SETUP answer gave.
    pub fn session_id(&self) -> &str {
        &self.session
    }

    /// End the session.
    pub fn teardown(mut self) -> Result<()> {
        let (url, session) = (self.url.clone(), self.session.clone());
        self.request("TEARDOWN", &url, &[("Session", &session)], "").map(|_| ())
    }

    /// The next whole frame (rows repaired by NACK where lost), within
    /// `timeout`; frames given up on the way are counted
    /// ([`Tally::given_up`]), not returned.
    pub fn next_frame(&mut self, timeout: Duration) -> Result<Frame> {
        let deadline = Instant::now() + timeout;
        let mut buf = [0u8; 2048];
        loop {
            if let Some(frame) = self.ready.pop_front() {
                return Ok(frame);
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(format!("no whole frame within {timeout:?}"));
            }
            if self.transport == Transport::Tcp {
                self.next_interleaved(&mut buf)?;
            } else {
                // Wake for the receiver's timers too (a NACK due, a frame
                // to give up).
                let timers = self.receiver_deadline().map_or(Duration::from_millis(50), |d| {
                    d.saturating_duration_since(now).clamp(Duration::from_millis(1), Duration::from_millis(50))
                });
                self.rtp.set_read_timeout(Some(timers)).map_err(|e| e.to_string())?;
                match self.rtp.recv(&mut buf) {
                    // A group is open to any sender on the network: what is
                    // not this stream's RTP is someone else's, not the
                    // server's fault.
                    Ok(n) if matches!(self.transport, Transport::Multicast(_)) && !self.is_ours(&buf[..n]) => {
                        self.foreign += 1;
                    }
                    Ok(n) => self.take(&buf[..n])?,
                    Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
                    Err(e) => return Err(format!("RTP: {e}")),
                }
            }
            let (now, ready) = (self.clock(), &mut self.ready);
            self.receiver.poll(now, |f| keep_whole(ready, f));
            self.frames.update(&self.receiver.counts());
            self.ask_for_missing()?;
        }
    }

    /// The receiver's clock: milliseconds since the session began.
    fn clock(&self) -> rt_services::Instant {
        rt_services::Instant::from_millis(u64::try_from(self.started.elapsed().as_millis()).unwrap_or(u64::MAX))
    }

    /// When the receiver's next timer runs out, on the wall clock.
    fn receiver_deadline(&self) -> Option<Instant> {
        let at = self.receiver.deadline()?;
        Some(self.started + Duration::from_millis(at.millis()))
    }

    /// One interleaved packet from the connection, if one came (RTCP on
    /// channel 1 is skipped), to the receiver.
    fn next_interleaved(&mut self, buf: &mut [u8; 2048]) -> Result<()> {
        let mut head = [0u8; 4];
        match self.reader.read_exact(&mut head) {
            Ok(()) => {}
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                return Ok(())
            }
            Err(e) => return Err(format!("interleaved: {e}")),
        }
        if head[0] != b'$' {
            return Err(format!("interleaved data starts with {:#04x}, not '$'", head[0]));
        }
        let len = usize::from(u16::from_be_bytes([head[2], head[3]]));
        let data = buf.get_mut(..len).ok_or(format!("an interleaved packet of {len} bytes"))?;
        // The packet's rest arrives soon after its header: wait for it.
        self.reader.get_ref().set_read_timeout(Some(Duration::from_secs(5))).map_err(|e| e.to_string())?;
        let read = self.reader.read_exact(data);
        self.reader.get_ref().set_read_timeout(Some(Duration::from_millis(50))).map_err(|e| e.to_string())?;
        read.map_err(|e| format!("interleaved packet: {e}"))?;
        match head[1] {
            0 => self.take(&buf[..len]),
            _ => Ok(()),
        }
    }

    /// Skip the interleaved packets (`$`) in front of a response, which
    /// keep coming on the connection until the server has the request.
    fn skip_interleaved(&mut self) -> std::io::Result<()> {
        use std::io::ErrorKind;
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            let first = match self.reader.fill_buf() {
                Ok([]) => return Ok(()),
                Ok(b) => b[0],
                Err(e)
                    if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) && Instant::now() < deadline =>
                {
                    continue
                }
                Err(e) => return Err(e),
            };
            if first != b'$' {
                // The response: read it with a patient timeout.
                return self.reader.get_ref().set_read_timeout(Some(Duration::from_secs(10)));
            }
            let mut head = [0u8; 4];
            self.reader.get_ref().set_read_timeout(Some(Duration::from_secs(5)))?;
            self.reader.read_exact(&mut head)?;
            let mut rest = vec![0u8; usize::from(u16::from_be_bytes([head[2], head[3]]))];
            self.reader.read_exact(&mut rest)?;
        }
    }

    /// Whether `p` looks like this stream's RTP (version 2, its SSRC).
    fn is_ours(&self, p: &[u8]) -> bool {
        p.len() >= 12 && p[0] >> 6 == 2 && p[8..12] == self.ssrc.to_be_bytes()
    }

    /// One RTP packet, checked and handed to the receiver (frames it
    /// finishes wait in `ready`).
    fn take(&mut self, p: &[u8]) -> Result<()> {
        // What the receiver does not check, the suite does: the SSRC the
        // SETUP answer announced, and the marker on the last row alone.
        if p.len() < HEADER_BYTES || p[8..12] != self.ssrc.to_be_bytes() {
            return Err(format!("not this stream's packet ({} bytes, SSRC {:02x?})", p.len(), p.get(8..12)));
        }
        let be16 = |i: usize| u16::from_be_bytes([p[i], p[i + 1]]);
        let (seq, line, marker) = (u32::from(be16(12)) << 16 | u32::from(be16(2)), be16(16), p[1] & 0x80 != 0);
        if marker != (line == rt_services::frames::ROWS - 1) {
            return Err(format!("line {line} with marker {marker}"));
        }
        if self.highest.is_none_or(|h| seq.wrapping_sub(h) < 1 << 31) {
            self.highest = Some(seq);
        }
        if self.frames.drop_once == Some(usize::from(line)) {
            self.frames.drop_once = None;
            return Ok(());
        }
        let now = self.clock();
        let ready = &mut self.ready;
        let verdict = self.receiver.receive(now, p, |f| keep_whole(ready, f));
        self.frames.update(&self.receiver.counts());
        match verdict {
            Verdict::Ignored(why) => Err(format!("not a row packet of this stream: {why:?} ({} bytes)", p.len())),
            Verdict::Accepted | Verdict::Duplicate | Verdict::Late => Ok(()),
        }
    }

    /// Send the NACK the receiver has due (each frame's again after its
    /// interval while rows are still missing), and a receiver report when
    /// one is due.
    fn ask_for_missing(&mut self) -> Result<()> {
        if self.transport == Transport::Tcp {
            return Ok(()); // TCP loses nothing
        }
        self.report()?;
        let mut nack = [0u8; MAX_NACK_BYTES];
        if let Some(len) = self.receiver.write_nack(self.clock(), &mut nack) {
            self.rtcp.send_to(&nack[..len], self.server_rtcp).map_err(|e| format!("NACK: {e}"))?;
            self.nacks += 1;
        }
        Ok(())
    }
}

impl RtspSession {
    /// Send a receiver report every 2.5 s: it keeps the session alive. Its
    /// LSR and DLSR are 0 (no round trip measured), so the server keeps
    /// its default round trip, 50 ms: rt-client's carry the sender
    /// reports' times, and from those the emulated board measures a round
    /// trip far shorter than the time its repairs take on its CPU, and
    /// its repair window closes before they come (through the lossy
    /// relay's 10% drop: 140 rows unrepairable, 91.7% of frames whole).
    fn report(&mut self) -> Result<()> {
        use rt_services::camera::wire::rtcp;
        if self.last_report.elapsed() < Duration::from_millis(2_500) {
            return Ok(());
        }
        self.last_report = Instant::now();
        let mut rr = [0u8; rtcp::RECEIVER_REPORT_BYTES];
        if rtcp::write_receiver_report(OUR_SSRC, self.ssrc, 0, 0, &mut rr).is_ok() {
            self.rtcp.send_to(&rr, self.server_rtcp).map_err(|e| format!("RR: {e}"))?;
        }
        Ok(())
    }
}

/// Keep a frame the receiver handed over if it came whole.
fn keep_whole(ready: &mut VecDeque<Frame>, f: ReceivedFrame<'_>) {
    if f.quality == Quality::Damaged {
        return;
    }
    let repaired = (0..rt_services::frames::ROWS).filter(|&y| f.repaired.contains(y)).map(usize::from).collect();
    ready.push_back(Frame { timestamp: f.timestamp, bytes: f.pixels.to_vec(), repaired });
}

fn field(h: &Headers, name: &str) -> Result<String> {
    h.get(name).cloned().ok_or(format!("no {name} header in {h:?}"))
}

/// Two client UDP sockets on consecutive ports, the first even; the RTP
/// one with a receive buffer of [`RECEIVE_BUFFER`].
fn udp_pair(local: Ipv4Addr) -> Result<(UdpSocket, UdpSocket)> {
    for _ in 0..64 {
        let probe = UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
        let port = probe.local_addr().map_err(|e| e.to_string())?.port() & !1;
        drop(probe);
        if let (Ok(a), Ok(b)) = (bind_rtp(local, port), UdpSocket::bind((local, port + 1))) {
            return Ok((a, b));
        }
    }
    Err("no free UDP port pair".into())
}

/// A socket receiving `group:port`, joined on the interface `iface`
/// (several receivers on one host share the port).
fn join_group(group: Ipv4Addr, port: u16, iface: Ipv4Addr) -> Result<UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let go = || -> std::io::Result<UdpSocket> {
        let socket = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
        socket.set_reuse_address(true)?;
        set_receive_buffer(&socket);
        socket.bind(&SocketAddr::from((group, port)).into())?;
        socket.join_multicast_v4(&group, &iface)?;
        Ok(socket.into())
    };
    go().map_err(|e| format!("joining {group}:{port} on {iface}: {e}"))
}

/// The receive buffer the suite's RTP sockets ask for: 4 MiB, some five
/// frames' packets in the kernel's accounting (about 2.3 KB each).
pub const RECEIVE_BUFFER: usize = 4 << 20;

/// Give `socket` a receive buffer of [`RECEIVE_BUFFER`], past
/// `net.core.rmem_max` where the process may (`SO_RCVBUFFORCE`, socket(7):
/// CAP_NET_ADMIN, which the suite has as root), else as much as that
/// grants. The suite's figures then do not hang on the host's setting:
/// with Linux's default 208 KiB (a third of a frame) a receiver on a busy
/// machine lost rows every frame, and bench-fw counted the board's repairs
/// of them (106,300 guest instructions per frame for one RTP viewer, 98,981
/// with a 4 MiB buffer). Losses the tests mean to have come from their
/// lossy links. socket2 has no call for `SO_RCVBUFFORCE`.
fn set_receive_buffer(socket: &socket2::Socket) {
    use std::os::fd::AsRawFd;
    let bytes = libc::c_int::try_from(RECEIVE_BUFFER).unwrap_or(libc::c_int::MAX);
    // SAFETY: a valid socket descriptor, an option value of the type and
    // length setsockopt(2) documents for SO_RCVBUFFORCE (an int), read
    // during the call only.
    let forced = unsafe {
        libc::setsockopt(
            socket.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_RCVBUFFORCE,
            (&bytes as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    if forced != 0 {
        // Best effort: a smaller buffer only means more repairs.
        let _ = socket.set_recv_buffer_size(RECEIVE_BUFFER);
    }
}

fn bind_rtp(local: Ipv4Addr, port: u16) -> std::io::Result<UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let socket = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
    set_receive_buffer(&socket);
    socket.bind(&std::net::SocketAddr::from((local, port)).into())?;
    Ok(socket.into())
}

/// A TCP connection to `to`, from `local` when given (10 s to connect).
pub fn connect_from(local: Option<Ipv4Addr>, to: SocketAddr) -> std::io::Result<TcpStream> {
    use socket2::{Domain, Protocol, Socket, Type};
    let Some(local) = local else { return TcpStream::connect_timeout(&to, Duration::from_secs(10)) };
    let socket = Socket::new(Domain::IPV4, Type::STREAM, Some(Protocol::TCP))?;
    socket.bind(&SocketAddr::from((local, 0)).into())?;
    socket.connect_timeout(&to.into(), Duration::from_secs(10))?;
    Ok(socket.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The RTP socket gets all of [`RECEIVE_BUFFER`] where the process may
    /// force it (root, as in the suite), else what `net.core.rmem_max`
    /// allows (Linux reports twice the size asked for: its bookkeeping).
    #[test]
    fn the_rtp_socket_gets_its_receive_buffer() {
        let socket = bind_rtp(Ipv4Addr::LOCALHOST, 0).unwrap();
        let granted = socket2::SockRef::from(&socket).recv_buffer_size().unwrap();
        // SAFETY: geteuid has no preconditions and cannot fail.
        let root = unsafe { libc::geteuid() } == 0;
        let rmem_max: usize = std::fs::read_to_string("/proc/sys/net/core/rmem_max").unwrap().trim().parse().unwrap();
        let want = if root { RECEIVE_BUFFER } else { RECEIVE_BUFFER.min(rmem_max) };
        assert!(granted >= 2 * want, "granted {granted} bytes, wanted twice {want} (root: {root})");
    }
}
