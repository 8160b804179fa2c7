//! Frame memory in the host's RAM: a ring of frame slots that an
//! accelerator's frame DMA (simulated, Verilated, or rows written by the
//! driver) fills and the services read.

use std::sync::{Arc, Mutex, MutexGuard};

use hal_avalon::sim::{DmaTarget, SimAccelerator};
use model::{FRAME_BYTES, ROW_BYTES};
use rt_services::{FrameMemory, SliceMemory};

/// Bus address of the ring (any 8-byte aligned value: the frame DMA is
/// given slot addresses from it, and nothing else is at that address).
const RING_BASE: u32 = 0x0410_0000;

/// STATUS polls a simulated row stays busy for: enough that the driver's
/// polling loop runs, few enough to cost nothing.
pub const SIM_BUSY_POLLS: u32 = 2;

/// Host memory shared by the frame DMA (which writes it) and the frame
/// ring (which reads it); `Send`, so that one ring can serve every
/// connection's thread, as on the board (the lock is never contended: the
/// ring that owns it is behind a lock of its own).
#[derive(Clone)]
pub struct SharedMemory(Arc<Mutex<Vec<u8>>>);

impl SharedMemory {
    /// Zeroed memory for `slots` frame slots.
    pub fn new(slots: usize) -> SharedMemory {
        SharedMemory(Arc::new(Mutex::new(vec![0; slots * FRAME_BYTES])))
    }

    fn bytes(&self) -> MutexGuard<'_, Vec<u8>> {
        // Nothing panics while holding it; a poisoned lock's bytes are whole.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn offset(addr: u32) -> Option<usize> {
        addr.checked_sub(RING_BASE).map(|o| o as usize)
    }
}

impl DmaTarget for SharedMemory {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        let mut mem = self.bytes();
        match Self::offset(addr).and_then(|o| mem.get_mut(o..o + bytes.len())) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                true
            }
            None => false,
        }
    }
}

impl FrameMemory for SharedMemory {
    fn slot_address(&self, slot: usize) -> u32 {
        RING_BASE + (slot * FRAME_BYTES) as u32
    }

    fn read_row(&mut self, slot: usize, y: u16, offset: usize, out: &mut [u8]) {
        SliceMemory::new(RING_BASE, &mut self.bytes()).read_row(slot, y, offset, out)
    }

    fn write_row(&mut self, slot: usize, y: u16, row: &[u8; ROW_BYTES]) {
        SliceMemory::new(RING_BASE, &mut self.bytes()).write_row(slot, y, row)
    }
}

/// hal-avalon's simulated accelerator, its frame DMA writing `mem`.
pub fn simulated_accelerator<M: DmaTarget>(mem: M) -> SimAccelerator<M> {
    SimAccelerator::with_memory(mem, SIM_BUSY_POLLS)
}
