//! The board's address on a smoltcp interface (feature `smoltcp`): the
//! settings' static address, or smoltcp's DHCPv4 client with a link-local
//! claim beside it ([`LinkLocal`]) while there is no lease.
//!
//! [`Addressing::poll`] runs once a main-loop turn after the interface's
//! poll: it takes the DHCP socket's events (smoltcp renews at T1 and
//! rebinds at T2, RFC 2131 section 4.4.5, and reports a changed or lost
//! lease), feeds the ARP packets received ([`LinkNotes`], filled by the
//! [`Snoop`](crate::snoop::Snoop) device) to the claim, puts the claim's
//! probes and announcements on the wire, and sets the interface's address
//! and default route to the one [`Assignment`] that wins: static, else the
//! lease, else the link-local address (RFC 3927 section 1.9: a routable
//! address is preferred). It returns the new assignment whenever it
//! changes, so that the caller moves every service and display to it.

use core::net::Ipv4Addr;

use smoltcp::iface::{Interface, SocketHandle, SocketSet};
use smoltcp::phy::{Device, TxToken};
use smoltcp::socket::dhcpv4;
use smoltcp::time::Instant as NetInstant;
use smoltcp::wire::{
    ArpOperation, ArpPacket, ArpRepr, DhcpOption, EthernetAddress, EthernetFrame, EthernetProtocol, EthernetRepr,
    IpCidr, IpProtocol, Ipv4Packet, UdpPacket,
};

use super::link_local::{ArpSeen, ArpSend, LinkLocal};
use super::settings::AddressMode;
use super::{Assignment, Origin};
use crate::snoop::Learn;
use crate::time::Instant;

/// ARP packets kept between two [`Addressing::poll`]s (more are dropped:
/// the claim needs to see one conflict, not all).
pub const ARP_NOTES: usize = 8;

/// Prefix length of the link-local network 169.254/16 (RFC 3927 section 2.1).
const LINK_LOCAL_PREFIX: u8 = 16;

/// UDP ports whose datagrams wake the housekeeping: the DHCP client's
/// (RFC 2131 section 4.1) and mDNS (RFC 6762 section 3).
const WAKE_PORTS: [u16; 2] = [68, 5353];

/// What the link brought for the address and the name since they were
/// last looked after: the ARP packets (for the link-local claim), and
/// whether a DHCP or mDNS datagram arrived ([`take_wake`](Self::take_wake)),
/// so that the main loop looks after them when something came or a timer
/// is due, not on every turn.
#[derive(Clone, Debug, Default)]
pub struct LinkNotes {
    seen: heapless::Deque<ArpSeen, ARP_NOTES>,
    wake: bool,
}

impl LinkNotes {
    /// None yet.
    pub const fn new() -> LinkNotes {
        LinkNotes { seen: heapless::Deque::new(), wake: false }
    }

    fn pop(&mut self) -> Option<ArpSeen> {
        self.seen.pop_front()
    }

    /// Whether an ARP, DHCP or mDNS frame arrived since the last call.
    pub fn take_wake(&mut self) -> bool {
        core::mem::take(&mut self.wake)
    }
}

impl Learn for LinkNotes {
    /// Note an Ethernet/IPv4 ARP request or reply, and the arrival of a
    /// UDP datagram for DHCP's client port or mDNS; anything else is
    /// ignored.
    fn learn(&mut self, frame: &[u8]) {
        let Ok(eth) = EthernetFrame::new_checked(frame) else { return };
        if eth.ethertype() == EthernetProtocol::Ipv4 {
            let Ok(ip) = Ipv4Packet::new_checked(eth.payload()) else { return };
            if ip.next_header() == IpProtocol::Udp {
                if let Ok(udp) = UdpPacket::new_checked(ip.payload()) {
                    self.wake |= WAKE_PORTS.contains(&udp.dst_port());
                }
            }
            return;
        }
        if eth.ethertype() != EthernetProtocol::Arp {
            return;
        }
        self.wake = true;
        let Ok(packet) = ArpPacket::new_checked(eth.payload()) else { return };
        let Ok(ArpRepr::EthernetIpv4 { source_hardware_addr, source_protocol_addr, target_protocol_addr, .. }) =
            ArpRepr::parse(&packet)
        else {
            return;
        };
        if self.seen.is_full() {
            self.seen.pop_front();
        }
        let _ = self.seen.push_back(ArpSeen {
            sender_mac: source_hardware_addr.0,
            sender_ip: source_protocol_addr,
            target_ip: target_protocol_addr,
        });
    }
}

/// The board's address: its source, the claim, and what is on the
/// interface.
#[derive(Debug)]
pub struct Addressing {
    mode: AddressMode,
    mac: EthernetAddress,
    dhcp: Option<SocketHandle>,
    lease: Option<Assignment>,
    link_local: LinkLocal,
    current: Option<Assignment>,
    /// Leases taken (the first, and each change at renewal or rebinding).
    leases: u32,
    /// The link as the last poll saw it.
    link_was_up: bool,
}

impl Addressing {
    /// Take the address as `mode` says. For [`AddressMode::Automatic`], a
    /// DHCPv4 socket is added to `sockets`, sending `options` in its
    /// requests (the host name, option 12, so that the DHCP server's DNS
    /// knows the board by name).
    pub fn new<'a>(
        mode: AddressMode,
        mac: [u8; 6],
        sockets: &mut SocketSet<'a>,
        options: &'a [DhcpOption<'a>],
    ) -> Addressing {
        let dhcp = match mode {
            AddressMode::Automatic => {
                let mut socket = dhcpv4::Socket::new();
                socket.set_outgoing_options(options);
                Some(sockets.add(socket))
            }
            AddressMode::Static { .. } => None,
        };
        Addressing {
            mode,
            mac: EthernetAddress(mac),
            dhcp,
            lease: None,
            link_local: LinkLocal::new(mac),
            current: None,
            leases: 0,
            link_was_up: false,
        }
    }

    /// The address on the interface, if any.
    pub fn current(&self) -> Option<Assignment> {
        self.current
    }

    /// Leases taken so far.
    pub fn leases(&self) -> u32 {
        self.leases
    }

    /// Link-local conflicts met.
    pub fn link_local_conflicts(&self) -> u32 {
        self.link_local.conflicts()
    }

    /// The link came up, at boot or perhaps on another network (a cable
    /// moved from a router to a laptop): DHCP starts over with a DISCOVER
    /// now (a lease from another network is worth nothing here; smoltcp's
    /// client cannot ask for the old address by INIT-REBOOT, RFC 2131
    /// section 3.2), and a link-local address is probed again before use.
    fn link_came_up(&mut self, t: Instant, sockets: &mut SocketSet<'_>) {
        if let Some(handle) = self.dhcp {
            sockets.get_mut::<dhcpv4::Socket>(handle).reset();
            self.lease = None;
        }
        self.link_local.link_up(t);
    }

    /// When [`poll`](Self::poll) must run next without a frame for it: the
    /// link-local claim's next step (the DHCP client's own timers run in
    /// smoltcp's egress; what they change shows at the next look).
    pub fn poll_at(&self) -> Option<NetInstant> {
        self.link_local.poll_at().map(|t| NetInstant::from_millis(i64::try_from(t.millis()).unwrap_or(i64::MAX)))
    }

    /// One turn (module docs). `link_up`: the PHY has a link (the claim
    /// starts only then). Returns the new assignment if it changed (`Some(None)`:
    /// the board has no address any more).
    pub fn poll<D: Device>(
        &mut self,
        now: NetInstant,
        link_up: bool,
        iface: &mut Interface,
        sockets: &mut SocketSet<'_>,
        notes: &mut LinkNotes,
        device: &mut D,
    ) -> Option<Option<Assignment>> {
        let t = Instant::from_millis(u64::try_from(now.total_millis()).unwrap_or(0));
        if link_up && !self.link_was_up {
            self.link_came_up(t, sockets);
        }
        self.link_was_up = link_up;
        if let Some(handle) = self.dhcp {
            match sockets.get_mut::<dhcpv4::Socket>(handle).poll() {
                Some(dhcpv4::Event::Configured(c)) => {
                    self.leases = self.leases.saturating_add(1);
                    self.lease = Some(Assignment {
                        address: c.address.address(),
                        prefix_len: c.address.prefix_len(),
                        gateway: c.router,
                        origin: Origin::Dhcp,
                    });
                }
                Some(dhcpv4::Event::Deconfigured) => self.lease = None,
                None => {}
            }
        }
        if self.lease.is_some() || self.dhcp.is_none() {
            self.link_local.stop();
        } else if link_up {
            self.link_local.start(t);
        }
        while let Some(arp) = notes.pop() {
            self.link_local.on_arp(t, &arp);
        }
        while let Some(send) = self.link_local.poll(t) {
            if !send_arp(device, now, self.mac, send) {
                // No transmit descriptor: this one is lost, as a packet on
                // the wire can be; the claim's timings go on.
                break;
            }
        }
        let wanted = match self.mode {
            AddressMode::Static { address, prefix_len, gateway } => {
                Some(Assignment { address, prefix_len, gateway, origin: Origin::Static })
            }
            AddressMode::Automatic => self.lease.or_else(|| {
                self.link_local.address().map(|address| Assignment {
                    address,
                    prefix_len: LINK_LOCAL_PREFIX,
                    gateway: None,
                    origin: Origin::LinkLocal,
                })
            }),
        };
        if wanted == self.current {
            return None;
        }
        apply(iface, wanted);
        self.current = wanted;
        Some(wanted)
    }
}

/// Put `assignment` on the interface: its one address and default route.
fn apply(iface: &mut Interface, assignment: Option<Assignment>) {
    iface.update_ip_addrs(|addrs| {
        addrs.clear();
        if let Some(a) = assignment {
            let _ = addrs.push(IpCidr::new(a.address.into(), a.prefix_len));
        }
    });
    iface.routes_mut().remove_default_ipv4_route();
    if let Some(gateway) = assignment.and_then(|a| a.gateway) {
        // The route table holds several; one default route always fits.
        let _ = iface.routes_mut().add_default_ipv4_route(gateway);
    }
}

/// Broadcast an ARP probe or announcement from `mac`; false if the device
/// had no room.
fn send_arp<D: Device>(device: &mut D, now: NetInstant, mac: EthernetAddress, send: ArpSend) -> bool {
    let (sender, target) = match send {
        ArpSend::Probe(a) => (Ipv4Addr::UNSPECIFIED, a),
        ArpSend::Announce(a) => (a, a),
    };
    let arp = ArpRepr::EthernetIpv4 {
        operation: ArpOperation::Request,
        source_hardware_addr: mac,
        source_protocol_addr: sender,
        target_hardware_addr: EthernetAddress([0; 6]),
        target_protocol_addr: target,
    };
    let eth = EthernetRepr { src_addr: mac, dst_addr: EthernetAddress::BROADCAST, ethertype: EthernetProtocol::Arp };
    let Some(tx) = device.transmit(now) else { return false };
    tx.consume(eth.buffer_len() + arp.buffer_len(), |buf| {
        let mut frame = EthernetFrame::new_unchecked(buf);
        eth.emit(&mut frame);
        arp.emit(&mut ArpPacket::new_unchecked(frame.payload_mut()));
    });
    true
}
