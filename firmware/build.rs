//! Build script: link the board binary with aarch32-rt's `link.x` and this
//! crate's `memory.x`, and name the build's features for its boot log
//! (`FIRMWARE_FEATURES`: a test that boots a build can tell which one
//! answered). (The address, name and MAC are read at boot from the card's
//! raytracer.txt, not set at build time.)

use std::env;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    let dir = env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into());
    println!("cargo:rustc-link-search={dir}");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    // Cargo sets CARGO_FEATURE_<NAME> for every enabled feature (those a
    // feature implies too), upper-cased with `-` as `_`.
    let mut features: Vec<String> = env::vars()
        .filter_map(|(k, _)| k.strip_prefix("CARGO_FEATURE_").map(|f| f.to_ascii_lowercase().replace('_', "-")))
        .filter(|f| f != "default")
        .collect();
    features.sort();
    println!("cargo:rustc-env=FIRMWARE_FEATURES={}", features.join(","));
}
