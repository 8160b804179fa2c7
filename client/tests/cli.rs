//! `rt-client` as a user runs it: frames and orbits against the simulated
//! board, checked against the model, and its one-line errors.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;
use std::process::{Command, Output};
use std::thread;

use hps_sim::HpsSim;
use image::AnimationDecoder;
use model::colour::shade;
use model::scene::{AMBIENT, CHECKER_EVEN, CHECKER_ODD};
use model::{render_frame, Light, HEIGHT, WIDTH};

fn rt_client(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rt-client")).args(args).output().expect("rt-client runs")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rt-client-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

fn model_frame(l: &Light) -> Vec<u8> {
    render_frame(l)
}

fn png(path: &PathBuf) -> Vec<u8> {
    image::open(path).expect("PNG decodes").to_rgb8().into_raw()
}

fn board() -> HpsSim {
    HpsSim::start_quiet("127.0.0.1:0".parse().expect("addr")).expect("board starts")
}

#[test]
fn frame_command_saves_the_model_frame() {
    let sim = board();
    let out = scratch("frame").join("f.png");
    let r = rt_client(&[
        "frame",
        "--server",
        &sim.frame_addr().to_string(),
        "--light",
        "3,4,-2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(png(&out) == model_frame(&Light::from_world(3.0, 4.0, -2.0).unwrap()));
}

/// Column of the centre of the ambient-only (shadowed) plane pixels.
fn shadow_centre_x(rgb: &[u8]) -> f64 {
    let ambient = [shade(CHECKER_EVEN, AMBIENT), shade(CHECKER_ODD, AMBIENT)];
    let (mut sum, mut n) = (0usize, 0usize);
    for y in 180..HEIGHT {
        for x in 0..WIDTH {
            let i = (y * WIDTH + x) * 3;
            let c = model::Rgb::new(rgb[i], rgb[i + 1], rgb[i + 2]);
            if ambient.contains(&c) {
                sum += x;
                n += 1;
            }
        }
    }
    assert!(n > 500, "a visible shadow");
    sum as f64 / n as f64
}

#[test]
fn orbit_to_png_directory_goes_round_the_sphere() {
    let dir = scratch("orbit");
    let r = rt_client(&["orbit", "--frames", "4", "--radius", "3", "--height", "4", "--out", dir.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(stdout.contains("frames/s") && stdout.contains("MB/s") && stdout.contains("median"), "{stdout}");
    let lights = [(3.0, 0.0), (0.0, 3.0), (-3.0, 0.0), (0.0, -3.0)];
    let frames: Vec<Vec<u8>> = (0..4).map(|k| png(&dir.join(format!("frame_{k:03}.png")))).collect();
    for (k, (x, z)) in lights.iter().enumerate() {
        assert!(frames[k] == model_frame(&Light::from_world(*x, 4.0, *z).unwrap()), "frame {k}");
    }
    // Light on the right (+x): shadow left of centre; on the left: right.
    assert!(shadow_centre_x(&frames[0]) < 200.0);
    assert!(shadow_centre_x(&frames[2]) > 280.0);
}

#[test]
fn orbit_to_gif_has_every_frame() {
    let gif = scratch("gif").join("o.gif");
    let r = rt_client(&["orbit", "--frames", "6", "--out", gif.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let file = std::fs::File::open(&gif).expect("GIF written");
    let decoder = image::codecs::gif::GifDecoder::new(std::io::BufReader::new(file)).expect("GIF decodes");
    let frames = decoder.into_frames().collect_frames().expect("frames decode");
    assert_eq!(frames.len(), 6);
    assert_eq!(frames[0].buffer().dimensions(), (WIDTH as u32, HEIGHT as u32));
}

#[test]
fn bench_prints_figures() {
    let r = rt_client(&["bench", "--frames", "5"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(String::from_utf8_lossy(&r.stdout).contains("5 frames in"));
}

fn one_line_error(r: &Output, needle: &str) {
    assert!(!r.status.success(), "exit code must be non-zero");
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains(needle), "stderr {err:?} lacks {needle:?}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err:?}");
}

#[test]
fn refused_connection_is_a_clear_error() {
    let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let server = format!("127.0.0.1:{port}");
    one_line_error(&rt_client(&["frame", "--server", &server, "--light", "1,2,3"]), "refused");
    one_line_error(&rt_client(&["bench", "--server", &server]), "refused");
}

#[test]
fn short_frame_is_a_clear_error() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr: SocketAddr = listener.local_addr().unwrap();
    let fake = thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let mut req = [0u8; 12];
        s.read_exact(&mut req).unwrap();
        s.write_all(&[7u8; 1000]).unwrap();
    });
    let out = scratch("short").join("f.png");
    let r = rt_client(&["frame", "--server", &addr.to_string(), "--light", "1,2,3", "--out", out.to_str().unwrap()]);
    fake.join().unwrap();
    one_line_error(&r, "short frame");
    assert!(String::from_utf8_lossy(&r.stderr).contains("1000 of 518400"));
    assert!(!out.exists(), "no file for a failed frame");
}

#[test]
fn bad_arguments_fail() {
    for args in [
        &["frame", "--server", "127.0.0.1:1", "--light", "1,2"][..],
        &["frame", "--server", "127.0.0.1:1", "--light", "9000,0,0"],
        &["orbit", "--frames", "0"],
        &["orbit", "--radius", "9000", "--frames", "2"],
        &["frame", "--server", "no-such-host.invalid:7878", "--light", "1,2,3"],
    ] {
        let r = rt_client(args);
        assert!(!r.status.success(), "{args:?} must fail");
        assert!(!r.stderr.is_empty(), "{args:?} says why");
    }
}

/// `bench --transport rtsp` against the in-process simulated board's RTSP
/// server.
#[test]
fn bench_over_rtsp_counts_every_frame() {
    let r = rt_client(&["bench", "--transport", "rtsp", "--frames", "20", "--fps", "max"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = String::from_utf8_lossy(&r.stdout);
    assert!(out.contains("20 frames in "), "{out}");
    let count = |what: &str| -> u64 {
        let at = out.find(&format!(" {what}")).unwrap_or_else(|| panic!("no {what} in {out}"));
        out[..at].rsplit([' ', ':']).next().unwrap().parse().unwrap()
    };
    assert_eq!(count("exact,") + count("repaired,") + count("damaged ("), 20, "{out}");
}
