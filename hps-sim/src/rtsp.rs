//! The simulated board as a network camera: `rt_services::camera::rtsp`'s server
//! and `rt_services::camera::sender`'s RTP sender on std sockets, drawing frames
//! from one frame ring that the simulated accelerator (or the RTL) fills,
//! as the board does.
//!
//! One thread runs it all, polling non-blocking sockets: RTSP on TCP, RTP
//! and RTCP on a pair of consecutive UDP ports. A row packet is its 20
//! header bytes and the row read from the ring's memory, sent with one
//! `send_to` (the host has no two-buffer DMA; the board's zero-copy path is
//! the firmware's).

use std::fmt::Write as _;
use std::io::{self, Read, Write};
use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant as StdInstant, SystemTime, UNIX_EPOCH};

use hal_avalon::sim::CountingDelay;
use hal_avalon::sim::SimAccelerator;
use hal_avalon::{Accelerator, PollTimeout};
use model::{Light, ROW_BYTES};
use rt_services::camera::rtp::{self, Packetiser, RowPacket};
use rt_services::camera::rtsp::{self, Action, Connection, Server, MAX_RESPONSE_BYTES, MAX_SESSIONS};
use rt_services::camera::sender::{Camera, Destination, RtpSink};
use rt_services::{FrameEngine, FrameMemory, FrameRing, Instant};

use crate::{Device, Log, SharedMemory, SIM_BUSY_POLLS};

/// Frame slots of the camera's ring: frames being rendered and sent, and
/// those the repair windows hold for resends (the board keeps six too).
pub const CAMERA_SLOTS: usize = 6;

/// The light of a live stream before its first `SET_PARAMETER` (the one
/// `rt-client` starts with).
pub const LIVE_LIGHT: (f64, f64, f64) = (3.0, 4.0, -2.0);

/// A running RTSP server; stops when dropped.
pub struct RtspServer {
    addr: SocketAddr,
    rtp_port: u16,
    stop: Arc<AtomicBool>,
    thread: Option<thread::JoinHandle<()>>,
}

impl RtspServer {
    /// Listen for RTSP on `addr` (port 0: any free one) and send RTP from
    /// a pair of free consecutive UDP ports on its address, rendering with
    /// `device`; log sessions to stderr if `verbose`.
    pub fn start(addr: SocketAddr, device: Device, verbose: bool) -> io::Result<RtspServer> {
        if device == Device::Rtl && !rtl_port::available() {
            return Err(io::Error::new(io::ErrorKind::Unsupported, rtl_port::NotBuilt));
        }
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let (rtp, rtcp) = udp_pair(addr.ip())?;
        let rtp_port = rtp.local_addr()?.port();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = thread::Builder::new().name("rtsp".into()).spawn(move || {
            let mut log = Log::new(0, verbose);
            let sockets = Sockets { listener, rtp, rtcp };
            let result = match device {
                Device::Sim => {
                    let mem = SharedMemory::new(CAMERA_SLOTS);
                    let sim = SimAccelerator::with_memory(mem.clone(), SIM_BUSY_POLLS);
                    let engine = Accelerator::new(sim, CountingDelay::default(), PollTimeout::DEFAULT);
                    run(sockets, FrameRing::new(mem.clone(), engine), mem, &flag, &mut log)
                }
                Device::Rtl => {
                    let mem = SharedMemory::new(CAMERA_SLOTS);
                    match rtl_port::RtlAccelerator::with_memory(mem.clone()) {
                        Ok(rtl) => {
                            let engine = Accelerator::new(rtl, CountingDelay::default(), PollTimeout::DEFAULT);
                            run(sockets, FrameRing::new(mem.clone(), engine), mem, &flag, &mut log)
                        }
                        Err(e) => Err(io::Error::new(io::ErrorKind::Unsupported, e)),
                    }
                }
            };
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
}

/// One RTSP connection.
struct Client {
    stream: TcpStream,
    conn: Connection,
    /// Received bytes the connection could not take yet.
    pending: Vec<u8>,
    open: bool,
}

/// The time one row packet takes on the board's Gigabit link: 1,502 bytes
/// of frame plus preamble, start delimiter, FCS and inter-packet gap
/// (8 + 4 + 12 bytes), at 1 bit per ns.
pub const PACKET_TIME: Duration = Duration::from_nanos((rtp::FRAME_HEADER_BYTES + ROW_BYTES + 24) as u64 * 8);

/// Packets the sink sends back to back before pacing sets in (the board's
/// transmit ring).
pub const BURST: u32 = 32;

/// Rows out of the ring's memory into UDP datagrams, no faster than the
/// board's link would carry them. Unpaced, a frame's 360 packets land in
/// the receiver's socket at once, and a socket buffer of the usual 208 KiB
/// (Linux `net.core.rmem_max`) holds about a third of a frame: every frame
/// would lose rows on the host that the board's link never sends that fast.
struct UdpSink<'a> {
    rtp: &'a UdpSocket,
    rtcp: &'a UdpSocket,
    mem: SharedMemory,
    packet: [u8; rtp::PACKET_BYTES],
    /// Token bucket: packets that may go now, as of `refilled`.
    tokens: u32,
    refilled: StdInstant,
}

impl UdpSink<'_> {
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
}

impl RtpSink for UdpSink<'_> {
    fn send_row(&mut self, to: &Destination, p: &Packetiser, packet: &RowPacket, slot: usize) -> bool {
        if !self.take_token() {
            return false;
        }
        let (header, row) = self.packet.split_at_mut(rtp::HEADER_BYTES);
        if p.emit(packet, header).is_err() {
            return false;
        }
        self.mem.read_row(slot, packet.row, 0, &mut row[..ROW_BYTES]);
        match self.rtp.send_to(&self.packet, SocketAddr::new(to.addr, to.rtp_port)) {
            Ok(_) => true,
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => false,
            // Unreachable client (ICMP port unreachable reported back):
            // the packet is gone like a lost one; the session times out.
            Err(_) => true,
        }
    }

    fn send_rtcp(&mut self, to: &Destination, datagram: &[u8]) -> bool {
        self.rtcp.send_to(datagram, SocketAddr::new(to.addr, to.rtcp_port)).is_ok()
    }
}

/// A small xorshift for session ids, SSRCs and initial sequence numbers
/// (RFC 3550 asks for unpredictable ones; nothing here is a secret, and a
/// random-number crate for three values would be more than they need).
fn random_source() -> impl FnMut() -> u32 {
    let seed = SystemTime::now().duration_since(UNIX_EPOCH).map_or(1, |d| d.as_nanos() as u64) | 1;
    let mut x = seed ^ u64::from(std::process::id()) << 32;
    move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 16) as u32
    }
}

fn wall_ntp() -> u64 {
    rt_services::camera::rtcp::ntp_timestamp(SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default())
}

fn run<E: FrameEngine<SharedMemory>>(
    sockets: Sockets,
    mut ring: FrameRing<SharedMemory, E, CAMERA_SLOTS>,
    mem: SharedMemory,
    stop: &AtomicBool,
    log: &mut Log,
) -> io::Result<()> {
    let start = StdInstant::now();
    let now = || Instant::from_millis(start.elapsed().as_millis() as u64);
    let server_ip = match sockets.listener.local_addr()?.ip() {
        IpAddr::V4(ip) if !ip.is_unspecified() => ip,
        _ => Ipv4Addr::LOCALHOST,
    };
    let (x, y, z) = LIVE_LIGHT;
    let live_light = Light::from_world(x, y, z).map_err(|e| io::Error::other(format!("{e:?}")))?;
    let rtp_port = sockets.rtp.local_addr()?.port();
    let mut server: Server<MAX_SESSIONS> = Server::new(rtsp::Config { server_ip, rtp_port, live_light });
    let mut camera: Box<Camera<MAX_SESSIONS>> = Box::new(Camera::new());
    let mut clients: Vec<Client> = Vec::new();
    let mut rng = random_source();
    let mut response = [0u8; MAX_RESPONSE_BYTES];
    let mut sink = UdpSink {
        rtp: &sockets.rtp,
        rtcp: &sockets.rtcp,
        mem,
        packet: [0; rtp::PACKET_BYTES],
        tokens: BURST,
        refilled: StdInstant::now(),
    };
    let mut datagram = [0u8; 2048];
    let mut input = [0u8; 4096];
    while !stop.load(Ordering::SeqCst) {
        let mut busy = false;
        // New connections.
        loop {
            match sockets.listener.accept() {
                Ok((stream, peer)) => {
                    stream.set_nonblocking(true)?;
                    let _ = stream.set_nodelay(true);
                    let _ = writeln!(log, "rtsp: connection from {peer}");
                    clients.push(Client { stream, conn: Connection::new(peer.ip()), pending: vec![], open: true });
                    busy = true;
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) => return Err(e),
            }
        }
        // Requests.
        for c in &mut clients {
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
                let taken = c.conn.receive(&c.pending);
                c.pending.drain(..taken);
                let Some(reply) = server.handle(&mut c.conn, now(), &mut rng, &mut response) else { break };
                let _ = writeln!(log, "rtsp: {} -> {}", c.conn.peer(), reply.status.code());
                if write_all_blocking(&c.stream, &response[..reply.len]).is_err() {
                    c.open = false;
                }
                if let Some(action) = reply.action {
                    apply(&mut server, &mut camera, action, now(), &mut ring, log);
                }
                if reply.close {
                    c.open = false;
                    break;
                }
            }
        }
        clients.retain(|c| c.open);
        // Sessions gone quiet.
        while let Some(action) = server.poll(now()) {
            apply(&mut server, &mut camera, action, now(), &mut ring, log);
        }
        // RTCP: keep-alive and NACKs, from session clients only.
        loop {
            match sockets.rtcp.recv_from(&mut datagram) {
                Ok((n, from)) => {
                    if server.rtcp_received(now(), from.ip(), from.port()).is_some() {
                        camera.rtcp_received(from.ip(), from.port(), &datagram[..n], &mut sink);
                    }
                    busy = true;
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                // ICMP errors of earlier sends surface here on some hosts.
                Err(_) => break,
            }
        }
        // Frames.
        for _ in 0..64 {
            if !camera.poll(now(), wall_ntp(), &mut ring, &mut sink) {
                break;
            }
            busy = true;
        }
        if !busy {
            // A stream waiting for the link or the renderer comes back soon.
            let wait = if camera.busy() { PACKET_TIME * 8 } else { Duration::from_millis(2) };
            thread::sleep(wait);
        }
    }
    Ok(())
}

fn apply<E: FrameEngine<SharedMemory>>(
    server: &mut Server<MAX_SESSIONS>,
    camera: &mut Camera<MAX_SESSIONS>,
    action: Action,
    now: Instant,
    ring: &mut FrameRing<SharedMemory, E, CAMERA_SLOTS>,
    log: &mut Log,
) {
    let _ = writeln!(log, "rtsp: {action:?}");
    if let Some((seq, rtptime)) = camera.apply(action, now, ring) {
        if let Action::Pause { session } = action {
            server.set_position(session, seq, rtptime);
        }
    }
}

/// Write a response on a non-blocking socket (responses are small: a
/// short wait for room is enough; a peer that never reads is dropped).
fn write_all_blocking(mut stream: &TcpStream, mut bytes: &[u8]) -> io::Result<()> {
    let deadline = StdInstant::now() + Duration::from_secs(2);
    while !bytes.is_empty() {
        match stream.write(bytes) {
            Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
            Ok(n) => bytes = &bytes[n..],
            Err(e) if e.kind() == io::ErrorKind::WouldBlock && StdInstant::now() < deadline => {
                thread::sleep(Duration::from_millis(1))
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}
