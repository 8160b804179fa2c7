//! Frames that reach the emulated board while its link comes up.
//!
//! A peer does not wait for the board: a switch port forwards broadcasts
//! and a desktop's IPv6 start-up (router solicitations, MLD reports) from
//! the moment the cable is in. On the board the MAC drops what arrives
//! while its receiver is off. QEMU's model (hw/net/npcm_gmac.c, up to
//! 10.0.2) instead refuses such a frame, and its `-nic dgram` backend then
//! stops reading until the model flushes its queue, which it does only on
//! a DMA-control write that starts receive or a status write that clears
//! RU, never on the MAC-configuration write that turns the receiver on.
//! One frame in that window left the board deaf for good (a fresh-clone
//! suite run's lossy-link step: 7 SYNs and no answer).
//!
//! The test sends ARP requests for the board from before QEMU starts,
//! every millisecond, until the link is up, then asks once more: the
//! board must answer.

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use smoltcp::wire::{
    ArpOperation, ArpPacket, ArpRepr, EthernetAddress, EthernetFrame, EthernetProtocol, EthernetRepr, Ipv4Address,
};

use crate::images::firmware::{free_udp_port, Guest};
use crate::support::Result;

/// The QEMU build's address and MAC (firmware/src/boards/qemu_npcm750.rs).
const BOARD_IP: Ipv4Address = Ipv4Address::new(10, 0, 2, 15);
const BOARD_MAC: EthernetAddress = EthernetAddress([0x52, 0x54, 0x00, 0x12, 0x34, 0x56]);
/// The asking peer (slirp's gateway address, on the board's subnet).
const PEER_IP: Ipv4Address = Ipv4Address::new(10, 0, 2, 2);
const PEER_MAC: EthernetAddress = EthernetAddress([0x02, 0, 0, 0, 0, 0x02]);

/// A broadcast ARP request (RFC 826) from the peer for `BOARD_IP`,
/// padded to the Ethernet minimum.
fn arp_request() -> Vec<u8> {
    let mut f = vec![0u8; 60];
    let mut frame = EthernetFrame::new_unchecked(&mut f[..]);
    EthernetRepr { src_addr: PEER_MAC, dst_addr: EthernetAddress::BROADCAST, ethertype: EthernetProtocol::Arp }
        .emit(&mut frame);
    ArpRepr::EthernetIpv4 {
        operation: ArpOperation::Request,
        source_hardware_addr: PEER_MAC,
        source_protocol_addr: PEER_IP,
        target_hardware_addr: EthernetAddress([0; 6]),
        target_protocol_addr: BOARD_IP,
    }
    .emit(&mut ArpPacket::new_unchecked(frame.payload_mut()));
    f
}

/// Whether `f` is the board's ARP reply to the peer.
fn is_board_arp_reply(f: &[u8]) -> bool {
    let Ok(frame) = EthernetFrame::new_checked(f) else { return false };
    if frame.dst_addr() != PEER_MAC || frame.ethertype() != EthernetProtocol::Arp {
        return false;
    }
    let arp = ArpPacket::new_checked(frame.payload()).and_then(|p| ArpRepr::parse(&p));
    matches!(arp, Ok(ArpRepr::EthernetIpv4 {
        operation: ArpOperation::Reply,
        source_hardware_addr,
        source_protocol_addr,
        ..
    }) if source_hardware_addr == BOARD_MAC && source_protocol_addr == BOARD_IP)
}

/// Boot `elf` on a `-nic dgram` link whose other end sends ARP requests
/// every millisecond from before boot until the link is up; then the board
/// must answer a request within `ANSWER_WITHIN`.
pub fn run(elf: &Path) -> Result<()> {
    const ANSWER_WITHIN: Duration = Duration::from_secs(5);
    let peer = UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let qemu_port = free_udp_port()?;
    let peer_port = peer.local_addr().map_err(|e| e.to_string())?.port();
    let qemu = SocketAddr::from(([127, 0, 0, 1], qemu_port));
    let stop = Arc::new(AtomicBool::new(false));
    let sender = {
        let (peer, stop) = (peer.try_clone().map_err(|e| e.to_string())?, stop.clone());
        std::thread::spawn(move || {
            let (request, mut sent) = (arp_request(), 0u64);
            while !stop.load(Ordering::Relaxed) {
                // Refused while QEMU has not bound its port yet: go on.
                if peer.send_to(&request, qemu).is_ok() {
                    sent += 1;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            sent
        })
    };
    let netdev = crate::images::firmware::dgram_netdev(qemu_port, peer_port);
    let booted = Guest::boot_netdev(elf, &netdev, &[]).and_then(|mut g| {
        g.wait_for_log("link up", Duration::from_secs(30))?;
        Ok(g)
    });
    // A little longer, so requests also arrive just after the link.
    std::thread::sleep(Duration::from_millis(100));
    stop.store(true, Ordering::Relaxed);
    let sent = sender.join().map_err(|_| "the ARP sender panicked")?;
    let g = booted?;
    // Drain what came during the start-up, then ask once more.
    peer.set_read_timeout(Some(Duration::from_millis(200))).map_err(|e| e.to_string())?;
    let mut buf = [0u8; 2048];
    let mut early = 0;
    while let Ok(n) = peer.recv(&mut buf) {
        early += usize::from(is_board_arp_reply(&buf[..n]));
    }
    peer.send_to(&arp_request(), qemu).map_err(|e| e.to_string())?;
    let deadline = Instant::now() + ANSWER_WITHIN;
    while Instant::now() < deadline {
        if let Ok(n) = peer.recv(&mut buf) {
            if is_board_arp_reply(&buf[..n]) {
                println!(
                    "qemu e2e: frames while the link comes up ({sent} ARP requests from before boot, {early} answered then): the board answers the next ... ok"
                );
                return Ok(());
            }
        }
    }
    Err(format!(
        "after {sent} ARP requests sent while the board came up ({early} answered then), it did not answer one within {} s: its receive path is stuck\n--- UART log ---\n{}",
        ANSWER_WITHIN.as_secs(),
        g.uart()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_request_asks_for_the_board_and_only_its_reply_counts() {
        let req = arp_request();
        assert_eq!(req.len(), 60);
        assert_eq!(&req[38..42], &BOARD_IP.octets());
        assert!(!is_board_arp_reply(&req), "a request is not a reply");
        let mut reply = vec![0u8; 60];
        let mut frame = EthernetFrame::new_unchecked(&mut reply[..]);
        EthernetRepr { src_addr: BOARD_MAC, dst_addr: PEER_MAC, ethertype: EthernetProtocol::Arp }.emit(&mut frame);
        ArpRepr::EthernetIpv4 {
            operation: ArpOperation::Reply,
            source_hardware_addr: BOARD_MAC,
            source_protocol_addr: BOARD_IP,
            target_hardware_addr: PEER_MAC,
            target_protocol_addr: PEER_IP,
        }
        .emit(&mut ArpPacket::new_unchecked(frame.payload_mut()));
        assert!(is_board_arp_reply(&reply));
        reply[31] = 16;
        assert!(!is_board_arp_reply(&reply), "another sender's address");
    }
}
