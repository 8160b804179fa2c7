//! smoltcp [`Device`] for [`Dwmac`]: receive and transmit tokens borrowing
//! one descriptor each.

use smoltcp::phy::{Device, DeviceCapabilities, Medium};
use smoltcp::time::Instant;

use super::desc::{self, DescFormat, RxStatus, OWN};
use super::regs::{DMA_RX_POLL, DMA_STATUS, DMA_TX_POLL, STATUS_RU};
use super::{bus_addr, Dwmac, RxRing, TxRing, BUFFER_SIZE, MAX_FRAME, RX_RING, TX_RING};
use crate::arch::dsb;
use crate::drivers::mmio::Mmio;

impl RxRing<'_> {
    /// Length of the complete good frame at `next`, dropping bad or split
    /// frames on the way; `None` while the DMA has nothing new.
    fn ready(&mut self, regs: Mmio) -> Option<usize> {
        // Each pass either returns or recycles one descriptor: bounded.
        for _ in 0..RX_RING {
            let status = desc::rx_status(self.desc[self.next].read(0));
            match status {
                RxStatus::Dma => return None,
                RxStatus::Frame { len } if len <= MAX_FRAME => return Some(len),
                RxStatus::Incomplete => {
                    // QEMU clears OWN before it sets LS: wait, unless the DMA
                    // has moved on to the next descriptor (a frame split
                    // over several descriptors, which the driver drops).
                    let after = (self.next + 1) % RX_RING;
                    if self.desc[after].read(0) & OWN != 0 {
                        return None;
                    }
                    self.dropped += 1;
                    self.recycle(regs);
                }
                RxStatus::Frame { .. } | RxStatus::Bad => {
                    self.dropped += 1;
                    self.recycle(regs);
                }
            }
        }
        None
    }

    /// Give the descriptor at `next` back to the DMA and advance.
    fn recycle(&mut self, regs: Mmio) {
        dsb();
        self.desc[self.next].write(0, OWN);
        dsb();
        self.next = (self.next + 1) % RX_RING;
        // Receive may have stopped for want of descriptors: clear RU (which
        // restarts QEMU's receive) and demand a poll (the board's).
        if regs.read(DMA_STATUS) & STATUS_RU != 0 {
            regs.write(DMA_STATUS, STATUS_RU);
        }
        regs.write(DMA_RX_POLL, 0);
    }
}

impl TxRing<'_> {
    fn free(&self) -> bool {
        self.desc[self.next].read(0) & OWN == 0
    }

    /// Fill the descriptor at `next` with a frame of `len` bytes built by
    /// `f` and hand it to the DMA.
    fn send<R>(&mut self, regs: Mmio, format: DescFormat, len: usize, f: impl FnOnce(&mut [u8]) -> R) -> R {
        let i = self.next;
        let len = len.min(BUFFER_SIZE);
        let r = f(&mut self.buf[i].0[..len]);
        let [tdes0, tdes1] = desc::tx_control(format, len, i == TX_RING - 1);
        let d = &mut self.desc[i];
        d.write(1, tdes1);
        d.write(2, bus_addr(&self.buf[i]));
        d.write(3, 0);
        // Buffer and control words before OWN; OWN before the poll demand.
        dsb();
        d.write(0, tdes0 | OWN);
        dsb();
        regs.write(DMA_TX_POLL, 0);
        self.next = (i + 1) % TX_RING;
        r
    }
}

/// A received frame, borrowed from the receive ring until consumed.
pub struct DwmacRxToken<'b, 'a> {
    ring: &'b mut RxRing<'a>,
    regs: Mmio,
    len: usize,
}

/// Room for one frame in the transmit ring.
pub struct DwmacTxToken<'b, 'a> {
    ring: &'b mut TxRing<'a>,
    regs: Mmio,
    format: DescFormat,
}

impl smoltcp::phy::RxToken for DwmacRxToken<'_, '_> {
    fn consume<R, F: FnOnce(&[u8]) -> R>(self, f: F) -> R {
        let i = self.ring.next;
        let r = f(&self.ring.buf[i].0[..self.len]);
        self.ring.frames += 1;
        self.ring.recycle(self.regs);
        r
    }
}

impl smoltcp::phy::TxToken for DwmacTxToken<'_, '_> {
    fn consume<R, F: FnOnce(&mut [u8]) -> R>(self, len: usize, f: F) -> R {
        self.ring.frames += 1;
        self.ring.send(self.regs, self.format, len, f)
    }
}

impl<'a> Device for Dwmac<'a> {
    type RxToken<'b>
        = DwmacRxToken<'b, 'a>
    where
        Self: 'b;
    type TxToken<'b>
        = DwmacTxToken<'b, 'a>
    where
        Self: 'b;

    fn receive(&mut self, _timestamp: Instant) -> Option<(Self::RxToken<'_>, Self::TxToken<'_>)> {
        // A frame waits in the ring until there is room to answer it.
        if !self.tx.free() {
            return None;
        }
        let len = self.rx.ready(self.regs)?;
        Some((
            DwmacRxToken { ring: &mut self.rx, regs: self.regs, len },
            DwmacTxToken { ring: &mut self.tx, regs: self.regs, format: self.format },
        ))
    }

    fn transmit(&mut self, _timestamp: Instant) -> Option<Self::TxToken<'_>> {
        if !self.tx.free() {
            return None;
        }
        Some(DwmacTxToken { ring: &mut self.tx, regs: self.regs, format: self.format })
    }

    fn capabilities(&self) -> DeviceCapabilities {
        let mut caps = DeviceCapabilities::default();
        caps.medium = Medium::Ethernet;
        caps.max_transmission_unit = MAX_FRAME;
        caps.max_burst_size = Some(TX_RING);
        caps
    }
}
