//! The reset entry's shape, checked in the DE1-SoC image's disassembly
//! (`cargo xtask image`): `firmware/src/start.rs` runs with caches a boot
//! loader may have left dirty, so
//!
//! * no load in `_start` reads memory through the PC (a literal pool): with
//!   the D-cache off such a load reads DRAM, which may be stale under a
//!   dirty line; every constant is built with `movw`/`movt`;
//! * between the SCTLR write that turns the D-cache off and the L2C-310's
//!   clean-and-invalidate-by-way (offset 0x7FC), every load is from the
//!   L2C-310's registers (the base built with `movw`/`movt`);
//! * before its first store or CP15 write, `_start` reads MPIDR and sends
//!   every core but core 0 to `_asm_secondary_core_park` (QEMU starts all
//!   cores at the ELF entry: a late second core would overwrite the entry
//!   record and could turn the L2 off under core 0);
//! * the L2C-310's control register (offset 0x100) is read on every path:
//!   the branch taken when SCTLR has the D-cache and MMU off lands at or
//!   before that read (U-Boot's `dcache off` leaves the L2 on).
//!
//! Input: `llvm-objdump -d --no-show-raw-insn --disassemble-symbols=_start`
//! (LLVM 14 prints immediates in decimal, later versions too).

use std::path::Path;
use std::process::Command;

use crate::support::Result;

/// The DE1-SoC's L2C-310 (Cyclone V HPS TRM, "HPS Address Map": `L2`
/// 0xFFFE_F000; firmware/src/boards/de1_soc.rs).
pub const DE1_SOC_L2C: u32 = 0xfffe_f000;

/// L2C-310 register offsets (ARM DDI 0246, 3.3 "Register summary").
const CONTROL: u32 = 0x100;
const CLEAN_INVALIDATE_WAY: u32 = 0x7fc;

/// One instruction: address, mnemonic, operands.
#[derive(Debug)]
struct Insn {
    addr: u64,
    mnemonic: String,
    operands: String,
}

fn parse(disasm: &str) -> Vec<Insn> {
    let mut out = vec![];
    let mut inside = false;
    for line in disasm.lines() {
        if line.ends_with("<_start>:") {
            inside = true;
            continue;
        }
        if !inside {
            continue;
        }
        let t = line.trim();
        if t.is_empty() {
            if !out.is_empty() {
                break;
            }
            continue;
        }
        let Some((addr, rest)) = t.split_once(':') else { continue };
        let Ok(addr) = u64::from_str_radix(addr.trim(), 16) else { continue };
        let rest = rest.split('@').next().unwrap_or("").trim();
        let (mnemonic, operands) = rest.split_once(char::is_whitespace).unwrap_or((rest, ""));
        out.push(Insn { addr, mnemonic: mnemonic.to_string(), operands: operands.trim().to_string() });
    }
    out
}

fn imm(s: &str) -> Option<u32> {
    let s = s.trim().trim_start_matches('#');
    match s.strip_prefix("0x") {
        Some(h) => u32::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

/// `[rN, #off]` of a load or store: base register and offset.
fn address(operands: &str) -> Option<(String, u32)> {
    let inner = operands.split_once('[')?.1.split_once(']')?.0;
    let mut parts = inner.split(',');
    let base = parts.next()?.trim().to_string();
    let off = parts.next().map_or(Some(0), imm)?;
    Some((base, off))
}

fn is_load(m: &str) -> bool {
    m.starts_with("ldr") || m.starts_with("ldm") || m.starts_with("pop") || m.starts_with("vldr")
}

/// Check the disassembly of `_start` for a board whose L2C-310 is at `l2c`.
pub fn check(disasm: &str, l2c: u32) -> Result<()> {
    let insns = parse(disasm);
    if insns.is_empty() {
        return Err("no _start in the disassembly".into());
    }
    for i in &insns {
        if i.mnemonic.starts_with('.') || i.mnemonic.contains("unknown") {
            return Err(format!("_start holds data at {:#x} ({} {})", i.addr, i.mnemonic, i.operands));
        }
        if is_load(&i.mnemonic) && i.operands.contains("[pc") {
            return Err(format!("_start loads a literal at {:#x}: {} {}", i.addr, i.mnemonic, i.operands));
        }
    }
    secondary_cores_park_first(&insns)?;
    // The register movw/movt set to the L2C-310's base.
    let mut lo: Vec<(String, u32)> = vec![];
    let mut base = None;
    for i in &insns {
        let mut ops = i.operands.splitn(2, ',');
        let (reg, val) = (ops.next().unwrap_or("").trim().to_string(), ops.next().and_then(imm));
        match (i.mnemonic.as_str(), val) {
            ("movw", Some(v)) => lo.push((reg, v)),
            ("movt", Some(v)) if lo.iter().rev().find(|(r, _)| *r == reg).is_some_and(|(_, l)| v << 16 | l == l2c) => {
                base = Some(reg)
            }
            _ => {}
        }
    }
    let base = base.ok_or_else(|| format!("_start never builds the L2C-310 base {l2c:#010x} with movw/movt"))?;
    let at = |off: u32, load: bool| {
        insns.iter().position(|i| {
            (if load { is_load(&i.mnemonic) } else { i.mnemonic.starts_with("str") })
                && address(&i.operands).is_some_and(|(b, o)| b == base && o == off)
        })
    };
    let control = at(CONTROL, true).ok_or("_start never reads the L2C-310 control register")?;
    let clean = at(CLEAN_INVALIDATE_WAY, false).ok_or("_start never cleans and invalidates the L2 by way")?;
    let sctlr_write = insns
        .iter()
        .position(|i| i.mnemonic == "mcr" && i.operands.replace(' ', "").ends_with("c1,c0,#0"))
        .ok_or("_start never writes SCTLR")?;
    for i in &insns[sctlr_write..clean] {
        if is_load(&i.mnemonic) && address(&i.operands).is_none_or(|(b, _)| b != base) {
            return Err(format!(
                "_start loads from memory between turning the D-cache off and the L2 clean, at {:#x}: {} {}",
                i.addr, i.mnemonic, i.operands
            ));
        }
    }
    // The SCTLR test's branch (caches off at entry) must not skip the L2.
    let tst = insns
        .iter()
        .position(|i| i.mnemonic == "tst" && i.operands.replace(' ', "") == "r0,#5")
        .ok_or("_start does not test SCTLR.C|M")?;
    let branch = insns[tst + 1..].iter().find(|i| i.mnemonic.starts_with('b')).ok_or("no branch after the test")?;
    let target = branch
        .operands
        .split_whitespace()
        .next()
        .and_then(|t| u64::from_str_radix(t.trim_start_matches("0x"), 16).ok())
        .ok_or_else(|| format!("branch target of {:?}", branch.operands))?;
    if target > insns[control].addr {
        return Err(format!(
            "with the caches off at entry _start branches to {target:#x}, past the L2C-310 check at {:#x}",
            insns[control].addr
        ));
    }
    Ok(())
}

/// Before the first store or CP15 write: MPIDR read, then a conditional
/// branch to the park for any core but 0.
fn secondary_cores_park_first(insns: &[Insn]) -> Result<()> {
    let first_write = insns
        .iter()
        .position(|i| i.mnemonic.starts_with("str") || i.mnemonic.starts_with("stm") || i.mnemonic == "mcr")
        .unwrap_or(insns.len());
    let before = &insns[..first_write];
    let mpidr = before
        .iter()
        .position(|i| i.mnemonic == "mrc" && i.operands.replace(' ', "").ends_with("c0,c0,#5"))
        .ok_or("_start does not read MPIDR before its first store or CP15 write")?;
    let parks = before[mpidr + 1..].iter().any(|i| {
        i.mnemonic.starts_with('b') && i.mnemonic.len() > 1 && i.operands.contains("<_asm_secondary_core_park>")
    });
    if !parks {
        return Err("_start does not send the other cores to _asm_secondary_core_park before its first store".into());
    }
    Ok(())
}

/// Disassemble `_start` of `elf` with llvm-objdump and check it.
pub fn check_elf(elf: &Path, l2c: u32) -> Result<()> {
    let out = Command::new("llvm-objdump")
        .args(["-d", "--no-show-raw-insn", "--disassemble-symbols=_start"])
        .arg(elf)
        .output()
        .map_err(|e| format!("llvm-objdump (Debian package llvm): {e}"))?;
    if !out.status.success() {
        return Err(format!("llvm-objdump: {}", String::from_utf8_lossy(&out.stderr)));
    }
    check(&String::from_utf8_lossy(&out.stdout), l2c)
}

#[cfg(test)]
mod tests {
    use super::*;

    const L2C: u32 = 0xfffe_f000;

    /// The entry as built (llvm-objdump 14 output, trimmed).
    const NOW: &str = "
00106ba4 <_start>:
  106ba4:      \tmrc\tp15, #0, r0, c0, c0, #5
  106ba8:      \tands\tr0, r0, #255
  106bac:      \tbne\t0x106c90 <_asm_secondary_core_park> @ imm = #220
  106bb0:      \tmrc\tp15, #0, r0, c1, c0, #0
  106bb4:      \tmovw\tr1, #40992
  106bb8:      \tmovt\tr1, #42
  106bbc:      \tstr\tr0, [r1]
  106bc0:      \ttst\tr0, #5
  106bc4:      \tbeq\t0x106c04 <_start+0x54>  @ imm = #56
  106bc8:      \tbic\tr1, r0, #4
  106bcc:      \tmcr\tp15, #0, r1, c1, c0, #0
  106bd0:      \tisb\tsy
  106be4:      \tmcr\tp15, #0, r4, c7, c14, #2
  106c00:      \tdsb\tsy
  106c04:      \tmovw\tr6, #61440
  106c08:      \tmovt\tr6, #65534
  106c0c:      \tldr\tr1, [r6, #256]
  106c10:      \ttst\tr1, #1
  106c14:      \tbeq\t0x106c58 <_start+0xa8>  @ imm = #60
  106c18:      \tldr\tr1, [r6, #260]
  106c28:      \tstr\tr2, [r6, #2044]
  106c2c:      \tmovw\tr7, #16960
  106c30:      \tmovt\tr7, #15
  106c34:      \tldr\tr1, [r6, #2044]
  106c58:      \tbic\tr0, r0, #5
  106c60:      \tmcr\tp15, #0, r0, c1, c0, #0
  106c8c:      \tb\t0x10ab6c <_default_start> @ imm = #16088
";

    #[test]
    fn the_entry_as_built_passes() {
        assert_eq!(check(NOW, L2C), Ok(()));
        assert!(check(NOW, 0xf03f_c000).is_err(), "another board's L2C base is not built");
    }

    #[test]
    fn an_entry_that_lets_every_core_through_fails() {
        // The entry before: core 1, started at the ELF entry by QEMU,
        // stored its SCTLR over core 0's record.
        let old = NOW.replace("\tbne\t0x106c90 <_asm_secondary_core_park> @ imm = #220", "\tnop");
        let e = check(&old, L2C).expect_err("no park");
        assert!(e.contains("_asm_secondary_core_park"), "{e}");
        let late = NOW.replace("\tmrc\tp15, #0, r0, c0, c0, #5", "\tnop");
        assert!(check(&late, L2C).expect_err("no MPIDR").contains("MPIDR"));
    }

    #[test]
    fn a_literal_pool_load_fails() {
        // The entry before: `ldr r6, =L2C` assembled as a PC-relative load
        // with a literal pool behind the function.
        let old = NOW.replace("\tmovw\tr6, #61440", "\tldr\tr6, [pc, #132]").replace("\tmovt\tr6, #65534", "\tnop");
        let e = check(&old, L2C).expect_err("literal load");
        assert!(e.contains("loads a literal"), "{e}");
        let with_pool = NOW.replace("  106c8c:", "  106c88:      \t.word\t0xfffef000\n  106c8c:");
        assert!(check(&with_pool, L2C).expect_err("data").contains("holds data"));
    }

    #[test]
    fn a_memory_load_between_the_d_cache_off_and_the_l2_clean_fails() {
        let bad = NOW.replace("  106c00:      \tdsb\tsy", "  106c00:      \tldr\tr9, [r1, #4]");
        let e = check(&bad, L2C).expect_err("load from r1");
        assert!(e.contains("between turning the D-cache off"), "{e}");
    }

    #[test]
    fn skipping_the_l2_when_sctlr_has_the_caches_off_fails() {
        // The entry before: `beq 5f` from the SCTLR test jumped past the L2.
        let old = NOW.replace("beq\t0x106c04 <_start+0x54>", "beq\t0x106c68 <_start+0xb8>");
        let e = check(&old, L2C).expect_err("skips the L2");
        assert!(e.contains("past the L2C-310 check"), "{e}");
        assert!(check(&NOW.replace("[r6, #256]", "[r6, #264]"), L2C).is_err(), "no control read");
    }
}
