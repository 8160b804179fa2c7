//! `cargo xtask players`: a real player as the board's client. GStreamer's
//! `rtspsrc` sets up a stream from a release `hps-sim` over RTSP, receives
//! it over RTP/UDP and `rtpvrawdepay` turns the RFC 4175 rows back into
//! frames, which `multifilesink` writes one file each; those files must be
//! the model's frames byte for byte. This checks what the hand-written
//! client of `hps-sim/tests/rtsp.rs` cannot: that the SDP, the RTSP
//! exchange and the payload are what an independent implementation reads.
//!
//! Two streams: a fixed light (every frame the same) and an orbit (every
//! frame the light of its own media time). GStreamer's files keep no RTP
//! timestamp, so the orbit's frames are placed by their buffer times:
//! `rtspsrc buffer-mode=none` stamps buffers from the RTP timestamps alone
//! (first frame 0), which `identity silent=false` prints under `-v`
//! (docs/streaming.md). The first frame's media time is found by search,
//! then every other frame must be the orbit's frame at that time plus its
//! buffer time, exactly.

use std::collections::HashMap;
use std::fs;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use model::{Light, FRAME_BYTES, HEIGHT, ROW_BYTES, WIDTH};
use rt_services::camera::rtsp::StreamSpec;

use crate::support::process::{free_ports, start_server, Guard};
use crate::support::tools::{ensure_apt_packages, root};
use crate::support::Result;

/// The Debian packages of `gst-launch-1.0`, `rtspsrc` (plugins-good, with
/// the RTP elements and `multifilesink`) and `identity` (core).
pub const GSTREAMER_PACKAGES: [&str; 3] =
    ["gstreamer1.0-tools", "gstreamer1.0-plugins-base", "gstreamer1.0-plugins-good"];

/// Frames taken from each stream.
const FRAMES: usize = 8;

/// Exact frames a stream must give at least, if some were damaged by loss.
const MIN_EXACT: usize = 3;

/// The stream rate: paced well below what loopback carries.
const FPS: u32 = 10;

/// The longest one capture may take (a few seconds when all is well).
const CAPTURE_TIMEOUT: Duration = Duration::from_secs(20);

/// `GST_BUFFER_FLAG_DISCONT`: the depayloader's mark on a buffer after a
/// gap in the sequence numbers (and on the first buffer).
const DISCONT: u32 = 0x40;

/// Run the step.
pub fn run() -> Result<()> {
    ensure_apt_packages(&GSTREAMER_PACKAGES, None)?;
    crate::support::tools::build_host_programs()?;
    let started = Instant::now();
    let dir = root().join("target/players");
    fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (listen, rtsp) = free_ports()?;
    let log = dir.join("hps-sim.log");
    println!("==> players: hps-sim on {listen}, RTSP on {rtsp} (log {})", log.display());
    let mut cmd = Command::new(root().join("target/release/hps-sim"));
    cmd.args(["--listen", &listen.to_string(), "--rtsp", &rtsp.to_string()]);
    let mut sim = start_server(cmd, "hps-sim", &log, rtsp)?;
    check_server("hps-sim", rtsp, &dir)?;
    if let Ok(Some(status)) = sim.0.try_wait() {
        return Err(format!("hps-sim exited during the test ({status}); see {}", log.display()));
    }
    println!("players: done in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

/// GStreamer against the RTSP server at `rtsp` (hps-sim, or the emulated
/// board through its forwarded port), captures under `dir`: a fixed
/// light's frames and an orbit's equal the model's.
pub fn check_server(name: &str, rtsp: SocketAddr, dir: &Path) -> Result<()> {
    ensure_apt_packages(&GSTREAMER_PACKAGES, None)?;
    let light = Light::from_world(3.0, 4.0, -2.0).map_err(|e| format!("{e:?}"))?;
    let path = format!("/light/3,4,-2?fps={FPS}");
    let capture = gstreamer(&dir.join("light"), &format!("rtsp://{rtsp}{path}"), FRAMES)?;
    let expected = model::render_frame(&light);
    let report = check_fixed(&capture, &expected)?;
    println!("players: GStreamer from {name}, {path}: {report}");

    let path = format!("/orbit?radius=3&height=4&period=2&fps={FPS}");
    let url = format!("rtsp://{rtsp}{path}");
    let spec = StreamSpec::parse(&url).map_err(|e| format!("{url}: {e:?}"))?;
    let capture = gstreamer(&dir.join("orbit"), &url, FRAMES)?;
    let orbit = |ms: u64| spec.light_at(Duration::from_millis(ms), light);
    let report = check_orbit(&capture, orbit)?;
    println!("players: GStreamer from {name}, {path}: {report}");
    Ok(())
}

/// One buffer as `identity` reported it.
#[derive(Debug, PartialEq)]
struct Buffer {
    /// Presentation time, ns.
    pts: u64,
    /// `GstBufferFlags`.
    flags: u32,
}

/// What one GStreamer run gave.
struct Capture {
    /// The frames, in order.
    frames: Vec<Vec<u8>>,
    /// Their buffers, in the same order.
    buffers: Vec<Buffer>,
    /// How long gst-launch ran.
    elapsed: Duration,
}

/// Receive `frames` frames of `url` with GStreamer into `dir`.
fn gstreamer(dir: &Path, url: &str, frames: usize) -> Result<Capture> {
    if dir.exists() {
        fs::remove_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (out_path, err_path) = (dir.join("gst-launch.out"), dir.join("gst-launch.err"));
    let open = |p: &PathBuf| fs::File::create(p).map_err(|e| format!("{}: {e}", p.display()));
    let mut cmd = Command::new("gst-launch-1.0");
    // `identity eos-after=N` ends the stream as the Nth buffer arrives (it
    // is not passed on): N - 1 frames reach the sink, then gst-launch exits
    // and rtspsrc sends TEARDOWN.
    cmd.arg("-v")
        .arg("rtspsrc")
        .arg(format!("location={url}"))
        .args(["protocols=udp", "latency=200", "buffer-mode=none", "!", "rtpvrawdepay", "!", "identity"])
        .arg(format!("eos-after={}", frames + 1))
        .args(["silent=false", "!", "multifilesink"])
        .arg(format!("location={}", dir.join("frame-%05d.rgb").display()))
        .stdin(Stdio::null())
        .stdout(open(&out_path)?)
        .stderr(open(&err_path)?);
    println!("==> GStreamer: {cmd:?}");
    let started = Instant::now();
    let child = cmd.spawn().map_err(|e| format!("gst-launch-1.0: {e}"))?;
    let mut gst = Guard(child, "gst-launch-1.0");
    let status = loop {
        if let Some(status) = gst.0.try_wait().map_err(|e| e.to_string())? {
            break status;
        }
        if started.elapsed() > CAPTURE_TIMEOUT {
            drop(gst);
            return Err(format!(
                "gst-launch-1.0 had not received {frames} frames of {url} after {} s (killed); see {} and {}",
                CAPTURE_TIMEOUT.as_secs(),
                out_path.display(),
                err_path.display()
            ));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let elapsed = started.elapsed();
    let out = fs::read_to_string(&out_path).map_err(|e| format!("{}: {e}", out_path.display()))?;
    if !status.success() {
        let err = fs::read_to_string(&err_path).unwrap_or_default();
        return Err(format!("gst-launch-1.0 failed ({status}):\n{err}\n(see {})", out_path.display()));
    }
    check_caps(&out)?;
    let buffers: Vec<Buffer> = out.lines().filter_map(buffer_line).collect();
    let mut names: Vec<PathBuf> = fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "rgb"))
        .collect();
    names.sort();
    let frames_read: Vec<Vec<u8>> =
        names.iter().map(|p| fs::read(p).map_err(|e| format!("{}: {e}", p.display()))).collect::<Result<_>>()?;
    if frames_read.len() != frames || buffers.len() != frames {
        return Err(format!(
            "GStreamer wrote {} frame files and logged {} buffers; expected {frames} of each (see {})",
            frames_read.len(),
            buffers.len(),
            out_path.display()
        ));
    }
    for (p, f) in names.iter().zip(&frames_read) {
        if f.len() != FRAME_BYTES {
            return Err(format!("{}: {} bytes, a frame has {FRAME_BYTES}", p.display(), f.len()));
        }
    }
    Ok(Capture { frames: frames_read, buffers, elapsed })
}

/// The depayloader's output caps must be packed RGB of the frame's size
/// (then a buffer is the frame's bytes: 1,440-byte rows need no padding).
///
/// `-v` prints them in one of two places, and not always both: the
/// `deep-notify` of rtpvrawdepay's source pad, which gst-launch may never
/// print when the pipeline ends soon after (seen once in three runs), and
/// `identity`'s caps event (its `last-message`, written with `\` escapes)
/// that comes before the first buffer.
fn check_caps(log: &str) -> Result<()> {
    let caps = log
        .lines()
        .find(|l| l.contains("GstRtpVRawDepay") && l.contains("src: caps = "))
        .or_else(|| log.lines().find(|l| l.contains("GstIdentity") && l.contains("GstEventCaps")))
        .ok_or("gst-launch -v printed no caps for rtpvrawdepay's source pad nor identity's caps event")?
        .replace('\\', "");
    for want in
        ["video/x-raw", "format=(string)RGB,", &format!("width=(int){WIDTH},"), &format!("height=(int){HEIGHT},")]
    {
        if !caps.contains(want) {
            return Err(format!("rtpvrawdepay's caps lack `{want}`: {caps}"));
        }
    }
    Ok(())
}

/// A buffer from `identity silent=false`'s `last-message` under `-v`:
/// `... chain ... pts: 0:00:00.101000000, ... flags: 00000040 discont ...`.
fn buffer_line(line: &str) -> Option<Buffer> {
    if !line.contains("last-message = chain") {
        return None;
    }
    let pts = line.split("pts: ").nth(1)?.split(',').next()?;
    let mut parts = pts.split(':');
    let (h, m, s) = (parts.next()?, parts.next()?, parts.next()?);
    let (secs, nanos) = s.split_once('.')?;
    let ns = (h.parse::<u64>().ok()? * 3600 + m.parse::<u64>().ok()? * 60 + secs.parse::<u64>().ok()?)
        .checked_mul(1_000_000_000)?
        .checked_add(nanos.parse().ok()?)?;
    let flags = line.split("flags: ").nth(1)?.split_whitespace().next()?;
    Some(Buffer { pts: ns, flags: u32::from_str_radix(flags, 16).ok()? })
}

/// Whether buffer `i` is marked as following lost packets (the first
/// buffer of a stream always carries DISCONT and tells nothing).
fn after_loss(c: &Capture, i: usize) -> bool {
    i > 0 && c.buffers[i].flags & DISCONT != 0
}

/// Every frame equals `expected`, or is marked as damaged by loss; at least
/// [`MIN_EXACT`] are exact.
fn check_fixed(c: &Capture, expected: &[u8]) -> Result<String> {
    let mut exact = 0;
    let mut damaged = Vec::new();
    for (i, f) in c.frames.iter().enumerate() {
        if f == expected {
            exact += 1;
        } else if after_loss(c, i) {
            damaged.push(format!("frame {i}: {}", row_difference(f, expected)));
        } else {
            return Err(format!(
                "frame {i} is not the model's frame and GStreamer reported no loss before it: {}",
                row_difference(f, expected)
            ));
        }
    }
    summary(c, exact, &damaged)
}

/// `n of 360 rows differ (first y)`.
fn row_difference(a: &[u8], b: &[u8]) -> String {
    let differ: Vec<usize> =
        a.chunks(ROW_BYTES).zip(b.chunks(ROW_BYTES)).enumerate().filter(|(_, (x, y))| x != y).map(|(y, _)| y).collect();
    match differ.first() {
        Some(first) => format!("{} of {HEIGHT} rows differ (the first: row {first})", differ.len()),
        None => "equal".into(),
    }
}

fn summary(c: &Capture, exact: usize, damaged: &[String]) -> Result<String> {
    if exact < MIN_EXACT {
        return Err(format!(
            "only {exact} of {} frames exact (at least {MIN_EXACT} needed); damaged by loss: {}",
            c.frames.len(),
            damaged.join("; ")
        ));
    }
    let mut s = format!(
        "{exact} of {} frames equal the model's, byte for byte ({:.1} s in gst-launch)",
        c.frames.len(),
        c.elapsed.as_secs_f64()
    );
    if !damaged.is_empty() {
        s += &format!("; {} damaged after reported loss: {}", damaged.len(), damaged.join("; "));
    }
    Ok(s)
}

/// Rows compared before a whole frame is rendered: through the sphere and
/// through its shadow, where the light shows most.
const PROBE_ROWS: [u16; 2] = [HEIGHT as u16 / 2, HEIGHT as u16 * 3 / 4];

/// Renders of the model, each light's probe rows and whole frame at most
/// once (neighbouring milliseconds may quantise to the same light).
#[derive(Default)]
struct Renders {
    probes: HashMap<Light, Vec<u8>>,
    frames: HashMap<Light, Vec<u8>>,
}

impl Renders {
    fn probe(&mut self, light: Light) -> &[u8] {
        self.probes.entry(light).or_insert_with(|| {
            let mut words = [0u32; WIDTH];
            let mut bytes = vec![0u8; ROW_BYTES * PROBE_ROWS.len()];
            for (y, out) in PROBE_ROWS.iter().zip(bytes.chunks_exact_mut(ROW_BYTES)) {
                model::render_row(*y, &light, &mut words);
                if let Ok(out) = <&mut [u8; ROW_BYTES]>::try_from(out) {
                    model::row_to_rgb888(&words, out);
                }
            }
            bytes
        })
    }

    fn frame(&mut self, light: Light) -> &[u8] {
        self.frames.entry(light).or_insert_with(|| model::render_frame(&light))
    }

    /// Whether `frame` is the model's frame for `light`: the probe rows
    /// first, the whole frame only if they match.
    fn is(&mut self, frame: &[u8], light: Light) -> bool {
        let probe = self.probe(light);
        let matches = PROBE_ROWS
            .iter()
            .zip(probe.chunks_exact(ROW_BYTES))
            .all(|(y, row)| frame.get(usize::from(*y) * ROW_BYTES..).is_some_and(|f| f.starts_with(row)));
        matches && self.frame(light) == frame
    }
}

/// Every frame of an orbit is the orbit's frame at its media time: the
/// first frame's media time `t0` (whole milliseconds: the server's clock)
/// is searched over everything that can have passed since PLAY, the others
/// are at `t0` plus their buffer times. `orbit(ms)` is the light `ms` into
/// the stream. Frames marked as after loss may differ, as in
/// [`check_fixed`].
fn check_orbit(c: &Capture, orbit: impl Fn(u64) -> Light) -> Result<String> {
    let mut renders = Renders::default();
    let limit = c.elapsed.as_millis() as u64 + 1000;
    // Media times of the first frame that can be right; usually one.
    let mut origin: Option<(usize, Vec<u64>)> = None;
    let mut exact = 0;
    let mut damaged = Vec::new();
    // The exact frames' media times after the first's, ms.
    let mut times = Vec::new();
    for (i, f) in c.frames.iter().enumerate() {
        let Some((first, t0s)) = &mut origin else {
            let found: Vec<u64> = (0..=limit).filter(|&ms| renders.is(f, orbit(ms))).collect();
            if found.is_empty() {
                if after_loss(c, i) {
                    damaged.push(format!("frame {i}: the orbit's light at no millisecond in 0..={limit}"));
                    continue;
                }
                return Err(format!(
                    "frame {i} is the orbit's frame at no media time 0..={limit} ms, and GStreamer reported no \
                     loss before it"
                ));
            }
            println!("players: orbit frame {i} is the orbit's frame at {found:?} ms (searched 0..={limit} ms)");
            exact += 1;
            origin = Some((i, found));
            continue;
        };
        let since = c.buffers[i].pts.checked_sub(c.buffers[*first].pts).ok_or_else(|| {
            format!("frame {i}: its buffer time goes back ({} ns before frame {first}'s)", c.buffers[*first].pts)
        })?;
        if since % 1_000_000 != 0 {
            return Err(format!(
                "frame {i}: {since} ns after frame {first}, not whole milliseconds as the server's media time is"
            ));
        }
        let ms = since / 1_000_000;
        let fits: Vec<u64> = t0s.iter().copied().filter(|t0| renders.is(f, orbit(t0 + ms))).collect();
        if fits.is_empty() {
            let at: Vec<u64> = t0s.iter().map(|t0| t0 + ms).collect();
            if after_loss(c, i) {
                damaged.push(format!("frame {i}: not the orbit's frame at {at:?} ms"));
                continue;
            }
            return Err(format!(
                "frame {i} ({ms} ms after frame {first} by its RTP timestamp) is not the orbit's frame at {at:?} ms"
            ));
        }
        *t0s = fits;
        times.push(ms);
        exact += 1;
    }
    let mut report = summary(c, exact, &damaged)?;
    if let Some((first, t0s)) = origin {
        report += &format!("; frame {first} at {t0s:?} ms, the others at {times:?} ms after it");
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn caps_come_from_the_depayloader_or_identitys_caps_event() {
        let pad = "/GstPipeline:pipeline0/GstRtpVRawDepay:rtpvrawdepay0.GstPad:src: caps = video/x-raw, \
                   format=(string)RGB, width=(int)480, height=(int)360, framerate=(fraction)0/1";
        let event = "/GstPipeline:pipeline0/GstIdentity:identity0: last-message = event   ******* (identity0:sink) E \
                     (type: caps (12814), GstEventCaps, caps=(GstCaps)\"video/x-raw\\,\\ format\\=\\(string\\)RGB\\,\\ \
                     width\\=\\(int\\)480\\,\\ height\\=\\(int\\)360\\,\\ interlace-mode\"";
        assert_eq!(check_caps(pad), Ok(()));
        assert_eq!(check_caps(event), Ok(()));
        assert!(check_caps(&event.replace("RGB", "BGR")).is_err());
        assert!(check_caps(&pad.replace("360", "240")).is_err());
        assert!(check_caps("Setting pipeline to PAUSED ...").is_err());
    }

    #[test]
    fn identity_lines_give_times_and_flags() {
        let line = "/GstPipeline:pipeline0/GstIdentity:identity0: last-message = chain   ******* (identity0:sink) \
                    (518400 bytes, dts: none, pts: 0:00:01.101000000, duration: none, offset: -1, offset_end: -1, \
                    flags: 00000040 discont , meta: none) 0x7f8b281b7360";
        assert_eq!(buffer_line(line), Some(Buffer { pts: 1_101_000_000, flags: DISCONT }));
        assert_eq!(buffer_line("last-message = event   ******* (identity0:sink) E (type: eos (28174), )"), None);
    }

    fn capture(frames: Vec<Vec<u8>>, pts_ms: &[u64], flags: &[u32]) -> Capture {
        let buffers = pts_ms.iter().zip(flags).map(|(&p, &flags)| Buffer { pts: p * 1_000_000, flags }).collect();
        Capture { frames, buffers, elapsed: Duration::from_millis(500) }
    }

    /// A frame unlike any the model renders: every check must refuse it
    /// unless loss explains it.
    #[test]
    fn wrong_frames_fail_unless_loss_explains_them() {
        let light = Light::from_world(3.0, 4.0, -2.0).expect("light");
        let good = model::render_frame(&light);
        let mut bad = good.clone();
        bad[ROW_BYTES * 200 + 7] ^= 1;
        let c =
            capture(vec![good.clone(), good.clone(), bad.clone(), good.clone()], &[0, 100, 200, 300], &[0x40, 0, 0, 0]);
        assert!(check_fixed(&c, &good).is_err(), "a wrong pixel, no loss reported");
        let c = capture(vec![good.clone(), good.clone(), bad, good.clone()], &[0, 100, 200, 300], &[0x40, 0, 0x40, 0]);
        let report = check_fixed(&c, &good).expect("loss explains it");
        assert!(report.contains("3 of 4") && report.contains("1 of 360 rows differ (the first: row 200)"), "{report}");
        let other = model::render_frame(&Light::from_world(3.0, 4.0, 2.0).expect("light"));
        assert!(check_fixed(&capture(vec![other; 4], &[0, 100, 200, 300], &[0x40, 0, 0, 0]), &good).is_err());
    }

    /// An orbit of a made-up light path: frames placed by their buffer
    /// times pass; a frame of the wrong time, or wrong times, fail.
    #[test]
    fn orbit_frames_must_be_the_lights_of_their_times() {
        let lights: Vec<Light> =
            (0..4).map(|k| Light::from_world(3.0, 4.0, -2.0 + f64::from(k)).expect("light")).collect();
        // Light k from 100 k ms on; the stream's first frame is at 140 ms.
        let orbit = |ms: u64| lights[(ms / 100).min(3) as usize];
        let f: Vec<Vec<u8>> = lights.iter().map(model::render_frame).collect();
        let c = capture(vec![f[1].clone(), f[2].clone(), f[3].clone()], &[0, 100, 200], &[0x40, 0, 0]);
        assert!(check_orbit(&c, orbit).expect("right").contains("3 of 3"));
        let c = capture(vec![f[1].clone(), f[3].clone(), f[2].clone()], &[0, 100, 200], &[0x40, 0, 0]);
        assert!(check_orbit(&c, orbit).is_err(), "frames out of place");
        let c = capture(vec![f[1].clone(), f[2].clone(), f[3].clone()], &[0, 100, 100], &[0x40, 0, 0]);
        assert!(check_orbit(&c, orbit).is_err(), "times that do not fit");
        let c = capture(vec![f[1].clone(), f[2].clone(), f[3].clone()], &[0, 100, 200], &[0x40, 0, 0]);
        let backwards = |ms: u64| lights[3 - (ms / 100).min(3) as usize];
        assert!(check_orbit(&c, backwards).is_err(), "another light path");
    }
}
