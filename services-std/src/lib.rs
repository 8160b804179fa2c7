//! `rt-services-std`: the board's services on std, what the host
//! simulation (`hps-sim`) and the board's Linux program (`hps-linux`) both
//! run. The sans-IO services of `rt_services` on std sockets and threads:
//!
//! * [`seed`]: the seed protocol on the listen port and the persistent
//!   protocol on the next, a thread per connection, at most as many at
//!   once as the board has sockets (`rt_services::seed::SEED_SOCKETS`);
//!   one more is closed at once, as the board refuses it;
//! * [`rtsp`]: the network camera (RTSP on TCP, RTP and RTCP on UDP);
//! * [`web`]: the web page (`--http`), the live picture in a browser, and
//!   the status facts it shows ([`web::Facts`]);
//! * [`board`]: one frame supply for every service, each within its
//!   quota, as on the board;
//! * [`cli`]: the command-line flags the two programs share.
//!
//! Where frames come from is the program's: a [`board::Board`] (one
//! engine and one ring for everyone, as on the board: hps-linux) or
//! [`OwnDevices`], a device of its own per seed connection and a ring each
//! for the page and the camera (hps-sim: clients stay independent and
//! their frames identical).

pub mod board;
pub mod cli;
mod connection;
mod log;
mod memory;
pub mod rtsp;
pub mod seed;
pub mod web;

use std::io;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use rt_services::persistent_port;
use rt_services::seed::server::Mode;

pub use log::{Log, Tail, HISTORY_BYTES};
pub use memory::{simulated_accelerator, SharedMemory, SIM_BUSY_POLLS};
pub use web::{Facts, SelfTest};

use connection::ConnectionCap;

/// Devices of their own for each user of a server without a
/// [`board::Board`]: what hps-sim runs (a simulated or Verilated
/// accelerator per seed connection, a ring each for the page and the
/// camera).
pub trait OwnDevices: Send + Sync {
    /// Serve one seed connection to its end with a device of its own
    /// ([`seed::serve`] on it).
    fn serve_seed(&self, stream: TcpStream, mode: Mode, log: Log);
    /// The page's frame ring, made when its first frame is begun.
    fn web_frames(&self) -> Box<dyn board::Frames>;
    /// Start the camera on `addr` with a ring of its own.
    fn start_camera(&self, addr: SocketAddr, options: rtsp::Options) -> io::Result<rtsp::RtspServer>;
}

/// Where a server's frames come from.
#[derive(Clone)]
pub(crate) enum Supply {
    /// Devices of each user's own.
    Own(Arc<dyn OwnDevices>),
    /// The board's one ring.
    Board(Arc<board::Board>),
}

/// A running server: the seed listeners, and the camera and the page once
/// started; stops accepting when dropped.
pub struct Server {
    frame_addr: SocketAddr,
    persistent_addr: SocketAddr,
    stop: Arc<AtomicBool>,
    rtsp: Option<rtsp::RtspServer>,
    shared: Arc<web::Shared>,
    web: Option<web::WebServer>,
    supply: Supply,
}

impl Server {
    /// Listen on `addr` (seed protocol) and on its port + 1 (persistent),
    /// every client on devices of its own from `devices`; `/status` says
    /// `facts`; logging connections and requests to stderr if `verbose`.
    /// Port 0 picks a free pair.
    pub fn start_own(
        addr: SocketAddr,
        devices: Arc<dyn OwnDevices>,
        facts: web::Facts,
        verbose: bool,
    ) -> io::Result<Server> {
        let shared = web::Shared::with_own(rt_services::camera::rtsp::RTSP_PORT, devices.clone(), facts);
        Server::start_supply(addr, Supply::Own(devices), shared, verbose)
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
    ) -> io::Result<Server> {
        let shared = web::Shared::with_board(rt_services::camera::rtsp::RTSP_PORT, board.clone(), facts);
        Server::start_supply(addr, Supply::Board(board), shared, verbose)
    }

    fn start_supply(addr: SocketAddr, supply: Supply, shared: web::Shared, verbose: bool) -> io::Result<Server> {
        let (single, persistent) = bind_pair(addr)?;
        let server = Server {
            frame_addr: single.local_addr()?,
            persistent_addr: persistent.local_addr()?,
            stop: Arc::new(AtomicBool::new(false)),
            rtsp: None,
            shared: Arc::new(shared),
            web: None,
            supply,
        };
        let ids = Arc::new(AtomicU64::new(1));
        let cap = ConnectionCap::new(rt_services::seed::SEED_SOCKETS);
        for (listener, mode) in [(single, Mode::Single), (persistent, Mode::Persistent)] {
            let (stop, ids, shared, cap) = (server.stop.clone(), ids.clone(), server.shared.clone(), cap.clone());
            let supply = server.supply.clone();
            thread::Builder::new()
                .name(format!("accept {mode:?}"))
                .spawn(move || seed::accept_loop(listener, mode, &supply, &stop, &ids, &shared, &cap, verbose))?;
        }
        Ok(server)
    }

    /// Address of the seed-protocol listener.
    pub fn frame_addr(&self) -> SocketAddr {
        self.frame_addr
    }

    /// Address of the persistent listener (the frame port + 1).
    pub fn persistent_addr(&self) -> SocketAddr {
        self.persistent_addr
    }

    /// Also serve RTSP/RTP on `addr` (port 0: any free one) as `options`
    /// say, from the board or a ring of the camera's own.
    pub fn start_rtsp_with(&mut self, addr: SocketAddr, options: rtsp::Options) -> io::Result<SocketAddr> {
        let server = match &self.supply {
            Supply::Board(board) => rtsp::RtspServer::start_on(addr, options, board.share(board::Service::Camera))?,
            Supply::Own(devices) => devices.start_camera(addr, options)?,
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

    /// The RTSP listener's address, once [`start_rtsp_with`](Self::start_rtsp_with) ran.
    pub fn rtsp_addr(&self) -> Option<SocketAddr> {
        self.rtsp.as_ref().map(rtsp::RtspServer::addr)
    }
}

impl Drop for Server {
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
