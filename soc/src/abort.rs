//! Data aborts: decoding the fault status, and recovering from the one
//! abort the firmware expects, an accelerator probe that no FPGA answers.
//!
//! On the Cyclone V, a read of the lightweight bridge with no slave behind
//! the address (an FPGA design without the ray tracer) ends in an AXI
//! DECERR/SLVERR response, which the Cortex-A9 takes as an external abort
//! (Cyclone V TRM, "HPS-to-FPGA bridges": unmapped addresses return a
//! decode error). While a probe is in progress the data-abort handler marks
//! the probe failed and resumes; any other abort is a real fault.
//!
//! Fault status register (short-descriptor format): ARM ARM DDI 0406C
//! B4.1.52 DFSR and table B3-23: FS = bits 10 and 3:0, WnR 11, ExT 12.
//! aarch32-cpu's `Dfsr::status()` decodes the long-descriptor layout, hence
//! the decoding here.

use core::sync::atomic::{AtomicBool, Ordering};

/// FS 0b01000: synchronous external abort (not on a translation walk).
pub const FS_SYNC_EXTERNAL: u8 = 0b01000;
/// FS 0b10110: asynchronous external abort.
pub const FS_ASYNC_EXTERNAL: u8 = 0b10110;

/// The 5-bit fault status of a short-descriptor DFSR value.
pub const fn fault_status(dfsr: u32) -> u8 {
    (((dfsr >> 6) & 0x10) | (dfsr & 0xf)) as u8
}

/// Where to resume after a data abort taken at `addr` (the address of the
/// faulting instruction for a synchronous abort, of the next instruction
/// for an asynchronous one, as aarch32-rt's trampoline passes it: LR - 8)
/// while a probe is in progress: after the load for a synchronous external
/// abort, at `addr` for an asynchronous one. `None` for any other fault,
/// which the handler reports as fatal. The probe's load must be one A32
/// `ldr` whose destination holds a value that reads as "absent" when the
/// load is skipped.
pub const fn probe_resume(dfsr: u32, addr: usize) -> Option<usize> {
    match fault_status(dfsr) {
        FS_SYNC_EXTERNAL => Some(addr + 4),
        FS_ASYNC_EXTERNAL => Some(addr),
        _ => None,
    }
}

/// Whether a probe is in progress, and whether it faulted; shared between
/// the probing code and the data-abort handler.
#[derive(Debug, Default)]
pub struct ProbeGuard {
    active: AtomicBool,
    faulted: AtomicBool,
}

impl ProbeGuard {
    /// No probe in progress.
    pub const fn new() -> ProbeGuard {
        ProbeGuard { active: AtomicBool::new(false), faulted: AtomicBool::new(false) }
    }

    /// Run `read` (which performs the probe's bus accesses) with the guard
    /// active; returns its value, or `None` if an external abort was taken
    /// meanwhile.
    pub fn probe<T>(&self, read: impl FnOnce() -> T) -> Option<T> {
        self.faulted.store(false, Ordering::SeqCst);
        self.active.store(true, Ordering::SeqCst);
        let value = read();
        self.active.store(false, Ordering::SeqCst);
        (!self.faulted.load(Ordering::SeqCst)).then_some(value)
    }

    /// The data-abort handler's decision for fault `dfsr` at `addr`: the
    /// resume address when a probe is in progress and the fault is an
    /// external abort (the probe is then marked failed), else `None`.
    pub fn on_data_abort(&self, dfsr: u32, addr: usize) -> Option<usize> {
        if !self.active.load(Ordering::SeqCst) {
            return None;
        }
        let resume = probe_resume(dfsr, addr)?;
        self.faulted.store(true, Ordering::SeqCst);
        Some(resume)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_status_takes_bit_10_and_bits_3_to_0() {
        assert_eq!(fault_status(0x0000_0008), FS_SYNC_EXTERNAL);
        assert_eq!(fault_status(0x0000_0406), FS_ASYNC_EXTERNAL);
        assert_eq!(fault_status(0x0000_0808), FS_SYNC_EXTERNAL, "WnR does not change FS");
        assert_eq!(fault_status(0x0000_1008), FS_SYNC_EXTERNAL, "ExT does not change FS");
        assert_eq!(fault_status(0x0000_0005), 0b00101, "translation fault, section");
    }

    #[test]
    fn only_external_aborts_during_a_probe_are_recovered() {
        let g = ProbeGuard::new();
        assert_eq!(g.on_data_abort(0x8, 0x1000), None, "no probe: fatal");
        let got = g.probe(|| {
            // The abort taken inside the probe's load.
            assert_eq!(g.on_data_abort(0x8, 0x1000), Some(0x1004), "precise: skip the load");
            0u32
        });
        assert_eq!(got, None, "the probe reports the fault");
        let got = g.probe(|| {
            assert_eq!(g.on_data_abort(0x406, 0x2000), Some(0x2000), "imprecise: resume where taken");
            7
        });
        assert_eq!(got, None);
        let got = g.probe(|| {
            assert_eq!(g.on_data_abort(0x5, 0x3000), None, "a translation fault stays fatal");
            7
        });
        assert_eq!(got, Some(7), "no external abort: the value stands");
        assert_eq!(g.probe(|| 0x5254_0002u32), Some(0x5254_0002));
    }
}
