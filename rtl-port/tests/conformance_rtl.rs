//! The register-semantics suite (`hal_avalon::conformance`) against the
//! Verilated RTL: the same checks as against the simulated accelerator.
#![cfg(rtl_verilated)]

use hal_avalon::conformance::{BoardPins, Device, TestMemory};
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

    fn set_board_inputs(&mut self, keys: u8, switches: u16) {
        self.0.set_board_inputs(keys, switches)
    }

    fn board_outputs(&mut self) -> BoardPins {
        let (ledr, hex_n) = self.0.board_outputs();
        BoardPins { ledr, hex_n }
    }

    fn pass_clocks(&mut self, clocks: u32) {
        self.0.step(u64::from(clocks))
    }
}

fn rtl() -> Rtl {
    match RtlAccelerator::with_memory(TestMemory::default()) {
        Ok(a) => Rtl(a),
        Err(e) => panic!("{e}"),
    }
}

hal_avalon::conformance_tests!(rtl());
