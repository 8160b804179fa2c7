//! `rt-client`: fetch frames from the ray tracer (board, emulated board or
//! the simulated board started in-process) as PNG, GIF or a live window.

mod control;
mod discover;
mod doctor;
mod live;
mod net;
mod orbit;
mod output;
mod rtsp;
mod script;
mod stats;
mod window;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::{Args, Parser, Subcommand, ValueEnum};
use hps_sim::HpsSim;
use indicatif::{ProgressBar, ProgressStyle};
use model::Light;

use crate::orbit::OrbitPath;
use crate::output::FrameSink;
use crate::stats::RunStats;

#[derive(Parser)]
#[command(name = "rt-client", version, about = "Client of the real-time FPGA ray tracer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fetch one frame over the seed protocol and save it as PNG.
    Frame {
        /// The server's frame port, HOST:PORT or HOST (port 7878). Without it, a simulated
        /// board is started in-process.
        #[arg(long)]
        server: Option<String>,
        /// Light position in world units: X,Y,Z.
        #[arg(long, allow_hyphen_values = true)]
        light: Light,
        /// Output PNG.
        #[arg(long, default_value = "frame.png")]
        out: PathBuf,
    },
    /// Animate the light orbiting the sphere over the persistent port.
    Orbit {
        #[command(flatten)]
        run: RunArgs,
        /// Output: an animated GIF (`*.gif`) or a directory of PNG frames.
        #[arg(long, default_value = "orbit.gif")]
        out: PathBuf,
        /// Show the frames live in a window as they arrive.
        #[arg(long)]
        show: bool,
    },
    /// Measure frames/s and latency of an orbit, saving nothing (with
    /// --transport rtsp: frames/s and how many frames came exact,
    /// repaired, damaged or were lost).
    Bench {
        #[command(flatten)]
        run: RunArgs,
    },
    /// A window onto the server's frames; move the light and see it
    /// re-rendered live.
    ///
    /// Mouse: drag with the left button orbits the light around the sphere
    /// (azimuth, elevation); the wheel changes its distance. Keys: arrows
    /// turn it by 5 degrees, PageUp/PageDown bring it closer/farther, Space
    /// starts/stops the automatic orbit, R resets, P saves the frame on
    /// screen as live-NNN.png, Escape (or closing the window) quits. The
    /// title shows the light, frames/s and median latency of the last
    /// second, the server and the connection state.
    Live {
        /// The server's frame port, HOST:PORT or HOST (7878; the persistent port is the
        /// next one). Without it, a simulated board is started in-process.
        #[arg(long)]
        server: Option<String>,
        /// Enlarge the window by this integer factor (1-8).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=8))]
        scale: u32,
        /// Replay timed input events from FILE instead of the mouse and keys
        /// (docs/live-viewer.md: one `MS EVENT` per line).
        #[arg(long)]
        script: Option<PathBuf>,
        /// How frames travel: `tcp`, one request per frame on the
        /// persistent port; `rtsp`, the `/live` RTP stream with the light
        /// moved by SET_PARAMETER (frames/s and latency then count every
        /// streamed frame).
        #[arg(long, value_enum, default_value_t = Transport::Tcp)]
        transport: Transport,
        /// The RTSP server, HOST:PORT, for --transport rtsp; default
        /// --server's host on port 8554.
        #[arg(long)]
        rtsp: Option<String>,
        /// Write the frames shown to an animated GIF.
        #[arg(long)]
        record: Option<PathBuf>,
        /// On exit, save the last frame shown as PNG.
        #[arg(long)]
        save_last: Option<PathBuf>,
    },
    /// List the boards on this network (mDNS/DNS-SD): name, address,
    /// version, renderer, fault code.
    Discover {
        /// Seconds to listen for answers.
        #[arg(long, default_value_t = 3)]
        wait: u64,
    },
    /// Check every link from here to the board's picture, one line each
    /// (a tick, or a cross and what to do); exit status 1 if any fails.
    Doctor {
        /// The board: a name (default raytracer.local) or an address.
        #[arg(default_value = "raytracer.local")]
        host: String,
        /// The seed port (hps-sim: its --listen port).
        #[arg(long, default_value_t = rt_services::FRAME_PORT)]
        seed_port: u16,
        /// The RTSP port.
        #[arg(long, default_value_t = rt_services::camera::rtsp::RTSP_PORT)]
        rtsp_port: u16,
        /// The page's port.
        #[arg(long, default_value_t = rt_services::web::WEB_PORT)]
        http_port: u16,
    },
    /// Print a server's stream URLs (light, orbit, live), for any RTSP
    /// player.
    Url {
        /// The server, HOST or HOST:PORT; PORT is the RTSP port (default
        /// 8554).
        #[arg(long)]
        server: String,
    },
    /// Measure the live viewer's input-to-screen latency (no window).
    BenchLive {
        /// The server's frame port; without it, a simulated board in-process.
        #[arg(long)]
        server: Option<String>,
        /// Input events to send.
        #[arg(long, default_value_t = 200)]
        events: usize,
        /// Input events per second.
        #[arg(long, default_value_t = 60.0)]
        hz: f64,
        /// tcp: a frame requested per light on the persistent port; rtsp:
        /// the `/live?fps=max` stream, its light moved by SET_PARAMETER.
        #[arg(long, value_enum, default_value_t = Transport::Tcp)]
        transport: Transport,
        /// The RTSP server, HOST:PORT, for --transport rtsp; default
        /// --server's host on port 8554.
        #[arg(long)]
        rtsp: Option<String>,
    },
}

#[derive(Args)]
struct RunArgs {
    /// The server's frame port, HOST:PORT or HOST (7878; the persistent port is the next
    /// one). Without it, a simulated board is started in-process.
    #[arg(long)]
    server: Option<String>,
    /// Number of frames (light positions) in one orbit.
    #[arg(long, default_value_t = 48, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Orbit radius in world units.
    #[arg(long, default_value_t = 3.0)]
    radius: f64,
    /// Light height in world units.
    #[arg(long, default_value_t = 4.0, allow_hyphen_values = true)]
    height: f64,
    /// How frames travel: `tcp`, one request per light on the persistent
    /// port (--frames lights evenly round the orbit); `rtsp`, the server's
    /// `/orbit` RTP stream, the light placed by stream time (--period),
    /// lost rows asked for again by NACK.
    #[arg(long, value_enum, default_value_t = Transport::Tcp)]
    transport: Transport,
    /// The RTSP server, HOST:PORT, for --transport rtsp; default
    /// --server's host on port 8554.
    #[arg(long)]
    rtsp: Option<String>,
    /// rtsp: seconds per turn. --frames frames span frames/rate seconds of
    /// the orbit; `--fps 24 --period F/24` makes F frames one turn, like tcp.
    #[arg(long, default_value_t = 2.0)]
    period: f64,
    /// rtsp: frames per second asked of the stream, 1-1000 or `max`.
    #[arg(long, default_value = "max", value_parser = parse_fps)]
    fps: String,
    /// rtsp: a fixed light, X,Y,Z in world units: the `/light/X,Y,Z`
    /// stream instead of the orbit.
    #[arg(long, allow_hyphen_values = true)]
    light: Option<String>,
}

/// How frames travel from the server.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Transport {
    /// The seed protocol's persistent TCP port: a request per frame.
    Tcp,
    /// An RTSP session and its RTP/UDP stream.
    Rtsp,
}

fn parse_fps(s: &str) -> Result<String, String> {
    match s.parse::<u16>() {
        _ if s.eq_ignore_ascii_case("max") => Ok("max".into()),
        Ok(n) if (1..=rt_services::camera::rtsp::MAX_FPS).contains(&n) => Ok(n.to_string()),
        _ => Err(format!("expected 1-{} or max", rt_services::camera::rtsp::MAX_FPS)),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Frame { server, light, out } => frame(server.as_deref(), &light, &out),
        Command::Live { server, scale, script, transport, rtsp, record, save_last } => {
            live(server, scale, script, transport, rtsp, record, save_last)
        }
        Command::Url { server } => url(&server),
        Command::Discover { wait } => discover::browse(std::time::Duration::from_secs(wait)).map(|boards| {
            print!("{}", discover::table(&boards));
        }),
        Command::Doctor { host, seed_port, rtsp_port, http_port } => {
            let target =
                doctor::Target { seed: seed_port, rtsp: rtsp_port, http: http_port, ..doctor::Target::board(&host) };
            println!("rt-client {} doctor: {}", env!("CARGO_PKG_VERSION"), target.host);
            let checks = doctor::run(&target, |c| println!("{c}"));
            let failed = checks.iter().filter(|c| !c.ok).count();
            if failed == 0 {
                println!("all {} checks passed", checks.len());
                Ok(())
            } else {
                Err(format!("{failed} of {} checks failed", checks.len()))
            }
        }
        Command::BenchLive { server, events, hz, transport: Transport::Tcp, .. } => {
            board(server.as_deref()).and_then(|(addr, _b)| live::bench(addr, events, hz))
        }
        Command::BenchLive { server, events, hz, transport: Transport::Rtsp, rtsp } => {
            rtsp_board(server.as_deref(), rtsp.as_deref())
                .and_then(|(addr, _b)| live::bench_rtsp(addr, &rtsp::stream_url(addr, "/live?fps=120"), events, hz))
        }
        Command::Orbit { run, out, show } => orbit(&run, Some(out), show),
        Command::Bench { run } => orbit(&run, None, false),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rt-client: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The server's frame port, or a simulated board started in-process
/// (kept alive by the returned handle).
fn board(server: Option<&str>) -> Result<(SocketAddr, Option<HpsSim>), String> {
    match server {
        Some(s) => Ok((net::resolve(s).map_err(|e| e.to_string())?, None)),
        None => {
            let board = HpsSim::start_quiet(SocketAddr::from(([127, 0, 0, 1], 0)))
                .map_err(|e| format!("cannot start the simulated board: {e}"))?;
            eprintln!(
                "rt-client: no --server: the frames come from a board simulated in this process ({}), \
                 not from a board; give --server HOST for one",
                board.frame_addr()
            );
            Ok((board.frame_addr(), Some(board)))
        }
    }
}

/// The RTSP server: `--rtsp`, else `--server`'s host on port 8554, else a
/// simulated board started in-process (kept alive by the returned handle).
fn rtsp_board(server: Option<&str>, rtsp: Option<&str>) -> Result<(SocketAddr, Option<HpsSim>), String> {
    match (rtsp, server) {
        (Some(r), _) => Ok((net::resolve(r).map_err(|e| e.to_string())?, None)),
        (None, Some(s)) => Ok((rtsp::rtsp_addr_of(net::resolve(s).map_err(|e| e.to_string())?), None)),
        (None, None) => {
            let mut board = HpsSim::start_quiet(SocketAddr::from(([127, 0, 0, 1], 0)))
                .map_err(|e| format!("cannot start the simulated board: {e}"))?;
            let addr = board
                .start_rtsp(SocketAddr::from(([127, 0, 0, 1], 0)), false)
                .map_err(|e| format!("cannot start the simulated board's RTSP server: {e}"))?;
            eprintln!(
                "rt-client: no --server: the stream comes from a board simulated in this process (RTSP on \
                 {addr}), not from a board; give --server HOST for one"
            );
            Ok((addr, Some(board)))
        }
    }
}

fn url(server: &str) -> Result<(), String> {
    let with_port = net::with_port(server, rt_services::camera::rtsp::RTSP_PORT);
    let base = format!("rtsp://{with_port}");
    println!("{base}/light/3,4,-2?fps=30        fixed light at (3, 4, -2), 30 frames/s");
    println!("{base}/orbit?radius=3&height=4&period=2&fps=max   orbiting light, one turn per 2 s, as fast as rendered");
    println!("{base}/live?fps=60                light moved by SET_PARAMETER (light: x,y,z), 60 frames/s");
    Ok(())
}

fn live(
    server: Option<String>,
    scale: u32,
    script: Option<PathBuf>,
    transport: Transport,
    rtsp: Option<String>,
    record: Option<PathBuf>,
    save_last: Option<PathBuf>,
) -> Result<(), String> {
    let script = match script {
        Some(p) => {
            Some(script::Script::parse(&std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?)?)
        }
        None => None,
    };
    let (target, _board) = match transport {
        Transport::Tcp => {
            let (addr, b) = board(server.as_deref())?;
            (live::Target::Tcp(net::persistent_addr(addr).map_err(|e| e.to_string())?), b)
        }
        Transport::Rtsp => {
            let (addr, b) = rtsp_board(server.as_deref(), rtsp.as_deref())?;
            (live::Target::Rtsp { addr, url: rtsp::stream_url(addr, "/live?fps=120") }, b)
        }
    };
    let server_name = match (&server, &target) {
        (_, live::Target::Rtsp { url, .. }) => url.clone(),
        (Some(s), _) => s.clone(),
        (None, live::Target::Tcp(addr)) => format!("simulated board {addr}"),
    };
    live::run(live::LiveOptions { target, server_name, scale: scale as usize, script, record, save_last })
}

fn frame(server: Option<&str>, light: &Light, out: &std::path::Path) -> Result<(), String> {
    let (addr, _board) = board(server)?;
    let start = Instant::now();
    let rgb = net::fetch_frame(addr, light).map_err(|e| e.to_string())?;
    let took = start.elapsed();
    output::save_png(&rgb, out)?;
    println!("wrote {} ({:.1} ms)", out.display(), took.as_secs_f64() * 1e3);
    Ok(())
}

fn orbit(args: &RunArgs, out: Option<PathBuf>, show: bool) -> Result<(), String> {
    if args.transport == Transport::Rtsp {
        return orbit_rtsp(args, out, show);
    }
    let path = OrbitPath { frames: args.frames as usize, radius: args.radius, height: args.height };
    let lights = path.lights().map_err(|e| format!("orbit leaves the light range: {e}"))?;
    // Keep the in-process board alive for the whole run.
    let (addr, _board) = board(args.server.as_deref())?;
    let mut window = if show { Some(window::LiveWindow::open("rt-client orbit")?) } else { None };
    let mut sink = FrameSink::new(out)?;
    let bar = ProgressBar::new(lights.len() as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut sink_error = None;
    let persistent = net::persistent_addr(addr).map_err(|e| e.to_string())?;
    let stats: RunStats = orbit::run(persistent, &lights, |_, rgb| {
        bar.inc(1);
        if let Err(e) = sink.push(rgb) {
            sink_error = Some(e);
            return false;
        }
        window.as_mut().is_none_or(|w| w.show(rgb))
    })
    .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    if let Some(e) = sink_error {
        return Err(e);
    }
    println!("{}", stats.report());
    finish_sink(sink)
}

/// Wait for the encoder and say how long it took, apart from the stream.
fn finish_sink(sink: FrameSink) -> Result<(), String> {
    let waited = Instant::now();
    if let Some(w) = sink.finish()? {
        println!(
            "{}; encoding took {:.2} s, {:.2} s of it after the last frame",
            w.summary,
            w.busy.as_secs_f64(),
            waited.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// `orbit`/`bench` over RTSP: `--frames` frames of the `/orbit` stream.
fn orbit_rtsp(args: &RunArgs, out: Option<PathBuf>, show: bool) -> Result<(), String> {
    let (addr, _board) = rtsp_board(args.server.as_deref(), args.rtsp.as_deref())?;
    let path = match &args.light {
        Some(light) => {
            light.parse::<Light>().map_err(|e| format!("--light {light}: {e}"))?;
            format!("/light/{}?fps={}", light.replace(',', "/"), args.fps)
        }
        None => format!("/orbit?radius={}&height={}&period={}&fps={}", args.radius, args.height, args.period, args.fps),
    };
    let url = rtsp::stream_url(addr, &path);
    let frames = args.frames as usize;
    let mut window = if show { Some(window::LiveWindow::open("rt-client orbit")?) } else { None };
    let mut sink = FrameSink::new(out)?;
    let bar = ProgressBar::new(frames as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let mut stream = rtsp::RtpStream::open(addr, &url).map_err(|e| e.to_string())?;
    let (mut got, mut first_at, mut last_at) = (0usize, None, start);
    let mut failure: Option<String> = None;
    let mut closed = false;
    while got < frames && failure.is_none() && !closed {
        stream
            .receive(rtsp::STREAM_TIMEOUT, |f| {
                if got >= frames || failure.is_some() {
                    return;
                }
                got += 1;
                last_at = Instant::now();
                first_at.get_or_insert(last_at);
                bar.inc(1);
                if let Err(e) = sink.push(f.pixels) {
                    failure = Some(e);
                }
                closed |= window.as_mut().is_some_and(|w| !w.show(f.pixels));
            })
            .map_err(|e| e.to_string())?;
    }
    let counts = stream.counts();
    let repair_delay = stream.repair_delay();
    if let Err(e) = stream.close() {
        eprintln!("rt-client: {e}");
    }
    bar.finish_and_clear();
    if let Some(e) = failure {
        return Err(e);
    }
    let elapsed = last_at.duration_since(start).as_secs_f64().max(1e-9);
    // The rate between the first frame and the last leaves out the set-up.
    let steady = first_at.map(|f| last_at.duration_since(f).as_secs_f64()).filter(|&s| s > 0.0 && got > 1);
    println!(
        "{got} frames in {elapsed:.2} s over RTSP: {:.1} frames/s ({} after the first), {:.1} MB/s\n\
         frames: {} exact, {} repaired, {} damaged ({} crowded out by newer frames), {} lost; \
         {} NACKs for {} rows, {} duplicates, {} late; repairs took {}",
        got as f64 / elapsed,
        steady.map_or("-".into(), |s| format!("{:.1}", (got - 1) as f64 / s)),
        got as f64 * model::FRAME_BYTES as f64 / elapsed / 1e6,
        counts.exact,
        counts.repaired,
        counts.damaged,
        counts.crowded_out,
        counts.lost,
        counts.nacks,
        counts.rows_nacked,
        counts.duplicates,
        counts.late,
        repair_delay.map_or("-".into(), |d| format!("{} ms", d.as_millis())),
    );
    finish_sink(sink)
}
