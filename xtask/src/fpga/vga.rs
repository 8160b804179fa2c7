//! `cargo xtask vga`: what a VGA monitor on the board would show. Renders
//! the frame for a light with the model, puts it in the co-simulation's
//! memory, lets the Verilated `rt_top` scan it out (640x480@60, full screen
//! or letterbox) and writes the picture the testbench's monitor rebuilt
//! from the VGA pins, after checking it against `model::display`, as PNG.

use std::fs;
use std::path::PathBuf;
use std::process::Command;

use clap::Args;
use model::display::{DISPLAY_HEIGHT, DISPLAY_WIDTH};
use model::{Light, HEIGHT};

use super::rtl::{build_cosim, rtl_files, vga_args, write_display_maps, write_golden, DEFAULT_LANES};
use crate::support::tools::{ensure_apt_packages, root, step};
use crate::support::Result;

#[derive(Args)]
pub struct VgaArgs {
    /// Light position in world units, e.g. 3,4,-2.
    #[arg(long, allow_hyphen_values = true, default_value = "3,4,-2")]
    light: Light,
    /// Output PNG path (640 x 480).
    #[arg(long, default_value = "vga.png")]
    out: PathBuf,
    /// The frame 1:1 in the middle instead of scaled to the full screen.
    #[arg(long)]
    letterbox: bool,
}

pub fn run(args: &VgaArgs) -> Result<()> {
    let root = root();
    let out = root.join("target/rtl");
    let dir = out.join("vga");
    fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    ensure_apt_packages(&["verilator", "g++", "make"], None)?;
    let files = rtl_files(&root.join("fpga/rtl"))?;
    let golden = dir.join("frame.hex");
    write_golden(&golden, &args.light, 0, HEIGHT as u16)?;
    let maps = write_display_maps(&dir)?;
    let bin = build_cosim(&root, &out, &files, DEFAULT_LANES)?;
    let ppm = dir.join("vga.ppm");
    let mut sim = Command::new(&bin);
    sim.arg("--frame").arg(&golden).arg("--vga-only").arg("--vga-out").arg(&ppm);
    vga_args(&mut sim, &maps);
    if args.letterbox {
        sim.arg("--letterbox");
    }
    step("co-simulated VGA scan-out, two frames checked against model::display", sim)?;
    let data = fs::read(&ppm).map_err(|e| format!("{}: {e}", ppm.display()))?;
    let header = format!("P6\n{DISPLAY_WIDTH} {DISPLAY_HEIGHT}\n255\n");
    let pixels = data
        .strip_prefix(header.as_bytes())
        .filter(|p| p.len() == DISPLAY_WIDTH * DISPLAY_HEIGHT * 3)
        .ok_or_else(|| format!("{}: not a {DISPLAY_WIDTH}x{DISPLAY_HEIGHT} PPM", ppm.display()))?;
    image::save_buffer(&args.out, pixels, DISPLAY_WIDTH as u32, DISPLAY_HEIGHT as u32, image::ExtendedColorType::Rgb8)
        .map_err(|e| format!("writing {}: {e}", args.out.display()))?;
    println!("==> {}: the simulated monitor's 640x480 picture", args.out.display());
    Ok(())
}
