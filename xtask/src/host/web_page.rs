//! The board's web page served by `hps-sim --http`, in a real browser
//! (`support::browser`): with `/?light=3,4,-2` the canvas equals the
//! model's frame byte for byte, a scripted drag moves the light and the
//! canvas follows it exactly, the status counters move while it plays; the
//! browser's screenshot of the page is left in `target/web/hps-sim`.

use std::fs;
use std::net::TcpListener;
use std::process::Command;
use std::time::Instant;

use crate::support::browser::{check_page, ensure_browser, pages_share, PageCheck};
use crate::support::process::{free_ports, start_server};
use crate::support::tools::root;
use crate::support::Result;

/// Run the step.
pub fn run() -> Result<()> {
    ensure_browser()?;
    crate::support::tools::build_host_programs()?;
    let started = Instant::now();
    let dir = root().join("target/web/hps-sim");
    fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (listen, rtsp) = free_ports()?;
    let http =
        TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map_err(|e| format!("no free port: {e}"))?;
    let log = dir.join("hps-sim.log");
    println!("==> the web page in Chromium: hps-sim on http://{http}/ (log {})", log.display());
    let mut cmd = Command::new(root().join("target/release/hps-sim"));
    cmd.args(["--listen", &listen.to_string(), "--rtsp", &rtsp.to_string(), "--http", &http.to_string()]);
    let mut sim = start_server(cmd, "hps-sim", &log, http)?;
    let check = PageCheck { url: format!("http://{http}"), out: dir.clone(), timeout_s: 60, during: None, play_s: 0 };
    let summary = check_page(&check)?;
    if let Ok(Some(status)) = sim.0.try_wait() {
        return Err(format!("hps-sim exited during the test ({status}); see {}", log.display()));
    }
    println!("web (hps-sim): {summary}; screenshot {}", dir.join("page.png").display());
    // Four pages at once over the web's two shared frame slots.
    println!("web (hps-sim): {}", pages_share(&format!("http://{http}"), 15)?);
    println!("web (hps-sim): done in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}
