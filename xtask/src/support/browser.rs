//! The board's web page in a real browser: Debian's Chromium, headless,
//! driven by `tests/browser/page_check.py` (Selenium with chromium-driver,
//! from Debian's packages), which reads the canvas back with
//! `getImageData` and leaves what it saw in a folder; here each picture is
//! held to the model's frame for the light the page reported, byte for
//! byte.

use std::path::{Path, PathBuf};
use std::process::Command;

use model::{render_frame, Light, FRAME_BYTES};

use super::tools::{ensure_apt_packages, root};
use super::Result;

/// What the browser check needs.
pub const BROWSER_PACKAGES: [&str; 3] = ["chromium", "chromium-driver", "python3-selenium"];

/// Install the browser, its driver and Selenium.
pub fn ensure_browser() -> Result<()> {
    ensure_apt_packages(&BROWSER_PACKAGES, None)
}

/// How a page check runs.
pub struct PageCheck<'a> {
    /// Where the page is (`http://127.0.0.1:PORT`).
    pub url: String,
    /// Where the pictures, the status and the screenshot go.
    pub out: PathBuf,
    /// How long any one wait may take (the emulated board is slow).
    pub timeout_s: u32,
    /// A command to run while the page plays (the hostile clients).
    pub during: Option<&'a [String]>,
    /// Seconds the page then plays on, watched: frames in every 10 s
    /// window, one socket, no close (0: none).
    pub play_s: u32,
}

/// The pictures the check leaves (`NAME.rgb` with `NAME.light`): the held
/// light, after a drag, and, when a command ran during the page, one drawn
/// while it ran and one after.
const PICTURES: [&str; 4] = ["held", "drag", "during", "after"];

/// Four pages at once in four Chromium browsers at `url`
/// (`tests/browser/pages_share.py`): each must draw at least a fifth of
/// the frames the four draw over `seconds`. Returns its summary line.
pub fn pages_share(url: &str, seconds: u32) -> Result<String> {
    let script = root().join("tests/browser/pages_share.py");
    let out = Command::new("/usr/bin/python3")
        .arg(&script)
        .args(["--url", url, "--seconds", &seconds.to_string()])
        .output()
        .map_err(|e| format!("cannot run {}: {e}", script.display()))?;
    let said = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    print!("{said}");
    if !out.status.success() {
        return Err(format!("four pages at once did not each get a fair share ({})", out.status));
    }
    Ok(said.lines().rfind(|l| l.contains("passed")).unwrap_or_default().to_string())
}

/// Run the page check, then hold every picture it read back to the model.
/// Returns a one-line summary.
pub fn check_page(check: &PageCheck<'_>) -> Result<String> {
    std::fs::create_dir_all(&check.out).map_err(|e| format!("{}: {e}", check.out.display()))?;
    let script = root().join("tests/browser/page_check.py");
    // Debian's interpreter: Selenium comes from Debian's python3-selenium,
    // which a python3 earlier on PATH (pyenv, a venv) does not see.
    let mut c = Command::new("/usr/bin/python3");
    c.arg(&script)
        .args(["--url", &check.url, "--out"])
        .arg(&check.out)
        .args(["--timeout", &check.timeout_s.to_string()]);
    if check.play_s > 0 {
        c.args(["--play", &check.play_s.to_string()]);
    }
    if let Some(during) = check.during {
        // One argument; the script splits it at spaces (no word has one).
        c.arg("--during").arg(during.join(" "));
    }
    let status = c.status().map_err(|e| format!("cannot run {}: {e}", script.display()))?;
    if !status.success() {
        return Err(format!("the page check failed ({status}); what it saw is in {}", check.out.display()));
    }
    let mut exact = Vec::new();
    for name in PICTURES {
        let picture = check.out.join(format!("{name}.rgb"));
        if !picture.exists() {
            if matches!(name, "during" | "after") && check.during.is_none() {
                continue;
            }
            return Err(format!("the page check left no {}", picture.display()));
        }
        let raw = read_light(&check.out.join(format!("{name}.light")))?;
        compare(&picture, raw)?;
        exact.push(format!("{name} ({},{},{})", raw[0], raw[1], raw[2]));
    }
    Ok(format!("canvas equals the model's frame byte for byte: {}", exact.join(", ")))
}

fn read_light(path: &Path) -> Result<[i32; 3]> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let words: Vec<i32> = text
        .trim()
        .split(',')
        .map(|w| w.trim().parse::<i32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    words.try_into().map_err(|_| format!("{}: not three words", path.display()))
}

/// The canvas read back in `picture` (RGB, 480 x 360) against the model's
/// frame for `raw`.
fn compare(picture: &Path, raw: [i32; 3]) -> Result<()> {
    let got = std::fs::read(picture).map_err(|e| format!("{}: {e}", picture.display()))?;
    let light = Light::from_raw(raw[0], raw[1], raw[2]).map_err(|e| format!("{}: {e}", picture.display()))?;
    let want = render_frame(&light);
    if got.len() != FRAME_BYTES {
        return Err(format!("{}: {} bytes, not a frame's {FRAME_BYTES}", picture.display(), got.len()));
    }
    if let Some(i) = got.iter().zip(&want).position(|(a, b)| a != b) {
        let differ = got.iter().zip(&want).filter(|(a, b)| a != b).count();
        let (pixel, channel) = (i / 3, i % 3);
        return Err(format!(
            "{}: the canvas differs from the model's frame for light {raw:?} at pixel ({}, {}) channel {channel} ({} != {}); {differ} bytes differ",
            picture.display(),
            pixel % model::WIDTH,
            pixel / model::WIDTH,
            got[i],
            want[i]
        ));
    }
    Ok(())
}
