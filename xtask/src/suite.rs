//! `cargo xtask test`: the whole suite, installing what it needs.

use std::process::Command;

use crate::Result;

/// The firmware's target; everything `no_std` must build for it.
const FIRMWARE_TARGET: &str = "armv7a-none-eabi";

pub fn run() -> Result<()> {
    ensure_rust_target(FIRMWARE_TARGET)?;
    step("host tests", cargo(&["test", "--workspace"]))?;
    step(
        "model builds no_std for the firmware target",
        cargo(&["build", "-p", "model", "--target", FIRMWARE_TARGET]),
    )?;
    let mut doc = cargo(&["doc", "--workspace", "--no-deps"]);
    doc.env("RUSTDOCFLAGS", "-D warnings");
    step("rustdoc without warnings", doc)?;
    println!("xtask test: all steps passed");
    Ok(())
}

fn cargo(args: &[&str]) -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.args(args);
    c
}

fn step(what: &str, mut cmd: Command) -> Result<()> {
    println!("==> {what}: {cmd:?}");
    let status = cmd.status().map_err(|e| format!("{what}: cannot start: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed ({status})"))
    }
}

/// Add a rustup target when it is missing (a fresh machine has only the host).
fn ensure_rust_target(target: &str) -> Result<()> {
    let out = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .map_err(|e| format!("rustup not found ({e}); install Rust with rustup first"))?;
    if String::from_utf8_lossy(&out.stdout).lines().any(|l| l.trim() == target) {
        return Ok(());
    }
    let mut add = Command::new("rustup");
    add.args(["target", "add", target]);
    step(&format!("install rust target {target}"), add)
}
