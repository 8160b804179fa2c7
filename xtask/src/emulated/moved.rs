//! A board carried from one network to another (issue 46, "cable
//! moved"): on the virtual LAN with dnsmasq it is found as
//! `raytracer.local` at its lease; then its cable comes out (QEMU's
//! `set_link`), the LAN loses its DHCP server and a host becomes a laptop
//! with only a link-local address, and the cable goes back in: within 15 s
//! the laptop finds `raytracer.local` at a link-local address and takes a
//! frame from it. Carried back (cable out, dnsmasq again, cable in), a
//! host finds it at its lease within 15 s. Before the board restarted DHCP
//! and re-probed at link-up, it kept the lease of the network it had left.
//! Every query is a one-shot mDNS query (tests/mdns/browse.py `--hosts`)
//! through the relay's MAC filter. Last, a frame from another device with
//! the board's MAC (two boards from one card image): the board says so on
//! its UART and in `/status`.

use std::net::{Ipv4Addr, SocketAddr};
use std::path::Path;
use std::time::{Duration, Instant};

use super::addressing::{exchange, seed_frame};
use super::lan::{Addressing, Lan};
use super::qemu_e2e::expected_frame;
use crate::support::tools::root;
use crate::support::Result;

/// The board's MAC and lease on the DHCP LAN.
const MAC: &str = "02:de:1c:00:46:04";
const LEASE: Ipv4Addr = Ipv4Addr::new(10, 0, 2, 77);

/// How soon after the cable goes in the board must be found by name.
const FOUND_WITHIN: Duration = Duration::from_secs(15);

/// Run the check against the firmware `elf` (a frame-mode build).
pub fn run(elf: &Path) -> Result<()> {
    let text = format!("# cargo xtask moved\nip=dhcp\nhostname=raytracer\nmac={MAC}\n");
    let mut lan = Lan::boot_addressed(elf, 2, &[], Addressing::Settings { text, dhcp: Some(LEASE) })?;
    lan.guest
        .wait_for_line(0, "mdns: raytracer.local is this board's", Duration::from_secs(30))
        .map_err(|e| lan.with_uart(e))?;
    let (took, at) = found(&lan, 0, |a| a == LEASE)?;
    println!("moved: on the DHCP LAN: raytracer.local at {at} (found in {:.1} s)", took.as_secs_f64());

    // To a laptop: no DHCP server, a host with a link-local address only.
    unplug(&mut lan)?;
    lan.stop_dhcp();
    lan.make_link_local_only(1)?;
    lan.guest.set_link(true)?;
    let (took, at) = found(&lan, 1, |a| a.octets()[..2] == [169, 254])?;
    let want = expected_frame(super::names::LIGHT)?;
    lan.on_host(1, move || seed_frame(SocketAddr::from((at, 7878)), &want)).map_err(|e| lan.with_uart(e))?;
    println!(
        "moved: to a network without DHCP: raytracer.local at {at} {:.1} s after the cable went in, a seed frame from it byte-exact",
        took.as_secs_f64()
    );

    // And back to the DHCP LAN.
    unplug(&mut lan)?;
    lan.move_dhcp(MAC, LEASE)?;
    lan.guest.set_link(true)?;
    let (took, at) = found(&lan, 0, |a| a == LEASE)?;
    println!(
        "moved: back on the DHCP LAN: raytracer.local at {at} {:.1} s after the cable went in",
        took.as_secs_f64()
    );

    // Another device with the board's MAC (a second board from the same
    // card image): one broadcast frame from it, and the board says so.
    let from = lan.guest.uart().len();
    let out =
        lan.command(0, "/usr/bin/python3").args(["-c", CLASH, MAC]).output().map_err(|e| format!("python3: {e}"))?;
    if !out.status.success() {
        return Err(format!("the frame from the board's MAC: {}", String::from_utf8_lossy(&out.stderr)));
    }
    let said = lan
        .guest
        .wait_for_line(from, "another device on this network sends from this board's MAC", Duration::from_secs(10))
        .map_err(|e| lan.with_uart(e))?;
    // The switch learnt the MAC on host 0's port; an answer from the
    // board teaches it back before the page is asked.
    found(&lan, 0, |a| a == LEASE)?;
    let request = "GET /status HTTP/1.1\r\nHost: raytracer.local\r\nConnection: close\r\n\r\n";
    let status =
        lan.on_host(0, move || exchange(SocketAddr::from((LEASE, 80)), request)).map_err(|e| lan.with_uart(e))?;
    let want = format!("\"mac\":\"{MAC}\",\"mac_from\":\"settings\",\"mac_clashes\":1");
    if !status.contains(&want) {
        return Err(format!("/status after one frame from the board's MAC lacks {want}: {status}"));
    }
    println!("moved: a frame from another device with the board's MAC: {said:?}; /status has {want}");
    Ok(())
}

/// One broadcast Ethernet frame from the MAC given as the argument, out
/// of the host's eth0 (a raw packet socket).
const CLASH: &str = r#"
import socket, sys
mac = bytes(int(b, 16) for b in sys.argv[1].split(":"))
s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW)
s.bind(("eth0", 0))
s.send(b"\xff" * 6 + mac + b"\x88\xb5" + bytes(46))
"#;

/// Take the cable out and wait until the board saw it go.
fn unplug(lan: &mut Lan) -> Result<()> {
    let from = lan.guest.uart().len();
    lan.guest.set_link(false)?;
    lan.guest.wait_for_line(from, "link down", Duration::from_secs(10)).map(drop).map_err(|e| lan.with_uart(e))
}

/// From host `k`, one-shot queries for `raytracer.local` until one is
/// answered with an address `good` accepts, within [`FOUND_WITHIN`] of
/// now; how long it took and the address.
fn found(lan: &Lan, k: usize, good: impl Fn(Ipv4Addr) -> bool) -> Result<(Duration, Ipv4Addr)> {
    let start = Instant::now();
    let script = root().join("tests/mdns/browse.py");
    let mut answers = Vec::new();
    while start.elapsed() < FOUND_WITHIN {
        let out = lan
            .command(k, "/usr/bin/python3")
            .arg(&script)
            .args(["--seconds", "0", "--hosts", "raytracer.local"])
            .output()
            .map_err(|e| format!("{}: {e}", script.display()))?;
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        let json: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
        let addresses: Vec<Ipv4Addr> = json["hosts"]["raytracer.local"]
            .as_array()
            .map(|l| l.iter().filter_map(|a| a.as_str()?.parse().ok()).collect())
            .unwrap_or_default();
        if let Some(&a) = addresses.iter().find(|&&a| good(a)) {
            return Ok((start.elapsed(), a));
        }
        answers.push(format!("{:.1} s: {addresses:?}", start.elapsed().as_secs_f64()));
    }
    Err(lan.with_uart(format!(
        "raytracer.local not found from host {k} within {FOUND_WITHIN:?} of the cable going in; answers: {answers:?}"
    )))
}
