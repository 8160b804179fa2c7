//! The live viewer end to end under Xvfb (`cargo xtask test`): a scripted
//! session against the in-process board; the last frame shown (the
//! window's buffer, saved by `--save-last`) must be the model's frame for
//! the last light requested, byte for byte.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::support::tools::{ensure_apt_packages, root};
use crate::support::Result;

/// Drags, the wheel, keys and the automatic orbit, then quit.
const SCRIPT: &str = "\
0    key space
300  drag 40 -10
600  wheel 1
900  key space
1000 key left
1100 key pagedown
1200 drag -25 5
1500 quit
";

/// `[x, y, z]` from a log line's `light raw [x, y, z]`.
fn raw_light(line: &str) -> Option<[i32; 3]> {
    let list = line.split("light raw [").nth(1)?.split(']').next()?;
    let v: Vec<i32> = list.split(',').filter_map(|s| s.trim().parse().ok()).collect();
    v.try_into().ok()
}

/// Debian's packages of the virtual X server the window runs in.
pub const PACKAGES: [&str; 2] = ["xvfb", "xauth"];

/// Run the test.
pub fn run() -> Result<()> {
    ensure_apt_packages(&PACKAGES, None)?;
    crate::support::tools::build_host_programs()?;
    let dir = root().join("target/live-test");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (script, last) = (dir.join("session.txt"), dir.join("last.png"));
    std::fs::write(&script, SCRIPT).map_err(|e| e.to_string())?;
    let _ = std::fs::remove_file(&last);
    let bin = root().join("target/release/rt-client");
    println!("==> live viewer under Xvfb: scripted session against the in-process board");
    let mut child = Command::new("xvfb-run")
        .arg("-a")
        .arg(&bin)
        .args(["live", "--script"])
        .arg(&script)
        .arg("--save-last")
        .arg(&last)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("xvfb-run: {e}"))?;
    let started = Instant::now();
    loop {
        if child.try_wait().map_err(|e| e.to_string())?.is_some() {
            break;
        }
        if started.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            return Err("the live viewer did not finish its script within 120 s".into());
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let out = child.wait_with_output().map_err(|e| e.to_string())?;
    let log = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        return Err(format!("rt-client live failed ({}):\n{log}", out.status));
    }
    check(&log, &last)
}

fn check(log: &str, last: &Path) -> Result<()> {
    let requested: Vec<[i32; 3]> =
        log.lines().filter(|l| l.contains("request light raw")).filter_map(raw_light).collect();
    let shown = log
        .lines()
        .find(|l| l.contains("last frame shown"))
        .and_then(raw_light)
        .ok_or_else(|| format!("no `last frame shown` line:\n{log}"))?;
    if requested.len() < 3 {
        return Err(format!("only {} requests logged for a session that moves the light:\n{log}", requested.len()));
    }
    if requested.last() != Some(&shown) {
        return Err(format!("the last frame shown is for {shown:?}, the last light requested {:?}", requested.last()));
    }
    let light = model::Light::from_raw(shown[0], shown[1], shown[2]).map_err(|e| e.to_string())?;
    let png = image::open(last).map_err(|e| format!("{}: {e}", last.display()))?.to_rgb8().into_raw();
    if png != model::render_frame(&light) {
        return Err(format!("the last frame shown differs from the model's frame for {shown:?}"));
    }
    println!(
        "live viewer: {} requests, the last frame shown ({shown:?}) equals the model's frame, byte for byte",
        requested.len()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logged_lights_parse() {
        assert_eq!(raw_light("rt-client: request light raw [2901, 4138, -977]"), Some([2901, 4138, -977]));
        assert_eq!(raw_light("rt-client: last frame shown: light raw [1, 2, 3], saved to x"), Some([1, 2, 3]));
        assert_eq!(raw_light("light raw [1, 2]"), None);
    }
}
