//! The network camera on smoltcp (feature `smoltcp`), as the firmware runs
//! it: [`rtsp::Server`] on [`RTSP_SOCKETS`] TCP sockets listening on
//! [`RTSP_PORT`], RTCP on a UDP socket on the RTP port + 1, and
//! [`Camera`]'s row packets handed, as a 62-byte header plus the row's
//! place in the frame ring, to a [`RowTransmitter`]: on the board the MAC's
//! two-buffer descriptors, so the CPU never touches a pixel. An
//! interleaved session's rows go through its RTSP socket instead (copied:
//! TCP needs the bytes in its buffer). smoltcp keeps ARP, ICMP and the
//! frame server's TCP beside it.
//!
//! # Connections
//!
//! Every RTSP socket holds one connection; a spare listens while the
//! others are taken, so the player after the last session gets its 453
//! rather than a refused connection. A connection is closed when the
//! server's deadlines say so (`rtsp::Server::connection_expired`: half a
//! request left for 5 s, or no session and no request for 10 s), and by
//! smoltcp when its peer stops answering, or when its handshake is never
//! finished ([`crate::tcp`]'s policy, the same for every service). One
//! address holds at most [`rtsp::CONNECTIONS_PER_ADDRESS`] of them.
//!
//! RTP leaves beside smoltcp: the next hop's MAC address and the ICMP
//! answers to the camera's packets come from the received frames
//! ([`super::snoop`]). The multicast groups the streams send to are joined
//! ([`GroupMembership`]) and their RTCP port read, so players' reports to a
//! group reach the board.

use core::fmt::Write;
use core::net::{IpAddr, Ipv4Addr, SocketAddrV4};

use smoltcp::iface::{SocketHandle, SocketSet};
use smoltcp::socket::{tcp, udp};
use smoltcp::time::Instant;
use smoltcp::wire::{EthernetAddress, IpEndpoint};

use super::frame_header::{Endpoints, HeaderTemplate, UdpChecksum, UNICAST_TTL};
use super::packetiser::Packetiser;
use super::random::SessionRng;
use super::rtsp::{
    self, ConnId, Connection, Server, CONNECTIONS, CONNECTIONS_PER_ADDRESS, MAX_RESPONSE_BYTES, MAX_SESSIONS, RTSP_PORT,
};
use super::sender::{Bound, Camera, Dest, RtpSink, SlotSource};
pub use super::snoop::{Snooped, Unreachable, PEERS, UNREACHABLE_NOTES};
use super::station::Station;
use super::wire::rtp::{interleaved_head, RowPacket, HEADER_BYTES};
use crate::frames::FrameSource;
pub use crate::snoop::{Snoop, SnoopRx};
use crate::tcp::{self as service_tcp, Listener};
use crate::time;

/// TCP sockets listening for RTSP: one per session's player and two
/// spares ([`rtsp::CONNECTIONS`]).
pub const RTSP_SOCKETS: usize = CONNECTIONS;

/// Transmit buffer of an RTSP socket: 64 KiB, 44 interleaved row packets
/// (RTP over the RTSP connection needs room for a run; responses alone
/// would need 2.5 KiB).
pub const RTSP_TX_BYTES: usize = 64 * 1024;

/// Most [`Camera::poll`] calls per [`CameraService::poll`], a bound of
/// last resort. One call already sends what the streams' frames have
/// landed, in runs, returning early when the transmitter says a frame was
/// received ([`RowTransmitter::receive_waiting`]: NACKs arrive only
/// through `Interface::poll`); more calls follow only while they move
/// something.
pub const MAX_POLLS: usize = 2 * crate::frames::ROWS as usize;

/// Largest RTCP datagram read (an Ethernet MTU's worth; longer ones are
/// cut, and a cut compound packet fails its length checks).
pub const RTCP_DATAGRAM_BYTES: usize = 1500;

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

/// One RTSP socket's buffers.
type RtspBuffers = crate::tcp::SocketBuffers<RTSP_TX_BYTES, { rtsp::MAX_REQUEST_BYTES }>;

/// Buffers of the service's sockets (in a `static` on the board).
pub struct CameraBuffers {
    rtsp: [RtspBuffers; RTSP_SOCKETS],
    rtcp_meta: [udp::PacketMetadata; 8],
    rtcp_rx: [u8; 4096],
    rtcp_tx_meta: [udp::PacketMetadata; 8],
    rtcp_tx: [u8; 1024],
    group_rtcp_meta: [udp::PacketMetadata; 8],
    group_rtcp_rx: [u8; 4096],
    group_rtcp_tx_meta: [udp::PacketMetadata; 1],
    group_rtcp_tx: [u8; 1],
}

impl CameraBuffers {
    /// Zeroed buffers (usable in a `static`).
    pub const fn new() -> CameraBuffers {
        CameraBuffers {
            rtsp: [const { RtspBuffers::new() }; RTSP_SOCKETS],
            rtcp_meta: [udp::PacketMetadata::EMPTY; 8],
            rtcp_rx: [0; 4096],
            rtcp_tx_meta: [udp::PacketMetadata::EMPTY; 8],
            rtcp_tx: [0; 1024],
            group_rtcp_meta: [udp::PacketMetadata::EMPTY; 8],
            group_rtcp_rx: [0; 4096],
            group_rtcp_tx_meta: [udp::PacketMetadata::EMPTY; 1],
            group_rtcp_tx: [0; 1],
        }
    }
}

impl Default for CameraBuffers {
    fn default() -> Self {
        CameraBuffers::new()
    }
}

/// One RTSP socket and its connection.
struct RtspSocket {
    handle: SocketHandle,
    conn: Option<Connection>,
    listener: Listener,
}

/// A UDP or multicast output's 62-byte header template, made when its
/// first packet goes.
struct Route {
    to: Dest,
    template: HeaderTemplate,
}

/// What the service has done, for logs and the bench.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ServiceStats {
    /// Rows handed to the transmitter, resends included.
    pub rows_sent: u32,
    /// Rows copied into RTSP connections (interleaved).
    pub rows_interleaved: u32,
    /// Row packets dropped because the next hop was unknown.
    pub no_route: u32,
    /// RTSP connections accepted.
    pub connections: u32,
    /// Connections closed at a deadline (an unfinished request, or idle
    /// without a session).
    pub expired: u32,
    /// RTCP datagrams from no session's client, dropped.
    pub stray_rtcp: u32,
}

/// The network camera bound to smoltcp sockets.
pub struct CameraService<'c> {
    server: Server<MAX_SESSIONS>,
    camera: &'c mut Camera<MAX_SESSIONS>,
    sockets: [RtspSocket; RTSP_SOCKETS],
    rtcp: SocketHandle,
    /// RTCP to the multicast groups' port (receivers' reports and NACKs,
    /// to a group the board joined or to the board itself).
    group_rtcp: Option<SocketHandle>,
    /// Whether a multicast stream runs (the group socket is read only
    /// then), as of the camera's output count `outputs_seen`.
    multicast_live: bool,
    outputs_seen: u32,
    /// [`Snooped::frames_seen`] when the RTCP sockets were last read: a
    /// datagram arrives only with a frame, so a poll with none reads
    /// nothing (the sockets are drained at each read).
    frames_read: Option<u32>,
    routes: [Option<Route>; MAX_SESSIONS],
    local_mac: EthernetAddress,
    rng: SessionRng,
    next_conn: u32,
    response: [u8; MAX_RESPONSE_BYTES],
    /// Where a received RTCP datagram is read (a field, not a local: a
    /// zeroed local would cost the main loop 1,500 bytes of stores every
    /// pass).
    datagram: [u8; RTCP_DATAGRAM_BYTES],
    /// What it has done.
    pub stats: ServiceStats,
}

impl<'c> CameraService<'c> {
    /// Add the service's sockets to `sockets`: [`RTSP_SOCKETS`] TCP sockets
    /// on [`RTSP_PORT`] and a UDP socket on `config.rtp_port + 1` (RTCP).
    /// `entropy` keys the session ids, SSRCs and sequence numbers
    /// ([`SessionRng`]); each connection stirs in the `entropy` given to
    /// [`poll`](Self::poll) when it arrives.
    pub fn new<'a>(
        sockets: &mut SocketSet<'a>,
        buffers: &'a mut CameraBuffers,
        camera: &'c mut Camera<MAX_SESSIONS>,
        config: rtsp::Config,
        local_mac: EthernetAddress,
        entropy: &[u8],
    ) -> Result<CameraService<'c>, udp::BindError> {
        let CameraBuffers {
            rtsp,
            rtcp_meta,
            rtcp_rx,
            rtcp_tx_meta,
            rtcp_tx,
            group_rtcp_meta,
            group_rtcp_rx,
            group_rtcp_tx_meta,
            group_rtcp_tx,
        } = buffers;
        let tcp_sockets = rtsp.each_mut().map(|b| RtspSocket {
            handle: sockets.add(b.socket()),
            conn: None,
            listener: Listener::new("rtsp:", None, RTSP_PORT),
        });
        let mut rtcp = udp::Socket::new(
            udp::PacketBuffer::new(&mut rtcp_meta[..], &mut rtcp_rx[..]),
            udp::PacketBuffer::new(&mut rtcp_tx_meta[..], &mut rtcp_tx[..]),
        );
        rtcp.bind(config.rtp_port.wrapping_add(1))?;
        let group_rtcp = match camera.multicast() {
            Some(m) => {
                let mut g = udp::Socket::new(
                    udp::PacketBuffer::new(&mut group_rtcp_meta[..], &mut group_rtcp_rx[..]),
                    udp::PacketBuffer::new(&mut group_rtcp_tx_meta[..], &mut group_rtcp_tx[..]),
                );
                g.bind(m.base_port.wrapping_add(1))?;
                Some(sockets.add(g))
            }
            None => None,
        };
        Ok(CameraService {
            server: Server::new(config),
            camera,
            sockets: tcp_sockets,
            rtcp: sockets.add(rtcp),
            group_rtcp,
            multicast_live: false,
            outputs_seen: 0,
            frames_read: None,
            routes: [const { None }; MAX_SESSIONS],
            local_mac,
            rng: SessionRng::new(entropy),
            next_conn: 0,
            response: [0; MAX_RESPONSE_BYTES],
            datagram: [0; RTCP_DATAGRAM_BYTES],
            stats: ServiceStats::default(),
        })
    }

    /// The RTSP server (its sessions).
    pub fn server(&self) -> &Server<MAX_SESSIONS> {
        &self.server
    }

    /// The RTP sender.
    pub fn camera(&self) -> &Camera<MAX_SESSIONS> {
        self.camera
    }

    /// The board's address changed (DHCP, link-local): descriptions, RTP
    /// packets and reports carry `ip` from now on. Sessions set up on the
    /// old address end as their clients find it gone.
    pub fn set_address(&mut self, ip: Ipv4Addr) {
        self.server.set_server_ip(ip);
        self.camera.set_cname(super::sender::Cname::for_address(ip));
    }

    /// One line per session the sender serves: what its output did (for a
    /// log a second: the hostile-network tests read the repair budget's
    /// effect from it).
    pub fn report(&self, log: &mut impl Write) {
        for (session, s) in self.camera.sessions() {
            let _ = writeln!(
                log,
                "camera: session {session}: {} frames, {} packets, {} resent ({} over budget, {} too soon, {} unrepairable, {} NACKs unread), {} cut, {} late, {} RTCP in",
                s.frames, s.packets, s.resent, s.over_budget, s.too_soon, s.unrepairable, s.nacks_unread, s.cut, s.late, s.reports
            );
        }
    }

    /// RTSP sockets listening for a connection.
    pub fn listening(&self, sockets: &SocketSet<'_>) -> usize {
        service_tcp::listening(sockets, self.sockets.iter().map(|s| s.handle))
    }

    /// Serve once: RTSP connections (requests, deadlines), session
    /// timeouts, RTCP (keep-alive, round trips and NACKs), what the
    /// received frames told ([`Snooped`]), then the streams' rows through
    /// `tx`. Call it after each `Interface::poll`; `entropy` (a fast
    /// counter's value) is stirred into the random numbers when a
    /// connection arrives.
    #[allow(clippy::too_many_arguments)]
    pub fn poll<S: SlotSource, T: RowTransmitter>(
        &mut self,
        now: Instant,
        sockets: &mut SocketSet<'_>,
        snooped: &mut Snooped,
        source: &mut S,
        tx: &mut T,
        entropy: u64,
        log: &mut impl Write,
    ) {
        let now_ms = time::Instant::from_millis(u64::try_from(now.total_millis()).unwrap_or(0));
        // The sender reports' clock: time since start (the board has no
        // other; receivers use it to pair RTP and NTP times, and the
        // round trip is measured on it).
        let wall =
            super::wire::rtcp::ntp_timestamp(core::time::Duration::from_micros(now.total_micros().max(0) as u64));
        for i in 0..RTSP_SOCKETS {
            self.serve_socket(i, now_ms, wall, sockets, source, entropy, log);
        }
        self.station(source, now_ms, wall).expire_sessions(log);
        while let Some(u) = snooped.take_unreachable() {
            self.camera.unreachable(IpAddr::V4(u.client), u.port, u.ssrc, now_ms, source);
        }
        let local = *self.server.config();
        let mut sink = Sink {
            tx,
            peers: snooped,
            routes: &mut self.routes,
            local: &local,
            local_mac: self.local_mac,
            sockets,
            rtcp: self.rtcp,
            rtsp: &self.sockets,
            stats: &mut self.stats,
        };
        if self.camera.output_changes() != self.outputs_seen {
            self.outputs_seen = self.camera.output_changes();
            self.multicast_live = self.camera.multicast_groups().next().is_some();
        }
        let group_rtcp = self.group_rtcp.filter(|_| self.multicast_live);
        if self.frames_read != Some(sink.peers.frames_seen()) {
            self.frames_read = Some(sink.peers.frames_seen());
            for handle in core::iter::once(self.rtcp).chain(group_rtcp) {
                let (server, camera, datagram) = (&mut self.server, &mut *self.camera, &mut self.datagram);
                read_rtcp(handle, server, camera, datagram, now_ms, wall, source, &mut sink);
            }
        }
        // Rounds until nothing moves, a frame was received (NACKs arrive
        // only through the next `Interface::poll`) or a stream began or
        // ended a frame: the rest of the main loop (the seed port, the
        // display) gets a turn at every frame edge, even where the
        // transmitter never fills (QEMU's MAC sends as soon as it is
        // handed a frame).
        let edges = self.camera.frame_edges();
        for _ in 0..MAX_POLLS {
            if !self.camera.poll(now_ms, wall, source, &mut sink)
                || sink.tx.receive_waiting()
                || self.camera.frame_edges() != edges
            {
                break;
            }
        }
        self.station(source, now_ms, wall).forget_ended(log);
        // Routes of outputs that are gone are dropped; a new output to the
        // same place makes its own (its own IPv4 identifications).
        let camera = &*self.camera;
        for r in &mut self.routes {
            if r.as_ref().is_some_and(|r| !camera_has(camera, &r.to)) {
                *r = None;
            }
        }
        source.set_held(self.camera.held());
    }

    #[allow(clippy::too_many_arguments)]
    fn serve_socket<S: SlotSource>(
        &mut self,
        i: usize,
        now: time::Instant,
        wall: u64,
        sockets: &mut SocketSet<'_>,
        source: &mut S,
        entropy: u64,
        log: &mut impl Write,
    ) {
        let socket = sockets.get_mut::<tcp::Socket>(self.sockets[i].handle);
        self.sockets[i].listener.reclaim(socket, now, log);
        if !socket.is_open() {
            if let Some(conn) = self.sockets[i].conn.take() {
                self.station(source, now, wall).connection_closed(conn.id(), log);
            }
        }
        let client = self.sockets[i].listener.accept(socket, log);
        if self.sockets[i].conn.is_none() {
            let Some(peer) = client else { return };
            let open = self.sockets.iter().filter_map(|s| s.conn.as_ref()).map(Connection::peer);
            if !rtsp::admits(open, IpAddr::from(peer.addr)) {
                let _ =
                    writeln!(log, "rtsp: client {peer} refused: {CONNECTIONS_PER_ADDRESS} connections open from it");
                socket.abort();
                return;
            }
            self.next_conn = self.next_conn.wrapping_add(1);
            let id = ConnId(self.next_conn);
            let _ = writeln!(log, "rtsp: client {peer} ({id})");
            // The arrival's time on a fast counter, and who arrived.
            let mut sample = [0u8; 14];
            sample[..8].copy_from_slice(&entropy.to_le_bytes());
            let smoltcp::wire::IpAddress::Ipv4(a) = peer.addr;
            sample[8..12].copy_from_slice(&a.octets());
            sample[12..].copy_from_slice(&peer.port.to_le_bytes());
            self.rng.stir(&sample);
            self.stats.connections = self.stats.connections.wrapping_add(1);
            self.sockets[i].conn = Some(Connection::new(id, IpAddr::from(peer.addr), now));
        }
        if !socket.may_recv() && socket.recv_queue() == 0 {
            // The client closed its side: its UDP sessions live on (RFC
            // 2326 section 3.1); the connection and what went through it go.
            socket.close();
            if let Some(conn) = self.sockets[i].conn.take() {
                self.station(source, now, wall).connection_closed(conn.id(), log);
            }
            return;
        }
        loop {
            let Some(conn) = self.sockets[i].conn.as_mut() else { return };
            let socket = sockets.get_mut::<tcp::Socket>(self.sockets[i].handle);
            while socket.can_recv() {
                match socket.recv(|buf| {
                    let n = conn.receive(now, buf);
                    (n, n)
                }) {
                    Ok(n) if n > 0 => {}
                    _ => break,
                }
            }
            if self.server.connection_expired(conn, now) {
                self.stats.expired = self.stats.expired.wrapping_add(1);
                let _ = writeln!(log, "rtsp: connection {} closed at its deadline", conn.id());
                let id = conn.id();
                socket.abort();
                self.sockets[i].conn = None;
                self.station(source, now, wall).connection_closed(id, log);
                return;
            }
            // Answer only what fits: a response is never cut, nor put
            // inside an interleaved packet (those go whole too).
            if socket.send_capacity() - socket.send_queue() < MAX_RESPONSE_BYTES {
                return;
            }
            let mut station = Station {
                server: &mut self.server,
                streams: Bound { camera: &mut *self.camera, source: &mut *source, now, wall },
            };
            let Some(reply) = station.answer(conn, &mut self.rng, &mut self.response, log) else { return };
            let _ = socket.send_slice(&self.response[..reply.len]);
            if reply.close {
                sockets.get_mut::<tcp::Socket>(self.sockets[i].handle).close();
                return;
            }
        }
    }

    /// The server and the sender with `source` at `now` (`wall` on the
    /// sender reports' clock).
    fn station<'s, S: SlotSource>(
        &'s mut self,
        source: &'s mut S,
        now: time::Instant,
        wall: u64,
    ) -> Station<'s, 's, S, MAX_SESSIONS> {
        Station { server: &mut self.server, streams: Bound { camera: &mut *self.camera, source, now, wall } }
    }
}

/// Read the RTCP datagrams waiting on socket `handle`: each from a
/// session's client keeps the session alive and goes to the sender (round
/// trips, NACKs); the rest are counted and dropped.
#[allow(clippy::too_many_arguments)]
fn read_rtcp<S: SlotSource, T: RowTransmitter>(
    handle: SocketHandle,
    server: &mut Server<MAX_SESSIONS>,
    camera: &mut Camera<MAX_SESSIONS>,
    datagram: &mut [u8; RTCP_DATAGRAM_BYTES],
    now: time::Instant,
    wall: u64,
    source: &mut S,
    sink: &mut Sink<'_, '_, T>,
) {
    loop {
        let socket = sink.sockets.get_mut::<udp::Socket>(handle);
        let Ok((n, meta)) = socket.recv_slice(datagram) else { break };
        let IpAddr::V4(from) = IpAddr::from(meta.endpoint.addr) else { continue };
        let from = IpAddr::V4(from);
        let port = meta.endpoint.port;
        let mut station =
            Station { server: &mut *server, streams: Bound { camera: &mut *camera, source: &mut *source, now, wall } };
        if !station.rtcp(core::net::SocketAddr::new(from, port), &datagram[..n], sink) {
            sink.stats.stray_rtcp = sink.stats.stray_rtcp.wrapping_add(1);
        }
    }
}

/// The multicast groups the camera wants the board in: each group a
/// multicast stream goes to, so that receivers' RTCP sent to the group
/// reaches the board through a switch that snoops IGMP. It names them to
/// the board's [`Membership`](crate::multicast::Membership), which joins
/// and reports them. Call [`sync`](Self::sync) after each camera poll; it
/// works only when the camera's outputs changed.
pub struct GroupMembership {
    joined: heapless::Vec<Ipv4Addr, MAX_SESSIONS>,
    seen: Option<u32>,
}

impl GroupMembership {
    /// No group joined.
    pub const fn new() -> GroupMembership {
        GroupMembership { joined: heapless::Vec::new(), seen: None }
    }

    /// The groups joined.
    pub fn joined(&self) -> &[Ipv4Addr] {
        &self.joined
    }

    /// Want the groups `camera` sends to and no others of the camera's.
    pub fn sync<const N: usize>(
        &mut self,
        camera: &Camera<N>,
        groups: &mut crate::multicast::Membership,
        log: &mut impl Write,
    ) {
        if self.seen == Some(camera.output_changes()) {
            return;
        }
        self.seen = Some(camera.output_changes());
        let wanted = |a: &Ipv4Addr| camera.multicast_groups().any(|g| g.addr == *a);
        while let Some(i) = self.joined.iter().position(|a| !wanted(a)) {
            let a = self.joined.swap_remove(i);
            groups.unwant(a);
            let _ = writeln!(log, "camera: left multicast group {a}");
        }
        for g in camera.multicast_groups() {
            if self.joined.contains(&g.addr) {
                continue;
            }
            if groups.want(g.addr) && self.joined.push(g.addr).is_ok() {
                let _ = writeln!(log, "camera: joined multicast group {}", g.addr);
            } else {
                let _ = writeln!(log, "camera: joining multicast group {}: no room", g.addr);
            }
        }
    }
}

impl Default for GroupMembership {
    fn default() -> Self {
        GroupMembership::new()
    }
}

/// Whether `camera` still has an output to `to`.
fn camera_has<const N: usize>(camera: &Camera<N>, to: &Dest) -> bool {
    camera.sessions().any(|(s, _)| camera.destination(s).as_ref() == Some(to))
}

/// The camera's way out: UDP and multicast rows through the transmitter
/// with a header template per output, interleaved rows and RTCP through
/// smoltcp's sockets.
struct Sink<'s, 'r, T> {
    tx: &'s mut T,
    peers: &'s Snooped,
    routes: &'s mut [Option<Route>; MAX_SESSIONS],
    local: &'s rtsp::Config,
    local_mac: EthernetAddress,
    sockets: &'s mut SocketSet<'r>,
    rtcp: SocketHandle,
    rtsp: &'s [RtspSocket; RTSP_SOCKETS],
    stats: &'s mut ServiceStats,
}

/// Why a packet has no route.
enum NoRoute {
    /// The next hop is not known (or not IPv4): the packet is dropped.
    Unknown,
    /// Every route is taken (never expected: one per output): try later.
    Full,
}

/// The Ethernet address of an IPv4 multicast group (RFC 1112 section 6.4:
/// 01-00-5E and the group's low 23 bits).
pub fn multicast_mac(group: Ipv4Addr) -> EthernetAddress {
    let [_, b, c, d] = group.octets();
    EthernetAddress([0x01, 0x00, 0x5e, b & 0x7f, c, d])
}

impl<T: RowTransmitter> Sink<'_, '_, T> {
    /// The route to `to` (UDP or multicast), made (with its header
    /// template) the first time a packet goes there.
    fn route(&mut self, to: &Dest, first_ident: u16) -> Result<usize, NoRoute> {
        if let Some(i) = self.routes.iter().position(|r| r.as_ref().is_some_and(|r| r.to == *to)) {
            return Ok(i);
        }
        let (dst_mac, dst, ttl) = match *to {
            // The board speaks IPv4 only.
            Dest::Udp { addr: IpAddr::V4(client), rtp_port, .. } => {
                let mac = self.peers.lookup(client).ok_or(NoRoute::Unknown)?;
                (mac, SocketAddrV4::new(client, rtp_port), UNICAST_TTL)
            }
            Dest::Multicast(g) => (multicast_mac(g.addr), SocketAddrV4::new(g.addr, g.port), g.ttl),
            _ => return Err(NoRoute::Unknown),
        };
        let endpoints = Endpoints {
            src_mac: self.local_mac,
            dst_mac,
            src: SocketAddrV4::new(self.local.server_ip, self.local.rtp_port),
            dst,
            ttl,
        };
        let checksum = if self.tx.checksum_offload() { UdpChecksum::Offload } else { UdpChecksum::Zero };
        let i = self.routes.iter().position(Option::is_none).ok_or(NoRoute::Full)?;
        self.routes[i] = Some(Route { to: *to, template: HeaderTemplate::new(&endpoints, checksum, first_ident) });
        Ok(i)
    }

    /// The RTSP socket of connection `conn`.
    fn connection(&self, conn: ConnId) -> Option<SocketHandle> {
        self.rtsp.iter().find(|s| s.conn.as_ref().is_some_and(|c| c.id() == conn)).map(|s| s.handle)
    }
}

/// Bytes of an interleaved row packet: `$`, channel, length, then the RTP
/// packet.
const INTERLEAVED_BYTES: usize = 4 + HEADER_BYTES + model::ROW_BYTES;

impl<T: RowTransmitter> RtpSink for Sink<'_, '_, T> {
    fn send_rows<S: FrameSource<Frame = usize>>(
        &mut self,
        to: &Dest,
        packetiser: &Packetiser,
        first: &RowPacket,
        count: u16,
        slot: usize,
        source: &mut S,
    ) -> u16 {
        if let Dest::Interleaved { conn, rtp_channel, .. } = *to {
            let Some(handle) = self.connection(conn) else { return count };
            let socket = self.sockets.get_mut::<tcp::Socket>(handle);
            // A client that reads nothing is asked every poll: answered
            // before a packet's worth of stack is even zeroed.
            if socket.send_capacity() - socket.send_queue() < INTERLEAVED_BYTES {
                return 0;
            }
            let mut packet = [0u8; INTERLEAVED_BYTES];
            packet[..4].copy_from_slice(&interleaved_head(rtp_channel, (HEADER_BYTES + model::ROW_BYTES) as u16));
            for k in 0..count {
                if socket.send_capacity() - socket.send_queue() < INTERLEAVED_BYTES {
                    return k;
                }
                let p = first.nth(k);
                let _ = packetiser.emit(&p, &mut packet[4..4 + HEADER_BYTES]);
                if source.copy_row(slot, p.row, 0, &mut packet[4 + HEADER_BYTES..]) < model::ROW_BYTES {
                    // Not the current frame's row (never expected): skipped
                    // like a lost one.
                    continue;
                }
                let _ = socket.send_slice(&packet);
                self.stats.rows_interleaved = self.stats.rows_interleaved.wrapping_add(1);
            }
            return count;
        }
        let route = match self.route(to, first.seq as u16) {
            Ok(i) => i,
            Err(NoRoute::Unknown) => {
                self.stats.no_route = self.stats.no_route.wrapping_add(u32::from(count));
                return count;
            }
            Err(NoRoute::Full) => return 0,
        };
        let Some(r) = self.routes[route].as_mut() else { return 0 };
        let sent = self.tx.send_run(&mut r.template, packetiser, first, count, slot);
        self.stats.rows_sent = self.stats.rows_sent.wrapping_add(u32::from(sent));
        sent
    }

    fn send_rtcp(&mut self, to: &Dest, datagram: &[u8]) -> bool {
        match *to {
            Dest::Udp { addr: IpAddr::V4(addr), rtcp_port, .. } => {
                let socket = self.sockets.get_mut::<udp::Socket>(self.rtcp);
                socket.send_slice(datagram, IpEndpoint::new(addr.into(), rtcp_port)).is_ok()
            }
            Dest::Multicast(g) => {
                let socket = self.sockets.get_mut::<udp::Socket>(self.rtcp);
                socket.set_hop_limit(Some(g.ttl));
                let sent = socket.send_slice(datagram, IpEndpoint::new(g.addr.into(), g.port.wrapping_add(1))).is_ok();
                socket.set_hop_limit(None);
                sent
            }
            Dest::Interleaved { conn, rtcp_channel, .. } => {
                let Some(handle) = self.connection(conn) else { return false };
                let socket = self.sockets.get_mut::<tcp::Socket>(handle);
                if socket.send_capacity() - socket.send_queue() < 4 + datagram.len() {
                    return false;
                }
                let head = interleaved_head(rtcp_channel, datagram.len() as u16);
                socket.send_slice(&head).is_ok() && socket.send_slice(datagram).is_ok()
            }
            Dest::Udp { addr: IpAddr::V6(_), .. } => false,
        }
    }

    fn should_yield(&mut self) -> bool {
        self.tx.receive_waiting()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multicast_groups_map_to_their_ethernet_address() {
        assert_eq!(multicast_mac(Ipv4Addr::new(239, 255, 42, 1)).0, [0x01, 0x00, 0x5e, 0x7f, 0x2a, 0x01]);
        assert_eq!(multicast_mac(Ipv4Addr::new(224, 128, 0, 9)).0, [0x01, 0x00, 0x5e, 0x00, 0x00, 0x09], "23 bits");
    }
}
