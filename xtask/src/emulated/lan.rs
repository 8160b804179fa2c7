//! A virtual LAN for the emulated board, where each client is a host of
//! its own: QEMU's user networking (slirp) makes every client reach the
//! guest from 10.0.2.2, so a per-address limit could never be told apart
//! from a global one there.
//!
//! The board's MAC sends each Ethernet frame as a UDP datagram to the
//! relay (lossy.rs, here without faults), which puts it on a tap device.
//! The tap is a port of a bridge inside a network namespace made for the
//! run (the "switch", 10.0.2.2, the board's gateway); each host is a
//! namespace of its own with a veth port on that bridge and the address
//! 10.0.2.(20 + k). Nothing leaves the namespaces (DEVELOPERS.md's network
//! rule), and all of them go when the [`Lan`] is dropped.

use std::fs::File;
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::os::fd::AsRawFd;
use std::path::Path;
use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};
use std::thread;
use std::time::Duration;

use super::lossy::{self, ip, open_tap, Faults, Namespace, Relay};
use crate::images::firmware::{free_udp_port, Guest};
use crate::support::Result;

/// The board's address (firmware/src/platform/qemu_npcm750.rs).
pub const BOARD: Ipv4Addr = Ipv4Addr::new(10, 0, 2, 15);

/// The board's MAC (QEMU's default for the npcm750-evb's first GMAC).
const BOARD_MAC: &str = "52:54:00:12:34:56";

/// Numbers this process's LANs.
static LAN_SEQ: AtomicU32 = AtomicU32::new(0);

/// How the board on a [`Lan`] takes its address.
#[derive(Clone, Debug)]
pub enum Addressing {
    /// The tests' plan: 10.0.2.15 in the settings (`TEST_LAN_SETTINGS`).
    Plan,
    /// These settings (raytracer.txt), and a DHCP server (dnsmasq, on the
    /// switch) if `dhcp` names the address it gives.
    Settings { text: String, dhcp: Option<Ipv4Addr> },
}

/// The emulated board on a LAN of `hosts` hosts.
pub struct Lan {
    /// The board (dropped first: QEMU stops before its network goes).
    pub guest: Guest,
    /// The link between the board and the switch (faults can be set).
    pub relay: Relay,
    /// More boards on the same switch ([`add_board`](Self::add_board)).
    pub others: Vec<(Guest, Relay)>,
    hosts: Vec<Namespace>,
    dhcp: Option<Dnsmasq>,
    switch: Namespace,
}

/// dnsmasq as the LAN's DHCP server, on the switch's bridge; stopped on
/// drop.
struct Dnsmasq {
    child: std::process::Child,
    leases: std::path::PathBuf,
}

impl Drop for Dnsmasq {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.leases);
    }
}

/// Debian's package of the LAN's DHCP server (the binary alone: no
/// service is started on the machine).
pub const PACKAGES: [&str; 1] = ["dnsmasq-base"];

/// Start dnsmasq in namespace `switch` on br0, giving `address` to the
/// board (`mac`) for 2 minutes, its shortest lease, and refusing (NAK) any
/// other (authoritative), so that a changed plan moves the board at its
/// next renewal.
fn dnsmasq(switch: &str, mac: &str, address: Ipv4Addr) -> Result<Dnsmasq> {
    let leases = std::env::temp_dir().join(format!("rt-dnsmasq-{switch}.leases"));
    let _ = std::fs::remove_file(&leases);
    let child = Command::new("ip")
        .args(["netns", "exec", switch, "dnsmasq", "--keep-in-foreground", "--conf-file=/dev/null", "--port=0"])
        .args(["--interface=br0", "--bind-interfaces", "--dhcp-authoritative", "--log-dhcp"])
        .arg("--dhcp-range=10.0.2.100,10.0.2.199,255.255.255.0,2m")
        .arg(format!("--dhcp-host={mac},{address}"))
        .arg(format!("--dhcp-leasefile={}", leases.display()))
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .map_err(|e| format!("dnsmasq: {e} (cargo xtask test installs {})", PACKAGES[0]))?;
    Ok(Dnsmasq { child, leases })
}

impl Lan {
    /// Boot `elf` on a LAN with `hosts` hosts and wait for its link.
    pub fn boot(elf: &Path, hosts: usize) -> Result<Lan> {
        Lan::boot_with(elf, hosts, &[])
    }

    /// [`boot`](Self::boot) with extra QEMU arguments (`-icount`).
    pub fn boot_with(elf: &Path, hosts: usize, extra: &[&str]) -> Result<Lan> {
        Lan::boot_addressed(elf, hosts, extra, Addressing::Plan)
    }

    /// [`boot_with`](Self::boot_with), the board taking its address as
    /// `addressing` says.
    pub fn boot_addressed(elf: &Path, hosts: usize, extra: &[&str], addressing: Addressing) -> Result<Lan> {
        lossy::available().map_err(|why| format!("the virtual LAN needs network namespaces: {why}"))?;
        // This process's LANs told apart (two may be up at once: `moved`
        // runs while `names` waits); interface names stay within 15 bytes.
        let id = format!("{}{}", std::process::id() % 100_000, LAN_SEQ.fetch_add(1, Ordering::Relaxed) % 10);
        let tap = format!("rtlan{id}");
        let tap_file = open_tap(&tap)?;
        let switch = Namespace::new(&format!("rtlan{id}"), &tap)?;
        let sw = switch.0.clone();
        // The tap becomes a bridge port; the switch keeps 10.0.2.2 on the
        // bridge.
        ip(&["-n", &sw, "addr", "flush", "dev", &tap])?;
        ip(&["-n", &sw, "link", "add", "br0", "type", "bridge"])?;
        ip(&["-n", &sw, "link", "set", &tap, "master", "br0"])?;
        ip(&["-n", &sw, "addr", "add", "10.0.2.2/24", "dev", "br0"])?;
        ip(&["-n", &sw, "link", "set", "br0", "up"])?;
        let mut named = Vec::new();
        for k in 0..hosts {
            let name = format!("rtlan{id}h{k}");
            let _ = ip(&["netns", "del", &name]);
            ip(&["netns", "add", &name])?;
            let host = Namespace(name.clone());
            let port = format!("p{k}");
            ip(&["-n", &sw, "link", "add", &port, "type", "veth", "peer", "name", "eth0", "netns", &name])?;
            ip(&["-n", &sw, "link", "set", &port, "master", "br0", "up"])?;
            let addr = format!("{}/24", Lan::host_addr(k));
            ip(&["-n", &name, "addr", "add", &addr, "dev", "eth0"])?;
            ip(&["-n", &name, "link", "set", "eth0", "up"])?;
            ip(&["-n", &name, "link", "set", "lo", "up"])?;
            // As in lossy.rs: the board as a fixed neighbour, so a lost
            // ARP answer never fails a connect (on the tests' plan only:
            // otherwise where the board is is what is tested).
            if matches!(addressing, Addressing::Plan) {
                ip(&["-n", &name, "neigh", "replace", &BOARD.to_string(), "lladdr", BOARD_MAC, "dev", "eth0"])?;
            }
            ip(&["-n", &name, "route", "add", "224.0.0.0/4", "dev", "eth0"])?;
            named.push(host);
        }
        let (qemu_port, relay_port) = (free_udp_port()?, free_udp_port()?);
        let udp = UdpSocket::bind(("127.0.0.1", relay_port)).map_err(|e| e.to_string())?;
        let relay = Relay::start(udp, SocketAddr::from(([127, 0, 0, 1], qemu_port)), tap_file, Faults::default(), 1)?;
        let netdev = crate::images::firmware::dgram_netdev(qemu_port, relay_port);
        let (settings, dhcp) = match &addressing {
            Addressing::Plan => (Some(crate::images::firmware::TEST_LAN_SETTINGS), None),
            Addressing::Settings { text, dhcp } => {
                let mac = rt_services::address::settings::Settings::parse(text.as_bytes())
                    .mac
                    .map_or(BOARD_MAC.to_string(), |m| m.map(|b| format!("{b:02x}")).join(":"));
                let server = dhcp.map(|a| dnsmasq(&sw, &mac, a)).transpose()?;
                (Some(text.as_str()), server)
            }
        };
        let args: Vec<&str> = relay.qemu_args().into_iter().chain(extra.iter().copied()).collect();
        let mut guest = Guest::boot_netdev_with(elf, &netdev, settings, &args)?;
        guest.wait_for_log("link up", Duration::from_secs(120))?;
        Ok(Lan { guest, relay, others: Vec::new(), hosts: named, dhcp, switch })
    }

    /// Boot another board on the switch with `settings`, and wait for its
    /// link and address.
    pub fn add_board(&mut self, elf: &Path, settings: &str) -> Result<&mut Guest> {
        let tap = format!("{}b{}", self.switch.0, self.others.len() + 1);
        let tap_file = open_tap(&tap)?;
        let sw = self.switch.0.clone();
        ip(&["link", "set", &tap, "netns", &sw])?;
        ip(&["-n", &sw, "link", "set", &tap, "master", "br0", "up"])?;
        let (qemu_port, relay_port) = (free_udp_port()?, free_udp_port()?);
        let udp = UdpSocket::bind(("127.0.0.1", relay_port)).map_err(|e| e.to_string())?;
        let relay = Relay::start(udp, SocketAddr::from(([127, 0, 0, 1], qemu_port)), tap_file, Faults::default(), 2)?;
        let netdev = crate::images::firmware::dgram_netdev(qemu_port, relay_port);
        let mut guest = Guest::boot_netdev_with(elf, &netdev, Some(settings), &relay.qemu_args())?;
        guest.wait_for_log("link up", Duration::from_secs(120))?;
        self.others.push((guest, relay));
        let last = self.others.len() - 1;
        Ok(&mut self.others[last].0)
    }

    /// Restart the LAN's DHCP server with `address` for the board: the
    /// board's next renewal is refused and it takes the new one.
    pub fn move_dhcp(&mut self, mac: &str, address: Ipv4Addr) -> Result<()> {
        self.dhcp = None;
        self.dhcp = Some(dnsmasq(&self.switch.0, mac, address)?);
        Ok(())
    }

    /// Stop the LAN's DHCP server: a network without one (a cable straight
    /// to a laptop).
    pub fn stop_dhcp(&mut self) {
        self.dhcp = None;
    }

    /// Make host `k` a laptop on a cable of its own: only a link-local
    /// address, 169.254.200.(1 + k)/16 (its 10.0.2.x address removed).
    pub fn make_link_local_only(&self, k: usize) -> Result<()> {
        ip(&["-n", self.host(k), "addr", "flush", "dev", "eth0"])?;
        self.add_link_local(k)?;
        ip(&["-n", self.host(k), "route", "replace", "224.0.0.0/4", "dev", "eth0"])
    }

    /// Give host `k` an address in 169.254/16 too, for a board with a
    /// link-local address.
    pub fn add_link_local(&self, k: usize) -> Result<()> {
        ip(&["-n", self.host(k), "addr", "add", &format!("169.254.200.{}/16", 1 + k), "dev", "eth0"])
    }

    /// Host `k`'s address: 10.0.2.(20 + k).
    pub fn host_addr(k: usize) -> Ipv4Addr {
        Ipv4Addr::new(10, 0, 2, 20 + k as u8)
    }

    /// Host `k`'s namespace (for `ip netns exec`).
    pub fn host(&self, k: usize) -> &str {
        &self.hosts[k].0
    }

    /// `program` run on host `k`.
    pub fn command(&self, k: usize, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut c = Command::new("ip");
        c.args(["netns", "exec", self.host(k)]).arg(program);
        c
    }

    /// Run `f` on a thread of its own on host `k` (its sockets are that
    /// host's) and wait for its result.
    pub fn on_host<T: Send + 'static>(&self, k: usize, f: impl FnOnce() -> Result<T> + Send + 'static) -> Result<T> {
        self.spawn_on_host(k, f)?.join().map_err(|_| "a host's thread panicked".to_string())?
    }

    /// Start `f` on a thread of its own on host `k`.
    pub fn spawn_on_host<T: Send + 'static>(
        &self,
        k: usize,
        f: impl FnOnce() -> Result<T> + Send + 'static,
    ) -> Result<thread::JoinHandle<Result<T>>> {
        let path = format!("/var/run/netns/{}", self.host(k));
        let ns = File::open(&path).map_err(|e| format!("{path}: {e}"))?;
        Ok(thread::spawn(move || {
            // SAFETY: setns on a descriptor of a network namespace this
            // process holds open; CLONE_NEWNET moves only the calling
            // thread, which is this new one (nothing else runs on it).
            if unsafe { libc::setns(ns.as_raw_fd(), libc::CLONE_NEWNET) } != 0 {
                return Err(format!("setns: {}", std::io::Error::last_os_error()));
            }
            f()
        }))
    }

    /// The board's UART's last lines, after `e`.
    pub fn with_uart(&self, e: impl std::fmt::Display) -> String {
        let uart = self.guest.uart();
        let tail: Vec<&str> = uart.lines().filter(|l| !l.starts_with("display:")).rev().take(40).collect();
        format!(
            "{e}\nthe emulated board's UART, last lines:\n{}",
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        )
    }
}
