//! Builds the Verilated `rt_top` (fpga/rtl) and the C ABI over it
//! (csrc/rtl_port.cpp) into static libraries, when Verilator is installed.
//!
//! Without Verilator the crate still builds (plain `cargo test` needs
//! nothing but Rust) and `RtlAccelerator::new` says why there is no RTL;
//! with `RT_REQUIRE_RTL=1` (set by `cargo xtask test`, which installs
//! Verilator first) a missing Verilator is a build error instead, so the
//! suite can never silently run without the RTL.
//!
//! Verilator 5's `--cc --build` makes the model library; the runtime's
//! objects (`verilated.o`, `verilated_threads.o`) are targets of the same
//! generated makefile and go into an archive here. The `cc` crate compiles
//! the C ABI against both.

use std::env;
use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let rtl = manifest.join("../fpga/rtl");
    println!("cargo::rustc-check-cfg=cfg(rtl_verilated)");
    println!("cargo::rerun-if-env-changed=RT_REQUIRE_RTL");
    println!("cargo::rerun-if-env-changed=PATH");
    println!("cargo::rerun-if-changed=csrc");
    println!("cargo::rerun-if-changed={}", rtl.display());
    // The Verilated RTL is a host simulation: a cross build (hps-sim's code
    // in hps-linux for the board's ARM Linux) builds without it, required
    // or not.
    if env::var("TARGET").ok() != env::var("HOST").ok() {
        return;
    }
    let required = env::var("RT_REQUIRE_RTL").is_ok_and(|v| v == "1");
    // Rerun once Verilator appears (or is upgraded): a path that does not
    // exist makes Cargo rerun the script on every build, which costs only
    // this check until it is installed.
    println!("cargo::rerun-if-changed={}", which("verilator").unwrap_or_else(|| "/usr/bin/verilator".into()).display());

    let root = match verilator_root() {
        Some(r) => r,
        None if required => panic!(
            "RT_REQUIRE_RTL=1 but `verilator` is not installed (apt-get install verilator; cargo xtask test does it)"
        ),
        None => {
            println!(
                "cargo::warning=verilator not found: rtl-port builds without the RTL (hps-sim --accelerator rtl will say so)"
            );
            return;
        }
    };

    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let mdir = out.join("verilated");
    let files = rtl_files(&rtl);
    let mut v = Command::new("verilator");
    v.current_dir(&rtl)
        .args(["--cc", "--build", "-j", "2", "--top-module", "rt_top", "-Mdir"])
        .arg(&mdir)
        .args(["-CFLAGS", "-O1", "-MAKEFLAGS", "OPT_FAST=-O1 OPT_SLOW=-O1 OPT_GLOBAL=-O1"])
        .args(&files);
    run(v, "verilator --cc --build rt_top");
    // The runtime's objects, with the flags of the generated makefile, into
    // an archive of their own.
    let runtime = ["verilated.o", "verilated_threads.o"];
    let mut m = Command::new("make");
    m.current_dir(&mdir).args(["-f", "Vrt_top.mk", "OPT_FAST=-O1", "OPT_SLOW=-O1", "OPT_GLOBAL=-O1"]).args(runtime);
    run(m, "make the Verilator runtime");
    let _ = std::fs::remove_file(out.join("libverilated.a"));
    let mut ar = Command::new("ar");
    ar.current_dir(&mdir).arg("rcs").arg(out.join("libverilated.a")).args(runtime);
    run(ar, "ar libverilated.a");
    // Cargo links `lib<name>.a`.
    copy(&mdir.join("Vrt_top__ALL.a"), &out.join("libvrt_top.a"));

    cc::Build::new()
        .cpp(true)
        .std("c++17")
        .opt_level(1)
        .include(&mdir)
        .include(root.join("include"))
        .include(root.join("include/vltstd"))
        .warnings(false)
        .file(manifest.join("csrc/rtl_port.cpp"))
        .compile("rtl_port");
    println!("cargo::rustc-link-search=native={}", out.display());
    println!("cargo::rustc-link-lib=static=vrt_top");
    println!("cargo::rustc-link-lib=static=verilated");
    println!("cargo::rustc-link-lib=dylib=stdc++");
    println!("cargo::rustc-link-lib=dylib=pthread");
    println!("cargo::rustc-cfg=rtl_verilated");
    // For dependents' build scripts (DEP_RTL_PORT_VERILATED).
    println!("cargo::metadata=verilated=1");
}

/// `name` on PATH.
fn which(name: &str) -> Option<PathBuf> {
    env::split_paths(&env::var_os("PATH")?).map(|d| d.join(name)).find(|p| p.is_file())
}

/// `verilator --getenv VERILATOR_ROOT`, if Verilator runs.
fn verilator_root() -> Option<PathBuf> {
    let out = Command::new("verilator").args(["--getenv", "VERILATOR_ROOT"]).output().ok()?;
    let root = String::from_utf8(out.stdout).ok()?;
    (out.status.success() && !root.trim().is_empty()).then(|| PathBuf::from(root.trim()))
}

/// The design's files in compile order (`files.f`, `#` comments).
fn rtl_files(rtl: &Path) -> Vec<String> {
    let list = std::fs::read_to_string(rtl.join("files.f")).unwrap_or_else(|e| panic!("fpga/rtl/files.f: {e}"));
    list.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#')).map(String::from).collect()
}

fn run(mut c: Command, what: &str) {
    let st = c.status().unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    assert!(st.success(), "{what} failed ({st})");
}

fn copy(from: &Path, to: &Path) {
    std::fs::copy(from, to).unwrap_or_else(|e| panic!("copy {} -> {}: {e}", from.display(), to.display()));
}
