//! `cargo xtask fuzz`: the hostile-input property harnesses with many cases
//! (release build): the sans-IO frame server (rt-services
//! tests/fuzz_server.rs), the sans-IO RTSP server (rt-services
//! tests/fuzz_rtsp.rs) and the DesignWare MAC's receive path on random
//! descriptors (dwmac's receive property test). The suite runs the same
//! harnesses with proptest's default 256 cases.

use clap::Args;

use crate::support::tools::{cargo, step};
use crate::support::Result;

/// `cargo xtask fuzz` options.
#[derive(Args)]
pub struct FuzzArgs {
    /// Cases for the frame server harness.
    #[arg(long, default_value_t = 1_000_000)]
    pub cases: u64,
    /// Cases for the RTSP server harness.
    #[arg(long, default_value_t = 1_000_000)]
    pub rtsp_cases: u64,
    /// Cases for the MAC's receive-path harness.
    #[arg(long, default_value_t = 100_000)]
    pub mac_cases: u64,
}

/// Run the three harnesses.
pub fn run(args: &FuzzArgs) -> Result<()> {
    let start = std::time::Instant::now();
    let mut c = cargo(&["test", "--release", "-p", "rt-services", "--test", "fuzz_server", "--", "--nocapture"]);
    c.env("PROPTEST_CASES", args.cases.to_string());
    step(&format!("frame server: {} hostile clients", args.cases), c)?;
    let server = start.elapsed();
    let mut r = cargo(&["test", "--release", "-p", "rt-services", "--test", "fuzz_rtsp", "--", "--nocapture"]);
    r.env("PROPTEST_CASES", args.rtsp_cases.to_string());
    step(&format!("RTSP server: {} hostile clients", args.rtsp_cases), r)?;
    let rtsp = start.elapsed() - server;
    let mut m =
        cargo(&["test", "--release", "-p", "dwmac", "any_receive_descriptor_contents_are_safe", "--", "--nocapture"]);
    m.env("PROPTEST_CASES", args.mac_cases.to_string());
    step(&format!("MAC receive path: {} random descriptor rings", args.mac_cases), m)?;
    println!(
        "fuzz: {} frame-server cases in {:.0} s, {} RTSP cases in {:.0} s, {} MAC receive cases in {:.0} s: \
         no panic, every property held",
        args.cases,
        server.as_secs_f64(),
        args.rtsp_cases,
        rtsp.as_secs_f64(),
        args.mac_cases,
        (start.elapsed() - server - rtsp).as_secs_f64()
    );
    Ok(())
}
