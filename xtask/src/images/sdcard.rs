//! `cargo xtask sdcard`: one SD-card image that boots a DE1-SoC straight
//! into the firmware (docs/flash-and-boot.md).
//!
//! Layout (MBR, 512-byte sectors):
//!
//! | partition | type | start | size | contents |
//! |---|---|---|---|---|
//! | 1 | 0xA2 | 1 MiB | 2 MiB | `u-boot-with-spl.sfp`: four 64 KiB SPL copies, then `u-boot.img` at 256 KiB |
//! | 2 | 0x0E (FAT16, LBA), bootable | 4 MiB | 60 MiB | `boot.scr`, `firmware.bin`, `raytracer.rbf` if given |
//!
//! The Cyclone V boot ROM loads the preloader from the first partition of
//! type 0xA2 (Cyclone V HPS TRM, booting: "SD/MMC ... the partition with
//! ID 0xA2"); the SPL loads U-Boot from the same partition, 0x200 sectors
//! in (`CONFIG_SYS_MMCSD_RAW_MODE_U_BOOT_PARTITION_TYPE=0xa2`,
//! `..._SECTOR=0x200`); U-Boot's distro boot finds `boot.scr` on the
//! bootable partition. U-Boot's environment lives at 0x4400 (17 KiB,
//! `CONFIG_ENV_OFFSET`), before the first partition: a fresh image holds no
//! environment there, so the default one (with the patched `bootcmd`) is
//! used.
//!
//! U-Boot is Debian's source package (bookworm: 2023.01) with
//! `boot/u-boot-2023.01-de1-soc.patch`, cross-built with Debian's
//! `gcc-arm-linux-gnueabihf`; source and build are cached under
//! `target/sdcard/u-boot/`. No root mounts: the MBR is written here, the
//! FAT partition by `mkfs.vfat -C` and `mcopy` into a file.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use clap::Args;

use super::uimage::IH_MAGIC;
use crate::support::tools::{ensure_apt_packages, ensure_apt_source, root, step};
use crate::support::Result;

/// Bytes per sector.
pub const SECTOR: u64 = 512;
const MIB: u64 = 1 << 20;
/// Partition 1 (preloader): start and size.
pub const PRELOADER: (u64, u64) = (MIB, 2 * MIB);
/// Partition 2 (FAT): start and size.
pub const FAT: (u64, u64) = (4 * MIB, 60 * MIB);
/// The whole image.
pub const IMAGE_BYTES: u64 = 64 * MIB;
/// Partition type the boot ROM looks for.
pub const TYPE_PRELOADER: u8 = 0xA2;
/// FAT16 with LBA addressing.
pub const TYPE_FAT16_LBA: u8 = 0x0E;
/// Where the SPL finds `u-boot.img` inside the preloader partition.
pub const UBOOT_IMG_OFFSET: usize = 0x200 * SECTOR as usize;
/// One SPL copy (the boot ROM tries four).
pub const SPL_COPY: usize = 64 * 1024;
/// `fpgaportrst` the patched handoff releases (docs/frame-dma.md#boot-loader).
pub const FPGAPORTRST: u32 = 0x311;

/// The files on the FAT partition.
pub const FIRMWARE_FILE: &str = "firmware.bin";
/// The FPGA configuration's name on the card.
pub const RBF_FILE: &str = "raytracer.rbf";
/// The compiled boot script.
pub const SCRIPT_FILE: &str = "boot.scr";

/// `cargo xtask sdcard` options.
#[derive(Args)]
pub struct SdcardArgs {
    /// FPGA configuration (raw binary from `quartus_cpf`, uncompressed for
    /// MSEL 00000) to put on the card as raytracer.rbf; without it the
    /// firmware renders in software.
    #[arg(long)]
    pub rbf: Option<PathBuf>,
    /// The image to write.
    #[arg(long, default_value = "target/sdcard/raytracer-de1-soc.img")]
    pub out: PathBuf,
    /// The board's settings to put on the card as raytracer.txt; without
    /// it a new file: DHCP, the name raytracer, and a MAC address of its
    /// own chosen at random (docs/networking.md).
    #[arg(long)]
    pub settings: Option<PathBuf>,
}

/// The board's settings file on the card.
pub const SETTINGS_FILE: &str = "raytracer.txt";

/// A new card's raytracer.txt: DHCP, the default name, and `mac`.
pub fn settings_text(mac: [u8; 6]) -> String {
    let mac = mac.map(|b| format!("{b:02x}")).join(":");
    format!(
        "# raytracer.txt: this board's settings, read at every boot (docs/networking.md).\n\
         # Edit it on any computer: the card's FAT partition shows up as a drive.\n\
         #\n\
         # The address: dhcp (and a 169.254.x.y link-local address while no DHCP\n\
         # server answers), or a static one with its gateway, e.g.\n\
         #   ip=192.168.0.50/24\n\
         #   gateway=192.168.0.1\n\
         ip=dhcp\n\
         # The name the board answers to: NAME.local (mDNS), the page's address.\n\
         hostname={}\n\
         # This card's own Ethernet address, chosen at random when the card was\n\
         # made (locally administered): one card per board, and two boards on one\n\
         # network never share an address.\n\
         mac={mac}\n",
        rt_services::DEFAULT_HOST_NAME
    )
}

/// A random, locally administered, unicast MAC address (IEEE 802, section
/// 8.2: bit 1 of the first octet set, bit 0 clear), from the OS's
/// generator.
pub fn random_mac() -> Result<[u8; 6]> {
    use std::io::Read;
    let mut mac = [0u8; 6];
    fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut mac))
        .map_err(|e| format!("/dev/urandom: {e}"))?;
    mac[0] = (mac[0] & 0xfc) | 0x02;
    Ok(mac)
}

// ---- MBR ----------------------------------------------------------------------------

/// One MBR partition entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Partition {
    /// Boot flag (0x80).
    pub bootable: bool,
    /// Partition type.
    pub kind: u8,
    /// First sector.
    pub start: u32,
    /// Length in sectors.
    pub sectors: u32,
}

/// A master boot record with up to four primary partitions. The CHS fields
/// hold the "use LBA" marker (0xFE, 0xFF, 0xFF), as partitioners do for
/// disks of any size.
pub fn mbr(parts: &[Partition], disk_id: u32) -> Result<[u8; 512]> {
    if parts.len() > 4 {
        return Err("an MBR holds four primary partitions".into());
    }
    let mut s = [0u8; 512];
    s[440..444].copy_from_slice(&disk_id.to_le_bytes());
    for (i, p) in parts.iter().enumerate() {
        let e = &mut s[446 + 16 * i..462 + 16 * i];
        e[0] = if p.bootable { 0x80 } else { 0 };
        e[1..4].copy_from_slice(&[0xFE, 0xFF, 0xFF]);
        e[4] = p.kind;
        e[5..8].copy_from_slice(&[0xFE, 0xFF, 0xFF]);
        e[8..12].copy_from_slice(&p.start.to_le_bytes());
        e[12..16].copy_from_slice(&p.sectors.to_le_bytes());
    }
    s[510] = 0x55;
    s[511] = 0xAA;
    Ok(s)
}

/// The used entries of an MBR.
pub fn parse_mbr(sector: &[u8]) -> Result<Vec<Partition>> {
    if sector.len() < 512 || sector[510..512] != [0x55, 0xAA] {
        return Err("no MBR signature 55 AA".into());
    }
    let mut out = Vec::new();
    for i in 0..4 {
        let e = &sector[446 + 16 * i..462 + 16 * i];
        let word = |o: usize| u32::from_le_bytes([e[o], e[o + 1], e[o + 2], e[o + 3]]);
        if e[4] == 0 {
            continue;
        }
        if e[0] != 0 && e[0] != 0x80 {
            return Err(format!("partition {}: boot flag {:#04x}", i + 1, e[0]));
        }
        out.push(Partition { bootable: e[0] == 0x80, kind: e[4], start: word(8), sectors: word(12) });
    }
    Ok(out)
}

/// The project's layout.
pub fn layout() -> [Partition; 2] {
    let lba = |b: u64| (b / SECTOR) as u32;
    [
        Partition { bootable: false, kind: TYPE_PRELOADER, start: lba(PRELOADER.0), sectors: lba(PRELOADER.1) },
        Partition { bootable: true, kind: TYPE_FAT16_LBA, start: lba(FAT.0), sectors: lba(FAT.1) },
    ]
}

// ---- SoC FPGA preloader image (mkimage -T socfpgaimage, header v0) ------------------

/// What a valid preloader copy says about itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Preloader {
    /// Program length in bytes, the CRC word included.
    pub length: usize,
}

/// CRC-32/BZIP2 (polynomial 0x04C11DB7, MSB first, initial and final
/// inversion): what U-Boot's `tools/pbl_crc32.c` computes for the
/// preloader.
fn crc32_bzip2(data: &[u8]) -> u32 {
    crc::Crc::<u32>::new(&crc::CRC_32_BZIP2).checksum(data)
}

/// Header checksum: the byte sum U-Boot's `sfp_hdr_checksum` forms over the
/// header's first nine bytes.
fn sfp_header_sum(h: &[u8]) -> u16 {
    h[..9].iter().fold(0u16, |a, b| a.wrapping_add(u16::from(*b)))
}

/// Check one 64 KiB preloader copy as the Cyclone V boot ROM and `mkimage`
/// do (U-Boot `tools/socfpgaimage.c`, header version 0 at 0x40: validation
/// word 0x31305341, version 0, length in words, zero, header checksum;
/// then a CRC-32/BZIP2 of everything before the image's last word, stored
/// little-endian in it).
pub fn check_preloader(copy: &[u8]) -> Result<Preloader> {
    let h = copy.get(0x40..0x4C).ok_or("shorter than the header")?;
    let validation = u32::from_le_bytes([h[0], h[1], h[2], h[3]]);
    if validation != 0x3130_5341 {
        return Err(format!("validation word {validation:#010x}, want 0x31305341"));
    }
    if h[4] != 0 {
        return Err(format!("header version {}, want 0 (Cyclone V)", h[4]));
    }
    let sum = u16::from_le_bytes([h[10], h[11]]);
    if sum != sfp_header_sum(h) {
        return Err(format!("header checksum {sum:#06x}, computed {:#06x}", sfp_header_sum(h)));
    }
    let length = usize::from(u16::from_le_bytes([h[6], h[7]])) * 4;
    if !(0x50..=SPL_COPY).contains(&length) || length > copy.len() {
        return Err(format!("program length {length} bytes"));
    }
    let crc = u32::from_le_bytes([copy[length - 4], copy[length - 3], copy[length - 2], copy[length - 1]]);
    let want = crc32_bzip2(&copy[..length - 4]);
    if crc != want {
        return Err(format!("CRC {crc:#010x}, computed {want:#010x}"));
    }
    Ok(Preloader { length })
}

/// The text of a compiled U-Boot script (`mkimage -T script`: a 64-byte
/// legacy header, then a zero-terminated table of big-endian lengths, then
/// the parts).
pub fn script_text(img: &[u8]) -> Result<String> {
    if img.len() < 72 || img[..4] != IH_MAGIC.to_be_bytes() {
        return Err("not a U-Boot legacy image".into());
    }
    if img[30] != 6 {
        return Err(format!("image type {}, want 6 (script)", img[30]));
    }
    let be = |o: usize| img.get(o..o + 4).map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let (mut lens, mut at) = (Vec::new(), 64);
    loop {
        let n = be(at).ok_or("truncated length table")?;
        at += 4;
        if n == 0 {
            break;
        }
        lens.push(n);
    }
    let n = *lens.first().ok_or("no script in the image")?;
    let text = img.get(at..at + n).ok_or("truncated script")?;
    Ok(String::from_utf8_lossy(text).trim_end_matches('\0').to_string())
}

// ---- Building -------------------------------------------------------------------------

const CROSS: &str = "arm-linux-gnueabihf-";

fn dir() -> PathBuf {
    root().join("target/sdcard")
}

fn run_in(dir: &Path, what: &str, program: &str, args: &[&str]) -> Result<()> {
    let mut c = Command::new(program);
    c.current_dir(dir).args(args);
    step(what, c)
}

/// The patched U-Boot source tree (downloaded and patched once).
fn uboot_source() -> Result<PathBuf> {
    let base = dir().join("u-boot");
    let src = base.join("src");
    let patch = root().join("boot/u-boot-2023.01-de1-soc.patch");
    if !src.join("Makefile").exists() {
        let dl = base.join("download");
        let _ = fs::remove_dir_all(&dl);
        fs::create_dir_all(&dl).map_err(|e| format!("{}: {e}", dl.display()))?;
        // deb-src for bookworm, copied from the machine's Debian entry.
        ensure_apt_source(DEB_SRC_FILE, "deb-src", "bookworm", "bookworm")?;
        crate::support::tools::apt_update()?;
        run_in(&dl, "apt-get source u-boot (Debian bookworm)", "apt-get", &["source", "-q", "u-boot"])?;
        let tree = fs::read_dir(&dl)
            .map_err(|e| e.to_string())?
            .flatten()
            .map(|e| e.path())
            .find(|p| p.is_dir() && p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("u-boot-")))
            .ok_or("apt-get source left no u-boot-* directory")?;
        let _ = fs::remove_dir_all(&src);
        fs::rename(&tree, &src).map_err(|e| format!("{} -> {}: {e}", tree.display(), src.display()))?;
        let p = patch.to_string_lossy().into_owned();
        run_in(&src, "patch U-Boot (boot/u-boot-2023.01-de1-soc.patch)", "patch", &["-p1", "--forward", "-i", &p])?;
    }
    Ok(src)
}

/// `u-boot-with-spl.sfp`, built once and then incrementally.
fn uboot() -> Result<PathBuf> {
    let src = uboot_source()?;
    let build = dir().join("u-boot/build");
    let out = format!("O={}", build.display());
    let cross = format!("CROSS_COMPILE={CROSS}");
    if !build.join(".config").exists() {
        run_in(&src, "U-Boot: socfpga_de1_soc_defconfig", "make", &[&out, &cross, "socfpga_de1_soc_defconfig"])?;
    }
    run_in(&src, "U-Boot: build SPL and U-Boot", "make", &[&out, &cross, "-j2", "-s"])?;
    let sfp = build.join("u-boot-with-spl.sfp");
    if !sfp.exists() {
        return Err(format!("the U-Boot build wrote no {}", sfp.display()));
    }
    Ok(sfp)
}

/// Compile `boot/boot.cmd` into a U-Boot script image.
fn boot_script(out: &Path) -> Result<PathBuf> {
    let cmd = root().join("boot/boot.cmd");
    let scr = out.join(SCRIPT_FILE);
    let mut c = Command::new("mkimage");
    c.args(["-A", "arm", "-O", "linux", "-T", "script", "-C", "none", "-n", "raytracer boot", "-d"])
        .arg(&cmd)
        .arg(&scr);
    c.stdout(std::process::Stdio::null());
    step("boot script (mkimage -T script)", c)?;
    Ok(scr)
}

/// The FAT partition as a file: `mkfs.vfat -C`, then `mcopy`.
fn fat_image(path: &Path, files: &[(&Path, &str)]) -> Result<()> {
    let _ = fs::remove_file(path);
    let mut mk = Command::new("mkfs.vfat");
    mk.args(["-F", "16", "-n", "RAYTRACER", "-C"]).arg(path).arg((FAT.1 / 1024).to_string());
    mk.stdout(std::process::Stdio::null());
    step("FAT16 file system (mkfs.vfat -C)", mk)?;
    for (src, name) in files {
        let mut c = Command::new("mcopy");
        c.arg("-i").arg(path).arg(src).arg(format!("::{name}"));
        step(&format!("mcopy {name}"), c)?;
    }
    Ok(())
}

/// Write `out` from its parts.
fn assemble(out: &Path, sfp: &[u8], fat: &[u8]) -> Result<()> {
    if sfp.len() as u64 > PRELOADER.1 || fat.len() as u64 > FAT.1 {
        return Err("a part is larger than its partition".into());
    }
    let mut img = vec![0u8; IMAGE_BYTES as usize];
    img[..512].copy_from_slice(&mbr(&layout(), 0x5254_5243)?);
    img[PRELOADER.0 as usize..][..sfp.len()].copy_from_slice(sfp);
    img[FAT.0 as usize..][..fat.len()].copy_from_slice(fat);
    if let Some(d) = out.parent() {
        fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    fs::write(out, img).map_err(|e| format!("{}: {e}", out.display()))
}

/// The apt source file (in /etc/apt/sources.list.d) of bookworm's
/// `deb-src` entry, for U-Boot's source.
pub const DEB_SRC_FILE: &str = "raytracer-bookworm-src";

/// The tools the image needs (Debian packages).
pub const PACKAGES: &[&str] = &[
    "gcc-arm-linux-gnueabihf",
    "make",
    "bison",
    "flex",
    "bc",
    "libssl-dev",
    "python3",
    "dpkg-dev",
    "patch",
    "u-boot-tools",
    "mtools",
    "dosfstools",
    "fdisk",
];

/// Build the image; check it; print where it is and how to write it.
pub fn run(args: &SdcardArgs) -> Result<()> {
    ensure_apt_packages(PACKAGES, None)?;
    let out_dir = dir();
    fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let sfp = uboot()?;
    super::firmware::image(&super::firmware::ImageArgs { out: out_dir.clone() })?;
    let firmware = out_dir.join(FIRMWARE_FILE);
    let script = boot_script(&out_dir)?;
    let settings = out_dir.join(SETTINGS_FILE);
    let settings_text = match &args.settings {
        Some(p) => fs::read_to_string(p).map_err(|e| format!("--settings {}: {e}", p.display()))?,
        None => settings_text(random_mac()?),
    };
    fs::write(&settings, &settings_text).map_err(|e| format!("{}: {e}", settings.display()))?;
    let mut files: Vec<(&Path, &str)> =
        vec![(script.as_path(), SCRIPT_FILE), (firmware.as_path(), FIRMWARE_FILE), (settings.as_path(), SETTINGS_FILE)];
    let rbf = args.rbf.as_ref().map(|r| if r.is_absolute() { r.clone() } else { root().join(r) });
    if let Some(r) = &rbf {
        if !r.is_file() {
            return Err(format!("--rbf {}: no such file", r.display()));
        }
        files.push((r.as_path(), RBF_FILE));
    }
    let fat = out_dir.join("fat.img");
    fat_image(&fat, &files)?;
    let out = if args.out.is_absolute() { args.out.clone() } else { root().join(&args.out) };
    let read = |p: &Path| fs::read(p).map_err(|e| format!("{}: {e}", p.display()));
    assemble(&out, &read(&sfp)?, &read(&fat)?)?;
    let expected = Expected {
        firmware: read(&firmware)?,
        rbf: rbf.as_deref().map(read).transpose()?,
        script: fs::read_to_string(root().join("boot/boot.cmd")).map_err(|e| e.to_string())?,
        settings: settings_text.clone().into_bytes(),
    };
    check_image(&out, &expected)?;
    println!("wrote {} ({} MiB)", out.display(), IMAGE_BYTES / MIB);
    match &rbf {
        Some(r) => println!("  FPGA: {} as {RBF_FILE}", r.display()),
        None => println!("  FPGA: none (the firmware renders in software; --rbf FILE adds one)"),
    }
    let parsed = rt_services::address::settings::Settings::parse(settings_text.as_bytes());
    for p in &parsed.problems {
        println!("  warning: {SETTINGS_FILE} {p}: the board will ignore it");
    }
    match parsed.mac {
        Some(m) => println!("  {SETTINGS_FILE}: MAC {}", m.map(|b| format!("{b:02x}")).join(":")),
        None => println!("  {SETTINGS_FILE}: no mac= line: the board's default MAC (every such board shares it)"),
    }
    println!("write it to a card (all data on it is lost), e.g. on Linux:");
    println!("  sudo dd if={} of=/dev/sdX bs=4M conv=fsync status=progress", out.display());
    println!("then MSEL (SW10) 00000, UART 115200 8N1, Ethernet; docs/flash-and-boot.md");
    Ok(())
}

// ---- Checking an image -------------------------------------------------------------------

/// What an image must hold.
pub struct Expected {
    /// `firmware.bin`.
    pub firmware: Vec<u8>,
    /// `raytracer.rbf`, if one was given.
    pub rbf: Option<Vec<u8>>,
    /// The boot script's source.
    pub script: String,
    /// `raytracer.txt`.
    pub settings: Vec<u8>,
}

/// A file of the image's FAT partition, read back with `mtools`.
fn fat_file(img: &Path, name: &str) -> Result<Option<Vec<u8>>> {
    let tmp = dir().join(format!("check-{name}"));
    let _ = fs::remove_file(&tmp);
    let st = Command::new("mcopy")
        .arg("-n")
        .arg("-i")
        .arg(format!("{}@@{}", img.display(), FAT.0))
        .arg(format!("::{name}"))
        .arg(&tmp)
        .stderr(std::process::Stdio::null())
        .status()
        .map_err(|e| format!("mcopy: {e}"))?;
    if !st.success() {
        return Ok(None);
    }
    let bytes = fs::read(&tmp).map_err(|e| e.to_string())?;
    let _ = fs::remove_file(&tmp);
    Ok(Some(bytes))
}

/// Check an image: the partition table, every preloader copy, U-Boot's
/// image behind them, and the FAT files.
pub fn check_image(img: &Path, want: &Expected) -> Result<()> {
    let bytes = fs::read(img).map_err(|e| format!("{}: {e}", img.display()))?;
    let parts = parse_mbr(&bytes)?;
    if parts != layout() {
        return Err(format!("partition table {parts:?}, want {:?}", layout()));
    }
    let pre = &bytes[PRELOADER.0 as usize..(PRELOADER.0 + PRELOADER.1) as usize];
    for i in 0..4 {
        check_preloader(&pre[i * SPL_COPY..(i + 1) * SPL_COPY]).map_err(|e| format!("preloader copy {i}: {e}"))?;
    }
    let uimg = &pre[UBOOT_IMG_OFFSET..];
    if uimg[..4] != IH_MAGIC.to_be_bytes() {
        return Err("no U-Boot legacy image at 256 KiB into the preloader partition".into());
    }
    let script = fat_file(img, SCRIPT_FILE)?.ok_or("no boot.scr on the FAT partition")?;
    let text = script_text(&script)?;
    if text.trim() != want.script.trim() {
        return Err("boot.scr does not hold boot/boot.cmd".into());
    }
    if fat_file(img, FIRMWARE_FILE)?.as_deref() != Some(&want.firmware[..]) {
        return Err("firmware.bin on the card differs from the build".into());
    }
    if fat_file(img, SETTINGS_FILE)?.as_deref() != Some(&want.settings[..]) {
        return Err(format!("{SETTINGS_FILE} on the card differs from what was written (or is missing)"));
    }
    let rbf = fat_file(img, RBF_FILE)?;
    if rbf != want.rbf {
        return Err(match want.rbf {
            Some(_) => "raytracer.rbf on the card differs from --rbf (or is missing)".into(),
            None => "raytracer.rbf on the card, but none was given".into(),
        });
    }
    Ok(())
}

/// The `.config` symbols the boot script and the port release depend on.
pub fn check_uboot_config(config: &str) -> Result<()> {
    let on = |sym: &str| config.lines().any(|l| l == format!("CONFIG_{sym}=y"));
    for sym in [
        "CMD_FAT",
        "FS_FAT",
        "CMD_FS_GENERIC",
        "CMD_FPGA",
        "FPGA_SOCFPGA",
        "CMD_MEMORY",
        "CMD_CACHE",
        "CMD_MMC",
        "DISTRO_DEFAULTS",
        "USE_BOOTCOMMAND",
    ] {
        if !on(sym) {
            return Err(format!("U-Boot .config: CONFIG_{sym} is not set"));
        }
    }
    if !config.lines().any(|l| l == "CONFIG_BOOTCOMMAND=\"run distro_bootcmd\"") {
        return Err("U-Boot .config: CONFIG_BOOTCOMMAND is not \"run distro_bootcmd\"".into());
    }
    // U-Boot leaves the boot ROM's watchdog alone and the firmware holds it
    // in reset (docs/flash-and-boot.md#watchdog): no watchdog driver here.
    for sym in ["WATCHDOG", "HW_WATCHDOG", "WDT", "SPL_WDT", "DESIGNWARE_WATCHDOG"] {
        if on(sym) {
            return Err(format!("U-Boot .config: CONFIG_{sym} is set: a watchdog would run into the firmware"));
        }
    }
    Ok(())
}

/// What the boot script must (not) do: load the FPGA before `bridge
/// enable`, and leave the SDRAM controller's registers to U-Boot's code
/// (`bridge enable` applies `staticcfg` from one I-cache line; a `mw` to it
/// would run out of SDRAM).
pub fn check_boot_script(script: &str) -> Result<()> {
    let lines: Vec<&str> = script.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#')).collect();
    let at = |cmd: &str| lines.iter().position(|l| l.starts_with(cmd));
    if let Some(l) = lines.iter().find(|l| {
        let l = l.to_ascii_lowercase();
        l.starts_with("mw") && l.contains("0xffc25")
    }) {
        return Err(format!("boot script writes the SDRAM controller itself: {l:?}"));
    }
    // The bridges are enabled only when `fpga load` succeeded (U-Boot's
    // hush runs the `then` branch on exit status 0), and a failure says what
    // to check.
    let load = lines.iter().position(|l| l.starts_with("if fpga load"));
    match (load, at("bridge enable"), at("else")) {
        (Some(load), Some(enable), Some(other)) if load < enable && enable < other => {}
        (load, enable, other) => {
            return Err(format!(
                "boot script: `if fpga load` at {load:?}, bridge enable at {enable:?}, its else at {other:?}"
            ))
        }
    }
    if !lines.iter().any(|l| l.contains("fpga load FAILED") && l.starts_with("echo")) || !script.contains("MSEL") {
        return Err("boot script: a failed fpga load is not reported with what to check (MSEL)".into());
    }
    check_settings_handoff(&lines)?;
    // The I-cache invalidated between the firmware's load and `go`, which
    // only branches (U-Boot cmd/cache.c: `icache flush` runs
    // invalidate_icache_all).
    let firmware = lines.iter().position(|l| l.starts_with("load") && l.contains("firmware.bin"));
    let flush = lines.iter().rposition(|l| *l == "icache flush");
    match (firmware, flush, at("go ")) {
        (Some(load), Some(flush), Some(go)) if load < flush && flush < go => Ok(()),
        (load, flush, go) => {
            Err(format!("boot script: firmware load at {load:?}, icache flush at {flush:?}, go at {go:?}"))
        }
    }
}

/// raytracer.txt reaches the firmware as firmware/src/settings.rs reads it:
/// the header cleared, the file's size asked for and written as the length,
/// then at most the area's 0xff8 bytes of text loaded 8 bytes into the
/// hand-off area (firmware/memory.x), then the word "RTCF" last.
fn check_settings_handoff(lines: &[&str]) -> Result<()> {
    let base = super::firmware::HANDOFF_ADDR;
    let find = |want: &str| lines.iter().position(|l| l.contains(want));
    let clear = find(&format!("mw.l {base:#010x} 0"));
    let size = lines.iter().position(|l| l.starts_with("size") && l.ends_with(" raytracer.txt"));
    let len = find(&format!("mw.l {:#010x} ${{filesize}}", base + 4));
    let limit = format!("{:#x}", super::firmware::HANDOFF_BYTES - 8);
    let text = lines
        .iter()
        .position(|l| l.starts_with("load") && l.ends_with(&format!("{:#010x} raytracer.txt {limit}", base + 8)));
    let magic = find(&format!("mw.l {base:#010x} {:#010x}", u32::from_le_bytes(*b"RTCF")));
    match (clear, size, len, text, magic) {
        (Some(c), Some(s), Some(l), Some(t), Some(m)) if c < s && s < l && l < t && t < m => Ok(()),
        found => Err(format!(
            "boot script: the settings hand-off at {base:#010x} (clear, size, length, load of at most {limit} bytes, word) is at {found:?}"
        )),
    }
}

/// The patched `do_bridge_reset` applies the static configuration before it
/// releases the FPGA-to-SDRAM ports.
pub fn check_bridge_applycfg(misc_gen5_c: &str) -> Result<()> {
    let body = misc_gen5_c.split("void do_bridge_reset(").nth(1).ok_or("no do_bridge_reset")?;
    let enable = body.split("} else {").next().unwrap_or(body);
    let apply = enable.find("socfpga_sdram_apply_static_cfg();").ok_or("bridge enable does not apply staticcfg")?;
    let release = enable.find("&sdr_ctrl->fpgaport_rst").ok_or("bridge enable does not release the ports")?;
    if apply > release {
        return Err("bridge enable releases the ports before it applies staticcfg".into());
    }
    let Some(line) = misc_gen5_c.find(".balign 32") else {
        return Err("the applycfg routine is not aligned to an I-cache line".into());
    };
    // Buffered writes drained before the line: a dsb, then the L2C-310's
    // cache sync.
    let before = &misc_gen5_c[..line];
    match (before.rfind("asm volatile(\"dsb\""), before.rfind("pl310->pl310_cache_sync")) {
        (Some(dsb), Some(sync)) if dsb < sync => Ok(()),
        _ => Err("the applycfg routine does not drain the write buffers (dsb, then L2 cache sync) first".into()),
    }
}

/// The handoff value the patched source carries.
pub fn fpgaportrst_in(sdram_config_h: &str) -> Option<u32> {
    sdram_config_h.lines().find_map(|l| {
        let rest = l.trim().strip_prefix("#define CFG_HPS_SDR_CTRLCFG_FPGAPORTRST")?;
        let v = rest.trim();
        u32::from_str_radix(v.trim_start_matches("0x"), if v.starts_with("0x") { 16 } else { 10 }).ok()
    })
}

/// The suite's image test: build a card with a stand-in FPGA image and check
/// it, including with the tools (`mkimage -l`, `sfdisk --dump`), and the
/// U-Boot configuration and patch.
pub fn suite_test() -> Result<()> {
    let rbf_path = dir().join("test.rbf");
    fs::create_dir_all(dir()).map_err(|e| e.to_string())?;
    // Not an FPGA image: bytes the check can recognise.
    let rbf: Vec<u8> = (0u32..300_000).map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8).collect();
    fs::write(&rbf_path, &rbf).map_err(|e| e.to_string())?;
    let img = dir().join("test-card.img");
    run(&SdcardArgs { rbf: Some(rbf_path), out: img.clone(), settings: None })?;
    // Cross-checks with the tools.
    let bytes = fs::read(&img).map_err(|e| e.to_string())?;
    let spl = dir().join("test-spl.bin");
    fs::write(&spl, &bytes[PRELOADER.0 as usize..][..SPL_COPY]).map_err(|e| e.to_string())?;
    let l = Command::new("mkimage").arg("-l").arg(&spl).output().map_err(|e| format!("mkimage: {e}"))?;
    let listing = String::from_utf8_lossy(&l.stdout);
    if !listing.contains("Cyclone V / Arria V SoC Image") {
        return Err(format!("mkimage -l does not see a Cyclone V preloader:\n{listing}"));
    }
    let d = Command::new("sfdisk").arg("--dump").arg(&img).output().map_err(|e| format!("sfdisk: {e}"))?;
    let dump = String::from_utf8_lossy(&d.stdout);
    for want in
        ["start=        2048, size=        4096, type=a2", "start=        8192, size=      122880, type=e, bootable"]
    {
        if !dump.contains(want) {
            return Err(format!("sfdisk --dump lacks {want:?}:\n{dump}"));
        }
    }
    let config = fs::read_to_string(dir().join("u-boot/build/.config")).map_err(|e| e.to_string())?;
    check_uboot_config(&config)?;
    let h = fs::read_to_string(dir().join("u-boot/src/board/terasic/de1-soc/qts/sdram_config.h"))
        .map_err(|e| e.to_string())?;
    match fpgaportrst_in(&h) {
        Some(FPGAPORTRST) => {}
        other => return Err(format!("patched handoff FPGAPORTRST is {other:?}, want {FPGAPORTRST:#x}")),
    }
    let misc =
        fs::read_to_string(dir().join("u-boot/src/arch/arm/mach-socfpga/misc_gen5.c")).map_err(|e| e.to_string())?;
    check_bridge_applycfg(&misc)?;
    check_boot_script(&fs::read_to_string(root().join("boot/boot.cmd")).map_err(|e| e.to_string())?)?;
    let dts = fs::read_to_string(dir().join("u-boot/src/arch/arm/dts/socfpga_cyclone5_de1_soc.dts"))
        .map_err(|e| e.to_string())?;
    if !dts.contains("&watchdog0 {\n\tstatus = \"disabled\";") {
        return Err(
            "U-Boot's DE1-SoC device tree no longer disables watchdog0: check docs/flash-and-boot.md#watchdog".into()
        );
    }
    // The built U-Boot itself: its default environment boots the distro
    // way, and it has the bridge command (no Kconfig symbol of its own).
    let bin = fs::read(dir().join("u-boot/build/u-boot.bin")).map_err(|e| e.to_string())?;
    for want in [&b"bootcmd=run distro_bootcmd\0"[..], b"SoCFPGA HPS FPGA bridge control"] {
        if !bin.windows(want.len()).any(|w| w == want) {
            return Err(format!("u-boot.bin lacks {:?}", String::from_utf8_lossy(want)));
        }
    }
    println!("sdcard: partition table, 4 preloader copies (own check and mkimage -l), U-Boot image, boot.scr, firmware.bin, raytracer.rbf, U-Boot config and handoff: as intended");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mbr_round_trips_and_holds_the_layout() {
        let s = mbr(&layout(), 1).expect("four or fewer");
        assert_eq!(parse_mbr(&s).expect("valid"), layout());
        assert_eq!(layout()[0], Partition { bootable: false, kind: 0xA2, start: 2048, sectors: 4096 });
        assert_eq!(layout()[1], Partition { bootable: true, kind: 0x0E, start: 8192, sectors: 122_880 });
        assert!(FAT.0 + FAT.1 <= IMAGE_BYTES && PRELOADER.0 + PRELOADER.1 <= FAT.0, "no overlap, inside the image");
        assert!(0x4400 + 0x2000 <= PRELOADER.0, "U-Boot's environment fits before the first partition");
        let mut bad = s;
        bad[511] = 0;
        assert!(parse_mbr(&bad).is_err());
        let mut bad = s;
        bad[446] = 0x12;
        assert!(parse_mbr(&bad).is_err(), "boot flag neither 0 nor 0x80");
    }

    /// A preloader copy made the way U-Boot's mkimage makes one.
    fn preloader(program: &[u8]) -> Vec<u8> {
        let len = (program.len().max(0x50) + 4).next_multiple_of(4);
        let mut b = vec![0u8; SPL_COPY];
        b[..program.len()].copy_from_slice(program);
        b[0x40..0x50].fill(0);
        b[0x40..0x44].copy_from_slice(&0x3130_5341u32.to_le_bytes());
        b[0x46..0x48].copy_from_slice(&((len / 4) as u16).to_le_bytes());
        let sum = sfp_header_sum(&b[0x40..0x4C]);
        b[0x4A..0x4C].copy_from_slice(&sum.to_le_bytes());
        let crc = crc32_bzip2(&b[..len - 4]);
        b[len - 4..len].copy_from_slice(&crc.to_le_bytes());
        b
    }

    #[test]
    fn preloader_headers_and_crcs_are_checked() {
        // CRC-32/BZIP2 check value ("123456789" -> 0xFC891918).
        assert_eq!(crc32_bzip2(b"123456789"), 0xFC89_1918);
        let p = preloader(&[0xE1; 200]);
        assert_eq!(check_preloader(&p), Ok(Preloader { length: 204 }));
        let mut bad = p.clone();
        bad[100] ^= 1;
        assert!(check_preloader(&bad).unwrap_err().contains("CRC"));
        let mut bad = p.clone();
        bad[0x47] ^= 0x10;
        assert!(check_preloader(&bad).unwrap_err().contains("checksum"));
        let mut bad = p;
        bad[0x40] = 0;
        assert!(check_preloader(&bad).unwrap_err().contains("validation"));
    }

    #[test]
    fn script_text_comes_back_out_of_a_script_image() {
        let text = "echo hello\ngo 0x100040\n";
        let mut img = vec![0u8; 64];
        img[..4].copy_from_slice(&IH_MAGIC.to_be_bytes());
        img[30] = 6;
        img.extend_from_slice(&(text.len() as u32).to_be_bytes());
        img.extend_from_slice(&0u32.to_be_bytes());
        img.extend_from_slice(text.as_bytes());
        assert_eq!(script_text(&img).expect("a script"), text);
        img[30] = 2;
        assert!(script_text(&img).is_err(), "a kernel image is no script");
    }

    #[test]
    fn uboot_config_and_handoff_checks() {
        let good = "CONFIG_CMD_FAT=y\nCONFIG_FS_FAT=y\nCONFIG_CMD_FS_GENERIC=y\nCONFIG_CMD_FPGA=y\nCONFIG_FPGA_SOCFPGA=y\n\
                    CONFIG_CMD_MEMORY=y\nCONFIG_CMD_CACHE=y\nCONFIG_CMD_MMC=y\nCONFIG_DISTRO_DEFAULTS=y\nCONFIG_USE_BOOTCOMMAND=y\n\
                    CONFIG_BOOTCOMMAND=\"run distro_bootcmd\"\n# CONFIG_WDT is not set\n";
        assert_eq!(check_uboot_config(good), Ok(()));
        assert!(check_uboot_config(&good.replace("CONFIG_CMD_FPGA=y\n", "")).is_err());
        assert!(check_uboot_config(&format!("{good}CONFIG_WDT=y\n")).is_err());
        assert!(check_uboot_config(&good.replace("run distro_bootcmd", "bootm")).is_err());
        assert_eq!(fpgaportrst_in("#define CFG_HPS_SDR_CTRLCFG_FPGAPORTRST\t\t\t0x311\n"), Some(0x311));
        assert_eq!(fpgaportrst_in("#define CFG_HPS_SDR_CTRLCFG_FPGAPORTRST 0x0\n"), Some(0));
        // The patch in the repository sets exactly that.
        let patch = std::fs::read_to_string(root().join("boot/u-boot-2023.01-de1-soc.patch")).expect("patch");
        assert!(patch.contains(&format!("+#define CFG_HPS_SDR_CTRLCFG_FPGAPORTRST\t\t\t{FPGAPORTRST:#x}")));
        assert!(patch.contains("+CONFIG_BOOTCOMMAND=\"run distro_bootcmd\""));
        assert!(patch.contains(
            "+\t\tsocfpga_sdram_apply_static_cfg();\n \t\twritel(iswgrp_handoff[3], &sdr_ctrl->fpgaport_rst);"
        ));
    }

    #[test]
    fn the_boot_script_leaves_the_sdram_controller_to_bridge_enable() {
        let script = std::fs::read_to_string(root().join("boot/boot.cmd")).expect("boot.cmd");
        assert_eq!(check_boot_script(&script), Ok(()));
        let with_mw = script.replace("\tbridge enable", "\tmw 0xffc2505c 0xa\n\tbridge enable");
        assert!(check_boot_script(&with_mw).is_err(), "a mw to staticcfg");
        assert!(
            check_boot_script(&script.replace("\tbridge enable", "\tmw.l 0xFFC25080 0x311\n\tbridge enable")).is_err()
        );
        assert!(check_boot_script(&script.replace("bridge enable", "echo no bridges")).is_err());
        assert!(check_boot_script("bridge enable\nif fpga load 0 0 0; then\nelse\n").is_err(), "order");
        assert!(
            check_boot_script(&script.replace(
                "if fpga load 0 ${kernel_addr_r} ${filesize}; then",
                "fpga load 0 ${kernel_addr_r} ${filesize}"
            ))
            .is_err(),
            "the load's result not checked"
        );
        assert!(check_boot_script(&script.replace("fpga load FAILED", "fpga load failed")).is_err(), "silent");
        assert_eq!(check_boot_script(&format!("# mw 0xffc2505c 0xa\n{script}")), Ok(()), "comments are not commands");
    }

    #[test]
    fn a_new_cards_settings_read_back_as_written_with_a_mac_of_its_own() {
        let mac = random_mac().expect("a MAC");
        assert_eq!(mac[0] & 3, 2, "locally administered, unicast: {mac:02x?}");
        assert_ne!(random_mac().expect("another"), mac, "two cards, two MACs");
        let s = rt_services::address::settings::Settings::parse(settings_text(mac).as_bytes());
        assert!(s.problems.is_empty(), "{:?}", s.problems);
        assert_eq!(s.mac, Some(mac));
        assert_eq!(s.hostname.as_deref(), Some(rt_services::DEFAULT_HOST_NAME));
        assert_eq!(s.address, rt_services::address::settings::AddressMode::Automatic);
    }

    #[test]
    fn the_boot_script_hands_the_settings_over_where_the_firmware_reads_them() {
        let script = std::fs::read_to_string(root().join("boot/boot.cmd")).expect("boot.cmd");
        assert_eq!(check_boot_script(&script), Ok(()));
        let memory_x = std::fs::read_to_string(root().join("firmware/memory.x")).expect("memory.x");
        let origin = format!("HANDOFF : ORIGIN = {:#010x}", super::super::firmware::HANDOFF_ADDR);
        assert!(memory_x.contains(&origin), "memory.x lacks {origin:?}");
        let moved = script.replace("0x04900008 raytracer.txt", "0x04a00008 raytracer.txt");
        assert!(check_boot_script(&moved).is_err(), "text loaded elsewhere");
        let swapped = script.replace("\tmw.l 0x04900000 0x46435452\n", "").replace(
            "\tmw.l 0x04900004 ${filesize}\n",
            "\tmw.l 0x04900000 0x46435452\n\tmw.l 0x04900004 ${filesize}\n",
        );
        assert!(check_boot_script(&swapped).is_err(), "the word before the length");
        let unlimited = script.replace("raytracer.txt 0xff8", "raytracer.txt");
        assert!(check_boot_script(&unlimited).is_err(), "a load that may run past the area");
        let late = script.replace("\tsize ${devtype} ${devnum}:${distro_bootpart} raytracer.txt\n", "");
        assert!(check_boot_script(&late).is_err(), "the length of what was loaded, not the file's");
    }

    #[test]
    fn the_boot_script_invalidates_the_icache_between_the_firmware_load_and_go() {
        let script = std::fs::read_to_string(root().join("boot/boot.cmd")).expect("boot.cmd");
        assert_eq!(check_boot_script(&script), Ok(()));
        assert!(check_boot_script(&script.replace("icache flush\n", "")).is_err(), "no flush");
        let early = script.replace("icache flush\n", "").replace("bridge enable\n", "bridge enable\n\ticache flush\n");
        assert!(check_boot_script(&early).is_err(), "flushed before the load");
        assert!(check_boot_script(&script.replace("icache flush", "# icache flush")).is_err(), "commented out");
    }

    #[test]
    fn bridge_enable_applies_staticcfg_before_the_port_release() {
        let good = "void do_bridge_reset(int enable, unsigned int mask)\n{\n\tif (enable) {\n\t\tsocfpga_sdram_apply_static_cfg();\n\
                    \t\twritel(iswgrp_handoff[3], &sdr_ctrl->fpgaport_rst);\n\t} else {\n\t\twritel(0, &sdr_ctrl->fpgaport_rst);\n\t}\n}\n";
        let routine = "asm volatile(\"dsb\" : : : \"memory\");\nwritel(0, &pl310->pl310_cache_sync);\nasm volatile(\".balign 32\\n\"";
        assert_eq!(check_bridge_applycfg(&format!("{routine}\n{good}")), Ok(()));
        assert!(check_bridge_applycfg(good).is_err(), "not aligned");
        let undrained = "asm volatile(\".balign 32\\n\"";
        assert!(check_bridge_applycfg(&format!("{undrained}\n{good}")).is_err(), "no dsb and sync first");
        let unsynced = "asm volatile(\"dsb\" : : : \"memory\");\nasm volatile(\".balign 32\\n\"";
        assert!(check_bridge_applycfg(&format!("{unsynced}\n{good}")).is_err(), "no L2 sync");
        let late = good.replace(
            "\t\tsocfpga_sdram_apply_static_cfg();\n\t\twritel(iswgrp_handoff[3], &sdr_ctrl->fpgaport_rst);",
            "\t\twritel(iswgrp_handoff[3], &sdr_ctrl->fpgaport_rst);\n\t\tsocfpga_sdram_apply_static_cfg();",
        );
        assert!(check_bridge_applycfg(&format!("{routine}\n{late}")).is_err(), "released first");
        let none = good.replace("\t\tsocfpga_sdram_apply_static_cfg();\n", "");
        assert!(check_bridge_applycfg(&format!("{routine}\n{none}")).is_err(), "never applied");
    }
}
