//! Polling driver for the Synopsys DesignWare GMAC (DWC Ethernet MAC 3.x):
//! the Cyclone V HPS EMACs (3.70a, enhanced descriptors) and QEMU's
//! `npcm-gmac` (normal descriptors), with the PHY on its MDIO bus, behind
//! smoltcp's [`Device`](smoltcp::phy::Device).
//!
//! * [`regs`]: the register block, typed, ending before offset 0x1060 (QEMU's
//!   model reads and writes past its register array from there on).
//! * [`desc`]: both descriptor formats as pure encode/decode functions;
//!   [`csum`]: the checksum insertion each frame asks for.
//! * [`ring`]: descriptors and buffers in memory the MAC's DMA shares with
//!   the CPU, accessed through volatile cells and raw pointers only.
//! * [`mac`]: bring-up, link configuration and statistics; [`device`]: the
//!   smoltcp `Device`; [`split`]: zero-copy header + payload transmit beside
//!   it (RTP rows straight from the frame ring).
//! * [`phy`]: IEEE 802.3 clause 22 PHYs (and the Micrel KSZ9021's RGMII
//!   skews) and the link monitor the main loop polls.
//! * [`sync`]: the barriers and outer-cache drain a hand-over needs, which
//!   the board provides.
//!
//! No interrupts, no allocation; every wait is bounded ([`wait`]).
#![cfg_attr(not(test), no_std)]

pub mod csum;
pub mod desc;
pub mod device;
pub mod filter;
pub mod mac;
pub mod phy;
pub mod regs;
pub mod ring;
pub mod split;
pub mod sync;
pub mod wait;

pub use filter::MulticastFilter;
pub use mac::{Dwmac, Error, Stats};
pub use ring::{DmaArea, RX_RING, TX_RING};
pub use split::{SplitError, SplitSeq};
pub use sync::DmaSync;

#[cfg(test)]
mod gmac_csum_model;
#[cfg(test)]
mod tests;
