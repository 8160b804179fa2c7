//! Offline consistency check of the Quartus side (fpga/quartus), for
//! machines without Quartus: the files must agree with each other and with
//! hal-avalon's register map before a board owner runs the first build.
//!
//! * every port of the top level (de1_soc_top.sv) has an I/O standard in
//!   the .qsf, and a pin location unless it is dedicated HPS I/O (HPS_*:
//!   placed by the HPS; the DDR3 standards come from the HPS pin script,
//!   which build.sh must run);
//! * every interface soc_system.tcl exports is connected in the top level
//!   (its `<name>_...` ports on the soc_system instance), and nothing else
//!   is;
//! * the component's Avalon slave spans hal-avalon's window (word address
//!   width, CSRs and line buffer inside), its ports exist in rt_accel.sv
//!   with the same widths, and it is the fileset's top;
//! * the .sdc constrains CLOCK_50 at 20 ns.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::support::Result;

/// A port of a SystemVerilog module header: name and width in bits.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Port {
    /// The port's name.
    pub name: String,
    /// Width in bits.
    pub width: u32,
    /// Declared with a range (`[0:0]` too): its bits are `NAME[i]`.
    pub vector: bool,
}

/// The ports of the first module header in `sv` (ANSI style, one port per
/// line: `input logic [14:0] NAME,`).
pub fn module_ports(sv: &str) -> Vec<Port> {
    let mut ports = Vec::new();
    let mut in_header = false;
    for line in sv.lines() {
        let code = line.split("//").next().unwrap_or("").trim();
        if code.starts_with("module ") {
            in_header = true;
        }
        if !in_header {
            continue;
        }
        let mut words = code.split_whitespace().peekable();
        if let Some(dir) = words.peek() {
            if ["input", "output", "inout"].contains(dir) {
                let rest: Vec<&str> = words.skip(1).collect();
                let rest = rest.join(" ");
                let rest = rest.trim_end_matches([',', ')', ';']).trim();
                let width = rest
                    .find('[')
                    .and_then(|a| rest[a..].find(']').map(|b| &rest[a + 1..a + b]))
                    .and_then(|r| r.split_once(':'))
                    .and_then(|(h, l)| Some(h.trim().parse::<u32>().ok()?.abs_diff(l.trim().parse::<u32>().ok()?) + 1))
                    .unwrap_or(1);
                if let Some(name) = rest.split_whitespace().last() {
                    ports.push(Port {
                        name: name.trim_end_matches(',').to_string(),
                        width,
                        vector: rest.contains('['),
                    });
                }
            }
        }
        if code.starts_with(");") {
            break;
        }
    }
    ports
}

/// The bits of a port as the .qsf names them: `NAME` for a scalar, else
/// `NAME[i]`.
fn port_bits(p: &Port) -> Vec<String> {
    if !p.vector {
        vec![p.name.clone()]
    } else {
        (0..p.width).map(|i| format!("{}[{i}]", p.name)).collect()
    }
}

/// `-to` targets of .qsf assignments: (locations, I/O standards).
pub fn qsf_targets(qsf: &str) -> (BTreeSet<String>, BTreeSet<String>) {
    let (mut loc, mut io) = (BTreeSet::new(), BTreeSet::new());
    for line in qsf.lines().map(str::trim).filter(|l| !l.starts_with('#')) {
        let Some(to) = line.split(" -to ").nth(1).and_then(|t| t.split_whitespace().next()) else { continue };
        if line.starts_with("set_location_assignment") {
            loc.insert(to.to_string());
        } else if line.contains("-name IO_STANDARD") {
            io.insert(to.to_string());
        }
    }
    (loc, io)
}

/// The interfaces a qsys-script exports (`set_interface_property X
/// EXPORT_OF ...`).
pub fn exported_interfaces(tcl: &str) -> BTreeSet<String> {
    tcl.lines()
        .map(str::trim)
        .filter(|l| l.starts_with("set_interface_property") && l.contains("EXPORT_OF"))
        .filter_map(|l| l.split_whitespace().nth(1).map(String::from))
        .collect()
}

/// The named port connections (`.name (...)`) of the instance of `module`
/// in `sv`.
pub fn instance_connections(sv: &str, module: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut inside = false;
    for line in sv.lines() {
        let code = line.split("//").next().unwrap_or("").trim();
        if code.starts_with(module) && code.contains('(') {
            inside = true;
            continue;
        }
        if !inside {
            continue;
        }
        if code.starts_with(");") {
            break;
        }
        if let Some(rest) = code.strip_prefix('.') {
            let name: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            out.insert(name);
        }
    }
    out
}

/// The ports a component declares on `interface`: name to width.
pub fn hw_tcl_ports(tcl: &str, interface: &str) -> BTreeMap<String, u32> {
    let mut out = BTreeMap::new();
    // `add_interface_port IF NAME ROLE DIR WIDTH` lines, and the
    // `foreach {port role dir width} { ... }` table of the AXI master.
    for line in tcl.lines().map(str::trim) {
        let w: Vec<&str> = line.split_whitespace().collect();
        if w.len() == 6 && w[0] == "add_interface_port" && w[1] == interface {
            if let Ok(width) = w[5].parse() {
                out.insert(w[2].to_string(), width);
            }
        }
    }
    if let Some(start) = tcl.find("foreach {port role dir width} {") {
        let body = &tcl[start..];
        let body = &body[body.find('{').map_or(0, |i| i + 1)..];
        let body = &body[body.find('{').map_or(0, |i| i + 1)..];
        let body = &body[..body.find('}').unwrap_or(body.len())];
        let w: Vec<&str> = body.split_whitespace().collect();
        for q in w.chunks(4) {
            if let [port, _role, _dir, width] = q {
                if let Ok(width) = width.parse() {
                    out.insert(port.to_string(), width);
                }
            }
        }
    }
    out
}

/// Every inconsistency found, one line each.
pub fn problems(top: &str, qsf: &str, system_tcl: &str, hw_tcl: &str, accel_sv: &str, sdc: &str) -> Vec<String> {
    let mut p = Vec::new();
    // Pins and I/O standards.
    let (loc, io) = qsf_targets(qsf);
    let ports = module_ports(top);
    if ports.is_empty() {
        p.push("de1_soc_top.sv: no ports found".into());
    }
    for port in &ports {
        let hps = port.name.starts_with("HPS_");
        let ddr = port.name.starts_with("HPS_DDR3_");
        for bit in port_bits(port) {
            if !hps && !loc.contains(&bit) {
                p.push(format!("{bit}: no pin location in de1_soc.qsf"));
            }
            if !ddr && !io.contains(&bit) {
                p.push(format!("{bit}: no I/O standard in de1_soc.qsf"));
            }
        }
    }
    // Exported interfaces against the top level's connections.
    let exported = exported_interfaces(system_tcl);
    let connected = instance_connections(top, "soc_system");
    for iface in &exported {
        if !connected.iter().any(|c| c.starts_with(&format!("{iface}_"))) {
            p.push(format!("exported interface {iface} is not connected in de1_soc_top.sv"));
        }
    }
    for c in &connected {
        if !exported.iter().any(|i| c.starts_with(&format!("{i}_"))) {
            p.push(format!("de1_soc_top.sv connects {c}, which soc_system.tcl does not export"));
        }
    }
    // The component against the RTL and the register map.
    if !hw_tcl.contains("TOP_LEVEL rt_accel") {
        p.push("rt_accel_hw.tcl: the fileset's top level is not rt_accel".into());
    }
    let accel: BTreeMap<String, u32> = module_ports(accel_sv).into_iter().map(|q| (q.name, q.width)).collect();
    for iface in ["s0", "axm", "clock", "reset"] {
        let declared = hw_tcl_ports(hw_tcl, iface);
        if declared.is_empty() {
            p.push(format!("rt_accel_hw.tcl: interface {iface} declares no ports"));
        }
        for (name, width) in declared {
            match accel.get(&name) {
                None => p.push(format!("rt_accel_hw.tcl: {iface} port {name} is not a port of rt_accel.sv")),
                Some(w) if *w != width => {
                    p.push(format!("rt_accel_hw.tcl: {iface} port {name} is {width} bits, rt_accel.sv says {w}"))
                }
                Some(_) => {}
            }
        }
    }
    let span = hw_tcl_ports(hw_tcl, "s0").get("avs_address_i").map(|bits| 4usize << bits);
    let needed = hal_avalon::map::line_word_offset(hal_avalon::map::LINE_WORDS);
    match span {
        Some(span) if span >= needed && hw_tcl.contains("addressUnits WORDS") => {}
        Some(span) => {
            p.push(format!("slave s0 spans {span:#x} bytes; the register map needs {needed:#x} (word addressed)"))
        }
        None => p.push("rt_accel_hw.tcl: s0 has no avs_address_i".into()),
    }
    if !system_tcl.contains("add_connection rt_accel_0.axm hps_0.f2h_sdram0_data") {
        p.push("soc_system.tcl: the accelerator's AXI master is not connected to f2h_sdram0".into());
    }
    // The clock constraint.
    let clock = sdc
        .lines()
        .map(str::trim)
        .any(|l| l.starts_with("create_clock") && l.contains("get_ports CLOCK_50") && l.contains("-period 20"));
    if !clock {
        p.push("de1_soc.sdc: no create_clock for CLOCK_50 at 20 ns".into());
    }
    p
}

/// Check fpga/quartus; an error lists every problem.
pub fn run(root: &Path) -> Result<()> {
    let q = root.join("fpga/quartus");
    let read = |f: &str| std::fs::read_to_string(q.join(f)).map_err(|e| format!("fpga/quartus/{f}: {e}"));
    let found = problems(
        &read("de1_soc_top.sv")?,
        &read("de1_soc.qsf")?,
        &read("soc_system.tcl")?,
        &read("rt_accel_hw.tcl")?,
        &read("rt_accel.sv")?,
        &read("de1_soc.sdc")?,
    );
    if found.is_empty() {
        println!(
            "quartus check: pins, I/O standards, exported interfaces, component ports and span, clock: consistent"
        );
        Ok(())
    } else {
        Err(format!("fpga/quartus is inconsistent:\n  {}", found.join("\n  ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files() -> [String; 6] {
        let q = crate::support::tools::root().join("fpga/quartus");
        ["de1_soc_top.sv", "de1_soc.qsf", "soc_system.tcl", "rt_accel_hw.tcl", "rt_accel.sv", "de1_soc.sdc"]
            .map(|f| std::fs::read_to_string(q.join(f)).expect("fpga/quartus file"))
    }

    fn check(f: &[String; 6]) -> Vec<String> {
        problems(&f[0], &f[1], &f[2], &f[3], &f[4], &f[5])
    }

    #[test]
    fn the_shipped_files_are_consistent() {
        assert_eq!(check(&files()), Vec::<String>::new());
    }

    #[test]
    fn each_kind_of_inconsistency_is_found() {
        let f = files();
        let mut g = f.clone();
        g[1] = g[1].replace("set_location_assignment PIN_V16 -to LEDR[0]", "");
        assert_eq!(check(&g), ["LEDR[0]: no pin location in de1_soc.qsf"]);
        let mut g = f.clone();
        g[1] = g[1].replace("-to HPS_SD_CMD", "-to HPS_SD_CMDX");
        assert_eq!(check(&g), ["HPS_SD_CMD: no I/O standard in de1_soc.qsf"]);
        let mut g = f.clone();
        g[0] = g[0].replace(".hps_0_h2f_reset_reset_n         (h2f_rst_n),", "");
        assert_eq!(check(&g), ["exported interface hps_0_h2f_reset is not connected in de1_soc_top.sv"]);
        let mut g = f.clone();
        g[3] = g[3].replace("avs_address_i address Input 11", "avs_address_i address Input 9");
        assert!(check(&g).iter().any(|p| p.contains("spans 0x800 bytes")), "{:?}", check(&g));
        let mut g = f.clone();
        g[3] = g[3].replace("axm_wdata_o wdata Output 64", "axm_wdata_o wdata Output 32");
        assert!(check(&g).iter().any(|p| p.contains("wdata") || p.contains("axm_wdata_o")), "{:?}", check(&g));
        let mut g = f.clone();
        g[5] = g[5].replace("-period 20.000", "-period 10.000");
        assert_eq!(check(&g), ["de1_soc.sdc: no create_clock for CLOCK_50 at 20 ns"]);
    }

    #[test]
    fn ports_parse_with_their_widths() {
        let sv = "module m (\n  input logic clk,\n  output logic [14:0] a, // c\n  inout wire [3:0] d\n);\n";
        let names: Vec<_> = module_ports(sv).into_iter().map(|p| (p.name, p.width)).collect();
        assert_eq!(names, [("clk".to_string(), 1), ("a".to_string(), 15), ("d".to_string(), 4)]);
    }
}
