//! `hps-linux`: the ray tracer board's services as a Linux program on the
//! DE1-SoC's HPS (docs/linux.md).
//!
//!     hps-linux check [--accelerator uio|uio:/dev/uioN|devmem]
//!
//! `check` runs the checks the program makes before its first access to
//! the bridge (the FPGA configured, the lightweight bridge out of reset,
//! the window mapped, the ray tracer answering with a known register map)
//! and prints what it saw, or why the accelerator cannot be used (exit
//! status 1).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use hps_linux::preflight::{self, Access, System};

#[derive(Parser)]
#[command(name = "hps-linux", version, about = "The ray tracer board's services under Linux on the DE1-SoC's HPS")]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Check that the accelerator can be used: FPGA configured, bridge out
    /// of reset, window mapped, ray tracer answering; print what was seen.
    Check {
        /// How the bridge window is mapped: `uio` (the UIO device whose map
        /// 0 is the lightweight bridge), `uio:/dev/uioN`, or `devmem`
        /// (/dev/mem at 0xff200000, as root).
        #[arg(long, default_value = "uio", value_parser = parse_access)]
        accelerator: Access,
        /// sysfs (a stand-in in tests).
        #[arg(long, default_value = "/sys", hide = true)]
        sysfs: PathBuf,
        /// Device nodes (a stand-in in tests).
        #[arg(long, default_value = "/dev", hide = true)]
        dev: PathBuf,
        /// Physical memory (a stand-in in tests).
        #[arg(long, default_value = "/dev/mem", hide = true)]
        dev_mem: PathBuf,
    },
}

fn parse_access(s: &str) -> Result<Access, String> {
    match s {
        "uio" => Ok(Access::Uio(None)),
        "devmem" => Ok(Access::DevMem),
        _ => match s.strip_prefix("uio:") {
            Some(path) if !path.is_empty() => Ok(Access::Uio(Some(path.into()))),
            _ => Err(format!("{s:?}: expected uio, uio:/dev/uioN or devmem")),
        },
    }
}

fn main() -> ExitCode {
    match Args::parse().command {
        Command::Check { accelerator, sysfs, dev, dev_mem } => {
            let sys = System { sysfs, dev, dev_mem };
            match preflight::open(&sys, &accelerator) {
                Ok((_, report)) => {
                    println!("FPGA: {}", report.fpga);
                    println!("bridge: {}", report.bridge);
                    println!("window: {}", report.window);
                    println!("register map: version {}", report.register_map);
                    match report.build_id {
                        0 => println!("FPGA build: none recorded"),
                        id => println!("FPGA build: {id:07x}"),
                    }
                    println!("accelerator: ready");
                    ExitCode::SUCCESS
                }
                Err(refusal) => {
                    eprintln!("hps-linux: {refusal}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}
