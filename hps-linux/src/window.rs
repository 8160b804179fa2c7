//! The lightweight bridge's window mapped into the process, two ways, and
//! the accelerator's registers on it ([`MappedPort`]): the same hal-avalon
//! driver code as on bare metal ([`MmioPort`]), on either mapping.
//!
//! * **UIO** ([`Window::uio`]): a device-tree node with `compatible =
//!   "generic-uio"` and `reg = <0xff200000 0x200000>` makes the kernel's
//!   `uio_pdrv_genirq` driver (given `uio_pdrv_genirq.of_id=generic-uio`)
//!   create `/dev/uioN`; map `i` of it is mapped at file offset `i` pages,
//!   and `/sys/class/uio/uioN/maps/mapI/{addr,size}` say where it is and how
//!   big (Linux `Documentation/driver-api/uio-howto.rst`, "How to use
//!   mmap()" and "Further information: sysfs"). No root needed beyond the
//!   device's permissions.
//! * **/dev/mem** ([`Window::dev_mem`]): the bridge's physical address as
//!   the file offset (root, no device-tree change).
//!
//! Either way the kernel maps physical memory outside RAM non-cached:
//! `pgprot_noncached` (Linux `drivers/char/mem.c` `phys_mem_access_prot`
//! for /dev/mem, `drivers/uio/uio.c` `uio_mmap_physical` for UIO), which on
//! ARMv7 is the Strongly-ordered type (`arch/arm/include/asm/
//! pgtable-2level.h`, `L_PTE_MT_UNCACHED`): every access completes before
//! the next, as the firmware's own table maps the window (hal-avalon
//! `mmio`, "Ordering").
//!
//! Raw word access ([`Window::read_word`], [`Window::write_word`]) serves
//! the register-semantics suite and the managers' registers; the driver
//! goes through [`MappedPort`].

use std::fmt;
use std::fs::{File, OpenOptions};
use std::io;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use hal_avalon::map::{Csr, CSR_OFFSET, LINE_BUFFER_OFFSET, LINE_WORDS, LW_BRIDGE_BASE, LW_BRIDGE_SIZE};
use hal_avalon::{MmioPort, RegisterPort};
use memmap2::{MmapOptions, MmapRaw};

/// Where UIO devices are described.
pub const UIO_CLASS: &str = "/sys/class/uio";

/// Bytes of the window the accelerator uses: its CSR block and line buffer.
pub const ACCELERATOR_BYTES: usize = CSR_OFFSET + LINE_BUFFER_OFFSET + 4 * LINE_WORDS;

/// Why a window could not be mapped: each names the cause and what to do.
#[derive(Debug)]
pub enum OpenError {
    /// The device exists but this user may not open it.
    Permission {
        /// The device.
        path: PathBuf,
    },
    /// No such device.
    Missing {
        /// The device.
        path: PathBuf,
    },
    /// No UIO device maps the bridge window.
    NoUioForBridge {
        /// Where UIO devices were looked for.
        class: PathBuf,
        /// The physical address looked for.
        phys: u64,
    },
    /// The UIO device named maps another physical window than the bridge.
    NotTheBridge {
        /// The device.
        path: PathBuf,
        /// Where its map 0 is.
        addr: u64,
        /// Where the bridge is.
        phys: u64,
    },
    /// The mapping is smaller than the accelerator's registers.
    TooSmall {
        /// The device.
        path: PathBuf,
        /// Its size.
        size: usize,
    },
    /// Anything else: the path and the system's error.
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        error: io::Error,
    },
}

impl fmt::Display for OpenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OpenError::Permission { path } if path.to_string_lossy().contains("uio") => {
                write!(
                    f,
                    "permission denied opening {}: give this user the device (a udev rule, docs/linux.md) or run as root",
                    path.display()
                )
            }
            OpenError::Permission { path } => write!(
                f,
                "permission denied opening {}: mapping the bridge through /dev/mem needs root (sudo), or use UIO (--accelerator uio, docs/linux.md)",
                path.display()
            ),
            OpenError::Missing { path } => write!(f, "{} does not exist", path.display()),
            OpenError::NoUioForBridge { class, phys } => write!(
                f,
                "no UIO device maps the lightweight bridge at {phys:#x} ({} lists none): add the generic-uio node \
                 and uio_pdrv_genirq.of_id=generic-uio to the kernel command line (docs/linux.md), or use \
                 --accelerator devmem as root",
                class.display()
            ),
            OpenError::NotTheBridge { path, addr, phys } => write!(
                f,
                "{} maps {addr:#x}, not the lightweight bridge at {phys:#x}: its registers are another device's; \
                 name the UIO device of the generic-uio node, or leave the device out to have it found (docs/linux.md)",
                path.display()
            ),
            OpenError::TooSmall { path, size } => write!(
                f,
                "{} maps {size:#x} bytes, fewer than the accelerator's {ACCELERATOR_BYTES:#x}: the device-tree node's \
                 reg is wrong (docs/linux.md)",
                path.display()
            ),
            OpenError::Io { path, error } => write!(f, "{}: {error}", path.display()),
        }
    }
}

impl std::error::Error for OpenError {}

fn classify(path: &Path, error: io::Error) -> OpenError {
    let path = path.to_path_buf();
    match error.kind() {
        io::ErrorKind::PermissionDenied => OpenError::Permission { path },
        io::ErrorKind::NotFound => OpenError::Missing { path },
        _ => OpenError::Io { path, error },
    }
}

/// A physical window mapped into the process (unmapped on drop).
pub struct Window {
    map: MmapRaw,
    /// What was mapped, for messages: `/dev/uio0 (map 0)`, `/dev/mem at 0xff200000`.
    what: String,
}

impl fmt::Debug for Window {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Window({}, {:#x} bytes)", self.what, self.map.len())
    }
}

impl Window {
    /// `len` bytes at physical address `phys` through `dev_mem` (the
    /// system's `/dev/mem`; tests pass a file standing in for it), opened
    /// `O_SYNC` (non-cached even where the range is RAM).
    pub fn dev_mem(dev_mem: &Path, phys: u64, len: usize) -> Result<Window, OpenError> {
        let file = open_rw(dev_mem, libc::O_SYNC)?;
        // A regular file standing in for /dev/mem (tests) must hold the
        // window: a page mapped past its end faults on the first access.
        if let Ok(meta) = file.metadata() {
            if meta.is_file() && phys.saturating_add(len as u64) > meta.len() {
                let error = io::Error::new(io::ErrorKind::UnexpectedEof, format!("ends before {phys:#x} + {len:#x}"));
                return Err(OpenError::Io { path: dev_mem.to_path_buf(), error });
            }
        }
        let map = MmapOptions::new().offset(phys).len(len).map_raw(&file).map_err(|e| classify(dev_mem, e))?;
        Ok(Window { map, what: format!("{} at {phys:#x}", dev_mem.display()) })
    }

    /// Map 0 of the UIO device `device` (`/dev/uioN`), as big as its sysfs
    /// entry under `class` (`/sys/class/uio`) says, if it starts at
    /// physical address `phys` (a device named by hand may be another
    /// device's registers: nothing is written to those).
    pub fn uio(device: &Path, class: &Path, phys: u64) -> Result<Window, OpenError> {
        let name = device.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let addr = read_hex(&class.join(&name).join("maps/map0/addr"))?;
        if addr != phys {
            return Err(OpenError::NotTheBridge { path: device.to_path_buf(), addr, phys });
        }
        let size_file = class.join(&name).join("maps/map0/size");
        let size = read_hex(&size_file)?;
        let size = usize::try_from(size).map_err(|_| OpenError::TooSmall { path: device.to_path_buf(), size: 0 })?;
        if size < ACCELERATOR_BYTES {
            return Err(OpenError::TooSmall { path: device.to_path_buf(), size });
        }
        let file = open_rw(device, 0)?;
        // Map 0: file offset 0 (map N would be at N pages).
        let map = MmapOptions::new().offset(0).len(size).map_raw(&file).map_err(|e| classify(device, e))?;
        Ok(Window { map, what: format!("{} (map 0)", device.display()) })
    }

    /// The UIO device whose map 0 starts at `phys` (the lightweight
    /// bridge: [`LW_BRIDGE_BASE`]): `/dev/uioN` under `dev` for the first
    /// `uioN` under `class` whose `maps/map0/addr` is `phys`.
    pub fn find_uio(class: &Path, dev: &Path, phys: u64) -> Result<PathBuf, OpenError> {
        let missing = || OpenError::NoUioForBridge { class: class.to_path_buf(), phys };
        let entries = std::fs::read_dir(class).map_err(|_| missing())?;
        let mut names: Vec<String> =
            entries.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        names
            .into_iter()
            .find(|n| read_hex(&class.join(n).join("maps/map0/addr")).is_ok_and(|a| a == phys))
            .map(|n| dev.join(n))
            .ok_or_else(missing)
    }

    /// The bridge window through /dev/mem: [`LW_BRIDGE_SIZE`] bytes at
    /// [`LW_BRIDGE_BASE`].
    pub fn lightweight_bridge(dev_mem: &Path) -> Result<Window, OpenError> {
        Window::dev_mem(dev_mem, LW_BRIDGE_BASE as u64, LW_BRIDGE_SIZE)
    }

    /// Bytes mapped.
    pub fn len(&self) -> usize {
        self.map.len()
    }

    /// Whether nothing is mapped (never, for a window that opened).
    pub fn is_empty(&self) -> bool {
        self.map.len() == 0
    }

    /// What was mapped, for messages.
    pub fn describe(&self) -> &str {
        &self.what
    }

    /// The 32-bit word at byte `offset` (its two low bits select nothing,
    /// as on the bus: the word holding it is read); `None` past the end.
    pub fn read_word(&self, offset: usize) -> Option<u32> {
        let at = self.word_ptr(offset)?;
        // SAFETY: `word_ptr` checked the word lies in the mapping, which
        // lives as long as `self`, and is 4-byte aligned (the mapping is
        // page aligned); a volatile read of device memory.
        Some(unsafe { at.read_volatile() })
    }

    /// Write the 32-bit word at byte `offset` (low bits as for
    /// [`read_word`](Self::read_word)); `false` past the end.
    pub fn write_word(&self, offset: usize, value: u32) -> bool {
        let Some(at) = self.word_ptr(offset) else { return false };
        // SAFETY: as in `read_word`.
        unsafe { at.write_volatile(value) };
        true
    }

    fn word_ptr(&self, offset: usize) -> Option<*mut u32> {
        let word = offset & !3;
        if word.checked_add(4)? > self.map.len() {
            return None;
        }
        // In bounds (checked above); the base is page aligned.
        Some(self.map.as_mut_ptr().wrapping_add(word).cast::<u32>())
    }

    /// The accelerator's registers in this window, at [`CSR_OFFSET`].
    pub fn into_port(self) -> Result<MappedPort, OpenError> {
        if self.map.len() < ACCELERATOR_BYTES {
            let size = self.map.len();
            return Err(OpenError::TooSmall { path: PathBuf::from(self.what), size });
        }
        let base = self.map.as_mut_ptr() as usize + CSR_OFFSET;
        // SAFETY: the mapping covers the whole register block (checked
        // above) from a page-aligned base; the `MmioPort` is a private field
        // of the `MappedPort` that owns the mapping, so it never outlives
        // it, and nothing else reaches the window from now on (the
        // `MappedPort` lends it to no one). The kernel maps it
        // Strongly-ordered and non-cached (module documentation).
        let port = unsafe { MmioPort::new(base) };
        Ok(MappedPort { port, window: self })
    }
}

fn open_rw(path: &Path, flags: i32) -> Result<File, OpenError> {
    OpenOptions::new().read(true).write(true).custom_flags(flags).open(path).map_err(|e| classify(path, e))
}

/// A sysfs number such as `0xff200000` (UIO prints `0x%p`-style hex).
fn read_hex(path: &Path) -> Result<u64, OpenError> {
    let text = std::fs::read_to_string(path).map_err(|e| classify(path, e))?;
    let t = text.trim();
    let digits = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")).unwrap_or(t);
    u64::from_str_radix(digits, 16).map_err(|_| OpenError::Io {
        path: path.to_path_buf(),
        error: io::Error::new(io::ErrorKind::InvalidData, format!("not a hex number: {t:?}")),
    })
}

/// The accelerator's registers on a mapped window: hal-avalon's
/// [`MmioPort`], owning the mapping it points into.
pub struct MappedPort {
    port: MmioPort,
    window: Window,
}

impl fmt::Debug for MappedPort {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "MappedPort({:?})", self.window)
    }
}

impl RegisterPort for MappedPort {
    fn read(&mut self, csr: Csr) -> u32 {
        self.port.read(csr)
    }

    fn write(&mut self, csr: Csr, value: u32) {
        self.port.write(csr, value)
    }

    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        self.port.read_line(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sysfs_numbers_parse_as_uio_prints_them() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("addr");
        for (text, want) in [("0xff200000\n", 0xff20_0000u64), ("0x00200000", 0x20_0000), ("1000\n", 0x1000)] {
            std::fs::write(&p, text).unwrap();
            assert_eq!(read_hex(&p).unwrap(), want, "{text:?}");
        }
        std::fs::write(&p, "banana").unwrap();
        assert!(read_hex(&p).is_err());
    }

    #[test]
    fn messages_say_what_to_do() {
        let root = OpenError::Permission { path: "/dev/mem".into() };
        assert!(root.to_string().contains("needs root"), "{root}");
        let uio = OpenError::Permission { path: "/dev/uio0".into() };
        assert!(uio.to_string().contains("udev rule"), "{uio}");
        let none = OpenError::NoUioForBridge { class: "/sys/class/uio".into(), phys: 0xff20_0000 };
        assert!(none.to_string().contains("uio_pdrv_genirq.of_id=generic-uio"), "{none}");
    }
}
