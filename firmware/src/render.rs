//! The row source the frame server renders with: on the DE1-SoC the FPGA
//! accelerator through hal-avalon, falling back to the model on the A9 for
//! any row it fails and for good once it is wedged; elsewhere the model.

use core::fmt::Write;

use hal_avalon::{Accelerator, MmioPort};
use model::{Light, WIDTH};
use rt_protocol::fallback::{Fallback, FallbackEvent, WEDGED_AFTER};
use rt_protocol::{RowSource, SoftwareRenderer};
use soc::global_timer::TimerDelay;

/// The FPGA row driver on the board, as a row source.
pub struct FpgaRows(pub Accelerator<MmioPort, TimerDelay<'static>>);

impl RowSource for FpgaRows {
    type Error = hal_avalon::Error;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Self::Error> {
        self.0.run_row(y, light, out)
    }
}

/// Where rows come from.
pub struct Renderer(Fallback<FpgaRows, SoftwareRenderer>);

impl Renderer {
    /// The FPGA accelerator if there is one, with the software renderer
    /// (`model::render_row` on the CPU) as fallback.
    pub fn new(fpga: Option<FpgaRows>) -> Renderer {
        Renderer(Fallback::new(fpga, SoftwareRenderer))
    }

    /// Report what the accelerator did since the last call.
    pub fn report(&mut self, log: &mut impl Write) {
        match self.0.take_event() {
            Some(FallbackEvent::RowsFailed { error, total }) => {
                let _ = writeln!(log, "FPGA: {error}; row rendered in software ({total} so far)");
            }
            Some(FallbackEvent::SwitchedOff { error }) => {
                let _ = writeln!(log, "FPGA: {error}; {WEDGED_AFTER} rows failed in a row: accelerator switched off, software from now on");
            }
            None => {}
        }
    }
}

impl RowSource for Renderer {
    type Error = core::convert::Infallible;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), Self::Error> {
        #[cfg(feature = "bench")]
        return bench::timed(y, || self.0.render_row(y, light, out));
        #[cfg(not(feature = "bench"))]
        self.0.render_row(y, light, out)
    }
}

/// Bench build: guest nanoseconds per frame and per frame's rendering, on
/// the UART. Under QEMU's `-icount shift=0` one guest nanosecond is one
/// guest instruction.
#[cfg(feature = "bench")]
mod bench {
    use core::fmt::Write;
    use core::sync::atomic::{AtomicU64, Ordering};

    use crate::log::Log;

    static RENDER_NS: AtomicU64 = AtomicU64::new(0);

    /// Run `f` (rendering row `y`), adding its duration to the frame's.
    pub fn timed<R>(y: u16, f: impl FnOnce() -> R) -> R {
        let t0 = crate::TIMER.now_ns();
        if y == 0 {
            RENDER_NS.store(0, Ordering::Relaxed);
            let _ = writeln!(Log, "bench: frame start {t0}");
        }
        let r = f();
        let dt = crate::TIMER.now_ns().saturating_sub(t0);
        let total = RENDER_NS.fetch_add(dt, Ordering::Relaxed) + dt;
        if usize::from(y) == model::HEIGHT - 1 {
            let _ = writeln!(Log, "bench: frame rendered {total}");
        }
        r
    }
}
