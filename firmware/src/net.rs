//! Network bring-up and the main loop: MAC, PHY and link, the smoltcp
//! interface with a static IPv4 address (ARP and ICMP echo come with it),
//! and the frame service on ports 7878 / 7879.

use core::fmt::Write;
use core::mem::MaybeUninit;
use core::net::Ipv4Addr;

use firmware::drivers::dwmac::{DmaArea, Dwmac};
use firmware::drivers::global_timer::GlobalTimer;
use firmware::drivers::mmio::Mmio;
use firmware::drivers::phy;
use firmware::service::{FrameService, SocketBuffers, FRAME_PORT, PERSISTENT_PORT};
use smoltcp::iface::{Config, Interface, SocketSet, SocketStorage};
use smoltcp::wire::{EthernetAddress, HardwareAddress, IpCidr, Ipv4Cidr};

use crate::boards::board;
use crate::log::Log;
use crate::render::Renderer;

/// TCP sockets of the frame service: half on each port, so while one client
/// of a port is served three more are accepted (and served interleaved)
/// instead of refused.
pub const SOCKETS: usize = 8;

/// The interface's address: `FW_IPV4` at build time, else the board's.
pub fn ipv4() -> Ipv4Cidr {
    let text = option_env!("FW_IPV4").unwrap_or(board::DEFAULT_IPV4);
    parse_cidr(text).or_else(|| parse_cidr(board::DEFAULT_IPV4)).unwrap_or(Ipv4Cidr::new(Ipv4Addr::UNSPECIFIED, 0))
}

/// The default gateway: `FW_GATEWAY` at build time, else the board's.
pub fn gateway() -> Option<Ipv4Addr> {
    option_env!("FW_GATEWAY").unwrap_or(board::DEFAULT_GATEWAY).parse().ok()
}

fn parse_cidr(s: &str) -> Option<Ipv4Cidr> {
    let (addr, len) = s.split_once('/')?;
    let len: u8 = len.parse().ok().filter(|l| *l <= 32)?;
    Some(Ipv4Cidr::new(addr.parse().ok()?, len))
}

/// The MAC's rings and buffers, in the non-cacheable `.dma` section (not
/// zeroed by the start-up code: `run` zeroes it).
#[unsafe(link_section = ".dma")]
static mut DMA: MaybeUninit<DmaArea> = MaybeUninit::uninit();

/// Bring the network up and serve forever. Returns only if the MAC or the
/// PHY cannot be brought up (the caller reports and halts).
pub fn run(timer: &'static GlobalTimer, rows: &mut Renderer) -> Result<core::convert::Infallible, &'static str> {
    static mut SOCKET_BUFFERS: [SocketBuffers; SOCKETS] = [const { SocketBuffers::new() }; SOCKETS];
    static mut SOCKET_STORAGE: [SocketStorage<'static>; SOCKETS] = [SocketStorage::EMPTY; SOCKETS];
    let mut log = Log;

    // SAFETY: `run` is called once, from kmain on core 0; nothing else names
    // these statics, so each `&mut` is the only reference for the rest of
    // the program. DMA is zeroed before it is viewed as a `DmaArea` (all
    // bytes zero is a valid `DmaArea`).
    let (dma, socket_buffers, socket_storage) = unsafe {
        let dma = &mut *(&raw mut DMA);
        core::ptr::write_bytes(dma.as_mut_ptr(), 0, 1);
        (dma.assume_init_mut(), &mut *(&raw mut SOCKET_BUFFERS), &mut *(&raw mut SOCKET_STORAGE))
    };

    // SAFETY: EMAC_BASE is the board's DesignWare MAC, mapped as device
    // memory; only this driver uses it.
    let regs = unsafe { Mmio::new(board::EMAC_BASE) };
    let mut mac = match Dwmac::new(regs, dma, board::MAC_ADDR, timer) {
        Ok(m) => m,
        Err(e) => {
            let _ = writeln!(log, "eth: {e}");
            return Err("MAC bring-up failed");
        }
    };
    let _ = writeln!(
        log,
        "eth: DWMAC at {:#010x}, version {:#06x}, {:?} descriptors",
        board::EMAC_BASE,
        mac.version() & 0xffff,
        mac.format()
    );

    let link = {
        let mut mdio = mac.mdio(timer);
        let phy = match phy::scan(&mut mdio) {
            Ok(p) => p,
            Err(e) => {
                let _ = writeln!(log, "phy: {e}");
                return Err("no PHY");
            }
        };
        let _ = writeln!(log, "phy: {phy}{}", if phy.is_ksz9021() { " (KSZ9021)" } else { "" });
        if let Err(e) = phy::configure(&mut mdio, phy, &board::PHY, timer) {
            let _ = writeln!(log, "phy: {e}");
            return Err("PHY set-up failed");
        }
        let _ = writeln!(log, "phy: waiting for link (at most {} s)", board::LINK_TIMEOUT_US / 1_000_000);
        match phy::wait_link(&mut mdio, phy, timer, board::LINK_TIMEOUT_US) {
            Ok(link) => link,
            Err(e) => {
                let _ = writeln!(log, "phy: {e}");
                return Err("no link");
            }
        }
    };
    mac.set_link(link);
    let _ = writeln!(log, "link up: {link}");

    let mut config = Config::new(HardwareAddress::Ethernet(EthernetAddress(board::MAC_ADDR)));
    config.random_seed = timer.ticks();
    let mut iface = Interface::new(config, &mut mac, timer.instant());
    let cidr = ipv4();
    iface.update_ip_addrs(|addrs| {
        let _ = addrs.push(IpCidr::Ipv4(cidr));
    });
    let gw = gateway();
    if let Some(gw) = gw {
        if iface.routes_mut().add_default_ipv4_route(gw).is_err() {
            let _ = writeln!(log, "net: no room for the default route");
        }
    }
    let mut sockets = SocketSet::new(&mut socket_storage[..]);
    let mut service = FrameService::<SOCKETS>::new(&mut sockets, socket_buffers);
    let _ = writeln!(
        log,
        "net: {cidr} via {}, MAC {}, listening on TCP {FRAME_PORT} and {PERSISTENT_PORT} ({SOCKETS} sockets)",
        gw.unwrap_or(Ipv4Addr::UNSPECIFIED),
        EthernetAddress(board::MAC_ADDR),
    );

    loop {
        let now = timer.instant();
        iface.poll(now, &mut mac, &mut sockets);
        service.poll(now, &mut sockets, rows, &mut log);
        rows.report(&mut log);
    }
}
