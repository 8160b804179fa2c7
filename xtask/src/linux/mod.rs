//! The board's services as a Linux program (`hps-linux`, docs/linux.md):
//! cross-built for the HPS's 32-bit ARM Linux as one static executable
//! ([`build`]) and run under Debian's QEMU user mode (`cargo xtask
//! linux-test`, [`run`]): its checks, and serving ([`user_mode`]); and
//! booted on Debian's ARM kernel in QEMU's `virt` machine ([`system`]).
//!
//! The target is `armv7-unknown-linux-gnueabihf` with glibc linked in
//! (`+crt-static`, `.cargo/config.toml`), linked by Debian's
//! `arm-linux-gnueabihf-gcc`: one executable with no loader or library to
//! match on the card, which runs on any kernel from 3.2 (Debian's glibc
//! is configured for that). The musl target the issue names would do the
//! same, but its standard library is not in this machine's Rust registry
//! (`rustup target add armv7-unknown-linux-musleabihf`: 404).
//!
//! May import: `support`.

pub mod bench;
mod cpio;
pub mod system;
pub mod user_mode;

use std::path::PathBuf;
use std::process::Command;

use crate::support::tools::{cargo, ensure_apt_packages, ensure_apt_source, ensure_rust_target, root, step};
use crate::support::Result;

/// The HPS's Linux target.
pub const TARGET: &str = "armv7-unknown-linux-gnueabihf";

/// Debian's cross linker and static C library for [`TARGET`], and the
/// device-tree compiler for the UIO overlay.
pub const PACKAGES: [&str; 3] = ["gcc-arm-linux-gnueabihf", "libc6-dev-armhf-cross", "device-tree-compiler"];

/// The UIO overlay (docs/linux.md).
const OVERLAY: &str = "hps-linux/dts/raytracer-uio.dtso";

/// The systemd unit.
const UNIT: &str = "hps-linux/systemd/hps-linux.service";

/// Install what the build and the tests need.
pub fn ensure_tools() -> Result<()> {
    ensure_rust_target(TARGET)?;
    ensure_apt_packages(&PACKAGES, None)?;
    // QEMU's user mode from the same suite as its system emulator
    // (bookworm-backports, `support::tools::ensure_qemu`).
    ensure_apt_source("bookworm-backports", "deb", "bookworm-backports", "bookworm")?;
    ensure_apt_packages(&["qemu-user"], Some("bookworm-backports"))
}

/// Build `hps-linux` for the board (release); the executable's path.
pub fn build() -> Result<PathBuf> {
    step(
        &format!("build hps-linux for {TARGET} (release, static)"),
        cargo(&["build", "--release", "-p", "hps-linux", "--target", TARGET]),
    )?;
    let exe = executable();
    let bytes = std::fs::read(&exe).map_err(|e| format!("{}: {e}", exe.display()))?;
    static_arm_executable(&bytes).map_err(|e| format!("{}: {e}", exe.display()))?;
    Ok(exe)
}

/// `cargo xtask linux-test`: the UIO overlay compiles and maps the bridge
/// window of hal-avalon's map; the ARM executable builds static, and runs
/// under QEMU user mode: `--version`, `check` against a stand-in system
/// printing what the host's build prints, and serving
/// ([`user_mode::serves`]); then on a real ARM kernel in QEMU's system
/// emulator ([`system::run`]).
pub fn run() -> Result<()> {
    ensure_tools()?;
    overlay()?;
    let exe = build()?;
    println!("==> hps-linux under QEMU user mode ({})", exe.display());
    let version = output(Command::new("qemu-arm").arg(&exe).arg("--version"))?;
    let want = format!("hps-linux {}", env!("CARGO_PKG_VERSION"));
    if version.trim() != want {
        return Err(format!("qemu-arm hps-linux --version printed {version:?}, expected {want:?}"));
    }
    let help = output(Command::new("qemu-arm").arg(&exe).arg("--help"))?;
    unit_flags_exist(&help)?;
    let stand = StandIn::new()?;
    step("build hps-linux for the host", cargo(&["build", "-p", "hps-linux"]))?;
    let host = output(stand.check(&mut Command::new(root().join("target/debug/hps-linux"))))?;
    let mut qemu = Command::new("qemu-arm");
    qemu.arg(&exe);
    let arm = output(stand.check(&mut qemu))?;
    if arm != host || !arm.lines().any(|l| l == "accelerator: ready") {
        return Err(format!("hps-linux check under qemu-arm printed\n{arm}\nthe host's build printed\n{host}"));
    }
    println!("linux-test: the ARM executable is static and its check reads the stand-in as the host's does ... ok");
    user_mode::serves(&exe)?;
    system::run(&exe)
}

/// Compile the overlay with `dtc` and read it back: one `generic-uio` node
/// whose `reg` is the lightweight bridge window (0xff200000, 2 MiB:
/// hal-avalon's `LW_BRIDGE_BASE`, `LW_BRIDGE_SIZE`).
fn overlay() -> Result<()> {
    let dtbo = root().join("target/linux-test-overlay.dtbo");
    step("compile the UIO overlay", {
        let mut c = Command::new("dtc");
        c.args(["-@", "-q", "-I", "dts", "-O", "dtb", "-o"]).arg(&dtbo).arg(root().join(OVERLAY));
        c
    })?;
    let text = output(Command::new("dtc").args(["-q", "-I", "dtb", "-O", "dts"]).arg(&dtbo))?;
    overlay_maps_the_bridge(&text)
}

/// The decompiled overlay holds the node hps-linux looks for.
fn overlay_maps_the_bridge(dts: &str) -> Result<()> {
    let has = |line: &str| dts.lines().any(|l| l.trim() == line);
    for line in ["compatible = \"generic-uio\";", "reg = <0xff200000 0x200000>;", "linux,uio-name = \"raytracer\";"] {
        if !has(line) {
            return Err(format!("{OVERLAY}: no `{line}` in the compiled overlay:\n{dts}"));
        }
    }
    Ok(())
}

/// Every flag the systemd unit's `ExecStart` gives is one the program's
/// `--help` lists.
fn unit_flags_exist(help: &str) -> Result<()> {
    let path = root().join(UNIT);
    let unit = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let exec = unit.lines().find_map(|l| l.strip_prefix("ExecStart=")).ok_or(format!("{UNIT}: no ExecStart"))?;
    let mut words = exec.split_whitespace();
    if !words.next().is_some_and(|w| w.ends_with("/hps-linux")) {
        return Err(format!("{UNIT}: ExecStart does not run hps-linux: {exec}"));
    }
    for flag in words.filter(|w| w.starts_with("--")) {
        if !help.split_whitespace().any(|w| w.trim_end_matches(',') == flag) {
            return Err(format!("{UNIT}: {flag} is not one of hps-linux's flags:\n{help}"));
        }
    }
    Ok(())
}

fn output(cmd: &mut Command) -> Result<String> {
    let out = cmd.output().map_err(|e| format!("{cmd:?}: {e}"))?;
    if !out.status.success() {
        return Err(format!("{cmd:?} failed ({}): {}", out.status, String::from_utf8_lossy(&out.stderr)));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// A stand-in system for `hps-linux check`: no FPGA classes in sysfs, and a
/// sparse /dev/mem where the FPGA is in user mode, the bridges out of reset
/// and the ray tracer answers (hps-linux's own tests build the same).
struct StandIn {
    dir: PathBuf,
}

impl StandIn {
    fn new() -> Result<StandIn> {
        let dir = root().join("target/linux-test");
        let _ = std::fs::remove_dir_all(&dir);
        let io = |e: std::io::Error| format!("{}: {e}", dir.display());
        std::fs::create_dir_all(dir.join("sys")).map_err(io)?;
        std::fs::create_dir_all(dir.join("dev")).map_err(io)?;
        let mem = std::fs::File::create(dir.join("mem")).map_err(io)?;
        // hal-avalon's map: the bridge at 0xff20_0000, ID at 0x18 (version
        // 3), BUILD_ID at 0x4c; soc's: the FPGA manager's stat at
        // 0xff70_6000 (4: user mode), the reset manager's brgmodrst at
        // 0xffd0_501c.
        mem.set_len(0xff20_0000 + (2 << 20)).map_err(io)?;
        use std::os::unix::fs::FileExt;
        for (at, value) in
            [(0xff70_6000u64, 4u32), (0xffd0_501c, 0), (0xff20_0018, 0x5254_0003), (0xff20_004c, 0x00ab_cdef)]
        {
            mem.write_all_at(&value.to_le_bytes(), at).map_err(io)?;
        }
        Ok(StandIn { dir })
    }

    /// `cmd` (the executable, or `qemu-arm` and it) as `check` against it.
    fn check<'c>(&self, cmd: &'c mut Command) -> &'c mut Command {
        cmd.args(["check", "--accelerator", "devmem"])
            .arg("--sysfs")
            .arg(self.dir.join("sys"))
            .arg("--dev")
            .arg(self.dir.join("dev"))
            .arg("--dev-mem")
            .arg(self.dir.join("mem"))
    }
}

/// `bytes` is a 32-bit little-endian ARM ELF executable with no program
/// interpreter (statically linked: nothing to find on the card).
pub fn static_arm_executable(bytes: &[u8]) -> Result<()> {
    // ELF (System V gABI, "ELF Header" and "Program Header"): ident, then
    // e_type at 16, e_machine at 18, e_phoff at 28, e_phentsize at 42,
    // e_phnum at 44; a program header's p_type first.
    const EM_ARM: u16 = 40;
    const ET_EXEC: u16 = 2;
    const ET_DYN: u16 = 3;
    const PT_INTERP: u32 = 3;
    let u16_at = |o: usize| bytes.get(o..o + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
    let u32_at = |o: usize| bytes.get(o..o + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    if bytes.get(..6) != Some(&[0x7f, b'E', b'L', b'F', 1, 1][..]) {
        return Err("not a 32-bit little-endian ELF".into());
    }
    if u16_at(18) != Some(EM_ARM) {
        return Err(format!("machine {:?}, not ARM", u16_at(18)));
    }
    if !matches!(u16_at(16), Some(ET_EXEC | ET_DYN)) {
        return Err(format!("type {:?}, not an executable", u16_at(16)));
    }
    let (Some(phoff), Some(phentsize), Some(phnum)) = (u32_at(28), u16_at(42), u16_at(44)) else {
        return Err("truncated header".into());
    };
    for i in 0..usize::from(phnum) {
        let at = phoff as usize + i * usize::from(phentsize);
        match u32_at(at) {
            Some(PT_INTERP) => return Err("dynamically linked (it names a program interpreter)".into()),
            Some(_) => {}
            None => return Err("truncated program headers".into()),
        }
    }
    Ok(())
}

/// The path of the executable [`build`] makes, for other steps.
pub fn executable() -> PathBuf {
    root().join("target").join(TARGET).join("release/hps-linux")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// A minimal ELF32 header and `types` as program headers.
    fn elf(machine: u16, types: &[u32]) -> Vec<u8> {
        let mut b = vec![0u8; 52 + 32 * types.len()];
        b[..6].copy_from_slice(&[0x7f, b'E', b'L', b'F', 1, 1]);
        b[16..18].copy_from_slice(&2u16.to_le_bytes());
        b[18..20].copy_from_slice(&machine.to_le_bytes());
        b[28..32].copy_from_slice(&52u32.to_le_bytes());
        b[42..44].copy_from_slice(&32u16.to_le_bytes());
        b[44..46].copy_from_slice(&(types.len() as u16).to_le_bytes());
        for (i, t) in types.iter().enumerate() {
            b[52 + 32 * i..56 + 32 * i].copy_from_slice(&t.to_le_bytes());
        }
        b
    }

    #[test]
    fn only_a_static_arm_executable_passes() {
        assert_eq!(static_arm_executable(&elf(40, &[6, 1, 1, 2])), Ok(()));
        assert!(static_arm_executable(&elf(40, &[6, 3, 1])).unwrap_err().contains("dynamically linked"));
        assert!(static_arm_executable(&elf(62, &[1])).unwrap_err().contains("not ARM"));
        assert!(static_arm_executable(b"#!/bin/sh\n").is_err());
        let mut truncated = elf(40, &[1, 1]);
        truncated.truncate(60);
        assert!(static_arm_executable(&truncated).unwrap_err().contains("truncated"));
    }

    #[test]
    fn the_overlay_check_wants_the_bridge_window() {
        let good = "/ {\n\tcompatible = \"generic-uio\";\n\treg = <0xff200000 0x200000>;\n\tlinux,uio-name = \"raytracer\";\n};";
        assert_eq!(overlay_maps_the_bridge(good), Ok(()));
        let wrong = good.replace("0xff200000", "0xc0000000");
        assert!(overlay_maps_the_bridge(&wrong).unwrap_err().contains("reg = <0xff200000 0x200000>"));
    }

    #[test]
    fn the_units_flags_are_checked_against_the_help() {
        let help = "Options:\n  --accelerator <ACCELERATOR>\n  --listen <LISTEN>\n  --http <HTTP>\n";
        assert_eq!(unit_flags_exist(help), Ok(()));
        assert!(unit_flags_exist("Options:\n  --listen <LISTEN>\n").unwrap_err().contains("--accelerator"));
    }

    #[test]
    fn the_executable_path_is_the_targets_release_build() {
        assert!(executable().ends_with(Path::new(TARGET).join("release/hps-linux")));
    }
}
