//! Build script: link the board binary with aarch32-rt's `link.x` and this
//! crate's `memory.x`. (The address, name and MAC are read at boot from the
//! card's raytracer.txt, not set at build time.)

use std::env;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    let dir = env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into());
    println!("cargo:rustc-link-search={dir}");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
}
