//! What is checked before the first access to the bridge, so that the
//! program says what is wrong instead of hanging or dying of a bus error:
//! the FPGA is configured, the lightweight bridge is out of reset, the
//! window maps, and the ray tracer answers with a register map this
//! program knows ([`open`]).
//!
//! Where the kernel says (the FPGA manager and bridge classes in sysfs,
//! Linux `drivers/fpga/fpga-mgr.c` and `fpga-bridge.c`), that is asked
//! first; else the HPS's own registers through /dev/mem: the FPGA manager's
//! `stat.mode` and the reset manager's `brgmodrst` (soc's
//! [`FpgaStat`] and [`BrgModRst`], the firmware's definitions). When
//! neither can be read (UIO as a user on a kernel without those classes)
//! the check says so and goes on: the ID register is then the only check.

use std::fmt;
use std::path::{Path, PathBuf};

use hal_avalon::map::{Csr, ID_MAGIC, ID_VERSION, LW_BRIDGE_BASE};
use hal_avalon::RegisterPort;
use soc::cyclone_v::{BrgModRst, FpgaMode, FpgaStat, FPGAMGR_BASE, FPGAPORTRST, FPGAPORTRST_RELEASED, RSTMGR_BASE};

use crate::window::{MappedPort, OpenError, Window};

/// Where the checks look: the system's paths, or a test's stand-ins.
#[derive(Clone, Debug)]
pub struct System {
    /// sysfs (`/sys`).
    pub sysfs: PathBuf,
    /// Device nodes (`/dev`): the UIO devices.
    pub dev: PathBuf,
    /// Physical memory (`/dev/mem`).
    pub dev_mem: PathBuf,
}

impl System {
    /// The running system's paths.
    pub fn real() -> System {
        System { sysfs: "/sys".into(), dev: "/dev".into(), dev_mem: "/dev/mem".into() }
    }

    fn uio_class(&self) -> PathBuf {
        self.sysfs.join("class/uio")
    }
}

/// How the bridge window is mapped.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Access {
    /// A UIO device: the given one, or the one whose map 0 is the bridge.
    Uio(Option<PathBuf>),
    /// /dev/mem at the bridge's physical address.
    DevMem,
}

/// What a check found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Finding {
    /// As needed; how it was seen.
    Good(String),
    /// Not as needed; what was seen.
    Bad(String),
    /// Could not be seen; why.
    Unknown(String),
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Finding::Good(s) | Finding::Bad(s) => f.write_str(s),
            Finding::Unknown(s) => write!(f, "not checked ({s})"),
        }
    }
}

/// Why the program will not use the accelerator.
#[derive(Debug)]
pub enum Refusal {
    /// The window could not be mapped.
    Open(OpenError),
    /// The FPGA holds no configuration.
    FpgaNotConfigured(String),
    /// The lightweight bridge is held in reset.
    BridgeInReset(String),
    /// Something answers that is not the ray tracer (or nothing: all ones).
    NotTheRayTracer {
        /// What the ID register read.
        id: u32,
    },
    /// A ray tracer with a register map newer than this program knows.
    UnknownRegisterMap {
        /// The version it reports.
        version: u16,
    },
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::Open(e) => write!(f, "{e}"),
            Refusal::FpgaNotConfigured(seen) => write!(
                f,
                "the FPGA is not configured ({seen}): load the ray tracer's image first (U-Boot `fpga load`, or the \
                 FPGA manager from Linux; docs/linux.md), with MSEL (SW10) set for it"
            ),
            Refusal::BridgeInReset(seen) => write!(
                f,
                "the lightweight HPS-to-FPGA bridge is held in reset ({seen}): release it before starting (U-Boot \
                 `bridge enable` after `fpga load`, or a device-tree overlay that loads the image through an \
                 fpga-region listing the bridge; docs/linux.md)"
            ),
            Refusal::NotTheRayTracer { id: 0xFFFF_FFFF } => write!(
                f,
                "nothing answers at the lightweight bridge (ID reads 0xffffffff): the FPGA image has no ray tracer, or \
                 the bridge is not enabled in the L3 remap (U-Boot `bridge enable`)"
            ),
            Refusal::NotTheRayTracer { id } => write!(
                f,
                "the FPGA image is not the ray tracer: ID reads {id:#010x}, expected {:#06x} in bits 31:16 (a wrong \
                 .rbf on the card or loaded by Linux)",
                ID_MAGIC
            ),
            Refusal::UnknownRegisterMap { version } => write!(
                f,
                "the FPGA image's register map is version {version}, newer than this program's {ID_VERSION}: build \
                 the program from the same commit as the image"
            ),
        }
    }
}

impl std::error::Error for Refusal {}

impl From<OpenError> for Refusal {
    fn from(e: OpenError) -> Refusal {
        Refusal::Open(e)
    }
}

/// What the checks saw, for the log and `/status`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Report {
    /// The FPGA's configuration.
    pub fpga: Finding,
    /// The lightweight bridge's reset.
    pub bridge: Finding,
    /// The window mapped.
    pub window: String,
    /// The register-map version the ray tracer reports.
    pub register_map: u16,
    /// BUILD_ID (0: none recorded).
    pub build_id: u32,
}

/// Whether the FPGA is configured: the FPGA manager class's `state`
/// (`operating`), else the FPGA manager's `stat.mode` (user mode).
pub fn fpga(sys: &System) -> Finding {
    let class = sys.sysfs.join("class/fpga_manager");
    if let Some((name, state)) = first_entry(&class, "state") {
        return match state.as_str() {
            "operating" => Finding::Good(format!("{name}: operating")),
            _ => Finding::Bad(format!("{name}: {state}")),
        };
    }
    match Window::dev_mem(&sys.dev_mem, FPGAMGR_BASE as u64, 4096) {
        Ok(w) => {
            let stat = FpgaStat::new_with_raw_value(w.read_word(0).unwrap_or(0));
            match stat.mode() {
                Ok(FpgaMode::User) => Finding::Good("FPGA manager: user mode".into()),
                Ok(mode) => Finding::Bad(format!("FPGA manager: {mode:?}")),
                Err(raw) => Finding::Bad(format!("FPGA manager: mode {raw}")),
            }
        }
        Err(e) => Finding::Unknown(format!("no FPGA manager in sysfs, and {e}")),
    }
}

/// Whether the lightweight bridge is out of reset: the FPGA bridge class
/// entry named `lwhps2fpga` (`state`: `enabled`), else `brgmodrst`.
pub fn bridge(sys: &System) -> Finding {
    let class = sys.sysfs.join("class/fpga_bridge");
    let named = entries(&class)
        .into_iter()
        .find(|e| read_trimmed(&class.join(e).join("name")).as_deref() == Some("lwhps2fpga"));
    if let Some(entry) = named {
        let state = read_trimmed(&class.join(&entry).join("state")).unwrap_or_default();
        return match state.as_str() {
            "enabled" => Finding::Good(format!("{entry} (lwhps2fpga): enabled")),
            _ => Finding::Bad(format!("{entry} (lwhps2fpga): {state}")),
        };
    }
    match Window::dev_mem(&sys.dev_mem, RSTMGR_BASE as u64, 4096) {
        Ok(w) => {
            let raw = w.read_word(0x1c).unwrap_or(0);
            if BrgModRst::new_with_raw_value(raw).lwhps2fpga() {
                Finding::Bad(format!("brgmodrst {raw:#x}: lwhps2fpga in reset"))
            } else {
                Finding::Good(format!("brgmodrst {raw:#x}: lwhps2fpga out of reset"))
            }
        }
        Err(e) => Finding::Unknown(format!("no lwhps2fpga bridge in sysfs, and {e}")),
    }
}

/// Whether the SDRAM controller's FPGA ports the frame DMA writes through
/// are out of reset: `fpgaportrst` through /dev/mem has every bit of
/// [`FPGAPORTRST_RELEASED`] set. Only the boot loader can release them
/// (the controller takes the change only while SDRAM is idle); a frame DMA
/// into a port held in reset never finishes, so frame mode is not tried
/// then. Unknown without /dev/mem (the self-test's frame half then finds
/// out).
pub fn sdram_ports(sys: &System) -> Finding {
    let page = FPGAPORTRST & !0xfff;
    match Window::dev_mem(&sys.dev_mem, page as u64, 4096) {
        Ok(w) => {
            let Some(raw) = w.read_word(FPGAPORTRST - page) else {
                return Finding::Unknown("fpgaportrst lies outside the page mapped".into());
            };
            if raw & FPGAPORTRST_RELEASED == FPGAPORTRST_RELEASED {
                Finding::Good(format!("fpgaportrst {raw:#x}: the frame DMA's ports run"))
            } else {
                Finding::Bad(format!(
                    "fpgaportrst {raw:#x}: the frame DMA's ports ({FPGAPORTRST_RELEASED:#x}) are held in reset; the \
                     boot loader must release them (docs/linux.md, \"Frame mode\")"
                ))
            }
        }
        Err(e) => Finding::Unknown(format!("fpgaportrst unread: {e}")),
    }
}

/// Check, map and probe: the accelerator's registers, ready for the driver,
/// and what was seen; or why not.
pub fn open(sys: &System, access: &Access) -> Result<(MappedPort, Report), Refusal> {
    let fpga = fpga(sys);
    if let Finding::Bad(seen) = &fpga {
        return Err(Refusal::FpgaNotConfigured(seen.clone()));
    }
    let bridge = bridge(sys);
    if let Finding::Bad(seen) = &bridge {
        return Err(Refusal::BridgeInReset(seen.clone()));
    }
    let window = match access {
        Access::DevMem => Window::lightweight_bridge(&sys.dev_mem)?,
        Access::Uio(device) => {
            let device = match device {
                Some(d) => d.clone(),
                None => Window::find_uio(&sys.uio_class(), &sys.dev, LW_BRIDGE_BASE as u64)?,
            };
            Window::uio(&device, &sys.uio_class(), LW_BRIDGE_BASE as u64)?
        }
    };
    let what = window.describe().to_string();
    let mut port = window.into_port()?;
    let id = port.read(Csr::Id);
    if id >> 16 != u32::from(ID_MAGIC) || id & 0xffff == 0 {
        return Err(Refusal::NotTheRayTracer { id });
    }
    let version = (id & 0xffff) as u16;
    if version > ID_VERSION {
        return Err(Refusal::UnknownRegisterMap { version });
    }
    let build_id = if version >= 3 { port.read(Csr::BuildId) } else { 0 };
    Ok((port, Report { fpga, bridge, window: what, register_map: version, build_id }))
}

/// The entries of a sysfs class directory, sorted.
fn entries(class: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(class)
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).collect())
        .unwrap_or_default();
    names.sort();
    names
}

/// The first entry of a class directory that has `file`, and its text.
fn first_entry(class: &Path, file: &str) -> Option<(String, String)> {
    entries(class).into_iter().find_map(|e| read_trimmed(&class.join(&e).join(file)).map(|t| (e, t)))
}

fn read_trimmed(path: &Path) -> Option<String> {
    std::fs::read_to_string(path).ok().map(|s| s.trim().to_string())
}
