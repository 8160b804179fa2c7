//! The board's address on networks it was not built for (issue 35, "any
//! network, no rebuild"), on the emulated board:
//!
//! 1. **QEMU's DHCP server.** With no settings file the board asks slirp's
//!    built-in server and takes 10.0.2.15 (every other slirp boot of the
//!    suite relies on it too).
//! 2. **dnsmasq on a virtual LAN.** Settings with `ip=dhcp` and a MAC of
//!    their own: the board takes the address dnsmasq keeps for that MAC,
//!    and serves a byte-exact frame, `/status` (naming the address and
//!    that it came from DHCP) and an RTSP description
//!    there. dnsmasq then keeps another address for it and refuses the
//!    old one: at its renewal (T1, a minute into the two-minute lease) the
//!    board moves, and every service (seed port, page, RTSP's description)
//!    answers at the new address.
//! 3. **No DHCP server.** The board claims a 169.254.x.y address within
//!    10 s of its network start (RFC 3927) and serves a frame there to a
//!    host with a link-local address of its own.
//!
//! Everything but case 1 stays inside the test's own namespaces
//! (DEVELOPERS.md's network rule).

use std::io::{Read, Write};
use std::net::{Ipv4Addr, SocketAddr, TcpStream};
use std::path::Path;
use std::time::{Duration, Instant};

use super::lan::{Addressing, Lan};
use super::qemu_e2e::expected_frame;
use crate::images::firmware::Guest;
use crate::support::Result;

/// The MAC of the board in cases 2 and 3 (not QEMU's default, so that the
/// settings' MAC is the one that counts).
const MAC: &str = "02:de:1c:00:35:01";

/// The addresses dnsmasq gives it in case 2, before and after the move.
const FIRST: Ipv4Addr = Ipv4Addr::new(10, 0, 2, 77);
const MOVED: Ipv4Addr = Ipv4Addr::new(10, 0, 2, 78);

/// Run the three cases against the firmware `elf` (a frame-mode build).
pub fn run(elf: &Path) -> Result<()> {
    slirp(elf)?;
    println!("addressing: slirp's DHCP server: 10.0.2.15, frames through its forwards");
    let moved_after = dnsmasq(elf)?;
    println!(
        "addressing: dnsmasq on a virtual LAN: {FIRST}, then {MOVED} {:.0} s later at the renewal, every service following",
        moved_after.as_secs_f64()
    );
    let (address, took) = link_local(elf)?;
    println!("addressing: no DHCP server: {address} claimed {:.1} s after the network started", took.as_secs_f64());
    Ok(())
}

/// Case 1.
fn slirp(elf: &Path) -> Result<()> {
    let g = Guest::boot(elf, &[])?;
    let line = g.uart().lines().find(|l| l.starts_with("net: address ")).map(str::to_string).unwrap_or_default();
    if !line.starts_with("net: address 10.0.2.15/24 via 10.0.2.2 (dhcp)") {
        return Err(format!("with no settings under slirp the board said {line:?}"));
    }
    let port = g.port_single;
    let want = expected_frame(LIGHT)?;
    seed_frame(SocketAddr::from(([127, 0, 0, 1], port)), &want)
}

/// The light every frame here is asked at.
const LIGHT: [i32; 3] = [3 << 10, 4 << 10, -(2 << 10)];

fn settings(extra: &str) -> String {
    format!("# case of cargo xtask addressing\nmac={MAC}\n{extra}")
}

/// Case 2; how long the move took from dnsmasq's restart.
fn dnsmasq(elf: &Path) -> Result<Duration> {
    let addressing = Addressing::Settings { text: settings("ip=dhcp\n"), dhcp: Some(FIRST) };
    let mut lan = Lan::boot_addressed(elf, 1, &[], addressing)?;
    let line = lan.guest.wait_for_line(0, "net: address ", Duration::from_secs(30)).map_err(|e| lan.with_uart(e))?;
    if !line.starts_with(&format!("net: address {FIRST}/24 via 10.0.2.2 (dhcp)")) {
        return Err(lan.with_uart(format!("dnsmasq keeps {FIRST} for the board; it said {line:?}")));
    }
    if !lan.guest.uart().contains(&format!("settings' MAC {}", MAC.replace(':', "-"))) {
        return Err(lan.with_uart("the board does not say it took the settings' MAC"));
    }
    every_service(&lan, FIRST).map_err(|e| lan.with_uart(e))?;
    let from = lan.guest.uart().len();
    let start = Instant::now();
    lan.move_dhcp(MAC, MOVED)?;
    // T1 is half the 2-minute lease: the renewal comes within a minute.
    let moved = format!("net: address {MOVED}/24");
    lan.guest.wait_for_line(from, &moved, Duration::from_secs(100)).map_err(|e| lan.with_uart(e))?;
    let took = start.elapsed();
    every_service(&lan, MOVED).map_err(|e| lan.with_uart(format!("after the move: {e}")))?;
    Ok(took)
}

/// Case 3: the address and how long after the network start it came.
fn link_local(elf: &Path) -> Result<(Ipv4Addr, Duration)> {
    let addressing = Addressing::Settings { text: settings(""), dhcp: None };
    let lan = Lan::boot_addressed(elf, 1, &[], addressing)?;
    // `Guest::start` waited for the address; its wait began at "listening".
    let took = lan.guest.address_wait;
    let uart = lan.guest.uart();
    let line = uart.lines().find(|l| l.starts_with("net: address ")).unwrap_or_default();
    let address: Ipv4Addr = line
        .strip_prefix("net: address ")
        .and_then(|r| r.split('/').next())
        .and_then(|a| a.parse().ok())
        .ok_or_else(|| lan.with_uart(format!("no address line: {line:?}")))?;
    let o = address.octets();
    let link_local = o[0] == 169 && o[1] == 254 && (1..=254).contains(&o[2]);
    if !link_local || !line.ends_with("(link-local)") {
        return Err(lan.with_uart(format!("with no DHCP server the board said {line:?}")));
    }
    if took > Duration::from_secs(10) {
        return Err(
            lan.with_uart(format!("the link-local address came {took:?} after the network started (10 s allowed)"))
        );
    }
    lan.add_link_local(0)?;
    let want = expected_frame(LIGHT)?;
    let to = SocketAddr::from((address, 7878));
    lan.on_host(0, move || seed_frame(to, &want)).map_err(|e| lan.with_uart(e))?;
    Ok((address, took))
}

/// The seed port, the page's `/status` and RTSP's description answer at
/// `address`, the description naming it.
fn every_service(lan: &Lan, address: Ipv4Addr) -> Result<()> {
    let want = expected_frame(LIGHT)?;
    lan.on_host(0, move || {
        seed_frame(SocketAddr::from((address, 7878)), &want)?;
        let status = exchange(
            SocketAddr::from((address, 80)),
            &format!("GET /status HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n"),
        )?;
        let says = format!("\"address\":\"{address}\",\"address_from\":\"dhcp\"");
        if !status.starts_with("HTTP/1.1 200") || !status.contains(&says) {
            return Err(format!("/status at {address} lacks {says}: {status:?}"));
        }
        let sdp = exchange(
            SocketAddr::from((address, 8554)),
            &format!(
                "DESCRIBE rtsp://{address}:8554/light/3/4/-2 RTSP/1.0\r\nCSeq: 1\r\nAccept: application/sdp\r\n\r\n"
            ),
        )?;
        if !sdp.starts_with("RTSP/1.0 200") || !sdp.contains(&format!("IN IP4 {address}")) {
            return Err(format!("DESCRIBE at {address}: {sdp:?}"));
        }
        Ok(())
    })
}

/// Send `request` to `to` and read the answer until the peer closes or
/// goes quiet for 3 s.
pub(crate) fn exchange(to: SocketAddr, request: &str) -> Result<String> {
    let mut c = TcpStream::connect_timeout(&to, Duration::from_secs(5)).map_err(|e| format!("{to}: {e}"))?;
    c.set_read_timeout(Some(Duration::from_secs(3))).map_err(|e| e.to_string())?;
    c.write_all(request.as_bytes()).map_err(|e| e.to_string())?;
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        match c.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => got.extend_from_slice(&buf[..n]),
        }
    }
    Ok(String::from_utf8_lossy(&got).into_owned())
}

/// A seed-protocol frame from `to`, byte-exact.
pub(crate) fn seed_frame(to: SocketAddr, want: &[u8]) -> Result<()> {
    let mut c = TcpStream::connect_timeout(&to, Duration::from_secs(5)).map_err(|e| format!("{to}: {e}"))?;
    c.set_read_timeout(Some(Duration::from_secs(30))).map_err(|e| e.to_string())?;
    let light: Vec<u8> = LIGHT.iter().flat_map(|v| v.to_be_bytes()).collect();
    c.write_all(&light).map_err(|e| e.to_string())?;
    let mut got = Vec::new();
    c.read_to_end(&mut got).map_err(|e| format!("{to}: {e}"))?;
    if got != want {
        return Err(format!("a seed frame of {} bytes from {to}, not the model's", got.len()));
    }
    Ok(())
}
