//! The frame service and the network camera on smoltcp, tested over an
//! in-memory Ethernet link between two smoltcp interfaces: one runs the
//! service, the other clients.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use model::{render_frame, Light, FRAME_BYTES};
use rt_services::camera::frame_header::FRAME_HEADER_BYTES;
use rt_services::camera::packetiser::Packetiser;
use rt_services::camera::service::RowTransmitter;
use rt_services::camera::wire::rtp::RowPacket;
use rt_services::seed::service::{FrameService, SocketBuffers};
use rt_services::{
    encode_raw_request, encode_request, FrameRing, FrameSource, RowEngine, RowFrames, SliceMemory, SoftwareRenderer,
    FRAME_PORT, PERSISTENT_PORT,
};
use smoltcp::iface::{Config, Interface, SocketHandle, SocketSet};
use smoltcp::phy::{self, Device, DeviceCapabilities, Medium};
use smoltcp::socket::tcp;
use smoltcp::time::Instant;
use smoltcp::wire::{EthernetAddress, IpAddress, IpCidr, Ipv4Address};

type Queue = Rc<RefCell<VecDeque<Vec<u8>>>>;

/// Faults of a lossy cable, per frame and direction, from a seeded
/// generator (the same run every time).
#[derive(Clone, Copy, Debug, Default)]
struct Faults {
    drop: f64,
    reorder: f64,
    corrupt: f64,
}

/// The cable's fault state: the generator and what it did.
#[derive(Default)]
struct Injector {
    faults: Faults,
    state: u64,
    dropped: u64,
    reordered: u64,
    corrupted: u64,
}

impl Injector {
    fn chance(&mut self, p: f64) -> bool {
        // SplitMix64.
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        p > 0.0 && (((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64) < p
    }

    /// Put `frame` on `queue`, or lose, damage or reorder it.
    fn send(&mut self, queue: &mut VecDeque<Vec<u8>>, mut frame: Vec<u8>) {
        if self.chance(self.faults.drop) {
            self.dropped += 1;
            return;
        }
        if frame.len() > 14 && self.chance(self.faults.corrupt) {
            let i = 14 + (self.state as usize) % (frame.len() - 14);
            frame[i] ^= 0x10;
            self.corrupted += 1;
        }
        if !queue.is_empty() && self.chance(self.faults.reorder) {
            // Overtake the frame queued before it.
            let last = queue.len() - 1;
            queue.insert(last, frame);
            self.reordered += 1;
            return;
        }
        queue.push_back(frame);
    }
}

type Shared = Rc<RefCell<Injector>>;

/// One end of a point-to-point Ethernet cable.
struct CableEnd {
    rx: Queue,
    tx: Queue,
    faults: Shared,
}

fn cable_with(faults: Faults, seed: u64) -> (CableEnd, CableEnd) {
    let (a, b) = (Queue::default(), Queue::default());
    let f = Rc::new(RefCell::new(Injector { faults, state: seed, ..Injector::default() }));
    (CableEnd { rx: a.clone(), tx: b.clone(), faults: f.clone() }, CableEnd { rx: b, tx: a, faults: f })
}

struct Rx(Vec<u8>);
struct Tx(Queue, Shared);

impl phy::RxToken for Rx {
    fn consume<R, F: FnOnce(&[u8]) -> R>(self, f: F) -> R {
        f(&self.0)
    }
}

impl phy::TxToken for Tx {
    fn consume<R, F: FnOnce(&mut [u8]) -> R>(self, len: usize, f: F) -> R {
        let mut frame = vec![0u8; len];
        let r = f(&mut frame);
        self.1.borrow_mut().send(&mut self.0.borrow_mut(), frame);
        r
    }
}

impl Device for CableEnd {
    type RxToken<'a> = Rx;
    type TxToken<'a> = Tx;

    fn receive(&mut self, _: Instant) -> Option<(Rx, Tx)> {
        let frame = self.rx.borrow_mut().pop_front()?;
        Some((Rx(frame), Tx(self.tx.clone(), self.faults.clone())))
    }

    fn transmit(&mut self, _: Instant) -> Option<Tx> {
        Some(Tx(self.tx.clone(), self.faults.clone()))
    }

    fn capabilities(&self) -> DeviceCapabilities {
        let mut caps = DeviceCapabilities::default();
        caps.medium = Medium::Ethernet;
        caps.max_transmission_unit = 1514;
        caps
    }
}

fn interface(device: &mut CableEnd, last_octet: u8) -> Interface {
    let mac = EthernetAddress([0x02, 0, 0, 0, 0, last_octet]);
    let mut iface = Interface::new(Config::new(mac.into()), device, Instant::ZERO);
    iface.update_ip_addrs(|a| {
        a.push(IpCidr::new(IpAddress::v4(10, 0, 0, last_octet), 24)).expect("one address");
    });
    iface
}

const SERVER: Ipv4Address = Ipv4Address::new(10, 0, 0, 1);

fn frame(light: &Light) -> Vec<u8> {
    render_frame(light)
}

fn request(light: &Light) -> [u8; 12] {
    encode_request(light)
}

struct Client {
    handle: SocketHandle,
    send: Vec<u8>,
    close_after_send: bool,
    /// Reset the connection once this many bytes have arrived.
    abort_after: Option<usize>,
    /// Connect only from this step on.
    start_step: u64,
    /// Remote port and local port, until connected.
    pending_connect: Option<(u16, u16)>,
    received: Vec<u8>,
}

/// Where the server's frames come from.
#[derive(Clone, Copy, Debug)]
enum Mode {
    /// Row mode: rendered a row at a time as they are sent.
    Rows,
    /// Frame mode: a ring of two frame slots filled by a software engine.
    Ring,
}

const MODES: [Mode; 2] = [Mode::Rows, Mode::Ring];

/// The cable with an interface at each end (server 10.0.0.1, clients 10.0.0.2).
struct Link {
    mode: Mode,
    server_dev: CableEnd,
    client_dev: CableEnd,
    server_if: Interface,
    client_if: Interface,
    clients: SocketSet<'static>,
    /// After its first poll (its sockets listen), the service is polled
    /// again from this step on (a main loop busy elsewhere while the
    /// client connects, sends and closes).
    service_starts: u64,
}

impl Link {
    fn new(mode: Mode) -> Link {
        Link::lossy(mode, Faults::default(), 0)
    }

    fn lossy(mode: Mode, faults: Faults, seed: u64) -> Link {
        let (mut server_dev, mut client_dev) = cable_with(faults, seed);
        let server_if = interface(&mut server_dev, 1);
        let client_if = interface(&mut client_dev, 2);
        Link { mode, server_dev, client_dev, server_if, client_if, clients: SocketSet::new(vec![]), service_starts: 0 }
    }

    fn connect(&mut self, port: u16, local_port: u16, send: Vec<u8>, close_after_send: bool) -> Client {
        let s = tcp::Socket::new(tcp::SocketBuffer::new(vec![0; 65535]), tcp::SocketBuffer::new(vec![0; 4096]));
        Client {
            handle: self.clients.add(s),
            send,
            close_after_send,
            abort_after: None,
            start_step: 0,
            pending_connect: Some((port, local_port)),
            received: Vec::new(),
        }
    }

    /// Run the service and the clients in 1 ms steps until every client
    /// has seen the server close (or `max_steps` pass). Returns the log.
    fn run(&mut self, clients: &mut [Client], max_steps: u64) -> String {
        match self.mode {
            Mode::Rows => self.run_with(clients, max_steps, &mut RowFrames::<_, 4>::new(SoftwareRenderer)),
            Mode::Ring => {
                let mut memory = vec![0u8; 2 * FRAME_BYTES];
                let mut ring =
                    FrameRing::<_, _, 2>::new(SliceMemory::new(0, &mut memory), RowEngine::new(SoftwareRenderer));
                let log = self.run_with(clients, max_steps, &mut ring);
                assert_eq!(ring.free_slots(), 2, "every slot given back; log: {log}");
                log
            }
        }
    }

    fn run_with<S: FrameSource<Frame = usize>>(
        &mut self,
        clients: &mut [Client],
        max_steps: u64,
        frames: &mut S,
    ) -> String {
        let mut buffers: Box<[SocketBuffers; 4]> = Box::default();
        let mut server_sockets = SocketSet::new(vec![]);
        let mut service = FrameService::new(&mut server_sockets, &mut buffers, 2);
        let mut log = String::new();
        for step in 0..max_steps {
            let now = Instant::from_millis(step as i64);
            self.server_if.poll(now, &mut self.server_dev, &mut server_sockets);
            if step == 0 || step >= self.service_starts {
                service.poll(now, &mut server_sockets, frames, &mut log);
            }
            self.server_if.poll(now, &mut self.server_dev, &mut server_sockets);
            self.client_if.poll(now, &mut self.client_dev, &mut self.clients);
            let mut open = 0;
            for c in clients.iter_mut() {
                if step < c.start_step {
                    open += 1;
                    continue;
                }
                let s = self.clients.get_mut::<tcp::Socket>(c.handle);
                if let Some((port, local)) = c.pending_connect.take() {
                    s.connect(self.client_if.context(), (IpAddress::Ipv4(SERVER), port), local).expect("connect");
                    open += 1;
                    continue;
                }
                if c.abort_after.is_some_and(|n| c.received.len() >= n) {
                    if s.is_open() {
                        s.abort();
                    }
                    continue;
                }
                if s.can_send() && !c.send.is_empty() {
                    let n = s.send_slice(&c.send).expect("client send");
                    c.send.drain(..n);
                    if c.send.is_empty() && c.close_after_send {
                        s.close();
                    }
                }
                while s.can_recv() {
                    s.recv(|b| {
                        c.received.extend_from_slice(b);
                        (b.len(), ())
                    })
                    .expect("client recv");
                }
                if s.state() == tcp::State::CloseWait {
                    // The server finished: close our side too.
                    s.close();
                }
                if s.may_recv() || matches!(s.state(), tcp::State::SynSent | tcp::State::SynReceived) {
                    open += 1;
                }
            }
            if open == 0 {
                break;
            }
        }
        log
    }
}

#[test]
fn single_port_serves_the_seed_protocol() {
    for mode in MODES {
        let lights = [Light::from_world(3.0, 4.0, -2.0).unwrap(), Light::from_world(-1.5, 2.5, 2.0).unwrap()];
        for light in lights {
            let mut link = Link::new(mode);
            let mut clients = [link.connect(FRAME_PORT, 50_000, request(&light).to_vec(), false)];
            let log = link.run(&mut clients, 20_000);
            assert_eq!(clients[0].received.len(), FRAME_BYTES, "log: {log}");
            assert!(clients[0].received == frame(&light), "frame differs from the model ({mode:?})");
            assert!(log.contains("request light raw"), "{log}");
            assert!(log.contains("done"), "{log}");
        }
    }
}

#[test]
fn persistent_port_pipelines_frames_in_order() {
    for mode in MODES {
        let lights = [
            Light::from_world(3.0, 4.0, -2.0).unwrap(),
            Light::from_world(0.0, 8.0, 0.0).unwrap(),
            Light::from_world(-3.0, 1.0, 1.0).unwrap(),
        ];
        let bytes: Vec<u8> = lights.iter().flat_map(request).collect();
        let mut link = Link::new(mode);
        let mut clients = [link.connect(PERSISTENT_PORT, 50_001, bytes, true)];
        let log = link.run(&mut clients, 60_000);
        let want: Vec<u8> = lights.iter().flat_map(frame).collect();
        assert_eq!(clients[0].received.len(), want.len(), "log: {log}");
        assert!(clients[0].received == want, "frames differ from the model");
    }
}

#[test]
fn two_clients_at_once_and_a_bad_request() {
    for mode in MODES {
        let a = Light::from_world(2.0, 3.0, -1.0).unwrap();
        let b = Light::from_world(-2.0, 3.0, -1.0).unwrap();
        let [_, y, z] = a.raw();
        let bad = encode_raw_request([1 << 23, y, z]);
        let mut link = Link::new(mode);
        let mut clients = [
            link.connect(FRAME_PORT, 50_010, request(&a).to_vec(), false),
            link.connect(PERSISTENT_PORT, 50_011, request(&b).to_vec(), true),
            link.connect(FRAME_PORT, 50_012, bad.to_vec(), false),
        ];
        let log = link.run(&mut clients, 60_000);
        assert!(clients[0].received == frame(&a), "client a; log: {log}");
        assert!(clients[1].received == frame(&b), "client b; log: {log}");
        assert!(clients[2].received.is_empty(), "bad request gets no frame bytes");
        assert!(log.contains("closing: bad request"), "{log}");
    }
}

#[test]
fn client_vanishing_mid_frame_does_not_stop_the_next() {
    for mode in MODES {
        let light = Light::from_world(3.0, 4.0, -2.0).unwrap();
        let mut link = Link::new(mode);
        let mut quitter = link.connect(FRAME_PORT, 50_020, request(&light).to_vec(), false);
        quitter.abort_after = Some(100_000);
        // Two more clients, one after the other, after the quitter has gone: the
        // second of them needs the quitter's socket listening again (two sockets
        // serve the port).
        let mut next = link.connect(FRAME_PORT, 50_021, request(&light).to_vec(), false);
        next.start_step = 1_000;
        let mut last = link.connect(FRAME_PORT, 50_022, request(&light).to_vec(), false);
        last.start_step = 1_001;
        let mut clients = [quitter, next, last];
        let log = link.run(&mut clients, 60_000);
        assert!(clients[0].received.len() < FRAME_BYTES, "the quitter left early");
        assert!(log.contains("vanished mid-frame"), "{log}");
        assert!(clients[1].received == frame(&light), "next client served; log: {log}");
        assert!(clients[2].received == frame(&light), "last client served; log: {log}");
    }
}

#[test]
fn frames_stay_byte_exact_over_a_lossy_link() {
    let (a, b) = (Light::from_world(3.0, 4.0, -2.0).unwrap(), Light::from_world(-4.0, 6.0, -3.0).unwrap());
    for (name, faults) in [
        ("2% drop, 1% reorder, 1% corrupt", Faults { drop: 0.02, reorder: 0.01, corrupt: 0.01 }),
        ("10% drop, 1% reorder, 1% corrupt", Faults { drop: 0.10, reorder: 0.01, corrupt: 0.01 }),
    ] {
        let mut link = Link::lossy(Mode::Ring, faults, 11);
        let two: Vec<u8> = [request(&a), request(&b)].concat();
        let mut clients = [
            link.connect(PERSISTENT_PORT, 50_030, two, true),
            link.connect(FRAME_PORT, 50_031, request(&b).to_vec(), false),
        ];
        // 1 ms steps: smoltcp's retransmission timeout (at least 1 s) needs
        // room.
        let log = link.run(&mut clients, 900_000);
        let f = link.server_dev.faults.borrow();
        println!(
            "lossy link, {name}: {} dropped, {} reordered, {} corrupted; frames byte-exact",
            f.dropped, f.reordered, f.corrupted
        );
        assert!(f.dropped > 0, "{name}: the link lost nothing");
        assert!(clients[0].received == [frame(&a), frame(&b)].concat(), "{name}: persistent client; log: {log}");
        assert!(clients[1].received == frame(&b), "{name}: seed client; log: {log}");
    }
}

// ---- The network camera over the same cable ------------------------------------------

/// Row packets as the board's MAC would get them: the header's bytes, the
/// slot and the row.
#[derive(Default)]
struct Recorder {
    sent: Vec<([u8; FRAME_HEADER_BYTES], usize, u16)>,
}

impl RowTransmitter for Recorder {
    fn send_run(
        &mut self,
        template: &mut rt_services::camera::frame_header::HeaderTemplate,
        session: &Packetiser,
        first: &RowPacket,
        count: u16,
        slot: usize,
    ) -> u16 {
        for k in 0..count {
            let packet = first.nth(k);
            self.sent.push((template.words(session, &packet).bytes(), slot, packet.row));
        }
        count
    }

    fn checksum_offload(&self) -> bool {
        false
    }

    fn receive_waiting(&self) -> bool {
        false
    }
}

/// An RTSP client on the client's end: one request at a time, each
/// answered before the next goes.
struct RtspClient {
    handle: SocketHandle,
    requests: VecDeque<String>,
    waiting: bool,
    received: Vec<u8>,
    responses: Vec<String>,
}

impl RtspClient {
    /// Send the next request once the previous one is answered; collect
    /// whole responses (no body follows a response here but DESCRIBE's,
    /// whose Content-Length is honoured).
    fn step(&mut self, sockets: &mut SocketSet<'static>, session: &mut Option<String>) {
        let s = sockets.get_mut::<tcp::Socket>(self.handle);
        while s.can_recv() {
            s.recv(|b| {
                self.received.extend_from_slice(b);
                (b.len(), ())
            })
            .expect("recv");
        }
        let text = String::from_utf8_lossy(&self.received).into_owned();
        if let Some(end) = text.find("\r\n\r\n") {
            let body = text
                .lines()
                .find_map(|l| l.strip_prefix("Content-Length: "))
                .map_or(0, |n| n.trim().parse().unwrap_or(0));
            if text.len() >= end + 4 + body {
                let response = text[..end + 4 + body].to_string();
                if let Some(id) = response.lines().find_map(|l| l.strip_prefix("Session: ")) {
                    *session = Some(id.split(';').next().unwrap_or(id).trim().to_string());
                }
                self.received.drain(..end + 4 + body);
                self.responses.push(response);
                self.waiting = false;
            }
        }
        if !self.waiting && s.can_send() {
            if let Some(r) = self.requests.pop_front() {
                let r = r.replace("{session}", session.as_deref().unwrap_or(""));
                s.send_slice(r.as_bytes()).expect("send");
                self.waiting = true;
            }
        }
    }
}

/// The network camera on one end of a cable, a client on the other with
/// an RTSP connection whose requests play `url` to UDP ports 6000-6001.
/// The service's storage is leaked: one rig a test.
struct CameraRig {
    server_dev: CableEnd,
    client_dev: CableEnd,
    server_if: Interface,
    client_if: Interface,
    server_sockets: SocketSet<'static>,
    service: rt_services::camera::service::CameraService<'static>,
    ring: FrameRing<SliceMemory<'static>, RowEngine<SoftwareRenderer>, 4>,
    peers: rt_services::camera::service::Snooped,
    tx: Recorder,
    log: String,
    clients: SocketSet<'static>,
    rtsp: RtspClient,
    /// The client's RTCP socket (port 6001).
    rtcp: SocketHandle,
    session: Option<String>,
    server_mac: EthernetAddress,
}

impl CameraRig {
    fn new(url: &str) -> CameraRig {
        use rt_services::camera::rtsp::{self, MAX_SESSIONS, RTSP_PORT, SERVER_RTP_PORT};
        use rt_services::camera::sender::Camera;
        use rt_services::camera::service::{CameraBuffers, CameraService, Snooped};
        use smoltcp::socket::udp;

        let (mut server_dev, mut client_dev) = cable_with(Faults::default(), 0);
        let server_if = interface(&mut server_dev, 1);
        let mut client_if = interface(&mut client_dev, 2);
        let light = Light::from_world(3.0, 4.0, -2.0).unwrap();

        let buffers = Box::leak(Box::new(CameraBuffers::new()));
        let camera: &'static mut Camera<MAX_SESSIONS> = Box::leak(Box::new(Camera::new()));
        camera.configure(rt_services::camera::sender::Config {
            live_light: light,
            multicast: None,
            cname: rt_services::camera::sender::Cname::for_address(std::net::Ipv4Addr::new(10, 0, 0, 1)),
        });
        let mut server_sockets = SocketSet::new(vec![]);
        let config = rtsp::Config { server_ip: SERVER, rtp_port: SERVER_RTP_PORT, udp: true };
        let server_mac = EthernetAddress([0x02, 0, 0, 0, 0, 1]);
        let service =
            CameraService::new(&mut server_sockets, buffers, camera, config, server_mac, b"seed").expect("RTCP binds");
        let memory = Box::leak(vec![0u8; 4 * FRAME_BYTES].into_boxed_slice());
        let ring = FrameRing::<_, _, 4>::new(SliceMemory::new(0, memory), RowEngine::new(SoftwareRenderer));

        let mut clients = SocketSet::new(vec![]);
        let tcp = tcp::Socket::new(tcp::SocketBuffer::new(vec![0; 8192]), tcp::SocketBuffer::new(vec![0; 4096]));
        let rtsp = RtspClient {
            handle: clients.add(tcp),
            requests: [
                format!("OPTIONS {url} RTSP/1.0\r\nCSeq: 1\r\n\r\n"),
                format!("DESCRIBE {url} RTSP/1.0\r\nCSeq: 2\r\nAccept: application/sdp\r\n\r\n"),
                format!("SETUP {url} RTSP/1.0\r\nCSeq: 3\r\nTransport: RTP/AVP;unicast;client_port=6000-6001\r\n\r\n"),
                format!("PLAY {url} RTSP/1.0\r\nCSeq: 4\r\nSession: {{session}}\r\n\r\n"),
            ]
            .into(),
            waiting: false,
            received: vec![],
            responses: vec![],
        };
        let mut rtcp = udp::Socket::new(
            udp::PacketBuffer::new(vec![udp::PacketMetadata::EMPTY; 4], vec![0; 2048]),
            udp::PacketBuffer::new(vec![udp::PacketMetadata::EMPTY; 4], vec![0; 2048]),
        );
        rtcp.bind(6001).expect("bind");
        let rtcp = clients.add(rtcp);
        clients
            .get_mut::<tcp::Socket>(rtsp.handle)
            .connect(client_if.context(), (IpAddress::Ipv4(SERVER), RTSP_PORT), 40_000)
            .expect("connect");
        CameraRig {
            server_dev,
            client_dev,
            server_if,
            client_if,
            server_sockets,
            service,
            ring,
            peers: Snooped::new(SERVER_RTP_PORT),
            tx: Recorder::default(),
            log: String::new(),
            clients,
            rtsp,
            rtcp,
            session: None,
            server_mac,
        }
    }

    /// One millisecond: both interfaces, the service, the RTSP client.
    fn step(&mut self, ms: i64) {
        use rt_services::camera::service::Snoop;
        let now = Instant::from_millis(ms);
        let server = &mut Snoop { inner: &mut self.server_dev, peers: &mut self.peers };
        self.server_if.poll(now, server, &mut self.server_sockets);
        self.service.poll(
            now,
            &mut self.server_sockets,
            &mut self.peers,
            &mut self.ring,
            &mut self.tx,
            ms as u64,
            &mut self.log,
        );
        let server = &mut Snoop { inner: &mut self.server_dev, peers: &mut self.peers };
        self.server_if.poll(now, server, &mut self.server_sockets);
        self.client_if.poll(now, &mut self.client_dev, &mut self.clients);
        self.rtsp.step(&mut self.clients, &mut self.session);
    }
}

#[test]
fn the_camera_streams_a_frame_over_smoltcp_and_answers_a_nack_from_the_client() {
    use rt_services::camera::rtsp::{RTSP_PORT, SERVER_RTP_PORT};
    use smoltcp::socket::udp;
    use smoltcp::wire::{EthernetFrame, Ipv4Packet, UdpPacket};

    let mut rig = CameraRig::new(&format!("rtsp://{SERVER}:{RTSP_PORT}/light/3,4,-2?fps=10"));
    let mut nacked = None;
    for step in 0..20_000i64 {
        rig.step(step);
        let tx = &rig.tx;
        // Once the first frame went: NACK its row 100 (RFC 4585 generic
        // NACK, PID and no further bits) from the client's RTCP port.
        if nacked.is_none() && tx.sent.len() >= 360 {
            let (h, _, row) = tx.sent[100];
            assert_eq!(row, 100);
            let seq = u16::from_be_bytes([h[44], h[45]]);
            let mut nack = vec![0x81, 205, 0, 3, 0xde, 0xad, 0xbe, 0xef];
            nack.extend_from_slice(&h[50..54]); // the media SSRC
            nack.extend_from_slice(&seq.to_be_bytes());
            nack.extend_from_slice(&[0, 0]);
            let to = (IpAddress::Ipv4(SERVER), SERVER_RTP_PORT + 1);
            rig.clients.get_mut::<udp::Socket>(rig.rtcp).send_slice(&nack, to).expect("NACK");
            nacked = Some(tx.sent.len());
        }
        if nacked.is_some_and(|n| tx.sent.len() > n && tx.sent[n..].iter().any(|s| s.2 == 100)) {
            break;
        }
    }
    let (tx, log, rtsp, server_mac) = (&rig.tx, &rig.log, &rig.rtsp, rig.server_mac);
    let statuses: Vec<&str> = rtsp.responses.iter().filter_map(|r| r.lines().next()).collect();
    assert_eq!(statuses, ["RTSP/1.0 200 OK"; 4], "log:\n{log}");
    assert!(rtsp.responses[2].contains("server_port=5004-5005"), "{}", rtsp.responses[2]);

    // The first frame: 360 packets in order, each a valid Ethernet + IPv4
    // + UDP header to the client's next hop (learnt from its frames).
    assert!(tx.sent.len() >= 360, "{} rows sent; log:\n{log}", tx.sent.len());
    let first = &tx.sent[..360];
    let (seq0, stamp) = (u16::from_be_bytes([first[0].0[44], first[0].0[45]]), &first[0].0[46..50]);
    for (y, (h, slot, row)) in first.iter().enumerate() {
        assert_eq!((usize::from(*row), *slot), (y, first[0].1), "rows of one slot, in order");
        let eth = EthernetFrame::new_checked(&h[..]).expect("Ethernet");
        assert_eq!((eth.src_addr(), eth.dst_addr()), (server_mac, EthernetAddress([0x02, 0, 0, 0, 0, 2])));
        let ip = Ipv4Packet::new_unchecked(&h[14..34]);
        assert!(ip.verify_checksum(), "row {y}: IPv4 checksum (no engine: the software's)");
        assert_eq!((ip.src_addr(), ip.dst_addr()), (SERVER, Ipv4Address::new(10, 0, 0, 2)));
        let udp = UdpPacket::new_unchecked(&h[34..42]);
        assert_eq!((udp.src_port(), udp.dst_port(), udp.checksum()), (5004, 6000, 0));
        assert_eq!(u16::from_be_bytes([h[44], h[45]]), seq0.wrapping_add(y as u16), "consecutive numbers");
        assert_eq!(&h[46..50], stamp, "one timestamp a frame");
        assert_eq!(h[43] & 0x80 != 0, y == 359, "the marker on the last row only");
        assert_eq!(u16::from_be_bytes([h[58], h[59]]), y as u16, "RFC 4175 line number");
    }
    // The NACKed packet again: the same RTP packet, a new IPv4 datagram.
    let n = nacked.expect("a NACK went");
    let again = tx.sent[n..].iter().find(|s| s.2 == 100).unwrap_or_else(|| panic!("row 100 not resent; log:\n{log}"));
    assert_eq!(again.0[42..], tx.sent[100].0[42..], "RTP and RFC 4175 headers unchanged");
    assert_ne!(again.0[18..20], tx.sent[100].0[18..20], "a new IPv4 identification");
    assert_eq!(rig.service.stats.rows_sent as usize, tx.sent.len());
}

#[test]
fn a_service_poll_handles_one_frame_edge_where_the_transmitter_never_fills() {
    use rt_services::camera::rtsp::RTSP_PORT;

    // The recorder takes every row at once, as QEMU's MAC does: without a
    // bound, one poll would stream frame after frame and the rest of the
    // main loop (the seed port, the display) would wait. A poll may begin
    // a frame and end it, never end one and begin the next.
    let mut rig = CameraRig::new(&format!("rtsp://{SERVER}:{RTSP_PORT}/light/3,4,-2?fps=max"));
    let mut step = 0;
    while rig.tx.sent.len() < 5 * 360 && step < 20_000 {
        let before = rig.tx.sent.len();
        rig.step(step);
        let rows: Vec<u16> = rig.tx.sent[before..].iter().map(|s| s.2).collect();
        if let Some(end) = rows.iter().position(|&r| r == 359) {
            assert!(!rows[end..].contains(&0), "poll at {step} ms ended a frame and began the next");
        }
        step += 1;
    }
    assert!(rig.tx.sent.len() >= 5 * 360, "{} rows sent; log:\n{}", rig.tx.sent.len(), rig.log);
}

#[test]
fn a_request_sent_with_its_fin_is_still_answered() {
    // The request and the FIN can arrive together, before the service
    // sees the connection established: the socket is then in CloseWait,
    // and must be served (and freed), not left hanging.
    for mode in MODES {
        let light = Light::from_world(3.0, 4.0, -2.0).unwrap();
        let mut link = Link::new(mode);
        link.service_starts = 200;
        let mut clients = [link.connect(FRAME_PORT, 50_000, request(&light).to_vec(), true)];
        let log = link.run(&mut clients, 20_000);
        assert!(clients[0].received == frame(&light), "{} bytes ({mode:?}); log: {log}", clients[0].received.len());
    }
}

/// Four SYNs to the seed ports that are never completed (a phone leaving
/// WiFi mid-connect, a scanner) take every socket, and smoltcp alone would
/// keep them in SYN-RECEIVED, resending its SYN-ACK, for its timeout or
/// for ever: the services' policy (`rt_services::tcp`) drops each after
/// `REQUEST_LIMIT`, and a client arriving then is served.
#[test]
fn handshakes_never_finished_hold_the_sockets_seconds_not_for_ever() {
    use rt_services::time::REQUEST_LIMIT;
    let (mut server_dev, mut client_dev) = cable_with(Faults::default(), 0);
    let mut server_if = interface(&mut server_dev, 1);
    let mut client_if = interface(&mut client_dev, 2);
    let mut buffers: Box<[SocketBuffers; 4]> = Box::default();
    let mut server_sockets = SocketSet::new(vec![]);
    let mut service = FrameService::new(&mut server_sockets, &mut buffers, 2);
    let mut frames = RowFrames::<_, 4>::new(SoftwareRenderer);
    let mut log = String::new();
    let mut ghosts = SocketSet::new(vec![]);
    let mut clients = SocketSet::new(vec![]);
    let ports = [FRAME_PORT, FRAME_PORT, PERSISTENT_PORT, PERSISTENT_PORT];
    let limit = REQUEST_LIMIT.as_millis() as u64;
    let light = Light::from_world(3.0, 4.0, -2.0).unwrap();
    let mut visitor = None;
    let mut received = Vec::new();
    let mut held_at_1s = None;
    let mut ghosts_sending = true;
    for step in 0..limit + 3_000 {
        let now = Instant::from_millis(step as i64);
        server_if.poll(now, &mut server_dev, &mut server_sockets);
        service.poll(now, &mut server_sockets, &mut frames, &mut log);
        server_if.poll(now, &mut server_dev, &mut server_sockets);
        if step == 10 {
            for (i, port) in ports.iter().enumerate() {
                let mut s = tcp::Socket::new(tcp::SocketBuffer::new(vec![0; 64]), tcp::SocketBuffer::new(vec![0; 64]));
                s.connect(client_if.context(), (IpAddress::Ipv4(SERVER), *port), 40_000 + i as u16).expect("connect");
                ghosts.add(s);
            }
        }
        if step >= 10 && ghosts_sending {
            // The ghosts send their SYNs (after ARP) and are heard of no
            // more once the server has them: their SYN-ACKs go unread.
            if service.listening(&server_sockets) == 0 {
                ghosts_sending = false;
            } else {
                client_if.poll(now, &mut client_dev, &mut ghosts);
            }
        }
        if !ghosts_sending && visitor.is_none() {
            client_dev.rx.borrow_mut().clear();
        }
        if visitor.is_some() {
            client_if.poll(now, &mut client_dev, &mut clients);
        }
        if step == 1_000 {
            held_at_1s = Some(service.listening(&server_sockets));
        }
        if step == limit + 500 {
            assert_eq!(service.listening(&server_sockets), 4, "every socket listens again; log: {log}");
            let mut s = tcp::Socket::new(tcp::SocketBuffer::new(vec![0; 1 << 20]), tcp::SocketBuffer::new(vec![0; 64]));
            s.connect(client_if.context(), (IpAddress::Ipv4(SERVER), FRAME_PORT), 50_000).expect("connect");
            visitor = Some(clients.add(s));
        }
        if let Some(h) = visitor {
            let s = clients.get_mut::<tcp::Socket>(h);
            if s.may_send() && s.send_queue() == 0 && received.is_empty() {
                let _ = s.send_slice(&request(&light));
            }
            while s.can_recv() {
                s.recv(|b| {
                    received.extend_from_slice(b);
                    (b.len(), ())
                })
                .expect("recv");
            }
            if received.len() == FRAME_BYTES {
                break;
            }
        }
    }
    assert_eq!(held_at_1s, Some(0), "the ghosts held every socket at first; log: {log}");
    assert!(log.contains("a handshake never finished"), "{log}");
    assert!(received == frame(&light), "the visitor after them got its frame ({} bytes); log: {log}", received.len());
}
