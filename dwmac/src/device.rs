//! smoltcp [`Device`] for [`Dwmac`]: receive and transmit tokens that each
//! borrow one descriptor.
//!
//! * `transmit` returns `None` while every TX descriptor belongs to the MAC:
//!   smoltcp then keeps the segment and tries again on the next poll, where a
//!   silent drop would cost a TCP retransmission time-out.
//! * `receive` returns `None` unless a received frame *and* a free TX
//!   descriptor exist, so an answer (an ACK) never finds the ring full.
//! * Checksums: with the MAC inserting them, smoltcp computes IPv4, TCP and
//!   UDP checksums only on receive and writes 0 into the fields it leaves
//!   to the MAC (smoltcp 0.14 `src/wire/tcp.rs`, `ipv4.rs`:
//!   `set_checksum(0)`); ICMP stays in software because QEMU's model does
//!   not insert it. Each frame's descriptor asks for what that frame needs
//!   ([`crate::csum`]): CIC 3 for TCP/UDP, 1 (IPv4 header only) for ICMP,
//!   whose filled-in checksum CIC 3 would corrupt, 0 for ARP.

use embedded_hal::delay::DelayNs;
use smoltcp::phy::{Checksum, ChecksumCapabilities, Device, DeviceCapabilities, Medium};
use smoltcp::time::Instant;

use crate::csum;
use crate::desc::{self, ChecksumInsertion, RxStatus, OWN};
use crate::mac::{Dwmac, RxState, Shared, TxState, MAX_FRAME};
use crate::regs::DmaStatus;
use crate::ring::{BUFFER_SIZE, RX_RING, TX_RING, TX_SKEW};
use crate::sync::DmaSync;

impl RxState {
    /// Length of the complete good frame at `next`, dropping bad or split
    /// frames on the way; `None` while the DMA has nothing new.
    fn ready<S: DmaSync>(&mut self, shared: &Shared<'_, S>) -> Option<usize> {
        // Each pass either returns or recycles one descriptor: bounded.
        for _ in 0..RX_RING {
            // One snapshot of the status word per look.
            let status = desc::rx_status(shared.area.rx_descriptor(self.next).word(0));
            match status {
                RxStatus::Dma => return None,
                RxStatus::Frame { len } if len <= MAX_FRAME => {
                    // OWN seen clear: order the buffer reads after it.
                    shared.sync.dmb();
                    return Some(len);
                }
                RxStatus::Incomplete => {
                    // QEMU clears OWN before it sets LS: wait, unless the DMA
                    // has moved on to the next descriptor (a frame split
                    // over several descriptors, which the driver drops).
                    let after = (self.next + 1) % RX_RING;
                    if shared.area.rx_descriptor(after).word(0) & OWN != 0 {
                        return None;
                    }
                    self.dropped = self.dropped.wrapping_add(1);
                    self.recycle(shared);
                }
                RxStatus::Frame { .. } | RxStatus::Bad => {
                    self.dropped = self.dropped.wrapping_add(1);
                    self.recycle(shared);
                }
            }
        }
        None
    }

    /// Give the descriptor at `next` back to the DMA and advance.
    fn recycle<S: DmaSync>(&mut self, shared: &Shared<'_, S>) {
        // The CPU's reads of the buffer complete before the DMA may refill it.
        shared.sync.dmb();
        shared.area.rx_descriptor(self.next).set_word(0, OWN);
        shared.publish();
        self.next = (self.next + 1) % RX_RING;
        // Receive may have stopped for want of descriptors: clear RU (which
        // restarts QEMU's receive) and demand a poll (the board's).
        let regs = &shared.regs;
        if regs.dma().status.read().ru() {
            regs.clear_status(DmaStatus::DEFAULT.with_ru(true));
        }
        regs.rx_poll_demand();
    }
}

impl TxState {
    /// Take back every descriptor the DMA has finished with (OWN clear),
    /// oldest first; returns how many split frames that completed. Reads
    /// at most `pending` descriptor words.
    #[inline]
    pub(crate) fn reclaim<S: DmaSync>(&mut self, shared: &Shared<'_, S>) -> usize {
        let mut taken = 0;
        let mut split = 0;
        while self.pending > 0 && shared.area.tx_descriptor(self.dirty).word(0) & OWN == 0 {
            if core::mem::take(&mut self.split[self.dirty]) {
                self.split_done += 1;
                split += 1;
            }
            self.dirty = (self.dirty + 1) % TX_RING;
            self.pending -= 1;
            taken += 1;
        }
        if taken > 0 {
            // OWN seen clear: whatever the caller does next (refill the
            // buffer, let the FPGA overwrite a payload) comes after it.
            shared.sync.dmb();
        }
        split
    }

    /// Whether the descriptor at `next` is the CPU's. Reclaims only when
    /// the ring looks full: a descriptor outside the `pending` ones was
    /// reclaimed before (OWN seen clear, then a dmb) or never handed over,
    /// so the common case reads no descriptor word. Completions are taken
    /// in when the ring fills or a caller asks ([`Dwmac::split_completed`],
    /// [`Dwmac::tx_reclaim`]).
    ///
    /// [`Dwmac::split_completed`]: crate::Dwmac::split_completed
    /// [`Dwmac::tx_reclaim`]: crate::Dwmac::tx_reclaim
    #[inline(always)]
    pub(crate) fn free<S: DmaSync>(&mut self, shared: &Shared<'_, S>) -> bool {
        if self.pending < TX_RING {
            return true;
        }
        self.reclaim(shared);
        self.pending < TX_RING
    }

    /// Fill the descriptor at `next` with a frame of `len` bytes built by
    /// `f` and hand it to the DMA.
    fn send<S: DmaSync, R>(&mut self, shared: &Shared<'_, S>, len: usize, f: impl FnOnce(&mut [u8]) -> R) -> R {
        let i = self.next;
        let len = len.min(BUFFER_SIZE - TX_SKEW);
        let buffer = shared.area.tx_buffer(i);
        // OWN was seen clear (`free`): the MAC is done with the buffer.
        shared.sync.dmb();
        // SAFETY: the CPU owns descriptor `i` and its buffer until OWN is set
        // below, and this is the only slice of the buffer.
        let frame = unsafe { buffer.bytes_mut(TX_SKEW, len) };
        let r = f(&mut *frame);
        // Checksum insertion for this frame's protocol (crate::csum): never
        // CIC 3 over a checksum the stack filled in (ICMP).
        let cic = csum::for_frame(frame, shared.csum);
        let control = desc::tx_control(shared.format, len, i == TX_RING - 1, cic);
        self.hand_over(shared, control, buffer.bus_address() + TX_SKEW as u32, 0, false);
        self.bytes = self.bytes.wrapping_add(len as u64);
        r
    }

    /// Write the descriptor at `next` (`control` = TDES0 without OWN and
    /// TDES1, buffer addresses `buf1` and `buf2`), give it to the DMA and
    /// demand a poll. The caller has filled the buffers the CPU writes.
    #[inline(always)]
    pub(crate) fn hand_over<S: DmaSync>(
        &mut self,
        shared: &Shared<'_, S>,
        control: [u32; 2],
        buf1: u32,
        buf2: u32,
        split: bool,
    ) {
        self.hand_over_descriptor(shared, control, buf1, buf2, split);
        self.pending += 1;
        self.frames = self.frames.wrapping_add(1);
    }

    /// Count `n` split frames just handed over
    /// ([`hand_over_descriptor`](Self::hand_over_descriptor)), each of
    /// `header_len` + `payload_len` bytes.
    #[inline(always)]
    pub(crate) fn count_split(&mut self, n: usize, header_len: usize, payload_len: usize) {
        self.pending += n;
        self.frames = self.frames.wrapping_add(n as u32);
        self.split_sent += n as u64;
        self.split_frames = self.split_frames.wrapping_add(n as u32);
        self.split_payload_bytes = self.split_payload_bytes.wrapping_add((n * payload_len) as u64);
        self.bytes = self.bytes.wrapping_add((n * (header_len + payload_len)) as u64);
    }

    /// [`hand_over`](Self::hand_over) without the counts (`pending`,
    /// `frames`): a caller handing over a run counts it once.
    #[inline(always)]
    pub(crate) fn hand_over_descriptor<S: DmaSync>(
        &mut self,
        shared: &Shared<'_, S>,
        [tdes0, tdes1]: [u32; 2],
        buf1: u32,
        buf2: u32,
        split: bool,
    ) {
        let i = self.next;
        self.prepare(shared, i, tdes1, buf1, buf2, split);
        // Buffer and TDES1..3 in memory before OWN can be (crate::sync).
        shared.publish();
        Self::give(shared, i, tdes0);
        self.next = (i + 1) % TX_RING;
    }

    /// Write descriptor `i`'s TDES1..3; OWN stays clear. The caller owns
    /// the descriptor and has filled the buffers the CPU writes; until a
    /// [`Shared::publish`] these writes may still sit in a store buffer.
    #[inline(always)]
    pub(crate) fn prepare<S: DmaSync>(
        &mut self,
        shared: &Shared<'_, S>,
        i: usize,
        tdes1: u32,
        buf1: u32,
        buf2: u32,
        split: bool,
    ) {
        let desc = shared.area.tx_descriptor(i);
        desc.set_word(1, tdes1);
        desc.set_word(2, buf1);
        desc.set_word(3, buf2);
        self.split[i] = split;
    }

    /// Give prepared descriptor `i` to the DMA: TDES0 with OWN, drained to
    /// memory, then a poll demand. The caller has [published](Shared::publish)
    /// the descriptor's other words and buffers since it wrote them.
    #[inline(always)]
    pub(crate) fn give<S: DmaSync>(shared: &Shared<'_, S>, i: usize, tdes0: u32) {
        shared.area.tx_descriptor(i).set_word(0, tdes0 | OWN);
        shared.publish();
        shared.regs.tx_poll_demand();
    }
}

/// A received frame, borrowed from the receive ring until consumed.
pub struct DwmacRxToken<'b, 'a, S> {
    shared: &'b Shared<'a, S>,
    rx: &'b mut RxState,
    len: usize,
}

/// Room for one frame in the transmit ring.
pub struct DwmacTxToken<'b, 'a, S> {
    shared: &'b Shared<'a, S>,
    tx: &'b mut TxState,
}

impl<S: DmaSync> smoltcp::phy::RxToken for DwmacRxToken<'_, '_, S> {
    fn consume<R, F: FnOnce(&[u8]) -> R>(self, f: F) -> R {
        let buffer = self.shared.area.rx_buffer(self.rx.next);
        // SAFETY: `ready` saw OWN clear (then a dmb): the CPU owns the buffer
        // until `recycle` below hands it back; no mutable slice exists.
        let r = f(unsafe { buffer.bytes(self.len) });
        self.rx.frames = self.rx.frames.wrapping_add(1);
        self.rx.bytes = self.rx.bytes.wrapping_add(self.len as u64);
        self.rx.recycle(self.shared);
        r
    }
}

impl<S: DmaSync> smoltcp::phy::TxToken for DwmacTxToken<'_, '_, S> {
    fn consume<R, F: FnOnce(&mut [u8]) -> R>(self, len: usize, f: F) -> R {
        self.tx.send(self.shared, len, f)
    }
}

impl<'a, S: DmaSync, D: DelayNs> Device for Dwmac<'a, S, D> {
    type RxToken<'b>
        = DwmacRxToken<'b, 'a, S>
    where
        Self: 'b;
    type TxToken<'b>
        = DwmacTxToken<'b, 'a, S>
    where
        Self: 'b;

    fn receive(&mut self, _timestamp: Instant) -> Option<(Self::RxToken<'_>, Self::TxToken<'_>)> {
        // A frame waits in the ring until there is room to answer it.
        if !self.tx.free(&self.shared) {
            return None;
        }
        let len = self.rx.ready(&self.shared)?;
        Some((
            DwmacRxToken { shared: &self.shared, rx: &mut self.rx, len },
            DwmacTxToken { shared: &self.shared, tx: &mut self.tx },
        ))
    }

    fn transmit(&mut self, _timestamp: Instant) -> Option<Self::TxToken<'_>> {
        if !self.tx.free(&self.shared) {
            self.tx.ring_full = self.tx.ring_full.wrapping_add(1);
            return None;
        }
        Some(DwmacTxToken { shared: &self.shared, tx: &mut self.tx })
    }

    fn capabilities(&self) -> DeviceCapabilities {
        let mut caps = DeviceCapabilities::default();
        caps.medium = Medium::Ethernet;
        caps.max_transmission_unit = MAX_FRAME;
        caps.max_burst_size = Some(TX_RING);
        caps.checksum = checksum_capabilities(self.shared.csum);
        caps
    }
}

/// What smoltcp must compute itself, given what the MAC inserts.
pub fn checksum_capabilities(csum: ChecksumInsertion) -> ChecksumCapabilities {
    let mut caps = ChecksumCapabilities::default();
    if csum == ChecksumInsertion::Full {
        caps.ipv4 = Checksum::Rx;
        caps.tcp = Checksum::Rx;
        caps.udp = Checksum::Rx;
        // ICMP: QEMU's model does not insert it (npcm_gmac.c).
        caps.icmpv4 = Checksum::Both;
    }
    caps
}
