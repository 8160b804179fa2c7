//! Bit-exact fixed-point model of the FPGA ray tracer.
//!
//! This crate is the specification: the simulated accelerator, the firmware's
//! software renderer and the RTL co-simulation all agree with it bit for bit.
//!
//! * [`word`]: the Q13.10 word [`Q`] (24-bit signed, 10 fractional bits).
//! * [`arith`]: the arithmetic primitives, each defined as the hardware
//!   computes it (widths, rounding, saturation, division by zero).
//! * [`scene`]: every constant of the scene, once.
//! * [`trace`]: [`trace_pixel`] and [`render_row`]; [`frame`]: the 518,400-byte
//!   wire format.
//! * [`light`]: the validated light position.
//! * [`display`]: the VGA display (640 x 480) and how it maps onto the frame.
//! * With the `std` feature, [`mod@reference`] (an `f64` renderer of the same
//!   scene) and [`quality`] (PSNR and the share of pixels within +-8).
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]

pub mod arith;
pub mod colour;
pub mod display;
pub mod frame;
pub mod light;
pub mod scene;
pub mod trace;
pub mod word;

#[cfg(feature = "std")]
pub mod quality;
#[cfg(feature = "std")]
pub mod reference;

pub use colour::Rgb;
#[cfg(feature = "std")]
pub use frame::render_frame;
pub use frame::{render_frame_rgb888, row_to_rgb888, FRAME_BYTES, ROW_BYTES};
pub use light::{Light, LightError, ParseLightError};
pub use scene::{HEIGHT, WIDTH};
pub use trace::{render_row, trace_pixel};
pub use word::Q;
