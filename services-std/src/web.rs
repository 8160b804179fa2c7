//! The board's web page on std (`--http ADDR:PORT`): the
//! firmware's web connections (`rt_services::web::server`) on std TCP, a
//! thread per connection (at most [`WEB_SOCKETS`]), at most
//! [`WEB_VIEWERS`] WebSocket viewers at once, and, as on the board, one
//! ring of frames that every viewer shares, taken in turn
//! ([`Turns`]): two viewers that keep a request queued cannot hold both
//! slots while the others wait, here as there.

use std::fmt;
use std::io::{self, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU16, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use model::ROW_BYTES;
use rt_services::web::server::{drive, Action, Connection, Context, Turns, SEND_TIMEOUT};
use rt_services::web::status::{BoardStatus, Health, Identity, Viewers};
use rt_services::web::{WEB_SOCKETS, WEB_VIEWERS};
use rt_services::{FrameSource, Instant as ProtocolInstant};

use crate::board::{Board, Failed, Frames, Service, Share};
use crate::connection::{close_gracefully, spawn_reader, ConnectionCap, Input, ShutOnDrop};
use crate::{Log, OwnDevices, Tail};

/// The boot self-test's outcome, as `/status` gives it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SelfTest {
    /// `"pass"`, `"fail"` or `"skipped"`.
    pub result: &'static str,
    /// Its log line.
    pub detail: String,
}

/// What `/status` says of the board besides the live figures.
#[derive(Clone, Debug)]
pub struct Facts {
    /// Who renders, as the page names it: `simulated`, `fpga`, `software`.
    pub renderer: String,
    /// The link, in words.
    pub link: String,
    /// How frames are made: `frames`, `rows` or `software`.
    pub mode: String,
    /// The version it claims.
    pub version: String,
    /// The accelerator's register-map version, if one answers.
    pub register_map: Option<u16>,
    /// Its BUILD_ID (0: none recorded).
    pub fpga_build: Option<u32>,
    /// The bridges, in words.
    pub bridges: String,
    /// The VGA output, in words.
    pub vga: String,
    /// Where the address came from.
    pub address_from: String,
    /// The boot self-test's outcome.
    pub self_test: SelfTest,
}

/// What the connections share: the board's figures, and the frames.
pub struct Shared {
    started: Instant,
    /// What `/status` says of the board.
    facts: Facts,
    /// The board, when the frames are one's: what it says of itself now
    /// ([`Board::live`]) overrides `facts`' VGA and code.
    board: Option<Arc<Board>>,
    frames: Mutex<WebFrames>,
    /// Viewers now (the lock also orders handshakes against the cap).
    viewers: Mutex<usize>,
    /// Seed-protocol clients now (the seed listeners count them).
    pub seed_clients: AtomicUsize,
    frames_rendered: AtomicU64,
    frames_sent: AtomicU64,
    rtsp_port: AtomicU16,
}

impl Shared {
    /// Figures from now on; the page's RTSP URLs name `rtsp_port`; the
    /// viewers' frames from a ring of their own that `devices` makes;
    /// `/status` says `facts`.
    pub fn with_own(rtsp_port: u16, devices: Arc<dyn OwnDevices>, facts: Facts) -> Shared {
        Shared::with_source(rtsp_port, WebSource::Own { ring: None, devices }, facts)
    }

    /// As [`with_own`](Self::with_own), the viewers' frames from `board`
    /// (within the page's quota there).
    pub fn with_board(rtsp_port: u16, board: Arc<Board>, facts: Facts) -> Shared {
        let share = board.share(Service::Web);
        Shared { board: Some(board), ..Shared::with_source(rtsp_port, WebSource::Board(share), facts) }
    }

    fn with_source(rtsp_port: u16, source: WebSource, facts: Facts) -> Shared {
        Shared {
            started: Instant::now(),
            facts,
            board: None,
            frames: Mutex::new(WebFrames { source, turns: Turns::new(), taken: [false; WEB_SOCKETS] }),
            viewers: Mutex::new(0),
            seed_clients: AtomicUsize::new(0),
            frames_rendered: AtomicU64::new(0),
            frames_sent: AtomicU64::new(0),
            rtsp_port: AtomicU16::new(rtsp_port),
        }
    }

    /// The camera's port, once it listens.
    pub fn set_rtsp_port(&self, port: u16) {
        self.rtsp_port.store(port, Ordering::Relaxed);
    }

    /// Frames begun: by every service of a board, else the page's own
    /// (what `/status` calls `frames_rendered`).
    fn frames_rendered(&self) -> u64 {
        match &lock(&self.frames).source {
            WebSource::Board(share) => share.board().frames_begun(),
            WebSource::Own { .. } => self.frames_rendered.load(Ordering::Relaxed),
        }
    }

    fn viewers(&self) -> usize {
        self.viewers.lock().map_or(WEB_VIEWERS, |v| *v)
    }
}

/// The web listener: accepts until dropped.
pub struct WebServer {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
}

impl WebServer {
    /// Listen on `addr` (port 0: any free one), logging if `verbose`.
    pub fn start(addr: SocketAddr, shared: Arc<Shared>, verbose: bool) -> io::Result<WebServer> {
        let listener = TcpListener::bind(addr)?;
        let server = WebServer { addr: listener.local_addr()?, stop: Arc::new(AtomicBool::new(false)) };
        let stop = server.stop.clone();
        let cap = ConnectionCap::new(WEB_SOCKETS);
        thread::Builder::new().name("accept web".into()).spawn(move || {
            let mut id = 0u64;
            for stream in listener.incoming() {
                if stop.load(Ordering::SeqCst) {
                    return;
                }
                let Ok(stream) = stream else { continue };
                let Some(place) = cap.take() else {
                    // Every socket is taken: refused, as on the board.
                    drop(stream);
                    continue;
                };
                id += 1;
                let shared = shared.clone();
                let log = Log::new(id, verbose);
                let spawned = thread::Builder::new().name(format!("web {id}")).spawn(move || {
                    let _place = place;
                    serve(stream, &shared, log)
                });
                if let Err(e) = spawned {
                    eprintln!("web: cannot start a thread: {e}");
                }
            }
        })?;
        Ok(server)
    }

    /// The listener's address.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for WebServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        let _ = TcpStream::connect_timeout(&self.addr, Duration::from_millis(200));
    }
}

/// The web connections' frames: one ring, made when the first frame is
/// begun (a connection that asks for a page file or `/status` never makes
/// one), whose turn it is to begin a frame, and which turn places
/// (connection indices) are taken.
struct WebFrames {
    source: WebSource,
    turns: Turns<WEB_SOCKETS>,
    taken: [bool; WEB_SOCKETS],
}

/// Where the viewers' frames come from.
enum WebSource {
    /// A ring of their own, made when the first frame is begun.
    Own { ring: Option<Box<dyn Frames>>, devices: Arc<dyn OwnDevices> },
    /// The board's one ring.
    Board(Share),
}

impl WebSource {
    fn begin(&mut self, light: &model::Light) -> Result<Option<usize>, Failed> {
        match self {
            WebSource::Own { ring, devices } => ring.get_or_insert_with(|| devices.web_frames()).begin_frame(light),
            WebSource::Board(share) => share.begin(light),
        }
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, Failed> {
        match self {
            WebSource::Own { ring: Some(ring), .. } => ring.frame_rows(frame),
            WebSource::Own { ring: None, .. } => Ok(0),
            WebSource::Board(share) => share.rows_ready(frame),
        }
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        match self {
            WebSource::Own { ring: Some(ring), .. } => ring.copy_frame_row(frame, y, offset, out),
            WebSource::Own { ring: None, .. } => 0,
            WebSource::Board(share) => share.copy_row(frame, y, offset, out),
        }
    }

    fn end(&mut self, frame: usize) {
        match self {
            WebSource::Own { ring: Some(ring), .. } => ring.end_frame(frame),
            WebSource::Own { ring: None, .. } => {}
            WebSource::Board(share) => share.end(frame),
        }
    }
}

fn lock(frames: &Mutex<WebFrames>) -> std::sync::MutexGuard<'_, WebFrames> {
    // A connection thread that panicked left the ring as it was: go on.
    frames.lock().unwrap_or_else(|e| e.into_inner())
}

/// One connection's view of the shared frames (each call under the lock).
/// The frames it began and has not ended are ended when it is dropped,
/// so a connection thread that panics mid-frame gives them back (on a
/// board, to the page's quota) instead of holding them for good.
struct SharedFrames<'a> {
    frames: &'a Mutex<WebFrames>,
    /// Frames begun through it and not yet ended.
    open: Vec<usize>,
}

impl<'a> SharedFrames<'a> {
    fn new(frames: &'a Mutex<WebFrames>) -> SharedFrames<'a> {
        SharedFrames { frames, open: Vec::new() }
    }
}

impl Drop for SharedFrames<'_> {
    fn drop(&mut self) {
        // `end` takes each out of `open`.
        while let Some(&frame) = self.open.last() {
            self.end(frame);
        }
    }
}

impl FrameSource for SharedFrames<'_> {
    type Frame = usize;
    type Error = Failed;

    fn begin(&mut self, light: &model::Light) -> Result<Option<usize>, Failed> {
        let frame = lock(self.frames).source.begin(light)?;
        self.open.extend(frame);
        Ok(frame)
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, Failed> {
        lock(self.frames).source.rows_ready(frame)
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        lock(self.frames).source.copy_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: usize) {
        let Some(k) = self.open.iter().position(|&f| f == frame) else {
            // Not this connection's (or ended already): nothing to give back.
            return;
        };
        self.open.swap_remove(k);
        lock(self.frames).source.end(frame)
    }
}

/// A connection's place among the turns, given back on drop.
struct TurnPlace<'a> {
    frames: &'a Mutex<WebFrames>,
    index: usize,
}

impl<'a> TurnPlace<'a> {
    fn take(frames: &'a Mutex<WebFrames>) -> Option<TurnPlace<'a>> {
        let mut f = lock(frames);
        let index = f.taken.iter().position(|t| !t)?;
        f.taken[index] = true;
        Some(TurnPlace { frames, index })
    }
}

impl Drop for TurnPlace<'_> {
    fn drop(&mut self) {
        let mut f = lock(self.frames);
        f.turns.served(self.index, false);
        f.taken[self.index] = false;
    }
}

/// Frames begun through it count as rendered.
struct Counted<'a, S> {
    frames: &'a mut S,
    rendered: &'a AtomicU64,
}

impl<S: FrameSource> FrameSource for Counted<'_, S> {
    type Frame = S::Frame;
    type Error = S::Error;

    fn begin(&mut self, light: &model::Light) -> Result<Option<S::Frame>, S::Error> {
        let frame = self.frames.begin(light)?;
        if frame.is_some() {
            self.rendered.fetch_add(1, Ordering::Relaxed);
        }
        Ok(frame)
    }

    fn rows_ready(&mut self, frame: S::Frame) -> Result<u16, S::Error> {
        self.frames.rows_ready(frame)
    }

    fn copy_row(&mut self, frame: S::Frame, y: u16, offset: usize, out: &mut [u8]) -> usize {
        self.frames.copy_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: S::Frame) {
        self.frames.end(frame)
    }
}

/// How often a connection reads the board's live state for `/status`.
const LIVE_EVERY: std::time::Duration = std::time::Duration::from_millis(250);

fn serve(stream: TcpStream, shared: &Shared, mut log: Log) {
    // The cap on sockets keeps connections to WEB_SOCKETS: a place is free.
    let Some(place) = TurnPlace::take(&shared.frames) else { return };
    let mut ring = SharedFrames::new(&shared.frames);
    let mut frames = Counted { frames: &mut ring, rendered: &shared.frames_rendered };
    let _ = stream.set_nodelay(true);
    let _ = stream.set_write_timeout(Some(SEND_TIMEOUT));
    let input = match stream.try_clone().and_then(spawn_reader) {
        Ok(rx) => rx,
        Err(e) => {
            let _ = fmt::Write::write_fmt(&mut log, format_args!("web: cannot read: {e}\n"));
            return;
        }
    };
    // Writes go through a shared reference (`&TcpStream` writes too), so
    // that the guard can hold one.
    let mut stream = &stream;
    let _shut = ShutOnDrop(stream);
    let start = Instant::now();
    let now = || ProtocolInstant::from_millis(u64::try_from(start.elapsed().as_millis()).unwrap_or(u64::MAX));
    let mut connection = Connection::new(now());
    let mut pending: Vec<u8> = Vec::new();
    let mut input_ended = false;
    let mut viewer: Option<ViewerPlace<'_>> = None;
    let (mut live, mut live_at) = (None, None);
    loop {
        if !pending.is_empty() {
            let n = connection.receive(&pending);
            pending.drain(..n);
        }
        if input_ended && pending.is_empty() {
            connection.receive_eof();
        }
        let facts = &shared.facts;
        // The board's own state, looked at a few times a second (not for
        // every row sent).
        if live_at.is_none_or(|t: Instant| t.elapsed() >= LIVE_EVERY) {
            live_at = Some(Instant::now());
            live = shared.board.as_ref().and_then(|b| b.live());
        }
        let status_now = BoardStatus {
            uptime_s: shared.started.elapsed().as_secs(),
            renderer: &facts.renderer,
            link: &facts.link,
            frames_rendered: shared.frames_rendered(),
            frames_sent: shared.frames_sent.load(Ordering::Relaxed),
            viewers: Viewers {
                web: shared.viewers(),
                web_max: WEB_VIEWERS,
                seed: shared.seed_clients.load(Ordering::Relaxed),
                rtsp: 0,
            },
            rtsp_port: shared.rtsp_port.load(Ordering::Relaxed),
            identity: Identity {
                version: &facts.version,
                name: rt_services::DEFAULT_HOST_NAME,
                address: None,
                address_from: &facts.address_from,
                // The host's own interface: not this program's to report.
                mac: None,
                mac_from: "none",
                mac_clashes: 0,
            },
            health: Health {
                self_test: facts.self_test.result,
                self_test_detail: &facts.self_test.detail,
                mode: &facts.mode,
                register_map: facts.register_map,
                fpga_build: facts.fpga_build,
                bridges: &facts.bridges,
                vga: live.map_or(facts.vga.as_str(), |l| l.vga),
                code: live.map_or(if facts.self_test.result == "fail" { "E2" } else { "ok" }, |l| l.code),
            },
        };
        let before = connection.frames_sent();
        let mut write_failed = false;
        let mut send = |fill: &mut dyn FnMut(&mut [u8]) -> usize| {
            let mut buf = [0u8; ROW_BYTES];
            let n = fill(&mut buf);
            match stream.write_all(&buf[..n]) {
                Ok(()) => n,
                Err(_) => {
                    write_failed = true;
                    0
                }
            }
        };
        let action = if viewer.is_some() {
            let may_begin = lock(&shared.frames).turns.may_begin(place.index);
            let cx = Context {
                now: now(),
                room: false,
                status: &status_now,
                name: rt_services::DEFAULT_HOST_NAME,
                may_begin,
                log: &Tail,
            };
            let action = drive(&mut connection, &cx, &mut frames, &mut send, &mut log);
            lock(&shared.frames).turns.served(place.index, connection.wants_frame());
            action
        } else {
            // The cap holds across threads: a handshake is answered under
            // the lock.
            let mut count = shared.viewers.lock().unwrap_or_else(|e| e.into_inner());
            let cx = Context {
                now: now(),
                room: *count < WEB_VIEWERS,
                status: &status_now,
                name: rt_services::DEFAULT_HOST_NAME,
                may_begin: true,
                log: &Tail,
            };
            let action = drive(&mut connection, &cx, &mut frames, &mut send, &mut log);
            if connection.is_viewer() {
                *count += 1;
                viewer = Some(ViewerPlace(&shared.viewers));
                let _ = fmt::Write::write_fmt(&mut log, format_args!("web: viewer {} of {WEB_VIEWERS}\n", *count));
            }
            action
        };
        shared.frames_sent.fetch_add(u64::from(connection.frames_sent().wrapping_sub(before)), Ordering::Relaxed);
        let done = match action {
            Action::Close(reason) => {
                let _ = fmt::Write::write_fmt(&mut log, format_args!("web: {reason}\n"));
                if reason.graceful() {
                    close_gracefully(stream, &input, input_ended);
                }
                true
            }
            Action::Write | Action::Send { .. } if write_failed => {
                let _ = fmt::Write::write_str(&mut log, "web: client went away\n");
                connection.abandon(&mut frames);
                // The reader thread's socket is a copy: end it too.
                let _ = stream.shutdown(std::net::Shutdown::Both);
                true
            }
            Action::Wait { deadline } if !input_ended => {
                let mut wait = deadline.map_or(Duration::from_secs(3600), |d| {
                    d.saturating_duration_since(now()).max(Duration::from_millis(1))
                });
                if connection.wants_frame() {
                    // Waiting its turn: another thread's frame ending is
                    // no message to this one, so look again soon.
                    wait = wait.min(Duration::from_millis(2));
                }
                match input.recv_timeout(wait) {
                    Ok(Input::Bytes(b)) => pending.extend_from_slice(&b),
                    Ok(Input::End) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => input_ended = true,
                    Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
                }
                false
            }
            // Waiting for a slot or rows: the simulated accelerator moves on
            // with every status read.
            _ => false,
        };
        if done {
            break;
        }
        while let Ok(msg) = input.try_recv() {
            match msg {
                Input::Bytes(b) => pending.extend_from_slice(&b),
                Input::End => input_ended = true,
            }
        }
    }
    // Whatever ended it, a frame it held goes back to the shared ring (and
    // a viewer's place to the count, as `viewer` drops).
    connection.abandon(&mut frames);
}

/// A viewer's place in the count of viewers, given back on drop (also
/// when its connection's thread panics).
struct ViewerPlace<'a>(&'a Mutex<usize>);

impl Drop for ViewerPlace<'_> {
    fn drop(&mut self) {
        let mut count = self.0.lock().unwrap_or_else(|e| e.into_inner());
        *count = count.saturating_sub(1);
    }
}
