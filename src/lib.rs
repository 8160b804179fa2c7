//! Host test shim of the ray tracer workspace.
//!
//! The root package owns the cross-crate integration tests in `tests/` (and,
//! as the frame server lands, the `hps-sim` host board simulation). It has no
//! logic of its own.
