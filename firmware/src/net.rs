//! Network bring-up and the main loop: MAC and PHY, the smoltcp interface
//! with its IPv4 address from the settings, DHCP or a link-local claim
//! (`rt_services::address`; ARP and ICMP echo come with smoltcp), the frame
//! service on the protocol's two ports, the network camera, the web page,
//! the link monitor and the log drain.

use core::cell::UnsafeCell;
use core::fmt::{self, Write};
use core::mem::MaybeUninit;
use core::net::Ipv4Addr;
use core::sync::atomic::{AtomicBool, Ordering};

use dwmac::phy::LinkMonitor;
use dwmac::regs::Regs;
use dwmac::{DmaArea, Dwmac, MulticastFilter};
use hal_avalon::RegisterPort;
use rt_services::address::assign::{Addressing, LinkNotes};
use rt_services::address::settings::{AddressMode, HostName, Settings};
use rt_services::camera::random::TimingPool;
use rt_services::camera::rtsp::{self, MAX_SESSIONS, RTSP_PORT, SERVER_RTP_PORT};
use rt_services::camera::sender::Camera;
use rt_services::camera::sender::{self, Multicast};
use rt_services::camera::service::{CameraBuffers, CameraService, GroupMembership, Snoop, Snooped, RTSP_SOCKETS};
use rt_services::frames::Quota;
use rt_services::mdns::responder::{Services, MDNS_GROUP};
use rt_services::mdns::service::{MdnsBuffers, MdnsService};
use rt_services::monitor::code::{hps_led, Code};
use rt_services::multicast::Membership;
use rt_services::seed::service::{FrameService, SocketBuffers};
use rt_services::snoop::{MacClashes, SynWatch};
use rt_services::web::service::{SocketBuffers as WebBuffers, WebService};
use rt_services::web::status::{BoardStatus, Health, Identity, Viewers};
use rt_services::web::WEB_PORT;
use rt_services::{FrameSource, FRAME_PORT, PERSISTENT_PORT};
use smoltcp::iface::{Config, Interface, SocketSet, SocketStorage};
use smoltcp::time::Instant;
use smoltcp::wire::{DhcpOption, EthernetAddress, HardwareAddress};
use soc::global_timer::{GlobalTimer, TimerDelay};
use static_cell::{ConstStaticCell, StaticCell};

use crate::cpu::Caches;
use crate::display::Display;
use crate::health::BootFacts;
use crate::limits::{FRAME_PORT_SOCKETS, RING_SLOTS, SEED_FRAMES, SOCKETS, WEB_FRAMES, WEB_SOCKETS, WEB_VIEWERS};
use crate::log::{self, Log};
use crate::platform::Board;
use crate::render::Frames;

/// Sockets of the network camera: RTSP listeners, the RTCP socket and the
/// multicast groups' RTCP socket (`CameraService::new` adds them all).
const CAMERA_SOCKETS: usize = RTSP_SOCKETS + 2;

/// The longest the main loop goes without looking after the address (DHCP,
/// the link-local claim) and the name (mDNS) when no frame for them came
/// and none of their timers is due (a lease's end shows at the next look).
const HOUSEKEEPING_US: u64 = 1_000_000;

/// How often the fault code and the HPS LED are looked at (the LED's
/// blinks are 200 ms lit, 300 ms dark: rt_services::monitor::code).
const INDICATORS_US: u64 = 100_000;

/// Where a code shows: the 7-segment text and the HPS LED's pattern.
fn shown_as(code: Code) -> &'static str {
    match code.number() {
        0 => "HPS LED: heartbeat",
        1 => "HPS LED: 1 blink, then a pause",
        2 => "7-segment \"Err  2\", HPS LED: 2 blinks",
        3 => "7-segment \"Err  3\", HPS LED: 3 blinks",
        4 => "7-segment \"Err  4\", HPS LED: 4 blinks",
        5 => "7-segment \"Err  5\", HPS LED: 5 blinks",
        6 => "7-segment \"Err  6\", HPS LED: 6 blinks",
        _ => "7-segment \"Err  7\", HPS LED: 7 blinks",
    }
}

/// Every socket: the seed server's, the camera's, the page's, the DHCP
/// client's and mDNS's.
const ALL_SOCKETS: usize = SOCKETS + CAMERA_SOCKETS + WEB_SOCKETS + 2;

/// Why the network did not start.
#[derive(Clone, Copy, Debug)]
pub enum NetError {
    /// The MAC or the PHY could not be brought up.
    Mac(dwmac::Error),
    /// The network's static memory was already handed out: `run` was
    /// called a second time.
    AlreadyRunning,
}

impl fmt::Display for NetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NetError::Mac(e) => write!(f, "Ethernet bring-up failed: {e}"),
            NetError::AlreadyRunning => f.write_str("the network is already running"),
        }
    }
}

impl core::error::Error for NetError {}

/// Where the camera's multicast streams go: `FW_MULTICAST` at build time
/// (`GROUP[:PORT[:TTL]]`, or `off`), else 239.255.42.1, port 5006, TTL 1
/// (an administratively scoped group, RFC 2365, kept on the board's link).
fn multicast_config() -> Option<Multicast> {
    parse_multicast(option_env!("FW_MULTICAST").unwrap_or("239.255.42.1:5006:1"))
}

fn parse_multicast(text: &str) -> Option<Multicast> {
    let mut parts = text.split(':');
    // The pool: MAX_SESSIONS addresses from GROUP on, all multicast.
    let last = |g: &Ipv4Addr| u32::from(*g).checked_add(MAX_SESSIONS as u32 - 1).map(Ipv4Addr::from);
    let group: Ipv4Addr = parts
        .next()?
        .parse()
        .ok()
        .filter(|g: &Ipv4Addr| g.is_multicast() && last(g).is_some_and(|l| l.is_multicast()))?;
    let base_port = parts.next().map_or(Some(5006), |p| p.parse().ok())?;
    let ttl = parts.next().map_or(Some(1), |t| t.parse().ok())?;
    Some(Multicast { group, base_port, ttl })
}

fn instant(timer: &GlobalTimer) -> Instant {
    Instant::from_micros(i64::try_from(timer.now_us()).unwrap_or(i64::MAX))
}

/// The MAC's rings and buffers, in the non-cacheable `.dma` section, which
/// the start-up code neither loads nor zeroes: [`take_dma_area`] zeroes it
/// the one time it hands it out (`DMA_TAKEN` lives in `.bss`, not in the
/// uninitialised section).
#[repr(transparent)]
struct DmaStatic(UnsafeCell<MaybeUninit<DmaArea>>);

// SAFETY: only `take_dma_area` touches the contents, once (`DMA_TAKEN`).
unsafe impl Sync for DmaStatic {}

#[unsafe(link_section = ".dma")]
static DMA: DmaStatic = DmaStatic(UnsafeCell::new(MaybeUninit::uninit()));
static DMA_TAKEN: AtomicBool = AtomicBool::new(false);

/// The DMA area, zeroed, the first time; `None` after.
fn take_dma_area() -> Option<&'static DmaArea> {
    if DMA_TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    let area = DMA.0.get();
    // SAFETY: first and only call (`DMA_TAKEN`): nothing else references the
    // area. All bytes zero is a valid `DmaArea` (every field is an integer in
    // a cell), so after the zeroing a shared reference to it is sound; the
    // area's fields are interior-mutable, as the MAC writes them.
    unsafe {
        core::ptr::write_bytes(area, 0, 1);
        Some((*area).assume_init_ref())
    }
}

/// Why the DMA area or the sockets were already taken: `run` was called twice.
const TAKEN_TWICE: NetError = NetError::AlreadyRunning;

/// Bring the network up and serve forever. Returns only if the MAC or the
/// PHY cannot be brought up (the caller reports and halts). A missing cable
/// is not an error: the link monitor brings the MAC up when it arrives.
pub fn run<B: Board, P: RegisterPort>(
    timer: &'static GlobalTimer,
    caches: Caches,
    frames: &mut Frames<P>,
    settings: &Settings,
    facts: &BootFacts,
) -> Result<core::convert::Infallible, NetError> {
    static SOCKET_BUFFERS: ConstStaticCell<[SocketBuffers; SOCKETS]> =
        ConstStaticCell::new([const { SocketBuffers::new() }; SOCKETS]);
    static SOCKET_STORAGE: ConstStaticCell<[SocketStorage<'static>; ALL_SOCKETS]> =
        ConstStaticCell::new([SocketStorage::EMPTY; ALL_SOCKETS]);
    // The host name the DHCP requests carry (option 12, RFC 2132 section 3.14).
    static HOST_NAME: StaticCell<HostName> = StaticCell::new();
    static DHCP_OPTIONS: StaticCell<[DhcpOption<'static>; 1]> = StaticCell::new();
    static MDNS_BUFFERS: ConstStaticCell<MdnsBuffers> = ConstStaticCell::new(MdnsBuffers::new());
    static WEB_BUFFERS: ConstStaticCell<[WebBuffers; WEB_SOCKETS]> =
        ConstStaticCell::new([const { WebBuffers::new() }; WEB_SOCKETS]);
    static CAMERA_BUFFERS: ConstStaticCell<CameraBuffers> = ConstStaticCell::new(CameraBuffers::new());
    // The RTP senders' repair windows, some 32 KiB a session.
    static CAMERA: ConstStaticCell<Camera<MAX_SESSIONS>> = ConstStaticCell::new(Camera::new());
    let mut log = Log;
    let dma = take_dma_area().ok_or(TAKEN_TWICE)?;
    let socket_buffers = SOCKET_BUFFERS.try_take().ok_or(TAKEN_TWICE)?;
    let socket_storage = SOCKET_STORAGE.try_take().ok_or(TAKEN_TWICE)?;
    let camera_buffers = CAMERA_BUFFERS.try_take().ok_or(TAKEN_TWICE)?;
    let camera_senders = CAMERA.try_take().ok_or(TAKEN_TWICE)?;
    let web_buffers = WEB_BUFFERS.try_take().ok_or(TAKEN_TWICE)?;
    let host_name: &'static HostName = HOST_NAME
        .try_init(settings.hostname.clone().unwrap_or_else(|| {
            let mut name = HostName::new();
            let _ = name.push_str(rt_services::DEFAULT_HOST_NAME);
            name
        }))
        .ok_or(TAKEN_TWICE)?;
    let dhcp_options =
        DHCP_OPTIONS.try_init([DhcpOption { kind: 12, data: host_name.as_bytes() }]).ok_or(TAKEN_TWICE)?;
    // The settings' MAC (unique per card: `cargo xtask sdcard` writes one),
    // else the board's.
    let mac_addr = settings.mac.unwrap_or(B::MAC_ADDR);

    // SAFETY: the board's DesignWare MAC, mapped Device; only this driver
    // uses it.
    let regs = unsafe { Regs::new(crate::platform::register_block(B::EMAC)) };
    let mut mac = Dwmac::new(regs, dma, caches, TimerDelay(timer));
    let _ = writeln!(
        log,
        "eth: DWMAC at {:#010x}, version {:#06x}, {:?} descriptors, checksum insertion {:?}",
        B::EMAC,
        mac.version() & 0xffff,
        mac.format(),
        mac.checksum_insertion()
    );
    let phy = mac.bring_up(mac_addr, &B::PHY).map_err(NetError::Mac)?;
    let _ = writeln!(
        log,
        "phy: {phy}{}; PHY reset, then DMA reset: done",
        if phy.is_ksz9021() { " (KSZ9021)" } else { "" }
    );
    if phy.is_ksz9021() {
        // The RGMII skews as the PHY holds them (docs/board-bring-up.md).
        match dwmac::phy::ksz9021_skews(&mut mac, phy.addr) {
            Ok([clk, rxd, txd]) => {
                let _ = writeln!(log, "phy: KSZ9021 skews 0x104={clk:#06x} 0x105={rxd:#06x} 0x106={txd:#06x}");
            }
            Err(e) => {
                let _ = writeln!(log, "phy: KSZ9021 skews unreadable: {e}");
            }
        }
    }
    let mut link = LinkMonitor::new(phy);
    log::flush();

    let mut config = Config::new(HardwareAddress::Ethernet(EthernetAddress(mac_addr)));
    config.random_seed = timer.ticks();
    let mut iface = Interface::new(config, &mut mac, instant(timer));
    let mut sockets = SocketSet::new(&mut socket_storage[..]);
    let mut addressing = Addressing::new(settings.address, mac_addr, &mut sockets, dhcp_options);
    let mut link_notes = LinkNotes::new();
    // Another device sending with this board's MAC (`MacClashes`): said
    // on the UART when first seen and then at most once a minute.
    let mut clashes = MacClashes::new(mac_addr);
    let mut clashes_said = (0u32, 0u64);
    let mac_from = if settings.mac.is_some() { "settings" } else { "default" };
    // Connection attempts to the seed ports and the page (`SynWatch`).
    let mut syns = SynWatch::new([FRAME_PORT, PERSISTENT_PORT, WEB_PORT]);
    // NAME.local and the services, by mDNS / DNS-SD on 224.0.0.251:5353.
    let services = Services { http: WEB_PORT, rtsp: RTSP_PORT, rtsp_path: "/orbit", seed: FRAME_PORT };
    // The multicast groups the board is in (IGMP, and the MAC's filter).
    let mut membership = Membership::new();
    let mdns_buffers = MDNS_BUFFERS.try_take().ok_or(TAKEN_TWICE)?;
    let mut mdns = match MdnsService::new(&mut sockets, mdns_buffers, host_name, services, timer.ticks()) {
        Ok(m) => {
            membership.want(MDNS_GROUP);
            Some(m)
        }
        Err(e) => {
            let _ = writeln!(log, "mdns: cannot bind UDP 5353: {e:?}");
            None
        }
    };
    let mut service = FrameService::<usize, SOCKETS>::new(&mut sockets, socket_buffers, FRAME_PORT_SOCKETS);
    let mut web = WebService::<usize, WEB_SOCKETS>::new(&mut sockets, web_buffers);
    let mut counts = crate::bench::Counts::default();
    let _ = writeln!(
        log,
        "net: {} MAC {}, name {host_name}, address {}; listening on TCP {FRAME_PORT} and {PERSISTENT_PORT} ({FRAME_PORT_SOCKETS} + {} sockets)",
        if settings.mac.is_some() { "settings'" } else { "the board's" },
        EthernetAddress(mac_addr),
        match settings.address {
            AddressMode::Automatic => "by DHCP, link-local while there is no lease",
            AddressMode::Static { .. } => "static (settings)",
        },
        SOCKETS - FRAME_PORT_SOCKETS,
    );
    let _ = writeln!(
        log,
        "web: page on TCP {WEB_PORT} ({WEB_SOCKETS} sockets, at most {WEB_VIEWERS} viewers sharing {WEB_FRAMES} frame slots)"
    );
    log::flush();

    // The network camera, in frame mode: its packets point into the ring.
    let slot_addresses = frames.slot_addresses();
    // A live stream's light until its first SET_PARAMETER: rt-client's first.
    let live_light = model::Light::from_world(3.0, 4.0, -2.0).ok();
    let mut camera = match slot_addresses.zip(live_light) {
        Some((_, live_light)) => {
            let multicast = multicast_config();
            camera_senders.configure(sender::Config {
                live_light,
                multicast,
                // Named again when the board has its address.
                cname: sender::Cname::for_address(Ipv4Addr::UNSPECIFIED),
            });
            let config = rtsp::Config { server_ip: Ipv4Addr::UNSPECIFIED, rtp_port: SERVER_RTP_PORT, udp: true };
            // What the board has to key its random numbers with: the time
            // since reset on the 200 MHz global timer (boot loaders and DDR
            // training vary it), its MAC address (not secret, but its own);
            // each received frame's arrival time is stirred in later
            // (docs/streaming.md, "Random numbers").
            let mut entropy = [0u8; 14];
            entropy[..8].copy_from_slice(&timer.ticks().to_le_bytes());
            entropy[8..14].copy_from_slice(&mac_addr);
            let eth = EthernetAddress(mac_addr);
            match CameraService::new(&mut sockets, camera_buffers, camera_senders, config, eth, &entropy) {
                Ok(c) => {
                    let _ = writeln!(
                        log,
                        "camera: RTSP on TCP {RTSP_PORT} ({RTSP_SOCKETS} sockets), RTP from UDP {SERVER_RTP_PORT}, rows zero-copy from the ring"
                    );
                    match multicast {
                        Some(m) => {
                            let _ = writeln!(
                                log,
                                "camera: multicast to {} (a group for each of up to {MAX_SESSIONS} streams), port {}, TTL {}",
                                m.group, m.base_port, m.ttl
                            );
                        }
                        None => {
                            let _ = writeln!(log, "camera: no multicast (FW_MULTICAST=off)");
                        }
                    }
                    Some(c)
                }
                Err(e) => {
                    let _ = writeln!(log, "camera: cannot bind RTCP: {e:?}");
                    None
                }
            }
        }
        None => {
            let _ = writeln!(log, "camera: off in row mode (its packets point into frame slots)");
            None
        }
    };
    let mut peers = Snooped::new(SERVER_RTP_PORT);
    // The multicast groups the camera sends to, joined (IGMP).
    let mut groups = GroupMembership::new();
    // The arrival times of received frames, for the camera's generator
    // (docs/streaming.md, "Session ids"): the timer's count at each main
    // loop turn in which frames arrived.
    let mut arrivals = TimingPool::new(timer.ticks());
    let mut frames_seen = 0u32;
    let mut in_flight = [None; RING_SLOTS];
    let mut refused = 0u32;
    // Frames the seed server holds (its quota's count).
    let mut seed_frames = 0usize;
    // Frames the web page's viewers hold (their quota's count).
    let mut web_frames = 0usize;
    // Frames every service has handed back (sent, or abandoned): the
    // status page's "sent".
    let mut ended = 0u64;
    let mut link_text: heapless::String<32> = heapless::String::new();
    let _ = link_text.push_str("down");
    log::flush();

    let mut display = Display::probe(frames, &mut log);
    let mut requests = 0u32;
    let mut link_up = false;
    // How many times the link came up (a new one means new IGMP reports).
    let mut link_ups = 0u32;
    // The address the displays show (0.0.0.0 until there is one).
    let mut address = [0u8; 4];
    log::flush();

    let mac_moved = |m: &Dwmac<'_, _, _>| m.stats().tx_frames.wrapping_add(m.stats().rx_frames);
    // When the address and the name are next looked after (µs; sooner when
    // a frame for them arrives).
    let mut housekeeping_at = 0u64;
    // Idle since (µs), after having served someone.
    let mut idle_since: Option<u64> = None;
    // When the camera's sessions were last reported (µs).
    let mut camera_report = 0u64;
    // The fault code, and when it and the HPS LED are next looked at (µs).
    let mut code: Option<Code> = None;
    let mut indicators_at = 0u64;
    // How frames are made (`Frames::mode`), looked at with the code: it
    // changes only when the accelerator is switched off.
    let mut mode = frames.mode();
    let mut led_on: Option<bool> = None;
    loop {
        let iteration = crate::bench::Iteration::start(mac_moved(&mac));
        let now_us = timer.now_us();
        let now = Instant::from_micros(i64::try_from(now_us).unwrap_or(i64::MAX));
        if let Some(change) = link.poll(now_us, &mut mac) {
            mac.set_link(change);
            link_up = change.is_some();
            link_ups = link_ups.wrapping_add(u32::from(link_up));
            link_text.clear();
            let _ = match change {
                Some(l) => write!(link_text, "{l}"),
                None => link_text.push_str("down").map_err(|_| fmt::Error),
            };
            match change {
                Some(l) => {
                    let _ = writeln!(log, "link up: {l}");
                    // Perhaps on another network: the name is probed and
                    // announced again (the address, by `addressing`).
                    if let Some(m) = &mut mdns {
                        m.link_up(now);
                    }
                }
                None => {
                    let _ = writeln!(log, "link down (waiting for the cable or the partner)");
                }
            }
        }
        // The address and the name are looked after when a frame for them
        // arrived (ARP, DHCP, mDNS: `LinkNotes`) or one of their timers is
        // due, at least once a HOUSEKEEPING_US; not on every turn, which
        // keeps the frame path's instruction count (bench-fw) where it was.
        let housekeeping = now_us >= housekeeping_at;
        // The address first: a static one is on the interface before the
        // first frame is taken in.
        let change = if housekeeping {
            addressing.poll(now, link_up, &mut iface, &mut sockets, &mut link_notes, &mut mac)
        } else {
            None
        };
        if let Some(change) = change {
            let ip = change.map_or(Ipv4Addr::UNSPECIFIED, |a| a.address);
            address = ip.octets();
            if let Some(c) = &mut camera {
                c.set_address(ip);
            }
            if let Some(m) = &mut mdns {
                m.set_address(now, change.map(|a| a.address));
            }
            match change {
                Some(a) => {
                    let _ = writeln!(log, "net: address {a}");
                }
                None => {
                    let _ = writeln!(log, "net: address lost (lease ended); asking again");
                }
            }
        }
        // The groups: joined (and reported) with an address and a link,
        // reported again on a new one; the MAC passes what they need.
        let address_now = addressing.current().map(|a| a.address);
        membership.update(address_now, link_up.then_some(link_ups), &mut iface, &mut log);
        if membership.take_changed() {
            let mut filter = MulticastFilter::new();
            membership.filter_groups().for_each(|g| filter.add_group(g));
            mac.set_multicast(filter);
        }
        let learners = &mut (&mut peers, (&mut link_notes, (&mut syns, &mut clashes)));
        iface.poll(now, &mut Snoop { inner: &mut mac, peers: learners }, &mut sockets);
        let woke = link_notes.take_wake();
        if let Some(m) = mdns.as_mut().filter(|_| housekeeping || woke) {
            m.poll(now, &mut sockets, &mut log);
        }
        if woke {
            // The address's turn comes next: its frames were taken in now.
            housekeeping_at = now_us;
        } else if housekeeping {
            let micros = |t: Instant| u64::try_from(t.total_micros()).unwrap_or(0);
            let mdns_at = mdns.as_ref().and_then(|m| m.responder().poll_at()).map(|t| t.millis() * 1000);
            housekeeping_at = [addressing.poll_at().map(micros), mdns_at]
                .into_iter()
                .flatten()
                .fold(now_us + HOUSEKEEPING_US, u64::min)
                .max(now_us + 1);
        }
        if clashes.count != clashes_said.0 && (clashes_said.0 == 0 || now_us >= clashes_said.1 + 60_000_000) {
            clashes_said = (clashes.count, now_us);
            let _ = writeln!(
                log,
                "net: another device on this network sends from this board's MAC {} (the {mac_from} MAC; {} frames \
                 from it so far): two boards from one card image? give each card its own mac= line (docs/networking.md)",
                EthernetAddress(mac_addr),
                clashes.count
            );
        }
        if peers.frames_seen() != frames_seen {
            frames_seen = peers.frames_seen();
            arrivals.add(timer.ticks());
        }
        // The seed server's frames count for the display (its attract
        // mode waits while they come) and stay within its quota of slots.
        let mut counted = Counting { frames: &mut *frames, begun: &mut requests, ended: &mut ended };
        // A service left with every socket listening has nothing to do
        // until a SYN comes for its port: smoltcp moves a listening socket
        // on nothing else (`quiet`, `SynWatch`). Skipping it meanwhile
        // keeps its 24 sockets off the RTP frame path (bench-fw).
        let seed_syn = syns.take(0) | syns.take(1);
        if seed_syn || !service.quiet() {
            service.poll(now, &mut sockets, &mut Quota::new(&mut counted, &mut seed_frames, SEED_FRAMES), &mut log);
        }
        if let (Some(c), Some(slots)) = (&mut camera, &slot_addresses) {
            let busy = crate::camera::slots_in_flight(&mut mac, &mut in_flight);
            frames.set_in_flight(busy);
            let mut tx = crate::camera::ZeroCopy {
                mac: &mut mac,
                slots,
                in_flight: &mut in_flight,
                refused: &mut refused,
                cic: None,
            };
            // The camera's frames count as clients' for the display too.
            let mut counted = Counting { frames: &mut *frames, begun: &mut requests, ended: &mut ended };
            let entropy = arrivals.value() ^ timer.ticks();
            crate::bench::camera(|| c.poll(now, &mut sockets, &mut peers, &mut counted, &mut tx, entropy, &mut log));
            groups.sync(c.camera(), &mut membership, &mut log);
        }
        // The fault code and the HPS LED's blinks, ten times a second (not
        // on every turn: the frame path's instruction count, bench-fw).
        if now_us >= indicators_at {
            // On a grid, so that the LED's 100 ms flashes keep their length.
            indicators_at = (now_us / INDICATORS_US + 1) * INDICATORS_US;
            mode = frames.mode();
            let in_use = mode != "software";
            let vga_fault = display.as_ref().is_some_and(Display::vga_fault);
            let now_code = Code::of(&facts.facts(in_use, link_up, addressing.current().is_some(), vga_fault));
            if code != Some(now_code) {
                code = Some(now_code);
                let _ = writeln!(log, "status: {now_code} ({})", shown_as(now_code));
            }
            let on = hps_led(now_code, rt_services::Instant::from_millis(now_us / 1000));
            if led_on != Some(on) {
                led_on = Some(on);
                B::status_led(on);
            }
        }
        let code = code.unwrap_or_default();
        // The web page: its viewers' frames count for the display too, and
        // stay within their quota of slots. Its status is made only when
        // the page has something to do (the frame path's instruction
        // count, bench-fw).
        if syns.take(2) || !web.quiet() {
            let vga = match &display {
                Some(d) => d.vga(),
                None if facts.register_map.is_some_and(|v| v >= hal_avalon::map::ID_VERSION_VGA) => {
                    "off: the software renderer makes the frames"
                }
                None => "off: no VGA block in this accelerator",
            };
            let status = BoardStatus {
                uptime_s: now_us / 1_000_000,
                // Who renders, as the page names it.
                renderer: if mode == "software" { "software" } else { "fpga" },
                link: &link_text,
                frames_rendered: frames.completed().map_or(u64::from(requests), u64::from),
                frames_sent: ended,
                viewers: Viewers {
                    web: web.viewers(),
                    web_max: WEB_VIEWERS,
                    seed: service.active_sessions(),
                    rtsp: camera.as_ref().map_or(0, |c| c.server().sessions().len()),
                },
                rtsp_port: RTSP_PORT,
                identity: Identity {
                    version: env!("CARGO_PKG_VERSION"),
                    name: mdns.as_ref().map_or(host_name.as_str(), |m| m.responder().name()),
                    address: addressing.current().map(|a| a.address),
                    address_from: addressing.current().map_or("none", |a| a.origin.as_str()),
                    mac: Some(mac_addr),
                    mac_from,
                    mac_clashes: clashes.count,
                },
                health: Health {
                    self_test: facts.self_test,
                    self_test_detail: &facts.self_test_detail,
                    mode,
                    register_map: facts.register_map,
                    fpga_build: facts.fpga_build,
                    bridges: &facts.bridges,
                    vga,
                    code: code.as_str(),
                },
            };
            let mut counted = Counting { frames: &mut *frames, begun: &mut requests, ended: &mut ended };
            crate::bench::web(|| {
                web.poll(
                    now,
                    &mut sockets,
                    &mut Quota::new(&mut counted, &mut web_frames, WEB_FRAMES),
                    &status,
                    mdns.as_ref().map_or(host_name.as_str(), |m| m.responder().name()),
                    &crate::log::Tail,
                    &mut log,
                )
            });
        }
        frames.report(&mut log);
        if let Some(c) = &camera {
            if now_us.saturating_sub(camera_report) >= 1_000_000 {
                camera_report = now_us;
                c.report(&mut log);
            }
        }
        if let Some(d) = &mut display {
            let status = rt_services::monitor::Status {
                link_up,
                fpga: mode != "software",
                self_test_passed: facts.self_test == "pass",
                clients: service.active_sessions(),
                address,
                name: mdns.as_ref().map_or(host_name.as_str(), |m| m.responder().name()),
                code,
            };
            d.poll(rt_services::Instant::from_millis(now_us / 1000), frames, requests, &status, &mut log);
        }
        // A second after the last client (of either service): say what is
        // free, so a long run can show nothing leaked (cargo xtask soak and
        // the hostile-network test read this line).
        let camera_busy =
            camera.as_ref().is_some_and(|c| !c.server().sessions().is_empty() || c.listening(&sockets) < RTSP_SOCKETS);
        if service.active_sessions() > 0 || camera_busy || web.connections() > 0 {
            idle_since = Some(now_us);
        } else if idle_since.is_some_and(|t| now_us.saturating_sub(t) >= 1_000_000) {
            idle_since = None;
            let (tx, rx) = mac.free_descriptors();
            let rtsp = camera.as_ref().map_or(0, |c| c.listening(&sockets));
            let _ = writeln!(
                log,
                "net: idle: {} of {SOCKETS} sockets listening, {tx} of {} TX and {rx} of {} RX descriptors free, {rtsp} of {RTSP_SOCKETS} RTSP sockets listening, {} of {WEB_SOCKETS} web sockets listening",
                service.listening(&sockets),
                dwmac::TX_RING,
                dwmac::RX_RING,
                web.listening(&sockets)
            );
        }
        let stats = mac.stats();
        let moved = crate::bench::Mac {
            frames: mac_moved(&mac),
            tx_frames: stats.tx_frames,
            tx_bytes: stats.tx_bytes,
            tx_zero_copy: stats.tx_split_payload_bytes,
            rx_bytes: stats.rx_bytes,
        };
        // The iteration ends before the report, so the report's window
        // holds whole iterations.
        iteration.end(moved.frames);
        counts.report(frames.bus_accesses(), moved, &mut log);
        log::drain();
    }
}

/// The frames as the service sees them, counting the frames its clients
/// begin (the display's attract mode waits while they come) and end (the
/// web page's status).
struct Counting<'a, F> {
    frames: &'a mut F,
    begun: &'a mut u32,
    ended: &'a mut u64,
}

impl<F: FrameSource> FrameSource for Counting<'_, F> {
    type Frame = F::Frame;
    type Error = F::Error;

    fn begin(&mut self, light: &model::Light) -> Result<Option<F::Frame>, F::Error> {
        let frame = self.frames.begin(light)?;
        if frame.is_some() {
            *self.begun = self.begun.wrapping_add(1);
        }
        Ok(frame)
    }

    fn rows_ready(&mut self, frame: F::Frame) -> Result<u16, F::Error> {
        self.frames.rows_ready(frame)
    }

    fn copy_row(&mut self, frame: F::Frame, y: u16, offset: usize, out: &mut [u8]) -> usize {
        self.frames.copy_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: F::Frame) {
        *self.ended += 1;
        self.frames.end(frame)
    }
}

impl<F: rt_services::camera::sender::SlotSource> rt_services::camera::sender::SlotSource for Counting<'_, F> {
    fn set_held(&mut self, mask: u32) {
        self.frames.set_held(mask)
    }
}
