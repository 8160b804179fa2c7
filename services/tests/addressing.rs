//! The board's address over smoltcp: a DHCP lease (and a lease that
//! changes), a link-local address when no DHCP server answers, a late
//! lease winning over it, conflicts, a static address. The board is a
//! smoltcp interface with `Addressing`; the network is this test, which
//! answers as a DHCP server (built with smoltcp's wire types) and as other
//! hosts' ARP.

use std::collections::VecDeque;
use std::net::Ipv4Addr;

use rt_services::address::assign::{Addressing, LinkNotes};
use rt_services::address::settings::AddressMode;
use rt_services::address::{Assignment, Origin};
use rt_services::snoop::Snoop;
use smoltcp::iface::{Config, Interface, SocketSet};
use smoltcp::phy::{self, Device, DeviceCapabilities, Medium};
use smoltcp::time::Instant;
use smoltcp::wire::{
    ArpOperation, ArpPacket, ArpRepr, DhcpMessageType, DhcpOption, DhcpPacket, DhcpRepr, EthernetAddress,
    EthernetFrame, EthernetProtocol, EthernetRepr, HardwareAddress, IpAddress, IpProtocol, Ipv4Packet, Ipv4Repr,
    UdpPacket, UdpRepr,
};

const BOARD_MAC: [u8; 6] = [0x02, 0xde, 0x1c, 0x00, 0x00, 0x07];
const SERVER_MAC: EthernetAddress = EthernetAddress([0x02, 0, 0, 0, 0, 2]);
const SERVER_IP: Ipv4Addr = Ipv4Addr::new(10, 0, 2, 2);
const HOST_NAME: &[u8] = b"raytracer";

/// The board's end of the cable: frames in, frames out.
#[derive(Default)]
struct Wire {
    to_board: VecDeque<Vec<u8>>,
    from_board: VecDeque<Vec<u8>>,
}

struct Rx(Vec<u8>);
struct Tx<'a>(&'a mut VecDeque<Vec<u8>>);

impl phy::RxToken for Rx {
    fn consume<R, F: FnOnce(&[u8]) -> R>(self, f: F) -> R {
        f(&self.0)
    }
}

impl phy::TxToken for Tx<'_> {
    fn consume<R, F: FnOnce(&mut [u8]) -> R>(self, len: usize, f: F) -> R {
        let mut buf = vec![0; len];
        let r = f(&mut buf);
        self.0.push_back(buf);
        r
    }
}

impl Device for Wire {
    type RxToken<'a> = Rx;
    type TxToken<'a> = Tx<'a>;

    fn receive(&mut self, _: Instant) -> Option<(Rx, Tx<'_>)> {
        let frame = self.to_board.pop_front()?;
        Some((Rx(frame), Tx(&mut self.from_board)))
    }

    fn transmit(&mut self, _: Instant) -> Option<Tx<'_>> {
        Some(Tx(&mut self.from_board))
    }

    fn capabilities(&self) -> DeviceCapabilities {
        let mut caps = DeviceCapabilities::default();
        caps.medium = Medium::Ethernet;
        caps.max_transmission_unit = 1514;
        caps
    }
}

/// The network around the board.
struct Network {
    /// The DHCP server's address for the board (`None`: no server).
    offer: Option<Ipv4Addr>,
    /// Lease time the server gives, seconds.
    lease_s: u32,
    /// Renewals for another address than `offer` are refused (DHCPNAK).
    nak_other: bool,
    /// Another host that holds this address (answers ARP about it).
    other_host: Option<Ipv4Addr>,
    /// ARP packets the board sent: (time ms, sender IP, target IP).
    arp: Vec<(i64, Ipv4Addr, Ipv4Addr)>,
    /// Host names the board's DHCP requests carried.
    names: Vec<Vec<u8>>,
}

struct Board {
    wire: Wire,
    iface: Interface,
    sockets: SocketSet<'static>,
    addressing: Addressing,
    notes: LinkNotes,
    /// Every change `poll` reported, with its time (ms).
    changes: Vec<(i64, Option<Assignment>)>,
    now: i64,
    /// The cable is in: frames go both ways and `poll` is told so.
    link: bool,
}

static OPTIONS: [DhcpOption<'static>; 1] = [DhcpOption { kind: 12, data: HOST_NAME }];

impl Board {
    fn new(mode: AddressMode) -> Board {
        let mut wire = Wire::default();
        let config = Config::new(HardwareAddress::Ethernet(EthernetAddress(BOARD_MAC)));
        let iface = Interface::new(config, &mut wire, Instant::from_millis(0));
        let mut sockets = SocketSet::new(Vec::new());
        let addressing = Addressing::new(mode, BOARD_MAC, &mut sockets, &OPTIONS);
        Board { wire, iface, sockets, addressing, notes: LinkNotes::new(), changes: Vec::new(), now: 0, link: true }
    }

    /// Run in 10 ms steps until `until_ms`, the network answering.
    fn run(&mut self, net: &mut Network, until_ms: i64) {
        while self.now < until_ms {
            let now = Instant::from_millis(self.now);
            self.iface.poll(now, &mut Snoop { inner: &mut self.wire, peers: &mut self.notes }, &mut self.sockets);
            if let Some(change) = self.addressing.poll(
                now,
                self.link,
                &mut self.iface,
                &mut self.sockets,
                &mut self.notes,
                &mut self.wire,
            ) {
                self.changes.push((self.now, change));
            }
            while let Some(frame) = self.wire.from_board.pop_front() {
                if !self.link {
                    continue;
                }
                for answer in net.answer(self.now, &frame) {
                    self.wire.to_board.push_back(answer);
                }
            }
            self.now += 10;
        }
    }

    /// The interface's one IPv4 address, if any.
    fn iface_address(&self) -> Option<(Ipv4Addr, u8)> {
        let addrs = self.iface.ip_addrs();
        assert!(addrs.len() <= 1, "one address at a time: {addrs:?}");
        addrs.first().map(|c| match c.address() {
            IpAddress::Ipv4(a) => (a, c.prefix_len()),
        })
    }
}

impl Network {
    fn new(offer: Option<Ipv4Addr>) -> Network {
        Network { offer, lease_s: 3600, nak_other: false, other_host: None, arp: Vec::new(), names: Vec::new() }
    }

    /// The network's answers to one frame from the board.
    fn answer(&mut self, now: i64, frame: &[u8]) -> Vec<Vec<u8>> {
        let eth = EthernetFrame::new_checked(frame).expect("an Ethernet frame");
        assert_eq!(eth.src_addr(), EthernetAddress(BOARD_MAC));
        match eth.ethertype() {
            EthernetProtocol::Arp => self.arp(now, eth.payload()),
            EthernetProtocol::Ipv4 => self.ipv4(eth.payload()),
            _ => vec![],
        }
    }

    fn arp(&mut self, now: i64, payload: &[u8]) -> Vec<Vec<u8>> {
        let packet = ArpPacket::new_checked(payload).expect("ARP");
        let ArpRepr::EthernetIpv4 { operation, source_protocol_addr, target_protocol_addr, .. } =
            ArpRepr::parse(&packet).expect("Ethernet/IPv4 ARP")
        else {
            unreachable!()
        };
        if operation == ArpOperation::Request {
            self.arp.push((now, source_protocol_addr, target_protocol_addr));
        }
        // The DHCP server (when there is one) and the other host answer
        // questions about their addresses.
        let server = self.offer.map(|_| (SERVER_IP, SERVER_MAC));
        let other = self.other_host.map(|ip| (ip, EthernetAddress([0x02, 0, 0, 0, 0, 0x99])));
        let Some((ip, mac)) = [server, other].into_iter().flatten().find(|(ip, _)| *ip == target_protocol_addr) else {
            return vec![];
        };
        if operation != ArpOperation::Request {
            return vec![];
        }
        let reply = ArpRepr::EthernetIpv4 {
            operation: ArpOperation::Reply,
            source_hardware_addr: mac,
            source_protocol_addr: ip,
            target_hardware_addr: EthernetAddress(BOARD_MAC),
            target_protocol_addr: source_protocol_addr,
        };
        let eth =
            EthernetRepr { src_addr: mac, dst_addr: EthernetAddress::BROADCAST, ethertype: EthernetProtocol::Arp };
        let mut buf = vec![0; eth.buffer_len() + reply.buffer_len()];
        let mut frame = EthernetFrame::new_unchecked(&mut buf[..]);
        eth.emit(&mut frame);
        reply.emit(&mut ArpPacket::new_unchecked(frame.payload_mut()));
        vec![buf]
    }

    /// A DHCP server on UDP 67.
    fn ipv4(&mut self, payload: &[u8]) -> Vec<Vec<u8>> {
        let ip = Ipv4Packet::new_checked(payload).expect("IPv4");
        if ip.next_header() != IpProtocol::Udp {
            return vec![];
        }
        let udp = UdpPacket::new_checked(ip.payload()).expect("UDP");
        if udp.dst_port() != 67 {
            return vec![];
        }
        let Some(offer) = self.offer else { return vec![] };
        let packet = DhcpPacket::new_checked(udp.payload()).expect("DHCP");
        let request = DhcpRepr::parse(&packet).expect("a DHCP request");
        if let Some(name) = packet.options().find(|o| o.kind == 12) {
            self.names.push(name.data.to_vec());
        }
        let asked = request.requested_ip.or((!request.client_ip.is_unspecified()).then_some(request.client_ip));
        let kind = match request.message_type {
            DhcpMessageType::Discover => DhcpMessageType::Offer,
            DhcpMessageType::Request if asked == Some(offer) || (asked.is_some() && !self.nak_other) => {
                DhcpMessageType::Ack
            }
            DhcpMessageType::Request => DhcpMessageType::Nak,
            _ => return vec![],
        };
        let your_ip = if kind == DhcpMessageType::Nak { Ipv4Addr::UNSPECIFIED } else { asked.unwrap_or(offer) };
        let your_ip = if kind == DhcpMessageType::Offer { offer } else { your_ip };
        let reply = DhcpRepr {
            message_type: kind,
            transaction_id: request.transaction_id,
            secs: 0,
            client_hardware_address: request.client_hardware_address,
            client_ip: Ipv4Addr::UNSPECIFIED,
            your_ip,
            server_ip: SERVER_IP,
            router: Some(SERVER_IP),
            subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
            relay_agent_ip: Ipv4Addr::UNSPECIFIED,
            broadcast: true,
            requested_ip: None,
            client_identifier: None,
            server_identifier: Some(SERVER_IP),
            parameter_request_list: None,
            dns_servers: None,
            max_size: None,
            lease_duration: Some(self.lease_s),
            renew_duration: None,
            rebind_duration: None,
            additional_options: &[],
        };
        let udp_repr = UdpRepr { src_port: 67, dst_port: 68 };
        let ip_repr = Ipv4Repr {
            src_addr: SERVER_IP,
            dst_addr: Ipv4Addr::BROADCAST,
            next_header: IpProtocol::Udp,
            payload_len: 8 + reply.buffer_len(),
            hop_limit: 64,
        };
        let eth = EthernetRepr {
            src_addr: SERVER_MAC,
            dst_addr: EthernetAddress::BROADCAST,
            ethertype: EthernetProtocol::Ipv4,
        };
        let mut buf = vec![0; eth.buffer_len() + ip_repr.buffer_len() + 8 + reply.buffer_len()];
        let mut frame = EthernetFrame::new_unchecked(&mut buf[..]);
        eth.emit(&mut frame);
        let caps = smoltcp::phy::ChecksumCapabilities::default();
        let mut ip = Ipv4Packet::new_unchecked(frame.payload_mut());
        ip_repr.emit(&mut ip, &caps);
        let mut udp = UdpPacket::new_unchecked(ip.payload_mut());
        udp_repr.emit(
            &mut udp,
            &SERVER_IP.into(),
            &Ipv4Addr::BROADCAST.into(),
            8 + reply.buffer_len() - 8,
            |buf| reply.emit(&mut DhcpPacket::new_unchecked(buf)).expect("emit DHCP"),
            &caps,
        );
        vec![buf]
    }
}

fn is_link_local(a: Ipv4Addr) -> bool {
    let o = a.octets();
    o[0] == 169 && o[1] == 254 && (1..=254).contains(&o[2])
}

#[test]
fn a_dhcp_lease_is_taken_with_its_route_and_the_board_named_in_its_requests() {
    let mut net = Network::new(Some(Ipv4Addr::new(10, 0, 2, 15)));
    let mut board = Board::new(AddressMode::Automatic);
    board.run(&mut net, 3_000);
    let lease = board.addressing.current().expect("a lease within 3 s");
    assert_eq!(lease.address, Ipv4Addr::new(10, 0, 2, 15));
    assert_eq!((lease.prefix_len, lease.gateway, lease.origin), (24, Some(SERVER_IP), Origin::Dhcp));
    assert_eq!(board.iface_address(), Some((Ipv4Addr::new(10, 0, 2, 15), 24)));
    let mut route = None;
    board.iface.routes_mut().update(|r| route = r.first().map(|r| r.via_router));
    assert_eq!(route, Some(IpAddress::Ipv4(SERVER_IP)), "the default route");
    assert!(!net.names.is_empty() && net.names.iter().all(|n| n == HOST_NAME), "{:?}", net.names);
    assert_eq!(board.changes.len(), 1, "{:?}", board.changes);
    assert!(net.arp.iter().all(|(_, s, _)| !s.is_unspecified()), "no link-local probe once leased: {:?}", net.arp);
}

#[test]
fn a_lease_that_changes_at_renewal_moves_the_address() {
    let mut net = Network::new(Some(Ipv4Addr::new(10, 0, 2, 15)));
    net.lease_s = 20;
    let mut board = Board::new(AddressMode::Automatic);
    board.run(&mut net, 3_000);
    assert_eq!(board.addressing.current().map(|a| a.address), Some(Ipv4Addr::new(10, 0, 2, 15)));
    // The server now has another address for the board and refuses the
    // old one at renewal (T1 = 10 s): the board starts over and takes it.
    net.offer = Some(Ipv4Addr::new(10, 0, 2, 16));
    net.nak_other = true;
    board.run(&mut net, 16_000);
    let now = board.addressing.current().expect("leased again");
    assert_eq!((now.address, now.origin), (Ipv4Addr::new(10, 0, 2, 16), Origin::Dhcp), "{:?}", board.changes);
    assert_eq!(board.iface_address(), Some((Ipv4Addr::new(10, 0, 2, 16), 24)));
    assert!(board.addressing.leases() >= 2);
}

#[test]
fn with_no_dhcp_server_a_link_local_address_within_ten_seconds_probed_as_rfc_3927_says() {
    let mut net = Network::new(None);
    let mut board = Board::new(AddressMode::Automatic);
    board.run(&mut net, 10_000);
    let a = board.addressing.current().expect("an address within 10 s");
    assert_eq!(a.origin, Origin::LinkLocal);
    assert!(is_link_local(a.address), "{a}");
    assert_eq!((a.prefix_len, a.gateway), (16, None));
    assert_eq!(board.iface_address(), Some((a.address, 16)));
    let probes: Vec<_> = net.arp.iter().filter(|(_, s, t)| s.is_unspecified() && *t == a.address).collect();
    let announcements: Vec<_> = net.arp.iter().filter(|(_, s, t)| *s == a.address && *t == a.address).collect();
    assert_eq!(probes.len(), 3, "{:?}", net.arp);
    assert_eq!(announcements.len(), 2, "{:?}", net.arp);
    assert!(probes[2].0 < announcements[0].0);
}

#[test]
fn a_dhcp_server_that_answers_late_wins_over_the_link_local_address() {
    let mut net = Network::new(None);
    let mut board = Board::new(AddressMode::Automatic);
    board.run(&mut net, 10_000);
    assert_eq!(board.addressing.current().map(|a| a.origin), Some(Origin::LinkLocal));
    net.offer = Some(Ipv4Addr::new(192, 168, 0, 40));
    // smoltcp's client sends a DISCOVER at least every 10 s.
    board.run(&mut net, 25_000);
    let a = board.addressing.current().expect("leased");
    assert_eq!((a.address, a.origin), (Ipv4Addr::new(192, 168, 0, 40), Origin::Dhcp));
    assert_eq!(board.iface_address(), Some((a.address, 24)), "the link-local address is gone");
}

#[test]
fn an_address_another_host_answers_for_is_not_taken() {
    let mut net = Network::new(None);
    // Learn the board's first choice, then have another host hold it.
    let mut first = Board::new(AddressMode::Automatic);
    first.run(&mut net, 10_000);
    let taken = first.addressing.current().expect("claimed").address;
    let mut net = Network::new(None);
    net.other_host = Some(taken);
    let mut board = Board::new(AddressMode::Automatic);
    board.run(&mut net, 12_000);
    let a = board.addressing.current().expect("claimed another");
    assert!(is_link_local(a.address) && a.address != taken, "{a} vs {taken}");
    assert_eq!(board.addressing.link_local_conflicts(), 0, "reset once claimed");
}

#[test]
fn a_static_address_is_set_at_once_and_nothing_is_asked_of_the_network() {
    let mut net = Network::new(Some(Ipv4Addr::new(10, 0, 2, 15)));
    let mode = AddressMode::Static {
        address: Ipv4Addr::new(192, 168, 7, 9),
        prefix_len: 24,
        gateway: Some(Ipv4Addr::new(192, 168, 7, 1)),
    };
    let mut board = Board::new(mode);
    board.run(&mut net, 12_000);
    let a = board.addressing.current().expect("static");
    assert_eq!((a.address, a.origin), (Ipv4Addr::new(192, 168, 7, 9), Origin::Static));
    assert_eq!(board.changes.len(), 1);
    assert_eq!(board.changes[0].0, 0, "from the first turn");
    assert!(net.names.is_empty(), "no DHCP");
    assert!(net.arp.iter().all(|(_, s, _)| !s.is_unspecified()), "no probes: {:?}", net.arp);
}

/// The cable out for `ms`, then in again (a board carried elsewhere).
fn replug(board: &mut Board, net: &mut Network, ms: i64) {
    board.link = false;
    board.run(net, board.now + ms);
    board.link = true;
}

/// A board moved from a router's LAN to a cable straight to a laptop (no
/// DHCP server there): its lease is worth nothing, and it has a link-local
/// address within 15 s of the link coming up; carried back, a lease
/// within 15 s again (a DISCOVER at link-up, not after smoltcp's 10 s).
#[test]
fn a_board_moved_to_a_network_without_dhcp_and_back_takes_an_address_there_within_15_s() {
    let mut net = Network::new(Some(Ipv4Addr::new(10, 0, 2, 15)));
    let mut board = Board::new(AddressMode::Automatic);
    board.run(&mut net, 3_000);
    assert_eq!(board.addressing.current().map(|a| a.origin), Some(Origin::Dhcp));
    let mut laptop = Network::new(None);
    replug(&mut board, &mut laptop, 2_000);
    let plugged = board.now;
    board.run(&mut laptop, plugged + 15_000);
    let (at, a) = board.changes.iter().rev().find_map(|(t, c)| c.map(|a| (*t, a))).expect("an address");
    assert_eq!(a.origin, Origin::LinkLocal, "{:?}", board.changes);
    assert!(at - plugged <= 15_000, "{} ms after the link came up", at - plugged);
    assert_eq!(board.iface_address(), Some((a.address, 16)), "the lease is gone");
    replug(&mut board, &mut net, 2_000);
    let plugged = board.now;
    board.run(&mut net, plugged + 15_000);
    let a = board.addressing.current().expect("leased again");
    assert_eq!((a.address, a.origin), (Ipv4Addr::new(10, 0, 2, 15), Origin::Dhcp), "{:?}", board.changes);
    let leased_at = board.changes.iter().rev().find(|(_, c)| c.is_some_and(|a| a.origin == Origin::Dhcp));
    assert!(leased_at.is_some_and(|(t, _)| t - plugged < 2_000), "at once, not after 10 s: {:?}", board.changes);
}

/// A link-local address held when the link comes back is probed again
/// before use (three probes for it after the link came up) and kept
/// where nobody has it.
#[test]
fn a_link_local_address_is_probed_again_when_the_link_comes_back() {
    let mut net = Network::new(None);
    let mut board = Board::new(AddressMode::Automatic);
    board.run(&mut net, 10_000);
    let held = board.addressing.current().expect("link-local").address;
    replug(&mut board, &mut net, 1_000);
    let plugged = board.now;
    board.run(&mut net, plugged + 10_000);
    let probes = net.arp.iter().filter(|(t, s, a)| *t >= plugged && s.is_unspecified() && *a == held).count();
    assert_eq!(probes, 3, "{:?}", net.arp);
    assert_eq!(board.addressing.current().map(|a| (a.address, a.origin)), Some((held, Origin::LinkLocal)));
}
