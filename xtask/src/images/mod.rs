//! Board images: the firmware built for a board (and booted in QEMU by
//! `cargo xtask qemu`), the U-Boot legacy image around it, and the SD card
//! that boots the DE1-SoC into it.
//!
//! May import: `support`. `emulated` imports this group, never the other
//! way round: its tests and benches boot the firmware built here
//! (`firmware::build`, `firmware::Guest`).

pub mod entry_check;
pub mod firmware;
pub mod sdcard;
pub mod uimage;
