//! `cargo xtask test`: the whole suite, installing what it needs.
//!
//! Each step prints a `==>` line; the first failure stops the run with a
//! non-zero exit.
//!
//! May import: `emulated`, `fpga`, `host`, `images`, `linux`, `support`. The suite
//! sits above every group: it runs them all, in order.

use crate::support::timing::Timings;
use crate::support::tools::{
    apt_install, apt_installed, cargo, ensure_apt_packages, ensure_apt_source, ensure_qemu, ensure_rust_components,
    ensure_rust_target, qemu_wanted, step, BOARDS, FIRMWARE_TARGET,
};
use crate::support::Result;

/// Library crates that must build for the bare-metal target without `std`
/// (with the features the firmware uses).
const NO_STD_CRATES: &[(&str, &str)] =
    &[("model", ""), ("rt-services", "smoltcp"), ("hal-avalon", ""), ("dwmac", ""), ("soc", "")];

/// Every Debian package the suite's steps use: installed at its start
/// with one `apt-get update` (each step still makes sure of its own, and
/// then finds them there). QEMU and its tools come from bookworm-backports
/// ([`qemu_wanted`], and `qemu-user` for the Linux program).
fn suite_packages() -> Vec<&'static str> {
    let lists: [&[&'static str]; 13] = [
        &["verilator", "g++", "make"],
        &crate::support::player::PLAYER_PACKAGES,
        &crate::host::players::GSTREAMER_PACKAGES,
        &crate::emulated::viewers::RELAY_PACKAGES,
        &crate::emulated::lan::PACKAGES,
        &crate::emulated::names::PACKAGES,
        &crate::emulated::per_host::PACKAGES,
        crate::images::sdcard::PACKAGES,
        &crate::linux::PACKAGES,
        &crate::support::browser::BROWSER_PACKAGES,
        &crate::host::live_test::PACKAGES,
        &crate::images::firmware::IMAGE_PACKAGES,
        &["qemu-user"],
    ];
    let mut all: Vec<&'static str> = lists.concat();
    all.sort_unstable();
    all.dedup();
    all
}

/// The suite's tools: the Rust target and components, the apt sources
/// (bookworm-backports, bookworm's deb-src for U-Boot), then every missing
/// package with one `apt-get update`.
pub fn install_tools() -> Result<()> {
    ensure_rust_target(FIRMWARE_TARGET)?;
    ensure_rust_components(&["clippy", "rustfmt"])?;
    ensure_apt_source("bookworm-backports", "deb", "bookworm-backports", "bookworm")?;
    ensure_apt_source(crate::images::sdcard::DEB_SRC_FILE, "deb-src", "bookworm", "bookworm")?;
    let mut backports = qemu_wanted();
    if !apt_installed("qemu-user") {
        backports.push("qemu-user");
    }
    let main: Vec<&str> =
        suite_packages().into_iter().filter(|p| !backports.contains(p) && !apt_installed(p)).collect();
    apt_install(&main, None)?;
    apt_install(&backports, Some("bookworm-backports"))?;
    // What a step checks for itself is now there.
    ensure_qemu()
}

/// Run every step; the table of their times at the end, passed or not.
pub fn run() -> Result<()> {
    let mut t = Timings::new();
    let result = run_timed(&mut t);
    println!("xtask test: the steps' times, slowest first\n{}", t.table());
    result
}

fn run_timed(t: &mut Timings) -> Result<()> {
    t.part("install the tools", install_tools)?;
    // Verilator for rtl-port (the RTL behind hal-avalon's driver, in the
    // host tests) and the RTL steps. With RT_REQUIRE_RTL=1 rtl-port's build
    // fails rather than build without the RTL, so the RTL tests always run
    // here. Set before any thread or child exists; every cargo below
    // inherits it.
    std::env::set_var("RT_REQUIRE_RTL", "1");
    t.part("rustfmt", || step("rustfmt", cargo(&["fmt", "--all", "--", "--check"])))?;
    t.part("clippy", || {
        step(
            "clippy (host crates, all targets)",
            cargo(&["clippy", "--workspace", "--exclude", "firmware", "--all-targets", "--", "-D", "warnings"]),
        )?;
        for board in BOARDS {
            step(
                &format!("clippy (firmware, {board}, {FIRMWARE_TARGET})"),
                cargo(&[
                    "clippy",
                    "-p",
                    "firmware",
                    "--target",
                    FIRMWARE_TARGET,
                    "--features",
                    board,
                    "--",
                    "-D",
                    "warnings",
                ]),
            )?;
        }
        Ok(())
    })?;
    // Plain `cargo test`: every default member, i.e. every host crate.
    t.part("host tests", || step("host tests", cargo(&["test"])))?;
    // The host tests that need an outside tool are ignored by plain
    // `cargo test` (a machine with nothing but Rust passes it) and run here,
    // where the tool was installed: mkimage (ensure_qemu) checks the U-Boot
    // image headers.
    t.part("host tests that need mkimage", || {
        step(
            "host tests that need mkimage",
            cargo(&[
                "test",
                "-p",
                "xtask",
                "--",
                "--ignored",
                "--exact",
                "images::uimage::tests::mkimage_lists_our_image_and_builds_the_same_header",
                "images::uimage::tests::mkimage_rejects_a_corrupted_payload",
            ]),
        )
    })?;
    // Real players as clients of hps-sim's RTSP server: GStreamer and
    // FFmpeg from Debian's packages (docs/streaming.md); then many viewers
    // of hps-sim at once (shared and separate streams, a laggard,
    // multicast in a namespace of its own).
    t.part("players of hps-sim", crate::host::players::run)?;
    t.part("many viewers of hps-sim", crate::host::viewers::run)?;
    // The network camera's hostile-input harnesses, a million cases each.
    t.part("fuzz the camera", || crate::host::fuzz::camera(1_000_000, 1_000_000))?;
    t.part("no_std builds", || {
        // The workspace run enables the model's `std` feature (fast float
        // paths); this runs the arithmetic properties against the
        // pure-integer paths the firmware uses.
        step("model arithmetic without std", cargo(&["test", "-p", "model", "--test", "arith"]))?;
        for (krate, features) in NO_STD_CRATES {
            let mut c = cargo(&["build", "-p", krate, "--target", FIRMWARE_TARGET]);
            if !features.is_empty() {
                c.args(["--features", features]);
            }
            step(&format!("{krate} builds no_std for {FIRMWARE_TARGET}"), c)?;
        }
        Ok(())
    })?;
    t.part("rustdoc", || {
        let mut doc = cargo(&["doc", "--workspace", "--exclude", "firmware", "--no-deps"]);
        doc.env("RUSTDOCFLAGS", "-D warnings");
        step("rustdoc without warnings", doc)
    })?;
    // The board's services as a Linux program: the ARM executable, static,
    // under QEMU user mode and on Debian's ARM kernel.
    t.part("hps-linux on ARM Linux", crate::linux::run)?;
    // Firmware: both boards build warning-free, then the QEMU end-to-end
    // tests boot the QEMU board.
    t.part("build firmware (de1-soc)", || crate::images::firmware::build("de1-soc", &[]).map(drop))?;
    qemu_tests_timed(t)?;
    // The SD-card image: U-Boot from Debian's source with the project's
    // patch, the firmware and a stand-in FPGA image, checked piece by piece.
    t.part("SD-card image", crate::images::sdcard::suite_test)?;
    // The emulated board behind a lossy link, the kernel's TCP as its peer,
    // and a short soak (cargo xtask soak runs 1,000 frames).
    t.part("lossy link", crate::emulated::lossy::suite_test)?;
    t.part("short soak of the emulated board", || {
        crate::emulated::soak::soak(40).map(|summary| println!("{summary}"))
    })?;
    // The live viewer, end to end in a window under Xvfb.
    t.part("live viewer", crate::host::live_test::run)?;
    // FPGA: lint, whole-frame co-simulation, resource estimate.
    t.part("RTL", crate::fpga::rtl::run)?;
    println!("xtask test: all steps passed");
    Ok(())
}

/// `cargo xtask viewers`: many viewers of hps-sim and of the emulated
/// board at once, and players through a relay.
pub fn viewers() -> Result<()> {
    ensure_qemu()?;
    ensure_apt_packages(&crate::support::player::PLAYER_PACKAGES, None)?;
    // host::viewers::run builds hps-sim and rt-client itself.
    println!("==> many viewers of hps-sim");
    crate::host::viewers::run()?;
    let elf = crate::images::firmware::build("qemu-npcm750", &["sim-accelerator"])?;
    many_viewers(&elf)
}

/// Many viewers of the emulated board running `elf`, then players through
/// a relay from one of its sessions.
fn many_viewers(elf: &std::path::Path) -> Result<()> {
    ensure_apt_packages(&crate::support::player::PLAYER_PACKAGES, None)?;
    ensure_apt_packages(&crate::emulated::viewers::RELAY_PACKAGES, None)?;
    crate::support::tools::build_host_programs()?;
    println!("==> many viewers of the emulated board ({})", elf.display());
    crate::emulated::viewers::run(elf)?;
    println!("==> players through a relay (tools/rtsp-relay.py) from one session of the emulated board");
    crate::emulated::viewers::relay(elf)
}

/// `cargo xtask web-test [--minutes N]`: the web page in Chromium, served
/// by hps-sim and by the emulated board under attack, then played for
/// `minutes` (the suite plays [`crate::emulated::web::SUITE_PLAY_S`]).
pub fn web(minutes: u32) -> Result<()> {
    ensure_qemu()?;
    crate::host::web_page::run()?;
    let elf = crate::images::firmware::build("qemu-npcm750", &["sim-accelerator"])?;
    web_on_the_emulated_board(&elf, minutes.saturating_mul(60))
}

fn web_on_the_emulated_board(elf: &std::path::Path, play_s: u32) -> Result<()> {
    println!(
        "==> the web page in Chromium, the emulated board under attack, then {play_s} s of play ({})",
        elf.display()
    );
    crate::emulated::web::run(elf, play_s)?;
    // Guest instruction counts (QEMU -icount), not seconds: they move by a
    // few hundred in 2.76 million between runs, not with the host's load.
    println!("==> bench-fw --web-only: the WebSocket path's instructions a frame and the board estimate");
    crate::emulated::bench_fw::web_case(6)
}

/// `cargo xtask hostile`: the network camera on a hostile network.
pub fn hostile() -> Result<()> {
    ensure_qemu()?;
    let elf = crate::images::firmware::build("qemu-npcm750", &["sim-accelerator"])?;
    println!("==> the network camera on a hostile network ({})", elf.display());
    crate::emulated::hostile::run(&elf)
}

/// `cargo xtask per-host`: what one host may do to the others.
pub fn per_host() -> Result<()> {
    ensure_qemu()?;
    let elf = crate::images::firmware::build("qemu-npcm750", &["sim-accelerator"])?;
    per_host_on(&elf)
}

/// `cargo xtask addressing`: the board's address from slirp's DHCP, from
/// dnsmasq (and moving with it), and link-local with no DHCP server.
pub fn addressing() -> Result<()> {
    ensure_qemu()?;
    let elf = crate::images::firmware::build("qemu-npcm750", &["sim-accelerator"])?;
    addressing_on(&elf)
}

fn addressing_on(elf: &std::path::Path) -> Result<()> {
    ensure_apt_packages(&crate::emulated::lan::PACKAGES, None)?;
    println!("==> the board's address on networks it was not built for ({})", elf.display());
    crate::emulated::addressing::run(elf)?;
    // The cable moved while the names wait for their announcements to age
    // out (their boards paused meanwhile).
    names_on(elf, || moved_on(elf))
}

/// `cargo xtask moved`: a board carried to a network without DHCP and
/// back, found by name on each.
pub fn moved() -> Result<()> {
    ensure_qemu()?;
    let elf = crate::images::firmware::build("qemu-npcm750", &["sim-accelerator"])?;
    ensure_apt_packages(&crate::emulated::lan::PACKAGES, None)?;
    ensure_apt_packages(&crate::emulated::names::PACKAGES, None)?;
    moved_on(&elf)
}

fn moved_on(elf: &std::path::Path) -> Result<()> {
    println!("==> a board carried to a network without DHCP and back, found by name on each ({})", elf.display());
    crate::emulated::moved::run(elf)
}

/// `cargo xtask doctor`: the doctor names what is wrong, and ticks what
/// is right.
pub fn doctor() -> Result<()> {
    ensure_qemu()?;
    println!("==> rt-client doctor against hps-sim and the emulated board, healthy and with faults");
    crate::emulated::doctor::run()
}

/// `cargo xtask names`: two boards on one LAN, found by name.
pub fn names() -> Result<()> {
    ensure_qemu()?;
    let elf = crate::images::firmware::build("qemu-npcm750", &["sim-accelerator"])?;
    ensure_apt_packages(&crate::emulated::lan::PACKAGES, None)?;
    names_on(&elf, || Ok(()))
}

fn names_on(elf: &std::path::Path, meanwhile: impl FnOnce() -> Result<()>) -> Result<()> {
    ensure_apt_packages(&crate::emulated::names::PACKAGES, None)?;
    crate::support::tools::build_host_programs()?;
    println!("==> two boards on one LAN, found by name (mDNS, DNS-SD) ({})", elf.display());
    crate::emulated::names::run(elf, meanwhile)
}

fn per_host_on(elf: &std::path::Path) -> Result<()> {
    ensure_apt_packages(&crate::emulated::per_host::PACKAGES, None)?;
    println!("==> what one host may do to the others, on a virtual LAN ({})", elf.display());
    crate::emulated::per_host::run(elf)
}

/// `cargo xtask players`' GStreamer checks against the emulated board.
pub fn players_on_the_emulated_board(elf: &std::path::Path) -> Result<()> {
    let mut g = crate::images::firmware::Guest::boot(elf, &[])?;
    // The documented boot log's service lines, as this build prints them
    // (the display's line comes last of them).
    g.wait_for_line(0, "display: VGA scan-out", std::time::Duration::from_secs(30))?;
    println!("==> {}", crate::emulated::boot_log::check(&g.uart())?);
    let f = g.forwards.ok_or("the guest has no forwarded ports")?;
    if f.rtcp != rt_services::camera::rtsp::SERVER_RTP_PORT + 1 {
        println!("players: host UDP port 5005 is taken: GStreamer's RTCP will not reach the board (no repair)");
    }
    let dir = crate::support::tools::root().join("target/players/emulated");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let rtsp = std::net::SocketAddr::from(([127, 0, 0, 1], f.rtsp));
    // On failure the board's side too: its UART says what its RTSP server
    // and camera saw.
    crate::host::players::check_server("the emulated board", rtsp, &dir)
        .map_err(|e| format!("{e}\nthe emulated board's UART:\n{}", g.uart()))
}

/// `cargo xtask qemu-test`: build the QEMU firmware (warnings are errors)
/// and run the end-to-end tests against it; the table of their times at
/// the end.
pub fn qemu_tests() -> Result<()> {
    ensure_qemu()?;
    let mut t = Timings::new();
    let result = qemu_tests_timed(&mut t);
    println!("xtask qemu-test: the steps' times, slowest first\n{}", t.table());
    result
}

/// The emulated board's tests, each a part of `t`.
fn qemu_tests_timed(t: &mut Timings) -> Result<()> {
    use crate::images::firmware::build;
    t.part("QEMU end-to-end tests", || {
        let elf = build("qemu-npcm750", &[])?;
        println!("==> QEMU end-to-end tests ({})", elf.display());
        crate::emulated::qemu_e2e::run(&elf)?;
        crate::emulated::early_frames::run(&elf)?;
        let elf = build("qemu-npcm750", &["reentry-test"])?;
        crate::emulated::qemu_e2e::reentry(&elf)
    })?;
    // The frame-mode build over the simulated accelerator (map version 3)
    // also drives the VGA display: attract mode, the display's counter, a
    // client's frame on screen. A real player against the emulated board:
    // GStreamer through the forwarded RTSP port (the rows leave through
    // two-buffer descriptors).
    let elf = t.part("build firmware (sim-accelerator)", || build("qemu-npcm750", &["sim-accelerator"]))?;
    t.part("players of the emulated board", || players_on_the_emulated_board(&elf))?;
    t.part("session ids and SSRCs on two boots", || {
        crate::emulated::entropy::run(&elf).map(|summary| println!("{summary}"))
    })?;
    // Many viewers of the emulated board, players through a relay, and the
    // camera on a hostile network.
    t.part("many viewers of the emulated board", || many_viewers(&elf))?;
    t.part("hostile network", || {
        println!("==> the network camera on a hostile network ({})", elf.display());
        crate::emulated::hostile::run(&elf)
    })?;
    t.part("one host against the others", || per_host_on(&elf))?;
    t.part("addressing and names", || addressing_on(&elf))?;
    t.part("doctor", doctor)?;
    // The web page in Chromium: served by hps-sim, then by the emulated
    // board while a hostile client attacks its port.
    t.part("the page in Chromium, hps-sim", crate::host::web_page::run)?;
    t.part("the page in Chromium, the emulated board", || {
        web_on_the_emulated_board(&elf, crate::emulated::web::SUITE_PLAY_S)
    })?;
    // The other renderers: row mode, and the FPGA's code paths (driver,
    // frame DMA into the ring, pipelined rows) over the simulated
    // accelerator, which passes the boot self-test; and one whose
    // simulated accelerator gets a pixel wrong: the self-test fails and
    // software serves the frames; and one whose frame DMA's memory never
    // answers: row mode passes, the FPGA renders rows into the ring.
    use crate::emulated::qemu_e2e::{frame_port_fault_lines, selftest_fault_lines, SELFTEST_PASS, SELFTEST_SKIPPED};
    let (skipped, pass) = (vec![SELFTEST_SKIPPED.to_string()], vec![SELFTEST_PASS.to_string()]);
    t.part("the other renderers", || {
        for (features, renderer, uart, display) in [
            (&["row-mode"][..], "row mode, software renderer", skipped, false),
            (
                &["sim-accelerator"][..],
                "frame mode, FPGA frame DMA into the ring (software fallback)",
                pass.clone(),
                true,
            ),
            (&["sim-accelerator", "row-mode"][..], "row mode, FPGA rows (software fallback)", pass, false),
            (&["selftest-fault"][..], "frame mode, software renderer into the ring", selftest_fault_lines()?, false),
            (
                &["frame-port-fault"][..],
                "frame mode, FPGA rows into the ring (its frame DMA is not used; software fallback)",
                frame_port_fault_lines(),
                false,
            ),
        ] {
            let elf = build("qemu-npcm750", features)?;
            crate::emulated::qemu_e2e::variant(&elf, renderer, &uart, display)?;
        }
        Ok(())
    })
}
