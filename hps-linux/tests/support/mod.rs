//! What the mapped-register tests share: a file standing in for the bridge,
//! opened by the code under test through /dev/mem or UIO, and the device
//! model (hal-avalon's simulated accelerator) answering each access through
//! a mapping of its own of that file.

#![allow(dead_code)] // each test file uses part of it

use std::path::Path;

use hal_avalon::conformance::TestMemory;
use hal_avalon::map::{line_word_offset, Csr, LINE_WORDS, LW_BRIDGE_BASE, LW_BRIDGE_SIZE};
use hal_avalon::sim::{DmaTarget, SimAccelerator};
use hal_avalon::RegisterPort;
use hps_linux::window::{MappedPort, Window};
use memmap2::{MmapOptions, MmapRaw};
use tempfile::TempDir;

/// What a word holds before a write is expected to land in it.
pub const POISON: u32 = 0xA5C3_96E1;

/// STATUS polls a simulated row stays busy for.
pub const BUSY_POLLS: u32 = 3;

/// The file standing in for the bridge and the model's view of the window
/// in it (a second mapping of the same bytes, as a second bus master sees
/// them).
pub struct Bridge {
    pub dir: TempDir,
    view: MmapRaw,
}

impl Bridge {
    pub fn get(&self, offset: usize) -> u32 {
        let word = offset & !3;
        assert!(word + 4 <= self.view.len());
        // SAFETY: in bounds (asserted), 4-byte aligned in a page-aligned
        // mapping that lives as long as `self`; volatile, since the code
        // under test writes the same bytes through its own mapping.
        unsafe { self.view.as_mut_ptr().add(word).cast::<u32>().read_volatile() }
    }

    pub fn set(&self, offset: usize, value: u32) {
        let word = offset & !3;
        assert!(word + 4 <= self.view.len());
        // SAFETY: as in `get`.
        unsafe { self.view.as_mut_ptr().add(word).cast::<u32>().write_volatile(value) }
    }

    /// The model's read at `offset`, put where the code under test reads.
    pub fn answer_read<M: DmaTarget>(&self, sim: &mut SimAccelerator<M>, offset: usize) {
        self.set(offset, sim.bus_read(offset));
    }

    /// Poison `offset` before a write the code under test makes there.
    pub fn expect_write(&self, offset: usize) {
        self.set(offset, POISON);
    }

    /// The value the write landed, handed to the model; `None` if nothing
    /// landed.
    pub fn take_write<M: DmaTarget>(&self, sim: &mut SimAccelerator<M>, offset: usize) -> Option<u32> {
        let value = self.get(offset);
        (value != POISON).then(|| {
            sim.bus_write(offset, value);
            value
        })
    }
}

/// A /dev/mem stand-in: a sparse file as long as the bridge's physical
/// address plus its window, the window opened by the code under test.
pub fn through_dev_mem() -> (Bridge, Window) {
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
pub fn through_uio() -> (Bridge, Window) {
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
    let window = Window::uio(&device, &class, LW_BRIDGE_BASE as u64).expect("the window through UIO");
    assert_eq!(window.len(), LW_BRIDGE_SIZE, "as big as sysfs says");
    let view = map_view(&device, 0, LW_BRIDGE_SIZE);
    (Bridge { dir, view }, window)
}

pub fn map_view(path: &Path, offset: u64, len: usize) -> MmapRaw {
    let file = std::fs::OpenOptions::new().read(true).write(true).open(path).expect("the stand-in file");
    MmapOptions::new().offset(offset).len(len).map_raw(&file).expect("the model's mapping")
}

pub fn simulated() -> SimAccelerator<TestMemory> {
    SimAccelerator::with_memory(TestMemory::default(), BUSY_POLLS)
}

/// The driver's port: the bare-metal `MmioPort` on the mapping under test,
/// each access answered by the model through the file.
pub struct Answered<M = TestMemory> {
    pub port: MappedPort,
    pub bridge: Bridge,
    pub sim: SimAccelerator<M>,
}

impl<M: DmaTarget> RegisterPort for Answered<M> {
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

/// A frame over the seed protocol (what the server sent before it
/// closed: short when the frame failed).
pub fn seed_frame(addr: std::net::SocketAddr, raw: [i32; 3]) -> Vec<u8> {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(std::time::Duration::from_secs(60))).unwrap();
    let req: Vec<u8> = raw.iter().flat_map(|v| v.to_be_bytes()).collect();
    s.write_all(&req).unwrap();
    let mut frame = Vec::new();
    s.read_to_end(&mut frame).expect("the frame");
    frame
}

/// The model's frame for the raw light `raw`.
pub fn model_frame(raw: [i32; 3]) -> Vec<u8> {
    let mut want = vec![0u8; model::FRAME_BYTES];
    let light = model::Light::from_raw(raw[0], raw[1], raw[2]).unwrap();
    model::render_frame_rgb888(&light, (&mut want[..]).try_into().unwrap());
    want
}

/// `GET path` on `addr`: the answer's body.
pub fn http_get(addr: std::net::SocketAddr, path: &str) -> String {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(std::time::Duration::from_secs(10))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").unwrap();
    let mut answer = String::new();
    s.read_to_string(&mut answer).unwrap();
    answer.split_once("\r\n\r\n").map(|(_, body)| body.to_string()).unwrap_or_default()
}
