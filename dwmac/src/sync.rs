//! What the CPU must do so that the MAC's DMA and the CPU agree on memory.
//!
//! The rings live in memory the CPU maps Normal non-cacheable, which on the
//! Cortex-A9 is still *bufferable*: a store may sit in the CPU's store buffer
//! or, with an L2C-310 outer cache, in the L2C's, after the instruction that
//! made it. The L2C-310 drains its store buffer's slots by its own rules,
//! not in program order (a full slot first, else the least recently used;
//! Zynq-7000 TRM UG585 "Store Buffer Operation", after ARM's L2C-310 TRM),
//! and a `dsb` completes once a store has reached that buffer, not memory.
//! Handing a descriptor to the MAC therefore takes, in this order:
//!
//! 1. the buffer and the descriptor's other words, then `dsb`, an outer
//!    cache sync (L2C-310 register 0x730, which completes when every buffer
//!    is empty) and `dsb`: they are in memory before
//! 2. the word with OWN, then the same drain, so the OWN store has left
//!    every buffer before
//! 3. the poll-demand register write.
//!
//! Without the first drain the DMA, still walking the ring from earlier
//! descriptors, could read OWN from memory before the header or buffer
//! address it guards. A run of descriptors fills them all and drains once
//! before the first OWN ([`Dwmac::send_split_run`]).
//!
//! [`Dwmac::send_split_run`]: crate::Dwmac::send_split_run
//!
//! Linux on this SoC: `wmb()` is `dsb(st)` followed by `outer_sync()` when
//! an outer cache is configured (`arch/arm/include/asm/barrier.h`), and the
//! stmmac driver issues one between setting OWN and the poll demand
//! (`drivers/net/ethernet/stmicro/stmmac/stmmac_main.c`, `stmmac_xmit`);
//! step 1 comes from its packet data being cacheable and cleaned by the
//! streaming DMA API, whose L2 clean ends in a cache sync.
//! Taking a descriptor back is the reverse: see OWN clear, `dmb`, then read
//! the length and the buffer (ARM ARM DDI 0406C A3.8.3: a `dmb` orders the
//! two reads; without it the buffer read may be satisfied before the OWN
//! read).

/// The CPU barriers and cache operation the driver orders its DMA
/// hand-overs with. The board implements it (on the Cortex-A9 with
/// `aarch32_cpu::asm` and the L2C-310); host tests record the calls.
pub trait DmaSync {
    /// Data synchronisation barrier: every earlier memory access completes
    /// before any later instruction executes.
    fn dsb(&self);

    /// Data memory barrier: earlier memory accesses are observed before
    /// later ones.
    fn dmb(&self);

    /// Drain the outer cache's store buffer (L2C-310 cache sync); nothing
    /// where there is no outer cache.
    fn outer_sync(&self);
}

impl<S: DmaSync + ?Sized> DmaSync for &S {
    fn dsb(&self) {
        (**self).dsb()
    }

    fn dmb(&self) {
        (**self).dmb()
    }

    fn outer_sync(&self) {
        (**self).outer_sync()
    }
}
