//! The seed protocol's two listeners (`rt_services::seed::server`) on std
//! TCP: every connection on a thread of its own, at most
//! [`SEED_SOCKETS`](rt_services::seed::SEED_SOCKETS) at once.

use std::fmt;
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use model::ROW_BYTES;
use rt_services::seed::server::{drive, Action, Closed, Mode, Session};
use rt_services::{FrameSource, Instant as ProtocolInstant};

use crate::board::Service;
use crate::connection::{close_gracefully, spawn_reader, ConnectionCap, Input, ShutOnDrop};
use crate::{web, Log, Supply};

#[allow(clippy::too_many_arguments)]
pub(crate) fn accept_loop(
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
                    // The page's status counts the seed clients (also
                    // when this thread panics: the guard counts it out).
                    let _counted = Counted::new(&shared.seed_clients);
                    match supply {
                        Supply::Own(devices) => devices.serve_seed(stream, mode, Log::new(id, verbose)),
                        Supply::Board(board) => {
                            serve(stream, mode, &mut board.share(Service::Seed), no_clocks, Log::new(id, verbose))
                        }
                    }
                });
                if let Err(e) = spawned {
                    eprintln!("[{id}] cannot start a thread: {e}");
                }
            }
            Err(e) => eprintln!("accept failed: {e}"),
        }
    }
}

/// One connection counted in a count of clients while it lives.
struct Counted<'a>(&'a AtomicUsize);

impl<'a> Counted<'a> {
    fn new(count: &'a AtomicUsize) -> Counted<'a> {
        count.fetch_add(1, Ordering::Relaxed);
        Counted(count)
    }
}

impl Drop for Counted<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::Relaxed);
    }
}

/// The clocks of a device without a clock ([`serve`]'s `clocks`).
pub fn no_clocks<S>(_: &mut S) -> Option<u64> {
    None
}

/// Serve one seed connection to its end from `frames`; `clocks` reads the
/// simulated clocks so far where the device counts them (the RTL: each
/// frame then logs its clocks), else `None`. Never panics on peer
/// behaviour.
pub fn serve<S: FrameSource>(
    stream: TcpStream,
    mode: Mode,
    frames: &mut S,
    clocks: fn(&mut S) -> Option<u64>,
    mut log: Log,
) {
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
    // Writes go through a shared reference (`&TcpStream` writes too), so
    // that the guard can hold one.
    let mut stream = &stream;
    let _shut = ShutOnDrop(stream);
    let start = Instant::now();
    let now = || ProtocolInstant::from_millis(u64::try_from(start.elapsed().as_millis()).unwrap_or(u64::MAX));
    let mut session = Session::new(mode, now());
    let mut pending: Vec<u8> = Vec::new();
    let mut input_ended = false;
    let mut frames = ClockLog { clocks_at_last: clocks(frames), frames, clocks, line: None };
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
                match std::io::Write::write(&mut stream, &buf[..n]) {
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
                close_gracefully(stream, &input, input_ended);
                return;
            }
            Action::Send { .. } => {
                let what = if write_failed { "vanished mid-frame; frame aborted" } else { "stopped taking data" };
                let _ = fmt::Write::write_fmt(&mut log, format_args!("client {what}\n"));
                session.abandon(frames);
                // The guard shuts the socket, the reader thread's copy too.
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
    clocks: fn(&mut S) -> Option<u64>,
    clocks_at_last: Option<u64>,
    line: Option<String>,
}

impl<S: FrameSource> FrameSource for ClockLog<'_, S> {
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
        if let (Some(before), Some(now)) = (self.clocks_at_last, (self.clocks)(self.frames)) {
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
