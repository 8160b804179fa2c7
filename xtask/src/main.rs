//! `cargo xtask <command>`: project automation in Rust, so it runs wherever
//! cargo does.

mod bench_fw;
mod cost_model;
mod depth;
mod entry_check;
mod firmware;
mod fuzz;
mod live_test;
mod lossy;
mod model_cmds;
mod qemu_e2e;
mod quartus_check;
mod rtl;
mod sdcard;
mod soak;
mod suite;
mod tools;
mod uimage;

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
    Render(model_cmds::RenderArgs),
    /// Dump golden rows (one 0x00RRGGBB word per line) for the RTL co-simulation.
    Golden(model_cmds::GoldenArgs),
    /// Print the quality report: the model against the f64 reference.
    Quality,
    /// Build the firmware for QEMU's npcm750-evb and boot it, forwarding
    /// host ports to the firmware's frame and persistent ports.
    Qemu(firmware::QemuArgs),
    /// Build the DE1-SoC payload: raw binary and U-Boot legacy image.
    Image(firmware::ImageArgs),
    /// Boot the QEMU firmware and run the end-to-end tests against it.
    QemuTest,
    /// Guest instructions per frame (QEMU -icount) and the board cost model.
    BenchFw(bench_fw::BenchArgs),
    /// Write an SD-card image that boots the DE1-SoC into the firmware:
    /// U-Boot SPL and U-Boot (Debian's source, patched), boot script,
    /// firmware, and the FPGA image if given.
    Sdcard(sdcard::SdcardArgs),
    /// The suite's SD-card test on its own: an image with a stand-in FPGA
    /// image, checked with the project's parsers and with the tools.
    SdcardTest,
    /// The live viewer end to end under Xvfb (a scripted session).
    LiveTest,
    /// The emulated board behind a lossy link, the kernel's TCP as the
    /// peer: clean, 2% and 10% loss; times, faults, retransmissions.
    LossyBench(lossy::BenchArgs),
    /// A long run of the emulated board: 1,000 frames in one boot, every
    /// one checked, nothing leaked.
    Soak(soak::SoakArgs),
    /// The hostile-input harnesses with many cases (frame server, MAC
    /// receive path).
    Fuzz(fuzz::FuzzArgs),
    /// The client `lossy-bench` runs inside its network namespace.
    #[command(hide = true)]
    LossyClient(lossy::ClientArgs),
    /// FPGA checks: Verilator lint, whole-frame co-simulation against the
    /// model, the Quartus files' consistency, Yosys resource estimate and
    /// logic depth.
    Rtl(rtl::RtlArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Test => suite::run(),
        Command::Render(args) => model_cmds::render(&args),
        Command::Golden(args) => model_cmds::golden(&args),
        Command::Quality => model_cmds::quality(),
        Command::Qemu(args) => firmware::qemu(&args),
        Command::Image(args) => firmware::image(&args),
        Command::QemuTest => suite::qemu_tests(),
        Command::BenchFw(args) => bench_fw::run(&args),
        Command::Sdcard(args) => sdcard::run(&args),
        Command::SdcardTest => sdcard::suite_test(),
        Command::LiveTest => live_test::run(),
        Command::LossyBench(args) => lossy::bench(&args),
        Command::Soak(args) => soak::run(&args),
        Command::Fuzz(args) => fuzz::run(&args),
        Command::LossyClient(args) => lossy::client(&args),
        Command::Rtl(args) => rtl::run_cli(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Errors of xtask commands: one line for the user.
pub type Result<T> = std::result::Result<T, String>;
