//! Compresses the web page's files (`web/`) with gzip at build time, so the
//! board serves them precompressed (`rt_services::web::assets`) without a
//! compressor of its own. The output is deterministic (no file name, time
//! zero), so a build of the same sources gives the same firmware image.
//! Each file's entity tag is the CRC-32 of its bytes (crc32fast, which
//! flate2 builds on already).

use std::io::Write;
use std::path::Path;
use std::{env, fs};

/// The page's files; `web::assets` lists the same names.
const FILES: [&str; 3] = ["index.html", "page.js", "page.css"];

fn main() {
    let out = env::var_os("OUT_DIR").expect("cargo sets OUT_DIR for build scripts");
    for name in FILES {
        let source = Path::new("web").join(name);
        println!("cargo::rerun-if-changed={}", source.display());
        let bytes = fs::read(&source).unwrap_or_else(|e| panic!("cannot read {}: {e}", source.display()));
        let mut gz = flate2::GzBuilder::new().mtime(0).write(Vec::new(), flate2::Compression::best());
        gz.write_all(&bytes).expect("compressing into memory cannot fail");
        let compressed = gz.finish().expect("compressing into memory cannot fail");
        let target = Path::new(&out).join(format!("{name}.gz"));
        fs::write(&target, compressed).unwrap_or_else(|e| panic!("cannot write {}: {e}", target.display()));
        let etag = Path::new(&out).join(format!("{name}.etag"));
        let tag = format!("\"{:08x}\"", crc32fast::hash(&bytes));
        fs::write(&etag, tag).unwrap_or_else(|e| panic!("cannot write {}: {e}", etag.display()));
    }
}
