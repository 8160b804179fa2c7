//! `hps-linux`: the ray tracer board's services as a Linux program on the
//! DE1-SoC's HPS (docs/linux.md).
//!
//!     hps-linux [--accelerator uio|uio:/dev/uioN|devmem|sim] [--software-fallback]
//!         [--listen 0.0.0.0:7878] [--rtsp ADDR] [--http ADDR] [--multicast-group G]
//!     hps-linux check [--accelerator ...]
//!
//! Serves the seed protocol on the listen port (the persistent protocol on
//! the next), RTSP/RTP on `--rtsp` (default: the listen address, port
//! 8554) and the web page on `--http` when given, every client from one
//! accelerator and one frame ring, as the bare-metal firmware does. The
//! flags mean what hps-sim's do (rt-services-std `cli`).
//!
//! `check` runs the checks made before the first access to the bridge and
//! prints what it saw, or why the accelerator cannot be used (exit 1).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args as ClapArgs, Parser, Subcommand};
use hps_linux::preflight::{self, Access, System};
use hps_linux::serve;
use rt_services_std::cli::ServiceArgs;
use rt_services_std::rtsp::Options;
use rt_services_std::Server;

#[derive(Parser)]
#[command(
    name = "hps-linux",
    version,
    about = "The ray tracer board's services under Linux on the DE1-SoC's HPS",
    long_about = "The ray tracer board's services under Linux on the DE1-SoC's HPS: the seed protocol, \
                  RTSP/RTP and the web page, every client from one accelerator and one frame ring.\n\n\
                  Load the FPGA image and enable the bridges first (docs/linux.md); `hps-linux check` \
                  says whether the accelerator can be used.",
    args_conflicts_with_subcommands = true
)]
struct Args {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    serve: ServeArgs,
}

#[derive(Subcommand)]
enum Command {
    /// Check that the accelerator can be used: FPGA configured, bridge out
    /// of reset, window mapped, ray tracer answering; print what was seen.
    Check {
        #[command(flatten)]
        access: AccessArgs,
    },
}

#[derive(ClapArgs)]
struct AccessArgs {
    /// The accelerator: `uio` (the UIO device whose map 0 is the
    /// lightweight bridge), `uio:/dev/uioN`, `devmem` (/dev/mem at
    /// 0xff200000, as root), or `sim` (hal-avalon's simulated one, no board).
    #[arg(long, default_value = "uio", value_parser = parse_accelerator)]
    accelerator: Accelerator,
    /// sysfs (a stand-in in tests).
    #[arg(long, default_value = "/sys", hide = true)]
    sysfs: PathBuf,
    /// Device nodes (a stand-in in tests).
    #[arg(long, default_value = "/dev", hide = true)]
    dev: PathBuf,
    /// Physical memory (a stand-in in tests).
    #[arg(long, default_value = "/dev/mem", hide = true)]
    dev_mem: PathBuf,
}

impl AccessArgs {
    fn system(&self) -> System {
        System { sysfs: self.sysfs.clone(), dev: self.dev.clone(), dev_mem: self.dev_mem.clone() }
    }
}

#[derive(ClapArgs)]
struct ServeArgs {
    #[command(flatten)]
    access: AccessArgs,
    /// When the accelerator cannot be used, serve frames rendered in
    /// software instead of stopping (said in the log and `/status`).
    #[arg(long)]
    software_fallback: bool,
    /// Address of the seed-protocol port; the persistent port is the next one.
    #[arg(long, default_value_t = SocketAddr::from(([0, 0, 0, 0], rt_services::FRAME_PORT)))]
    listen: SocketAddr,
    #[command(flatten)]
    services: ServiceArgs,
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum Accelerator {
    Board(Access),
    Sim,
}

fn parse_accelerator(s: &str) -> Result<Accelerator, String> {
    match s {
        "sim" => Ok(Accelerator::Sim),
        "uio" => Ok(Accelerator::Board(Access::Uio(None))),
        "devmem" => Ok(Accelerator::Board(Access::DevMem)),
        _ => match s.strip_prefix("uio:") {
            Some(path) if !path.is_empty() => Ok(Accelerator::Board(Access::Uio(Some(path.into())))),
            _ => Err(format!("{s:?}: expected uio, uio:/dev/uioN, devmem or sim")),
        },
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    match args.command {
        Some(Command::Check { access }) => check(&access),
        None => run(args.serve),
    }
}

fn check(access: &AccessArgs) -> ExitCode {
    let Accelerator::Board(how) = &access.accelerator else {
        println!("accelerator: simulated, nothing to check");
        return ExitCode::SUCCESS;
    };
    match preflight::open(&access.system(), how) {
        Ok((_, report)) => {
            println!("FPGA: {}", report.fpga);
            println!("bridge: {}", report.bridge);
            println!("window: {}", report.window);
            println!("register map: version {}", report.register_map);
            match report.build_id {
                0 => println!("FPGA build: none recorded"),
                id => println!("FPGA build: {id:07x}"),
            }
            println!("frame memory: {}", frame_memory_line(&access.system()));
            println!("accelerator: ready");
            ExitCode::SUCCESS
        }
        Err(refusal) => {
            eprintln!("hps-linux: {refusal}");
            ExitCode::FAILURE
        }
    }
}

/// What frame mode has to work with: the ring's buffer, or why rows.
fn frame_memory_line(system: &System) -> String {
    match serve::frame_memory(system) {
        Err(why) => why,
        Ok(ring) => format!("{ring:?}: frame mode, once the self-test's frame half passes there"),
    }
}

fn run(args: ServeArgs) -> ExitCode {
    let (board, facts) = match &args.access.accelerator {
        Accelerator::Sim => serve::simulated(),
        Accelerator::Board(how) => {
            let opened =
                preflight::open(&args.access.system(), how).map_err(|r| r.to_string()).and_then(|(port, report)| {
                    eprintln!("hps-linux: FPGA: {}; bridge: {}", report.fpga, report.bridge);
                    eprintln!(
                        "hps-linux: {}: register map version {}, FPGA build {:07x}",
                        report.window, report.register_map, report.build_id
                    );
                    let memory = serve::frame_memory(&args.access.system());
                    if let Err(why) = &memory {
                        eprintln!("hps-linux: {why}");
                    }
                    serve::fpga(port, &report, memory).map_err(|t| t.detail)
                });
            match opened {
                Ok(b) => b,
                Err(why) if args.software_fallback => {
                    eprintln!("hps-linux: {why}");
                    eprintln!("hps-linux: --software-fallback: rendering in software");
                    serve::software(&why)
                }
                Err(why) => {
                    eprintln!("hps-linux: {why}");
                    eprintln!("hps-linux: (--software-fallback serves frames rendered in software instead)");
                    return ExitCode::FAILURE;
                }
            }
        }
    };
    eprintln!("hps-linux: {}", facts.self_test.detail);
    eprintln!("hps-linux: VGA: {}", facts.vga);
    serve::drive(board.clone());
    let renderer = board.renderer().to_string();
    let mut server = match Server::start_board(args.listen, board.clone(), facts, true) {
        Ok(server) => server,
        Err(e) => {
            eprintln!("hps-linux: cannot listen on {} and the next port: {e}", args.listen);
            return ExitCode::FAILURE;
        }
    };
    // The device is the board's (its camera draws from it): not used.
    let options = Options::new(true);
    let started = match args.services.start(&mut server, args.listen, options) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("hps-linux: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Some(http) = started.http {
        eprintln!("hps-linux: web page on http://{http}/");
    }
    eprintln!(
        "hps-linux: {renderer}; frames on {}, persistent on {}, RTSP on rtsp://{}/light/3,4,-2 (also /orbit, /live)",
        server.frame_addr(),
        server.persistent_addr(),
        started.rtsp
    );
    stopping::watch();
    while !stopping::asked() {
        std::thread::sleep(Duration::from_millis(200));
    }
    // systemctl stop, or ^C: the display off and the lights out, rather
    // than the FPGA scanning out the last frame for ever.
    board.shut_down();
    eprintln!("hps-linux: stopped");
    ExitCode::SUCCESS
}

/// SIGTERM and SIGINT ask the program to stop; the main thread notices.
mod stopping {
    use std::sync::atomic::{AtomicBool, Ordering};

    static ASKED: AtomicBool = AtomicBool::new(false);

    extern "C" fn on_signal(_: libc::c_int) {
        // Only an atomic store: async-signal-safe.
        ASKED.store(true, Ordering::Relaxed);
    }

    /// Install the handlers.
    pub fn watch() {
        for signal in [libc::SIGTERM, libc::SIGINT] {
            // SAFETY: `on_signal` is an `extern "C" fn(c_int)` that only
            // stores to an atomic, which is async-signal-safe; replacing
            // the default action of these two signals affects nothing
            // else in the program.
            unsafe { libc::signal(signal, on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t) };
        }
    }

    /// Whether a stop was asked for.
    pub fn asked() -> bool {
        ASKED.load(Ordering::Relaxed)
    }
}
