//! The code that will touch the board's registers under Linux, tested: the
//! bridge window opened through UIO and through /dev/mem by
//! `hps_linux::window` (its device lookup, file offsets, sizes and word
//! accesses), over a file standing in for the bridge, with a device model
//! answering through a mapping of its own of the same file.
//!
//! The model is hal-avalon's simulated accelerator. Before each read the
//! code under test makes, it puts the register's value where that read
//! will look; after each write, it takes the value from where the write
//! should have landed (first poisoned, so a write that went elsewhere, or
//! nowhere, is seen) and hands it to the simulated accelerator. An offset,
//! a file offset or a size wrong in the mapping code shows up as a wrong
//! value in the suite.
//!
//! Two suites run over each mapping: hal-avalon's register-semantics suite
//! (`conformance_tests!`, raw word accesses through `Window`), and the
//! driver (`Accelerator` over `MappedPort`, the bare-metal `MmioPort`)
//! rendering rows and a whole frame equal to the model's.

mod support;

use std::path::PathBuf;

use hal_avalon::conformance::{BoardPins, Device, TestMemory, MEMORY_BASE};
use hal_avalon::map::{Csr, LINE_WORDS, LW_BRIDGE_BASE, LW_BRIDGE_SIZE};
use hal_avalon::sim::{CountingDelay, SimAccelerator};
use hal_avalon::{Accelerator, PollTimeout};
use hps_linux::window::Window;
use model::{Light, FRAME_BYTES};
use support::{simulated, through_dev_mem, through_uio, Answered, Bridge};

// ---- The register-semantics suite through `Window` -----------------------------

/// The suite's device: raw accesses through the window under test.
struct Mapped {
    window: Window,
    bridge: Bridge,
    sim: SimAccelerator<TestMemory>,
}

impl Device for Mapped {
    fn bus_read(&mut self, offset: usize) -> u32 {
        self.bridge.answer_read(&mut self.sim, offset);
        self.window.read_word(offset).expect("the suite's offsets lie in the window")
    }

    fn bus_write(&mut self, offset: usize, value: u32) {
        self.bridge.expect_write(offset);
        assert!(self.window.write_word(offset, value), "offset {offset:#x} in the window");
        let landed = self.bridge.take_write(&mut self.sim, offset);
        assert_eq!(landed, Some(value), "the write at {offset:#x} landed where the device sees it");
    }

    fn memory(&mut self) -> &mut TestMemory {
        self.sim.memory_mut()
    }

    fn set_board_inputs(&mut self, keys: u8, switches: u16) {
        self.sim.set_board_inputs(keys, switches)
    }

    fn board_outputs(&mut self) -> BoardPins {
        Device::board_outputs(&mut self.sim)
    }

    fn pass_clocks(&mut self, clocks: u32) {
        self.sim.pass_clocks(clocks)
    }
}

fn mapped((bridge, window): (Bridge, Window)) -> Mapped {
    Mapped { window, bridge, sim: simulated() }
}

mod dev_mem {
    use super::*;
    hal_avalon::conformance_tests!(mapped(through_dev_mem()));
}

mod uio {
    use super::*;
    hal_avalon::conformance_tests!(mapped(through_uio()));
}

// ---- The driver through `MappedPort` ---------------------------------------------

fn driver((bridge, window): (Bridge, Window)) -> Accelerator<Answered, CountingDelay> {
    let port = window.into_port().expect("the window holds the registers");
    Accelerator::new(Answered { port, bridge, sim: simulated() }, CountingDelay::default(), PollTimeout::DEFAULT)
}

fn rows_and_a_frame_equal_the_models(mut acc: Accelerator<Answered, CountingDelay>) {
    let caps = acc.probe().expect("the ray tracer answers through the mapping");
    assert_eq!(caps.version, hal_avalon::map::ID_VERSION);
    let light = Light::from_raw(3 << 10, 4 << 10, -(2 << 10)).unwrap();
    let (mut got, mut want) = ([0u32; LINE_WORDS], [0u32; LINE_WORDS]);
    for y in [0u16, 1, 119, 180, 359] {
        acc.run_row(y, &light, &mut got).expect("a row");
        model::render_row(y, &light, &mut want);
        assert_eq!(got, want, "row {y}");
    }
    acc.start_frame(MEMORY_BASE, &light).expect("a frame starts");
    let mut progress = acc.frame_progress().expect("frame progress");
    for _ in 0..1_000_000 {
        if progress.done {
            break;
        }
        progress = acc.frame_progress().expect("frame progress");
    }
    assert!(progress.done && progress.rows == 360, "{progress:?}");
    let mut frame = vec![0u8; FRAME_BYTES];
    model::render_frame_rgb888(&light, (&mut frame[..]).try_into().unwrap());
    let landed = &acc.port_mut().sim.memory_mut().bytes[..FRAME_BYTES];
    assert!(landed == &frame[..], "the frame DMA's frame is the model's");
}

#[test]
fn the_driver_renders_through_dev_mem() {
    rows_and_a_frame_equal_the_models(driver(through_dev_mem()));
}

#[test]
fn the_driver_renders_through_uio() {
    rows_and_a_frame_equal_the_models(driver(through_uio()));
}

#[test]
fn a_window_at_the_wrong_place_is_seen() {
    // The suite can fail: a window mapped one page off reads what the model
    // put a page away, not the ID.
    let (bridge, _) = through_dev_mem();
    let path: PathBuf = bridge.dir.path().join("mem");
    let off = Window::dev_mem(&path, LW_BRIDGE_BASE as u64 + 4096, LW_BRIDGE_SIZE - 4096).unwrap();
    let mut sim = simulated();
    bridge.answer_read(&mut sim, Csr::Id.offset());
    assert_eq!(bridge.get(Csr::Id.offset()), hal_avalon::map::ID_VALUE);
    assert_ne!(off.read_word(Csr::Id.offset()), Some(hal_avalon::map::ID_VALUE));
}
