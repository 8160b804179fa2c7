//! Logic depth between registers, from Yosys's `synth_intel_alm` netlist
//! (JSON): timing evidence without Quartus.
//!
//! Every register-to-register path is walked through the mapped cells:
//! LUTs (`MISTRAL_ALUT2..6`, `MISTRAL_NOT`), adder cells
//! (`MISTRAL_ALUT_ARITH`: its LUT inputs count as a level, carry-in to
//! carry-out as one bit of a carry chain) and multipliers
//! (`MISTRAL_MUL*`: a DSP block with no register inside the path). Flip-flops,
//! block RAM and the module's ports start and end paths.
//!
//! Each path gets a delay estimate from [`DELAY`], a deliberately rough
//! model (Intel publishes no per-LUT or per-carry-bit delay for Cyclone V;
//! the figures are typical of the family, routing included), and the report
//! names the deepest path of each part of the design. The check: every path
//! within [`TARGET_NS`], the 50 MHz period the accelerator runs at less a
//! 10% margin for the model's error. Paths over [`FAST_NS`] (100 MHz, what
//! a -C6 closes for shallow logic) are named as the ones to pipeline first
//! should the clock ever go up.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use serde_json::Value;

use crate::support::Result;

/// Delay model, ns (estimates; see the module doc).
pub struct Delays {
    /// A LUT level with its local routing.
    pub lut: f64,
    /// One bit of a carry chain.
    pub carry_bit: f64,
    /// A DSP multiplier used without its registers.
    pub dsp: f64,
    /// Clock-to-out plus setup of the registers at both ends.
    pub registers: f64,
}

/// The estimates used.
pub const DELAY: Delays = Delays { lut: 0.8, carry_bit: 0.05, dsp: 4.0, registers: 0.6 };

/// The bound per register-to-register path: 20 ns (50 MHz) less 10%.
pub const TARGET_NS: f64 = 18.0;

/// 100 MHz: paths above it are listed.
pub const FAST_NS: f64 = 10.0;

/// The deepest path into one net.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Depth {
    /// Estimated delay, ns (without the registers).
    pub ns: f64,
    /// LUT levels.
    pub luts: u32,
    /// Carry-chain bits.
    pub carry: u32,
    /// Unregistered multipliers.
    pub dsps: u32,
}

impl Depth {
    fn through(self, luts: u32, carry: u32, dsps: u32) -> Depth {
        Depth {
            ns: self.ns
                + f64::from(luts) * DELAY.lut
                + f64::from(carry) * DELAY.carry_bit
                + f64::from(dsps) * DELAY.dsp,
            luts: self.luts + luts,
            carry: self.carry + carry,
            dsps: self.dsps + dsps,
        }
    }

    /// The path's estimated period, registers included.
    pub fn period_ns(&self) -> f64 {
        self.ns + DELAY.registers
    }
}

/// The deepest path ending in each group of registers (by the first level
/// of the endpoint's hierarchical name), and its endpoint.
pub type Report = BTreeMap<String, (Depth, String)>;

enum Kind {
    /// Starts and ends paths.
    Sequential,
    Lut,
    Arith,
    Dsp,
    /// Ports and buffers: no delay of their own.
    Wire,
}

fn kind(cell_type: &str) -> Kind {
    match cell_type {
        t if t.starts_with("MISTRAL_ALUT_ARITH") => Kind::Arith,
        t if t.starts_with("MISTRAL_ALUT") || t == "MISTRAL_NOT" => Kind::Lut,
        t if t.starts_with("MISTRAL_MUL") => Kind::Dsp,
        "MISTRAL_IB" | "MISTRAL_OB" | "MISTRAL_CLKBUF" => Kind::Wire,
        _ => Kind::Sequential,
    }
}

/// Bits of a connection (constants are strings in the JSON: no bit).
fn bits(v: &Value) -> Vec<u64> {
    v.as_array().map(|a| a.iter().filter_map(Value::as_u64).collect()).unwrap_or_default()
}

/// Analyse the top module of a Yosys JSON netlist.
pub fn analyse(json: &Value) -> Result<Report> {
    let modules = json["modules"].as_object().ok_or("no modules in the netlist")?;
    let (_, top) = modules
        .iter()
        .find(|(_, m)| m["attributes"]["top"].as_str().is_some_and(|t| t.trim_start_matches('0') == "1"))
        .or_else(|| modules.iter().next())
        .ok_or("no top module")?;
    let cells = top["cells"].as_object().ok_or("no cells")?;

    // Who drives each bit, through which input bits, at what cost.
    struct Node {
        inputs: Vec<(u64, u32, u32, u32)>, // (bit, luts, carry, dsps) added on the way
    }
    let mut driver: HashMap<u64, Node> = HashMap::new();
    let mut sinks: Vec<u64> = Vec::new();
    for cell in cells.values() {
        let t = cell["type"].as_str().unwrap_or("");
        let dirs = cell["port_directions"].as_object();
        let conns = cell["connections"].as_object();
        let (Some(dirs), Some(conns)) = (dirs, conns) else { continue };
        let port_bits = |dir: &str| -> Vec<(String, Vec<u64>)> {
            conns
                .iter()
                .filter(|(p, _)| dirs.get(*p).and_then(Value::as_str) == Some(dir))
                .map(|(p, v)| (p.clone(), bits(v)))
                .collect()
        };
        let (ins, outs) = (port_bits("input"), port_bits("output"));
        match kind(t) {
            Kind::Sequential => {
                for (p, b) in &ins {
                    if !p.contains("CLK") && p != "ACLR" {
                        sinks.extend(b);
                    }
                }
                // Outputs are sources: no driver entry.
            }
            k => {
                let all_in: Vec<(String, u64)> =
                    ins.iter().flat_map(|(p, b)| b.iter().map(move |x| (p.clone(), *x))).collect();
                for (_, ob) in &outs {
                    for o in ob {
                        let inputs = all_in
                            .iter()
                            .map(|(p, b)| match k {
                                Kind::Lut => (*b, 1, 0, 0),
                                Kind::Arith if p == "CI" => (*b, 0, 1, 0),
                                Kind::Arith => (*b, 1, 0, 0),
                                Kind::Dsp => (*b, 0, 0, 1),
                                _ => (*b, 0, 0, 0),
                            })
                            .collect();
                        driver.insert(*o, Node { inputs });
                    }
                }
                if t == "MISTRAL_OB" {
                    for (_, b) in &ins {
                        sinks.extend(b);
                    }
                }
            }
        }
    }

    // Longest path into every bit, iteratively (carry chains are long).
    let mut depth: HashMap<u64, Depth> = HashMap::new();
    let mut on_stack: HashMap<u64, bool> = HashMap::new();
    for &sink in &sinks {
        let mut stack = vec![sink];
        while let Some(&b) = stack.last() {
            if depth.contains_key(&b) {
                stack.pop();
                continue;
            }
            let Some(node) = driver.get(&b) else {
                depth.insert(b, Depth::default());
                stack.pop();
                continue;
            };
            let pending: Vec<u64> = node.inputs.iter().map(|i| i.0).filter(|i| !depth.contains_key(i)).collect();
            if pending.is_empty() || on_stack.get(&b) == Some(&true) {
                let d = node
                    .inputs
                    .iter()
                    .map(|&(i, l, c, m)| depth.get(&i).copied().unwrap_or_default().through(l, c, m))
                    .fold(Depth::default(), |a, x| if x.ns > a.ns { x } else { a });
                depth.insert(b, d);
                on_stack.remove(&b);
                stack.pop();
            } else {
                on_stack.insert(b, true);
                stack.extend(pending);
            }
        }
    }

    // Names: the hierarchical net name of each bit, if it has one.
    let mut names: HashMap<u64, String> = HashMap::new();
    if let Some(nets) = top["netnames"].as_object() {
        for (name, n) in nets {
            if name.contains('$') {
                continue;
            }
            let hdl = n["attributes"]["hdlname"].as_str().map(str::to_string).unwrap_or_else(|| name.clone());
            for b in bits(&n["bits"]) {
                names.entry(b).or_insert_with(|| hdl.clone());
            }
        }
    }
    let mut report = Report::new();
    for &s in &sinks {
        let d = depth.get(&s).copied().unwrap_or_default();
        let name = names.get(&s).cloned().unwrap_or_else(|| format!("net {s}"));
        // Yosys names mapped nets after the cells they connect; the
        // register's own name is the part before the first cell name.
        let name = name.split("_MISTRAL_").next().unwrap_or(&name).to_string();
        let group = name.split([' ', '.']).next().unwrap_or("").to_string();
        let group = if group.starts_with("u_") { group } else { "(top level)".to_string() };
        let e = report.entry(group).or_insert((Depth::default(), String::new()));
        if d.ns > e.0.ns {
            *e = (d, name);
        }
    }
    Ok(report)
}

/// Print the report of `json_path`; an error if a path misses the target.
pub fn print_report(what: &str, json_path: &Path) -> Result<f64> {
    let text = std::fs::read_to_string(json_path).map_err(|e| format!("{}: {e}", json_path.display()))?;
    let json: Value = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", json_path.display()))?;
    let report = analyse(&json)?;
    println!(
        "logic depth, {what} (estimated; bound {TARGET_NS:.0} ns, 50 MHz less 10%; * over {FAST_NS:.0} ns, 100 MHz):"
    );
    let mut worst = 0f64;
    for (group, (d, end)) in &report {
        let p = d.period_ns();
        worst = worst.max(p);
        let mark = if p > FAST_NS { '*' } else { ' ' };
        println!(
            "  {group:<14} {p:>5.1} ns{mark} {} LUT levels, {} carry bits, {} DSPs unregistered; into {end}",
            d.luts, d.carry, d.dsps
        );
    }
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FF -> LUT -> ARITH (carry from another ARITH) -> FF.
    #[test]
    fn paths_add_up_luts_carry_and_dsps() {
        let json = serde_json::json!({"modules": {"m": {
            "attributes": {"top": "00000000000000000000000000000001"},
            "cells": {
                "ff0": {"type": "MISTRAL_FF", "port_directions": {"CLK": "input", "DATAIN": "input", "Q": "output"},
                        "connections": {"CLK": [1], "DATAIN": [9], "Q": [2]}},
                "lut": {"type": "MISTRAL_ALUT4", "port_directions": {"A": "input", "Q": "output"},
                        "connections": {"A": [2], "Q": [3]}},
                "a0": {"type": "MISTRAL_ALUT_ARITH", "port_directions": {"A": "input", "CI": "input", "SO": "output", "CO": "output"},
                        "connections": {"A": [3], "CI": ["0"], "SO": [4], "CO": [5]}},
                "a1": {"type": "MISTRAL_ALUT_ARITH", "port_directions": {"A": "input", "CI": "input", "SO": "output", "CO": "output"},
                        "connections": {"A": ["0"], "CI": [5], "SO": [6], "CO": [7]}},
                "mul": {"type": "MISTRAL_MUL27X27", "port_directions": {"A": "input", "Y": "output"},
                        "connections": {"A": [6], "Y": [8]}},
                "ff1": {"type": "MISTRAL_FF", "port_directions": {"CLK": "input", "DATAIN": "input", "Q": "output"},
                        "connections": {"CLK": [1], "DATAIN": [8], "Q": [9]}}
            },
            "netnames": {"u_stage q": {"bits": [8], "attributes": {"hdlname": "u_stage q"}}}
        }}});
        let r = analyse(&json).expect("analysis");
        let (d, end) = &r["u_stage"];
        assert_eq!((d.luts, d.carry, d.dsps), (2, 1, 1), "LUT, ARITH's LUT, one carry bit, the DSP");
        assert_eq!(end, "u_stage q");
        assert!((d.ns - (2.0 * DELAY.lut + DELAY.carry_bit + DELAY.dsp)).abs() < 1e-9);
    }
}
