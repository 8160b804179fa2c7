//! Descriptors and buffers: memory the CPU and the MAC's DMA share.
//!
//! While the MAC owns a descriptor (OWN set) it may write the descriptor and
//! its buffer at any time, so nothing here ever holds a `&mut` to either:
//! descriptor words are volatile cells, buffers are `UnsafeCell`s reached
//! through raw pointers, and a slice of a buffer exists only while the CPU
//! owns it (OWN observed clear, then a `dmb`; see [`crate::sync`]).

use core::cell::UnsafeCell;

use vcell::VolatileCell;

/// Receive descriptors: room for a burst of 24 clients connecting at once
/// (SYN, ACK and request each, 72 frames) while the main loop renders;
/// with 64 the burst overflowed the ring, and QEMU's slirp, retransmitting
/// after a backed-off timeout, lost requests past the server's 5 s idle
/// limit. (Linux stmmac's default is 512, `DMA_DEFAULT_RX_SIZE` in
/// `drivers/net/ethernet/stmicro/stmmac/common.h`.)
pub const RX_RING: usize = 128;
/// Transmit descriptors.
pub const TX_RING: usize = 32;
/// Bytes per buffer: a whole Ethernet frame (1514) plus FCS, rounded up to
/// a multiple of the bus width; fits both formats' buffer-1 size fields.
pub const BUFFER_SIZE: usize = 1536;

/// Where a transmitted frame starts in its buffer: two bytes in, so that
/// behind the 14-byte Ethernet header the IP header and a TCP segment's
/// payload (54 bytes in) are word aligned and smoltcp's payload copy takes
/// the word-by-word path instead of the shifting one (the `NET_IP_ALIGN`
/// idea of Linux, on transmit). The DMA takes transmit buffers at any byte
/// address (Stratix 10 HPS TRM, the same Synopsys GMAC: "Host Data Buffer
/// Alignment"; Linux `stmmac_xmit` maps `skb->data` as it is).
pub const TX_SKEW: usize = 2;

const _: () = assert!(BUFFER_SIZE <= crate::desc::DescFormat::Normal.max_buffer());
const _: () = assert!(1514 + TX_SKEW <= BUFFER_SIZE);
const _: () = assert!(BUFFER_SIZE.is_multiple_of(8));

/// One 4-word DMA descriptor (bus mode ATDS off: 16 bytes, contiguous).
#[repr(C, align(16))]
pub struct Descriptor {
    words: [VolatileCell<u32>; 4],
}

impl Descriptor {
    /// A zeroed descriptor.
    pub const fn new() -> Descriptor {
        Descriptor { words: [const { VolatileCell::new(0) }; 4] }
    }

    /// Word `i` (0..4), one volatile read.
    #[inline]
    pub fn word(&self, i: usize) -> u32 {
        self.words[i].get()
    }

    /// Write word `i` (0..4), one volatile write.
    #[inline]
    pub fn set_word(&self, i: usize, value: u32) {
        self.words[i].set(value)
    }

    /// The four words, read once each (diagnostics and tests).
    pub fn words(&self) -> [u32; 4] {
        [self.word(0), self.word(1), self.word(2), self.word(3)]
    }
}

impl Default for Descriptor {
    fn default() -> Self {
        Descriptor::new()
    }
}

/// One frame buffer.
#[repr(C, align(32))]
pub struct Buffer(UnsafeCell<[u8; BUFFER_SIZE]>);

impl Buffer {
    /// A zeroed buffer.
    pub const fn new() -> Buffer {
        Buffer(UnsafeCell::new([0; BUFFER_SIZE]))
    }

    /// Bus address of the buffer (the firmware runs identity-mapped).
    pub fn bus_address(&self) -> u32 {
        self.0.get() as usize as u32
    }

    /// The first `len` bytes (at most [`BUFFER_SIZE`]).
    ///
    /// # Safety
    ///
    /// The CPU owns the buffer (its descriptor's OWN was seen clear, followed
    /// by a `dmb`) for as long as the slice lives, and no mutable slice of it
    /// exists.
    pub unsafe fn bytes(&self, len: usize) -> &[u8] {
        // SAFETY: the caller guarantees the DMA does not write the buffer
        // while the slice lives and that no `&mut` aliases it.
        unsafe { core::slice::from_raw_parts(self.0.get().cast::<u8>(), len.min(BUFFER_SIZE)) }
    }

    /// `len` bytes from byte `skew` on (at most to the end), writable.
    ///
    /// # Safety
    ///
    /// As [`Buffer::bytes`], and no other slice of the buffer exists.
    #[allow(clippy::mut_from_ref)] // interior mutability: the CPU owns the buffer
    pub unsafe fn bytes_mut(&self, skew: usize, len: usize) -> &mut [u8] {
        let skew = skew.min(BUFFER_SIZE);
        let len = len.min(BUFFER_SIZE - skew);
        // SAFETY: as in `bytes`; the caller also excludes every other slice;
        // `skew + len` stays within the buffer.
        unsafe { core::slice::from_raw_parts_mut(self.0.get().cast::<u8>().add(skew), len) }
    }

    /// The first `count` words (at most the buffer's), writable: the
    /// buffer is word aligned.
    ///
    /// # Safety
    ///
    /// As [`Buffer::bytes_mut`].
    #[allow(clippy::mut_from_ref)] // interior mutability: the CPU owns the buffer
    pub unsafe fn words_mut(&self, count: usize) -> &mut [u32] {
        let count = count.min(BUFFER_SIZE / 4);
        // SAFETY: as in `bytes_mut`; the buffer is 32-byte aligned
        // (`repr(align(32))`) and `count` words stay within it.
        unsafe { core::slice::from_raw_parts_mut(self.0.get().cast::<u32>(), count) }
    }
}

impl Default for Buffer {
    fn default() -> Self {
        Buffer::new()
    }
}

/// Everything the MAC's DMA reads or writes: both descriptor rings and all
/// buffers. Place it in memory the CPU maps Normal non-cacheable (the
/// firmware's `.dma` section).
#[repr(C, align(64))]
pub struct DmaArea {
    pub(crate) rx_desc: [Descriptor; RX_RING],
    pub(crate) tx_desc: [Descriptor; TX_RING],
    pub(crate) rx_buf: [Buffer; RX_RING],
    pub(crate) tx_buf: [Buffer; TX_RING],
}

impl DmaArea {
    /// A zeroed area (for a host test; the firmware zeroes its static).
    pub const fn new() -> DmaArea {
        DmaArea {
            rx_desc: [const { Descriptor::new() }; RX_RING],
            tx_desc: [const { Descriptor::new() }; TX_RING],
            rx_buf: [const { Buffer::new() }; RX_RING],
            tx_buf: [const { Buffer::new() }; TX_RING],
        }
    }

    /// Receive descriptor `i`.
    pub fn rx_descriptor(&self, i: usize) -> &Descriptor {
        &self.rx_desc[i % RX_RING]
    }

    /// Transmit descriptor `i`.
    pub fn tx_descriptor(&self, i: usize) -> &Descriptor {
        &self.tx_desc[i % TX_RING]
    }

    /// Receive buffer `i`.
    pub fn rx_buffer(&self, i: usize) -> &Buffer {
        &self.rx_buf[i % RX_RING]
    }

    /// Transmit buffer `i`.
    pub fn tx_buffer(&self, i: usize) -> &Buffer {
        &self.tx_buf[i % TX_RING]
    }
}

impl Default for DmaArea {
    fn default() -> Self {
        DmaArea::new()
    }
}
