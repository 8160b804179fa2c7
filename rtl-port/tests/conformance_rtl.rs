//! The register-semantics suite (`hal_avalon::conformance`) against the
//! Verilated RTL: the same checks as against the simulated accelerator.
#![cfg(rtl_verilated)]

use hal_avalon::conformance::{Device, TestMemory};
use rtl_port::RtlAccelerator;

struct Rtl(RtlAccelerator<TestMemory>);

impl Device for Rtl {
    fn bus_read(&mut self, offset: usize) -> u32 {
        self.0.bus_read(offset)
    }

    fn bus_write(&mut self, offset: usize, value: u32) {
        self.0.bus_write(offset, value)
    }

    fn memory(&mut self) -> &mut TestMemory {
        self.0.memory_mut()
    }
}

fn rtl() -> Rtl {
    match RtlAccelerator::with_memory(TestMemory::default()) {
        Ok(a) => Rtl(a),
        Err(e) => panic!("{e}"),
    }
}

hal_avalon::conformance_tests!(rtl());
