//! The board on its own under Linux, as on bare metal: the VGA monitor
//! showing the newest frame (attract mode when no client asks), the keys
//! and switches steering it, the LEDs and the 7-segment displays
//! (`rt_services::monitor`, the firmware's policy, unchanged).
//!
//! [`PanelRing`] is the board's frame ring with the accelerator's board
//! I/O block beside it: hps-sim's [`Frames`] for the services, and on
//! every [`Frames::tick`] (a thread of the program's calls
//! [`Board::tick`](hps_sim::board::Board::tick) every few milliseconds)
//! one step of the monitor. Only on an FPGA image whose register map has
//! the block (version 3, hal-avalon [`has_board_io`]).
//!
//! The scan-out reads frames by physical address through the
//! FPGA-to-SDRAM port, so it runs in frame mode only (the ring in the
//! u-dma-buf buffer); in row mode the ring lies in the process's memory,
//! where the FPGA cannot read, and only the LEDs and displays run (code
//! E4 on the displays, as the firmware shows for rows only).
//!
//! What Linux owns, the monitor is told as it is: the link is up, the
//! address is the first IPv4 address of an interface that is up and not
//! loopback ([`host_address`]), the name is the host name. "Clients"
//! (LEDR3) are the frames the services hold.

use std::time::Instant as StdInstant;

use embedded_hal::delay::DelayNs;

use hal_avalon::board::{has_board_io, BoardIo};
use hal_avalon::map::Csr;
use hal_avalon::{Accelerator, RegisterPort};
use hps_sim::board::{Failed, Frames, BOARD_SLOTS};
use model::display::Layout;
use model::{Light, ROW_BYTES};
use rt_services::camera::sender::SlotSource;
use rt_services::frames::{Completed, FrameEngine, FrameMemory, FrameRing, RowEngine};
use rt_services::monitor::{Code, Inputs, Monitor, Panel, Refreshes, Screen, Status};
use rt_services::{FrameSource, Instant};

/// The frame on screen and the one waiting for vertical blanking: kept
/// beside the services' quotas, as the firmware's `DISPLAY_SLOTS`.
pub const DISPLAY_SLOTS: usize = 2;

/// The ring's slots: every service's quota and the display's.
pub const RING_SLOTS: usize = BOARD_SLOTS + DISPLAY_SLOTS;

/// The ring of the program's board.
pub type Ring<M, E> = FrameRing<M, E, RING_SLOTS>;

/// An engine whose accelerator's port the board I/O block is reached
/// through: the frame DMA's, or the row engine's.
pub trait BoardPort {
    /// The port.
    type Port: RegisterPort;
    /// The accelerator's port.
    fn board_port(&mut self) -> &mut Self::Port;
}

impl<P: RegisterPort, D: DelayNs> BoardPort for Accelerator<P, D> {
    type Port = P;
    fn board_port(&mut self) -> &mut P {
        self.port_mut()
    }
}

impl<P: RegisterPort, D: DelayNs> BoardPort for RowEngine<Accelerator<P, D>> {
    type Port = P;
    fn board_port(&mut self) -> &mut P {
        self.rows().port_mut()
    }
}

/// What the displays and LEDs say of the program: fixed at start, but the
/// address (read again now and then).
#[derive(Clone, Debug)]
pub struct Identity {
    /// The host name.
    pub name: String,
    /// The FPGA renders (LEDR1).
    pub fpga: bool,
    /// The boot self-test passed (LEDR2).
    pub self_test_passed: bool,
    /// What is wrong, shown after the address.
    pub code: Code,
}

/// The ring, the accelerator's board I/O and the monitor policy.
pub struct PanelRing<M: FrameMemory, E: FrameEngine<M>> {
    ring: Ring<M, E>,
    /// `None` on an image without the board I/O block.
    monitor: Option<Monitor>,
    scan_out: bool,
    identity: Identity,
    address: [u8; 4],
    address_read: Option<StdInstant>,
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
    /// mode).
    pub fn new(mut ring: Ring<M, E>, scan_out: bool, identity: Identity) -> PanelRing<M, E> {
        let id = ring.engine().board_port().read(Csr::Id);
        let monitor = has_board_io(id).then(Monitor::new);
        PanelRing {
            ring,
            monitor,
            scan_out,
            identity,
            address: [0; 4],
            address_read: None,
            requests: 0,
            origin: StdInstant::now(),
        }
    }

    /// Whether the image has the board I/O block (the monitor runs).
    pub fn has_panel(&self) -> bool {
        self.monitor.is_some()
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

    fn tick(&mut self, clients: usize) {
        let Some(monitor) = self.monitor.as_mut() else { return };
        let now = StdInstant::now();
        if self.address_read.is_none_or(|t| now.duration_since(t) >= ADDRESS_EVERY) {
            self.address_read = Some(now);
            self.address = host_address().unwrap_or([0; 4]);
        }
        let status = Status {
            link_up: true,
            fpga: self.identity.fpga,
            self_test_passed: self.identity.self_test_passed,
            clients,
            address: self.address,
            name: &self.identity.name,
            code: self.identity.code,
        };
        let t = Instant::from_millis(now.duration_since(self.origin).as_millis() as u64);
        let mut device = Device { ring: &mut self.ring };
        if !self.scan_out {
            monitor.poll_panel(t, &mut device, &status);
        } else if let Some(report) = monitor.poll(t, &mut device, self.requests, &status) {
            eprintln!("hps-linux: {report}");
        }
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

/// The ring and its accelerator's board I/O as the device the monitor
/// policy works on (the firmware's `display::Device`).
struct Device<'a, M: FrameMemory, E: FrameEngine<M>> {
    ring: &'a mut Ring<M, E>,
}

impl<M: FrameMemory, E: FrameEngine<M> + BoardPort> Device<'_, M, E> {
    fn io(&mut self) -> BoardIo<&mut E::Port> {
        BoardIo::checked(self.ring.engine().board_port())
    }
}

impl<M: FrameMemory, E: FrameEngine<M>> FrameSource for Device<'_, M, E> {
    type Frame = usize;
    type Error = <Ring<M, E> as FrameSource>::Error;

    fn begin(&mut self, light: &Light) -> Result<Option<usize>, Self::Error> {
        self.ring.begin(light)
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, Self::Error> {
        self.ring.rows_ready(frame)
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        self.ring.copy_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: usize) {
        self.ring.end(frame)
    }
}

impl<M: FrameMemory, E: FrameEngine<M>> Screen for Device<'_, M, E> {
    fn newest_complete(&self) -> Option<Completed> {
        self.ring.newest_complete()
    }

    fn pin(&mut self, slot: usize) {
        self.ring.pin(slot)
    }

    fn unpin(&mut self, slot: usize) {
        self.ring.unpin(slot)
    }

    fn slot_address(&self, slot: usize) -> u32 {
        self.ring.slot_address(slot)
    }

    fn edit_row(&mut self, slot: usize, y: u16, edit: &mut dyn FnMut(&mut [u8; ROW_BYTES])) {
        self.ring.edit_row(slot, y, edit)
    }
}

impl<M: FrameMemory, E: FrameEngine<M> + BoardPort> Panel for Device<'_, M, E> {
    fn refreshes(&mut self) -> Refreshes {
        Panel::refreshes(&mut self.io())
    }

    fn show(&mut self, base: u32) {
        self.io().show(base)
    }

    fn scan_out(&mut self, layout: Layout) {
        self.io().enable(layout)
    }

    fn inputs(&mut self) -> Inputs {
        Panel::inputs(&mut self.io())
    }

    fn set_leds(&mut self, leds: u16) {
        self.io().set_leds(leds)
    }

    fn set_text(&mut self, text: [u8; 6]) {
        self.io().set_text(text)
    }
}
