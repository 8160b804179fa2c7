//! `cargo xtask <command>`: project automation in Rust, so it runs wherever
//! cargo does.
//!
//! Modules by concern, in layers, each importing only from below or from
//! its own folder (each folder's `mod.rs` says what it may import; the
//! `layering` test holds the sources to it):
//!
//! * `main.rs`: the command line;
//! * [`suite`]: `cargo xtask test`, every group in order;
//! * the groups: [`emulated`] (the firmware on QEMU: end-to-end tests,
//!   benches, soak), which uses [`images`] (firmware, U-Boot image, SD
//!   card); [`fpga`] (RTL checks); [`host`] (model commands, live viewer,
//!   real players, fuzz harnesses);
//! * [`support`]: paths, the step runner, tool installation, the error type.

mod emulated;
mod fpga;
mod host;
mod images;
mod linux;
mod suite;
mod support;

#[cfg(test)]
mod layering;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "cargo xtask", about = "Ray tracer project tasks")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the whole test suite, installing missing tools first.
    Test,
    /// Render one frame with the fixed-point model to a PNG.
    Render(host::model_cmds::RenderArgs),
    /// Dump golden rows (one 0x00RRGGBB word per line) for the RTL co-simulation.
    Golden(host::model_cmds::GoldenArgs),
    /// Print the quality report: the model against the f64 reference.
    Quality,
    /// Build the firmware for QEMU's npcm750-evb and boot it, forwarding
    /// host ports to the firmware's frame and persistent ports.
    Qemu(images::firmware::QemuArgs),
    /// Build the DE1-SoC payload: raw binary and U-Boot legacy image.
    Image(images::firmware::ImageArgs),
    /// Boot the QEMU firmware and run the end-to-end tests against it.
    QemuTest,
    /// Guest instructions per frame (QEMU -icount) and the board cost model.
    BenchFw(emulated::bench_fw::BenchArgs),
    /// Write an SD-card image that boots the DE1-SoC into the firmware:
    /// U-Boot SPL and U-Boot (Debian's source, patched), boot script,
    /// firmware, and the FPGA image if given.
    Sdcard(images::sdcard::SdcardArgs),
    /// The suite's SD-card test on its own: an image with a stand-in FPGA
    /// image, checked with the project's parsers and with the tools.
    SdcardTest,
    /// The board's services as a Linux program: hps-linux cross-built for
    /// the HPS's ARM Linux (one static executable), run under QEMU user mode
    /// and on Debian's ARM kernel in QEMU's virt machine
    LinuxTest,
    /// hps-linux on a real ARM Linux kernel alone: Debian's armmp kernel in
    /// QEMU's virt machine, from an initramfs built here; the three
    /// services checked, the time to the first frame printed
    LinuxBoot,
    /// Frames per second of hps-linux on the host (simulated accelerator),
    /// one and four viewers, beside hps-sim's
    LinuxBench,
    /// The live viewer end to end under Xvfb (a scripted session).
    LiveTest,
    /// The emulated board behind a lossy link, the kernel's TCP as the
    /// peer: clean, 2% and 10% loss; times, faults, retransmissions.
    LossyBench(emulated::lossy::BenchArgs),
    /// The suite's lossy-link checks on their own: frames through 2% loss
    /// over TCP, RTP with NACK repair at 2% and 10% loss.
    LossyTest,
    /// The camera's session ids and SSRCs on two boots of one image under
    /// QEMU's -icount: they must differ.
    EntropyTest,
    /// A long run of the emulated board: 1,000 frames in one boot, every
    /// one checked, nothing leaked.
    Soak(emulated::soak::SoakArgs),
    /// Real players as clients: GStreamer receives hps-sim's RTSP streams
    /// (a fixed light, an orbit); every frame must be the model's.
    Players,
    /// Many viewers at once: four real players of the emulated board (one
    /// rendered frame for all), a fifth refused; hps-sim's shared and
    /// separate streams.
    Viewers,
    /// The hostile-input harnesses with many cases (frame server, MAC
    /// receive path).
    Fuzz(host::fuzz::FuzzArgs),
    /// One viewer that checks its frames (run inside a network namespace
    /// by the multicast checks).
    #[command(hide = true)]
    Receive(host::viewers::ReceiveArgs),
    /// Install everything the suite uses (the Rust target and components,
    /// Debian's packages with one `apt-get update`), and run nothing.
    InstallTools,
    /// The web page in Chromium: served by hps-sim, then by the emulated
    /// board while a hostile client attacks its port, then played on.
    WebTest {
        /// Minutes the page plays after the attack (the suite plays two).
        #[arg(long, default_value_t = 10)]
        minutes: u32,
    },
    /// The web page's hostile client (run by the browser check while the
    /// page plays).
    #[command(hide = true)]
    HostileWeb(emulated::web::ClientArgs),
    /// The hostile-network test's client (run inside its namespace).
    #[command(hide = true)]
    HostileClient(emulated::hostile::ClientArgs),
    /// The network camera on a hostile network: half-open connections,
    /// random bytes, a NACK flood, a killed player, multicast counted on
    /// the board's link.
    Hostile,
    /// What one host may do to the others, on a virtual LAN where every
    /// client has an address of its own: per-host caps of the camera,
    /// SYNs nobody completes, a viewer that never reads.
    PerHost,
    /// The board's address on networks it was not built for: slirp's DHCP
    /// server, dnsmasq on a virtual LAN (and a lease that moves), no DHCP
    /// server at all (link-local).
    Addressing,
    /// Two boards on one virtual LAN, found by name: mDNS probing and
    /// renaming, DNS-SD browsed with python-zeroconf, frames by name.
    Names,
    /// A board carried to a network without DHCP (its cable out and in)
    /// and back: found by name at a link-local address, then at its lease,
    /// within 15 s each.
    Moved,
    /// `rt-client doctor` against hps-sim and the emulated board, healthy
    /// and with five faults injected: each must be named.
    Doctor,
    /// The client `lossy-bench` runs inside its network namespace.
    #[command(hide = true)]
    LossyClient(emulated::lossy::ClientArgs),
    /// FPGA checks: Verilator lint, whole-frame co-simulation against the
    /// model, the Quartus files' consistency, Yosys resource estimate and
    /// logic depth.
    Rtl(fpga::rtl::RtlArgs),
    /// The co-simulated VGA scan-out of the frame for a light: the
    /// simulated monitor's 640x480 picture as PNG.
    Vga(fpga::vga::VgaArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Test => suite::run(),
        Command::InstallTools => suite::install_tools(),
        Command::Render(args) => host::model_cmds::render(&args),
        Command::Golden(args) => host::model_cmds::golden(&args),
        Command::Quality => host::model_cmds::quality(),
        Command::Qemu(args) => images::firmware::qemu(&args),
        Command::Image(args) => images::firmware::image(&args),
        Command::QemuTest => suite::qemu_tests(),
        Command::Viewers => suite::viewers(),
        Command::Receive(args) => host::viewers::receive(&args),
        Command::HostileClient(args) => emulated::hostile::client(&args),
        Command::HostileWeb(args) => emulated::web::client(&args),
        Command::WebTest { minutes } => suite::web(minutes),
        Command::Hostile => suite::hostile(),
        Command::PerHost => suite::per_host(),
        Command::Addressing => suite::addressing(),
        Command::Names => suite::names(),
        Command::Moved => suite::moved(),
        Command::Doctor => suite::doctor(),
        Command::LossyTest => support::tools::ensure_qemu().and_then(|()| emulated::lossy::suite_test()),
        Command::EntropyTest => support::tools::ensure_qemu()
            .and_then(|()| images::firmware::build("qemu-npcm750", &["sim-accelerator"]))
            .and_then(|elf| emulated::entropy::run(&elf))
            .map(|summary| println!("{summary}")),
        Command::BenchFw(args) => emulated::bench_fw::run(&args),
        Command::Sdcard(args) => images::sdcard::run(&args),
        Command::SdcardTest => images::sdcard::suite_test(),
        Command::LinuxTest => linux::run(),
        Command::LinuxBoot => {
            linux::ensure_tools().and_then(|()| linux::build()).and_then(|exe| linux::system::run(&exe))
        }
        Command::LinuxBench => linux::bench::run(),
        Command::LiveTest => host::live_test::run(),
        Command::LossyBench(args) => emulated::lossy::bench(&args),
        Command::Soak(args) => emulated::soak::run(&args),
        Command::Players => host::players::run(),
        Command::Fuzz(args) => host::fuzz::run(&args),
        Command::LossyClient(args) => emulated::lossy::client(&args),
        Command::Rtl(args) => fpga::rtl::run_cli(&args),
        Command::Vga(args) => fpga::vga::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
