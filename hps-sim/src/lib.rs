//! `hps-sim`: the board simulated on the host. The board's services on std
//! (`rt_services_std`: the seed frame server, the camera, the page) with a
//! device of its own per seed connection, rendering through hal-avalon's
//! driver and simulated accelerator, in either of the board's modes:
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
//! and per row. Faults can be injected ([`Fault`]) so that `rt-client
//! doctor` can be shown to name them.
//!
//! Every connection is served concurrently on its own thread with its own
//! simulated accelerator (a board has one accelerator and interleaves its
//! clients; on the host a device per client keeps the clients independent
//! and the frames identical); the page and the camera each have a ring of
//! their own.

use std::io;
use std::net::{SocketAddr, TcpStream};
use std::ops::{Deref, DerefMut};
use std::sync::Arc;

use hal_avalon::sim::{CountingDelay, DmaTarget, SimAccelerator};
use hal_avalon::{selftest, Accelerator, PollTimeout};
use rt_services::camera::sender::CAMERA_SLOTS;
use rt_services::seed::server::Mode;
use rt_services::{FrameRing, RowFrames};
use rt_services_std::board::Frames;
use rt_services_std::seed::{no_clocks, serve};
use rt_services_std::{rtsp, Facts, Log, OwnDevices, SelfTest, Server, SharedMemory};

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
    let mut sim = rt_services_std::simulated_accelerator(mem);
    if faults.wrong_pixel {
        sim.set_wrong_pixel(Some(WRONG_PIXEL));
    }
    sim
}

/// Frame slots per connection in frame mode: one being sent, one rendering.
pub const FRAME_SLOTS: usize = 2;

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

/// The RTL's simulated clocks so far, row mode ([`serve`]'s `clocks`).
fn rtl_row_clocks<M: DmaTarget>(rows: &mut RowFrames<RtlDriver<M>, 1>) -> Option<u64> {
    Some(rows.rows().port().cycles())
}

/// The RTL's simulated clocks so far, frame mode.
fn rtl_ring_clocks(ring: &mut FrameRing<SharedMemory, RtlDriver<SharedMemory>, FRAME_SLOTS>) -> Option<u64> {
    Some(ring.engine().port().cycles())
}

/// What `/status` says of a simulated board running `config` whose
/// self-test said `self_test`.
pub fn facts(config: Config, self_test: SelfTest) -> Facts {
    Facts {
        renderer: "simulated".into(),
        link: "loopback".into(),
        mode: match config.render {
            RenderMode::Frames => "frames",
            RenderMode::Rows => "rows",
        }
        .into(),
        version: config.faults.version().into(),
        register_map: Some(hal_avalon::map::ID_VERSION),
        fpga_build: Some(0),
        bridges: "not a board (hps-sim)".into(),
        vga: "off: not a board (hps-sim)".into(),
        address_from: "host".into(),
        self_test,
    }
}

/// The simulated board's devices: each user's own, as `config` says.
struct SimDevices(Config);

impl OwnDevices for SimDevices {
    fn serve_seed(&self, stream: TcpStream, mode: Mode, log: Log) {
        serve_connection(stream, mode, self.0, log)
    }

    fn web_frames(&self) -> Box<dyn Frames> {
        Box::new(frame_ring(self.0.faults))
    }

    fn start_camera(&self, addr: SocketAddr, options: rtsp::Options) -> io::Result<rtsp::RtspServer> {
        let faults = self.0.faults;
        match self.0.device {
            Device::Sim => rtsp::RtspServer::start_making(addr, options, move || {
                let mem = SharedMemory::new(CAMERA_SLOTS);
                let engine =
                    Accelerator::new(simulated(mem.clone(), faults), CountingDelay::default(), PollTimeout::DEFAULT);
                Ok(FrameRing::<_, _, CAMERA_SLOTS>::new(mem, engine))
            }),
            Device::Rtl => {
                if !rtl_port::available() {
                    return Err(io::Error::new(io::ErrorKind::Unsupported, rtl_port::NotBuilt));
                }
                rtsp::RtspServer::start_making(addr, options, || {
                    let mem = SharedMemory::new(CAMERA_SLOTS);
                    let rtl = rtl_port::RtlAccelerator::with_memory(mem.clone())
                        .map_err(|e| io::Error::new(io::ErrorKind::Unsupported, e))?;
                    let engine = Accelerator::new(rtl, CountingDelay::default(), PollTimeout::DEFAULT);
                    Ok(FrameRing::<_, _, CAMERA_SLOTS>::new(mem, engine))
                })
            }
        }
    }
}

/// A running simulated board: the services on std
/// ([`rt_services_std::Server`], which it derefs to) on devices of their
/// own.
pub struct HpsSim(Server);

impl Deref for HpsSim {
    type Target = Server;

    fn deref(&self) -> &Server {
        &self.0
    }
}

impl DerefMut for HpsSim {
    fn deref_mut(&mut self) -> &mut Server {
        &mut self.0
    }
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
        let facts = facts(config, self_test(config));
        Server::start_own(addr, Arc::new(SimDevices(config)), facts, verbose).map(HpsSim)
    }

    /// Also serve RTSP/RTP on `addr` (port 0: any free one) from a ring of
    /// the camera's own on the board's device, logging if `verbose`,
    /// without multicast.
    pub fn start_rtsp(&mut self, addr: SocketAddr, verbose: bool) -> io::Result<SocketAddr> {
        self.0.start_rtsp_with(addr, rtsp::Options::new(verbose))
    }
}

/// Serve one connection to its end with its own accelerator as `config`
/// says. Never panics on peer behaviour.
pub fn serve_connection(stream: TcpStream, mode: Mode, config: Config, mut log: Log) {
    let unavailable = match (config.device, config.render) {
        (Device::Sim, RenderMode::Frames) => {
            return serve(stream, mode, &mut frame_ring(config.faults), no_clocks, log)
        }
        (Device::Sim, RenderMode::Rows) => return serve(stream, mode, &mut row_frames(config.faults), no_clocks, log),
        (Device::Rtl, RenderMode::Frames) => match rtl_frame_ring() {
            Ok(mut ring) => return serve(stream, mode, &mut ring, rtl_ring_clocks, log),
            Err(e) => e,
        },
        (Device::Rtl, RenderMode::Rows) => match rtl_row_frames() {
            Ok(mut rows) => return serve(stream, mode, &mut rows, rtl_row_clocks, log),
            Err(e) => e,
        },
    };
    let _ = std::fmt::Write::write_fmt(&mut log, format_args!("{unavailable}\n"));
}
