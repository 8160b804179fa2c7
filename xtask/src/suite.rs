//! `cargo xtask test`: the whole suite, installing what it needs.
//!
//! Each step prints a `==>` line; the first failure stops the run with a
//! non-zero exit. Tools come from the machine's package registries: rustup
//! targets, Debian packages (`apt-get`), PyPI (`pip`).

use std::process::Command;

use crate::Result;

/// The firmware's target; everything `no_std` must build for it.
pub const FIRMWARE_TARGET: &str = "armv7a-none-eabi";

pub fn run() -> Result<()> {
    ensure_rust_target(FIRMWARE_TARGET)?;
    // QEMU for the firmware tests, mkimage for the U-Boot header test.
    ensure_qemu()?;
    step("host tests", cargo(&["test", "--workspace"]))?;
    // The workspace run enables the model's `std` feature (fast float paths);
    // this runs the arithmetic properties against the pure-integer paths the
    // firmware uses.
    step("model arithmetic without std", cargo(&["test", "-p", "model", "--test", "arith"]))?;
    for krate in NO_STD_CRATES {
        step(
            &format!("{krate} builds no_std for {FIRMWARE_TARGET}"),
            cargo(&["build", "-p", krate, "--target", FIRMWARE_TARGET]),
        )?;
    }
    let mut doc = cargo(&["doc", "--workspace", "--no-deps"]);
    doc.env("RUSTDOCFLAGS", "-D warnings");
    step("rustdoc without warnings", doc)?;
    // Firmware: both boards build warning-free, then the QEMU end-to-end
    // tests boot the QEMU board.
    crate::firmware::build("de1-soc", &[])?;
    qemu_tests()?;
    // FPGA: lint, whole-frame co-simulation, resource estimate.
    crate::rtl::run()?;
    println!("xtask test: all steps passed");
    Ok(())
}

/// Library crates that must build for the bare-metal target without `std`.
const NO_STD_CRATES: &[&str] = &["model", "hal-avalon"];

/// A `cargo` command using the same cargo that runs xtask.
pub fn cargo(args: &[&str]) -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.args(args);
    c
}

/// Run one step, echoing it; a failure becomes an error naming the step.
pub fn step(what: &str, mut cmd: Command) -> Result<()> {
    println!("==> {what}: {cmd:?}");
    let status = cmd.status().map_err(|e| format!("{what}: cannot start: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed ({status})"))
    }
}

/// Add a rustup target when it is missing (a fresh machine has only the host).
pub fn ensure_rust_target(target: &str) -> Result<()> {
    let out = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .map_err(|e| format!("rustup not found ({e}); install Rust with rustup first"))?;
    if String::from_utf8_lossy(&out.stdout).lines().any(|l| l.trim() == target) {
        return Ok(());
    }
    let mut add = Command::new("rustup");
    add.args(["target", "add", target]);
    step(&format!("install rust target {target}"), add)
}

/// Whether a Debian package is installed (`dpkg-query` status).
pub fn apt_installed(package: &str) -> bool {
    Command::new("dpkg-query")
        .args(["-W", "-f=${Status}", package])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).contains("install ok installed"))
        .unwrap_or(false)
}

/// Install the missing ones of `packages` with apt-get (non-interactive),
/// optionally from a suite such as `bookworm-backports`.
pub fn ensure_apt_packages(packages: &[&str], suite: Option<&str>) -> Result<()> {
    let missing: Vec<&str> = packages.iter().copied().filter(|p| !apt_installed(p)).collect();
    apt_install(&missing, suite)
}

/// `apt-get install` `packages` (installed or not: from a newer `suite`
/// this upgrades them).
fn apt_install(packages: &[&str], suite: Option<&str>) -> Result<()> {
    if packages.is_empty() {
        return Ok(());
    }
    let sudo = needs_sudo();
    let apt = |args: &[&str]| {
        let mut c = if sudo { Command::new("sudo") } else { Command::new("apt-get") };
        if sudo {
            c.arg("apt-get");
        }
        c.args(args).env("DEBIAN_FRONTEND", "noninteractive");
        c
    };
    step("apt-get update", apt(&["update", "-q"]))?;
    let mut args = vec!["install", "-y", "-q", "--no-install-recommends"];
    if let Some(s) = suite {
        args.extend(["-t", s]);
    }
    args.extend(packages);
    step(&format!("install {}", packages.join(" ")), apt(&args))
}

fn needs_sudo() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() != "0")
        .unwrap_or(true)
}

/// The first QEMU with the `npcm-gmac` NIC (shared/PLATFORM.md, QEMU recipe).
const QEMU_MIN: (u32, u32) = (9, 1);

/// Debian bookworm's own QEMU (7.2) lacks `npcm-gmac`: take qemu-system-arm
/// 10 from bookworm-backports (deb822 source as in shared/PLATFORM.md), also
/// when an older one is installed, and mkimage from u-boot-tools.
pub fn ensure_qemu() -> Result<()> {
    let qemu_ok = qemu_version().is_some_and(|v| v >= QEMU_MIN);
    let mut wanted = Vec::new();
    if !qemu_ok {
        wanted.push("qemu-system-arm");
    }
    if !apt_installed("u-boot-tools") {
        wanted.push("u-boot-tools");
    }
    if wanted.is_empty() {
        return Ok(());
    }
    ensure_backports_source()?;
    apt_install(&wanted, Some("bookworm-backports"))?;
    match qemu_version() {
        Some(v) if v >= QEMU_MIN => Ok(()),
        v => Err(format!(
            "qemu-system-arm {v:?} has no npcm-gmac: need {}.{} or newer (bookworm-backports)",
            QEMU_MIN.0, QEMU_MIN.1
        )),
    }
}

/// `(major, minor)` of the installed `qemu-system-arm`.
fn qemu_version() -> Option<(u32, u32)> {
    let out = Command::new("qemu-system-arm").arg("--version").output().ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let version = text.split("version ").nth(1)?.split_whitespace().next()?;
    let mut parts = version.split('.').map(|p| p.parse::<u32>().ok());
    Some((parts.next()??, parts.next()??))
}

fn ensure_backports_source() -> Result<()> {
    const SOURCE: &str = "/etc/apt/sources.list.d/bookworm-backports.sources";
    let has_backports = std::fs::read_dir("/etc/apt/sources.list.d")
        .map(|d| d.flatten().any(|e| std::fs::read_to_string(e.path()).is_ok_and(|t| t.contains("bookworm-backports"))))
        .unwrap_or(false)
        || std::fs::read_to_string("/etc/apt/sources.list").is_ok_and(|t| t.contains("bookworm-backports"));
    if has_backports {
        return Ok(());
    }
    let text = "Types: deb\nURIs: http://deb.debian.org/debian\nSuites: bookworm-backports\n\
                Components: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n";
    println!("==> add apt source {SOURCE}");
    if needs_sudo() {
        let mut c = Command::new("sudo");
        c.args(["sh", "-c", &format!("cat > {SOURCE} <<'EOF'\n{text}EOF\n")]);
        step("add bookworm-backports", c)
    } else {
        std::fs::write(SOURCE, text).map_err(|e| format!("{SOURCE}: {e}"))
    }
}

/// Build the QEMU firmware (warnings are errors) and run the end-to-end
/// tests against it.
pub fn qemu_tests() -> Result<()> {
    ensure_qemu()?;
    let elf = crate::firmware::build("qemu-npcm750", &[])?;
    println!("==> QEMU end-to-end tests ({})", elf.display());
    crate::qemu_e2e::run(&elf)
}
