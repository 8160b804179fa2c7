//! `hps-sim`: the board simulated on the host. The firmware's frame server
//! (`rt_services::seed::server`) on std TCP, rendering through hal-avalon's driver
//! and simulated accelerator, in either of the board's modes:
//!
//! * frame mode (the default): the accelerator's frame DMA writes whole
//!   frames into a ring of two frame slots in host memory, and rows stream
//!   out as its rows-done counter covers them (`rt_services::FrameRing`);
//! * row mode: one row per start through the line buffer
//!   (`rt_services::RowFrames`).
//!
//! The accelerator is hal-avalon's simulated one (the default) or the
//! Verilated RTL (`rtl-port`, [`Device::Rtl`]): the same driver code either
//! way, and with the RTL each connection logs the simulated clocks per frame
//! and per row.
//!
//! Beside them, [`rtsp`]: the board as a network camera (RTSP on TCP, RTP
//! and RTCP on UDP), from one shared frame ring as on the board; and [`web`]:
//! the board's web page (`--http`), the live picture in a browser.
//!
//! Two listeners: the seed protocol on the listen port and the persistent
//! protocol on the listen port + 1. Every connection is served concurrently
//! on its own thread with its own simulated accelerator (a board has one
//! accelerator and interleaves its clients; on the host a device per client
//! keeps the clients independent and the frames identical), at most as
//! many at once as the board has sockets (`rt_services::seed::SEED_SOCKETS`,
//! `rt_services::web::WEB_SOCKETS`); one more is closed at once, as the
//! board refuses it.

pub mod board;
pub mod cli;
pub mod rtsp;
pub mod web;

use std::fmt;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use hal_avalon::sim::{CountingDelay, DmaTarget, SimAccelerator};
use hal_avalon::{selftest, Accelerator, PollTimeout};
use model::{FRAME_BYTES, ROW_BYTES};
use rt_services::seed::server::{drive, Action, Closed, Mode, Session};
use rt_services::{
    persistent_port, FrameMemory, FrameRing, FrameSource, Instant as ProtocolInstant, RowFrames, SliceMemory,
};

/// STATUS polls a simulated row stays busy for: enough that the driver's
/// polling loop runs, few enough to cost nothing.
const SIM_BUSY_POLLS: u32 = 2;

/// How long a closing connection waits for the client's end of stream
/// before it is dropped (closing with unread input would reset the
/// connection and could cost the client the frame's tail).
const LINGER: Duration = Duration::from_secs(2);

/// How the simulated board renders (also the binary's `--mode`).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, clap::ValueEnum)]
pub enum RenderMode {
    /// Whole frames by the accelerator's frame DMA into a ring in memory.
    #[default]
    Frames,
    /// One row per start through the line buffer.
    Rows,
}

/// Which accelerator renders (also the binary's `--accelerator`).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, clap::ValueEnum)]
pub enum Device {
    /// hal-avalon's simulated accelerator (built from the model).
    #[default]
    Sim,
    /// The Verilated RTL (`rtl-port`): slower, cycle by cycle.
    Rtl,
}

/// What the simulated board runs.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct Config {
    /// Frame mode or row mode.
    pub render: RenderMode,
    /// Simulated accelerator or RTL.
    pub device: Device,
    /// Faults injected (none by default).
    pub faults: Faults,
}

/// A fault `hps-sim --fault` injects, so that `rt-client doctor` can be
/// shown to name it.
#[derive(Clone, Copy, PartialEq, Eq, Debug, clap::ValueEnum)]
pub enum Fault {
    /// The simulated accelerator inverts one pixel ([`WRONG_PIXEL`]) of
    /// every frame, where the boot self-test does not look: only a whole
    /// frame compared with the model finds it.
    WrongPixel,
    /// RTSP `SETUP`s asking for RTP over UDP are answered 461 Unsupported
    /// Transport (RTP over the RTSP connection still plays).
    RefuseUdp,
    /// `/status` claims version [`OLD_VERSION`], not this build's.
    OldVersion,
}

/// The faults injected.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct Faults {
    /// [`Fault::WrongPixel`].
    pub wrong_pixel: bool,
    /// [`Fault::RefuseUdp`].
    pub refuse_udp: bool,
    /// [`Fault::OldVersion`].
    pub old_version: bool,
}

impl Faults {
    /// The faults of a list of them.
    pub fn of(list: &[Fault]) -> Faults {
        Faults {
            wrong_pixel: list.contains(&Fault::WrongPixel),
            refuse_udp: list.contains(&Fault::RefuseUdp),
            old_version: list.contains(&Fault::OldVersion),
        }
    }

    /// The version `/status` gives.
    pub fn version(&self) -> &'static str {
        if self.old_version {
            OLD_VERSION
        } else {
            env!("CARGO_PKG_VERSION")
        }
    }
}

/// The pixel (row, x) [`Fault::WrongPixel`] inverts: a row neither half
/// of the boot self-test checks (hal-avalon `selftest::PLAN`).
pub const WRONG_PIXEL: (u16, u16) = (100, 200);

/// The version [`Fault::OldVersion`] claims.
pub const OLD_VERSION: &str = "0.0.1";

/// The boot self-test's outcome, as `/status` gives it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SelfTest {
    /// `"pass"`, `"fail"` or `"skipped"`.
    pub result: &'static str,
    /// Its log line.
    pub detail: String,
}

/// Run the board's boot self-test (hal-avalon `selftest`, the firmware's
/// plan) on a fresh accelerator of `config`, as the firmware does at boot;
/// skipped for the RTL (a frame takes it about a second).
pub fn self_test(config: Config) -> SelfTest {
    if config.device == Device::Rtl {
        return SelfTest { result: "skipped", detail: "self-test: skipped on the RTL (slow)".into() };
    }
    let mem = SharedMemory::new(FRAME_SLOTS);
    let mut accel =
        Accelerator::new(simulated(mem.clone(), config.faults), CountingDelay::default(), PollTimeout::DEFAULT);
    let report = selftest::run(
        &mut accel,
        &mut mem.clone(),
        &mut rt_services::SoftwareRenderer,
        &mut CountingDelay::default(),
        &selftest::PLAN,
    );
    SelfTest { result: if report.passed() { "pass" } else { "fail" }, detail: report.to_string() }
}

/// The simulated accelerator over `mem` with `faults`.
pub(crate) fn simulated<M: DmaTarget>(mem: M, faults: Faults) -> SimAccelerator<M> {
    let mut sim = SimAccelerator::with_memory(mem, SIM_BUSY_POLLS);
    if faults.wrong_pixel {
        sim.set_wrong_pixel(Some(WRONG_PIXEL));
    }
    sim
}

/// Frame slots per connection in frame mode: one being sent, one rendering.
pub const FRAME_SLOTS: usize = 2;

/// Bus address of the simulated frame ring (any 8-byte aligned value).
const RING_BASE: u32 = 0x0410_0000;

/// Host memory shared by the simulated frame DMA (which writes it) and the
/// frame ring (which reads it); `Send`, so that one ring can serve every
/// web connection's thread, as on the board (the lock is never contended:
/// the ring that owns it is behind a lock of its own).
#[derive(Clone)]
pub struct SharedMemory(Arc<Mutex<Vec<u8>>>);

impl SharedMemory {
    /// Zeroed memory for `slots` frame slots.
    pub fn new(slots: usize) -> SharedMemory {
        SharedMemory(Arc::new(Mutex::new(vec![0; slots * FRAME_BYTES])))
    }

    fn bytes(&self) -> std::sync::MutexGuard<'_, Vec<u8>> {
        // Nothing panics while holding it; a poisoned lock's bytes are whole.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn offset(addr: u32) -> Option<usize> {
        addr.checked_sub(RING_BASE).map(|o| o as usize)
    }
}

impl DmaTarget for SharedMemory {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        let mut mem = self.bytes();
        match Self::offset(addr).and_then(|o| mem.get_mut(o..o + bytes.len())) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                true
            }
            None => false,
        }
    }
}

impl FrameMemory for SharedMemory {
    fn slot_address(&self, slot: usize) -> u32 {
        RING_BASE + (slot * FRAME_BYTES) as u32
    }

    fn read_row(&mut self, slot: usize, y: u16, offset: usize, out: &mut [u8]) {
        SliceMemory::new(RING_BASE, &mut self.bytes()).read_row(slot, y, offset, out)
    }

    fn write_row(&mut self, slot: usize, y: u16, row: &[u8; ROW_BYTES]) {
        SliceMemory::new(RING_BASE, &mut self.bytes()).write_row(slot, y, row)
    }
}

/// The driver over a simulated accelerator whose frame DMA writes `M`.
pub type SimDriver<M> = Accelerator<SimAccelerator<M>, CountingDelay>;

/// Row mode: the driver over a fresh simulated accelerator with
/// `faults`, one frame.
pub fn row_frames(faults: Faults) -> RowFrames<SimDriver<hal_avalon::sim::NoMemory>, 1> {
    let accel =
        Accelerator::new(simulated(hal_avalon::sim::NoMemory, faults), CountingDelay::default(), PollTimeout::DEFAULT);
    RowFrames::new(accel)
}

/// The simulated accelerator's frame ring ([`frame_ring`]).
pub type SimFrameRing = FrameRing<SharedMemory, SimDriver<SharedMemory>, FRAME_SLOTS>;

/// Frame mode: a ring of [`FRAME_SLOTS`] in host memory, filled by the
/// simulated accelerator's frame DMA through the driver, with `faults`.
pub fn frame_ring(faults: Faults) -> SimFrameRing {
    let mem = SharedMemory::new(FRAME_SLOTS);
    let sim = simulated(mem.clone(), faults);
    FrameRing::new(mem, Accelerator::new(sim, CountingDelay::default(), PollTimeout::DEFAULT))
}

/// The driver over the Verilated RTL whose frame DMA writes `M`.
pub type RtlDriver<M> = Accelerator<rtl_port::RtlAccelerator<M>, CountingDelay>;

/// Row mode on the RTL.
pub fn rtl_row_frames() -> Result<RowFrames<RtlDriver<hal_avalon::sim::NoMemory>, 1>, rtl_port::NotBuilt> {
    let accel = Accelerator::new(rtl_port::RtlAccelerator::new()?, CountingDelay::default(), PollTimeout::DEFAULT);
    Ok(RowFrames::new(accel))
}

/// Frame mode on the RTL: its frame DMA's AXI master writes the ring.
pub fn rtl_frame_ring() -> Result<FrameRing<SharedMemory, RtlDriver<SharedMemory>, FRAME_SLOTS>, rtl_port::NotBuilt> {
    let mem = SharedMemory::new(FRAME_SLOTS);
    let rtl = rtl_port::RtlAccelerator::with_memory(mem.clone())?;
    Ok(FrameRing::new(mem, Accelerator::new(rtl, CountingDelay::default(), PollTimeout::DEFAULT)))
}

/// Simulated clocks so far, where the device counts them (the RTL).
pub trait Clocks {
    /// Clocks simulated since the device was made; `None` for a device
    /// without a clock.
    fn clocks(&mut self) -> Option<u64>;
}

impl Clocks for board::Share {
    fn clocks(&mut self) -> Option<u64> {
        None
    }
}

impl<M: DmaTarget> Clocks for RowFrames<SimDriver<M>, 1> {
    fn clocks(&mut self) -> Option<u64> {
        None
    }
}

impl Clocks for FrameRing<SharedMemory, SimDriver<SharedMemory>, FRAME_SLOTS> {
    fn clocks(&mut self) -> Option<u64> {
        None
    }
}

impl<M: DmaTarget> Clocks for RowFrames<RtlDriver<M>, 1> {
    fn clocks(&mut self) -> Option<u64> {
        Some(self.rows().port().cycles())
    }
}

impl Clocks for FrameRing<SharedMemory, RtlDriver<SharedMemory>, FRAME_SLOTS> {
    fn clocks(&mut self) -> Option<u64> {
        Some(self.engine().port().cycles())
    }
}

/// A running simulated board.
pub struct HpsSim {
    frame_addr: SocketAddr,
    persistent_addr: SocketAddr,
    stop: Arc<AtomicBool>,
    rtsp: Option<rtsp::RtspServer>,
    shared: Arc<web::Shared>,
    web: Option<web::WebServer>,
    /// The one frame supply, for a board started with
    /// [`start_board`](Self::start_board).
    board: Option<Arc<board::Board>>,
}

/// Where a seed connection's frames come from.
#[derive(Clone)]
enum Supply {
    /// A simulated accelerator of its own, as `config` says.
    Own(Config),
    /// The board's one ring.
    Board(Arc<board::Board>),
}

impl HpsSim {
    /// Listen on `addr` (seed protocol) and on its port + 1 (persistent),
    /// in frame mode, logging connections and requests to stderr. Port 0
    /// picks a free pair.
    pub fn start(addr: SocketAddr) -> io::Result<HpsSim> {
        HpsSim::start_with(addr, RenderMode::Frames, true)
    }

    /// [`HpsSim::start`] without the log (for a client that embeds the board).
    pub fn start_quiet(addr: SocketAddr) -> io::Result<HpsSim> {
        HpsSim::start_with(addr, RenderMode::Frames, false)
    }

    /// Listen on `addr` and its port + 1 with the simulated accelerator in
    /// `render` mode, logging to stderr if `verbose`.
    pub fn start_with(addr: SocketAddr, render: RenderMode, verbose: bool) -> io::Result<HpsSim> {
        HpsSim::start_config(addr, Config { render, device: Device::Sim, faults: Faults::default() }, verbose)
    }

    /// Listen on `addr` and its port + 1 running `config`, logging to
    /// stderr if `verbose`. With [`Device::Rtl`] in a build without the RTL
    /// the error says so (`rtl_port::NotBuilt`).
    pub fn start_config(addr: SocketAddr, config: Config, verbose: bool) -> io::Result<HpsSim> {
        if config.device == Device::Rtl && !rtl_port::available() {
            return Err(io::Error::new(io::ErrorKind::Unsupported, rtl_port::NotBuilt));
        }
        let shared = web::Shared::new(rt_services::camera::rtsp::RTSP_PORT, config, self_test(config));
        HpsSim::start_supply(addr, Supply::Own(config), shared, verbose)
    }

    /// Listen on `addr` and its port + 1 serving every client from `board`
    /// (one engine, one ring, each service within its quota, as on the
    /// board): the way `hps-linux` serves. The web page and RTSP, when
    /// started, draw from it too; `/status` says `facts`.
    pub fn start_board(
        addr: SocketAddr,
        board: Arc<board::Board>,
        facts: web::Facts,
        verbose: bool,
    ) -> io::Result<HpsSim> {
        let shared = web::Shared::with_board(rt_services::camera::rtsp::RTSP_PORT, board.clone(), facts);
        HpsSim::start_supply(addr, Supply::Board(board), shared, verbose)
    }

    fn start_supply(addr: SocketAddr, supply: Supply, shared: web::Shared, verbose: bool) -> io::Result<HpsSim> {
        let (single, persistent) = bind_pair(addr)?;
        let sim = HpsSim {
            frame_addr: single.local_addr()?,
            persistent_addr: persistent.local_addr()?,
            stop: Arc::new(AtomicBool::new(false)),
            rtsp: None,
            shared: Arc::new(shared),
            web: None,
            board: match &supply {
                Supply::Board(b) => Some(b.clone()),
                Supply::Own(_) => None,
            },
        };
        let ids = Arc::new(AtomicU64::new(1));
        let cap = ConnectionCap::new(rt_services::seed::SEED_SOCKETS);
        for (listener, mode) in [(single, Mode::Single), (persistent, Mode::Persistent)] {
            let (stop, ids, shared, cap) = (sim.stop.clone(), ids.clone(), sim.shared.clone(), cap.clone());
            let supply = supply.clone();
            thread::Builder::new()
                .name(format!("accept {mode:?}"))
                .spawn(move || accept_loop(listener, mode, &supply, &stop, &ids, &shared, &cap, verbose))?;
        }
        Ok(sim)
    }

    /// Address of the seed-protocol listener.
    pub fn frame_addr(&self) -> SocketAddr {
        self.frame_addr
    }

    /// Address of the persistent listener (the frame port + 1).
    pub fn persistent_addr(&self) -> SocketAddr {
        self.persistent_addr
    }

    /// Also serve RTSP/RTP ([`rtsp::RtspServer`]) on `addr` (port 0: any
    /// free one) with `device`, logging if `verbose`, without multicast.
    pub fn start_rtsp(&mut self, addr: SocketAddr, device: Device, verbose: bool) -> io::Result<SocketAddr> {
        self.start_rtsp_with(addr, rtsp::Options { device, verbose, multicast: None, faults: Faults::default() })
    }

    /// Also serve RTSP/RTP on `addr` as `options` say (from the board, for
    /// one started with [`start_board`](Self::start_board)).
    pub fn start_rtsp_with(&mut self, addr: SocketAddr, options: rtsp::Options) -> io::Result<SocketAddr> {
        let server = match &self.board {
            Some(board) => rtsp::RtspServer::start_on(addr, options, board.share(board::Service::Camera))?,
            None => rtsp::RtspServer::start(addr, options)?,
        };
        let addr = server.addr();
        self.rtsp = Some(server);
        self.shared.set_rtsp_port(addr.port());
        Ok(addr)
    }

    /// Also serve the board's web page ([`web`]) on `addr` (port 0: any
    /// free one), logging if `verbose`; returns its address.
    pub fn start_web(&mut self, addr: SocketAddr, verbose: bool) -> io::Result<SocketAddr> {
        let server = web::WebServer::start(addr, self.shared.clone(), verbose)?;
        let addr = server.addr();
        self.web = Some(server);
        Ok(addr)
    }

    /// The UDP port the RTSP server's RTP leaves from (RTCP: the next).
    pub fn rtsp_rtp_port(&self) -> Option<u16> {
        self.rtsp.as_ref().map(rtsp::RtspServer::rtp_port)
    }

    /// The RTSP listener's address, once [`start_rtsp`](Self::start_rtsp) ran.
    pub fn rtsp_addr(&self) -> Option<SocketAddr> {
        self.rtsp.as_ref().map(rtsp::RtspServer::addr)
    }
}

impl Drop for HpsSim {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the accept loops so they see the flag.
        for addr in [self.frame_addr, self.persistent_addr] {
            let _ = TcpStream::connect_timeout(&addr, Duration::from_millis(200));
        }
    }
}

fn bind_pair(addr: SocketAddr) -> io::Result<(TcpListener, TcpListener)> {
    if addr.port() != 0 {
        let second = SocketAddr::new(
            addr.ip(),
            persistent_port(addr.port())
                .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "listen port + 1 must be a valid port"))?,
        );
        return Ok((TcpListener::bind(addr)?, TcpListener::bind(second)?));
    }
    // Any free port whose successor is free too.
    let mut last_err = None;
    for _ in 0..64 {
        let first = TcpListener::bind(addr)?;
        let Some(next) = persistent_port(first.local_addr()?.port()) else {
            continue;
        };
        match TcpListener::bind(SocketAddr::new(addr.ip(), next)) {
            Ok(second) => return Ok((first, second)),
            Err(e) => last_err = Some(e),
        }
    }
    Err(last_err.unwrap_or_else(|| io::Error::new(io::ErrorKind::AddrInUse, "no free port pair")))
}

#[allow(clippy::too_many_arguments)]
fn accept_loop(
    listener: TcpListener,
    mode: Mode,
    supply: &Supply,
    stop: &AtomicBool,
    ids: &AtomicU64,
    shared: &Arc<web::Shared>,
    cap: &Arc<ConnectionCap>,
    verbose: bool,
) {
    for stream in listener.incoming() {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        match stream {
            Ok(stream) => {
                let Some(place) = cap.take() else {
                    // Every socket is taken: refused, as on the board.
                    drop(stream);
                    continue;
                };
                let id = ids.fetch_add(1, Ordering::Relaxed);
                let shared = shared.clone();
                let supply = supply.clone();
                let spawned = thread::Builder::new().name(format!("client {id}")).spawn(move || {
                    let _place = place;
                    // The page's status counts the seed clients.
                    shared.seed_clients.fetch_add(1, Ordering::Relaxed);
                    match supply {
                        Supply::Own(config) => serve_connection(stream, mode, config, Log::new(id, verbose)),
                        Supply::Board(board) => {
                            serve(stream, mode, &mut board.share(board::Service::Seed), Log::new(id, verbose))
                        }
                    }
                    shared.seed_clients.fetch_sub(1, Ordering::Relaxed);
                });
                if let Err(e) = spawned {
                    eprintln!("[{id}] cannot start a thread: {e}");
                }
            }
            Err(e) => eprintln!("accept failed: {e}"),
        }
    }
}

/// Connections served at once, as the board has sockets: each costs two
/// threads (its own and its reader), so a flood of connections must not
/// start threads without bound. One more is closed at once, as the board
/// answers a SYN with no socket listening with a reset.
#[derive(Debug)]
pub(crate) struct ConnectionCap {
    open: std::sync::atomic::AtomicUsize,
    max: usize,
}

/// One connection's place under a [`ConnectionCap`], given back on drop.
pub(crate) struct Place(Arc<ConnectionCap>);

impl ConnectionCap {
    pub(crate) fn new(max: usize) -> Arc<ConnectionCap> {
        Arc::new(ConnectionCap { open: std::sync::atomic::AtomicUsize::new(0), max })
    }

    /// A place, if one is free.
    pub(crate) fn take(self: &Arc<Self>) -> Option<Place> {
        self.open
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| (n < self.max).then_some(n + 1))
            .ok()
            .map(|_| Place(self.clone()))
    }
}

impl Drop for Place {
    fn drop(&mut self) {
        self.0.open.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Input from the reader thread.
enum Input {
    Bytes(Vec<u8>),
    End,
}

/// Log lines of one connection to stderr, prefixed with its id (or nowhere).
pub struct Log {
    id: u64,
    verbose: bool,
    line: String,
}

impl Log {
    /// The log of connection `id`; `verbose: false` discards it.
    pub fn new(id: u64, verbose: bool) -> Log {
        Log { id, verbose, line: String::new() }
    }
}

impl fmt::Write for Log {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        if !self.verbose {
            return Ok(());
        }
        self.line.push_str(s);
        while let Some(end) = self.line.find('\n') {
            let line = format!("[{}] {}", self.id, &self.line[..end]);
            eprintln!("{line}");
            keep(&line);
            self.line.drain(..=end);
        }
        Ok(())
    }
}

/// Bytes of log history kept for `/log`, as on the board.
pub const HISTORY_BYTES: usize = 8192;

/// The newest [`HISTORY_BYTES`] of the log, whole lines, every
/// connection's (the board's UART log is one too).
static HISTORY: Mutex<std::collections::VecDeque<u8>> = Mutex::new(std::collections::VecDeque::new());

/// Keep `line` in the history.
fn keep(line: &str) {
    let mut h = HISTORY.lock().unwrap_or_else(|e| e.into_inner());
    h.extend(line.as_bytes());
    h.push_back(b'\n');
    let over = h.len().saturating_sub(HISTORY_BYTES);
    h.drain(..over);
}

/// The log's newest lines, for `/log`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Tail;

impl rt_services::web::status::LogTail for Tail {
    fn tail(&self, out: &mut [u8]) -> usize {
        let h = HISTORY.lock().unwrap_or_else(|e| e.into_inner());
        let (old, new) = h.as_slices();
        rt_services::web::status::copy_tail([old, new], h.len() == HISTORY_BYTES, out)
    }
}

/// Serve one connection to its end with its own accelerator as `config`
/// says. Never panics on peer behaviour.
pub fn serve_connection(stream: TcpStream, mode: Mode, config: Config, mut log: Log) {
    let unavailable = match (config.device, config.render) {
        (Device::Sim, RenderMode::Frames) => return serve(stream, mode, &mut frame_ring(config.faults), log),
        (Device::Sim, RenderMode::Rows) => return serve(stream, mode, &mut row_frames(config.faults), log),
        (Device::Rtl, RenderMode::Frames) => match rtl_frame_ring() {
            Ok(mut ring) => return serve(stream, mode, &mut ring, log),
            Err(e) => e,
        },
        (Device::Rtl, RenderMode::Rows) => match rtl_row_frames() {
            Ok(mut rows) => return serve(stream, mode, &mut rows, log),
            Err(e) => e,
        },
    };
    let _ = fmt::Write::write_fmt(&mut log, format_args!("{unavailable}\n"));
}

fn serve<S: FrameSource + Clocks>(mut stream: TcpStream, mode: Mode, frames: &mut S, mut log: Log) {
    let peer = stream.peer_addr().map_or_else(|_| "?".into(), |a| a.to_string());
    let _ = fmt::Write::write_fmt(&mut log, format_args!("{mode:?} connection from {peer}\n"));
    let _ = stream.set_nodelay(true);
    // A client that stops reading must not hold its frames (on a board,
    // its service's share of the ring) for longer than the protocol's own
    // stall limit: a write blocked that long fails and the frame is given
    // back.
    let _ = stream.set_write_timeout(Some(rt_services::seed::server::SEND_TIMEOUT));
    let input = match stream.try_clone().and_then(spawn_reader) {
        Ok(rx) => rx,
        Err(e) => {
            let _ = fmt::Write::write_fmt(&mut log, format_args!("cannot read: {e}\n"));
            return;
        }
    };
    let start = Instant::now();
    let now = || ProtocolInstant::from_millis(u64::try_from(start.elapsed().as_millis()).unwrap_or(u64::MAX));
    let mut session = Session::new(mode, now());
    let mut pending: Vec<u8> = Vec::new();
    let mut input_ended = false;
    let mut frames = ClockLog { clocks_at_last: frames.clocks(), frames, line: None };
    let frames = &mut frames;
    loop {
        if !pending.is_empty() && session.wants_requests() {
            let n = session.receive(now(), &pending);
            pending.drain(..n);
        }
        if input_ended && pending.is_empty() {
            session.receive_eof();
        }
        let mut write_failed = false;
        let action = drive(
            &mut session,
            now(),
            frames,
            |fill| {
                // std TCP has no window into its buffer: copy a row's worth,
                // write what the stream takes (the rest is copied again).
                let mut buf = [0u8; ROW_BYTES];
                let n = fill(&mut buf);
                match stream.write(&buf[..n]) {
                    Ok(m) => m,
                    Err(_) => {
                        write_failed = true;
                        0
                    }
                }
            },
            &mut log,
        );
        if let Some(line) = frames.line.take() {
            let _ = fmt::Write::write_str(&mut log, &line);
        }
        match action {
            Action::Close(reason) => {
                let _ = match reason {
                    Closed::Done => fmt::Write::write_str(&mut log, "done\n"),
                    other => fmt::Write::write_fmt(&mut log, format_args!("closing: {other}\n")),
                };
                close_gracefully(&stream, &input, input_ended);
                return;
            }
            Action::Send { .. } => {
                let what = if write_failed { "vanished mid-frame; frame aborted" } else { "stopped taking data" };
                let _ = fmt::Write::write_fmt(&mut log, format_args!("client {what}\n"));
                session.abandon(frames);
                // The reader thread's socket is a copy: end it too.
                let _ = stream.shutdown(Shutdown::Both);
                return;
            }
            // The simulated accelerator moves on with every status read:
            // poll again at once.
            Action::Progress { .. } | Action::End { .. } => {}
            // No frame to be had yet (the ring or the service's quota is
            // full: other clients hold them): try again shortly.
            Action::Begin { .. } => thread::sleep(Duration::from_micros(200)),
            Action::Wait { deadline } => {
                if input_ended {
                    // Nothing more can arrive; poll again right away.
                    continue;
                }
                let wait = deadline.map_or(Duration::from_secs(3600), |d| {
                    d.saturating_duration_since(now()).max(Duration::from_millis(1))
                });
                match input.recv_timeout(wait) {
                    Ok(Input::Bytes(b)) => pending.extend_from_slice(&b),
                    Ok(Input::End) | Err(RecvTimeoutError::Disconnected) => input_ended = true,
                    Err(RecvTimeoutError::Timeout) => {}
                }
            }
        }
        // Take whatever else has arrived without waiting.
        while let Ok(msg) = input.try_recv() {
            match msg {
                Input::Bytes(b) => pending.extend_from_slice(&b),
                Input::End => input_ended = true,
            }
        }
    }
}

/// A frame source that notes, when a frame has been sent, the clocks the
/// device simulated since the previous one (rendering overlaps sending, so
/// in a stream of frames that is the time per frame).
struct ClockLog<'a, S> {
    frames: &'a mut S,
    clocks_at_last: Option<u64>,
    line: Option<String>,
}

impl<S: FrameSource + Clocks> FrameSource for ClockLog<'_, S> {
    type Frame = S::Frame;
    type Error = S::Error;

    fn begin(&mut self, light: &model::Light) -> Result<Option<S::Frame>, S::Error> {
        self.frames.begin(light)
    }

    fn rows_ready(&mut self, frame: S::Frame) -> Result<u16, S::Error> {
        self.frames.rows_ready(frame)
    }

    fn copy_row(&mut self, frame: S::Frame, y: u16, offset: usize, out: &mut [u8]) -> usize {
        self.frames.copy_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: S::Frame) {
        self.frames.end(frame);
        if let (Some(before), Some(now)) = (self.clocks_at_last, self.frames.clocks()) {
            let clocks = now.saturating_sub(before);
            self.line = Some(format!(
                "rtl: {clocks} clocks since the last frame, {} per row ({:.1} frames/s at 50 MHz)\n",
                clocks / u64::from(rt_services::frames::ROWS),
                50e6 / clocks.max(1) as f64
            ));
            self.clocks_at_last = Some(now);
        }
    }
}

fn spawn_reader(mut stream: TcpStream) -> io::Result<Receiver<Input>> {
    let (tx, rx) = mpsc::sync_channel(64);
    thread::Builder::new().name("reader".into()).spawn(move || {
        let mut buf = [0u8; 4096];
        loop {
            match stream.read(&mut buf) {
                Ok(0) | Err(_) => {
                    let _ = tx.send(Input::End);
                    return;
                }
                Ok(n) => {
                    if tx.send(Input::Bytes(buf[..n].to_vec())).is_err() {
                        return;
                    }
                }
            }
        }
    })?;
    Ok(rx)
}

/// Send FIN after the queued bytes, then wait (bounded) for the client to
/// finish so no unread input turns the close into a reset; then shut the
/// socket, so that the reader thread (which holds a copy of it) ends even
/// when the client never closes its side.
fn close_gracefully(stream: &TcpStream, input: &Receiver<Input>, input_ended: bool) {
    let _ = stream.shutdown(Shutdown::Write);
    if !input_ended {
        let deadline = Instant::now() + LINGER;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match input.recv_timeout(left) {
                Ok(Input::Bytes(_)) => {}
                Ok(Input::End) | Err(_) => break,
            }
        }
    }
    let _ = stream.shutdown(Shutdown::Both);
}
