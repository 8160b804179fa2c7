//! The emulated board behind a lossy link, with the Linux kernel's TCP as
//! its peer (docs/reliability.md).
//!
//! QEMU's slirp terminates the host's TCP itself, so loss between a host
//! client and slirp never reaches the firmware. Here the guest's Ethernet
//! frames leave QEMU as UDP datagrams (`-nic dgram`), pass a relay that
//! drops, reorders, duplicates and corrupts them (seeded, so a run repeats)
//! in both directions, and reach a tap device inside a network namespace
//! made for the test, where the client runs: its TCP is the kernel's
//! (window scaling, SACK, delayed ACKs), as a desktop viewer's would be.
//! Nothing leaves the namespace. This needs root and `/dev/net/tun`.

use std::collections::HashSet;
use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::os::fd::AsRawFd;
use std::path::Path;
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use clap::Args;

use super::mac_filter::FilterFollower;
use super::qemu_e2e::{expected_frame, LIGHTS};
use crate::images::firmware::{build, free_udp_port, Guest};
use crate::support::Result;

/// Per-frame fault probabilities, the same both ways.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Faults {
    /// Frame lost.
    pub drop: f64,
    /// Frame held back and sent after the next one.
    pub reorder: f64,
    /// Frame sent twice.
    pub duplicate: f64,
    /// One byte past the Ethernet header flipped (checksums catch it).
    pub corrupt: f64,
}

/// What the relay did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Frames that reached the relay, both ways.
    pub frames: u64,
    /// Of those, frames the board sent (a board that answers nothing shows
    /// here as 0).
    pub from_board: u64,
    /// Dropped.
    pub dropped: u64,
    /// Reordered.
    pub reordered: u64,
    /// Duplicated.
    pub duplicated: u64,
    /// Corrupted.
    pub corrupted: u64,
    /// TCP data segments from the firmware whose sequence number it had
    /// sent before: its retransmissions.
    pub retransmitted: u64,
    /// Frames to the board its MAC's frame filter, as programmed, drops
    /// ([`super::mac_filter`]).
    pub filtered: u64,
}

/// SplitMix64: small, seeded, good enough to pick faults.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && ((self.next() >> 11) as f64 / (1u64 << 53) as f64) < p
    }
}

/// The faults applied to one direction's frames: what to send, in order.
struct Direction {
    faults: Faults,
    rng: Rng,
    held: Option<Vec<u8>>,
}

/// The faults a relay applies now: the same both ways, changeable while it
/// runs (`Relay::set_faults`), so a test can compare a clean and a lossy
/// phase within one boot.
type SharedFaults = Arc<Mutex<Faults>>;

impl Direction {
    fn pass(&mut self, mut frame: Vec<u8>, counts: &mut Counts) -> Vec<Vec<u8>> {
        counts.frames += 1;
        if self.rng.chance(self.faults.drop) {
            counts.dropped += 1;
            return self.held.take().into_iter().collect();
        }
        if frame.len() > 14 && self.rng.chance(self.faults.corrupt) {
            let i = 14 + (self.rng.next() as usize) % (frame.len() - 14);
            frame[i] ^= 1 << (self.rng.next() % 8);
            counts.corrupted += 1;
        }
        let mut out = Vec::new();
        if self.rng.chance(self.faults.duplicate) {
            counts.duplicated += 1;
            out.push(frame.clone());
        }
        if self.held.is_none() && self.rng.chance(self.faults.reorder) {
            counts.reordered += 1;
            self.held = Some(frame);
            return out;
        }
        out.push(frame);
        out.extend(self.held.take());
        out
    }
}

/// (port, sequence number) of a TCP data segment sent from the firmware's
/// ports 7878/7879, if `frame` is one.
fn firmware_segment(frame: &[u8]) -> Option<(u16, u16, u32)> {
    if frame.len() < 54 || frame[12..14] != [0x08, 0x00] || frame[23] != 6 {
        return None;
    }
    let ihl = usize::from(frame[14] & 0x0F) * 4;
    let total = usize::from(u16::from_be_bytes([frame[16], frame[17]]));
    let tcp = 14 + ihl;
    let sport = u16::from_be_bytes([frame[tcp], frame[tcp + 1]]);
    let dport = u16::from_be_bytes([frame[tcp + 2], frame[tcp + 3]]);
    let seq = u32::from_be_bytes([frame[tcp + 4], frame[tcp + 5], frame[tcp + 6], frame[tcp + 7]]);
    let data_off = usize::from(frame[tcp + 12] >> 4) * 4;
    let payload = total.saturating_sub(ihl + data_off);
    ((sport == rt_services::FRAME_PORT || sport == rt_services::PERSISTENT_PORT) && payload > 0)
        .then_some((sport, dport, seq))
}

/// The relay between QEMU's datagrams and the tap device.
pub struct Relay {
    stop: Arc<AtomicBool>,
    faults: SharedFaults,
    counts: Arc<Mutex<Counts>>,
    multicast: Arc<Mutex<std::collections::HashMap<u32, u32>>>,
    threads: Vec<JoinHandle<()>>,
    mac_trace: [String; 2],
    igmp: Arc<Mutex<Vec<Igmp>>>,
}

/// An IGMPv2 message the board sent (RFC 2236 section 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Igmp {
    /// A membership report (type 0x16) for the group.
    Report(std::net::Ipv4Addr),
    /// A leave group message (type 0x17) for the group.
    Leave(std::net::Ipv4Addr),
}

/// The IGMPv2 report or leave `frame` carries (Ethernet, IPv4 protocol 2).
fn igmp_of(frame: &[u8]) -> Option<Igmp> {
    if frame.len() < 14 + 20 + 8 || frame[12..14] != [0x08, 0x00] || frame[23] != 2 {
        return None;
    }
    let ihl = usize::from(frame[14] & 0x0f) * 4;
    let igmp = frame.get(14 + ihl..14 + ihl + 8)?;
    let group = std::net::Ipv4Addr::new(igmp[4], igmp[5], igmp[6], igmp[7]);
    match igmp[0] {
        0x16 => Some(Igmp::Report(group)),
        0x17 => Some(Igmp::Leave(group)),
        _ => None,
    }
}

/// Numbers the relays' MAC trace files.
static TRACE_SEQ: AtomicU32 = AtomicU32::new(0);

/// The RTP packet a frame from the board carries to a multicast group
/// (Ethernet destination 01-00-5E-..., IPv4, UDP, RTP): its 16-bit
/// sequence number and 32-bit timestamp, as one key.
fn multicast_rtp(frame: &[u8]) -> Option<u32> {
    if frame.len() < 14 + 20 + 8 + 12 || frame[..3] != [0x01, 0x00, 0x5e] || frame[12..14] != [0x08, 0x00] {
        return None;
    }
    let ihl = usize::from(frame[14] & 0x0f) * 4;
    if frame[23] != 17 {
        return None;
    }
    let rtp = frame.get(14 + ihl + 8..)?;
    (rtp.len() >= 12 && rtp[0] >> 6 == 2 && rtp[1] & 0x7f == 96)
        .then(|| u32::from(u16::from_be_bytes([rtp[2], rtp[3]])))
}

impl Relay {
    pub(crate) fn start(udp: UdpSocket, qemu: SocketAddr, tap: File, faults: Faults, seed: u64) -> Result<Relay> {
        let stop = Arc::new(AtomicBool::new(false));
        let shared: SharedFaults = Arc::new(Mutex::new(faults));
        let counts = Arc::new(Mutex::new(Counts::default()));
        let multicast = Arc::new(Mutex::new(std::collections::HashMap::new()));
        let igmp = Arc::new(Mutex::new(Vec::new()));
        udp.set_read_timeout(Some(Duration::from_millis(50))).map_err(|e| e.to_string())?;
        let udp2 = udp.try_clone().map_err(|e| e.to_string())?;
        let mut tap_w = tap.try_clone().map_err(|e| e.to_string())?;
        let mut tap_r = tap;
        set_nonblocking(&tap_r)?;
        let mut threads = Vec::new();
        // Guest to peer.
        {
            let (stop, counts, multicast, shared) = (stop.clone(), counts.clone(), multicast.clone(), shared.clone());
            let igmp = igmp.clone();
            let mut dir = Direction { faults, rng: Rng(seed), held: None };
            threads.push(thread::spawn(move || {
                let mut seen: HashSet<(u16, u16, u32)> = HashSet::new();
                let mut buf = vec![0u8; 65536];
                while !stop.load(Ordering::Relaxed) {
                    let Ok(n) = udp.recv(&mut buf) else { continue };
                    let frame = buf[..n].to_vec();
                    if let (Some(seq), Ok(mut m)) = (multicast_rtp(&frame), multicast.lock()) {
                        *m.entry(seq).or_insert(0) += 1;
                    }
                    if let (Some(message), Ok(mut m)) = (igmp_of(&frame), igmp.lock()) {
                        m.push(message);
                    }
                    let Ok(mut c) = counts.lock() else { return };
                    dir.faults = shared.lock().map(|f| *f).unwrap_or(dir.faults);
                    c.from_board += 1;
                    if let Some(key) = firmware_segment(&frame) {
                        if !seen.insert(key) {
                            c.retransmitted += 1;
                        }
                    }
                    for f in dir.pass(frame, &mut c) {
                        let _ = tap_w.write(&f);
                    }
                }
            }));
        }
        // Peer to guest, through the board's MAC filter as its firmware
        // programmed it (QEMU's model has none).
        let trace = std::env::temp_dir().join(format!(
            "rt-gmac-{}-{}.trace",
            std::process::id(),
            TRACE_SEQ.fetch_add(1, Ordering::Relaxed)
        ));
        let mut mac = FilterFollower::new(trace);
        let mac_trace = mac.qemu_args();
        {
            let (stop, counts, shared) = (stop.clone(), counts.clone(), shared.clone());
            let mut dir = Direction { faults, rng: Rng(seed ^ 0x5555_5555_5555_5555), held: None };
            threads.push(thread::spawn(move || {
                let mut buf = vec![0u8; 65536];
                while !stop.load(Ordering::Relaxed) {
                    match tap_r.read(&mut buf) {
                        Ok(n) if n >= 6 => {
                            let frame = buf[..n].to_vec();
                            let Ok(mut c) = counts.lock() else { return };
                            mac.catch_up();
                            let mut destination = [0u8; 6];
                            destination.copy_from_slice(&frame[..6]);
                            if !mac.filter.passes(destination) {
                                c.frames += 1;
                                c.filtered += 1;
                                continue;
                            }
                            dir.faults = shared.lock().map(|f| *f).unwrap_or(dir.faults);
                            for f in dir.pass(frame, &mut c) {
                                let _ = udp2.send_to(&f, qemu);
                            }
                        }
                        _ => thread::sleep(Duration::from_micros(200)),
                    }
                }
            }));
        }
        Ok(Relay { stop, faults: shared, counts, multicast, threads, mac_trace, igmp })
    }

    /// The QEMU arguments that let the relay see the board's MAC
    /// registers: every guest behind a relay is booted with them.
    pub fn qemu_args(&self) -> [&str; 2] {
        [&self.mac_trace[0], &self.mac_trace[1]]
    }

    /// Apply `faults` from now on.
    pub fn set_faults(&self, faults: Faults) {
        if let Ok(mut f) = self.faults.lock() {
            *f = faults;
        }
    }

    /// The multicast RTP packets the board sent so far: how many times
    /// each sequence number went.
    pub fn multicast_packets(&self) -> std::collections::HashMap<u32, u32> {
        self.multicast.lock().map(|m| m.clone()).unwrap_or_default()
    }

    /// The IGMP messages the board sent so far, in order.
    pub fn igmp(&self) -> Vec<Igmp> {
        self.igmp.lock().map(|m| m.clone()).unwrap_or_default()
    }

    /// What happened so far.
    pub fn counts(&self) -> Counts {
        self.counts.lock().map(|c| *c).unwrap_or_default()
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

fn set_nonblocking(f: &File) -> Result<()> {
    // SAFETY: fcntl on a descriptor this process owns, flags read then set.
    let r = unsafe {
        let fl = libc::fcntl(f.as_raw_fd(), libc::F_GETFL);
        libc::fcntl(f.as_raw_fd(), libc::F_SETFL, fl | libc::O_NONBLOCK)
    };
    if r < 0 {
        return Err(format!("fcntl: {}", std::io::Error::last_os_error()));
    }
    Ok(())
}

/// A tap device `name` (no packet information header), as a file.
pub(crate) fn open_tap(name: &str) -> Result<File> {
    let f = OpenOptions::new().read(true).write(true).open("/dev/net/tun").map_err(|e| format!("/dev/net/tun: {e}"))?;
    // struct ifreq: 16-byte name, then the flags (IFF_TAP | IFF_NO_PI).
    let mut ifr = [0u8; 40];
    ifr[..name.len()].copy_from_slice(name.as_bytes());
    let flags: u16 = 0x0002 | 0x1000;
    ifr[16..18].copy_from_slice(&flags.to_ne_bytes());
    const TUNSETIFF: libc::c_ulong = 0x4004_54ca;
    // SAFETY: TUNSETIFF reads and writes the 40-byte ifreq passed in.
    let r = unsafe { libc::ioctl(f.as_raw_fd(), TUNSETIFF as _, ifr.as_mut_ptr()) };
    if r < 0 {
        return Err(format!("TUNSETIFF {name}: {}", std::io::Error::last_os_error()));
    }
    Ok(f)
}

pub(crate) fn ip(args: &[&str]) -> Result<()> {
    let out = Command::new("ip").args(args).output().map_err(|e| format!("ip: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!("ip {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim()))
    }
}

/// The network namespace of one run, removed on drop.
pub(crate) struct Namespace(pub(crate) String);

impl Namespace {
    /// A namespace holding tap `tap` as 10.0.2.2/24 (slirp's gateway
    /// address, which the QEMU firmware build uses).
    pub(crate) fn new(name: &str, tap: &str) -> Result<Namespace> {
        let _ = ip(&["netns", "del", name]);
        ip(&["netns", "add", name])?;
        let ns = Namespace(name.to_string());
        ip(&["link", "set", tap, "netns", name])?;
        ip(&["-n", name, "addr", "add", "10.0.2.2/24", "dev", tap])?;
        ip(&["-n", name, "link", "set", tap, "up"])?;
        ip(&["-n", name, "link", "set", "lo", "up"])?;
        // The board's MAC (firmware/src/boards/qemu_npcm750.rs) as a fixed
        // neighbour: the kernel's ARP gives up after three lost or late
        // probes and then fails connects at once (EHOSTUNREACH); what is
        // measured here is the data path, not ARP through the relay.
        ip(&[
            "-n",
            name,
            "neigh",
            "replace",
            "10.0.2.15",
            "lladdr",
            "52:54:00:12:34:56",
            "dev",
            tap,
            "nud",
            "permanent",
        ])?;
        Ok(ns)
    }
}

impl Drop for Namespace {
    fn drop(&mut self) {
        let _ = ip(&["netns", "del", &self.0]);
    }
}

/// Whether this machine can run the namespace set-up.
pub fn available() -> std::result::Result<(), String> {
    if !Path::new("/dev/net/tun").exists() {
        return Err("no /dev/net/tun".into());
    }
    let probe = format!("rtprobe{}", std::process::id() % 10000);
    ip(&["netns", "add", &probe]).map_err(|e| format!("cannot make a network namespace ({e})"))?;
    let _ = ip(&["netns", "del", &probe]);
    Ok(())
}

/// One run's outcome.
#[derive(Clone, Copy, Debug)]
pub struct Outcome {
    /// Wall time of the client's frames.
    pub elapsed: Duration,
    /// What the relay did.
    pub counts: Counts,
    /// The RTSP stream's frames, when asked for.
    pub rtsp: Option<RtspOutcome>,
}

/// What the client's RTSP stream got.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RtspOutcome {
    /// Whole frames received, all equal to the model's.
    pub exact: u64,
    /// Frames given up (rows missing when a newer frame completed).
    pub given_up: u64,
    /// Rows that came by NACK repair.
    pub repaired_rows: u64,
    /// NACK datagrams sent.
    pub nacks: u64,
    /// Packets of frames already whole or given up (a repair that came
    /// twice).
    pub stale: u64,
    /// Wall time of the stream, from its first frame to its last.
    pub elapsed_ms: u64,
}

impl RtspOutcome {
    /// Frames per second, first frame to last.
    pub fn fps(&self) -> f64 {
        self.exact.saturating_sub(1) as f64 / (self.elapsed_ms.max(1) as f64 / 1e3)
    }

    /// Share of the frames the stream carried that arrived byte-exact.
    pub fn exact_share(&self) -> f64 {
        self.exact as f64 / (self.exact + self.given_up).max(1) as f64
    }

    /// Two clean runs as one: their frames and times added.
    fn mean(a: &RtspOutcome, b: &RtspOutcome) -> RtspOutcome {
        RtspOutcome {
            exact: a.exact + b.exact - 1,
            given_up: a.given_up + b.given_up,
            repaired_rows: a.repaired_rows + b.repaired_rows,
            nacks: a.nacks + b.nacks,
            stale: a.stale + b.stale,
            elapsed_ms: a.elapsed_ms + b.elapsed_ms,
        }
    }

    /// Parse the client's `lossy-client: rtsp ...` line.
    fn parse(line: &str) -> Option<RtspOutcome> {
        let mut o = RtspOutcome::default();
        for pair in line.split_whitespace() {
            let (k, v) = pair.split_once('=')?;
            let v: u64 = v.parse().ok()?;
            match k {
                "exact" => o.exact = v,
                "given_up" => o.given_up = v,
                "repaired_rows" => o.repaired_rows = v,
                "nacks" => o.nacks = v,
                "stale" => o.stale = v,
                "elapsed_ms" => o.elapsed_ms = v,
                _ => return None,
            }
        }
        Some(o)
    }
}

/// Boot the firmware behind a relay with `faults`, and fetch `single`
/// seed-port and `persistent` persistent-port frames with the kernel's TCP
/// from inside the namespace; every frame must equal the model's.
pub fn run_once(elf: &Path, faults: Faults, seed: u64, single: usize, persistent: usize) -> Result<Outcome> {
    run_with_rtsp(elf, faults, seed, single, persistent, 0)
}

/// [`run_once`], and then `rtsp` frames of an RTSP stream at `fps=max`
/// (RTP through the same relay, NACK repair on).
pub fn run_with_rtsp(
    elf: &Path,
    faults: Faults,
    seed: u64,
    single: usize,
    persistent: usize,
    rtsp: usize,
) -> Result<Outcome> {
    // A name of its own per run: a previous run's relay thread may still
    // hold its tap open for a moment after that run ended.
    static RUNS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let run = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tap = format!("rtl{}r{run}", std::process::id() % 100_000);
    let tap_file = open_tap(&tap)?;
    let ns = Namespace::new(&tap, &tap)?;
    let (qemu_port, relay_port) = (free_udp_port()?, free_udp_port()?);
    let udp = UdpSocket::bind(("127.0.0.1", relay_port)).map_err(|e| e.to_string())?;
    let relay = Relay::start(udp, SocketAddr::from(([127, 0, 0, 1], qemu_port)), tap_file, faults, seed)?;
    let netdev = crate::images::firmware::dgram_netdev(qemu_port, relay_port);
    let guest = Guest::boot_netdev(elf, &netdev, &relay.qemu_args())?;
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let out = Command::new("ip")
        .args(["netns", "exec", &ns.0])
        .arg(&exe)
        .args(["lossy-client", "--single", &single.to_string(), "--persistent", &persistent.to_string()])
        .args(["--rtsp", &rtsp.to_string()])
        .output()
        .map_err(|e| format!("ip netns exec: {e}"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        let uart = guest.uart();
        let tail: Vec<&str> = uart.lines().rev().take(30).collect();
        return Err(format!(
            "the client in the namespace failed ({}): {}{}\nrelay: {:?}\nthe board's UART, last lines:\n{}",
            out.status,
            text,
            String::from_utf8_lossy(&out.stderr),
            relay.counts(),
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        ));
    }
    let ms: u64 = text
        .lines()
        .find_map(|l| l.strip_prefix("lossy-client: elapsed_ms="))
        .and_then(|v| v.trim().parse().ok())
        .ok_or_else(|| format!("no elapsed time from the client: {text}"))?;
    let rtsp = match rtsp {
        0 => None,
        _ => Some(
            text.lines()
                .find_map(|l| l.strip_prefix("lossy-client: rtsp "))
                .and_then(RtspOutcome::parse)
                .ok_or_else(|| format!("no RTSP figures from the client: {text}"))?,
        ),
    };
    Ok(Outcome { elapsed: Duration::from_millis(ms), counts: relay.counts(), rtsp })
}

// ---- The client, run inside the namespace --------------------------------------------

/// `cargo xtask lossy-client` (run by `run_once` inside the namespace).
#[derive(Args)]
pub struct ClientArgs {
    /// Frames over the seed-protocol port, one connection each.
    #[arg(long, default_value_t = 3)]
    pub single: usize,
    /// Frames pipelined over one persistent connection.
    #[arg(long, default_value_t = 8)]
    pub persistent: usize,
    /// Frames of an RTSP stream (fixed light, `fps=max`) after those.
    #[arg(long, default_value_t = 0)]
    pub rtsp: usize,
    /// Phases of `rtsp` frames each, on one stream, each started by a line
    /// on standard input (the relay's faults change in between).
    #[arg(long, default_value_t = 1)]
    pub rtsp_phases: usize,
}

/// Connect to `board:port`, trying again for up to 30 s while the kernel
/// finds no route: its three ARP probes can all be lost behind the relay
/// (or sent before the interface is up), and it then fails the connect with
/// EHOSTUNREACH at once instead of probing on, as a user's client would
/// simply retry.
pub(crate) fn connect_patiently(board: &str, port: u16) -> Result<TcpStream> {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        match TcpStream::connect((board, port)) {
            Ok(s) => return Ok(s),
            Err(e) if e.raw_os_error() == Some(113) && Instant::now() < deadline => {
                std::thread::sleep(Duration::from_millis(200))
            }
            Err(e) => return Err(format!("connect to {board}:{port}: {e}")),
        }
    }
}

/// Fetch and check the frames; print the elapsed time.
pub fn client(args: &ClientArgs) -> Result<()> {
    let board = "10.0.2.15";
    let timeout = Duration::from_secs(300);
    let expected: Vec<Vec<u8>> = LIGHTS.iter().map(|l| expected_frame(*l)).collect::<Result<_>>()?;
    // The first connection waits out the namespace's first ARP exchange
    // (its probes go through the lossy relay too); timing starts after it.
    drop(connect_patiently(board, rt_services::PERSISTENT_PORT)?);
    let start = Instant::now();
    for i in 0..args.single {
        let mut s = connect_patiently(board, rt_services::FRAME_PORT)?;
        s.set_read_timeout(Some(timeout)).map_err(|e| e.to_string())?;
        s.write_all(&rt_services::encode_raw_request(LIGHTS[i % LIGHTS.len()])).map_err(|e| e.to_string())?;
        let mut got = Vec::new();
        s.read_to_end(&mut got).map_err(|e| format!("seed frame {i}: {e}"))?;
        if got != expected[i % LIGHTS.len()] {
            return Err(format!("seed frame {i}: {} bytes, not the model's frame", got.len()));
        }
    }
    if args.persistent > 0 {
        let mut s = connect_patiently(board, rt_services::PERSISTENT_PORT)?;
        s.set_read_timeout(Some(timeout)).map_err(|e| e.to_string())?;
        let requests: Vec<u8> =
            (0..args.persistent).flat_map(|i| rt_services::encode_raw_request(LIGHTS[i % LIGHTS.len()])).collect();
        s.write_all(&requests).map_err(|e| e.to_string())?;
        let mut frame = vec![0u8; model::FRAME_BYTES];
        for i in 0..args.persistent {
            s.read_exact(&mut frame).map_err(|e| format!("persistent frame {i}: {e}"))?;
            if frame != expected[i % LIGHTS.len()] {
                return Err(format!("persistent frame {i}: not the model's frame"));
            }
        }
    }
    println!("lossy-client: elapsed_ms={}", start.elapsed().as_millis());
    if args.rtsp > 0 {
        rtsp_client(board, args.rtsp, args.rtsp_phases)?;
    }
    Ok(())
}

/// `phases` times `frames` frames of one fixed-light RTSP stream, each
/// phase after a line on standard input when there are several; every
/// whole frame must be the model's. Prints, a phase, what came and how.
fn rtsp_client(board: &str, frames: usize, phases: usize) -> Result<()> {
    let addr =
        SocketAddr::new(board.parse().map_err(|e| format!("{board}: {e}"))?, rt_services::camera::rtsp::RTSP_PORT);
    // The namespace's first ARP exchange may be lost: the TCP connect
    // retries like the frame ports' (connect_patiently).
    drop(connect_patiently(board, rt_services::camera::rtsp::RTSP_PORT)?);
    let mut s = crate::support::rtsp_client::RtspSession::open(addr, "/light/3,4,-2?fps=max", None)?;
    let want = expected_frame([3072, 4096, -2048])?;
    for phase in 0..phases {
        if phases > 1 {
            let mut go = String::new();
            std::io::stdin().read_line(&mut go).map_err(|e| e.to_string())?;
            // Frames under way when the faults changed belong to neither.
            s.next_frame(Duration::from_secs(300))?;
        }
        let (given_up, repaired, nacks, stale) = (s.frames.given_up, s.frames.repaired_rows, s.nacks, s.frames.stale);
        let mut start = None;
        for i in 0..frames {
            let f = s.next_frame(Duration::from_secs(300))?;
            if f.bytes != want {
                return Err(format!("RTSP frame {i} of phase {phase} (timestamp {}) is not the model's", f.timestamp));
            }
            start.get_or_insert_with(Instant::now);
        }
        let elapsed = start.map_or(0, |t| t.elapsed().as_millis());
        println!(
            "lossy-client: rtsp exact={frames} given_up={} repaired_rows={} nacks={} stale={} elapsed_ms={elapsed}",
            s.frames.given_up - given_up,
            s.frames.repaired_rows - repaired,
            s.nacks - nacks,
            s.frames.stale - stale
        );
    }
    s.teardown()
}

/// One boot behind the relay, one RTSP stream of `frames` frames a phase,
/// the relay's faults set to each of `phases` in turn: the outcome of each
/// phase. The boot's own pace drifts with the host's load; phases of one
/// stream in one boot can be compared.
///
/// Then, with `rt_client` (faults, frames, floor), the relay's faults set
/// to those and `rt-client bench --transport rtsp` (the product, release
/// build) fetching that many frames of the same light inside the
/// namespace: its counts, and those of a second run if the first had
/// fewer than `floor` frames whole.
pub fn run_rtsp_phases(
    elf: &Path,
    phases: &[Faults],
    seed: u64,
    frames: usize,
    rt_client: Option<(Faults, usize, u64)>,
) -> Result<(Vec<RtspOutcome>, Vec<RtClientCounts>)> {
    use std::io::BufRead;
    static RUNS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let run = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tap = format!("rtp{}r{run}", std::process::id() % 100_000);
    let tap_file = open_tap(&tap)?;
    let ns = Namespace::new(&tap, &tap)?;
    let (qemu_port, relay_port) = (free_udp_port()?, free_udp_port()?);
    let udp = UdpSocket::bind(("127.0.0.1", relay_port)).map_err(|e| e.to_string())?;
    let first = phases.first().copied().unwrap_or_default();
    let relay = Relay::start(udp, SocketAddr::from(([127, 0, 0, 1], qemu_port)), tap_file, first, seed)?;
    let netdev = crate::images::firmware::dgram_netdev(qemu_port, relay_port);
    let guest = Guest::boot_netdev(elf, &netdev, &relay.qemu_args())?;
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let mut child = Command::new("ip")
        .args(["netns", "exec", &ns.0])
        .arg(&exe)
        .args(["lossy-client", "--single", "0", "--persistent", "0", "--rtsp", &frames.to_string()])
        .args(["--rtsp-phases", &phases.len().to_string()])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .map_err(|e| format!("ip netns exec: {e}"))?;
    let mut input = child.stdin.take().ok_or("no stdin")?;
    let mut lines = std::io::BufReader::new(child.stdout.take().ok_or("no stdout")?).lines();
    let mut outcomes = Vec::new();
    for faults in phases {
        relay.set_faults(*faults);
        writeln!(input, "go").map_err(|e| format!("the client: {e}"))?;
        let outcome = loop {
            match lines.next() {
                Some(Ok(line)) => {
                    if let Some(o) = line.strip_prefix("lossy-client: rtsp ").and_then(RtspOutcome::parse) {
                        break o;
                    }
                }
                _ => {
                    let _ = child.kill();
                    let status = child.wait().map_err(|e| e.to_string())?;
                    let uart = guest.uart();
                    let tail: Vec<&str> = uart.lines().filter(|l| !l.starts_with("display:")).rev().take(30).collect();
                    return Err(format!(
                        "the client in the namespace ended ({status}) before its phase's figures; relay: {:?}\nthe board's UART, last lines:\n{}",
                        relay.counts(),
                        tail.into_iter().rev().collect::<Vec<_>>().join("\n")
                    ));
                }
            }
        };
        // The board's side of the phase: what its repairs did.
        let uart = guest.uart();
        if let Some(report) = uart.lines().rfind(|l| l.starts_with("camera: session")) {
            println!("lossy link, the board: {report}");
        }
        outcomes.push(outcome);
    }
    drop(input);
    let _ = child.wait();
    let Some((faults, frames, floor)) = rt_client else { return Ok((outcomes, Vec::new())) };
    relay.set_faults(faults);
    let client = crate::support::tools::root().join("target/release/rt-client");
    // A miss is measured once more (both are returned).
    let mut runs = Vec::new();
    while runs.len() < 2 && runs.last().is_none_or(|c: &RtClientCounts| c.whole() < floor) {
        let out = Command::new("ip")
            .args(["netns", "exec", &ns.0])
            .arg(&client)
            .args(["bench", "--transport", "rtsp", "--server", "10.0.2.15", "--light", "3,4,-2", "--fps", "max"])
            .args(["--frames", &frames.to_string()])
            .stdin(std::process::Stdio::null())
            .output()
            .map_err(|e| format!("{}: {e}", client.display()))?;
        let text = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            println!("lossy link, rt-client: {}", line.trim());
        }
        if let Some(report) = guest.uart().lines().rfind(|l| l.starts_with("camera: session")) {
            println!("lossy link, the board: {report}");
        }
        runs.push(RtClientCounts::parse(&text).ok_or(format!("rt-client bench through the relay: {}", text.trim()))?);
    }
    Ok((outcomes, runs))
}

/// What `rt-client bench --transport rtsp` counted (its `frames:` line).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RtClientCounts {
    /// Frames whole without a repair.
    pub exact: u64,
    /// Frames made whole by NACK repair.
    pub repaired: u64,
    /// Frames handed over with rows missing.
    pub damaged: u64,
    /// Frames of which nothing arrived.
    pub lost: u64,
}

impl RtClientCounts {
    /// Frames that came whole.
    pub fn whole(&self) -> u64 {
        self.exact + self.repaired
    }

    /// From `frames: E exact, R repaired, D damaged, L lost; ...`.
    fn parse(text: &str) -> Option<RtClientCounts> {
        let line = text.lines().find_map(|l| l.trim().strip_prefix("frames: "))?;
        let mut n = line.split([',', ';']).map(|part| part.split_whitespace().next()?.parse::<u64>().ok());
        Some(RtClientCounts { exact: n.next()??, repaired: n.next()??, damaged: n.next()??, lost: n.next()?? })
    }
}

// ---- Bench and suite ---------------------------------------------------------------------

/// The scenarios of `cargo xtask lossy-bench`.
pub const SCENARIOS: [(&str, Faults); 3] = [
    ("clean", Faults { drop: 0.0, reorder: 0.0, duplicate: 0.0, corrupt: 0.0 }),
    ("2% drop, 1% reorder, 1% corrupt", Faults { drop: 0.02, reorder: 0.01, duplicate: 0.0, corrupt: 0.01 }),
    ("10% drop", Faults { drop: 0.10, reorder: 0.0, duplicate: 0.0, corrupt: 0.0 }),
];

/// `cargo xtask lossy-bench` options.
#[derive(Args)]
pub struct BenchArgs {
    /// Seed-port frames per scenario.
    #[arg(long, default_value_t = 3)]
    pub single: usize,
    /// Persistent-port frames per scenario.
    #[arg(long, default_value_t = 8)]
    pub persistent: usize,
    /// Relay seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// RTSP frames per scenario (RTP with NACK repair, `fps=max`), from
    /// the frame-mode build over the simulated accelerator.
    #[arg(long, default_value_t = 40)]
    pub rtsp: usize,
}

/// Build the QEMU firmware with `features` and keep a copy of its ELF
/// under its own name: the next build writes the same path.
fn build_copy(features: &[&str]) -> Result<std::path::PathBuf> {
    let elf = build("qemu-npcm750", features)?;
    let name = if features.is_empty() {
        "lossy-software.elf".to_string()
    } else {
        format!("lossy-{}.elf", features.join("-"))
    };
    let copy = elf.with_file_name(name);
    std::fs::copy(&elf, &copy).map_err(|e| format!("{}: {e}", copy.display()))?;
    Ok(copy)
}

/// Each scenario once; times, faults and the lossy-to-clean ratios.
pub fn bench(args: &BenchArgs) -> Result<()> {
    available()?;
    crate::support::tools::ensure_qemu()?;
    let elf = build_copy(&[])?;
    let sim = build_copy(&["sim-accelerator"])?;
    let mut clean = None;
    let mut clean_rtsp = None;
    for (name, faults) in SCENARIOS {
        let o = run_once(&elf, faults, args.seed, args.single, args.persistent)?;
        if args.rtsp > 0 {
            let r = run_with_rtsp(&sim, faults, args.seed, 0, 0, args.rtsp)?;
            let rtsp = r.rtsp.ok_or("no RTSP outcome")?;
            let base = *clean_rtsp.get_or_insert(rtsp.fps());
            println!(
                "lossy-bench: {name}: RTSP {} frames: {:.1}% exact, {} given up, {} rows repaired by {} NACKs; {:.1} frames/s ({:.0}% of clean); relay: {} frames, {} dropped",
                rtsp.exact + rtsp.given_up,
                100.0 * rtsp.exact_share(),
                rtsp.given_up,
                rtsp.repaired_rows,
                rtsp.nacks,
                rtsp.fps(),
                100.0 * rtsp.fps() / base.max(1e-9),
                r.counts.frames,
                r.counts.dropped
            );
        }
        let c = o.counts;
        let base = *clean.get_or_insert(o.elapsed);
        println!(
            "lossy-bench: {name}: {} + {} frames byte-exact in {:.1} s ({:.1}x clean); relay: {} frames, {} dropped, {} reordered, {} duplicated, {} corrupted; {} firmware retransmissions",
            args.single,
            args.persistent,
            o.elapsed.as_secs_f64(),
            o.elapsed.as_secs_f64() / base.as_secs_f64().max(1e-3),
            c.frames,
            c.dropped,
            c.reordered,
            c.duplicated,
            c.corrupted,
            c.retransmitted
        );
    }
    Ok(())
}

/// The suite's short version: byte-exactness through the lossy link (no
/// timing asserted).
pub fn suite_test() -> Result<()> {
    if let Err(why) = available() {
        println!("==> lossy link with the kernel's TCP: not on this machine ({why}); the in-memory fault test covers the loss (rt-services tests/lossy_link.rs)");
        return Ok(());
    }
    let elf = build_copy(&[])?;
    let sim = build_copy(&["sim-accelerator"])?;
    println!("==> emulated board behind a lossy relay (2% drop, 1% reorder, 1% corrupt), the kernel's TCP as the peer");
    let o = run_once(&elf, SCENARIOS[1].1, 7, 1, 2)?;
    println!(
        "lossy link: 1 + 2 frames byte-exact in {:.1} s; {} relayed frames, {} dropped, {} reordered, {} corrupted, {} retransmissions",
        o.elapsed.as_secs_f64(),
        o.counts.frames,
        o.counts.dropped,
        o.counts.reordered,
        o.counts.corrupted,
        o.counts.retransmitted
    );
    // RTSP/RTP with NACK repair through the same relay, one stream in one
    // boot: clean, 2% drop (1% reorder, 1% corrupt), clean, 10% drop,
    // clean. Each lossy phase is held against the clean phases either
    // side of it (the boot's pace drifts with the host's load): at 2% at
    // least 99% of frames byte-exact and 80% of the clean rate, at 10% at
    // least 95% and 70%.
    println!("==> RTSP through the lossy relay: clean, 2% drop (1% reorder, 1% corrupt), clean, 10% drop, clean; NACK repair");
    let clean = SCENARIOS[0].1;
    let phases = [clean, SCENARIOS[1].1, clean, SCENARIOS[2].1, clean];
    crate::support::tools::build_host_programs()?;
    let (o, rt_client) = run_rtsp_phases(
        &sim,
        &phases,
        7,
        SUITE_RTSP_FRAMES,
        Some((SCENARIOS[2].1, RT_CLIENT_FRAMES, RT_CLIENT_WHOLE)),
    )?;
    for (k, name, bar) in [(1, SCENARIOS[1].0, BAR_2), (3, SCENARIOS[2].0, BAR_10)] {
        let base = RtspOutcome::mean(&o[k - 1], &o[k + 1]);
        let lossy = &o[k];
        let verdict = rtsp_verdict(&base, lossy, bar);
        println!(
            "lossy link, RTSP: {name}: {:.2} frames/s ({:.0}% of the clean phases around it, {:.2} and {:.2}), {:.1}% exact ({} given up), {} rows repaired by {} NACKs ({} packets of finished frames)",
            lossy.fps(),
            100.0 * lossy.fps() / base.fps().max(1e-9),
            o[k - 1].fps(),
            o[k + 1].fps(),
            100.0 * lossy.exact_share(),
            lossy.given_up,
            lossy.repaired_rows,
            lossy.nacks,
            lossy.stale
        );
        verdict?;
    }
    // The product itself, through the same 10% drop in the same boot.
    for c in &rt_client {
        println!(
            "lossy link, RTSP: 10% drop, rt-client bench: {} of {RT_CLIENT_FRAMES} frames whole ({} exact, {} repaired), {} damaged, {} lost",
            c.whole(),
            c.exact,
            c.repaired,
            c.damaged,
            c.lost
        );
    }
    match rt_client.last() {
        Some(c) if c.whole() >= RT_CLIENT_WHOLE => Ok(()),
        Some(c) => Err(format!(
            "rt-client through 10% drop: {} of {RT_CLIENT_FRAMES} frames whole, under {RT_CLIENT_WHOLE}, twice",
            c.whole()
        )),
        None => Err("rt-client did not run".into()),
    }
}

/// Frames rt-client takes through the 10% drop, and how many must come
/// whole: 95%, the suite client's bar. rt-client's receiver reports carry
/// LSR and DLSR, from which the emulated board measures a round trip far
/// shorter than its receiver's NACK rounds; the sender holds a frame for
/// the rounds its receiver was seen to take (`camera::sender`), without
/// which some repairs came after the frame left (56 of 60, 16 rows
/// unrepairable).
const RT_CLIENT_FRAMES: usize = 60;
const RT_CLIENT_WHOLE: u64 = 57;

/// RTSP frames per phase in the suite (the emulated board sends about five
/// a second at fps=max): at 100 the 99% bar of the 2% phase allows one
/// frame given up and the 95% bar of the 10% phase five. With 40 they
/// allowed none and two, and whether a loaded machine met them was luck.
const SUITE_RTSP_FRAMES: usize = 100;

/// A bar for RTP through a lossy link: the share of frames byte-exact and
/// the share of the clean run's rate, at least.
#[derive(Clone, Copy, Debug)]
pub struct Bar {
    /// Frames byte-exact, at least.
    pub exact: f64,
    /// The clean run's rate, at least.
    pub rate: f64,
}

/// At 2% drop (1% reorder, 1% corrupt): 99% of frames exact, 80% of the
/// clean rate.
pub const BAR_2: Bar = Bar { exact: 0.99, rate: 0.8 };

/// At 10% drop: 95% of frames exact, 70% of the clean rate.
pub const BAR_10: Bar = Bar { exact: 0.95, rate: 0.7 };

/// Whether `lossy` clears `bar` against `clean`.
fn rtsp_verdict(clean: &RtspOutcome, lossy: &RtspOutcome, bar: Bar) -> Result<()> {
    if lossy.exact_share() < bar.exact {
        return Err(format!(
            "RTSP through the lossy link: {:.1}% of frames exact, under {:.0}%",
            100.0 * lossy.exact_share(),
            100.0 * bar.exact
        ));
    }
    if lossy.fps() < bar.rate * clean.fps() {
        return Err(format!(
            "RTSP through the lossy link: {:.2} frames/s, under {:.0}% of clean ({:.2})",
            lossy.fps(),
            100.0 * bar.rate,
            clean.fps()
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rtsp_bars_hold_exact_frames_and_rate() {
        let o = |exact, given_up, elapsed_ms| RtspOutcome { exact, given_up, elapsed_ms, ..Default::default() };
        let clean = o(30, 0, 14_500); // 2 frames/s
        assert!(rtsp_verdict(&clean, &o(30, 0, 17_000), BAR_2).is_ok());
        assert!(rtsp_verdict(&clean, &o(30, 1, 14_500), BAR_2).is_err(), "one frame in 31 given up is under 99%");
        assert!(rtsp_verdict(&clean, &o(30, 0, 19_000), BAR_2).is_err(), "1.53 frames/s is under 80% of 2");
        assert!(rtsp_verdict(&clean, &o(30, 1, 19_000), BAR_10).is_ok(), "97% exact at 76% of the rate");
        assert!(rtsp_verdict(&clean, &o(30, 2, 14_500), BAR_10).is_err(), "two in 32 given up is under 95%");
        assert!(rtsp_verdict(&clean, &o(30, 0, 21_000), BAR_10).is_err(), "1.38 frames/s is under 70% of 2");
        let line = "exact=30 given_up=1 repaired_rows=5 nacks=2 stale=3 elapsed_ms=900";
        assert_eq!(
            RtspOutcome::parse(line),
            Some(RtspOutcome { exact: 30, given_up: 1, repaired_rows: 5, nacks: 2, stale: 3, elapsed_ms: 900 })
        );
        assert_eq!(RtspOutcome::parse("exact=x"), None);
        let bench = "60 frames in 40.1 s over RTSP: 1.5 frames/s (1.5 after the first), 0.8 MB/s\n\
                     frames: 41 exact, 17 repaired, 2 damaged (1 crowded out by newer frames), 0 lost; 90 NACKs for 400 rows, 3 duplicates, 1 late; repairs took 12 ms";
        let c = RtClientCounts::parse(bench).unwrap();
        assert_eq!((c.exact, c.repaired, c.damaged, c.lost, c.whole()), (41, 17, 2, 0, 58));
        assert_eq!(RtClientCounts::parse("no counts"), None);
    }

    #[test]
    fn faults_follow_the_seed_and_the_rates() {
        let f = Faults { drop: 0.1, reorder: 0.05, duplicate: 0.02, corrupt: 0.03 };
        let run = |seed| {
            let mut d = Direction { faults: f, rng: Rng(seed), held: None };
            let mut c = Counts::default();
            let out: Vec<Vec<u8>> = (0..10_000u32).flat_map(|i| d.pass(i.to_be_bytes().repeat(8), &mut c)).collect();
            (out, c)
        };
        let (a, ca) = run(3);
        let (b, cb) = run(3);
        assert_eq!(a, b, "the same seed, the same faults");
        assert_eq!(ca, cb);
        assert!((800..1200).contains(&ca.dropped), "{ca:?}");
        assert!((350..650).contains(&ca.reordered), "{ca:?}");
        assert!((100..300).contains(&ca.duplicated), "{ca:?}");
        assert!((200..400).contains(&ca.corrupted), "{ca:?}");
        // Frames out: passed + duplicates (a held frame may remain).
        let out = a.len() as u64;
        assert!(out + 1 >= 10_000 - ca.dropped + ca.duplicated && out <= 10_000 - ca.dropped + ca.duplicated);
        assert_ne!(run(4).1, ca, "another seed, other faults");
    }

    #[test]
    fn firmware_data_segments_are_recognised() {
        let mut f = vec![0u8; 60];
        f[12..14].copy_from_slice(&[0x08, 0x00]);
        f[14] = 0x45;
        f[16..18].copy_from_slice(&(20u16 + 20 + 6).to_be_bytes());
        f[23] = 6;
        f[34..36].copy_from_slice(&7878u16.to_be_bytes());
        f[36..38].copy_from_slice(&40000u16.to_be_bytes());
        f[38..42].copy_from_slice(&77u32.to_be_bytes());
        f[46] = 5 << 4;
        assert_eq!(firmware_segment(&f), Some((7878, 40000, 77)));
        f[16..18].copy_from_slice(&40u16.to_be_bytes());
        assert_eq!(firmware_segment(&f), None, "a pure ACK carries no data");
    }
}
