//! Host-only commands, no board and no emulator: the model's commands
//! (`render`, `golden`, `quality`), the live viewer end to end under Xvfb
//! against the in-process board, real players (GStreamer) as clients of
//! `hps-sim`'s RTSP server (`players`), the web page in Chromium
//! (`web_page`), and the hostile-input harnesses (`fuzz`).
//!
//! May import: `support`. These run host crates alone, so they need neither
//! the firmware images nor QEMU.

pub mod fuzz;
pub mod live_test;
pub mod model_cmds;
pub mod players;
pub mod viewers;
pub mod web_page;
