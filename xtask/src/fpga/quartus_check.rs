//! Offline consistency check of the Quartus side (fpga/quartus), for
//! machines without Quartus: the files must agree with each other, with
//! Terasic's pin list and with hal-avalon's register map before a board
//! owner runs the first build.
//!
//! * pins: every port of the top level (de1_soc_top.sv) has an I/O standard
//!   in the .qsf, and a pin location unless it is dedicated HPS I/O (HPS_*:
//!   placed by the HPS; the DDR3 standards come from the HPS pin script,
//!   which build.sh must run); every fabric pin is the one Terasic's
//!   DE1_SOC_golden_top.qsf gives the port (3.3-V LVTTL, [`GOLDEN_PINS`]);
//!   no pin is assigned twice, and no assignment names a port the top level
//!   does not have;
//! * exports: every interface soc_system.tcl exports is connected in the top
//!   level (its `<name>_...` ports on the soc_system instance), and nothing
//!   else is; every role of a conduit exported from the accelerator reaches
//!   the top as `<export>_<role>`, on a top-level port of the same width and
//!   direction;
//! * the component: every port of every interface in rt_accel_hw.tcl is a
//!   port of rt_accel.sv with the same width and direction, every port of
//!   rt_accel.sv belongs to an interface, every output of rt_accel.sv is
//!   driven (connected on rt_top or assigned), the Avalon slave spans
//!   hal-avalon's window (word address width, CSRs and line buffer inside),
//!   the AXI master goes to f2h_sdram0 with room for the VGA reader's and
//!   the DMA's bursts, and rt_accel is the fileset's top;
//! * timing: the .sdc constrains CLOCK_50 at 20 ns; every fabric input is a
//!   clock or has an input delay or a false path, every fabric output is a
//!   clock or has an output delay or a false path, and every delay names a
//!   clock the .sdc defines; the VGA pixel clock is a generated clock on
//!   rt_vga's phase register (CLOCK_50 / 2) and VGA_CLK one on the port
//!   from that register, so the analyzer traces the register;
//! * the VGA outputs but the constant SYNC_N leave from I/O registers
//!   (`FAST_OUTPUT_REGISTER ON`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::support::Result;

/// The fabric pins of the DE1-SoC, from Terasic's `DE1_SOC_golden_top.qsf`
/// (DE1-SoC System Builder, "Build by Terasic V1.0.0"; the public copies in
/// hbwangjinwu/DE1_SoC_MTL2_FB and Kota-35/Verilog-Calculator agree): port,
/// then the pins of bits 0, 1, ... (`PIN_` left off). All are 3.3-V LVTTL.
pub const GOLDEN_PINS: &[(&str, &str)] = &[
    ("CLOCK_50", "AF14"),
    ("VGA_CLK", "A11"),
    ("VGA_HS", "B11"),
    ("VGA_VS", "D11"),
    ("VGA_BLANK_N", "F10"),
    ("VGA_SYNC_N", "C10"),
    ("VGA_R", "A13 C13 E13 B12 C12 D12 E12 F13"),
    ("VGA_G", "J9 J10 H12 G10 G11 G12 F11 E11"),
    ("VGA_B", "B13 G13 H13 F14 H14 F15 G15 J14"),
    ("KEY", "AA14 AA15 W15 Y16"),
    ("SW", "AB12 AC12 AF9 AF10 AD11 AD12 AE11 AC9 AD10 AE12"),
    ("LEDR", "V16 W16 V17 V18 W17 W19 Y19 W20 W21 Y21"),
    ("HEX0", "AE26 AE27 AE28 AG27 AF28 AG28 AH28"),
    ("HEX1", "AJ29 AH29 AH30 AG30 AF29 AF30 AD27"),
    ("HEX2", "AB23 AE29 AD29 AC28 AD30 AC29 AC30"),
    ("HEX3", "AD26 AC27 AD25 AC25 AB28 AB25 AB22"),
    ("HEX4", "AA24 Y23 Y24 W22 W24 V23 W25"),
    ("HEX5", "V25 AA28 Y27 AB27 AB26 AA26 AA25"),
];

/// The I/O standard of every pin in [`GOLDEN_PINS`].
pub const GOLDEN_IO_STANDARD: &str = "3.3-V LVTTL";

/// Read bursts the VGA reader keeps in flight at most (rt_vga's
/// READS_IN_FLIGHT, counted from AR to RLAST): the AXI master's
/// readIssuingCapability must allow them.
pub const VGA_READS_OUTSTANDING: u32 = hal_avalon::map::VGA_READS_IN_FLIGHT;

/// The pin Terasic's golden top gives a port bit (`NAME` or `NAME[i]`), as
/// `PIN_xx`.
pub fn golden_pin(bit: &str) -> Option<String> {
    let (name, index) = match bit.split_once('[') {
        Some((n, i)) => (n, i.trim_end_matches(']').parse::<usize>().ok()?),
        None => (bit, 0),
    };
    let (_, pins) = GOLDEN_PINS.iter().find(|(n, _)| *n == name)?;
    pins.split_whitespace().nth(index).map(|p| format!("PIN_{p}"))
}

/// A port's direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dir {
    /// `input`
    Input,
    /// `output`
    Output,
    /// `inout`
    Inout,
}

impl Dir {
    fn parse(word: &str) -> Option<Dir> {
        match word.to_ascii_lowercase().as_str() {
            "input" => Some(Dir::Input),
            "output" => Some(Dir::Output),
            "inout" | "bidir" => Some(Dir::Inout),
            _ => None,
        }
    }
}

/// A port of a SystemVerilog module header: name and width in bits.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Port {
    /// The port's name.
    pub name: String,
    /// Width in bits.
    pub width: u32,
    /// Declared with a range (`[0:0]` too): its bits are `NAME[i]`.
    pub vector: bool,
    /// Direction.
    pub dir: Dir,
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
        if let Some(dir) = words.peek().and_then(|w| Dir::parse(w)) {
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
                    dir,
                });
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

/// The pin assignments of a .qsf.
#[derive(Debug, Default)]
pub struct Qsf {
    /// `set_location_assignment PIN -to TARGET`, in file order.
    pub locations: Vec<(String, String)>,
    /// `-name IO_STANDARD "STD" -to TARGET`: target to standard.
    pub io_standards: BTreeMap<String, String>,
    /// `-name FAST_OUTPUT_REGISTER ON -to TARGET` targets (patterns).
    pub fast_outputs: Vec<String>,
}

/// The pin assignments of `qsf`.
pub fn qsf_assignments(qsf: &str) -> Qsf {
    let mut q = Qsf::default();
    for line in qsf.lines().map(str::trim).filter(|l| !l.starts_with('#')) {
        let Some(to) = line.split(" -to ").nth(1).and_then(|t| t.split_whitespace().next()) else { continue };
        if line.starts_with("set_location_assignment") {
            let pin = line.split_whitespace().nth(1).unwrap_or("").to_string();
            q.locations.push((to.to_string(), pin));
        } else if line.contains("-name IO_STANDARD") {
            let std = line.split('"').nth(1).unwrap_or("").to_string();
            q.io_standards.insert(to.to_string(), std);
        } else if line.contains("-name FAST_OUTPUT_REGISTER ON") {
            q.fast_outputs.push(to.to_string());
        }
    }
    q
}

/// The interfaces a qsys-script exports (`set_interface_property X
/// EXPORT_OF ...`): export name to `instance.interface`.
pub fn exports(tcl: &str) -> BTreeMap<String, String> {
    tcl.lines()
        .map(str::trim)
        .filter(|l| l.starts_with("set_interface_property") && l.contains("EXPORT_OF"))
        .filter_map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            Some((w.get(1)?.to_string(), w.get(3)?.to_string()))
        })
        .collect()
}

/// The named port connections of the instance of `module` in `sv`: port
/// to the connected expression (`.name (expr)`, or `.name` for `.name
/// (name)`), any number per line.
pub fn instance_connections(sv: &str, module: &str) -> BTreeMap<String, String> {
    let mut body = String::new();
    let mut inside = false;
    for line in sv.lines() {
        let code = line.split("//").next().unwrap_or("").trim();
        if !inside && code.starts_with(module) && code.contains('(') {
            inside = true;
            // Parameters (`#(.LANES(LANES))`) are not ports.
            if let Some(i) = code.rfind(')').filter(|_| code.contains("#(")) {
                body.push_str(&code[i + 1..]);
            }
            body.push('\n');
            continue;
        }
        if !inside {
            continue;
        }
        if code.starts_with(");") {
            break;
        }
        body.push_str(code);
        body.push('\n');
    }
    let mut out = BTreeMap::new();
    let b = body.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i] != b'.' {
            i += 1;
            continue;
        }
        let start = i + 1;
        let mut j = start;
        while j < b.len() && (b[j].is_ascii_alphanumeric() || b[j] == b'_') {
            j += 1;
        }
        let name = body[start..j].to_string();
        let mut k = j;
        while k < b.len() && b[k].is_ascii_whitespace() {
            k += 1;
        }
        let expr = if k < b.len() && b[k] == b'(' {
            let mut depth = 0;
            let mut e = k;
            while e < b.len() {
                match b[e] {
                    b'(' => depth += 1,
                    b')' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    _ => {}
                }
                e += 1;
            }
            let expr = body[k + 1..e.min(b.len())].trim().to_string();
            k = e + 1;
            expr
        } else {
            name.clone()
        };
        if !name.is_empty() {
            out.insert(name, expr);
        }
        i = k.max(j).max(i + 1);
    }
    out
}

/// A port a component declares (`add_interface_port IF NAME ROLE DIR
/// WIDTH`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HwPort {
    /// The interface.
    pub interface: String,
    /// The HDL port.
    pub name: String,
    /// Its role in the interface.
    pub role: String,
    /// Direction.
    pub dir: Dir,
    /// Width in bits.
    pub width: u32,
}

/// Every port a component declares: `add_interface_port IF NAME ROLE DIR
/// WIDTH` lines, and `foreach {port role dir width} { ... } {
/// add_interface_port IF $port $role $dir $width }` tables.
pub fn hw_tcl_all_ports(tcl: &str) -> Vec<HwPort> {
    let mut out = Vec::new();
    for line in tcl.lines().map(str::trim) {
        let w: Vec<&str> = line.split_whitespace().collect();
        if w.len() == 6 && w[0] == "add_interface_port" && !w[2].starts_with('$') {
            if let (Some(dir), Ok(width)) = (Dir::parse(w[4]), w[5].parse()) {
                out.push(HwPort { interface: w[1].into(), name: w[2].into(), role: w[3].into(), dir, width });
            }
        }
    }
    let mut rest = tcl;
    while let Some(start) = rest.find("foreach {port role dir width} {") {
        let body = &rest[start..];
        let body = &body[body.find('{').map_or(0, |i| i + 1)..];
        let body = &body[body.find('{').map_or(0, |i| i + 1)..];
        let end = body.find('}').unwrap_or(body.len());
        let table = &body[..end];
        let after = &body[end..];
        let interface = after
            .lines()
            .map(str::trim)
            .find(|l| l.starts_with("add_interface_port"))
            .and_then(|l| l.split_whitespace().nth(1))
            .unwrap_or("")
            .to_string();
        let w: Vec<&str> = table.split_whitespace().collect();
        for q in w.chunks(4) {
            if let [port, role, dir, width] = q {
                if let (Some(dir), Ok(width)) = (Dir::parse(dir), width.parse()) {
                    out.push(HwPort {
                        interface: interface.clone(),
                        name: port.to_string(),
                        role: role.to_string(),
                        dir,
                        width,
                    });
                }
            }
        }
        rest = after;
    }
    out
}

/// The ports a component declares on `interface`: name to width.
pub fn hw_tcl_ports(tcl: &str, interface: &str) -> BTreeMap<String, u32> {
    hw_tcl_all_ports(tcl).into_iter().filter(|p| p.interface == interface).map(|p| (p.name, p.width)).collect()
}

/// `set_interface_property IF PROPERTY VALUE` as a number.
fn interface_property(tcl: &str, interface: &str, property: &str) -> Option<u32> {
    tcl.lines().map(str::trim).find_map(|l| {
        let w: Vec<&str> = l.split_whitespace().collect();
        (w.len() == 4 && w[0] == "set_interface_property" && w[1] == interface && w[2] == property)
            .then(|| w[3].parse().ok())
            .flatten()
    })
}

/// What an .sdc constrains, by port-name pattern.
#[derive(Debug, Default)]
pub struct Sdc {
    /// Clock names (`-name` of create_clock / create_generated_clock).
    pub clocks: BTreeSet<String>,
    /// Ports a clock is created on.
    pub clock_ports: Vec<String>,
    /// `set_input_delay` or `set_false_path -from` ports.
    pub inputs: Vec<String>,
    /// `set_output_delay` or `set_false_path -to` ports.
    pub outputs: Vec<String>,
    /// The `-clock` of every input or output delay.
    pub delay_clocks: Vec<String>,
}

/// A Tcl command line split into words, `[...]` and `{...}` kept whole.
fn tcl_words(line: &str) -> Vec<String> {
    let mut words = Vec::new();
    let mut cur = String::new();
    let mut depth = 0;
    for c in line.chars() {
        match c {
            '[' | '{' => {
                depth += 1;
                cur.push(c);
            }
            ']' | '}' => {
                depth -= 1;
                cur.push(c);
            }
            c if c.is_whitespace() && depth == 0 => {
                if !cur.is_empty() {
                    words.push(std::mem::take(&mut cur));
                }
            }
            c => cur.push(c),
        }
    }
    if !cur.is_empty() {
        words.push(cur);
    }
    words
}

/// The patterns of a `[get_ports ...]` word, or None for another word.
fn get_ports(word: &str) -> Option<Vec<String>> {
    let inner = word.strip_prefix("[get_ports")?.strip_suffix(']')?.trim();
    let inner = inner.trim_start_matches('{').trim_end_matches('}');
    Some(inner.split_whitespace().map(String::from).collect())
}

/// The word after `flag` in a Tcl command's words (`-name X`: X).
fn flag_value(words: &[String], flag: &str) -> Option<String> {
    words.iter().position(|x| x == flag).and_then(|i| words.get(i + 1)).cloned()
}

/// What `sdc` constrains.
pub fn sdc_constraints(sdc: &str) -> Sdc {
    let mut s = Sdc::default();
    for line in sdc.lines().map(str::trim).filter(|l| !l.starts_with('#')) {
        let w = tcl_words(line);
        let Some(cmd) = w.first() else { continue };
        let flag_value = |flag: &str| flag_value(&w, flag);
        for (i, word) in w.iter().enumerate() {
            let Some(ports) = get_ports(word) else { continue };
            let prev = if i > 0 { w[i - 1].as_str() } else { "" };
            match (cmd.as_str(), prev) {
                ("create_clock" | "create_generated_clock", p) if p != "-source" => s.clock_ports.extend(ports),
                ("set_false_path", "-from") | ("set_input_delay", _) => s.inputs.extend(ports),
                ("set_false_path", "-to") | ("set_output_delay", _) => s.outputs.extend(ports),
                _ => {}
            }
        }
        match cmd.as_str() {
            "create_clock" | "create_generated_clock" => s.clocks.extend(flag_value("-name")),
            "set_input_delay" | "set_output_delay" => s.delay_clocks.extend(flag_value("-clock")),
            _ => {}
        }
    }
    s
}

/// `*` matches any run of characters; everything else is literal (SDC
/// port patterns: `VGA_R[*]`, `HEX*`).
fn glob(pattern: &str, text: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == text,
        Some((head, tail)) => {
            let Some(rest) = text.strip_prefix(head) else { return false };
            (0..=rest.len()).filter(|&i| rest.is_char_boundary(i)).any(|i| glob(tail, &rest[i..]))
        }
    }
}

/// Whether every bit of `port` matches one of `patterns`.
fn covered(port: &Port, patterns: &[String]) -> bool {
    port_bits(port).iter().all(|bit| patterns.iter().any(|p| glob(p, bit) || glob(p, &port.name)))
}

/// Every inconsistency found, one line each.
pub fn problems(top: &str, qsf: &str, system_tcl: &str, hw_tcl: &str, accel_sv: &str, sdc: &str) -> Vec<String> {
    let mut p = Vec::new();
    let ports = module_ports(top);
    if ports.is_empty() {
        p.push("de1_soc_top.sv: no ports found".into());
    }
    let top_ports: BTreeMap<&str, &Port> = ports.iter().map(|q| (q.name.as_str(), q)).collect();
    let q = qsf_assignments(qsf);
    pin_problems(&ports, &q, &mut p);
    fast_output_problems(&ports, &q, &mut p);
    export_problems(top, &top_ports, system_tcl, hw_tcl, &mut p);
    component_problems(hw_tcl, accel_sv, system_tcl, &mut p);
    sdc_problems(&ports, sdc, &mut p);
    p
}

/// Pins and I/O standards against the top level and the golden top.
fn pin_problems(ports: &[Port], q: &Qsf, p: &mut Vec<String>) {
    let loc: BTreeMap<&str, &str> = q.locations.iter().map(|(t, pin)| (t.as_str(), pin.as_str())).collect();
    let mut bits = BTreeSet::new();
    for port in ports {
        let hps = port.name.starts_with("HPS_");
        let ddr = port.name.starts_with("HPS_DDR3_");
        for bit in port_bits(port) {
            if !hps && !loc.contains_key(bit.as_str()) {
                p.push(format!("{bit}: no pin location in de1_soc.qsf"));
            }
            if !ddr && !q.io_standards.contains_key(&bit) {
                p.push(format!("{bit}: no I/O standard in de1_soc.qsf"));
            }
            bits.insert(bit);
        }
    }
    let mut seen: BTreeMap<&str, &str> = BTreeMap::new();
    for (target, pin) in &q.locations {
        if let Some(other) = seen.insert(pin, target) {
            p.push(format!("{pin}: assigned to both {other} and {target} in de1_soc.qsf"));
        }
        match golden_pin(target) {
            Some(g) if g != *pin => p.push(format!("{target}: {pin} in de1_soc.qsf, Terasic's golden top has {g}")),
            Some(_) => {
                let std = q.io_standards.get(target).map_or("", String::as_str);
                if !std.is_empty() && std != GOLDEN_IO_STANDARD {
                    p.push(format!("{target}: I/O standard {std}, Terasic's golden top has {GOLDEN_IO_STANDARD}"));
                }
            }
            None => {
                p.push(format!("{target}: {pin} is not in the golden-top pin table (quartus_check.rs GOLDEN_PINS)"))
            }
        }
    }
    let assigned: BTreeSet<&String> = q.locations.iter().map(|(t, _)| t).chain(q.io_standards.keys()).collect();
    for target in assigned {
        if !bits.contains(target) {
            p.push(format!("{target}: assigned in de1_soc.qsf but not a port of de1_soc_top.sv"));
        }
    }
}

/// The VGA outputs latched by the DAC or read by the monitor, from I/O
/// registers: all but SYNC_N, which rt_vga ties to 0.
fn fast_output_problems(ports: &[Port], q: &Qsf, p: &mut Vec<String>) {
    for port in ports.iter().filter(|x| x.name.starts_with("VGA_") && x.name != "VGA_SYNC_N") {
        if !covered(port, &q.fast_outputs) {
            p.push(format!("{}: no FAST_OUTPUT_REGISTER in de1_soc.qsf", port.name));
        }
    }
}

/// Exported interfaces against the top level's connections.
fn export_problems(top: &str, top_ports: &BTreeMap<&str, &Port>, system_tcl: &str, hw_tcl: &str, p: &mut Vec<String>) {
    let exported = exports(system_tcl);
    let connected = instance_connections(top, "soc_system");
    for iface in exported.keys() {
        if !connected.keys().any(|c| c.starts_with(&format!("{iface}_"))) {
            p.push(format!("exported interface {iface} is not connected in de1_soc_top.sv"));
        }
    }
    for c in connected.keys() {
        if !exported.keys().any(|i| c.starts_with(&format!("{i}_"))) {
            p.push(format!("de1_soc_top.sv connects {c}, which soc_system.tcl does not export"));
        }
    }
    // Every top-level port goes somewhere: the system or an assign.
    for name in top_ports.keys() {
        let used = |e: &str| e == *name || e.strip_prefix(name).is_some_and(|r| r.starts_with('['));
        let assigned = top
            .lines()
            .any(|l| l.trim().strip_prefix("assign ").is_some_and(|r| used(r.split('=').next().unwrap_or("").trim())));
        if !connected.values().any(|e| used(e)) && !assigned {
            p.push(format!("{name}: top-level port connected to nothing in de1_soc_top.sv"));
        }
    }
    // The accelerator's conduits, role by role.
    let hw = hw_tcl_all_ports(hw_tcl);
    for (export, of) in &exported {
        let Some(iface) = of.strip_prefix("rt_accel_0.") else { continue };
        let roles: Vec<&HwPort> = hw.iter().filter(|h| h.interface == iface).collect();
        if roles.is_empty() {
            p.push(format!("soc_system.tcl exports rt_accel_0.{iface}, which rt_accel_hw.tcl does not declare"));
            continue;
        }
        for h in &roles {
            let pin = format!("{export}_{}", h.role);
            let Some(expr) = connected.get(&pin) else {
                p.push(format!(
                    "exported conduit {export}: role {} ({pin}) is not connected in de1_soc_top.sv",
                    h.role
                ));
                continue;
            };
            match top_ports.get(expr.as_str()) {
                None => p.push(format!("de1_soc_top.sv connects {pin} to {expr}, which is not a top-level port")),
                Some(t) if t.width != h.width || t.dir != h.dir => p.push(format!(
                    "de1_soc_top.sv connects {pin} ({:?} {}) to {expr} ({:?} {})",
                    h.dir, h.width, t.dir, t.width
                )),
                Some(_) => {}
            }
        }
        for c in connected.keys().filter(|c| c.starts_with(&format!("{export}_"))) {
            if !roles.iter().any(|h| *c == format!("{export}_{}", h.role)) {
                p.push(format!("de1_soc_top.sv connects {c}, which rt_accel_0.{iface} has no role for"));
            }
        }
    }
}

/// The component against the RTL, the system and the register map.
fn component_problems(hw_tcl: &str, accel_sv: &str, system_tcl: &str, p: &mut Vec<String>) {
    if !hw_tcl.contains("TOP_LEVEL rt_accel") {
        p.push("rt_accel_hw.tcl: the fileset's top level is not rt_accel".into());
    }
    let accel_ports = module_ports(accel_sv);
    let accel: BTreeMap<&str, &Port> = accel_ports.iter().map(|q| (q.name.as_str(), q)).collect();
    let hw = hw_tcl_all_ports(hw_tcl);
    for iface in ["s0", "axm", "clock", "reset", "vga", "board"] {
        if !hw.iter().any(|h| h.interface == iface) {
            p.push(format!("rt_accel_hw.tcl: interface {iface} declares no ports"));
        }
    }
    for h in &hw {
        let iface = &h.interface;
        let name = &h.name;
        match accel.get(name.as_str()) {
            None => p.push(format!("rt_accel_hw.tcl: {iface} port {name} is not a port of rt_accel.sv")),
            Some(a) if a.width != h.width => p.push(format!(
                "rt_accel_hw.tcl: {iface} port {name} is {} bits, rt_accel.sv says {}",
                h.width, a.width
            )),
            Some(a) if a.dir != h.dir => {
                p.push(format!("rt_accel_hw.tcl: {iface} port {name} is {:?}, rt_accel.sv says {:?}", h.dir, a.dir))
            }
            Some(_) => {}
        }
    }
    for a in &accel_ports {
        if !hw.iter().any(|h| h.name == a.name) {
            p.push(format!("rt_accel.sv port {} is in no interface of rt_accel_hw.tcl", a.name));
        }
    }
    // Every output is driven: connected on rt_top or assigned here.
    let inner = instance_connections(accel_sv, "rt_top");
    for a in accel_ports.iter().filter(|a| a.dir == Dir::Output) {
        let assigned = accel_sv.lines().any(|l| {
            let l = l.trim();
            l.strip_prefix("assign ").is_some_and(|r| {
                r.trim_start().strip_prefix(a.name.as_str()).is_some_and(|t| t.trim_start().starts_with('='))
            })
        });
        if !inner.contains_key(&a.name) && !assigned {
            p.push(format!(
                "rt_accel.sv: output {} is driven by nothing (not connected on rt_top, not assigned)",
                a.name
            ));
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
    let reads = interface_property(hw_tcl, "axm", "readIssuingCapability").unwrap_or(0);
    let writes = interface_property(hw_tcl, "axm", "writeIssuingCapability").unwrap_or(0);
    let combined = interface_property(hw_tcl, "axm", "combinedIssuingCapability").unwrap_or(0);
    if reads < VGA_READS_OUTSTANDING {
        p.push(format!(
            "rt_accel_hw.tcl: axm readIssuingCapability {reads}, the VGA reader keeps {VGA_READS_OUTSTANDING} bursts in flight"
        ));
    }
    if combined < reads + writes {
        p.push(format!("rt_accel_hw.tcl: axm combinedIssuingCapability {combined} < read {reads} + write {writes}"));
    }
}

/// The .sdc against the top level's ports.
fn sdc_problems(ports: &[Port], sdc: &str, p: &mut Vec<String>) {
    let clock = sdc
        .lines()
        .map(str::trim)
        .any(|l| l.starts_with("create_clock") && l.contains("get_ports CLOCK_50") && l.contains("-period 20"));
    if !clock {
        p.push("de1_soc.sdc: no create_clock for CLOCK_50 at 20 ns".into());
    }
    // The pixel clock on rt_vga's phase register, VGA_CLK from it.
    let generated: Vec<Vec<String>> =
        sdc.lines().map(str::trim).filter(|l| l.starts_with("create_generated_clock")).map(tcl_words).collect();
    let phase_reg = |word: &str| word.starts_with("[get_registers") && word.contains("u_vga|phase_q");
    let pixel = generated.iter().find(|w| w.last().is_some_and(|t| phase_reg(t)));
    match pixel {
        Some(w)
            if flag_value(w, "-divide_by").as_deref() == Some("2")
                && flag_value(w, "-source").as_deref() == Some("[get_ports CLOCK_50]") => {}
        _ => p.push("de1_soc.sdc: no generated clock CLOCK_50 / 2 on rt_vga's phase register (u_vga|phase_q)".into()),
    }
    let vga_clk = generated.iter().find(|w| w.last().map(String::as_str) == Some("[get_ports VGA_CLK]"));
    if !vga_clk.is_some_and(|w| flag_value(w, "-source").is_some_and(|s| phase_reg(&s))) {
        p.push("de1_soc.sdc: VGA_CLK is not a generated clock from rt_vga's phase register".into());
    }
    let s = sdc_constraints(sdc);
    for c in &s.delay_clocks {
        if !s.clocks.contains(c) {
            p.push(format!("de1_soc.sdc: a delay names clock {c}, which the .sdc does not create"));
        }
    }
    // HPS I/O is constrained by the HPS's own .sdc files (from the .qip).
    for port in ports.iter().filter(|q| !q.name.starts_with("HPS_")) {
        let (list, what) = match port.dir {
            Dir::Input => (&s.inputs, "input with no clock, input delay or false path"),
            Dir::Output => (&s.outputs, "output with no clock, output delay or false path"),
            Dir::Inout => continue,
        };
        if !covered(port, &s.clock_ports) && !covered(port, list) {
            p.push(format!("{}: {what} in de1_soc.sdc", port.name));
        }
    }
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
            "quartus check: pins (golden top), I/O standards, exported interfaces and conduits, component ports and span, clocks and I/O constraints: consistent"
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

    /// The problems after replacing `from` with `to` in file `i` (the
    /// replacement must change the file).
    fn broken(i: usize, from: &str, to: &str) -> Vec<String> {
        let mut g = files();
        assert!(g[i].contains(from), "{from:?} is not in file {i}");
        g[i] = g[i].replace(from, to);
        check(&g)
    }

    #[test]
    fn the_shipped_files_are_consistent() {
        assert_eq!(check(&files()), Vec::<String>::new());
    }

    #[test]
    fn each_kind_of_inconsistency_is_found() {
        assert_eq!(
            broken(1, "set_location_assignment PIN_V16 -to LEDR[0]", ""),
            ["LEDR[0]: no pin location in de1_soc.qsf"]
        );
        assert_eq!(
            broken(1, "-to HPS_SD_CMD\n", "-to HPS_SD_CMDX\n"),
            [
                "HPS_SD_CMD: no I/O standard in de1_soc.qsf",
                "HPS_SD_CMDX: assigned in de1_soc.qsf but not a port of de1_soc_top.sv"
            ]
        );
        assert_eq!(
            broken(0, ".clk_clk                         (CLOCK_50),", ""),
            [
                "exported interface clk is not connected in de1_soc_top.sv",
                "CLOCK_50: top-level port connected to nothing in de1_soc_top.sv"
            ]
        );
        let p = broken(3, "avs_address_i address Input 11", "avs_address_i address Input 9");
        assert!(p.iter().any(|p| p.contains("spans 0x800 bytes")), "{p:?}");
        let p = broken(3, "axm_wdata_o wdata Output 64", "axm_wdata_o wdata Output 32");
        assert!(p.iter().any(|p| p.contains("axm_wdata_o is 32 bits")), "{p:?}");
        assert_eq!(
            broken(5, "-period 20.000", "-period 10.000"),
            ["de1_soc.sdc: no create_clock for CLOCK_50 at 20 ns"]
        );
    }

    #[test]
    fn the_vga_clock_must_be_traced_through_its_register() {
        // The clock as it was: generated on the port straight from CLOCK_50.
        let sdc = files()[5].clone();
        let start = sdc.find("create_generated_clock -name vga_pixel").expect("pixel clock");
        let end = sdc[start..].find("\n\n").map_or(sdc.len(), |e| start + e);
        let mut g = files();
        g[5] = format!(
            "{}create_generated_clock -name VGA_CLK -source [get_ports CLOCK_50] -divide_by 2 [get_ports VGA_CLK]{}",
            &sdc[..start],
            &sdc[end..]
        );
        assert_eq!(
            check(&g),
            [
                "de1_soc.sdc: no generated clock CLOCK_50 / 2 on rt_vga's phase register (u_vga|phase_q)",
                "de1_soc.sdc: VGA_CLK is not a generated clock from rt_vga's phase register"
            ]
        );
        assert_eq!(
            broken(5, "-divide_by 2 [get_registers", "-divide_by 4 [get_registers"),
            ["de1_soc.sdc: no generated clock CLOCK_50 / 2 on rt_vga's phase register (u_vga|phase_q)"]
        );
    }

    #[test]
    fn the_vga_outputs_must_use_io_registers() {
        assert_eq!(
            broken(1, "set_instance_assignment -name FAST_OUTPUT_REGISTER ON -to VGA_G[*]\n", ""),
            ["VGA_G: no FAST_OUTPUT_REGISTER in de1_soc.qsf"]
        );
        assert_eq!(
            broken(1, "FAST_OUTPUT_REGISTER ON -to VGA_CLK", "FAST_OUTPUT_REGISTER OFF -to VGA_CLK"),
            ["VGA_CLK: no FAST_OUTPUT_REGISTER in de1_soc.qsf"]
        );
    }

    #[test]
    fn pins_must_be_the_golden_tops() {
        // A typo in a location.
        assert_eq!(
            broken(1, "PIN_A13 -to VGA_R[0]", "PIN_A12 -to VGA_R[0]"),
            ["VGA_R[0]: PIN_A12 in de1_soc.qsf, Terasic's golden top has PIN_A13"]
        );
        // One pin given to two bits.
        let p = broken(1, "PIN_W15 -to KEY[2]", "PIN_Y16 -to KEY[2]");
        assert_eq!(
            p,
            [
                "KEY[2]: PIN_Y16 in de1_soc.qsf, Terasic's golden top has PIN_W15",
                "PIN_Y16: assigned to both KEY[2] and KEY[3] in de1_soc.qsf"
            ]
        );
        // Another I/O standard.
        assert_eq!(
            broken(1, "\"3.3-V LVTTL\" -to HEX5[6]", "\"2.5 V\" -to HEX5[6]"),
            ["HEX5[6]: I/O standard 2.5 V, Terasic's golden top has 3.3-V LVTTL"]
        );
        // A missing standard on a new pin.
        assert_eq!(
            broken(1, "set_instance_assignment -name IO_STANDARD \"3.3-V LVTTL\" -to VGA_B[7]\n", ""),
            ["VGA_B[7]: no I/O standard in de1_soc.qsf"]
        );
        // A stale assignment (the port renamed in the top level).
        let p = broken(0, "output logic        VGA_BLANK_N,", "output logic        VGA_BLANK,");
        assert!(
            p.contains(&"VGA_BLANK_N: assigned in de1_soc.qsf but not a port of de1_soc_top.sv".to_string()),
            "{p:?}"
        );
        assert!(p.contains(&"VGA_BLANK: no pin location in de1_soc.qsf".to_string()), "{p:?}");
        // A pin the table does not know.
        let p = broken(1, "# VGA\n", "set_location_assignment PIN_AA30 -to IRDA_RXD\n# VGA\n");
        assert!(
            p.contains(
                &"IRDA_RXD: PIN_AA30 is not in the golden-top pin table (quartus_check.rs GOLDEN_PINS)".to_string()
            ),
            "{p:?}"
        );
        assert_eq!(golden_pin("HEX3[4]").as_deref(), Some("PIN_AB28"));
        assert_eq!(golden_pin("VGA_CLK").as_deref(), Some("PIN_A11"));
        assert_eq!(golden_pin("SW[10]"), None);
    }

    #[test]
    fn every_conduit_role_reaches_the_top() {
        assert_eq!(
            broken(0, ".vga_sync_n                      (VGA_SYNC_N),", ""),
            [
                "VGA_SYNC_N: top-level port connected to nothing in de1_soc_top.sv",
                "exported conduit vga: role sync_n (vga_sync_n) is not connected in de1_soc_top.sv"
            ]
        );
        assert_eq!(
            broken(0, ".board_hex3_n                    (HEX3),", ".board_hex3_n                    (HEX2),"),
            ["HEX3: top-level port connected to nothing in de1_soc_top.sv"]
        );
        assert_eq!(
            broken(0, ".board_sw                        (SW),", ".board_sw                        (SWX),"),
            [
                "SW: top-level port connected to nothing in de1_soc_top.sv",
                "de1_soc_top.sv connects board_sw to SWX, which is not a top-level port"
            ]
        );
        assert_eq!(
            broken(0, ".board_key_n                     (KEY),", ".board_key_n                     (LEDR),"),
            [
                "KEY: top-level port connected to nothing in de1_soc_top.sv",
                "de1_soc_top.sv connects board_key_n (Input 4) to LEDR (Output 10)"
            ]
        );
        assert_eq!(
            broken(
                0,
                ".vga_b                           (VGA_B),",
                ".vga_b                           (VGA_B),\n    .vga_de (VGA_B),"
            ),
            ["de1_soc_top.sv connects vga_de, which rt_accel_0.vga has no role for"]
        );
        let p = broken(2, "set_interface_property board EXPORT_OF rt_accel_0.board\n", "");
        assert!(
            p.contains(&"de1_soc_top.sv connects board_key_n, which soc_system.tcl does not export".to_string()),
            "{p:?}"
        );
        assert_eq!(
            broken(2, "EXPORT_OF rt_accel_0.vga", "EXPORT_OF rt_accel_0.video"),
            ["soc_system.tcl exports rt_accel_0.video, which rt_accel_hw.tcl does not declare"]
        );
    }

    #[test]
    fn the_component_matches_its_hdl() {
        // A port of rt_accel.sv in no interface.
        assert_eq!(
            broken(3, "add_interface_port board sw_i sw Input 10\n", ""),
            [
                "de1_soc_top.sv connects board_sw, which rt_accel_0.board has no role for",
                "rt_accel.sv port sw_i is in no interface of rt_accel_hw.tcl"
            ]
        );
        // A direction that differs.
        assert_eq!(
            broken(3, "ledr_o ledr Output 10", "ledr_o ledr Input 10"),
            [
                "de1_soc_top.sv connects board_ledr (Input 10) to LEDR (Output 10)",
                "rt_accel_hw.tcl: board port ledr_o is Input, rt_accel.sv says Output"
            ]
        );
        // A width that differs.
        let p = broken(3, "vga_g_o g Output 8", "vga_g_o g Output 6");
        assert!(p.contains(&"rt_accel_hw.tcl: vga port vga_g_o is 6 bits, rt_accel.sv says 8".to_string()), "{p:?}");
        // A role whose port rt_accel.sv does not have.
        let p =
            broken(3, "add_interface_port vga vga_vs_o vs Output 1", "add_interface_port vga vga_vsync_o vs Output 1");
        assert!(p.contains(&"rt_accel_hw.tcl: vga port vga_vsync_o is not a port of rt_accel.sv".to_string()), "{p:?}");
        // An output left undriven (the read channel tied off, then dropped).
        assert_eq!(
            broken(4, ".axm_arvalid_o, .axm_arready_i,", ".axm_arready_i,"),
            ["rt_accel.sv: output axm_arvalid_o is driven by nothing (not connected on rt_top, not assigned)"]
        );
        assert_eq!(
            broken(4, ".vga_clk_o, .vga_hs_o,", ".vga_clk_o,"),
            ["rt_accel.sv: output vga_hs_o is driven by nothing (not connected on rt_top, not assigned)"]
        );
        // Too few reads in flight for the VGA reader, or a combined limit
        // below the sum.
        assert_eq!(
            broken(3, "readIssuingCapability 4", "readIssuingCapability 1"),
            ["rt_accel_hw.tcl: axm readIssuingCapability 1, the VGA reader keeps 4 bursts in flight"]
        );
        assert_eq!(
            broken(3, "combinedIssuingCapability 20", "combinedIssuingCapability 16"),
            ["rt_accel_hw.tcl: axm combinedIssuingCapability 16 < read 4 + write 16"]
        );
        // A conduit missing altogether.
        let p = broken(3, "add_interface_port board ", "add_interface_port board_io ");
        assert!(p.contains(&"rt_accel_hw.tcl: interface board declares no ports".to_string()), "{p:?}");
        assert!(
            p.contains(&"soc_system.tcl exports rt_accel_0.board, which rt_accel_hw.tcl does not declare".to_string()),
            "{p:?}"
        );
    }

    #[test]
    fn every_fabric_pin_is_constrained() {
        assert_eq!(
            broken(5, "set_false_path -from [get_ports {KEY[*] SW[*]}]", "set_false_path -from [get_ports {SW[*]}]"),
            ["KEY: input with no clock, input delay or false path in de1_soc.sdc"]
        );
        assert_eq!(
            broken(5, " HEX4[*] HEX5[*]}]", " HEX4[*]}]"),
            ["HEX5: output with no clock, output delay or false path in de1_soc.sdc"]
        );
        assert_eq!(
            broken(5, "set_false_path -to [get_ports {VGA_HS VGA_VS}]", "set_false_path -to [get_ports {VGA_HS}]"),
            ["VGA_VS: output with no clock, output delay or false path in de1_soc.sdc"]
        );
        let p = broken(5, "set_output_delay -clock VGA_CLK -max 0.215 [get_ports {VGA_SYNC_N}]\n", "");
        assert!(p.is_empty(), "the -min line still covers VGA_SYNC_N: {p:?}");
        // The generated clock on VGA_CLK: without it, VGA_CLK is an
        // unconstrained output and every DAC delay names a missing clock.
        let p = broken(
            5,
            "create_generated_clock -name VGA_CLK -source [get_registers {*u_vga|phase_q}] [get_ports VGA_CLK]",
            "",
        );
        assert!(
            p.contains(&"VGA_CLK: output with no clock, output delay or false path in de1_soc.sdc".to_string()),
            "{p:?}"
        );
        assert!(
            p.contains(&"de1_soc.sdc: a delay names clock VGA_CLK, which the .sdc does not create".to_string()),
            "{p:?}"
        );
        // The -source port is not a clock target.
        let s = sdc_constraints("create_generated_clock -name g -source [get_ports A] -divide_by 2 [get_ports B]");
        assert_eq!(s.clock_ports, ["B"]);
        assert!(glob("VGA_R[*]", "VGA_R[7]") && glob("HEX*", "HEX0[1]") && !glob("VGA_R[*]", "VGA_G[0]"));
    }

    #[test]
    fn ports_parse_with_their_widths() {
        let sv = "module m (\n  input logic clk,\n  output logic [14:0] a, // c\n  inout wire [3:0] d\n);\n";
        let names: Vec<_> = module_ports(sv).into_iter().map(|p| (p.name, p.width, p.dir)).collect();
        assert_eq!(
            names,
            [("clk".to_string(), 1, Dir::Input), ("a".to_string(), 15, Dir::Output), ("d".to_string(), 4, Dir::Inout)]
        );
    }

    #[test]
    fn connections_parse_several_per_line() {
        let sv = "rt_top #(.LANES(LANES)) u (\n  .clk_i, .a_o (x[3:0]), .b_i(f(y)),\n  .c_o\n);\n";
        let c = instance_connections(sv, "rt_top");
        let c: Vec<_> = c.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        assert_eq!(c, [("a_o", "x[3:0]"), ("b_i", "f(y)"), ("c_o", "c_o"), ("clk_i", "clk_i")]);
    }
}
