//! The mDNS responder on a smoltcp UDP socket (feature `smoltcp`): port
//! 5353, IP TTL 255 (RFC 6762 section 11), the group 224.0.0.251 joined by
//! the caller (`Interface::join_multicast_group`, which sends the IGMP
//! report that switches with IGMP snooping need).

use core::fmt::Write;
use core::net::{Ipv4Addr, SocketAddrV4};

use smoltcp::iface::{SocketHandle, SocketSet};
use smoltcp::socket::udp;
use smoltcp::time::Instant as NetInstant;
use smoltcp::wire::{IpAddress, IpEndpoint};

use super::responder::{Destination, NameEvent, Responder, Services, MDNS_GROUP, MDNS_PORT};
use crate::address::settings::HostName;
use crate::time::Instant;

/// The largest datagram written: an Ethernet MTU's UDP payload.
const DATAGRAM_BYTES: usize = 1472;

/// The socket's buffers (lent for the program's life).
pub struct MdnsBuffers {
    rx_meta: [udp::PacketMetadata; 8],
    rx: [u8; 4096],
    tx_meta: [udp::PacketMetadata; 4],
    tx: [u8; 4 * DATAGRAM_BYTES],
}

impl MdnsBuffers {
    /// Zeroed buffers (usable in a `static`).
    pub const fn new() -> MdnsBuffers {
        MdnsBuffers {
            rx_meta: [udp::PacketMetadata::EMPTY; 8],
            rx: [0; 4096],
            tx_meta: [udp::PacketMetadata::EMPTY; 4],
            tx: [0; 4 * DATAGRAM_BYTES],
        }
    }
}

impl Default for MdnsBuffers {
    fn default() -> Self {
        MdnsBuffers::new()
    }
}

/// The responder and its socket.
pub struct MdnsService {
    handle: SocketHandle,
    responder: Responder,
    datagram: [u8; DATAGRAM_BYTES],
    received: [u8; DATAGRAM_BYTES],
}

impl MdnsService {
    /// Bind UDP 5353 for `name` and `services`; `seed` jitters the timings.
    pub fn new<'a>(
        sockets: &mut SocketSet<'a>,
        buffers: &'a mut MdnsBuffers,
        name: &HostName,
        services: Services,
        seed: u64,
    ) -> Result<MdnsService, udp::BindError> {
        let MdnsBuffers { rx_meta, rx, tx_meta, tx } = buffers;
        let mut socket = udp::Socket::new(
            udp::PacketBuffer::new(&mut rx_meta[..], &mut rx[..]),
            udp::PacketBuffer::new(&mut tx_meta[..], &mut tx[..]),
        );
        socket.bind(MDNS_PORT)?;
        socket.set_hop_limit(Some(255));
        Ok(MdnsService {
            handle: sockets.add(socket),
            responder: Responder::new(name, services, seed),
            datagram: [0; DATAGRAM_BYTES],
            received: [0; DATAGRAM_BYTES],
        })
    }

    /// The responder (its name, whether it is claimed).
    pub fn responder(&self) -> &Responder {
        &self.responder
    }

    /// The board's address changed.
    pub fn set_address(&mut self, now: NetInstant, address: Option<Ipv4Addr>) {
        self.responder.set_address(millis(now), address);
    }

    /// The link came up again ([`Responder::link_up`]).
    pub fn link_up(&mut self, now: NetInstant) {
        self.responder.link_up(millis(now));
    }

    /// Take what arrived, send what is due, log name changes.
    pub fn poll(&mut self, now: NetInstant, sockets: &mut SocketSet<'_>, log: &mut impl Write) {
        let t = millis(now);
        let socket = sockets.get_mut::<udp::Socket>(self.handle);
        while let Ok((n, meta)) = socket.recv_slice(&mut self.received) {
            let IpAddress::Ipv4(ip) = meta.endpoint.addr;
            {
                let from = SocketAddrV4::new(ip, meta.endpoint.port);
                self.responder.receive(t, from, &self.received[..n]);
            }
        }
        while socket.can_send() {
            let Some((dest, n)) = self.responder.poll(t, &mut self.datagram) else { break };
            let to = match dest {
                Destination::Multicast => IpEndpoint::new(MDNS_GROUP.into(), MDNS_PORT),
                Destination::Unicast(a) => IpEndpoint::new((*a.ip()).into(), a.port()),
            };
            if socket.send_slice(&self.datagram[..n], to).is_err() {
                break;
            }
        }
        match self.responder.take_event() {
            Some(NameEvent::Claimed) => {
                let _ = writeln!(
                    log,
                    "mdns: {}.local is this board's (probed, no other host has it)",
                    self.responder.name()
                );
            }
            Some(NameEvent::Conflict) => {
                let _ = writeln!(
                    log,
                    "mdns: another host has the name: this board is now {}.local (set hostname= in raytracer.txt)",
                    self.responder.name()
                );
            }
            None => {}
        }
    }
}

fn millis(now: NetInstant) -> Instant {
    Instant::from_millis(u64::try_from(now.total_millis()).unwrap_or(0))
}
