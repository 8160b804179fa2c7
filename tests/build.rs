//! `cfg(rtl_verilated)` when rtl-port was built with the Verilated RTL
//! (its build script says so through `links` metadata), so the RTL tests
//! exist exactly when the RTL does; `cargo xtask test` sets
//! `RT_REQUIRE_RTL=1`, which makes a build without it fail instead.

fn main() {
    println!("cargo::rustc-check-cfg=cfg(rtl_verilated)");
    println!("cargo::rerun-if-env-changed=DEP_RTL_PORT_VERILATED");
    if std::env::var("DEP_RTL_PORT_VERILATED").is_ok_and(|v| v == "1") {
        println!("cargo::rustc-cfg=rtl_verilated");
    }
}
