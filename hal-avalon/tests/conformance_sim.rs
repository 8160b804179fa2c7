//! The register-semantics suite (`hal_avalon::conformance`) against the
//! simulated accelerator; rtl-port runs the same suite against the RTL.

use hal_avalon::conformance::TestMemory;
use hal_avalon::sim::SimAccelerator;

hal_avalon::conformance_tests!(SimAccelerator::with_memory(TestMemory::default(), 3));
