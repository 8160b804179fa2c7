//! Where the frames every service sends come from.
//!
//! A [`FrameSource`] hands out frames, reports how many of a frame's rows can
//! be read, and copies row bytes straight into the transport's buffer (the
//! socket's), so a row is copied by the CPU once. Two sources:
//!
//! * [`RowFrames`] (row mode, [`rows`]): renders one row at a time with a
//!   [`RowSource`] (the model, the FPGA's row registers) into a single row
//!   buffer per frame. A session's rows are rendered as it sends them.
//! * [`FrameRing`] (frame mode, [`ring`]): whole frames in `SLOTS` slots of a
//!   [`FrameMemory`] (the FPGA-to-SDRAM frame buffers on the board), filled
//!   by a [`FrameEngine`] (the FPGA's frame DMA, or a software renderer that
//!   writes the same memory) one frame after another; rows become readable
//!   as the engine's rows-done counter covers them.
//!
//! [`engines`] wraps engines (a fallback for a failing primary, a stall
//! watchdog); [`fallback`] does the same for row sources.

pub mod engines;
pub mod fallback;
pub mod ring;
pub mod rows;
pub mod share;

pub use engines::{EngineError, FallbackEngine, Watchdog, WatchdogError};
pub use ring::{Completed, FrameEngine, FrameMemory, FrameRing, RowEngine, SliceMemory};
pub use rows::{RowFrames, RowSource, SoftwareRenderer};
pub use share::Quota;

use core::fmt;

use model::{Light, HEIGHT};

/// Rows of a frame.
pub const ROWS: u16 = HEIGHT as u16;

/// Frames for sessions.
pub trait FrameSource {
    /// A frame a session holds.
    type Frame: Copy + Eq + fmt::Debug;
    /// Why a frame could not be rendered.
    type Error: fmt::Display + fmt::Debug;

    /// Begin a frame for `light`; `Ok(None)` while no slot is free (ask
    /// again later).
    fn begin(&mut self, light: &Light) -> Result<Option<Self::Frame>, Self::Error>;

    /// Rows `0..n` of `frame` that can be copied now. May do work (render a
    /// row, read the accelerator's counter); never blocks for long.
    fn rows_ready(&mut self, frame: Self::Frame) -> Result<u16, Self::Error>;

    /// Copy bytes `offset..` of row `y` of `frame` into `out` (as many as fit
    /// and the row has); returns how many. Only for rows below what
    /// [`rows_ready`](Self::rows_ready) reported.
    fn copy_row(&mut self, frame: Self::Frame, y: u16, offset: usize, out: &mut [u8]) -> usize;

    /// The session is done with `frame` (sent, or abandoned): its slot may
    /// be reused.
    fn end(&mut self, frame: Self::Frame);
}
