//! Real players as the suite's viewers: GStreamer's `gst-launch-1.0`,
//! FFmpeg and `rt-client`, each started on a stream URL for a number of
//! frames, their frames gathered (with the time each arrived) to be
//! checked against the model. GStreamer and FFmpeg write raw RGB frames to
//! their standard output, `rt-client` PNGs to a folder; each exits by
//! itself after its frames, sending TEARDOWN, as a user's would.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use model::FRAME_BYTES;

use super::tools::root;
use super::Result;

/// Debian's packages for the players: GStreamer's tools and its RTSP
/// client and RFC 4175 depayloader, FFmpeg.
pub const PLAYER_PACKAGES: [&str; 4] =
    ["gstreamer1.0-tools", "gstreamer1.0-plugins-base", "gstreamer1.0-plugins-good", "ffmpeg"];

/// Which player, and how it asks for the stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// GStreamer's rtspsrc, RTP over UDP (`protocols=udp`).
    GstUdp,
    /// GStreamer's rtspsrc, RTP inside the RTSP connection (`protocols=tcp`).
    GstTcp,
    /// GStreamer's rtspsrc from a multicast group (`protocols=udp-mcast`).
    GstMulticast,
    /// FFmpeg, RTP inside the RTSP connection (`-rtsp_transport tcp`).
    FfmpegTcp,
    /// FFmpeg, RTP over UDP.
    FfmpegUdp,
    /// The project's own client (`rt-client orbit --transport rtsp`).
    RtClient,
}

impl Kind {
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Kind::GstUdp => "GStreamer (UDP)",
            Kind::GstTcp => "GStreamer (RTP over RTSP/TCP)",
            Kind::GstMulticast => "GStreamer (multicast)",
            Kind::FfmpegTcp => "FFmpeg (RTP over RTSP/TCP)",
            Kind::FfmpegUdp => "FFmpeg (UDP)",
            Kind::RtClient => "rt-client (UDP, NACK repair)",
        }
    }
}

/// Frames with the time each arrived.
type Frames = Vec<(Instant, Vec<u8>)>;

/// A player running.
pub struct Player {
    kind: Kind,
    /// Frames asked for.
    wanted: usize,
    child: Option<Child>,
    frames: Arc<Mutex<Frames>>,
    reader: Option<JoinHandle<()>>,
    dir: PathBuf,
    started: Instant,
    command: String,
}

/// What a player got.
pub struct Played {
    /// The player.
    pub kind: Kind,
    /// Its frames, each with when it arrived (rt-client's: when the run
    /// ended; its rate is its own report's).
    pub frames: Vec<(Instant, Vec<u8>)>,
    /// Frames per second, steady (the second half of its frames; for
    /// rt-client, its own figure after the first frame).
    pub fps: f64,
    /// What it said on standard error (and rt-client on its output).
    pub log: String,
}

impl Player {
    /// Start `kind` on `url` (an `rtsp://` URL) for `frames` frames; its
    /// files go under `dir`. `rt-client` needs `light` (world units, the
    /// URL's light) and the server's RTSP address.
    pub fn start(kind: Kind, url: &str, frames: usize, dir: &Path) -> Result<Player> {
        Player::start_in(None, kind, url, frames, dir)
    }

    /// [`start`](Self::start), inside the network namespace `netns` if one
    /// is given (`ip netns exec`).
    pub fn start_in(netns: Option<&str>, kind: Kind, url: &str, frames: usize, dir: &Path) -> Result<Player> {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut cmd = match kind {
            Kind::GstUdp | Kind::GstTcp | Kind::GstMulticast => {
                let protocols = match kind {
                    Kind::GstUdp => "udp",
                    Kind::GstTcp => "tcp",
                    _ => "udp-mcast",
                };
                let mut c = Command::new("gst-launch-1.0");
                // `identity eos-after=N` ends the stream as the Nth buffer
                // arrives (it is not passed on): N - 1 frames reach fdsink,
                // then gst-launch exits and rtspsrc sends TEARDOWN.
                c.arg("-q")
                    .arg("rtspsrc")
                    .arg(format!("location={url}"))
                    .arg(format!("protocols={protocols}"))
                    // A second of jitter buffer: time for its NACKs (AVPF) to be
                    // answered by a board that renders on its CPU.
                    .args(["latency=1000", "!", "rtpvrawdepay", "!", "identity"])
                    .arg(format!("eos-after={}", frames + 1))
                    .args(["!", "fdsink", "fd=1", "sync=false"]);
                c
            }
            Kind::FfmpegTcp | Kind::FfmpegUdp => {
                let mut c = Command::new("ffmpeg");
                let transport = if kind == Kind::FfmpegTcp { "tcp" } else { "udp" };
                // No probing: the description says what the stream is, and
                // a probe holds the first seconds of frames back.
                c.args(["-nostdin", "-loglevel", "error", "-analyzeduration", "0", "-probesize", "32"]);
                c.args(["-rtsp_transport", transport]);
                if kind == Kind::FfmpegUdp {
                    c.args(["-buffer_size", "4194304"]);
                }
                // Each frame as it came: without passthrough FFmpeg repeats
                // frames to a constant rate (fps=max announces none).
                c.args(["-i", url, "-fps_mode", "passthrough", "-frames:v", &frames.to_string()]);
                c.args(["-f", "rawvideo", "pipe:1"]);
                c
            }
            Kind::RtClient => {
                let (server, light) = rt_client_target(url)?;
                let mut c = Command::new(root().join("target/release/rt-client"));
                c.args(["orbit", "--transport", "rtsp", "--rtsp", &server, "--fps", "max"])
                    .arg(format!("--light={light}"))
                    .args(["--frames", &frames.to_string(), "--out"])
                    .arg(dir);
                c
            }
        };
        if let Some(ns) = netns {
            let mut wrapped = Command::new("ip");
            wrapped.args(["netns", "exec", ns]).arg(cmd.get_program()).args(cmd.get_args());
            cmd = wrapped;
        }
        let command = format!("{cmd:?}");
        let err = std::fs::File::create(dir.join("stderr.log")).map_err(|e| e.to_string())?;
        cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(err);
        let mut child = cmd.spawn().map_err(|e| format!("{}: {e}", kind.name()))?;
        let frames_got = Arc::new(Mutex::new(Vec::new()));
        let mut out = child.stdout.take().ok_or("no standard output")?;
        let sink = frames_got.clone();
        let raw = kind != Kind::RtClient;
        let log_path = dir.join("stdout.log");
        let reader = thread::spawn(move || {
            if !raw {
                let mut text = Vec::new();
                let _ = out.read_to_end(&mut text);
                let _ = std::fs::write(log_path, text);
                return;
            }
            let mut frame = vec![0u8; FRAME_BYTES];
            while out.read_exact(&mut frame).is_ok() {
                if let Ok(mut f) = sink.lock() {
                    f.push((Instant::now(), frame.clone()));
                }
            }
        });
        Ok(Player {
            kind,
            wanted: frames,
            child: Some(child),
            frames: frames_got,
            reader: Some(reader),
            dir: dir.to_path_buf(),
            started: Instant::now(),
            command,
        })
    }

    /// Frames received so far.
    pub fn received(&self) -> usize {
        self.frames.lock().map(|f| f.len()).unwrap_or(0)
    }

    /// Wait for the player to finish (killed after `timeout`); what it got.
    pub fn wait(mut self, timeout: Duration) -> Result<Played> {
        let mut child = self.child.take().ok_or("no player")?;
        let status = loop {
            if let Some(s) = child.try_wait().map_err(|e| e.to_string())? {
                break s;
            }
            if self.started.elapsed() > timeout {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!(
                    "{} did not finish within {timeout:?} ({} frames so far): {}\n{}",
                    self.kind.name(),
                    self.received(),
                    self.command,
                    self.log()
                ));
            }
            thread::sleep(Duration::from_millis(20));
        };
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
        let log = self.log();
        let complete = self.received() >= self.wanted;
        let race = complete && is_gstreamer_shutdown_race(self.kind, &log);
        if !status.success() && !race {
            return Err(format!("{} failed ({status}): {}\n{log}", self.kind.name(), self.command));
        }
        let mut frames = std::mem::take(&mut *self.frames.lock().map_err(|_| "frames lost")?);
        let mut fps = rate(&frames);
        if self.kind == Kind::RtClient {
            frames = read_pngs(&self.dir)?;
            fps = rt_client_rate(&log).ok_or(format!("no rate in rt-client's report: {log}"))?;
        }
        Ok(Played { kind: self.kind, frames, fps, log })
    }

    fn log(&self) -> String {
        let mut log = std::fs::read_to_string(self.dir.join("stderr.log")).unwrap_or_default();
        log += &std::fs::read_to_string(self.dir.join("stdout.log")).unwrap_or_default();
        log
    }
}

impl Drop for Player {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Frames per second over the second half of the frames: a player's
/// steady rate (FFmpeg probes the stream first and then hands over the
/// frames it held in one burst).
fn rate(frames: &[(Instant, Vec<u8>)]) -> f64 {
    let half = &frames[frames.len() / 2..];
    match (half.first(), half.last()) {
        (Some(a), Some(b)) if half.len() > 1 => {
            (half.len() - 1) as f64 / b.0.duration_since(a.0).as_secs_f64().max(1e-6)
        }
        _ => 0.0,
    }
}

/// rt-client's "... (F after the first) ..." rate.
fn rt_client_rate(report: &str) -> Option<f64> {
    report.lines().find_map(|l| l.split(" frames/s (").nth(1)?.split(' ').next()?.parse().ok())
}

/// The RTSP server and the light of a `rtsp://HOST:PORT/light/X,Y,Z?...` URL.
fn rt_client_target(url: &str) -> Result<(String, String)> {
    let rest = url.strip_prefix("rtsp://").ok_or(format!("{url}: not rtsp://"))?;
    let (server, path) = rest.split_once('/').ok_or(format!("{url}: no path"))?;
    let light = path.strip_prefix("light/").ok_or(format!("{url}: rt-client plays /light/ streams here"))?;
    let light = light.split('?').next().unwrap_or(light).replace("%2C", ",").replace('/', ",");
    Ok((server.to_string(), light))
}

/// rt-client's `frame_NNN.png` files, in order, as RGB.
fn read_pngs(dir: &Path) -> Result<Vec<(Instant, Vec<u8>)>> {
    let mut names: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    names.sort();
    names
        .iter()
        .map(|p| {
            let img = image::open(p).map_err(|e| format!("{}: {e}", p.display()))?;
            Ok((Instant::now(), img.to_rgb8().into_raw()))
        })
        .collect()
}

/// GStreamer 1.22's rtspsrc at the end of a stream: its streaming thread
/// sends PAUSE while the state change tears the session down and closes
/// the connection (`GST_DEBUG=rtspsrc:5`: "sending cmd PAUSE", "cancel
/// previous request PAUSE", "TEARDOWN...", "closing connection..."), and
/// when the close wins, the PAUSE fails with "Could not send message.
/// (Received end-of-file)" and gst-launch exits 1 although every frame
/// came and the server answered the TEARDOWN. Seen on hps-sim and the
/// emulated board alike, over multicast, rarely. Only that error, and
/// nothing else, is taken as a clean end once every frame arrived.
fn is_gstreamer_shutdown_race(kind: Kind, log: &str) -> bool {
    let gstreamer = matches!(kind, Kind::GstUdp | Kind::GstTcp | Kind::GstMulticast);
    let errors: Vec<&str> = log.lines().filter(|l| l.starts_with("ERROR:")).collect();
    gstreamer
        && !errors.is_empty()
        && errors.iter().all(|l| l.ends_with("Could not write to resource."))
        && log.matches("Could not send message. (Received end-of-file)").count() == errors.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rt_client_s_target_and_rate_are_read() {
        let (server, light) = rt_client_target("rtsp://127.0.0.1:8554/light/3%2C4%2C-2?fps=max").unwrap();
        assert_eq!((server.as_str(), light.as_str()), ("127.0.0.1:8554", "3,4,-2"));
        assert!(rt_client_target("rtsp://h/orbit").is_err());
        let report = "8 frames in 2.10 s over RTSP: 3.8 frames/s (4.1 after the first), 2.0 MB/s";
        assert_eq!(rt_client_rate(report), Some(4.1));
    }

    #[test]
    fn only_gstreamers_own_pause_teardown_race_counts_as_a_clean_end() {
        let race = "ERROR: from element /GstPipeline:pipeline0/GstRTSPSrc:rtspsrc0: Could not write to resource.\n\
                    Additional debug info:\n../gst/rtsp/gstrtspsrc.c(6766): gst_rtspsrc_try_send (): /GstPipeline:pipeline0/GstRTSPSrc:rtspsrc0:\n\
                    Could not send message. (Received end-of-file)\n\
                    ERROR: from element /GstPipeline:pipeline0/GstRTSPSrc:rtspsrc0: Could not write to resource.\n\
                    Additional debug info:\n../gst/rtsp/gstrtspsrc.c(9240): gst_rtspsrc_pause (): /GstPipeline:pipeline0/GstRTSPSrc:rtspsrc0:\n\
                    Could not send message. (Received end-of-file)\n";
        assert!(is_gstreamer_shutdown_race(Kind::GstMulticast, race));
        assert!(!is_gstreamer_shutdown_race(Kind::FfmpegTcp, race), "FFmpeg's errors are its own");
        let other = "ERROR: from element /GstPipeline:pipeline0/GstRTSPSrc:rtspsrc0: Could not read from resource.\n\
                     Could not receive message. (Timeout while waiting for server response)\n";
        assert!(!is_gstreamer_shutdown_race(Kind::GstUdp, other));
        assert!(!is_gstreamer_shutdown_race(Kind::GstUdp, &format!("{race}{other}")), "another error beside it");
        assert!(!is_gstreamer_shutdown_race(Kind::GstUdp, ""), "no error at all is not this one");
    }
}
