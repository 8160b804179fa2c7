//! hps-linux on a real ARM Linux kernel: Debian's armmp kernel (the one
//! its armhf installer boots) in QEMU's `virt` machine, from an initramfs
//! built here with nothing but the test's init
//! (`hps-linux/test-init`), the ARM executable and the virtio network
//! card's modules, on QEMU's user network with the three services'
//! ports forwarded to loopback. The same checks as under user mode
//! ([`super::user_mode::check_services`]) then run against it, and the
//! time from QEMU's start to the first frame is printed.
//!
//! The kernel and its modules come from Debian's `debian-installer-12-
//! netboot-armhf` package (architecture `all`: an amd64 bookworm host's
//! apt fetches it from bookworm's `main`): its `vmlinuz`, and the modules
//! in its `initrd.gz`. The armmp
//! kernel builds PL011, devtmpfs and initramfs in, and virtio-pci and
//! virtio-net as modules; the test gives QEMU's `virt` machine a
//! virtio-net-pci card (QEMU `docs/system/arm/virt.rst`: PCIe, virtio).

use std::fs;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::cpio;
use super::user_mode::{check_services, ensure_checkers, seed_frame, Served};
use super::TARGET;
use crate::support::process::Guard;
use crate::support::tools::{apt_get, cargo, ensure_qemu, root, step};
use crate::support::Result;

/// Debian's netboot installer for armhf, and where in it its kernel and
/// initrd are.
const INSTALLER: &str = "debian-installer-12-netboot-armhf";
const IMAGES: &str = "usr/lib/debian-installer/images/12/armhf/text/debian-installer/armhf";

/// The network card's modules, each after those it needs (the kernel's
/// `modules.dep` for 6.1 armmp: virtio_net needs net_failover, which needs
/// failover; virtio_pci needs both virtio_pci_*_dev).
const MODULES: [&str; 6] = [
    "failover.ko",
    "net_failover.ko",
    "virtio_pci_modern_dev.ko",
    "virtio_pci_legacy_dev.ko",
    "virtio_pci.ko",
    "virtio_net.ko",
];

/// The guest's address on QEMU's user network (QEMU `docs/system/devices/
/// net.rst`, "Using the user mode network stack": the guest is 10.0.2.15).
const GUEST: &str = "10.0.2.15/24";

/// The ports hps-linux listens on in the guest.
const GUEST_SEED: u16 = 7878;
const GUEST_RTSP: u16 = 8554;
const GUEST_HTTP: u16 = 80;

/// How long the kernel may take from QEMU's start to the first frame (a
/// boot under TCG takes some seconds; a slow, loaded machine several times
/// more).
const FIRST_FRAME_WITHIN: Duration = Duration::from_secs(300);

/// Boot the kernel with `exe` (the ARM build of hps-linux) in an initramfs
/// and check it serves.
pub fn run(exe: &Path) -> Result<()> {
    ensure_qemu()?;
    ensure_checkers()?;
    let dir = root().join("target/linux-test/system");
    fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (kernel, modules) = installer(&dir)?;
    step(
        &format!("build the test's init for {TARGET} (release, static)"),
        cargo(&["build", "--release", "-p", "hps-linux-test-init", "--target", TARGET]),
    )?;
    let init_path = root().join("target").join(TARGET).join("release/init");
    let init = read(&init_path)?;
    // A dynamic /init finds no loader in the initramfs, and the kernel
    // says only "No working init found" (RUSTFLAGS overrides the
    // configuration's +crt-static).
    super::static_arm_executable(&init).map_err(|e| format!("{}: {e}", init_path.display()))?;
    let initramfs = dir.join("initramfs.cpio");
    let archive = initramfs_archive(&init, &read(exe)?, &modules);
    fs::write(&initramfs, archive).map_err(|e| format!("{}: {e}", initramfs.display()))?;

    let Served { seed, rtsp, http } = Served::free()?;
    let console = dir.join("console.log");
    println!(
        "==> hps-linux on Debian's armmp kernel in QEMU virt: seed {seed}, RTSP {rtsp}, page {http} (console {})",
        console.display()
    );
    let started = Instant::now();
    let mut qemu = boot(&kernel, &initramfs, Served { seed, rtsp, http }, &console)?;
    wait_for_frame(&mut qemu, seed, &console)?;
    println!(
        "linux-test: QEMU start to the first frame on the seed port: {:.1} s (kernel boot, modules, hps-linux)",
        started.elapsed().as_secs_f64()
    );
    check_services(Served { seed, rtsp, http }, &dir, started).map_err(|e| match qemu.0.try_wait() {
        Ok(Some(status)) => format!("{e}\nQEMU had exited ({status}):\n{}", tail(&console)),
        _ => format!("{e}\nconsole (QEMU still running):\n{}", tail(&console)),
    })?;
    if let Ok(Some(status)) = qemu.0.try_wait() {
        return Err(format!("QEMU exited during the test ({status}):\n{}", tail(&console)));
    }
    println!("linux-test: served from a real ARM Linux kernel ... ok ({:.1} s)", started.elapsed().as_secs_f64());
    Ok(())
}

fn read(path: &Path) -> Result<Vec<u8>> {
    fs::read(path).map_err(|e| format!("{}: {e}", path.display()))
}

/// A kernel module: its file name and contents.
type Module = (String, Vec<u8>);

/// The installer's kernel (its path) and the network card's modules,
/// fetched with `apt-get download` into `dir` when not
/// there yet.
fn installer(dir: &Path) -> Result<(PathBuf, Vec<Module>)> {
    let unpacked = dir.join("installer");
    let kernel = unpacked.join(IMAGES).join("vmlinuz");
    if !kernel.exists() {
        let deb = download(dir)?;
        step("unpack the installer", {
            let mut c = Command::new("dpkg-deb");
            c.arg("-x").arg(&deb).arg(&unpacked);
            c
        })?;
    }
    let initrd = unpacked.join(IMAGES).join("initrd.gz");
    let out = Command::new("gzip").arg("-dc").arg(&initrd).output().map_err(|e| format!("gzip: {e}"))?;
    if !out.status.success() {
        return Err(format!("gzip -dc {}: {}", initrd.display(), String::from_utf8_lossy(&out.stderr)));
    }
    let entries = cpio::entries(&out.stdout).map_err(|e| format!("{}: {e}", initrd.display()))?;
    let mut modules = Vec::new();
    for name in MODULES {
        let found = entries
            .iter()
            .find(|e| e.is_file() && e.name.starts_with("lib/modules/") && e.name.ends_with(&format!("/{name}")))
            .ok_or(format!("{}: no {name} under lib/modules", initrd.display()))?;
        modules.push((name.to_string(), found.data.to_vec()));
    }
    Ok((kernel, modules))
}

/// `apt-get download` the installer into `dir` (after `apt-get update`
/// when the package lists name a version the archive no longer has); the
/// `.deb`'s path.
fn download(dir: &Path) -> Result<PathBuf> {
    // Only the one fetched now is left to find.
    for old in debs(dir) {
        fs::remove_file(&old).map_err(|e| format!("{}: {e}", old.display()))?;
    }
    let fetch = || {
        let mut c = apt_get(&["download", "-q", INSTALLER]);
        c.current_dir(dir);
        step(&format!("apt-get download {INSTALLER}"), c)
    };
    if fetch().is_err() {
        step("apt-get update", apt_get(&["update", "-q"]))?;
        fetch().map_err(|e| {
            format!("{e}\n(the package is in Debian 12 bookworm's main: is bookworm in apt's sources?)")
        })?;
    }
    debs(dir).into_iter().next().ok_or(format!("apt-get download left no {INSTALLER}*.deb in {}", dir.display()))
}

/// The installer packages in `dir`.
fn debs(dir: &Path) -> Vec<PathBuf> {
    fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .map(|e| e.path())
                .filter(|p| {
                    p.file_name().is_some_and(|n| {
                        let n = n.to_string_lossy();
                        n.starts_with(INSTALLER) && n.ends_with(".deb")
                    })
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The initramfs: the console node the kernel opens for init, the mount
/// points, `/init`, `/hps-linux` with its command, the modules in load
/// order and the address (what `hps-linux/test-init` reads).
fn initramfs_archive(init: &[u8], program: &[u8], modules: &[Module]) -> Vec<u8> {
    let mut w = cpio::Writer::default();
    for d in ["dev", "proc", "sys", "tmp", "modules"] {
        w.dir(d);
    }
    // The kernel opens /dev/console for init before anything mounts
    // devtmpfs (Linux `init/main.c`, `console_on_rootfs`).
    w.char_device("dev/console", 5, 1);
    w.file("init", 0o755, init);
    w.file("hps-linux", 0o755, program);
    let mut order = String::new();
    for (name, data) in modules {
        w.file(&format!("modules/{name}"), 0o644, data);
        order.push_str(name);
        order.push('\n');
    }
    w.file("modules/order", 0o644, order.as_bytes());
    w.file("network", 0o644, format!("{GUEST}\n").as_bytes());
    let command = [
        "/hps-linux".to_string(),
        "--accelerator".into(),
        "sim".into(),
        "--listen".into(),
        format!("0.0.0.0:{GUEST_SEED}"),
        "--rtsp".into(),
        format!("0.0.0.0:{GUEST_RTSP}"),
        "--http".into(),
        format!("0.0.0.0:{GUEST_HTTP}"),
    ];
    w.file("command", 0o644, (command.join("\n") + "\n").as_bytes());
    w.finish()
}

/// Start QEMU: the `virt` machine (a Cortex-A15, highmem off for a kernel
/// without LPAE), the kernel and initramfs, its serial console into
/// `console`, user networking forwarding `at`'s ports to the guest's.
fn boot(kernel: &Path, initramfs: &Path, at: Served, console: &Path) -> Result<Guard> {
    let forward = |host: SocketAddr, guest: u16| format!("hostfwd=tcp:127.0.0.1:{}-:{guest}", host.port());
    let netdev = format!(
        "user,id=lan,{},{},{}",
        forward(at.seed, GUEST_SEED),
        forward(at.rtsp, GUEST_RTSP),
        forward(at.http, GUEST_HTTP)
    );
    let log = fs::File::create(console).map_err(|e| format!("{}: {e}", console.display()))?;
    let mut c = Command::new("qemu-system-arm");
    c.args(["-M", "virt,highmem=off", "-m", "512", "-nographic", "-no-reboot", "-kernel"]).arg(kernel);
    c.arg("-initrd").arg(initramfs);
    // No boot ROM for the card (`romfile=`): the kernel needs none, and
    // Debian ships it apart from QEMU (ipxe-qemu).
    c.args(["-append", "console=ttyAMA0 panic=-1", "-netdev", &netdev]);
    c.args(["-device", "virtio-net-pci,netdev=lan,romfile="]);
    let log_err = log.try_clone().map_err(|e| e.to_string())?;
    let child = c.stdin(Stdio::null()).stdout(log).stderr(log_err).spawn();
    Ok(Guard(child.map_err(|e| format!("qemu-system-arm: {e}"))?, "qemu-system-arm (armmp kernel)"))
}

/// Ask the seed port for a frame until one comes whole (QEMU's forwarder
/// accepts before the guest listens, then closes), QEMU exits, or
/// [`FIRST_FRAME_WITHIN`] passes.
fn wait_for_frame(qemu: &mut Guard, seed: SocketAddr, console: &Path) -> Result<()> {
    let started = Instant::now();
    loop {
        if let Ok(Some(status)) = qemu.0.try_wait() {
            return Err(format!("QEMU exited before the first frame ({status}):\n{}", tail(console)));
        }
        if let Ok(frame) = seed_frame(seed) {
            if frame.len() == model::FRAME_BYTES {
                return Ok(());
            }
        }
        if started.elapsed() > FIRST_FRAME_WITHIN {
            return Err(format!("no frame from {seed} within {FIRST_FRAME_WITHIN:?}; console:\n{}", tail(console)));
        }
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// The console's last lines.
fn tail(console: &Path) -> String {
    let text = fs::read_to_string(console).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(40)..].join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_initramfs_holds_what_the_init_reads() {
        let modules = vec![("a.ko".to_string(), vec![1, 2]), ("b.ko".to_string(), vec![3])];
        let bytes = initramfs_archive(b"INIT", b"PROGRAM", &modules);
        let entries = cpio::entries(&bytes).unwrap();
        let get = |name: &str| entries.iter().find(|e| e.name == name).map(|e| e.data.to_vec());
        assert_eq!(get("init").as_deref(), Some(&b"INIT"[..]));
        assert_eq!(get("hps-linux").as_deref(), Some(&b"PROGRAM"[..]));
        assert_eq!(get("modules/order").as_deref(), Some(&b"a.ko\nb.ko\n"[..]));
        assert_eq!(get("modules/b.ko"), Some(vec![3]));
        assert_eq!(get("network").as_deref(), Some(&b"10.0.2.15/24\n"[..]));
        let command = String::from_utf8(get("command").unwrap()).unwrap();
        assert!(command.starts_with("/hps-linux\n--accelerator\nsim\n"), "{command}");
        assert!(command.contains("0.0.0.0:80\n"), "{command}");
        assert!(entries.iter().any(|e| e.name == "dev/console" && e.mode == 0o020600));
    }
}
