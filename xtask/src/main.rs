//! `cargo xtask <command>`: project automation in Rust, so it runs wherever
//! cargo does.

mod model_cmds;
mod suite;

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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Test => suite::run(),
        Command::Render(args) => model_cmds::render(&args),
        Command::Golden(args) => model_cmds::golden(&args),
        Command::Quality => model_cmds::quality(),
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
