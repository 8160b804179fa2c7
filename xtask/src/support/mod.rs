//! The bottom layer: what every xtask command shares (paths, targets, the
//! step runner, tool installation) and the error type.
//!
//! May import: `support` only. Nothing above it, so every group can use it
//! without a cycle.

pub mod browser;
pub mod laggard;
pub mod player;
pub mod process;
pub mod rtsp_client;
pub mod timing;
pub mod tools;

/// Errors of xtask commands: one line for the user.
pub type Result<T> = std::result::Result<T, String>;
