//! `cargo xtask fuzz`: the hostile-input property harnesses with many cases
//! (release build): the sans-IO frame server (rt-services
//! tests/fuzz_server.rs), the network camera's connection lifecycle (the
//! RTSP server with its RTP sender, tests/fuzz_rtsp.rs), its RTCP and
//! repair path (tests/fuzz_rtcp.rs) and the DesignWare MAC's receive path
//! on random descriptors (dwmac's receive property test). The host tests
//! run the same harnesses with proptest's default 256 cases; the suite runs
//! the camera's two with a million each ([`camera`]).

use clap::Args;

use crate::support::tools::{cargo, step};
use crate::support::Result;

/// `cargo xtask fuzz` options.
#[derive(Args)]
pub struct FuzzArgs {
    /// Cases for the frame server harness.
    #[arg(long, default_value_t = 1_000_000)]
    pub cases: u64,
    /// Cases for the camera's connection-lifecycle harness.
    #[arg(long, default_value_t = 1_000_000)]
    pub rtsp_cases: u64,
    /// Cases for the camera's RTCP and repair harness.
    #[arg(long, default_value_t = 1_000_000)]
    pub rtcp_cases: u64,
    /// Cases for the MAC's receive-path harness.
    #[arg(long, default_value_t = 100_000)]
    pub mac_cases: u64,
}

/// Run the harnesses.
pub fn run(args: &FuzzArgs) -> Result<()> {
    let start = std::time::Instant::now();
    let mut c = cargo(&["test", "--release", "-p", "rt-services", "--test", "fuzz_server", "--", "--nocapture"]);
    c.env("PROPTEST_CASES", args.cases.to_string());
    step(&format!("frame server: {} hostile clients", args.cases), c)?;
    let server = start.elapsed();
    camera(args.rtsp_cases, args.rtcp_cases)?;
    let camera_time = start.elapsed() - server;
    let mut m =
        cargo(&["test", "--release", "-p", "dwmac", "any_receive_descriptor_contents_are_safe", "--", "--nocapture"]);
    m.env("PROPTEST_CASES", args.mac_cases.to_string());
    step(&format!("MAC receive path: {} random descriptor rings", args.mac_cases), m)?;
    println!(
        "fuzz: {} frame-server cases in {:.0} s, {} + {} camera cases in {:.0} s, {} MAC receive cases in {:.0} s: \
         no panic, every property held",
        args.cases,
        server.as_secs_f64(),
        args.rtsp_cases,
        args.rtcp_cases,
        camera_time.as_secs_f64(),
        args.mac_cases,
        (start.elapsed() - server - camera_time).as_secs_f64()
    );
    Ok(())
}

/// The network camera's two harnesses, `lifecycle` and `rtcp` cases: the
/// connection lifecycle (RTSP server and sender, tests/fuzz_rtsp.rs) and
/// the RTCP and repair path (tests/fuzz_rtcp.rs), side by side (one core
/// each).
pub fn camera(lifecycle: u64, rtcp: u64) -> Result<()> {
    let start = std::time::Instant::now();
    let build =
        cargo(&["test", "--release", "-p", "rt-services", "--test", "fuzz_rtsp", "--test", "fuzz_rtcp", "--no-run"]);
    step("build the camera's harnesses (release)", build)?;
    let spawn = |test: &str, cases: u64| {
        let mut c = cargo(&["test", "--release", "-p", "rt-services", "--test", test, "--", "--nocapture"]);
        c.env("PROPTEST_CASES", cases.to_string());
        println!("==> camera harness {test}: {cases} cases: {c:?}");
        c.spawn().map_err(|e| format!("{test}: {e}"))
    };
    let mut a = spawn("fuzz_rtsp", lifecycle)?;
    let mut b = spawn("fuzz_rtcp", rtcp)?;
    let (sa, sb) = (a.wait().map_err(|e| e.to_string())?, b.wait().map_err(|e| e.to_string())?);
    if !sa.success() {
        return Err(format!("the camera's connection-lifecycle harness failed ({sa})"));
    }
    if !sb.success() {
        return Err(format!("the camera's RTCP and repair harness failed ({sb})"));
    }
    println!(
        "fuzz: camera: {lifecycle} connection-lifecycle cases and {rtcp} RTCP/repair cases in {:.0} s: no panic, every property held",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
