//! The emulated board: the firmware run on QEMU's npcm750-evb and tested
//! or measured there (end-to-end tests, `bench-fw` and its board cost
//! model, `lossy-bench`, `soak`).
//!
//! May import: `support`, `images`. The dependency on `images` is one-way:
//! every test here boots the firmware that `images::firmware` builds and
//! runs (`build`, `Guest`); nothing in `images` needs the tests.

pub mod addressing;
pub mod bench_fw;
pub mod boot_log;
pub mod cost_model;
pub mod doctor;
pub mod early_frames;
pub mod entropy;
pub mod hostile;
pub mod lan;
pub mod lossy;
pub mod mac_filter;
pub mod moved;
pub mod names;
pub mod per_host;
pub mod qemu_e2e;
pub mod soak;
pub mod viewers;
pub mod web;
