//! FPGA checks without Quartus (`cargo xtask rtl`): lint, co-simulation,
//! the Quartus-dialect gate, the Quartus files' consistency, resource
//! estimate and logic depth; `cargo xtask vga`, the simulated VGA monitor's
//! picture.
//!
//! May import: `support`. Nothing here needs the firmware or the emulated
//! board: the RTL is checked against the model alone.

pub mod depth;
pub mod quartus_check;
pub mod quartus_dialect;
pub mod rtl;
pub mod vga;
