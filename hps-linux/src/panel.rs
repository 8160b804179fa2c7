//! The board on its own under Linux, as on bare metal: the VGA monitor
//! showing the newest frame (attract mode when no client asks), the keys
//! and switches steering it, the LEDs and the 7-segment displays
//! (`rt_services::monitor`, the firmware's policy, unchanged).
//!
//! [`PanelRing`] is the board's frame ring with the accelerator's board
//! I/O block beside it: rt-services-std's [`Frames`] for the services, and on
//! every [`Frames::tick`] (a thread of the program's calls
//! [`Board::tick`](rt_services_std::board::Board::tick) every few milliseconds)
//! one step of the monitor. Only on an FPGA image whose register map has
//! the block (version 3, hal-avalon [`has_board_io`]). The code on the
//! displays is worked out on every step as the firmware's is
//! ([`Code::of`]), and `/status` reads it and the VGA state live
//! ([`Frames::live`]).
//!
//! The scan-out reads frames by physical address through the
//! FPGA-to-SDRAM port, so it runs in frame mode only (the ring in the
//! u-dma-buf buffer); in row mode the ring lies in the process's memory,
//! where the FPGA cannot read, and only the LEDs and displays run (code
//! E4 on the displays, as the firmware shows for rows only).
//!
//! What Linux owns, the monitor is told as it is: the link is up, the
//! address is the first IPv4 address of an interface that is up and not
//! loopback ([`host_address`], looked up by a thread of its own, never
//! under the board's lock), the name is the host name. "Clients" (LEDR3)
//! are the frames the services hold.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Instant as StdInstant;

use embedded_hal::delay::DelayNs;

use hal_avalon::board::{has_board_io, BoardIo};
use hal_avalon::map::Csr;
use hal_avalon::ring_panel::RingPanel;
use hal_avalon::{Accelerator, RegisterPort};
use model::Light;
use rt_services::camera::sender::SlotSource;
use rt_services::frames::{FallbackEngine, FrameEngine, FrameMemory, FrameRing, RowEngine, Watchdog};
use rt_services::monitor::code::Facts as CodeFacts;
use rt_services::monitor::{Code, Monitor, Status};
use rt_services::{FrameSource, Instant};
use rt_services_std::board::{Failed, Frames, Live, BOARD_SLOTS};

/// The frame on screen and the one waiting for vertical blanking: kept
/// beside the services' quotas, as the firmware's `DISPLAY_SLOTS`.
pub const DISPLAY_SLOTS: usize = 2;

/// The ring's slots: every service's quota and the display's.
pub const RING_SLOTS: usize = BOARD_SLOTS + DISPLAY_SLOTS;

/// The ring of the program's board.
pub type Ring<M, E> = FrameRing<M, E, RING_SLOTS>;

/// An engine whose accelerator's port the board I/O block is reached
/// through (the frame DMA's, or the row engine's), and whether the
/// accelerator still renders.
pub trait BoardPort {
    /// The port.
    type Port: RegisterPort;
    /// The accelerator's port, if the engine has one.
    fn board_port(&mut self) -> Option<&mut Self::Port>;
    /// Whether the accelerator still renders (not switched off after
    /// failed frames).
    fn fpga_in_use(&self) -> bool {
        true
    }
    /// `true` once, right after the accelerator was switched off.
    fn take_switched_off(&mut self) -> bool {
        false
    }
}

impl<P: RegisterPort, D: DelayNs> BoardPort for RowEngine<Accelerator<P, D>> {
    type Port = P;
    fn board_port(&mut self) -> Option<&mut P> {
        Some(self.rows().port_mut())
    }
}

/// Frame mode's engine: the frame DMA watched for stalls, the software
/// renderer once it was switched off (as the firmware's).
impl<P, D, C, F> BoardPort for FallbackEngine<Watchdog<Accelerator<P, D>, C>, F>
where
    P: RegisterPort,
    D: DelayNs,
    C: FnMut() -> Instant,
{
    type Port = P;
    fn board_port(&mut self) -> Option<&mut P> {
        self.primary_kept().map(|w| w.engine().port_mut())
    }
    fn fpga_in_use(&self) -> bool {
        self.primary_active()
    }
    fn take_switched_off(&mut self) -> bool {
        FallbackEngine::take_switched_off(self)
    }
}

/// What the displays and LEDs say of the program that does not change
/// while it runs.
#[derive(Clone, Debug)]
pub struct Identity {
    /// The host name.
    pub name: String,
    /// The frame path passed the self-test, or was not tried (no frame
    /// memory is not a fault; a frame path that failed is, E4).
    pub frames_passed: bool,
}

/// The ring, the accelerator's board I/O and the monitor policy.
pub struct PanelRing<M: FrameMemory, E: FrameEngine<M>> {
    ring: Ring<M, E>,
    /// `None` on an image without the board I/O block.
    monitor: Option<Monitor>,
    scan_out: bool,
    identity: Identity,
    /// The host's address (a thread of its own looks it up).
    address: Arc<AtomicU32>,
    /// The code shown at the last step.
    code: Code,
    /// Frames the services began (the monitor's "client requests").
    requests: u32,
    origin: StdInstant,
}

/// How often the host's address is looked up again.
const ADDRESS_EVERY: std::time::Duration = std::time::Duration::from_secs(5);

impl<M, E> PanelRing<M, E>
where
    M: FrameMemory,
    E: FrameEngine<M> + BoardPort,
{
    /// `ring` with its accelerator's board I/O, if the image has the
    /// block; `scan_out` where the ring is memory the FPGA reads (frame
    /// mode). Elsewhere the scan-out is switched off (an earlier run in
    /// frame mode may have left it reading that run's memory).
    pub fn new(mut ring: Ring<M, E>, scan_out: bool, identity: Identity) -> PanelRing<M, E> {
        let id = ring.engine().board_port().map_or(0, |p| p.read(Csr::Id));
        let monitor = has_board_io(id).then(Monitor::new);
        if monitor.is_some() && !scan_out {
            if let Some(port) = ring.engine().board_port() {
                BoardIo::checked(port).disable();
            }
        }
        let address = Arc::new(AtomicU32::new(u32::from_be_bytes(host_address().unwrap_or([0; 4]))));
        if monitor.is_some() {
            let shared = Arc::clone(&address);
            std::thread::spawn(move || loop {
                std::thread::sleep(ADDRESS_EVERY);
                shared.store(u32::from_be_bytes(host_address().unwrap_or([0; 4])), Ordering::Relaxed);
            });
        }
        PanelRing { ring, monitor, scan_out, identity, address, code: Code::Ok, requests: 0, origin: StdInstant::now() }
    }

    /// The VGA output in words, for `/status`.
    pub fn vga(&self) -> &'static str {
        match (&self.monitor, self.scan_out) {
            (None, _) => "off: the FPGA image has no VGA scan-out (register map before version 3)",
            (Some(_), false) => "off: rows over the bridge, and the scan-out reads frames from the frame DMA's memory",
            (Some(m), true) if m.scanout().port_fault() => "on, memory port fault (check fpgaportrst)",
            (Some(m), true) if m.scanout().enabled() => "on",
            (Some(_), true) => "starting",
        }
    }
}

impl<M, E> Frames for PanelRing<M, E>
where
    M: FrameMemory + Send,
    E: FrameEngine<M> + BoardPort + Send,
    E::Error: Send,
{
    fn begin_frame(&mut self, light: &Light) -> Result<Option<usize>, Failed> {
        self.requests = self.requests.wrapping_add(1);
        FrameSource::begin(&mut self.ring, light).map_err(|e| Failed(e.to_string()))
    }

    fn frame_rows(&mut self, frame: usize) -> Result<u16, Failed> {
        FrameSource::rows_ready(&mut self.ring, frame).map_err(|e| Failed(e.to_string()))
    }

    fn copy_frame_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        FrameSource::copy_row(&mut self.ring, frame, y, offset, out)
    }

    fn end_frame(&mut self, frame: usize) {
        FrameSource::end(&mut self.ring, frame)
    }

    fn hold_slots(&mut self, mask: u32) {
        SlotSource::set_held(&mut self.ring, mask)
    }

    fn tick(&mut self, clients: usize) -> Option<String> {
        let switched_off = self.ring.engine().take_switched_off();
        let fpga_in_use = self.ring.engine().fpga_in_use();
        let address = self.address.load(Ordering::Relaxed).to_be_bytes();
        let monitor = self.monitor.as_mut()?;
        self.code = Code::of(&CodeFacts {
            fpga_answers: true,
            rows_passed: true,
            frames_passed: self.identity.frames_passed,
            fpga_in_use,
            link_up: true,
            has_address: address != [0; 4],
            vga_fault: monitor.scanout().port_fault(),
        });
        let status = Status {
            link_up: true,
            fpga: fpga_in_use,
            self_test_passed: true,
            clients,
            address,
            name: &self.identity.name,
            code: self.code,
        };
        let now = StdInstant::now();
        let t = Instant::from_millis(now.duration_since(self.origin).as_millis() as u64);
        let mut device = RingPanel::new(&mut self.ring, E::board_port);
        let report = if !self.scan_out {
            monitor.poll_panel(t, &mut device, &status);
            None
        } else {
            monitor.poll(t, &mut device, self.requests, &status).map(|r| r.to_string())
        };
        if switched_off {
            return Some(format!("{}: frames from the software renderer from now on", Code::SwitchedOff.meaning()));
        }
        report
    }

    fn shut_down(&mut self) {
        if self.monitor.is_none() {
            return;
        }
        if let Some(port) = self.ring.engine().board_port() {
            let mut io = BoardIo::checked(port);
            io.disable();
            io.set_leds(0);
            io.set_text(*b"      ");
        }
    }

    fn live(&self) -> Option<Live> {
        self.monitor.as_ref()?;
        Some(Live { vga: self.vga(), code: self.code.as_str() })
    }
}

/// The first IPv4 address of an interface that is up and not loopback.
pub fn host_address() -> Option<[u8; 4]> {
    let mut list: *mut libc::ifaddrs = std::ptr::null_mut();
    // SAFETY: getifaddrs writes a list it allocated into `list`, or fails
    // and leaves it alone; the list is freed below, once.
    if unsafe { libc::getifaddrs(&mut list) } != 0 {
        return None;
    }
    let mut found = None;
    let mut at = list;
    while !at.is_null() && found.is_none() {
        // SAFETY: `at` is a node of the list getifaddrs made, not yet freed.
        let entry = unsafe { &*at };
        at = entry.ifa_next;
        let up = entry.ifa_flags & libc::IFF_UP as u32 != 0;
        let loopback = entry.ifa_flags & libc::IFF_LOOPBACK as u32 != 0;
        if !up || loopback || entry.ifa_addr.is_null() {
            continue;
        }
        // SAFETY: a non-null `ifa_addr` points at a sockaddr of the family
        // it names; read as sockaddr_in only for AF_INET.
        let family = unsafe { (*entry.ifa_addr).sa_family };
        if i32::from(family) == libc::AF_INET {
            // SAFETY: as above, the family is AF_INET.
            let sin = unsafe { &*entry.ifa_addr.cast::<libc::sockaddr_in>() };
            found = Some(u32::from_be(sin.sin_addr.s_addr).to_be_bytes());
        }
    }
    // SAFETY: the list getifaddrs allocated, freed once; no node is used
    // after this.
    unsafe { libc::freeifaddrs(list) };
    found
}
