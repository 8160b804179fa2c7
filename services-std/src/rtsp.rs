//! The board as a network camera on std: `rt_services::camera::rtsp`'s
//! server and `rt_services::camera::sender`'s RTP sender on std sockets,
//! drawing frames from one frame ring (the camera's own, or its share of
//! the board's), as the board does.
//!
//! One thread runs it all, polling non-blocking sockets: RTSP on TCP, RTP
//! and RTCP on a pair of consecutive UDP ports. A row packet is its 20
//! header bytes and the row read from the ring's memory, sent with one
//! `send_to` (the host has no two-buffer DMA; the board's zero-copy path is
//! the firmware's); an interleaved session's packets go into its
//! connection's output buffer. The rules are the board's: at most
//! [`rtsp::CONNECTIONS`] connections (more are closed at once), the
//! server's deadlines, RTCP silence ends a crashed player's stream. No
//! socket operation blocks: a client that does not read has its output
//! buffer fill, its rows wait, and after [`OUTPUT_STALL`] it is cut from
//! the frame, so the others never wait on it.
//!
//! [`OUTPUT_STALL`]: rt_services::camera::sender::OUTPUT_STALL

use std::fmt::Write as _;
use std::io::{self, Read, Write};
use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant as StdInstant, SystemTime, UNIX_EPOCH};

use model::{Light, ROW_BYTES};
use rt_services::camera::frame_header::FRAME_HEADER_BYTES;
use rt_services::camera::packetiser::Packetiser;
use rt_services::camera::random::SessionRng;
use rt_services::camera::rtsp::{
    self, ConnId, Connection, Server, CONNECTIONS, CONNECTIONS_PER_ADDRESS, MAX_RESPONSE_BYTES, MAX_SESSIONS,
};
use rt_services::camera::sender::{self, Bound, Camera, Dest, Multicast, RtpSink, SlotSource};
use rt_services::camera::station::Station;
use rt_services::camera::wire::rtcp::ntp_timestamp;
use rt_services::camera::wire::rtp::{self, RowPacket};
use rt_services::{FrameSource, Instant};

use crate::Log;

/// The light of a live stream before its first `SET_PARAMETER` (the one
/// `rt-client` starts with).
pub const LIVE_LIGHT: (f64, f64, f64) = (3.0, 4.0, -2.0);

/// Bytes a connection's output buffer holds before its interleaved rows
/// wait (responses always fit: a connection is closed rather than cut one).
pub const CLIENT_OUT_BYTES: usize = 256 * 1024;

/// How the RTSP server runs.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Log sessions to stderr.
    pub verbose: bool,
    /// Where multicast streams go (`None`: SETUP of multicast answers 461).
    pub multicast: Option<Multicast>,
    /// Whether `SETUP`s asking for RTP over UDP are taken (hps-sim's
    /// `--fault refuse-udp` answers them 461 Unsupported Transport).
    pub udp: bool,
}

impl Options {
    /// Unicast UDP and interleaved, no multicast, logging if `verbose`.
    pub fn new(verbose: bool) -> Options {
        Options { verbose, multicast: None, udp: true }
    }
}

/// A running RTSP server; stops when dropped.
pub struct RtspServer {
    addr: SocketAddr,
    rtp_port: u16,
    stop: Arc<AtomicBool>,
    thread: Option<thread::JoinHandle<()>>,
}

impl RtspServer {
    /// Listen for RTSP on `addr` (port 0: any free one) and send RTP from
    /// a pair of free consecutive UDP ports on its address, as `options`
    /// say, drawing frames from `source` (a ring of the camera's own, or
    /// its share of the board's, [`crate::board`]).
    pub fn start_on<S: SlotSource + Send + 'static>(
        addr: SocketAddr,
        options: Options,
        source: S,
    ) -> io::Result<RtspServer> {
        RtspServer::start_making(addr, options, move || Ok(source))
    }

    /// As [`start_on`](Self::start_on), the source made by `make` on the
    /// server's own thread (for a device that cannot move between
    /// threads, the Verilated RTL); its error stops the server.
    pub fn start_making<S: SlotSource>(
        addr: SocketAddr,
        options: Options,
        make: impl FnOnce() -> io::Result<S> + Send + 'static,
    ) -> io::Result<RtspServer> {
        RtspServer::spawn(addr, options, move |sockets, options, flag, log| run(sockets, make()?, options, flag, log))
    }

    fn spawn(
        addr: SocketAddr,
        options: Options,
        serve: impl FnOnce(Sockets, Options, &AtomicBool, &mut Log) -> io::Result<()> + Send + 'static,
    ) -> io::Result<RtspServer> {
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let (rtp, rtcp) = udp_pair(addr.ip())?;
        if let Some(m) = options.multicast {
            rtp.set_multicast_ttl_v4(u32::from(m.ttl))?;
            rtcp.set_multicast_ttl_v4(u32::from(m.ttl))?;
        }
        let rtp_port = rtp.local_addr()?.port();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = thread::Builder::new().name("rtsp".into()).spawn(move || {
            let mut log = Log::new(0, options.verbose);
            let group_rtcp = match options.multicast.map(|m| group_rtcp_socket(m.base_port.wrapping_add(1))) {
                Some(Ok(g)) => Some(g),
                Some(Err(e)) => {
                    eprintln!("hps-sim: the multicast groups' RTCP port: {e}");
                    None
                }
                None => None,
            };
            let sockets = Sockets { listener, rtp, rtcp, group_rtcp };
            let result = serve(sockets, options, &flag, &mut log);
            if let Err(e) = result {
                eprintln!("hps-sim: the RTSP server stopped: {e}");
            }
        })?;
        Ok(RtspServer { addr, rtp_port, stop, thread: Some(thread) })
    }

    /// The RTSP listener's address.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The UDP port RTP leaves from (RTCP: the next one).
    pub fn rtp_port(&self) -> u16 {
        self.rtp_port
    }
}

impl Drop for RtspServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Two UDP sockets on consecutive ports, the first even (RFC 3550 section
/// 11: RTP on an even port, RTCP on the next).
fn udp_pair(ip: IpAddr) -> io::Result<(UdpSocket, UdpSocket)> {
    let mut last = None;
    for _ in 0..64 {
        let probe = UdpSocket::bind(SocketAddr::new(ip, 0))?;
        let port = probe.local_addr()?.port() & !1;
        drop(probe);
        if port < 1024 {
            continue;
        }
        match (UdpSocket::bind(SocketAddr::new(ip, port)), UdpSocket::bind(SocketAddr::new(ip, port + 1))) {
            (Ok(a), Ok(b)) => {
                a.set_nonblocking(true)?;
                b.set_nonblocking(true)?;
                return Ok((a, b));
            }
            (Err(e), _) | (_, Err(e)) => last = Some(e),
        }
    }
    Err(last.unwrap_or_else(|| io::Error::new(io::ErrorKind::AddrInUse, "no free UDP port pair")))
}

struct Sockets {
    listener: TcpListener,
    rtp: UdpSocket,
    rtcp: UdpSocket,
    /// The multicast groups' RTCP port (receivers' reports and NACKs to a
    /// group it joined, or to it), with multicast on.
    group_rtcp: Option<UdpSocket>,
}

/// A socket on every address's `port`, shared with the receivers of the
/// same host that bind the group's ports too.
fn group_rtcp_socket(port: u16) -> io::Result<UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let socket = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
    socket.set_reuse_address(true)?;
    socket.bind(&SocketAddr::from(([0, 0, 0, 0], port)).into())?;
    socket.set_nonblocking(true)?;
    Ok(socket.into())
}

/// One RTSP connection.
struct Client {
    stream: TcpStream,
    conn: Connection,
    /// Received bytes the connection could not take yet.
    pending: Vec<u8>,
    /// Bytes to write: responses and interleaved packets, in order.
    out: Vec<u8>,
    open: bool,
}

impl Client {
    /// Write what the socket takes now; `false` if the peer is gone.
    fn flush(&mut self) -> bool {
        while !self.out.is_empty() {
            match self.stream.write(&self.out) {
                Ok(0) => return false,
                Ok(n) => {
                    self.out.drain(..n);
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return true,
                Err(_) => return false,
            }
        }
        true
    }

    /// Room left in the output buffer.
    fn room(&self) -> usize {
        CLIENT_OUT_BYTES.saturating_sub(self.out.len())
    }
}

/// The time one row packet takes on the board's Gigabit link: 1,502 bytes
/// of frame plus preamble, start delimiter, FCS and inter-packet gap
/// (8 + 4 + 12 bytes), at 1 bit per ns.
pub const PACKET_TIME: Duration = Duration::from_nanos((FRAME_HEADER_BYTES + ROW_BYTES + 24) as u64 * 8);

/// Packets the sink sends back to back before pacing sets in (the board's
/// transmit ring).
pub const BURST: u32 = 32;

/// Rows out of the ring's memory into UDP datagrams (no faster than the
/// board's link would carry them) or into a connection's output buffer.
/// Unpaced, a frame's 360 packets land in the receiver's socket at once,
/// and a socket buffer of the usual 208 KiB (Linux `net.core.rmem_max`)
/// holds about a third of a frame: every frame would lose rows on the host
/// that the board's link never sends that fast.
struct Sink<'a> {
    rtp: &'a UdpSocket,
    rtcp: &'a UdpSocket,
    clients: &'a mut Vec<Client>,
    packet: [u8; 4 + rtp::PACKET_BYTES],
    /// Token bucket: packets that may go now, as of `refilled`.
    tokens: u32,
    refilled: StdInstant,
}

impl Sink<'_> {
    /// Whether the link has room for one more packet now.
    fn take_token(&mut self) -> bool {
        let now = StdInstant::now();
        let earned = (now.duration_since(self.refilled).as_nanos() / PACKET_TIME.as_nanos()) as u32;
        if earned > 0 {
            self.tokens = (self.tokens + earned).min(BURST);
            self.refilled += PACKET_TIME * earned;
            if self.tokens == BURST {
                self.refilled = now;
            }
        }
        if self.tokens == 0 {
            return false;
        }
        self.tokens -= 1;
        true
    }

    fn client(&mut self, conn: ConnId) -> Option<&mut Client> {
        self.clients.iter_mut().find(|c| c.open && c.conn.id() == conn)
    }
}

impl RtpSink for Sink<'_> {
    fn send_rows<S: FrameSource<Frame = usize>>(
        &mut self,
        to: &Dest,
        p: &Packetiser,
        first: &RowPacket,
        count: u16,
        slot: usize,
        source: &mut S,
    ) -> u16 {
        for k in 0..count {
            let packet = first.nth(k);
            match *to {
                Dest::Interleaved { conn, rtp_channel, .. } => {
                    let Some(c) = self.clients.iter().position(|c| c.open && c.conn.id() == conn) else {
                        return count;
                    };
                    if self.clients[c].room() < self.packet.len() {
                        return k;
                    }
                    self.packet[..4].copy_from_slice(&rtp::interleaved_head(rtp_channel, rtp::PACKET_BYTES as u16));
                    let (header, row) = self.packet[4..].split_at_mut(rtp::HEADER_BYTES);
                    if p.emit(&packet, header).is_err() || source.copy_row(slot, packet.row, 0, row) < ROW_BYTES {
                        continue;
                    }
                    self.clients[c].out.extend_from_slice(&self.packet);
                }
                Dest::Udp { .. } | Dest::Multicast(_) => {
                    if !self.take_token() {
                        return k;
                    }
                    let (header, row) = self.packet[4..].split_at_mut(rtp::HEADER_BYTES);
                    if p.emit(&packet, header).is_err() {
                        return k;
                    }
                    if source.copy_row(slot, packet.row, 0, &mut row[..ROW_BYTES]) < ROW_BYTES {
                        // Not in the slot (any more): nothing to send.
                        continue;
                    }
                    let to = match *to {
                        Dest::Udp { addr, rtp_port, .. } => SocketAddr::new(addr, rtp_port),
                        Dest::Multicast(g) => SocketAddr::new(IpAddr::V4(g.addr), g.port),
                        Dest::Interleaved { .. } => unreachable!("handled above"),
                    };
                    match self.rtp.send_to(&self.packet[4..], to) {
                        Ok(_) => {}
                        Err(e) if e.kind() == io::ErrorKind::WouldBlock => return k,
                        // An error of an earlier send (ICMP reported back
                        // on Linux, unattributable to a client here): the
                        // packet is gone like a lost one; the sender's RTCP
                        // silence ends a crashed client's stream.
                        Err(_) => {}
                    }
                }
            }
        }
        count
    }

    fn send_rtcp(&mut self, to: &Dest, datagram: &[u8]) -> bool {
        match *to {
            Dest::Udp { addr, rtcp_port, .. } => self.rtcp.send_to(datagram, SocketAddr::new(addr, rtcp_port)).is_ok(),
            Dest::Multicast(g) => {
                self.rtcp.send_to(datagram, SocketAddr::new(IpAddr::V4(g.addr), g.port.wrapping_add(1))).is_ok()
            }
            Dest::Interleaved { conn, rtcp_channel, .. } => {
                let Some(c) = self.client(conn) else { return false };
                if c.room() < 4 + datagram.len() {
                    return false;
                }
                c.out.extend_from_slice(&rtp::interleaved_head(rtcp_channel, datagram.len() as u16));
                c.out.extend_from_slice(datagram);
                true
            }
        }
    }
}

/// Entropy for the session ids and SSRCs: the kernel's (`/dev/urandom`),
/// with the time and process id in case it cannot be read.
fn entropy() -> [u8; 48] {
    let mut seed = [0u8; 48];
    let _ = std::fs::File::open("/dev/urandom").and_then(|mut f| f.read_exact(&mut seed[..32]));
    let nanos = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    seed[32..48].copy_from_slice(&(nanos ^ u128::from(std::process::id()) << 96).to_le_bytes());
    seed
}

fn run<S: SlotSource>(
    sockets: Sockets,
    mut ring: S,
    options: Options,
    stop: &AtomicBool,
    log: &mut Log,
) -> io::Result<()> {
    let start = StdInstant::now();
    let now = || Instant::from_millis(start.elapsed().as_millis() as u64);
    let wall = || ntp_timestamp(SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default());
    let server_ip = match sockets.listener.local_addr()?.ip() {
        IpAddr::V4(ip) if !ip.is_unspecified() => ip,
        _ => Ipv4Addr::LOCALHOST,
    };
    let (x, y, z) = LIVE_LIGHT;
    let live_light = Light::from_world(x, y, z).map_err(|e| io::Error::other(format!("{e:?}")))?;
    let rtp_port = sockets.rtp.local_addr()?.port();
    let mut server: Server<MAX_SESSIONS> = Server::new(rtsp::Config { server_ip, rtp_port, udp: options.udp });
    let mut camera: Box<Camera<MAX_SESSIONS>> = Box::new(Camera::new());
    camera.configure(sender::Config {
        live_light,
        multicast: options.multicast,
        cname: sender::Cname::for_address(server_ip),
    });
    let mut clients: Vec<Client> = Vec::new();
    let mut rng = SessionRng::new(&entropy());
    let mut next_conn = 0u32;
    let mut response = [0u8; MAX_RESPONSE_BYTES];
    let mut datagram = [0u8; 2048];
    let mut input = [0u8; 4096];
    let mut tokens = (BURST, StdInstant::now());
    let mut groups = Joined::default();
    while !stop.load(Ordering::SeqCst) {
        let mut busy = false;
        // New connections, up to the board's number; more are closed at once.
        loop {
            match sockets.listener.accept() {
                Ok((stream, peer)) => {
                    busy = true;
                    if clients.len() >= CONNECTIONS {
                        let _ = writeln!(log, "rtsp: connection from {peer} refused: {CONNECTIONS} open");
                        continue;
                    }
                    if !rtsp::admits(clients.iter().map(|c| c.conn.peer()), peer.ip()) {
                        let _ = writeln!(
                            log,
                            "rtsp: connection from {peer} refused: {CONNECTIONS_PER_ADDRESS} open from it"
                        );
                        continue;
                    }
                    stream.set_nonblocking(true)?;
                    let _ = stream.set_nodelay(true);
                    next_conn = next_conn.wrapping_add(1);
                    let id = ConnId(next_conn);
                    let _ = writeln!(log, "rtsp: connection from {peer} ({id})");
                    let conn = Connection::new(id, peer.ip(), now());
                    clients.push(Client { stream, conn, pending: vec![], out: vec![], open: true });
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) => return Err(e),
            }
        }
        // Requests.
        for c in clients.iter_mut() {
            match c.stream.read(&mut input) {
                Ok(0) => c.open = false,
                Ok(n) => {
                    c.pending.extend_from_slice(&input[..n]);
                    busy = true;
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {}
                Err(_) => c.open = false,
            }
            loop {
                let taken = c.conn.receive(now(), &c.pending);
                c.pending.drain(..taken);
                if c.out.len() + MAX_RESPONSE_BYTES > CLIENT_OUT_BYTES {
                    break; // its responses wait until it reads
                }
                let streams = Bound { camera: &mut camera, source: &mut ring, now: now(), wall: wall() };
                let mut station = Station { server: &mut server, streams };
                let Some(reply) = station.answer(&mut c.conn, &mut rng, &mut response, log) else { break };
                c.out.extend_from_slice(&response[..reply.len]);
                if reply.close {
                    break;
                }
            }
            if !c.flush() {
                c.open = false;
            }
            if c.open && server.connection_expired(&c.conn, now()) && c.out.is_empty() {
                let _ = writeln!(log, "rtsp: connection {} closed at its deadline", c.conn.id());
                c.open = false;
            }
        }
        {
            let streams = Bound { camera: &mut camera, source: &mut ring, now: now(), wall: wall() };
            let mut station = Station { server: &mut server, streams };
            for c in clients.iter().filter(|c| !c.open) {
                station.connection_closed(c.conn.id(), log);
            }
            // Sessions gone quiet.
            station.expire_sessions(log);
        }
        clients.retain(|c| c.open);
        let mut sink = Sink {
            rtp: &sockets.rtp,
            rtcp: &sockets.rtcp,
            clients: &mut clients,
            packet: [0; 4 + rtp::PACKET_BYTES],
            tokens: tokens.0,
            refilled: tokens.1,
        };
        // RTCP: keep-alive, round trips and NACKs, from session clients only.
        for socket in std::iter::once(&sockets.rtcp).chain(sockets.group_rtcp.as_ref()) {
            loop {
                match socket.recv_from(&mut datagram) {
                    Ok((n, from)) => {
                        let streams = Bound { camera: &mut camera, source: &mut ring, now: now(), wall: wall() };
                        Station { server: &mut server, streams }.rtcp(from, &datagram[..n], &mut sink);
                        busy = true;
                    }
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                    // ICMP errors of earlier sends surface here on some hosts.
                    Err(_) => break,
                }
            }
        }
        // Frames.
        for _ in 0..64 {
            if !camera.poll(now(), wall(), &mut ring, &mut sink) {
                break;
            }
            busy = true;
        }
        tokens = (sink.tokens, sink.refilled);
        let streams = Bound { camera: &mut camera, source: &mut ring, now: now(), wall: wall() };
        Station { server: &mut server, streams }.forget_ended(log);
        if let Some(g) = sockets.group_rtcp.as_ref() {
            groups.sync(&camera, g, server_ip, log);
        }
        for c in clients.iter_mut() {
            if !c.flush() {
                c.open = false;
            }
        }
        if !busy {
            // A stream waiting for the link or the renderer comes back soon.
            let wait = if camera.busy() { PACKET_TIME * 8 } else { Duration::from_millis(2) };
            thread::sleep(wait);
        }
    }
    Ok(())
}

/// The multicast groups the group RTCP socket has joined: each group a
/// multicast stream goes to, as the board joins them (its
/// `GroupMembership`).
#[derive(Default)]
struct Joined {
    groups: Vec<Ipv4Addr>,
    seen: Option<u32>,
}

impl Joined {
    fn sync<const N: usize>(&mut self, camera: &Camera<N>, socket: &UdpSocket, iface: Ipv4Addr, log: &mut Log) {
        if self.seen == Some(camera.output_changes()) {
            return;
        }
        self.seen = Some(camera.output_changes());
        let wanted: Vec<Ipv4Addr> = camera.multicast_groups().map(|g| g.addr).collect();
        for g in self.groups.iter().filter(|g| !wanted.contains(g)) {
            let _ = socket.leave_multicast_v4(g, &iface);
            let _ = writeln!(log, "rtsp: left multicast group {g}");
        }
        self.groups.retain(|g| wanted.contains(g));
        for g in wanted {
            if self.groups.contains(&g) {
                continue;
            }
            match socket.join_multicast_v4(&g, &iface) {
                Ok(()) => {
                    let _ = writeln!(log, "rtsp: joined multicast group {g}");
                    self.groups.push(g);
                }
                Err(e) => {
                    let _ = writeln!(log, "rtsp: joining multicast group {g}: {e}");
                }
            }
        }
    }
}
