//! Hardware drivers shared by both boards.
//!
//! Everything here builds on the host too: register access goes through
//! [`mmio::Mmio`], and the parts with logic worth testing (descriptor
//! encodings, PHY negotiation, timer arithmetic) are pure functions or take
//! their hardware as a trait, so the host tests run them against fakes.

pub mod clock;
pub mod dwmac;
pub mod global_timer;
pub mod mmio;
pub mod phy;
pub mod uart16550;
