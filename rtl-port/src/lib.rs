//! hal-avalon's [`RegisterPort`] over the Verilated RTL: the accelerator
//! exactly as `fpga/rtl` describes it, driven by the same driver code the
//! firmware runs on the board.
//!
//! `build.rs` Verilates `rt_top` (default parameters: one lane) into a
//! static library with a small C ABI (`csrc/rtl_port.cpp`): reset, a bus
//! read, a bus write, step n clocks, the cycle count, and a write-only AXI3
//! memory port whose beats go to a [`DmaTarget`]. Every register access is
//! one Avalon transfer of the RTL, clocked (a read has the slave's fixed
//! latency of one), followed by [`RtlAccelerator::set_access_cycles`] idle
//! clocks that stand for the bridge's latency (default
//! [`DEFAULT_ACCESS_CYCLES`]); so polling STATUS advances simulated time
//! just as it does on the board.
//!
//! Without Verilator at build time the crate builds without the RTL and
//! [`RtlAccelerator::new`] returns [`NotBuilt`].

use core::fmt;

use hal_avalon::map::{Csr, CSR_OFFSET, LINE_WORDS};
use hal_avalon::sim::{DmaTarget, NoMemory};
use hal_avalon::RegisterPort;

/// Idle fabric clocks after each bus access: a lightweight-bridge register
/// read takes about 220 ns, 11 clocks at 50 MHz (docs/frame-dma.md, cost
/// model); one is the transfer itself.
pub const DEFAULT_ACCESS_CYCLES: u64 = 10;

/// Idle clocks after each line-buffer word: the firmware reads the line
/// buffer with `ldm` bursts, about 52 ns a word (76 MB/s) on a DE1-SoC.
pub const LINE_WORD_CYCLES: u64 = 2;

/// This build has no RTL: Verilator was not installed when it was built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NotBuilt;

impl fmt::Display for NotBuilt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(
            "this build has no RTL: Verilator was not installed when rtl-port was built \
             (apt-get install verilator, then rebuild; cargo xtask test installs it)",
        )
    }
}

impl std::error::Error for NotBuilt {}

/// Whether this build contains the Verilated RTL.
pub const fn available() -> bool {
    cfg!(rtl_verilated)
}

#[cfg(rtl_verilated)]
mod ffi {
    use core::ffi::c_void;

    #[repr(C)]
    pub struct RtlPort {
        _opaque: [u8; 0],
    }

    pub type DmaWrite = unsafe extern "C" fn(ctx: *mut c_void, addr: u32, bytes: *const u8, len: u32) -> i32;
    pub type DmaRead = unsafe extern "C" fn(ctx: *mut c_void, addr: u32, out: *mut u8, len: u32) -> i32;

    unsafe extern "C" {
        pub fn rtl_port_new() -> *mut RtlPort;
        pub fn rtl_port_free(p: *mut RtlPort);
        pub fn rtl_port_reset(p: *mut RtlPort);
        pub fn rtl_port_set_answering(p: *mut RtlPort, on: i32);
        pub fn rtl_port_set_dma(p: *mut RtlPort, f: Option<DmaWrite>, ctx: *mut c_void);
        pub fn rtl_port_set_dma_read(p: *mut RtlPort, f: Option<DmaRead>);
        pub fn rtl_port_set_board_inputs(p: *mut RtlPort, keys: u32, switches: u32);
        pub fn rtl_port_board_outputs(p: *mut RtlPort, ledr: *mut u16, hex_n: *mut u8);
        pub fn rtl_port_write(p: *mut RtlPort, byte_offset: u32, value: u32);
        pub fn rtl_port_read(p: *mut RtlPort, byte_offset: u32) -> u32;
        pub fn rtl_port_step(p: *mut RtlPort, n: u64);
        pub fn rtl_port_cycles(p: *const RtlPort) -> u64;
    }
}

/// The Verilated accelerator, its frame DMA writing into `M`.
pub struct RtlAccelerator<M: DmaTarget = NoMemory> {
    #[cfg(rtl_verilated)]
    raw: core::ptr::NonNull<ffi::RtlPort>,
    // Boxed: the C side holds its address for the DMA callback.
    mem: Box<M>,
    access_cycles: u64,
}

// SAFETY: the Verilated model has no thread affinity (each instance owns
// its VerilatedContext); the handle is only used through `&mut self`.
unsafe impl<M: DmaTarget + Send> Send for RtlAccelerator<M> {}

impl RtlAccelerator<NoMemory> {
    /// The RTL out of reset, no memory behind its frame DMA (every frame
    /// write gets an error response).
    pub fn new() -> Result<RtlAccelerator<NoMemory>, NotBuilt> {
        RtlAccelerator::with_memory(NoMemory)
    }
}

impl<M: DmaTarget> RtlAccelerator<M> {
    /// The RTL out of reset, its frame DMA writing into `mem`.
    pub fn with_memory(mem: M) -> Result<RtlAccelerator<M>, NotBuilt> {
        #[cfg(rtl_verilated)]
        {
            // SAFETY: `rtl_port_new` returns a fresh, reset model (or null
            // if the C++ allocation failed, which aborts before returning).
            let raw = core::ptr::NonNull::new(unsafe { ffi::rtl_port_new() }).ok_or(NotBuilt)?;
            let mut a = RtlAccelerator { raw, mem: Box::new(mem), access_cycles: DEFAULT_ACCESS_CYCLES };
            let ctx: *mut M = &mut *a.mem;
            // SAFETY: the callback gets back the boxed memory's address,
            // which lives (and does not move) as long as the model; it is
            // called only inside the FFI calls below, made through `&mut
            // self`, so no other reference to the memory is live then.
            unsafe {
                ffi::rtl_port_set_dma(a.raw.as_ptr(), Some(dma_write::<M>), ctx.cast());
                ffi::rtl_port_set_dma_read(a.raw.as_ptr(), Some(dma_read::<M>));
            }
            Ok(a)
        }
        #[cfg(not(rtl_verilated))]
        {
            let _ = mem;
            Err(NotBuilt)
        }
    }

    /// Idle clocks after every bus access (the bridge's latency).
    pub fn set_access_cycles(&mut self, cycles: u64) {
        self.access_cycles = cycles;
    }

    /// The memory behind the frame DMA.
    pub fn memory(&self) -> &M {
        &self.mem
    }

    /// The memory behind the frame DMA, mutably.
    pub fn memory_mut(&mut self) -> &mut M {
        &mut self.mem
    }

    /// Clocks simulated since the model was made.
    pub fn cycles(&self) -> u64 {
        #[cfg(rtl_verilated)]
        // SAFETY: a live model (`raw` is freed only on drop).
        return unsafe { ffi::rtl_port_cycles(self.raw.as_ptr()) };
        #[cfg(not(rtl_verilated))]
        0
    }

    /// Assert the reset for two clocks (registers to their reset values).
    pub fn reset(&mut self) {
        #[cfg(rtl_verilated)]
        // SAFETY: a live model; the DMA callback may run, see `with_memory`.
        unsafe {
            ffi::rtl_port_reset(self.raw.as_ptr())
        }
    }

    /// Let `n` clocks pass with the bus idle.
    pub fn step(&mut self, n: u64) {
        self.sync_answering();
        #[cfg(rtl_verilated)]
        // SAFETY: as in `reset`.
        unsafe {
            ffi::rtl_port_step(self.raw.as_ptr(), n)
        }
        #[cfg(not(rtl_verilated))]
        let _ = n;
    }

    /// Whether the AXI port answers follows the memory's
    /// [`DmaTarget::answers`] at every access.
    fn sync_answering(&mut self) {
        #[cfg(rtl_verilated)]
        // SAFETY: a live model; no callback runs in this call.
        unsafe {
            ffi::rtl_port_set_answering(self.raw.as_ptr(), i32::from(self.mem.answers()))
        }
    }

    /// Drive the board's inputs: `keys` held down (bit n: KEYn pressed; the
    /// pins are active low), `switches` (bit n: SWn up). They take effect
    /// on the next clock.
    pub fn set_board_inputs(&mut self, keys: u8, switches: u16) {
        #[cfg(rtl_verilated)]
        // SAFETY: a live model; no callback runs in this call.
        unsafe {
            ffi::rtl_port_set_board_inputs(self.raw.as_ptr(), u32::from(keys), u32::from(switches))
        }
        #[cfg(not(rtl_verilated))]
        let _ = (keys, switches);
    }

    /// The board's output pins: LEDR9..0 (1 = lit) and HEX0..HEX5's
    /// segment pins (bit s = segment s, active low).
    pub fn board_outputs(&mut self) -> (u16, [u8; 6]) {
        // Without the Verilated model: all LEDs dark, all segments off.
        #[allow(unused_mut)]
        let (mut ledr, mut hex_n) = (0u16, [0x7Fu8; 6]);
        #[cfg(rtl_verilated)]
        // SAFETY: a live model; the pointers are to a u16 and six bytes
        // that live across the call; no callback runs in it.
        unsafe {
            ffi::rtl_port_board_outputs(self.raw.as_ptr(), &mut ledr, hex_n.as_mut_ptr())
        }
        (ledr, hex_n)
    }

    /// A 32-bit read at byte `offset` of the bridge window, then the
    /// access's idle clocks.
    pub fn bus_read(&mut self, offset: usize) -> u32 {
        self.sync_answering();
        #[cfg(rtl_verilated)]
        {
            // SAFETY: as in `reset`.
            let v = unsafe { ffi::rtl_port_read(self.raw.as_ptr(), offset as u32) };
            self.step(self.access_cycles);
            v
        }
        #[cfg(not(rtl_verilated))]
        {
            let _ = offset;
            0
        }
    }

    /// A 32-bit write at byte `offset` of the bridge window, then the
    /// access's idle clocks.
    pub fn bus_write(&mut self, offset: usize, value: u32) {
        self.sync_answering();
        #[cfg(rtl_verilated)]
        {
            // SAFETY: as in `reset`.
            unsafe { ffi::rtl_port_write(self.raw.as_ptr(), offset as u32, value) };
            self.step(self.access_cycles);
        }
        #[cfg(not(rtl_verilated))]
        let _ = (offset, value);
    }
}

/// The AXI port's read beats from the Rust memory.
///
/// # Safety
///
/// `ctx` is the `*mut M` that `with_memory` registered and `out..out +
/// len` is writable (the C side's beat buffer).
#[cfg(rtl_verilated)]
unsafe extern "C" fn dma_read<M: DmaTarget>(ctx: *mut core::ffi::c_void, addr: u32, out: *mut u8, len: u32) -> i32 {
    // SAFETY: see the function's contract; the memory is not otherwise
    // borrowed while the model runs (calls go through `&mut self`).
    let (mem, out) = unsafe { (&mut *ctx.cast::<M>(), core::slice::from_raw_parts_mut(out, len as usize)) };
    i32::from(mem.read(addr, out))
}

#[cfg(rtl_verilated)]
unsafe extern "C" fn dma_write<M: DmaTarget>(
    ctx: *mut core::ffi::c_void,
    addr: u32,
    bytes: *const u8,
    len: u32,
) -> i32 {
    // SAFETY: the caller's contract; `len` is at most 8.
    let (mem, bytes) = unsafe { (&mut *ctx.cast::<M>(), core::slice::from_raw_parts(bytes, len as usize)) };
    i32::from(mem.write(addr, bytes))
}

impl<M: DmaTarget> Drop for RtlAccelerator<M> {
    fn drop(&mut self) {
        #[cfg(rtl_verilated)]
        // SAFETY: the model was made by `rtl_port_new` and is freed once.
        unsafe {
            ffi::rtl_port_free(self.raw.as_ptr())
        }
    }
}

impl<M: DmaTarget> RegisterPort for RtlAccelerator<M> {
    fn read(&mut self, csr: Csr) -> u32 {
        self.bus_read(CSR_OFFSET + csr.offset())
    }

    fn write(&mut self, csr: Csr, value: u32) {
        self.bus_write(CSR_OFFSET + csr.offset(), value)
    }

    fn read_line(&mut self, out: &mut [u32; LINE_WORDS]) {
        let single = core::mem::replace(&mut self.access_cycles, LINE_WORD_CYCLES);
        for (x, w) in out.iter_mut().enumerate() {
            *w = self.bus_read(hal_avalon::map::line_word_offset(x));
        }
        self.access_cycles = single;
    }
}
