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

use std::path::{Path, PathBuf};

use hal_avalon::conformance::{BoardPins, Device, TestMemory, MEMORY_BASE};
use hal_avalon::map::{line_word_offset, Csr, LINE_WORDS, LW_BRIDGE_BASE, LW_BRIDGE_SIZE};
use hal_avalon::sim::{CountingDelay, SimAccelerator};
use hal_avalon::{Accelerator, PollTimeout, RegisterPort};
use hps_linux::window::{MappedPort, Window};
use memmap2::{MmapOptions, MmapRaw};
use model::{Light, FRAME_BYTES};
use tempfile::TempDir;

/// What a word holds before a write is expected to land in it.
const POISON: u32 = 0xA5C3_96E1;

/// STATUS polls a simulated row stays busy for.
const BUSY_POLLS: u32 = 3;

/// The file standing in for the bridge and the model's view of the window
/// in it (a second mapping of the same bytes, as a second bus master sees
/// them).
struct Bridge {
    dir: TempDir,
    view: MmapRaw,
}

impl Bridge {
    fn get(&self, offset: usize) -> u32 {
        let word = offset & !3;
        assert!(word + 4 <= self.view.len());
        // SAFETY: in bounds (asserted), 4-byte aligned in a page-aligned
        // mapping that lives as long as `self`; volatile, since the code
        // under test writes the same bytes through its own mapping.
        unsafe { self.view.as_mut_ptr().add(word).cast::<u32>().read_volatile() }
    }

    fn set(&self, offset: usize, value: u32) {
        let word = offset & !3;
        assert!(word + 4 <= self.view.len());
        // SAFETY: as in `get`.
        unsafe { self.view.as_mut_ptr().add(word).cast::<u32>().write_volatile(value) }
    }

    /// The model's read at `offset`, put where the code under test reads.
    fn answer_read(&self, sim: &mut SimAccelerator<TestMemory>, offset: usize) {
        self.set(offset, sim.bus_read(offset));
    }

    /// Poison `offset` before a write the code under test makes there.
    fn expect_write(&self, offset: usize) {
        self.set(offset, POISON);
    }

    /// The value the write landed, handed to the model; `None` if nothing
    /// landed.
    fn take_write(&self, sim: &mut SimAccelerator<TestMemory>, offset: usize) -> Option<u32> {
        let value = self.get(offset);
        (value != POISON).then(|| {
            sim.bus_write(offset, value);
            value
        })
    }
}

/// A /dev/mem stand-in: a sparse file as long as the bridge's physical
/// address plus its window, the window opened by the code under test.
fn through_dev_mem() -> (Bridge, Window) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("mem");
    let end = LW_BRIDGE_BASE as u64 + LW_BRIDGE_SIZE as u64;
    std::fs::File::create(&path).and_then(|f| f.set_len(end)).expect("sparse /dev/mem stand-in");
    let window = Window::lightweight_bridge(&path).expect("the window through /dev/mem");
    let view = map_view(&path, LW_BRIDGE_BASE as u64, LW_BRIDGE_SIZE);
    (Bridge { dir, view }, window)
}

/// A UIO stand-in: `class/uio0` maps something else, `class/uio3` the
/// bridge; `dev/uio3` is a file holding the window (map 0 at offset 0).
/// The code under test finds the device by address and opens it.
fn through_uio() -> (Bridge, Window) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let class = dir.path().join("class");
    let dev = dir.path().join("dev");
    for (name, addr, size) in [("uio0", 0xffc0_2000u64, 0x1000usize), ("uio3", LW_BRIDGE_BASE as u64, LW_BRIDGE_SIZE)] {
        let maps = class.join(name).join("maps/map0");
        std::fs::create_dir_all(&maps).unwrap();
        std::fs::write(maps.join("addr"), format!("{addr:#010x}\n")).unwrap();
        std::fs::write(maps.join("size"), format!("{size:#010x}\n")).unwrap();
        std::fs::create_dir_all(&dev).unwrap();
        std::fs::File::create(dev.join(name)).and_then(|f| f.set_len(size as u64)).unwrap();
    }
    let device = Window::find_uio(&class, &dev, LW_BRIDGE_BASE as u64).expect("the bridge's UIO device");
    assert_eq!(device, dev.join("uio3"), "the device whose map 0 is the bridge");
    let window = Window::uio(&device, &class).expect("the window through UIO");
    assert_eq!(window.len(), LW_BRIDGE_SIZE, "as big as sysfs says");
    let view = map_view(&device, 0, LW_BRIDGE_SIZE);
    (Bridge { dir, view }, window)
}

fn map_view(path: &Path, offset: u64, len: usize) -> MmapRaw {
    let file = std::fs::OpenOptions::new().read(true).write(true).open(path).expect("the stand-in file");
    MmapOptions::new().offset(offset).len(len).map_raw(&file).expect("the model's mapping")
}

fn simulated() -> SimAccelerator<TestMemory> {
    SimAccelerator::with_memory(TestMemory::default(), BUSY_POLLS)
}

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

/// The driver's port: the bare-metal `MmioPort` on the mapping under test,
/// each access answered by the model through the file.
struct Answered {
    port: MappedPort,
    bridge: Bridge,
    sim: SimAccelerator<TestMemory>,
}

impl RegisterPort for Answered {
    fn read(&mut self, csr: Csr) -> u32 {
        self.bridge.answer_read(&mut self.sim, csr.offset());
        self.port.read(csr)
    }

    fn write(&mut self, csr: Csr, value: u32) {
        self.bridge.expect_write(csr.offset());
        self.port.write(csr, value);
        // A write the port does not make (a read-only register) reaches
        // nothing.
        let _ = self.bridge.take_write(&mut self.sim, csr.offset());
    }

    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        for x in 0..LINE_WORDS {
            self.bridge.answer_read(&mut self.sim, line_word_offset(x));
        }
        self.port.read_line(out)
    }
}

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
