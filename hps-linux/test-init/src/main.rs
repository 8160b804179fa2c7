//! PID 1 of the ARM Linux that `cargo xtask linux-test` boots (Debian's
//! armmp kernel in QEMU's `virt` machine) to run hps-linux on a real
//! kernel. The test's initramfs holds this, hps-linux and the modules of
//! the virtio network card, nothing else, so this does what a
//! distribution's init and network scripts would:
//!
//! 1. mounts /proc, /sys and /dev (devtmpfs: the kernel mounts it itself
//!    only on a disk root, not on an initramfs);
//! 2. loads the modules `/modules/order` names, one per line, in that order
//!    (`finit_module`; the armmp kernel builds virtio-pci and virtio-net as
//!    modules);
//! 3. gives `eth0` the address in `/network` (`10.0.2.15/24`, the guest's
//!    address on QEMU's user network) and brings it and `lo` up;
//! 4. becomes the command in `/command`, one argument per line.
//!
//! Each step is said on the console. A failed step ends init: the kernel
//! panics (`panic=-1`) and QEMU, run with `-no-reboot`, exits, so the test
//! sees the failure at once instead of waiting for a frame.

use std::ffi::CString;
use std::fs::File;
use std::io;
use std::net::Ipv4Addr;
use std::os::fd::AsRawFd;
use std::os::unix::process::CommandExt;
use std::process::Command;
use std::time::{Duration, Instant};

/// How long `eth0` may take to appear after its module loads.
const LINK_WAIT: Duration = Duration::from_secs(10);

fn main() {
    println!("init: hps-linux-test-init {}", env!("CARGO_PKG_VERSION"));
    let error = match boot() {
        Ok(command) => {
            println!("init: exec {}", command.join(" "));
            let Some((program, args)) = command.split_first() else {
                unreachable!("boot checks the command is not empty")
            };
            // `exec` returns only on failure.
            let e = Command::new(program).args(args).exec();
            format!("exec {program}: {e}")
        }
        Err(e) => e,
    };
    println!("init: FAILED: {error}");
    std::process::exit(1);
}

/// Steps 1 to 3; the command of step 4.
fn boot() -> Result<Vec<String>, String> {
    for (source, target, fstype) in
        [("proc", "/proc", "proc"), ("sysfs", "/sys", "sysfs"), ("devtmpfs", "/dev", "devtmpfs")]
    {
        mount(source, target, fstype).map_err(|e| format!("mount {fstype} on {target}: {e}"))?;
    }
    println!("init: mounted /proc, /sys, /dev");
    let order = read("/modules/order")?;
    for name in order.lines().map(str::trim).filter(|l| !l.is_empty()) {
        load_module(&format!("/modules/{name}"))?;
    }
    println!("init: loaded {}", order.split_whitespace().collect::<Vec<_>>().join(", "));
    let network = read("/network")?;
    let (address, prefix) = parse_cidr(network.trim())?;
    configure("lo", Ipv4Addr::LOCALHOST, 8)?;
    wait_for("eth0")?;
    configure("eth0", address, prefix)?;
    println!("init: eth0 {address}/{prefix} up, lo up");
    let command: Vec<String> =
        read("/command")?.lines().map(str::trim).filter(|l| !l.is_empty()).map(String::from).collect();
    if command.is_empty() {
        return Err("/command is empty".into());
    }
    Ok(command)
}

fn read(path: &str) -> Result<String, String> {
    std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))
}

fn mount(source: &str, target: &str, fstype: &str) -> io::Result<()> {
    let (source, target, fstype) = (c(source)?, c(target)?, c(fstype)?);
    // SAFETY: three NUL-terminated strings that outlive the call, no data.
    let rc = unsafe { libc::mount(source.as_ptr(), target.as_ptr(), fstype.as_ptr(), 0, std::ptr::null()) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

fn c(s: &str) -> io::Result<CString> {
    CString::new(s).map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "NUL in a path"))
}

/// `finit_module(2)` the module at `path`; one already loaded is fine.
fn load_module(path: &str) -> Result<(), String> {
    let file = File::open(path).map_err(|e| format!("{path}: {e}"))?;
    let no_params = c("").map_err(|e| e.to_string())?;
    // SAFETY: an open descriptor, a NUL-terminated (empty) parameter string
    // that outlives the call, no flags.
    let rc = unsafe { libc::syscall(libc::SYS_finit_module, file.as_raw_fd(), no_params.as_ptr(), 0) };
    let error = io::Error::last_os_error();
    if rc == 0 || error.raw_os_error() == Some(libc::EEXIST) {
        Ok(())
    } else {
        Err(format!("load {path}: {error}"))
    }
}

/// `10.0.2.15/24`.
fn parse_cidr(text: &str) -> Result<(Ipv4Addr, u8), String> {
    let bad = || format!("/network: {text:?} is not ADDRESS/PREFIX");
    let (address, prefix) = text.split_once('/').ok_or_else(bad)?;
    let address: Ipv4Addr = address.parse().map_err(|_| bad())?;
    let prefix: u8 = prefix.parse().ok().filter(|p| *p <= 32).ok_or_else(bad)?;
    Ok((address, prefix))
}

/// An `ifreq` for `name` (netdevice(7)).
fn ifreq(name: &str) -> Result<libc::ifreq, String> {
    // SAFETY: `ifreq` is plain old data (a name and a union of plain
    // structures): all zeroes is a valid value.
    let mut request: libc::ifreq = unsafe { std::mem::zeroed() };
    if name.len() >= request.ifr_name.len() {
        return Err(format!("interface name {name:?} too long"));
    }
    for (to, from) in request.ifr_name.iter_mut().zip(name.bytes()) {
        *to = from as libc::c_char;
    }
    Ok(request)
}

/// An `AF_INET` socket address holding `address` (port 0).
fn sockaddr(address: Ipv4Addr) -> libc::sockaddr {
    let inet = libc::sockaddr_in {
        sin_family: libc::AF_INET as libc::sa_family_t,
        sin_port: 0,
        sin_addr: libc::in_addr { s_addr: u32::from_ne_bytes(address.octets()) },
        sin_zero: [0; 8],
    };
    // SAFETY: `sockaddr_in` and `sockaddr` are both 16 bytes, and the
    // kernel reads an `AF_INET` address in a `sockaddr` as a `sockaddr_in`
    // (netdevice(7), SIOCSIFADDR).
    unsafe { std::mem::transmute::<libc::sockaddr_in, libc::sockaddr>(inet) }
}

/// A datagram socket for the interface ioctls.
fn control_socket() -> Result<File, String> {
    // SAFETY: plain socket(2) call; the descriptor is owned below.
    let fd = unsafe { libc::socket(libc::AF_INET, libc::SOCK_DGRAM, 0) };
    if fd < 0 {
        return Err(format!("socket: {}", io::Error::last_os_error()));
    }
    // SAFETY: `fd` is a new descriptor nothing else owns.
    Ok(unsafe { <File as std::os::fd::FromRawFd>::from_raw_fd(fd) })
}

fn ioctl(socket: &File, request: libc::Ioctl, what: &str, name: &str, req: &mut libc::ifreq) -> Result<(), String> {
    // SAFETY: an interface ioctl on a socket with a valid `ifreq` the
    // kernel reads and writes only within.
    let rc = unsafe { libc::ioctl(socket.as_raw_fd(), request, req as *mut libc::ifreq) };
    if rc < 0 {
        return Err(format!("{what} {name}: {}", io::Error::last_os_error()));
    }
    Ok(())
}

/// Wait up to [`LINK_WAIT`] for interface `name` to exist.
fn wait_for(name: &str) -> Result<(), String> {
    let socket = control_socket()?;
    let started = Instant::now();
    loop {
        let mut req = ifreq(name)?;
        match ioctl(&socket, libc::SIOCGIFFLAGS, "flags of", name, &mut req) {
            Ok(()) => return Ok(()),
            Err(e) if started.elapsed() > LINK_WAIT => {
                let have = std::fs::read_dir("/sys/class/net")
                    .map(|d| d.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect::<Vec<_>>())
                    .unwrap_or_default();
                return Err(format!("{e} after {LINK_WAIT:?}; interfaces: {have:?}"));
            }
            Err(_) => std::thread::sleep(Duration::from_millis(100)),
        }
    }
}

/// Address, netmask and up for interface `name`.
fn configure(name: &str, address: Ipv4Addr, prefix: u8) -> Result<(), String> {
    let socket = control_socket()?;
    let mut req = ifreq(name)?;
    req.ifr_ifru.ifru_addr = sockaddr(address);
    ioctl(&socket, libc::SIOCSIFADDR, "address of", name, &mut req)?;
    let mask = u32::MAX.checked_shl(32 - u32::from(prefix)).unwrap_or(0);
    let mut req = ifreq(name)?;
    req.ifr_ifru.ifru_netmask = sockaddr(Ipv4Addr::from(mask));
    ioctl(&socket, libc::SIOCSIFNETMASK, "netmask of", name, &mut req)?;
    let mut req = ifreq(name)?;
    ioctl(&socket, libc::SIOCGIFFLAGS, "flags of", name, &mut req)?;
    // SAFETY: SIOCGIFFLAGS just filled the union's flags member.
    let flags = unsafe { req.ifr_ifru.ifru_flags };
    req.ifr_ifru.ifru_flags = flags | (libc::IFF_UP | libc::IFF_RUNNING) as libc::c_short;
    ioctl(&socket, libc::SIOCSIFFLAGS, "bring up", name, &mut req)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_network_file_reads_as_address_and_prefix() {
        assert_eq!(parse_cidr("10.0.2.15/24"), Ok((Ipv4Addr::new(10, 0, 2, 15), 24)));
        assert!(parse_cidr("10.0.2.15").is_err());
        assert!(parse_cidr("10.0.2.15/33").is_err());
        assert!(parse_cidr("ten/24").is_err());
    }

    #[test]
    fn a_socket_address_carries_the_address_in_network_order() {
        let raw = sockaddr(Ipv4Addr::new(10, 0, 2, 15));
        assert_eq!(raw.sa_family, libc::AF_INET as libc::sa_family_t);
        // sa_data: port (2 bytes), then the address as sent on the wire.
        let data: Vec<u8> = raw.sa_data.iter().map(|b| *b as u8).collect();
        assert_eq!(&data[2..6], &[10, 0, 2, 15]);
    }

    #[test]
    fn an_interface_request_names_its_interface() {
        let req = ifreq("eth0").unwrap();
        assert_eq!(req.ifr_name[..5].iter().map(|b| *b as u8).collect::<Vec<_>>(), b"eth0\0");
        assert!(ifreq("a-name-much-too-long").is_err());
    }
}
