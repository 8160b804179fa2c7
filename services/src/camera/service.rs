//! The network camera on smoltcp (feature `smoltcp`), as the firmware runs
//! it: [`rtsp::Server`] on TCP sockets listening on [`RTSP_PORT`], RTCP on
//! a UDP socket on the RTP port + 1, and [`Camera`]'s row packets handed,
//! as a 62-byte header plus the row's place in the frame ring, to a
//! [`RowTransmitter`]: on the board the MAC's two-buffer descriptors, so
//! the CPU never touches a pixel. smoltcp keeps ARP, ICMP and the frame
//! server's TCP beside it.
//!
//! # The next hop
//!
//! RTP leaves beside smoltcp, so its Ethernet header needs the client's
//! (or its gateway's) MAC address. smoltcp 0.14 keeps its neighbour cache
//! to itself; [`PeerMacs`] learns the same thing from the frames that
//! arrive: the source MAC of the client's own IPv4 packets (its RTSP
//! connection) is the next hop towards it. [`Snoop`] wraps the MAC's
//! smoltcp device to feed it.

use core::fmt::Write;
use core::net::{IpAddr, Ipv4Addr, SocketAddrV4};

use smoltcp::iface::{SocketHandle, SocketSet};
use smoltcp::phy::{self, Device, DeviceCapabilities};
use smoltcp::socket::{tcp, udp};
use smoltcp::time::Instant;
use smoltcp::wire::{EthernetAddress, EthernetFrame, EthernetProtocol, IpEndpoint, Ipv4Packet};

use crate::camera::rtp::{Endpoints, HeaderTemplate, Packetiser, RowPacket, UdpChecksum};
use crate::camera::rtsp::{
    self, Action, Connection, Server, MAX_REQUEST_BYTES, MAX_RESPONSE_BYTES, MAX_SESSIONS, RTSP_PORT,
};
use crate::camera::sender::{Camera, Destination, RtpSink, SlotSource};
use crate::time;

/// TCP sockets listening for RTSP: two clients setting up at once.
pub const RTSP_SOCKETS: usize = 2;

/// Most [`Camera::poll`] calls per [`CameraService::poll`], a bound of
/// last resort. One call already sends what a frame has landed, in runs,
/// returning early when the transmitter says a frame was received
/// ([`RowTransmitter::receive_waiting`]: NACKs arrive only through
/// `Interface::poll`); more calls follow only while they move something
/// and no frame has completed. (Four short rounds a poll, the earlier
/// design, cost a main-loop iteration per eight rows on the emulated
/// board; 64 without the receive check let NACKs wait a frame time and
/// lossy-link repairs come too late.)
pub const MAX_POLLS: usize = 2 * crate::frames::ROWS as usize;

/// Peers remembered by [`PeerMacs`].
pub const PEERS: usize = 8;

/// The way rows leave: the board's zero-copy transmit path.
pub trait RowTransmitter {
    /// Send a run of `count` row packets of slot `slot`, one Ethernet
    /// frame each: the header (62 bytes of Ethernet, IPv4, UDP, RTP and
    /// RFC 4175 headers) [`HeaderTemplate::words`] of `template` for
    /// `first` and the packets after it ([`RowPacket::nth`]), then the row
    /// as it is in memory. Returns how many went, from the front (the
    /// rest found no room).
    fn send_run(
        &mut self,
        template: &mut HeaderTemplate,
        session: &Packetiser,
        first: &RowPacket,
        count: u16,
        slot: usize,
    ) -> u16;

    /// Whether the MAC computes the IPv4 and UDP checksums (else the UDP
    /// checksum is left zero, "none", as RFC 768 allows over IPv4).
    fn checksum_offload(&self) -> bool;

    /// Whether a received frame waits for `Interface::poll` (the camera's
    /// NACKs come that way): the camera then stops sending and lets the
    /// main loop take it in.
    fn receive_waiting(&self) -> bool;
}

/// IPv4 address to next-hop MAC, learnt from received frames; the newest
/// [`PEERS`] peers.
#[derive(Clone, Debug, Default)]
pub struct PeerMacs {
    entries: heapless::Deque<(Ipv4Addr, EthernetAddress), PEERS>,
}

impl PeerMacs {
    /// Nothing learnt.
    pub const fn new() -> PeerMacs {
        PeerMacs { entries: heapless::Deque::new() }
    }

    /// Learn from one received Ethernet frame (anything but IPv4 is
    /// ignored, as are broadcast and multicast sources).
    pub fn learn(&mut self, frame: &[u8]) {
        let Ok(eth) = EthernetFrame::new_checked(frame) else { return };
        if eth.ethertype() != EthernetProtocol::Ipv4 || !eth.src_addr().is_unicast() {
            return;
        }
        let Ok(ip) = Ipv4Packet::new_checked(eth.payload()) else { return };
        let (addr, mac) = (ip.src_addr(), eth.src_addr());
        if self.lookup(addr) == Some(mac) {
            return;
        }
        if let Some(i) = self.entries.iter().position(|(a, _)| *a == addr) {
            // Moved: forget the old entry (rare; keeps the order simple).
            let mut kept = heapless::Deque::new();
            for (j, e) in self.entries.iter().enumerate() {
                if j != i {
                    let _ = kept.push_back(*e);
                }
            }
            self.entries = kept;
        }
        if self.entries.is_full() {
            self.entries.pop_front();
        }
        let _ = self.entries.push_back((addr, mac));
    }

    /// The next hop towards `addr`, if a frame from it was seen.
    pub fn lookup(&self, addr: Ipv4Addr) -> Option<EthernetAddress> {
        self.entries.iter().rev().find(|(a, _)| *a == addr).map(|(_, m)| *m)
    }
}

/// A smoltcp device that lets [`PeerMacs`] see every received frame.
pub struct Snoop<'d, D> {
    /// The device.
    pub inner: &'d mut D,
    /// The table it feeds.
    pub peers: &'d mut PeerMacs,
}

/// A received frame's token, learning from the frame on its way in.
pub struct SnoopRx<'p, R> {
    inner: R,
    peers: &'p mut PeerMacs,
}

impl<R: phy::RxToken> phy::RxToken for SnoopRx<'_, R> {
    fn consume<T, F: FnOnce(&[u8]) -> T>(self, f: F) -> T {
        let peers = self.peers;
        self.inner.consume(|frame| {
            peers.learn(frame);
            f(frame)
        })
    }
}

impl<D: Device> Device for Snoop<'_, D> {
    type RxToken<'a>
        = SnoopRx<'a, D::RxToken<'a>>
    where
        Self: 'a;
    type TxToken<'a>
        = D::TxToken<'a>
    where
        Self: 'a;

    fn receive(&mut self, timestamp: Instant) -> Option<(Self::RxToken<'_>, Self::TxToken<'_>)> {
        let (rx, tx) = self.inner.receive(timestamp)?;
        Some((SnoopRx { inner: rx, peers: self.peers }, tx))
    }

    fn transmit(&mut self, timestamp: Instant) -> Option<Self::TxToken<'_>> {
        self.inner.transmit(timestamp)
    }

    fn capabilities(&self) -> DeviceCapabilities {
        self.inner.capabilities()
    }
}

/// Buffers of the service's sockets (in a `static` on the board).
pub struct CameraBuffers {
    rtsp: [([u8; MAX_REQUEST_BYTES], [u8; MAX_RESPONSE_BYTES * 2]); RTSP_SOCKETS],
    rtcp_meta: [udp::PacketMetadata; 8],
    rtcp_rx: [u8; 4096],
    rtcp_tx_meta: [udp::PacketMetadata; 4],
    rtcp_tx: [u8; 512],
}

impl CameraBuffers {
    /// Zeroed buffers (usable in a `static`).
    pub const fn new() -> CameraBuffers {
        CameraBuffers {
            rtsp: [([0; MAX_REQUEST_BYTES], [0; MAX_RESPONSE_BYTES * 2]); RTSP_SOCKETS],
            rtcp_meta: [udp::PacketMetadata::EMPTY; 8],
            rtcp_rx: [0; 4096],
            rtcp_tx_meta: [udp::PacketMetadata::EMPTY; 4],
            rtcp_tx: [0; 512],
        }
    }
}

impl Default for CameraBuffers {
    fn default() -> Self {
        CameraBuffers::new()
    }
}

/// One RTSP socket and its request buffer.
struct RtspSocket {
    handle: SocketHandle,
    conn: Option<Connection>,
}

/// A stream's 62-byte header template, made when its first packet goes.
struct Route {
    to: Destination,
    template: HeaderTemplate,
}

/// The network camera bound to smoltcp sockets.
pub struct CameraService<'c> {
    server: Server<MAX_SESSIONS>,
    camera: &'c mut Camera<MAX_SESSIONS>,
    sockets: [RtspSocket; RTSP_SOCKETS],
    rtcp: SocketHandle,
    routes: [Option<Route>; MAX_SESSIONS],
    local_mac: EthernetAddress,
    rng: u32,
    response: [u8; MAX_RESPONSE_BYTES],
    /// Rows handed to the transmitter, resends included.
    pub rows_sent: u32,
    /// Row packets dropped because the next hop was unknown.
    pub no_route: u32,
}

impl<'c> CameraService<'c> {
    /// Add the service's sockets to `sockets`: [`RTSP_SOCKETS`] TCP sockets
    /// on [`RTSP_PORT`] and a UDP socket on `config.rtp_port + 1` (RTCP).
    /// `seed` starts the session ids, SSRCs and sequence numbers (RFC 3550
    /// section 5.1 wants them unpredictable: a timer's ticks).
    pub fn new<'a>(
        sockets: &mut SocketSet<'a>,
        buffers: &'a mut CameraBuffers,
        camera: &'c mut Camera<MAX_SESSIONS>,
        config: rtsp::Config,
        local_mac: EthernetAddress,
        seed: u32,
    ) -> Result<CameraService<'c>, udp::BindError> {
        let CameraBuffers { rtsp, rtcp_meta, rtcp_rx, rtcp_tx_meta, rtcp_tx } = buffers;
        let tcp_sockets = rtsp.each_mut().map(|(rx, tx)| {
            let socket = tcp::Socket::new(tcp::SocketBuffer::new(&mut rx[..]), tcp::SocketBuffer::new(&mut tx[..]));
            RtspSocket { handle: sockets.add(socket), conn: None }
        });
        let mut rtcp = udp::Socket::new(
            udp::PacketBuffer::new(&mut rtcp_meta[..], &mut rtcp_rx[..]),
            udp::PacketBuffer::new(&mut rtcp_tx_meta[..], &mut rtcp_tx[..]),
        );
        rtcp.bind(config.rtp_port.wrapping_add(1))?;
        Ok(CameraService {
            server: Server::new(config),
            camera,
            sockets: tcp_sockets,
            rtcp: sockets.add(rtcp),
            routes: [const { None }; MAX_SESSIONS],
            local_mac,
            rng: seed | 1,
            response: [0; MAX_RESPONSE_BYTES],
            rows_sent: 0,
            no_route: 0,
        })
    }

    /// The RTSP server (its sessions).
    pub fn server(&self) -> &Server<MAX_SESSIONS> {
        &self.server
    }

    /// The RTP senders.
    pub fn camera(&self) -> &Camera<MAX_SESSIONS> {
        self.camera
    }

    /// Serve once: RTSP requests, session timeouts, RTCP (keep-alive and
    /// NACKs), then the streams' rows through `tx`. Call it after each
    /// `Interface::poll`; `held` says which slots the caller keeps besides
    /// the repair windows' (rows still in a descriptor), and the source
    /// learns the union.
    #[allow(clippy::too_many_arguments)]
    pub fn poll<S: SlotSource, T: RowTransmitter>(
        &mut self,
        now: Instant,
        sockets: &mut SocketSet<'_>,
        peers: &PeerMacs,
        source: &mut S,
        tx: &mut T,
        held: u32,
        log: &mut impl Write,
    ) {
        let now_ms = time::Instant::from_millis(u64::try_from(now.total_millis()).unwrap_or(0));
        for i in 0..RTSP_SOCKETS {
            self.serve_socket(i, now_ms, sockets, source, log);
        }
        while let Some(action) = self.server.poll(now_ms) {
            self.apply(action, now_ms, source, log);
        }
        let local = *self.server.config();
        let mut sink = Sink {
            tx,
            peers,
            routes: &mut self.routes,
            local: &local,
            local_mac: self.local_mac,
            rtcp: sockets.get_mut::<udp::Socket>(self.rtcp),
            rows_sent: &mut self.rows_sent,
            no_route: &mut self.no_route,
        };
        while let Ok((datagram, meta)) = sink.rtcp.recv() {
            let IpAddr::V4(from) = IpAddr::from(meta.endpoint.addr) else { continue };
            let from = IpAddr::V4(from);
            let mut copy = [0u8; 1500];
            let n = datagram.len().min(copy.len());
            copy[..n].copy_from_slice(&datagram[..n]);
            if self.server.rtcp_received(now_ms, from, meta.endpoint.port).is_some() {
                self.camera.rtcp_received(from, meta.endpoint.port, &copy[..n], &mut sink);
            } else {
                let _ = writeln!(log, "rtcp: {} bytes from {} ignored (no session of theirs)", n, meta.endpoint);
            }
        }
        // The wall clock of the sender reports: time since start (the board
        // has no other; receivers use it to pair RTP and NTP times only).
        let wall =
            crate::camera::rtcp::ntp_timestamp(core::time::Duration::from_micros(now.total_micros().max(0) as u64));
        // Rounds until nothing moves, a frame is complete or a frame was
        // received: NACKs arrive only through the next `Interface::poll`.
        let frames = |c: &Camera<MAX_SESSIONS>| c.streams().map(|s| s.stats().frames).fold(0u32, u32::wrapping_add);
        let before = frames(self.camera);
        for _ in 0..MAX_POLLS {
            if !self.camera.poll(now_ms, wall, source, &mut sink)
                || frames(self.camera) != before
                || sink.tx.receive_waiting()
            {
                break;
            }
        }
        source.set_held(self.camera.held() | held);
    }

    fn serve_socket<S: SlotSource>(
        &mut self,
        i: usize,
        now: time::Instant,
        sockets: &mut SocketSet<'_>,
        source: &mut S,
        log: &mut impl Write,
    ) {
        let socket = sockets.get_mut::<tcp::Socket>(self.sockets[i].handle);
        if socket.state() == tcp::State::TimeWait {
            socket.abort();
        }
        if !socket.is_open() {
            self.sockets[i].conn = None;
            if let Err(e) = socket.listen(RTSP_PORT) {
                let _ = writeln!(log, "rtsp: listen failed: {e:?}");
            }
            return;
        }
        if self.sockets[i].conn.is_none() {
            if socket.state() != tcp::State::Established {
                return;
            }
            let Some(peer) = socket.remote_endpoint() else { return };
            let _ = writeln!(log, "rtsp: client {peer}");
            self.sockets[i].conn = Some(Connection::new(IpAddr::from(peer.addr)));
        }
        if !socket.may_recv() && socket.recv_queue() == 0 {
            // The client closed its side: its sessions live on (RFC 2326
            // section 3.1); the connection goes.
            socket.close();
            self.sockets[i].conn = None;
            return;
        }
        loop {
            let Some(conn) = self.sockets[i].conn.as_mut() else { return };
            let socket = sockets.get_mut::<tcp::Socket>(self.sockets[i].handle);
            while socket.can_recv() {
                match socket.recv(|buf| {
                    let n = conn.receive(buf);
                    (n, n)
                }) {
                    Ok(n) if n > 0 => {}
                    _ => break,
                }
            }
            // Answer only what fits: a response is never cut.
            if socket.send_capacity() - socket.send_queue() < MAX_RESPONSE_BYTES {
                return;
            }
            let rng = &mut self.rng;
            let mut random = || xorshift(rng);
            let Some(reply) = self.server.handle(conn, now, &mut random, &mut self.response) else { return };
            let _ = socket.send_slice(&self.response[..reply.len]);
            let _ = writeln!(log, "rtsp: {} {}", reply.status.code(), reply.status.reason());
            let close = reply.close;
            if let Some(action) = reply.action {
                self.apply(action, now, source, log);
            }
            if close {
                sockets.get_mut::<tcp::Socket>(self.sockets[i].handle).close();
                self.sockets[i].conn = None;
                return;
            }
        }
    }

    fn apply<S: SlotSource>(&mut self, action: Action, now: time::Instant, source: &mut S, log: &mut impl Write) {
        match action {
            Action::Play { session, client_addr, rtp_port, .. } => {
                let _ = writeln!(log, "rtsp: session {session} plays to {client_addr}:{rtp_port}");
            }
            Action::Stop { session } | Action::Timeout { session } => match self.camera.stream(session) {
                Some(s) => {
                    let st = s.stats();
                    let _ = writeln!(
                        log,
                        "rtsp: session {session} ends: {} frames, {} packets, {} resent, {} not repairable, {} failed",
                        st.frames, st.packets, st.resent, st.unrepairable, st.failed
                    );
                }
                None => {
                    let _ = writeln!(log, "rtsp: session {session} ends");
                }
            },
            _ => {}
        }
        if let Some((seq, rtptime)) = self.camera.apply(action, now, source) {
            if let Action::Pause { session } = action {
                self.server.set_position(session, seq, rtptime);
            }
        }
        // Routes of streams that are gone are dropped; a new stream to the
        // same place makes its own (its own IPv4 identifications).
        let camera = &*self.camera;
        for r in &mut self.routes {
            if r.as_ref().is_some_and(|r| !camera.streams().any(|s| s.destination() == r.to)) {
                *r = None;
            }
        }
    }
}

/// The next of xorshift32 (Marsaglia 2003): unpredictable enough for RTP's
/// identifiers, none of which is a secret (a random-number crate for three
/// numbers a session would be more than they need).
fn xorshift(state: &mut u32) -> u32 {
    let mut x = *state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    x
}

/// The camera's way out through the transmitter, with a header per stream.
struct Sink<'s, 'r, T> {
    tx: &'s mut T,
    peers: &'s PeerMacs,
    routes: &'s mut [Option<Route>; MAX_SESSIONS],
    local: &'s rtsp::Config,
    local_mac: EthernetAddress,
    rtcp: &'s mut udp::Socket<'r>,
    rows_sent: &'s mut u32,
    no_route: &'s mut u32,
}

impl<T: RowTransmitter> Sink<'_, '_, T> {
    /// The route to `to`, made (with its header template) the first time a
    /// packet goes there; `None` while the next hop is unknown, or if
    /// every route is taken.
    fn route(&mut self, to: &Destination, first_ident: u16) -> Result<usize, NoRoute> {
        if let Some(i) = self.routes.iter().position(|r| r.as_ref().is_some_and(|r| r.to == *to)) {
            return Ok(i);
        }
        // The board speaks IPv4 only.
        let IpAddr::V4(client) = to.addr else { return Err(NoRoute::Unknown) };
        let Some(dst_mac) = self.peers.lookup(client) else { return Err(NoRoute::Unknown) };
        let endpoints = Endpoints {
            src_mac: self.local_mac,
            dst_mac,
            src: SocketAddrV4::new(self.local.server_ip, self.local.rtp_port),
            dst: SocketAddrV4::new(client, to.rtp_port),
        };
        let checksum = if self.tx.checksum_offload() { UdpChecksum::Offload } else { UdpChecksum::Zero };
        let i = self.routes.iter().position(Option::is_none).ok_or(NoRoute::Full)?;
        self.routes[i] = Some(Route { to: *to, template: HeaderTemplate::new(&endpoints, checksum, first_ident) });
        Ok(i)
    }
}

/// Why a packet has no route.
enum NoRoute {
    /// The next hop is not known (or not IPv4): the packet is dropped.
    Unknown,
    /// Every route is taken (never expected: one per stream): try later.
    Full,
}

impl<T: RowTransmitter> RtpSink for Sink<'_, '_, T> {
    fn send_row(&mut self, to: &Destination, packetiser: &Packetiser, packet: &RowPacket, slot: usize) -> bool {
        self.send_rows(to, packetiser, packet, 1, slot) == 1
    }

    fn send_rows(
        &mut self,
        to: &Destination,
        packetiser: &Packetiser,
        first: &RowPacket,
        count: u16,
        slot: usize,
    ) -> u16 {
        let route = match self.route(to, first.seq as u16) {
            Ok(i) => i,
            Err(NoRoute::Unknown) => {
                *self.no_route += u32::from(count);
                return count;
            }
            Err(NoRoute::Full) => return 0,
        };
        let Some(r) = self.routes[route].as_mut() else { return 0 };
        let sent = self.tx.send_run(&mut r.template, packetiser, first, count, slot);
        *self.rows_sent = self.rows_sent.wrapping_add(u32::from(sent));
        sent
    }

    fn send_rtcp(&mut self, to: &Destination, datagram: &[u8]) -> bool {
        let IpAddr::V4(addr) = to.addr else { return false };
        let endpoint = IpEndpoint::new(addr.into(), to.rtcp_port);
        self.rtcp.send_slice(datagram, endpoint).is_ok()
    }

    fn should_yield(&mut self) -> bool {
        self.tx.receive_waiting()
    }
}
