//! The bottom layer: what every xtask command shares (paths, targets, the
//! step runner, tool installation) and the error type.
//!
//! May import: nothing above it (only `support` itself), so every group can
//! use it without a cycle; the `layering` test checks this.

pub mod tools;

/// Errors of xtask commands: one line for the user.
pub type Result<T> = std::result::Result<T, String>;
