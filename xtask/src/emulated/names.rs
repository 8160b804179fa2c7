//! Two boards found by name on one virtual LAN (issue 35, "found by
//! name"): both cards say `hostname=raytracer`, each has a MAC of its own,
//! dnsmasq gives both an address. The first claims `raytracer.local`; the
//! second's probe meets the first's answer and it takes `raytracer-2` and
//! says so. python-zeroconf (Debian's, an mDNS stack independent of the
//! firmware's) on a host of the LAN browses the three service types and
//! resolves every instance: both boards, each by its name with its own
//! address, port and TXT. Then each board, at the address its name
//! resolved to: a seed frame and FFmpeg's RTSP frame byte-exact, the page
//! answering to `Host: NAME.local`. Multicast stays inside the test's
//! namespaces (DEVELOPERS.md's network rule).

use std::net::{Ipv4Addr, SocketAddr};
use std::path::Path;
use std::time::Duration;

use super::addressing::{exchange, seed_frame};
use super::lan::{Addressing, Lan};
use super::lossy::Igmp;
use super::qemu_e2e::expected_frame;
use crate::support::tools::root;
use crate::support::Result;

/// mDNS's group (RFC 6762 section 3).
const MDNS_GROUP: Ipv4Addr = Ipv4Addr::new(224, 0, 0, 251);

/// Debian packages the check runs: the independent mDNS browser and
/// FFmpeg.
pub const PACKAGES: [&str; 2] = ["python3-zeroconf", "ffmpeg"];

/// The light of every frame asked for (the seed frames' too,
/// `addressing::seed_frame`).
pub(crate) const LIGHT: [i32; 3] = [3 << 10, 4 << 10, -(2 << 10)];

fn settings(mac: &str) -> String {
    format!("# cargo xtask names\nip=dhcp\nhostname=raytracer\nmac={mac}\n")
}

/// The address a board's UART last reported.
fn address_of(uart: &str) -> Option<Ipv4Addr> {
    let line = uart.lines().rev().find(|l| l.starts_with("net: address "))?;
    line.strip_prefix("net: address ")?.split('/').next()?.parse().ok()
}

/// Run the check against the firmware `elf` (a frame-mode build); while
/// it waits for the announcements to age out, with both boards paused,
/// `meanwhile` runs.
pub fn run(elf: &Path, meanwhile: impl FnOnce() -> Result<()>) -> Result<()> {
    let first = Addressing::Settings { text: settings("02:de:1c:00:35:0a"), dhcp: Some(Ipv4Addr::new(10, 0, 2, 77)) };
    let started = std::time::Instant::now();
    let mut lan = Lan::boot_addressed(elf, 1, &[], first)?;
    // `boot_addressed` returns once the board's address line is out.
    let addressed = started.elapsed();
    lan.guest
        .wait_for_line(0, "mdns: raytracer.local is this board's", Duration::from_secs(30))
        .map_err(|e| lan.with_uart(e))?;
    // Its membership in 224.0.0.251 reported once it had the address (a
    // switch that snoops IGMP forwards the group's queries to it).
    let reports = |lan: &Lan| lan.relay.igmp().iter().filter(|m| **m == Igmp::Report(MDNS_GROUP)).count();
    if reports(&lan) == 0 {
        return Err(lan.with_uart(format!("no IGMP report for {MDNS_GROUP} from the board: {:?}", lan.relay.igmp())));
    }
    // The first frame by name: the seed service found by browsing, its
    // instance resolved, a frame from it.
    let found = browse(&lan, "1")?;
    let entry = found["_raytracer._tcp.local."]
        .as_array()
        .and_then(|l| l.iter().find(|e| e["name"] == "raytracer._raytracer._tcp.local."))
        .ok_or_else(|| format!("python-zeroconf did not find the first board's seed service: {found}"))?;
    let resolved: Ipv4Addr = entry["addresses"][0]
        .as_str()
        .and_then(|a| a.parse().ok())
        .ok_or_else(|| format!("no address for raytracer.local: {entry}"))?;
    let want = expected_frame(LIGHT)?;
    let frame = want.clone();
    lan.on_host(0, move || by_name("raytracer", resolved, &frame)).map_err(|e| lan.with_uart(e))?;
    println!(
        "names: from QEMU's start: a DHCP address after {:.1} s, the first frame by name (browsed, resolved, fetched) after {:.1} s",
        addressed.as_secs_f64(),
        started.elapsed().as_secs_f64()
    );
    let second = lan.add_board(elf, &settings("02:de:1c:00:35:0b"))?;
    let renamed = second.wait_for_line(0, "mdns: another host has the name", Duration::from_secs(30));
    let second_uart = second.uart();
    renamed.map_err(|e| format!("the second board: {e}\n{second_uart}"))?;
    if !second_uart.contains("this board is now raytracer-2.local") {
        return Err(format!("the second board did not take raytracer-2:\n{second_uart}"));
    }
    second
        .wait_for_line(0, "mdns: raytracer-2.local is this board's", Duration::from_secs(30))
        .map_err(|e| format!("the second board: {e}"))?;
    let a = address_of(&lan.guest.uart()).ok_or_else(|| lan.with_uart("no address"))?;
    let b = address_of(&second_uart).ok_or("the second board has no address")?;
    if a == b {
        return Err(format!("both boards at {a}"));
    }
    println!("names: two boards with hostname=raytracer: raytracer.local at {a}, raytracer-2.local at {b} (renamed on the conflict)");

    let found = browse(&lan, "4")?;
    let text = found.to_string();
    for (ty, port) in [("_http._tcp.local.", 80), ("_rtsp._tcp.local.", 8554), ("_raytracer._tcp.local.", 7878)] {
        for (name, address) in [("raytracer", a), ("raytracer-2", b)] {
            let instance = format!("{name}.{ty}");
            let entry = found[ty]
                .as_array()
                .and_then(|list| list.iter().find(|e| e["name"] == instance.as_str()))
                .ok_or_else(|| format!("python-zeroconf did not find {instance}: {text}"))?;
            let server_ok = entry["server"] == format!("{name}.local.").as_str();
            let address_ok =
                entry["addresses"].as_array().is_some_and(|l| l.iter().any(|x| x == address.to_string().as_str()));
            if !server_ok || !address_ok || entry["port"] != port {
                return Err(format!("{instance} resolved to {entry}, not {name}.local. {address}:{port}"));
            }
            if ty.starts_with("_rtsp") && entry["txt"]["path"] != "/orbit" {
                return Err(format!("{instance}'s TXT: {}", entry["txt"]));
            }
        }
    }
    println!(
        "names: python-zeroconf lists both boards' _http, _rtsp and _raytracer services, each resolved to its board"
    );
    let out = lan
        .command(0, root().join("target/release/rt-client").to_str().unwrap_or("rt-client"))
        .args(["discover", "--wait", "4"])
        .output()
        .map_err(|e| format!("rt-client discover: {e}"))?;
    let table = String::from_utf8_lossy(&out.stdout).into_owned();
    let version = env!("CARGO_PKG_VERSION");
    for (name, address) in [("raytracer", a), ("raytracer-2", b)] {
        let line = format!("{name}.local  {address}  seed port 7878  version {version}, renderer fpga, code ok");
        if !out.status.success() || !table.lines().any(|l| l == line) {
            return Err(format!(
                "rt-client discover did not list {line:?}:\n{table}{}",
                String::from_utf8_lossy(&out.stderr)
            ));
        }
    }
    println!("names: rt-client discover lists both boards with their version, renderer and fault code");

    for (name, address) in [("raytracer", a), ("raytracer-2", b)] {
        let frame = want.clone();
        lan.on_host(0, move || by_name(name, address, &frame)).map_err(|e| lan.with_uart(e))?;
        let ffmpeg = lan
            .command(0, "ffmpeg")
            .args(["-nostdin", "-loglevel", "error", "-analyzeduration", "0", "-probesize", "32"])
            .args(["-rtsp_transport", "tcp", "-i", &format!("rtsp://{address}:8554/light/3,4,-2")])
            .args(["-fps_mode", "passthrough", "-frames:v", "1", "-f", "rawvideo", "pipe:1"])
            .output()
            .map_err(|e| format!("ffmpeg: {e}"))?;
        if ffmpeg.stdout != want {
            return Err(lan.with_uart(format!(
                "FFmpeg's frame from {name}.local ({address}): {} bytes, not the model's: {}",
                ffmpeg.stdout.len(),
                String::from_utf8_lossy(&ffmpeg.stderr)
            )));
        }
    }
    println!("names: from each, by the address its name resolved to: a seed frame and FFmpeg's RTSP frame byte-exact, the page for Host: NAME.local");

    // Long after the boot announcements (whose host records live 120 s in
    // a peer's cache), both names and services are still found: by
    // answers to queries, which reach a board only through its MAC's
    // multicast filter (xtask/src/emulated/mac_filter.rs).
    let both = |paused: bool| -> Result<()> {
        lan.guest.pause(paused)?;
        lan.others.iter().try_for_each(|(g, _)| g.pause(paused))
    };
    both(true)?;
    let outcome = meanwhile();
    both(false)?;
    outcome?;
    if let Some(wait) = AFTER_ANNOUNCEMENTS.checked_sub(started.elapsed()) {
        std::thread::sleep(wait);
    }
    let found = browse_hosts(&lan, "2", &["raytracer.local", "raytracer-2.local"])?;
    for (name, address) in [("raytracer", a), ("raytracer-2", b)] {
        let host = format!("{name}.local");
        let answered =
            found["hosts"][&host].as_array().is_some_and(|l| l.iter().any(|x| x == address.to_string().as_str()));
        let listed = found["_raytracer._tcp.local."]
            .as_array()
            .is_some_and(|l| l.iter().any(|e| e["name"] == format!("{name}._raytracer._tcp.local.").as_str()));
        if !answered || !listed {
            return Err(lan.with_uart(format!(
                "{:.0} s after boot, {host} ({address}) answered {answered}, its service listed {listed}: {found}",
                started.elapsed().as_secs_f64()
            )));
        }
    }
    println!(
        "names: {:.0} s after boot (announcements long aged out): a one-shot query for each name answered with its address, both services browsed",
        started.elapsed().as_secs_f64()
    );
    // An IGMP general query (as a router or snooping switch sends every
    // 125 s) answered with a report for the group.
    let before = reports(&lan);
    let out = lan
        .command(0, "/usr/bin/python3")
        .args(["-c", IGMP_QUERY])
        .output()
        .map_err(|e| format!("the IGMP query: {e}"))?;
    if !out.status.success() {
        return Err(format!("the IGMP query: {}", String::from_utf8_lossy(&out.stderr)));
    }
    let asked = std::time::Instant::now();
    while reports(&lan) == before && asked.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(100));
    }
    if reports(&lan) == before {
        return Err(lan.with_uart(format!(
            "no IGMP report for {MDNS_GROUP} within 5 s of a general query: {:?}",
            lan.relay.igmp()
        )));
    }
    println!(
        "names: IGMP: the board reported {MDNS_GROUP} once addressed, and again {:.1} s after a general query",
        asked.elapsed().as_secs_f64()
    );
    Ok(())
}

/// An IGMPv2 general query (RFC 2236 section 2: type 0x11, maximum
/// response time 1 s, group 0) to 224.0.0.1, sent from a host of the LAN.
const IGMP_QUERY: &str = r#"
import socket, struct
def checksum(b):
    s = sum(struct.unpack(">%dH" % (len(b) // 2), b))
    s = (s & 0xffff) + (s >> 16)
    return ~(s + (s >> 16)) & 0xffff
q = struct.pack(">BBH4s", 0x11, 10, 0, bytes(4))
q = struct.pack(">BBH4s", 0x11, 10, checksum(q), bytes(4))
s = socket.socket(socket.AF_INET, socket.SOCK_RAW, socket.IPPROTO_IGMP)
s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
s.sendto(q, ("224.0.0.1", 0))
"#;

/// How long after the first board's start the names are looked up again:
/// past the 120 s a host record's announcement lives in a cache (RFC 6762
/// section 10).
const AFTER_ANNOUNCEMENTS: Duration = Duration::from_secs(130);

/// What tests/mdns/browse.py (python-zeroconf) finds from host 0 in
/// `seconds`.
fn browse(lan: &Lan, seconds: &str) -> Result<serde_json::Value> {
    browse_hosts(lan, seconds, &[])
}

/// [`browse`], and the addresses a one-shot query for each of `hosts`
/// brings back (under `"hosts"`).
fn browse_hosts(lan: &Lan, seconds: &str, hosts: &[&str]) -> Result<serde_json::Value> {
    let script = root().join("tests/mdns/browse.py");
    let mut command = lan.command(0, "/usr/bin/python3");
    command.arg(&script).args(["--seconds", seconds]);
    if !hosts.is_empty() {
        command.arg("--hosts").args(hosts);
    }
    let out = command.output().map_err(|e| format!("{}: {e}", script.display()))?;
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    if !out.status.success() {
        return Err(lan.with_uart(format!("browse.py failed: {text}{}", String::from_utf8_lossy(&out.stderr))));
    }
    serde_json::from_str(&text).map_err(|e| format!("browse.py's JSON: {e}: {text}"))
}

/// A seed frame from `address`, and the page asked for by `name.local`.
fn by_name(name: &str, address: Ipv4Addr, want: &[u8]) -> Result<()> {
    seed_frame(SocketAddr::from((address, 7878)), want).map_err(|e| format!("{name}.local: {e}"))?;
    let request = format!("GET / HTTP/1.1\r\nHost: {name}.local\r\nConnection: close\r\n\r\n");
    let page = exchange(SocketAddr::from((address, 80)), &request)?;
    if !page.starts_with("HTTP/1.1 200") || !page.contains("<html") {
        return Err(format!("{name}.local's page: {:?}", &page[..page.len().min(120)]));
    }
    Ok(())
}
