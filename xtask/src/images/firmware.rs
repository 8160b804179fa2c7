//! Firmware commands: build for a board, boot in QEMU (`cargo xtask qemu`),
//! build the DE1-SoC payload (`cargo xtask image`), and the QEMU guest
//! helper the end-to-end tests and the bench use.

use std::fs::File;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use clap::Args;
use rt_services::camera::rtsp::{RTSP_PORT, SERVER_RTP_PORT};
use rt_services::web::WEB_PORT;
use rt_services::{persistent_port, FRAME_PORT, PERSISTENT_PORT};

use super::uimage;
use crate::support::tools::{cargo, ensure_apt_packages, ensure_qemu, root, step, FIRMWARE_TARGET};
use crate::support::Result;

/// The release ELF of the firmware.
pub fn elf_path() -> PathBuf {
    root().join("target").join(FIRMWARE_TARGET).join("release").join("firmware")
}

/// Where the release ELF built with `features` (comma-separated, the
/// board first) is kept: a path of its own per feature set, so that a step
/// holding it runs the build it asked for whatever was built after.
pub fn elf_for(features: &str) -> PathBuf {
    elf_path().with_file_name(format!("firmware-{}", features.replace(',', "+")))
}

/// Build the release firmware for `board` (extra features appended), with
/// warnings as errors; its ELF's own path ([`elf_for`]).
pub fn build(board: &str, extra_features: &[&str]) -> Result<PathBuf> {
    let features = std::iter::once(board).chain(extra_features.iter().copied()).collect::<Vec<_>>().join(",");
    // Every command that boots the firmware builds it here: the target
    // comes with it (a fresh machine has only the host's).
    crate::support::tools::ensure_rust_target(FIRMWARE_TARGET)?;
    let mut c = cargo(&["build", "--release", "-p", "firmware", "--target", FIRMWARE_TARGET, "--features", &features]);
    c.env("RUSTFLAGS", "-D warnings");
    step(&format!("build firmware ({features})"), c)?;
    let out = elf_for(&features);
    std::fs::copy(elf_path(), &out).map_err(|e| format!("{} -> {}: {e}", elf_path().display(), out.display()))?;
    Ok(out)
}

/// The features firmware/Cargo.toml's `[features]` says each feature
/// turns on besides itself.
fn implied_features() -> Result<Vec<(String, Vec<String>)>> {
    let manifest = root().join("firmware/Cargo.toml");
    let text = std::fs::read_to_string(&manifest).map_err(|e| format!("{}: {e}", manifest.display()))?;
    let section = text.split("\n[features]\n").nth(1).ok_or("firmware/Cargo.toml has no [features]")?;
    let section = section.split("\n[").next().unwrap_or(section);
    Ok(section
        .lines()
        .filter_map(|l| l.split_once('='))
        .map(|(name, list)| {
            let deps = list.split('"').skip(1).step_by(2).map(str::to_string).collect();
            (name.trim().to_string(), deps)
        })
        .collect())
}

/// The `build: features ...` line the firmware in `elf` prints at boot,
/// if `elf` is a build of [`build`]'s (named for its features): those
/// features and all they imply, sorted, as the firmware's build script
/// lists them.
pub fn expected_build_line(elf: &Path) -> Result<Option<String>> {
    let Some(named) = elf.file_name().and_then(|n| n.to_str()).and_then(|n| n.strip_prefix("firmware-")) else {
        return Ok(None);
    };
    let implied = implied_features()?;
    let mut features: Vec<String> = named.split('+').map(str::to_string).collect();
    let mut i = 0;
    while i < features.len() {
        if let Some((_, deps)) = implied.iter().find(|(n, _)| *n == features[i]) {
            for d in deps {
                if !features.contains(d) {
                    features.push(d.clone());
                }
            }
        }
        i += 1;
    }
    features.sort();
    Ok(Some(format!("build: features {}", features.join(","))))
}

/// A free TCP port on 127.0.0.1 (asked from the OS, then released).
pub fn free_port() -> Result<u16> {
    let l = TcpListener::bind("127.0.0.1:0").map_err(|e| format!("no free port: {e}"))?;
    Ok(l.local_addr().map_err(|e| e.to_string())?.port())
}

/// Host ports forwarded into the emulated board (slirp's `hostfwd`).
#[derive(Clone, Copy, Debug)]
pub struct Forwards {
    /// To the frame port.
    pub single: u16,
    /// To the persistent port.
    pub persistent: u16,
    /// To the RTSP port (TCP).
    pub rtsp: u16,
    /// To the RTCP port (UDP): the board's RTP port + 1. A player sends
    /// its reports and NACKs to the `server_port` the board announced
    /// (5005) on the address it connected to, so only host port 5005
    /// reaches the board from a stock player; tests with their own client
    /// may use any.
    pub rtcp: u16,
    /// To the web page (TCP 80).
    pub web: u16,
}

impl Forwards {
    /// Free host ports for all four (RTCP on 5005 when that is free).
    pub fn free() -> Result<Forwards> {
        let rtcp = if std::net::UdpSocket::bind(("127.0.0.1", SERVER_RTP_PORT + 1)).is_ok() {
            SERVER_RTP_PORT + 1
        } else {
            free_udp_port()?
        };
        Ok(Forwards { single: free_port()?, persistent: free_port()?, rtsp: free_port()?, rtcp, web: free_port()? })
    }
}

/// The `-netdev` value that sends the guest's Ethernet frames as UDP
/// datagrams from loopback port `qemu_port` to `peer_port` (a relay or a
/// test that plays the network) and takes the peer's back.
pub fn dgram_netdev(qemu_port: u16, peer_port: u16) -> String {
    format!(
        "dgram,id=n0,local.type=inet,local.host=127.0.0.1,local.port={qemu_port},\
         remote.type=inet,remote.host=127.0.0.1,remote.port={peer_port}"
    )
}

/// A free UDP port on 127.0.0.1 (asked from the OS, then released).
pub fn free_udp_port() -> Result<u16> {
    let s = std::net::UdpSocket::bind("127.0.0.1:0").map_err(|e| format!("no free UDP port: {e}"))?;
    Ok(s.local_addr().map_err(|e| e.to_string())?.port())
}

/// Where the firmware reads the settings boot.cmd hands over
/// (firmware/memory.x, `HANDOFF`; boot/boot.cmd writes the same address).
pub const HANDOFF_ADDR: u32 = 0x0490_0000;

/// The hand-off area's size (firmware/memory.x, firmware/src/settings.rs):
/// the 8-byte header and at most 0xff8 bytes of text.
pub const HANDOFF_BYTES: usize = 4096;

/// The settings of boards on the tests' own networks (the relays, the
/// virtual LAN): the address plan of QEMU's user networking, fixed, so
/// that the tests' clients know where the board is.
pub const TEST_LAN_SETTINGS: &str = "# the tests' network plan\nip=10.0.2.15/24\ngateway=10.0.2.2\n";

/// `text` as boot.cmd leaves raytracer.txt in memory ("RTCF", the file's
/// length, as much of the text as the area holds), written to a file for
/// QEMU's `-device loader`.
pub fn settings_file(text: &str) -> Result<PathBuf> {
    static SEQ: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let path = std::env::temp_dir().join(format!(
        "rt-settings-{}-{}.bin",
        std::process::id(),
        SEQ.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    let len = u32::try_from(text.len()).map_err(|_| "settings too long")?;
    let mut bytes = b"RTCF".to_vec();
    bytes.extend_from_slice(&len.to_le_bytes());
    bytes.extend_from_slice(&text.as_bytes()[..text.len().min(HANDOFF_BYTES - 8)]);
    std::fs::write(&path, bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}

/// QEMU arguments that put `file` (from [`settings_file`]) where boot.cmd
/// would.
pub fn settings_loader(file: &Path) -> String {
    format!("loader,file={},addr={HANDOFF_ADDR:#x},force-raw=on", file.display())
}

/// The QEMU command line for `elf` with host ports forwarded to the
/// firmware's frame, persistent, RTSP, RTCP and web ports. The board's RTP
/// leaves for the client's ports on 10.0.2.2, which slirp delivers to the
/// host's 127.0.0.1 (QEMU's user networking: the host's alias).
pub fn qemu_command(elf: &Path, f: &Forwards) -> Command {
    let mut c = Command::new("qemu-system-arm");
    let (single, persistent, rtsp, rtcp, web) = (f.single, f.persistent, f.rtsp, f.rtcp, f.web);
    c.args(["-M", "npcm750-evb", "-kernel"]).arg(elf).args([
        "-nic",
        &format!(
            "user,id=n0,model=npcm-gmac,hostfwd=tcp:127.0.0.1:{single}-:{FRAME_PORT},\
             hostfwd=tcp:127.0.0.1:{persistent}-:{PERSISTENT_PORT},hostfwd=tcp:127.0.0.1:{rtsp}-:{RTSP_PORT},\
             hostfwd=udp:127.0.0.1:{rtcp}-:{},hostfwd=tcp:127.0.0.1:{web}-:{WEB_PORT}",
            SERVER_RTP_PORT + 1
        ),
    ]);
    c
}

/// The QEMU command line for `elf` with the MAC on the back end `netdev`
/// (a `-netdev` value with `id=n0`).
pub fn qemu_command_netdev(elf: &Path, netdev: &str) -> Command {
    let mut c = Command::new("qemu-system-arm");
    c.args(["-M", "npcm750-evb", "-kernel"]).arg(elf).args([
        "-netdev",
        netdev,
        "-net",
        "nic,model=npcm-gmac,netdev=n0",
    ]);
    c
}

/// Numbers the guests' UART logs.
static LOG_SEQ: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);

/// A running QEMU guest with its UART in a log file; killed on drop.
pub struct Guest {
    child: Child,
    /// UART log file.
    pub log: PathBuf,
    /// Host port forwarded to the frame port.
    pub port_single: u16,
    /// Host port forwarded to the persistent port.
    pub port_persistent: u16,
    /// Host ports forwarded to the RTSP and RTCP ports (0 without slirp).
    pub forwards: Option<Forwards>,
    /// From the firmware's "listening" line to its address (as this
    /// process saw the UART: a little late, never early).
    pub address_wait: Duration,
}

impl Guest {
    /// Boot `elf` with extra QEMU arguments; wait (at most 60 s) until the
    /// firmware says it listens.
    pub fn boot(elf: &Path, extra: &[&str]) -> Result<Guest> {
        // The forwarded ports are free when chosen, but another program
        // (a client's outgoing connection) may take one before QEMU binds
        // it; QEMU then stops at once ("Could not set up host forwarding
        // rule"), and other ports are tried.
        let mut refused = String::new();
        for _ in 0..3 {
            let f = Forwards::free()?;
            match Guest::start(qemu_command(elf, &f), elf, f.single, f.persistent, extra) {
                Ok(mut g) => {
                    g.forwards = Some(f);
                    return Ok(g);
                }
                Err(e) if e.contains("host forwarding") => refused = e,
                Err(e) => return Err(e),
            }
        }
        Err(refused)
    }

    /// Boot `elf` with the MAC on `netdev` (a `-netdev` value, `id=n0`)
    /// instead of slirp, with the tests' network plan as its settings
    /// ([`TEST_LAN_SETTINGS`]).
    pub fn boot_netdev(elf: &Path, netdev: &str, extra: &[&str]) -> Result<Guest> {
        Guest::boot_netdev_with(elf, netdev, Some(TEST_LAN_SETTINGS), extra)
    }

    /// Boot `elf` on `netdev` with `settings` as raytracer.txt (`None`: no
    /// file, as on a card without one).
    pub fn boot_netdev_with(elf: &Path, netdev: &str, settings: Option<&str>, extra: &[&str]) -> Result<Guest> {
        let mut c = qemu_command_netdev(elf, netdev);
        if let Some(text) = settings {
            c.args(["-device", &settings_loader(&settings_file(text)?)]);
        }
        Guest::start(c, elf, 0, 0, extra)
    }

    fn start(mut c: Command, elf: &Path, port_single: u16, port_persistent: u16, extra: &[&str]) -> Result<Guest> {
        let log = std::env::temp_dir().join(format!(
            "rt-firmware-uart-{}-{}.log",
            std::process::id(),
            LOG_SEQ.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        // The monitor on a socket of its own: `set_link` ([`Guest::set_link`]).
        let monitor = log.with_extension("monitor");
        // A socket left by an earlier run whose process had this number
        // and was killed (its guests never dropped) would stop QEMU's bind.
        let _ = std::fs::remove_file(&monitor);
        c.args(["-display", "none", "-monitor"]).arg(format!("unix:{},server=on,wait=off", monitor.display()));
        c.arg("-serial").arg(format!("file:{}", log.display()));
        c.args(extra);
        c.stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::from(File::create(log.with_extension("stderr")).map_err(|e| e.to_string())?));
        let child =
            c.spawn().map_err(|e| format!("cannot start qemu-system-arm: {e} (cargo xtask test installs it)"))?;
        let mut g = Guest { child, log, port_single, port_persistent, forwards: None, address_wait: Duration::ZERO };
        g.wait_for_log("listening on TCP", Duration::from_secs(60))?;
        // The build that answered is the one asked for.
        if let Some(want) = expected_build_line(elf)? {
            let uart = g.uart();
            if !uart.lines().any(|l| l.trim_end() == want) {
                let said = uart.lines().find(|l| l.starts_with("build: ")).unwrap_or("no build line");
                return Err(format!("{} booted, but its UART says {said:?}, not {want:?}", elf.display()));
            }
        }
        // Then its address: at once when static, from slirp's DHCP server
        // within a second, link-local within 10 s.
        let listening = Instant::now();
        g.wait_for_log("net: address ", Duration::from_secs(60))?;
        g.address_wait = listening.elapsed();
        Ok(g)
    }

    /// The UART output so far, whole lines only: the firmware writes the
    /// UART a byte at a time, so the log's last line may still be arriving,
    /// and a check must not read half a report (or half a number).
    pub fn uart(&self) -> String {
        let bytes = std::fs::read(&self.log).unwrap_or_default();
        let mut log = String::from_utf8_lossy(&bytes).into_owned();
        log.truncate(whole_lines(&log).len());
        log
    }

    /// Take the board's cable out (`false`) or put it back (`true`):
    /// QEMU's `set_link` on the MAC's back end (`id=n0`), which the PHY's
    /// link status shows (QEMU hw/net/npcm_gmac.c, `gmac_set_link`).
    pub fn set_link(&self, up: bool) -> Result<()> {
        self.monitor(if up { "set_link n0 on" } else { "set_link n0 off" })
    }

    /// Stop the guest's CPU (`true`) or let it go on: a board nobody talks
    /// to for a while costs the host nothing meanwhile (the firmware polls,
    /// so an idle guest takes a whole core).
    pub fn pause(&self, paused: bool) -> Result<()> {
        self.monitor(if paused { "stop" } else { "cont" })
    }

    /// Run `command` on QEMU's human monitor and wait until it has run.
    fn monitor(&self, command: &str) -> Result<()> {
        use std::io::{Read, Write};
        let path = self.log.with_extension("monitor");
        let mut s = std::os::unix::net::UnixStream::connect(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        s.set_read_timeout(Some(Duration::from_secs(5))).map_err(|e| e.to_string())?;
        let mut said = Vec::new();
        let prompt = |s: &mut std::os::unix::net::UnixStream, said: &mut Vec<u8>| -> Result<()> {
            let mut buf = [0u8; 512];
            let start = said.len();
            while !String::from_utf8_lossy(&said[start..]).contains("(qemu)") {
                let n = s.read(&mut buf).map_err(|e| format!("QEMU's monitor: {e}"))?;
                if n == 0 {
                    return Err("QEMU's monitor closed".into());
                }
                said.extend_from_slice(&buf[..n]);
            }
            Ok(())
        };
        prompt(&mut s, &mut said)?;
        s.write_all(format!("{command}\n").as_bytes()).map_err(|e| format!("QEMU's monitor: {e}"))?;
        // The command's echo, then the next prompt: it has run.
        prompt(&mut s, &mut said)?;
        let text = String::from_utf8_lossy(&said).into_owned();
        if text.contains("not found") || text.contains("Error") {
            return Err(format!("QEMU's monitor, {command:?}: {text}"));
        }
        Ok(())
    }

    /// Wait until a line of the UART log contains `needle`.
    pub fn wait_for_log(&mut self, needle: &str, timeout: Duration) -> Result<()> {
        self.wait_for_line(0, needle, timeout).map(drop)
    }

    /// The first UART line after byte `from` that contains `needle`.
    pub fn wait_for_line(&mut self, from: usize, needle: &str, timeout: Duration) -> Result<String> {
        let start = Instant::now();
        loop {
            let uart = self.uart();
            let after = uart.get(from..).unwrap_or("");
            if let Some(line) = after.lines().find(|l| l.contains(needle)) {
                return Ok(line.to_string());
            }
            if let Ok(Some(st)) = self.child.try_wait() {
                let said = std::fs::read_to_string(self.log.with_extension("stderr")).unwrap_or_default();
                return Err(format!(
                    "QEMU exited ({st}) before {needle:?}; QEMU said: {}; UART:\n{after}",
                    said.trim()
                ));
            }
            if start.elapsed() > timeout {
                return Err(format!("no {needle:?} on the UART within {timeout:?}; UART:\n{after}"));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// `log` up to and including its last newline.
fn whole_lines(log: &str) -> &str {
    log.rfind('\n').map_or("", |end| &log[..=end])
}

impl Drop for Guest {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.log);
        let _ = std::fs::remove_file(self.log.with_extension("stderr"));
        let _ = std::fs::remove_file(self.log.with_extension("monitor"));
    }
}

/// `cargo xtask qemu` options.
#[derive(Args)]
pub struct QemuArgs {
    /// Host port forwarded to the firmware's frame port (the next port goes
    /// to its persistent port).
    #[arg(long, default_value_t = FRAME_PORT)]
    pub port: u16,
    /// Host port forwarded to the firmware's RTSP port (UDP 5005 goes to
    /// its RTCP port, where players send reports and NACKs).
    #[arg(long, default_value_t = RTSP_PORT)]
    pub rtsp_port: u16,
    /// Host port forwarded to the firmware's web page (port 80).
    #[arg(long, default_value_t = 8080)]
    pub http_port: u16,
}

/// Build the QEMU firmware and boot it in the foreground (Ctrl-A X quits).
pub fn qemu(args: &QemuArgs) -> Result<()> {
    ensure_qemu()?;
    let elf = build("qemu-npcm750", &[])?;
    let (p1, p2) = (args.port, persistent_port(args.port).ok_or("--port has no port above it")?);
    println!("firmware: {}", elf.display());
    println!("forwarded: 127.0.0.1:{p1} -> firmware :{FRAME_PORT} (one frame per connection)");
    println!("forwarded: 127.0.0.1:{p2} -> firmware :{PERSISTENT_PORT} (persistent)");
    let f =
        Forwards { single: p1, persistent: p2, rtsp: args.rtsp_port, rtcp: SERVER_RTP_PORT + 1, web: args.http_port };
    println!("forwarded: 127.0.0.1:{} -> firmware :{RTSP_PORT} (RTSP), UDP {} -> :{} (RTCP)", f.rtsp, f.rtcp, f.rtcp);
    println!("forwarded: 127.0.0.1:{} -> firmware :{WEB_PORT} (the web page: open http://127.0.0.1:{}/)", f.web, f.web);
    println!("try: rt-client orbit --server 127.0.0.1:{p1}    (quit QEMU with Ctrl-A X)");
    println!("or:  gst-launch-1.0 rtspsrc location=rtsp://127.0.0.1:{}/light/3,4,-2 ! rtpvrawdepay ! videoconvert ! autovideosink", f.rtsp);
    let mut c = qemu_command(&elf, &f);
    c.arg("-nographic");
    let st = c.status().map_err(|e| format!("cannot start qemu-system-arm: {e}"))?;
    if st.success() {
        Ok(())
    } else {
        Err(format!("QEMU exited with {st}"))
    }
}

/// `cargo xtask image` options.
#[derive(Args)]
pub struct ImageArgs {
    /// Output directory.
    #[arg(long, default_value = "target/de1-soc")]
    pub out: PathBuf,
}

/// Link (and load/entry) address of the firmware: `memory.x`'s RAM origin.
pub const LOAD_ADDRESS: u32 = 0x0010_0040;

/// Build the DE1-SoC firmware and write `firmware.bin` (raw) and
/// Debian's packages `image` uses: llvm-objdump (Debian's llvm: it knows
/// the Arm encodings).
pub const IMAGE_PACKAGES: [&str; 1] = ["llvm"];

/// `firmware.img` (U-Boot legacy image, load and entry at the link address).
pub fn image(args: &ImageArgs) -> Result<()> {
    let elf_path = build("de1-soc", &[])?;
    // The reset entry: no literal load before the L2 clean, the L2 checked
    // on every path (xtask/src/images/entry_check.rs), read with
    // llvm-objdump (Debian's llvm: it knows the Arm encodings).
    ensure_apt_packages(&IMAGE_PACKAGES, None)?;
    super::entry_check::check_elf(&elf_path, super::entry_check::DE1_SOC_L2C)?;
    println!("reset entry: other cores parked first, constants by movw/movt, the L2C-310 checked whatever SCTLR says");
    let elf = std::fs::read(&elf_path).map_err(|e| format!("{}: {e}", elf_path.display()))?;
    let (start, bin, entry) = uimage::elf32_to_binary(&elf)?;
    if start != LOAD_ADDRESS {
        return Err(format!("the image starts at {start:#010x}, not at the link address {LOAD_ADDRESS:#010x}"));
    }
    let out = if args.out.is_absolute() { args.out.clone() } else { root().join(&args.out) };
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let time =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs() as u32).unwrap_or(0);
    let img = uimage::legacy_image(&bin, LOAD_ADDRESS, LOAD_ADDRESS, time, "raytracer firmware");
    let (bin_path, img_path) = (out.join("firmware.bin"), out.join("firmware.img"));
    std::fs::write(&bin_path, &bin).map_err(|e| e.to_string())?;
    std::fs::write(&img_path, &img).map_err(|e| e.to_string())?;
    println!("ELF entry {entry:#010x} (reset vector at {LOAD_ADDRESS:#010x} branches to it)");
    println!(
        "{}: {} bytes (raw, load at {LOAD_ADDRESS:#010x}; U-Boot: go {LOAD_ADDRESS:#010x})",
        bin_path.display(),
        bin.len()
    );
    println!("{}: {} bytes (U-Boot legacy image, load = entry = {LOAD_ADDRESS:#010x})", img_path.display(), img.len());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{elf_for, expected_build_line, whole_lines};

    #[test]
    fn every_feature_set_has_an_elf_of_its_own() {
        let (a, b) = (elf_for("qemu-npcm750,sim-accelerator"), elf_for("qemu-npcm750,frame-port-fault"));
        assert_ne!(a, b);
        assert!(a.ends_with("firmware-qemu-npcm750+sim-accelerator"), "{}", a.display());
    }

    #[test]
    fn the_build_line_names_what_a_feature_implies_too() {
        // firmware/Cargo.toml: frame-port-fault turns on sim-accelerator.
        let line = expected_build_line(&elf_for("qemu-npcm750,frame-port-fault")).unwrap();
        assert_eq!(line.as_deref(), Some("build: features frame-port-fault,qemu-npcm750,sim-accelerator"));
        let line = expected_build_line(&elf_for("qemu-npcm750,sim-accelerator")).unwrap();
        assert_eq!(line.as_deref(), Some("build: features qemu-npcm750,sim-accelerator"));
        // Not one of ours: nothing to check.
        assert_eq!(expected_build_line(std::path::Path::new("/tmp/some.elf")).unwrap(), None);
    }

    #[test]
    fn a_line_still_arriving_is_left_out() {
        assert_eq!(whole_lines("boot\nnet: idle: 24 of 24 sockets listening, 32 of "), "boot\n");
        assert_eq!(whole_lines("boot\r\nnet: idle: 24 of 24\r\n"), "boot\r\nnet: idle: 24 of 24\r\n");
        assert_eq!(whole_lines("boo"), "");
    }
}
