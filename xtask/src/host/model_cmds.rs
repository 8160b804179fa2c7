//! Commands built on the model: render a PNG, dump golden rows, quality report.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use clap::Args;
use model::{render_row, Light, HEIGHT, WIDTH};

use crate::support::Result;

#[derive(Args)]
pub struct RenderArgs {
    /// Light position in world units, e.g. 3,4,-2.
    #[arg(long, allow_hyphen_values = true, default_value = "3,4,-2")]
    light: Light,
    /// Output PNG path.
    #[arg(long, default_value = "frame.png")]
    out: PathBuf,
}

pub fn render(args: &RenderArgs) -> Result<()> {
    let frame = model::render_frame(&args.light);
    image::save_buffer(&args.out, &frame, WIDTH as u32, HEIGHT as u32, image::ExtendedColorType::Rgb8)
        .map_err(|e| format!("writing {}: {e}", args.out.display()))?;
    println!("wrote {} ({}x{})", args.out.display(), WIDTH, HEIGHT);
    Ok(())
}

#[derive(Args)]
pub struct GoldenArgs {
    /// Light position in world units, e.g. 3,4,-2.
    #[arg(long, allow_hyphen_values = true)]
    light: Light,
    /// Output file: a header comment, then 360 x 480 lines of 8 hex digits.
    #[arg(long)]
    out: PathBuf,
    /// First row to dump.
    #[arg(long, default_value_t = 0)]
    first_row: u16,
    /// Number of rows to dump.
    #[arg(long, default_value_t = HEIGHT as u16)]
    rows: u16,
}

/// Golden rows: line `k` after the header is pixel `k % 480` of row
/// `first_row + k / 480`, as `0x00RRGGBB` in 8 hex digits. `$readmemh`
/// skips the `//` header.
pub fn golden(args: &GoldenArgs) -> Result<()> {
    let file = fs::File::create(&args.out).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let mut w = BufWriter::new(file);
    let [x, y, z] = args.light.raw();
    let io = |e: std::io::Error| format!("{}: {e}", args.out.display());
    writeln!(w, "// golden rows {}..{} light raw {x} {y} {z}", args.first_row, args.first_row + args.rows)
        .map_err(io)?;
    let mut row = [0u32; WIDTH];
    for y in args.first_row..args.first_row + args.rows {
        render_row(y, &args.light, &mut row);
        for word in row {
            writeln!(w, "{word:08x}").map_err(io)?;
        }
    }
    w.flush().map_err(io)?;
    println!("wrote {} rows to {}", args.rows, args.out.display());
    Ok(())
}

pub fn quality() -> Result<()> {
    println!("{:<34} {:>9} {:>9} {:>5}", "light", "PSNR dB", "within 8", "max");
    for (name, light) in model::quality::REPORT_LIGHTS {
        let q = model::quality::measure(light).map_err(|e| e.to_string())?;
        println!("{name:<34} {:>9.2} {:>8.3}% {:>5}", q.psnr_db, 100.0 * q.within_tolerance, q.max_diff);
    }
    Ok(())
}
