//! Build script: link the board binary with aarch32-rt's `link.x` and this
//! crate's `memory.x`; check the build-time network overrides so a typo
//! fails the build, not the board.

use std::env;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    for var in ["FW_IPV4", "FW_GATEWAY"] {
        println!("cargo:rerun-if-env-changed={var}");
    }

    let dir = env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into());
    println!("cargo:rustc-link-search={dir}");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");

    if let Ok(v) = env::var("FW_IPV4") {
        let ok = v
            .split_once('/')
            .is_some_and(|(a, l)| a.parse::<std::net::Ipv4Addr>().is_ok() && l.parse::<u8>().is_ok_and(|l| l <= 32));
        if !ok {
            panic!("FW_IPV4={v:?}: expected an IPv4 address with prefix length, e.g. 192.168.1.200/24");
        }
    }
    if let Ok(v) = env::var("FW_GATEWAY") {
        if v.parse::<std::net::Ipv4Addr>().is_err() {
            panic!("FW_GATEWAY={v:?}: expected an IPv4 address, e.g. 192.168.1.1");
        }
    }
}
