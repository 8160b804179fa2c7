//! `hps-sim`: the board simulated on the host. The firmware's frame server
//! (`rt_protocol::server`) on std TCP, rendering through hal-avalon's row
//! driver and simulated accelerator.
//!
//! Two listeners: the seed protocol on the listen port and the persistent
//! protocol on the listen port + 1. Every connection is served concurrently
//! on its own thread with its own simulated accelerator (a board has one
//! accelerator and interleaves rows; on the host a device per client keeps
//! the clients independent and the frames identical).

use std::fmt;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use hal_avalon::sim::{CountingDelay, SimAccelerator};
use hal_avalon::{Accelerator, PollTimeout};
use model::{Light, WIDTH};
use rt_protocol::server::{drive, Action, Closed, Mode, RowSource, Session};
use rt_protocol::{persistent_port, Instant as ProtocolInstant};

/// STATUS polls a simulated row stays busy for: enough that the driver's
/// polling loop runs, few enough to cost nothing.
const SIM_BUSY_POLLS: u32 = 2;

/// How long a closing connection waits for the client's end of stream
/// before it is dropped (closing with unread input would reset the
/// connection and could cost the client the frame's tail).
const LINGER: Duration = Duration::from_secs(2);

/// The row driver over a simulated accelerator, as a row source.
pub struct SimRows(Accelerator<SimAccelerator, CountingDelay>);

impl SimRows {
    /// A fresh simulated accelerator behind the real driver.
    pub fn new() -> SimRows {
        SimRows(Accelerator::new(
            SimAccelerator::with_busy_polls(SIM_BUSY_POLLS),
            CountingDelay::default(),
            PollTimeout::DEFAULT,
        ))
    }
}

impl Default for SimRows {
    fn default() -> Self {
        SimRows::new()
    }
}

impl RowSource for SimRows {
    type Error = hal_avalon::Error;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Self::Error> {
        self.0.run_row(y, light, out)
    }
}

/// A running simulated board.
pub struct HpsSim {
    frame_addr: SocketAddr,
    persistent_addr: SocketAddr,
    stop: Arc<AtomicBool>,
}

impl HpsSim {
    /// Listen on `addr` (seed protocol) and on its port + 1 (persistent),
    /// logging connections and requests to stderr. Port 0 picks a free pair.
    pub fn start(addr: SocketAddr) -> io::Result<HpsSim> {
        HpsSim::start_with(addr, true)
    }

    /// [`HpsSim::start`] without the log (for a client that embeds the board).
    pub fn start_quiet(addr: SocketAddr) -> io::Result<HpsSim> {
        HpsSim::start_with(addr, false)
    }

    fn start_with(addr: SocketAddr, verbose: bool) -> io::Result<HpsSim> {
        let (single, persistent) = bind_pair(addr)?;
        let sim = HpsSim {
            frame_addr: single.local_addr()?,
            persistent_addr: persistent.local_addr()?,
            stop: Arc::new(AtomicBool::new(false)),
        };
        let ids = Arc::new(AtomicU64::new(1));
        for (listener, mode) in [(single, Mode::Single), (persistent, Mode::Persistent)] {
            let (stop, ids) = (sim.stop.clone(), ids.clone());
            thread::Builder::new()
                .name(format!("accept {mode:?}"))
                .spawn(move || accept_loop(listener, mode, &stop, &ids, verbose))?;
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

fn accept_loop(listener: TcpListener, mode: Mode, stop: &AtomicBool, ids: &AtomicU64, verbose: bool) {
    for stream in listener.incoming() {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        match stream {
            Ok(stream) => {
                let id = ids.fetch_add(1, Ordering::Relaxed);
                let spawned = thread::Builder::new()
                    .name(format!("client {id}"))
                    .spawn(move || serve_connection(stream, mode, Log::new(id, verbose)));
                if let Err(e) = spawned {
                    eprintln!("[{id}] cannot start a thread: {e}");
                }
            }
            Err(e) => eprintln!("accept failed: {e}"),
        }
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
            eprintln!("[{}] {}", self.id, &self.line[..end]);
            self.line.drain(..=end);
        }
        Ok(())
    }
}

/// Serve one connection to its end. Never panics on peer behaviour.
pub fn serve_connection(mut stream: TcpStream, mode: Mode, mut log: Log) {
    let peer = stream.peer_addr().map_or_else(|_| "?".into(), |a| a.to_string());
    let _ = fmt::Write::write_fmt(&mut log, format_args!("{mode:?} connection from {peer}\n"));
    let _ = stream.set_nodelay(true);
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
    let mut rows = SimRows::new();
    let mut row = [0u32; WIDTH];
    let mut pending: Vec<u8> = Vec::new();
    let mut input_ended = false;
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
            &mut rows,
            &mut row,
            |bytes| match stream.write(bytes) {
                Ok(n) => n,
                Err(_) => {
                    write_failed = true;
                    0
                }
            },
            &mut log,
        );
        match action {
            Action::Close(reason) => {
                let _ = match reason {
                    Closed::Done => fmt::Write::write_str(&mut log, "done\n"),
                    other => fmt::Write::write_fmt(&mut log, format_args!("closing: {other}\n")),
                };
                close_gracefully(&stream, &input, input_ended);
                return;
            }
            Action::Send => {
                let what = if write_failed { "vanished mid-frame; frame aborted" } else { "stopped taking data" };
                let _ = fmt::Write::write_fmt(&mut log, format_args!("client {what}\n"));
                return;
            }
            Action::Render { .. } => {}
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
/// finish so no unread input turns the close into a reset.
fn close_gracefully(stream: &TcpStream, input: &Receiver<Input>, input_ended: bool) {
    let _ = stream.shutdown(Shutdown::Write);
    if input_ended {
        return;
    }
    let deadline = Instant::now() + LINGER;
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match input.recv_timeout(left) {
            Ok(Input::Bytes(_)) => {}
            Ok(Input::End) | Err(_) => return,
        }
    }
}
