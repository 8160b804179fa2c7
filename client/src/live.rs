//! `rt-client live`: a window onto the server's frames, with the light
//! under the mouse and the keys (docs/live-viewer.md).
//!
//! The window loop runs on the main thread: it polls input (mouse and
//! keys, or a script), turns it into a light ([`Control`]), and hands new
//! lights to the coalescer ([`Requests`]), which allows at most
//! [`DEPTH`] requests on the persistent connection. A reader thread
//! receives frames and passes them back over a channel. When the server
//! goes away the window keeps running, the title and stderr say so, and the
//! link reconnects with back-off.

use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::thread;
use std::time::{Duration, Instant};

use minifb::{Key as MfKey, KeyRepeat, MouseButton, MouseMode, Window, WindowOptions};
use model::{Light, FRAME_BYTES, HEIGHT, WIDTH};

use crate::control::{Control, Effect, Input, Key, Requests, DEPTH};
use crate::net;
use crate::output::{save_png, FrameSink};
use crate::rtsp::RtpStream;
use crate::script::Script;

/// Where the frames come from.
#[derive(Clone, Debug)]
pub enum Target {
    /// The persistent port: one frame per light requested.
    Tcp(SocketAddr),
    /// An RTSP server's `/live` stream at `url`: frames at the stream's
    /// rate, the light moved by `SET_PARAMETER`.
    Rtsp {
        /// The RTSP server.
        addr: SocketAddr,
        /// The stream's URL.
        url: String,
    },
}

impl std::fmt::Display for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Target::Tcp(a) => write!(f, "{a}"),
            Target::Rtsp { url, .. } => f.write_str(url),
        }
    }
}

/// `rt-client live` options after the server is known.
pub struct LiveOptions {
    /// Where the frames come from.
    pub target: Target,
    /// What the title calls the server.
    pub server_name: String,
    /// Integer window scale.
    pub scale: usize,
    /// Replayed input instead of the mouse and keys.
    pub script: Option<Script>,
    /// Write what was shown as a GIF.
    pub record: Option<PathBuf>,
    /// On exit, save the last frame shown as PNG (tests compare it).
    pub save_last: Option<PathBuf>,
}

/// What the reader thread reports.
pub(crate) enum FromServer {
    /// A whole frame.
    Frame(Vec<u8>),
    /// The connection ended, and why.
    Lost(String),
}

/// One connection: requests written here, frames read by a thread.
pub(crate) struct Link {
    lights: LightsTo,
    pub(crate) frames: Receiver<FromServer>,
}

/// Where a [`Link`]'s lights go.
enum LightsTo {
    /// Requests on the persistent connection.
    Tcp(TcpStream),
    /// To the RTSP thread, which sends them as `SET_PARAMETER`.
    Rtsp(mpsc::Sender<Light>),
}

impl Link {
    pub(crate) fn open(target: &Target) -> Result<Link, String> {
        match target {
            Target::Tcp(addr) => Link::open_tcp(*addr),
            Target::Rtsp { addr, url } => Link::open_rtsp(*addr, url),
        }
    }

    /// The RTSP stream on a thread that owns it: between datagrams it
    /// sends the newest light asked for.
    fn open_rtsp(addr: SocketAddr, url: &str) -> Result<Link, String> {
        let mut stream = RtpStream::open(addr, url).map_err(|e| e.to_string())?;
        let (tx, frames) = mpsc::channel();
        let (lights, wanted) = mpsc::channel::<Light>();
        thread::Builder::new()
            .name("rtsp".into())
            .spawn(move || loop {
                let mut newest = None;
                loop {
                    match wanted.try_recv() {
                        Ok(l) => newest = Some(l),
                        Err(mpsc::TryRecvError::Empty) => break,
                        // The window went away: stop (the drop tears down).
                        Err(mpsc::TryRecvError::Disconnected) => return,
                    }
                }
                if let Some(l) = newest {
                    if let Err(e) = stream.set_light(&l) {
                        let _ = tx.send(FromServer::Lost(e.to_string()));
                        return;
                    }
                }
                let sent = stream.receive(Duration::from_millis(5), |f| {
                    let _ = tx.send(FromServer::Frame(f.pixels.to_vec()));
                });
                if let Err(e) = sent {
                    let _ = tx.send(FromServer::Lost(e.to_string()));
                    return;
                }
            })
            .map_err(|e| format!("thread: {e}"))?;
        Ok(Link { lights: LightsTo::Rtsp(lights), frames })
    }

    fn open_tcp(addr: SocketAddr) -> Result<Link, String> {
        let stream = net::connect(addr).map_err(|e| e.to_string())?;
        let mut reader = stream.try_clone().map_err(|e| format!("socket: {e}"))?;
        // No read timeout: a quiet server is normal while nothing is asked.
        reader.set_read_timeout(None).map_err(|e| format!("socket: {e}"))?;
        let (tx, frames) = mpsc::channel();
        thread::Builder::new()
            .name("frames".into())
            .spawn(move || loop {
                let mut frame = vec![0u8; FRAME_BYTES];
                match net::read_frame(&mut reader, 0, &mut frame) {
                    Ok(()) => {
                        if tx.send(FromServer::Frame(frame)).is_err() {
                            return;
                        }
                    }
                    Err(e) => {
                        let _ = tx.send(FromServer::Lost(e.to_string()));
                        return;
                    }
                }
            })
            .map_err(|e| format!("thread: {e}"))?;
        Ok(Link { lights: LightsTo::Tcp(stream), frames })
    }

    pub(crate) fn request(&mut self, light: &Light) -> Result<(), String> {
        match &mut self.lights {
            LightsTo::Tcp(stream) => net::send_request(stream, light).map_err(|e| e.to_string()),
            LightsTo::Rtsp(tx) => tx.send(*light).map_err(|_| "the RTSP stream stopped".into()),
        }
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        if let LightsTo::Tcp(stream) = &self.lights {
            let _ = stream.shutdown(std::net::Shutdown::Both);
        }
    }
}

/// Back-off between reconnection attempts.
fn backoff(attempt: u32) -> Duration {
    Duration::from_millis((250u64 << attempt.min(5)).min(5_000))
}

/// Frames/s and median latency of the last second.
#[derive(Default)]
struct Recent {
    frames: Vec<(Instant, Duration)>,
}

impl Recent {
    fn push(&mut self, now: Instant, latency: Duration) {
        self.frames.push((now, latency));
        self.frames.retain(|(t, _)| now.duration_since(*t) <= Duration::from_secs(1));
    }

    fn summary(&mut self, now: Instant) -> (usize, Duration) {
        self.frames.retain(|(t, _)| now.duration_since(*t) <= Duration::from_secs(1));
        let mut l: Vec<Duration> = self.frames.iter().map(|f| f.1).collect();
        l.sort();
        (l.len(), l.get(l.len() / 2).copied().unwrap_or_default())
    }
}

fn rgb_to_pixels(rgb: &[u8], scale: usize, out: &mut [u32]) {
    let w = WIDTH * scale;
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let i = (y * WIDTH + x) * 3;
            let px = crate::window::pack_rgb(&rgb[i..i + 3]);
            for sy in 0..scale {
                let row = (y * scale + sy) * w + x * scale;
                out[row..row + scale].fill(px);
            }
        }
    }
}

fn keys_of(window: &Window) -> Vec<Key> {
    window
        .get_keys_pressed(KeyRepeat::Yes)
        .into_iter()
        .filter_map(|k| match k {
            MfKey::Left => Some(Key::Left),
            MfKey::Right => Some(Key::Right),
            MfKey::Up => Some(Key::Up),
            MfKey::Down => Some(Key::Down),
            MfKey::PageUp => Some(Key::PageUp),
            MfKey::PageDown => Some(Key::PageDown),
            MfKey::Space => Some(Key::Space),
            MfKey::R => Some(Key::R),
            MfKey::P => Some(Key::P),
            MfKey::Escape => Some(Key::Escape),
            _ => None,
        })
        .collect()
}

/// Run the viewer until the user quits (or the script ends).
pub fn run(opts: LiveOptions) -> Result<(), String> {
    let scale = opts.scale.clamp(1, 8);
    let (w, h) = (WIDTH * scale, HEIGHT * scale);
    let mut window = Window::new("rt-client live", w, h, WindowOptions::default())
        .map_err(|e| format!("cannot open a window (is DISPLAY set?): {e}"))?;
    window.set_target_fps(120);
    let mut pixels = vec![0u32; w * h];
    let persistent = opts.target.clone();
    let mut sink = FrameSink::new(opts.record.clone())?;

    let mut control = Control::default();
    let mut requests = Requests::new(DEPTH);
    let mut sent_at: Vec<(u64, Instant)> = Vec::new();
    let mut recent = Recent::default();
    let mut link: Option<Link> = None;
    let (mut attempt, mut retry_at) = (0u32, Instant::now());
    let mut status = String::from("connecting");
    let mut last_frame: Option<Vec<u8>> = None;
    let mut last_light: Option<Light> = None;
    let mut tag = 0u64;
    let mut saved = 0u32;
    let mut last_tick = Instant::now();
    let mut title_at = Instant::now();
    let mut drag_from: Option<(f32, f32)> = None;
    let start = Instant::now();
    // A scripted session logs every request (its tests compare them).
    let log_requests = opts.script.is_some();
    let mut script = opts.script;
    let mut quitting = false;

    while window.is_open() {
        let now = Instant::now();
        // ---- Input ----
        let mut inputs = vec![Input::Tick(now.duration_since(last_tick))];
        last_tick = now;
        match script.as_mut() {
            Some(s) => match s.due(now.duration_since(start)) {
                Some(events) => inputs.extend(events),
                None => quitting = true,
            },
            None => {
                if window.get_mouse_down(MouseButton::Left) {
                    if let Some((x, y)) = window.get_mouse_pos(MouseMode::Pass) {
                        if let Some((x0, y0)) = drag_from {
                            let s = scale as f64;
                            inputs.push(Input::Drag(f64::from(x - x0) / s, f64::from(y - y0) / s));
                        }
                        drag_from = Some((x, y));
                    }
                } else {
                    drag_from = None;
                }
                if let Some((_, dy)) = window.get_scroll_wheel() {
                    inputs.push(Input::Wheel(f64::from(dy).signum()));
                }
                inputs.extend(keys_of(&window).into_iter().map(Input::Key));
            }
        }
        for i in inputs {
            match control.apply(i) {
                Effect::Quit => quitting = true,
                Effect::Save => {
                    if let Some(f) = &last_frame {
                        let path = PathBuf::from(format!("live-{saved:03}.png"));
                        saved += 1;
                        match save_png(f, &path) {
                            Ok(()) => eprintln!("rt-client: saved {}", path.display()),
                            Err(e) => eprintln!("rt-client: {e}"),
                        }
                    }
                }
                Effect::None => {}
            }
        }

        // ---- Connection ----
        if link.is_none() && now >= retry_at {
            match Link::open(&persistent) {
                Ok(l) => {
                    link = Some(l);
                    attempt = 0;
                    status = "connected".into();
                    eprintln!("rt-client: connected to {persistent}");
                    sent_at.clear();
                    if let Some((l, t)) = requests.reconnected() {
                        send(&mut link, &mut status, &l, t, &mut sent_at);
                    }
                }
                Err(e) => {
                    retry_at = now + backoff(attempt);
                    attempt += 1;
                    status = format!("no server: {e}; retrying");
                    eprintln!("rt-client: {e}; retrying in {:?}", backoff(attempt - 1));
                }
            }
        }

        // ---- Requests ----
        tag += 1;
        if let Some((l, t)) = requests.want(control.orbit.light(), tag) {
            if log_requests {
                eprintln!("rt-client: request light raw {:?}", l.raw());
            }
            send(&mut link, &mut status, &l, t, &mut sent_at);
        }

        // ---- Frames ----
        loop {
            let msg = match link.as_ref().map(|l| l.frames.try_recv()) {
                Some(Ok(m)) => m,
                Some(Err(TryRecvError::Disconnected)) => FromServer::Lost("connection closed".into()),
                Some(Err(TryRecvError::Empty)) | None => break,
            };
            match msg {
                FromServer::Frame(rgb) => {
                    let (done, next) = requests.arrived();
                    if let Some((l, t)) = done {
                        if let Some(i) = sent_at.iter().position(|(st, _)| *st == t) {
                            recent.push(Instant::now(), sent_at.remove(i).1.elapsed());
                        }
                        last_light = Some(l);
                    }
                    if let Some((l, t)) = next {
                        if log_requests {
                            eprintln!("rt-client: request light raw {:?}", l.raw());
                        }
                        send(&mut link, &mut status, &l, t, &mut sent_at);
                    }
                    rgb_to_pixels(&rgb, scale, &mut pixels);
                    if let Err(e) = sink.push(&rgb) {
                        eprintln!("rt-client: {e}");
                    }
                    last_frame = Some(rgb);
                }
                FromServer::Lost(why) => {
                    eprintln!("rt-client: lost the server: {why}");
                    status = format!("lost the server ({why}); reconnecting");
                    link = None;
                    retry_at = Instant::now() + backoff(0);
                }
            }
        }

        // ---- Screen ----
        if now.duration_since(title_at) >= Duration::from_millis(250) {
            title_at = now;
            let (fps, median) = recent.summary(now);
            let (x, y, z) = control.orbit.position();
            window.set_title(&format!(
                "rt-client live | light ({x:.2}, {y:.2}, {z:.2}) | {fps} frames/s, median {:.0} ms | {} | {status}",
                median.as_secs_f64() * 1e3,
                opts.server_name
            ));
        }
        // Redrawn every pass: minifb gathers input events in its update.
        if window.update_with_buffer(&pixels, w, h).is_err() {
            break;
        }
        // A quitting script waits for the frames of its last light.
        if quitting && (script.is_none() || requests.in_flight() == 0 || link.is_none()) {
            break;
        }
    }
    if let Some(path) = &opts.save_last {
        let f = last_frame.as_ref().ok_or("no frame was shown")?;
        save_png(f, path)?;
        if let Some(l) = last_light {
            eprintln!("rt-client: last frame shown: light raw {:?}, saved to {}", l.raw(), path.display());
        }
    }
    if let Some(written) = sink.finish()? {
        eprintln!("rt-client: {}", written.summary);
    }
    Ok(())
}

fn send(link: &mut Option<Link>, status: &mut String, light: &Light, tag: u64, sent_at: &mut Vec<(u64, Instant)>) {
    if let Some(l) = link.as_mut() {
        match l.request(light) {
            Ok(()) => sent_at.push((tag, Instant::now())),
            Err(e) => {
                eprintln!("rt-client: {e}");
                *status = format!("lost the server ({e}); reconnecting");
                *link = None;
            }
        }
    }
}

/// The row whose pixels tell which light a streamed frame has (crosses the
/// sphere and the floor, where the light shows).
const PROBE_ROW: u16 = 200;

/// `rt-client bench-live --transport rtsp`: the same input at `hz` for
/// `events` events, each moving the live stream's light with
/// `SET_PARAMETER`; an event is on screen with the first frame showing its
/// light or a later one (recognised by one row rendered with the model:
/// frames carry no request tag over RTP).
pub fn bench_rtsp(addr: SocketAddr, url: &str, events: usize, hz: f64) -> Result<(), String> {
    let mut link = Link::open(&Target::Rtsp { addr, url: url.to_string() })?;
    let mut control = Control::default();
    let period = Duration::from_secs_f64(1.0 / hz.max(1.0));
    let start = Instant::now();
    // Per event: when, and the probe row of its light.
    let mut sent: Vec<(Instant, Vec<u8>)> = Vec::with_capacity(events);
    let mut latencies: Vec<Duration> = Vec::with_capacity(events);
    let mut frames = 0usize;
    let probe = |l: &Light| {
        let mut words = [0u32; model::WIDTH];
        model::render_row(PROBE_ROW, l, &mut words);
        words.iter().flat_map(|w| [(w >> 16) as u8, (w >> 8) as u8, *w as u8]).collect::<Vec<u8>>()
    };
    let row = usize::from(PROBE_ROW) * model::ROW_BYTES..(usize::from(PROBE_ROW) + 1) * model::ROW_BYTES;
    loop {
        let now = Instant::now();
        while sent.len() < events && now >= start + period * sent.len() as u32 {
            control.apply(Input::Drag(5.0, 0.0));
            let l = control.orbit.light();
            sent.push((Instant::now(), probe(&l)));
            link.request(&l)?;
        }
        match link.frames.recv_timeout(Duration::from_millis(1)) {
            Ok(FromServer::Frame(f)) => {
                frames += 1;
                let arrived = Instant::now();
                let shown = f.get(row.clone()).ok_or("a short frame")?;
                // The newest event whose light this frame shows: it and
                // every event before it are on screen.
                if let Some(k) = sent.iter().rposition(|(_, p)| p.as_slice() == shown) {
                    while latencies.len() <= k {
                        latencies.push(arrived.duration_since(sent[latencies.len()].0));
                    }
                }
            }
            Ok(FromServer::Lost(why)) => return Err(format!("lost the server: {why}")),
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => return Err("lost the server".into()),
        }
        if latencies.len() == events {
            break;
        }
        if start.elapsed() > Duration::from_secs(600) {
            return Err("no end after 10 minutes".into());
        }
    }
    print_latencies(events, hz, frames, start, &mut latencies, "over RTSP");
    Ok(())
}

fn print_latencies(events: usize, hz: f64, frames: usize, start: Instant, latencies: &mut [Duration], how: &str) {
    latencies.sort();
    let pct =
        |p: f64| latencies.get(((latencies.len() as f64 - 1.0) * p).round() as usize).copied().unwrap_or_default();
    println!(
        "{events} input events at {hz:.0} Hz, {frames} frames in {:.2} s {how}; input to screen: median {:.1} ms, 95th percentile {:.1} ms, max {:.1} ms",
        start.elapsed().as_secs_f64(),
        pct(0.5).as_secs_f64() * 1e3,
        pct(0.95).as_secs_f64() * 1e3,
        pct(1.0).as_secs_f64() * 1e3
    );
}

/// `rt-client bench-live`: input-to-screen latency without a window. Drag
/// events arrive at `hz` for `events` events through the same control,
/// coalescing and connection as the viewer; an event is on screen with
/// the first frame whose request was made at or after it.
pub fn bench(server: SocketAddr, events: usize, hz: f64) -> Result<(), String> {
    let persistent = net::persistent_addr(server).map_err(|e| e.to_string())?;
    let mut link = Link::open(&Target::Tcp(persistent))?;
    let mut control = Control::default();
    let mut requests = Requests::new(DEPTH);
    let period = Duration::from_secs_f64(1.0 / hz.max(1.0));
    let start = Instant::now();
    let mut event_at: Vec<Instant> = Vec::with_capacity(events);
    let mut latencies: Vec<Duration> = Vec::with_capacity(events);
    let mut reflected = 0usize;
    let mut frames = 0usize;
    loop {
        let now = Instant::now();
        while event_at.len() < events && now >= start + period * event_at.len() as u32 {
            let i = event_at.len() as u64;
            event_at.push(Instant::now());
            control.apply(Input::Drag(5.0, 0.0));
            if let Some((l, t)) = requests.want(control.orbit.light(), i) {
                debug_assert_eq!(t, i);
                link.request(&l)?;
            }
        }
        match link.frames.recv_timeout(Duration::from_millis(1)) {
            Ok(FromServer::Frame(_)) => {
                frames += 1;
                let (done, next) = requests.arrived();
                let arrived = Instant::now();
                if let Some((_, tag)) = done {
                    while reflected <= tag as usize && reflected < event_at.len() {
                        latencies.push(arrived.duration_since(event_at[reflected]));
                        reflected += 1;
                    }
                }
                if let Some((l, _)) = next {
                    link.request(&l)?;
                }
            }
            Ok(FromServer::Lost(why)) => return Err(format!("lost the server: {why}")),
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => return Err("lost the server".into()),
        }
        if event_at.len() == events && requests.in_flight() == 0 {
            break;
        }
        if start.elapsed() > Duration::from_secs(600) {
            return Err("no end after 10 minutes".into());
        }
    }
    print_latencies(events, hz, frames, start, &mut latencies, "over TCP");
    Ok(())
}
