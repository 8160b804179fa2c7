//! The checks before the first access, on a stand-in system: a sysfs tree
//! and a sparse /dev/mem file holding the managers' registers and the
//! bridge window's ID. Each refusal names its cause.

use std::path::Path;

use hal_avalon::map::{Csr, ID_VALUE, LW_BRIDGE_BASE, LW_BRIDGE_SIZE};
use hps_linux::preflight::{self, Access, Finding, Refusal, System};
use soc::cyclone_v::{FPGAMGR_BASE, FPGAPORTRST, FPGAPORTRST_RELEASED, RSTMGR_BASE};
use tempfile::TempDir;

struct Stand {
    dir: TempDir,
    sys: System,
}

/// A system with no FPGA classes in sysfs and a /dev/mem where the FPGA
/// is in user mode, the bridge out of reset and the ray tracer answers.
fn stand() -> Stand {
    let dir = tempfile::tempdir().unwrap();
    let sys = System { sysfs: dir.path().join("sys"), dev: dir.path().join("dev"), dev_mem: dir.path().join("mem") };
    std::fs::create_dir_all(&sys.sysfs).unwrap();
    std::fs::create_dir_all(&sys.dev).unwrap();
    // Every page read whole: the bridge, the SDRAM controller's
    // (fpgaportrst) and the reset manager's, the highest.
    let end =
        [LW_BRIDGE_BASE as u64 + LW_BRIDGE_SIZE as u64, (FPGAPORTRST as u64 | 0xfff) + 1, RSTMGR_BASE as u64 + 0x1000]
            .into_iter()
            .max()
            .unwrap_or(0);
    std::fs::File::create(&sys.dev_mem).and_then(|f| f.set_len(end)).unwrap();
    let s = Stand { dir, sys };
    s.poke(FPGAPORTRST as u64, FPGAPORTRST_RELEASED);
    s.poke(FPGAMGR_BASE as u64, 4); // stat.mode: user mode
    s.poke(RSTMGR_BASE as u64 + 0x1c, 0); // brgmodrst: all bridges out of reset
    s.poke(LW_BRIDGE_BASE as u64 + Csr::Id.offset() as u64, ID_VALUE);
    s.poke(LW_BRIDGE_BASE as u64 + Csr::BuildId.offset() as u64, 0x0012_3abc);
    s
}

impl Stand {
    fn poke(&self, at: u64, value: u32) {
        use std::os::unix::fs::FileExt;
        let f = std::fs::OpenOptions::new().write(true).open(&self.sys.dev_mem).unwrap();
        f.write_all_at(&value.to_le_bytes(), at).unwrap();
    }

    fn class_entry(&self, class: &str, entry: &str, files: &[(&str, &str)]) {
        let d = self.sys.sysfs.join("class").join(class).join(entry);
        std::fs::create_dir_all(&d).unwrap();
        for (name, text) in files {
            std::fs::write(d.join(name), format!("{text}\n")).unwrap();
        }
    }

    /// `uio2` mapping the bridge window: a copy of it as the device file.
    fn uio(&self) {
        self.class_entry("uio", "uio2", &[]);
        let maps = self.sys.sysfs.join("class/uio/uio2/maps/map0");
        std::fs::create_dir_all(&maps).unwrap();
        std::fs::write(maps.join("addr"), "0xff200000\n").unwrap();
        std::fs::write(maps.join("size"), "0x00200000\n").unwrap();
        let mut window = vec![0u8; LW_BRIDGE_SIZE];
        window[Csr::Id.offset()..Csr::Id.offset() + 4].copy_from_slice(&ID_VALUE.to_le_bytes());
        std::fs::write(self.sys.dev.join("uio2"), window).unwrap();
    }

    fn refusal(&self, access: Access) -> Refusal {
        match preflight::open(&self.sys, &access) {
            Ok((_, report)) => panic!("expected a refusal, got {report:?}"),
            Err(r) => r,
        }
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }
}

#[test]
fn a_ready_board_through_dev_mem_reports_what_it_saw() {
    let s = stand();
    let (_, report) = preflight::open(&s.sys, &Access::DevMem).expect("ready");
    assert_eq!(report.fpga, Finding::Good("FPGA manager: user mode".into()));
    assert_eq!(report.bridge, Finding::Good("brgmodrst 0x0: lwhps2fpga out of reset".into()));
    assert_eq!((report.register_map, report.build_id), (3, 0x0012_3abc));
    assert!(report.window.ends_with("mem at 0xff200000"), "{}", report.window);
}

#[test]
fn sysfs_is_asked_before_the_registers() {
    let s = stand();
    // The registers say "not configured" and "in reset"; sysfs, asked
    // first, says otherwise.
    s.poke(FPGAMGR_BASE as u64, 1);
    s.poke(RSTMGR_BASE as u64 + 0x1c, 0x7);
    s.class_entry("fpga_manager", "fpga0", &[("state", "operating")]);
    s.class_entry("fpga_bridge", "br0", &[("name", "hps2fpga"), ("state", "disabled")]);
    s.class_entry("fpga_bridge", "br1", &[("name", "lwhps2fpga"), ("state", "enabled")]);
    s.uio();
    let (_, report) = preflight::open(&s.sys, &Access::Uio(None)).expect("ready");
    assert_eq!(report.fpga, Finding::Good("fpga0: operating".into()));
    assert_eq!(report.bridge, Finding::Good("br1 (lwhps2fpga): enabled".into()), "the lightweight one, by name");
    assert!(report.window.ends_with("uio2 (map 0)"), "{}", report.window);
}

#[test]
fn an_unconfigured_fpga_is_named() {
    let s = stand();
    s.poke(FPGAMGR_BASE as u64, 2);
    let r = s.refusal(Access::DevMem);
    assert!(matches!(r, Refusal::FpgaNotConfigured(_)), "{r:?}");
    assert!(r.to_string().starts_with("the FPGA is not configured (FPGA manager: Configuring)"), "{r}");
    s.class_entry("fpga_manager", "fpga0", &[("state", "power off")]);
    let r = s.refusal(Access::DevMem);
    assert!(r.to_string().contains("(fpga0: power off)") && r.to_string().contains("MSEL"), "{r}");
}

#[test]
fn a_bridge_in_reset_is_named() {
    let s = stand();
    s.poke(RSTMGR_BASE as u64 + 0x1c, 0x2);
    let r = s.refusal(Access::DevMem);
    assert!(matches!(r, Refusal::BridgeInReset(_)), "{r:?}");
    assert!(
        r.to_string().contains("brgmodrst 0x2: lwhps2fpga in reset") && r.to_string().contains("bridge enable"),
        "{r}"
    );
    s.class_entry("fpga_bridge", "br0", &[("name", "lwhps2fpga"), ("state", "disabled")]);
    assert!(s.refusal(Access::DevMem).to_string().contains("(br0 (lwhps2fpga): disabled)"));
}

#[test]
fn a_wrong_image_or_register_map_is_named() {
    let s = stand();
    let id_at = LW_BRIDGE_BASE as u64 + Csr::Id.offset() as u64;
    for (id, says) in [
        (0xFFFF_FFFF, "nothing answers at the lightweight bridge"),
        (0x1234_0003, "not the ray tracer: ID reads 0x12340003"),
        (0x5254_0000, "not the ray tracer"),
        (0x5254_0009, "register map is version 9, newer than this program's 3"),
    ] {
        s.poke(id_at, id);
        let r = s.refusal(Access::DevMem);
        assert!(r.to_string().contains(says), "ID {id:#x}: {r}");
    }
    // Older maps are known: row mode (1) and frame mode (2) boards run.
    s.poke(id_at, 0x5254_0001);
    let (_, report) = preflight::open(&s.sys, &Access::DevMem).expect("version 1 is known");
    assert_eq!((report.register_map, report.build_id), (1, 0), "no BUILD_ID before version 3");
}

#[test]
fn a_uio_device_named_on_the_command_line_must_map_the_bridge() {
    let s = stand();
    s.uio();
    // uio5 maps another device's registers (the SD/MMC host's, say): the
    // accelerator's START written there would reach that device.
    let maps = s.sys.sysfs.join("class/uio/uio5/maps/map0");
    std::fs::create_dir_all(&maps).unwrap();
    std::fs::write(maps.join("addr"), "0xff704000\n").unwrap();
    std::fs::write(maps.join("size"), "0x00200000\n").unwrap();
    std::fs::copy(s.sys.dev.join("uio2"), s.sys.dev.join("uio5")).unwrap();
    let r = s.refusal(Access::Uio(Some(s.sys.dev.join("uio5"))));
    assert!(r.to_string().contains("maps 0xff704000, not the lightweight bridge at 0xff200000"), "{r}");
    let (_, report) = preflight::open(&s.sys, &Access::Uio(Some(s.sys.dev.join("uio2")))).expect("uio2 is the bridge");
    assert!(report.window.ends_with("uio2 (map 0)"), "{}", report.window);
}

#[test]
fn missing_devices_say_what_to_do() {
    let s = stand();
    let r = s.refusal(Access::Uio(None));
    assert!(r.to_string().contains("no UIO device maps the lightweight bridge at 0xff200000"), "{r}");
    let r = s.refusal(Access::Uio(Some(s.path().join("dev/uio7"))));
    assert!(r.to_string().contains("uio7"), "{r}");
    std::fs::remove_file(&s.sys.dev_mem).unwrap();
    // No /dev/mem: the managers cannot be read (said, not refused), and
    // the window cannot be mapped (refused).
    assert!(matches!(preflight::fpga(&s.sys), Finding::Unknown(_)));
    let r = s.refusal(Access::DevMem);
    assert!(r.to_string().contains("mem does not exist"), "{r}");
}

// ---- The `check` command ----------------------------------------------------------

fn check_command(s: &Stand) -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_hps-linux"));
    c.arg("check").arg("--accelerator").arg("devmem");
    c.arg("--sysfs").arg(&s.sys.sysfs).arg("--dev").arg(&s.sys.dev).arg("--dev-mem").arg(&s.sys.dev_mem);
    c
}

#[test]
fn check_prints_what_it_saw_and_refuses_with_status_1() {
    let s = stand();
    let out = check_command(&s).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
    for line in
        ["FPGA: FPGA manager: user mode", "register map: version 3", "FPGA build: 0123abc", "accelerator: ready"]
    {
        assert!(stdout.lines().any(|l| l == line), "{line:?} in {stdout}");
    }
    let no_buffer = "frame memory: frame mode without contiguous memory: no u-dma-buf buffer";
    assert!(stdout.lines().any(|l| l.starts_with(no_buffer)), "{no_buffer:?} in {stdout}");
    s.poke(RSTMGR_BASE as u64 + 0x1c, 0x2);
    let out = check_command(&s).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.starts_with("hps-linux: the lightweight HPS-to-FPGA bridge is held in reset"), "{stderr}");
}

#[test]
fn without_root_dev_mem_is_refused_with_what_to_do() {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    use std::os::unix::process::CommandExt;
    let s = stand();
    // Nobody may open the stand-in /dev/mem (mode 000, as /dev/mem is to
    // all but root); the command runs as `nobody` when the test runs as
    // root, who could open it anyway. The binary and the stand-in are
    // copied where `nobody` can reach them.
    let shared = tempfile::Builder::new().prefix("hps-linux-noroot").tempdir_in("/tmp").unwrap();
    std::fs::set_permissions(shared.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    let bin = shared.path().join("hps-linux");
    std::fs::copy(env!("CARGO_BIN_EXE_hps-linux"), &bin).unwrap();
    std::fs::set_permissions(&bin, std::fs::Permissions::from_mode(0o755)).unwrap();
    let mem = shared.path().join("mem");
    std::fs::rename(&s.sys.dev_mem, &mem).or_else(|_| std::fs::copy(&s.sys.dev_mem, &mem).map(|_| ())).unwrap();
    std::fs::set_permissions(&mem, std::fs::Permissions::from_mode(0o000)).unwrap();
    let sysfs = shared.path().join("sys");
    std::fs::create_dir_all(&sysfs).unwrap();
    let mut c = std::process::Command::new(&bin);
    c.args(["check", "--accelerator", "devmem"]).arg("--sysfs").arg(&sysfs).arg("--dev-mem").arg(&mem);
    let root = std::fs::metadata("/proc/self").map(|m| m.uid() == 0).unwrap_or(false);
    if root {
        c.uid(65534).gid(65534);
    }
    let out = c.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("permission denied opening") && stderr.contains("needs root (sudo), or use UIO"),
        "{stderr}"
    );
}

// ---- Frame memory ----------------------------------------------------------------

/// A u-dma-buf buffer in the stand-in sysfs: `phys_addr` and `size` as the
/// module prints them on the A9 (`%pad` of a 32-bit address, `%zu`).
fn dma_buffer(s: &Stand, name: &str, phys_addr: u64, size: u64) {
    let dir = s.sys.sysfs.join("class/u-dma-buf").join(name);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("phys_addr"), format!("{phys_addr:#010x}\n")).unwrap();
    std::fs::write(dir.join("size"), format!("{size}\n")).unwrap();
}

#[test]
fn frame_mode_without_contiguous_memory_says_what_is_missing() {
    use hps_linux::frame_memory::{find, NoFrameMemory, RING_BYTES};
    let s = stand();
    let none = find(&s.sys.sysfs, &s.sys.dev, RING_BYTES).unwrap_err();
    assert!(matches!(none, NoFrameMemory::NoBuffer { .. }));
    let text = none.to_string();
    assert!(text.starts_with("frame mode without contiguous memory: no u-dma-buf buffer"), "{text}");
    assert!(text.ends_with("rendering rows over the lightweight bridge"), "{text}");
    // One too small, one above the SDRAM the port reaches: each said.
    dma_buffer(&s, "udmabuf0", 0x3f00_0000, 1 << 20);
    dma_buffer(&s, "udmabuf1", 0x4000_0000, 16 << 20);
    let text = find(&s.sys.sysfs, &s.sys.dev, RING_BYTES).unwrap_err().to_string();
    assert!(text.contains("udmabuf0 (1048576 bytes at 0x3f000000): smaller than the ring's 8294400 bytes"), "{text}");
    assert!(text.contains("udmabuf1") && text.contains("past the SDRAM"), "{text}");
    // One whose sync_mode keeps the cache on with O_SYNC: stale rows.
    dma_buffer(&s, "udmabuf10", 0x3d00_0000, 8 << 20);
    std::fs::write(s.sys.sysfs.join("class/u-dma-buf/udmabuf10/sync_mode"), "0\n").unwrap();
    let text = find(&s.sys.sysfs, &s.sys.dev, RING_BYTES).unwrap_err().to_string();
    assert!(text.contains("udmabuf10: sync_mode 0 keeps the CPU cache on"), "{text}");
    // A fitting one is found, with its device node.
    dma_buffer(&s, "udmabuf2", 0x3e00_0000, 8 << 20);
    std::fs::write(s.sys.sysfs.join("class/u-dma-buf/udmabuf2/sync_mode"), "1\n").unwrap();
    std::fs::File::create(s.sys.dev.join("udmabuf2")).and_then(|f| f.set_len(8 << 20)).unwrap();
    let found = find(&s.sys.sysfs, &s.sys.dev, RING_BYTES).unwrap();
    assert_eq!((found.phys_addr, found.size), (0x3e00_0000, 8 << 20));
    assert_eq!(found.device, s.sys.dev.join("udmabuf2"));
    let out = check_command(&s).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("frame memory: ") && stdout.contains("udmabuf2, 16 slots at 0x3e000000): frame mode"),
        "{stdout}"
    );
}
