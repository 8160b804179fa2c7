//! Cross-crate tests of the workspace live in this package's test targets
//! (`hps_sim.rs`, ...); the library itself is empty.
