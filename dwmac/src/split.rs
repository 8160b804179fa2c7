//! Zero-copy transmit of frames in two pieces: a header the CPU builds and
//! a payload the CPU never touches (an RTP row the FPGA wrote to SDRAM).
//!
//! Each frame takes one descriptor with two buffers in ring mode
//! ([`desc::tx_control_split`]): buffer 1 is the descriptor's own transmit
//! buffer, into which the header is copied (its *header slot*); buffer 2 is
//! the caller's bus address, which the DMA reads directly. The CPU reads
//! none of the payload, so the driver neither checksums it nor cleans or
//! invalidates a cache line of it: **the caller owns the payload memory's
//! coherence**. For a row the FPGA wrote through the FPGA-to-SDRAM port the
//! bytes are in SDRAM once the FPGA reports the row done, and the CPU, which
//! never writes them, holds no dirty line that could later overwrite them;
//! memory the CPU wrote through a write-back cache must be cleaned to the
//! point of coherency by the caller before [`Dwmac::send_split`].
//!
//! The payload must stay unchanged until the DMA is done with it. Frames
//! get consecutive [`SplitSeq`] numbers and complete in that order (the DMA
//! walks the ring in order); [`Dwmac::split_done`] says when one and all
//! before it are done, so a frame-ring slot goes back to the FPGA once the
//! sequence number of its last row is.
//!
//! Ring size: [`TX_RING`] descriptors, shared with smoltcp. 32 split frames
//! of 1,502 bytes (62-byte header, 1,440-byte row) are 49 KB, 0.39 ms at
//! 1 Gbit/s, so a 360-row picture needs the main loop to come back about
//! a dozen times: [`Dwmac::send_split`] returns [`SplitError::Full`] rather
//! than wait, and [`Dwmac::tx_free`] says how many frames fit now.

use embedded_hal::delay::DelayNs;

use crate::csum;
use crate::desc::{self, ChecksumInsertion};
use crate::mac::{Dwmac, TxState, MAX_FRAME};
use crate::ring::{BUFFER_SIZE, TX_RING, TX_SKEW};
use crate::sync::DmaSync;

/// Sequence number of a split frame: the n-th one handed to the DMA since
/// the driver was created, counting from 0. Never reused (64 bits: 584,000
/// years at a million frames a second).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct SplitSeq(pub u64);

/// Why [`Dwmac::send_split`] did not take a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitError {
    /// Every transmit descriptor is the DMA's: try again after it has sent
    /// some (the next call reclaims them).
    Full,
    /// Header and payload together exceed [`MAX_FRAME`] bytes, or the
    /// header is shorter than an Ethernet header (14 bytes).
    Length,
}

/// Shortest header: destination, source, EtherType (IEEE 802.3 3.1.1).
const MIN_HEADER: usize = 14;

/// The length of a split frame of these parts, if it has an Ethernet
/// header and fits a frame.
fn split_len(header_len: usize, payload_len: usize) -> Result<usize, SplitError> {
    let len = header_len.checked_add(payload_len).ok_or(SplitError::Length)?;
    if header_len < MIN_HEADER || len > MAX_FRAME {
        return Err(SplitError::Length);
    }
    Ok(len)
}

// A header slot is the rest of a transmit buffer; it holds any header a
// frame of MAX_FRAME bytes can have.
const _: () = assert!(MAX_FRAME <= BUFFER_SIZE - TX_SKEW);

impl<S: DmaSync, D: DelayNs> Dwmac<'_, S, D> {
    /// Send one frame made of `header` (Ethernet header on; copied into
    /// the descriptor's header slot) followed by `payload_len` bytes the DMA
    /// reads from bus address `payload` (any byte alignment). The CPU never
    /// reads the payload: see the [module documentation](self) for who
    /// keeps that memory coherent and unchanged until [`split_done`].
    ///
    /// Checksums: for a UDP or TCP over IPv4 header the descriptor asks the
    /// MAC for the IPv4 header checksum and the UDP/TCP checksum with the
    /// pseudo-header (CIC 3, [`crate::csum`]), computed over header and
    /// payload as they leave; the fields' contents do not matter. Without
    /// the engine ([`Dwmac::checksum_insertion`] is `Off`) nothing is
    /// inserted: the caller fills in the IPv4 header checksum and sets the
    /// UDP checksum to 0, "no checksum" (RFC 768).
    ///
    /// [`split_done`]: Dwmac::split_done
    pub fn send_split(&mut self, header: &[u8], payload: u32, payload_len: usize) -> Result<SplitSeq, SplitError> {
        let i = self.split_slot(header.len(), payload_len)?;
        let slot = self.shared.area.tx_buffer(i);
        // SAFETY: the CPU owns descriptor `i` and its buffer until
        // `hand_over` sets OWN (`split_slot` saw OWN clear, then a dmb),
        // and this is the only slice of the buffer.
        unsafe { slot.bytes_mut(TX_SKEW, header.len()) }.copy_from_slice(header);
        let cic = csum::for_frame(header, self.shared.csum);
        Ok(self.split_hand_over(i, header.len(), cic, payload, payload_len))
    }

    /// [`send_split`](Self::send_split) with the header given as the words
    /// of the transmit buffer from its start: their bytes in memory are
    /// [`TX_SKEW`] bytes of padding, then the header (`4 * words.len() -
    /// TX_SKEW` bytes), copied into the header slot as words. `cic` is the
    /// checksum insertion the frame takes, [`Dwmac::checksum_for`] its
    /// header: a sender of many frames of one header layout (an RTP
    /// stream's rows) works it out once instead of per frame.
    pub fn send_split_words(
        &mut self,
        words: &[u32],
        cic: ChecksumInsertion,
        payload: u32,
        payload_len: usize,
    ) -> Result<SplitSeq, SplitError> {
        let header_len = (words.len() * 4).checked_sub(TX_SKEW).ok_or(SplitError::Length)?;
        let i = self.split_slot(header_len, payload_len)?;
        let slot = self.shared.area.tx_buffer(i);
        // SAFETY: as in `send_split`.
        unsafe { slot.words_mut(words.len()) }.copy_from_slice(words);
        Ok(self.split_hand_over(i, header_len, cic, payload, payload_len))
    }

    /// Send a run of up to `count` split frames with one header layout:
    /// frame `k`'s header is what `fill(k, words)` writes into its header
    /// slot (the transmit buffer's first `header_words` words: [`TX_SKEW`]
    /// bytes of padding, then the header), its payload the `payload_len`
    /// bytes at `payload + k * stride`. One descriptor and one poll demand
    /// a frame, as [`send_split_words`](Self::send_split_words); the
    /// lengths are checked, the control words made and the counters kept
    /// once a run. Stops where the ring is full; returns how many went and
    /// the last one's sequence number.
    #[allow(clippy::too_many_arguments)] // one run, every part of it
    pub fn send_split_run(
        &mut self,
        count: usize,
        header_words: usize,
        cic: ChecksumInsertion,
        payload: u32,
        stride: u32,
        payload_len: usize,
        mut fill: impl FnMut(usize, &mut [u32]),
    ) -> Result<(usize, Option<SplitSeq>), SplitError> {
        let header_len = (header_words * 4).checked_sub(TX_SKEW).ok_or(SplitError::Length)?;
        split_len(header_len, payload_len)?;
        let (shared, tx) = (&self.shared, &mut self.tx);
        if tx.pending + count > TX_RING {
            tx.reclaim(shared);
        }
        let n = count.min(TX_RING - tx.pending);
        if n == 0 {
            if count > 0 {
                tx.split_full = tx.split_full.wrapping_add(1);
            }
            return Ok((0, None));
        }
        let control = desc::tx_control_split(shared.format, header_len, payload_len, false, cic);
        let last = desc::tx_control_split(shared.format, header_len, payload_len, true, cic);
        let control_of = |i: usize| if i == TX_RING - 1 { last } else { control };
        let first = tx.next;
        // Every header and TDES1..3 of the run first, then one drain, then
        // OWN in ring order: the DMA, maybe still walking the ring, can
        // never find OWN before the rest of its descriptor is in memory
        // (crate::sync).
        for k in 0..n {
            let i = (first + k) % TX_RING;
            let slot = shared.area.tx_buffer(i);
            // SAFETY: descriptor `i` is outside the pending ones (at most
            // `TX_RING - pending` are taken here), so the CPU owns it and
            // its buffer (OWN seen clear, then a dmb, when it was
            // reclaimed) until it is given below; this is the only slice.
            fill(k, unsafe { slot.words_mut(header_words) });
            let buf2 = payload.wrapping_add((k as u32).wrapping_mul(stride));
            tx.prepare(shared, i, control_of(i)[1], slot.bus_address() + TX_SKEW as u32, buf2, true);
        }
        shared.publish();
        // One poll demand a descriptor, each after its OWN is in memory:
        // QEMU up to 10.0.2 sends a wrong second frame when one poll finds
        // two (docs/streaming.md).
        for k in 0..n {
            let i = (first + k) % TX_RING;
            TxState::give(shared, i, control_of(i)[0]);
        }
        tx.next = (first + n) % TX_RING;
        tx.count_split(n, header_len, payload_len);
        Ok((n, Some(SplitSeq(tx.split_sent - 1))))
    }

    /// The checksum insertion a frame with this header takes ([`csum`]):
    /// what [`send_split`](Self::send_split) asks for, and what
    /// [`send_split_words`](Self::send_split_words) is told.
    pub fn checksum_for(&self, header: &[u8]) -> ChecksumInsertion {
        csum::for_frame(header, self.shared.csum)
    }

    /// The descriptor a split frame of these lengths goes into, if the
    /// lengths are right and the CPU owns it (OWN seen clear, then a dmb).
    fn split_slot(&mut self, header_len: usize, payload_len: usize) -> Result<usize, SplitError> {
        split_len(header_len, payload_len)?;
        let (shared, tx) = (&self.shared, &mut self.tx);
        if !tx.free(shared) {
            tx.split_full = tx.split_full.wrapping_add(1);
            return Err(SplitError::Full);
        }
        Ok(tx.next)
    }

    /// Hand descriptor `i`, its header slot filled, to the DMA with the
    /// payload as buffer 2.
    fn split_hand_over(
        &mut self,
        i: usize,
        header_len: usize,
        cic: ChecksumInsertion,
        payload: u32,
        payload_len: usize,
    ) -> SplitSeq {
        let (shared, tx) = (&self.shared, &mut self.tx);
        let control = desc::tx_control_split(shared.format, header_len, payload_len, i == TX_RING - 1, cic);
        let slot = shared.area.tx_buffer(i);
        tx.hand_over_descriptor(shared, control, slot.bus_address() + TX_SKEW as u32, payload, true);
        tx.count_split(1, header_len, payload_len);
        SplitSeq(tx.split_sent - 1)
    }

    /// Take back the descriptors the DMA has finished with; returns how
    /// many split frames that completed. The calls below do it too, and a
    /// send does when the ring looks full.
    pub fn tx_reclaim(&mut self) -> usize {
        self.tx.reclaim(&self.shared)
    }

    /// Whether the DMA is done with split frame `seq` and every one before
    /// it: their payload memory may change.
    pub fn split_done(&mut self, seq: SplitSeq) -> bool {
        seq < self.split_completed()
    }

    /// The first split frame the DMA may still read: every [`SplitSeq`]
    /// below it is done (reclaims first).
    pub fn split_completed(&mut self) -> SplitSeq {
        self.tx.reclaim(&self.shared);
        SplitSeq(self.tx.split_done)
    }

    /// Split frames the DMA may still read (reclaims first).
    pub fn split_in_flight(&mut self) -> usize {
        self.tx.reclaim(&self.shared);
        // At most TX_RING: every one holds a pending descriptor.
        self.tx.split.iter().filter(|s| **s).count()
    }

    /// Transmit descriptors handed to the DMA and not yet done, split or
    /// not (reclaims first).
    pub fn tx_in_flight(&mut self) -> usize {
        self.tx.reclaim(&self.shared);
        self.tx.pending
    }

    /// Frames that fit into the transmit ring now (reclaims first).
    pub fn tx_free(&mut self) -> usize {
        TX_RING - self.tx_in_flight()
    }
}
