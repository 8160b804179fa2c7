//! The row source the frame server renders with: the model on the A9, or on
//! the DE1-SoC the FPGA accelerator through hal-avalon, falling back to the
//! model for any row the accelerator fails.

#[cfg(feature = "de1-soc")]
use firmware::drivers::global_timer::GlobalTimer;
use firmware::server::{RowSource, SoftwareRenderer};
use model::Light;

/// The FPGA row driver on the board.
#[cfg(feature = "de1-soc")]
pub type FpgaRows = hal_avalon::Accelerator<hal_avalon::Mmio, TimerDelay>;

/// Where rows come from.
pub struct Renderer {
    #[cfg(feature = "de1-soc")]
    fpga: Option<FpgaRows>,
    /// Rows the accelerator failed (rendered in software instead).
    fpga_failures: u32,
    /// The last accelerator error not yet reported.
    #[cfg(feature = "de1-soc")]
    fault: Option<hal_avalon::Error>,
}

impl Renderer {
    /// The software renderer: `model::render_row` on the CPU.
    pub fn software() -> Renderer {
        Renderer {
            #[cfg(feature = "de1-soc")]
            fpga: None,
            fpga_failures: 0,
            #[cfg(feature = "de1-soc")]
            fault: None,
        }
    }

    /// The FPGA accelerator, with the software renderer as fallback.
    #[cfg(feature = "de1-soc")]
    pub fn fpga(accel: FpgaRows) -> Renderer {
        Renderer { fpga: Some(accel), fpga_failures: 0, fault: None }
    }

    /// Report (once) an accelerator failure since the last call.
    pub fn report(&mut self, log: &mut impl core::fmt::Write) {
        #[cfg(feature = "de1-soc")]
        if let Some(e) = self.fault.take() {
            let _ = writeln!(log, "FPGA: {e}; row rendered in software ({} so far)", self.fpga_failures);
        }
        let _ = log;
    }
}

impl RowSource for Renderer {
    type Error = core::convert::Infallible;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; model::WIDTH]) -> Result<(), Self::Error> {
        #[cfg(feature = "bench")]
        return bench::timed(y, || self.render_row_untimed(y, light, out));
        #[cfg(not(feature = "bench"))]
        self.render_row_untimed(y, light, out)
    }
}

impl Renderer {
    fn render_row_untimed(&mut self, y: u16, light: &Light, out: &mut [u32; model::WIDTH]) -> Result<(), core::convert::Infallible> {
        #[cfg(feature = "de1-soc")]
        if let Some(accel) = &mut self.fpga {
            match accel.run_row(y, light, out) {
                Ok(()) => return Ok(()),
                Err(e) => {
                    self.fpga_failures = self.fpga_failures.saturating_add(1);
                    self.fault = Some(e);
                }
            }
        }
        let _ = self.fpga_failures;
        SoftwareRenderer.render_row(y, light, out)
    }
}

/// `embedded-hal` delay on the global timer (for hal-avalon's polling).
#[cfg(feature = "de1-soc")]
pub struct TimerDelay(pub &'static GlobalTimer);

#[cfg(feature = "de1-soc")]
impl embedded_hal::delay::DelayNs for TimerDelay {
    fn delay_ns(&mut self, ns: u32) {
        let start = self.0.ticks();
        // ticks = ns * hz / 1e9, rounded up, at least 1.
        let ticks = (u64::from(ns) * u64::from(self.0.hz())).div_ceil(1_000_000_000).max(1);
        while self.0.ticks().wrapping_sub(start) < ticks {
            core::hint::spin_loop();
        }
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
        let timer = &crate::kmain::TIMER;
        let t0 = timer.now_ns();
        if y == 0 {
            RENDER_NS.store(0, Ordering::Relaxed);
            let _ = writeln!(Log, "bench: frame start {t0}");
        }
        let r = f();
        let dt = timer.now_ns().saturating_sub(t0);
        let total = RENDER_NS.fetch_add(dt, Ordering::Relaxed) + dt;
        if usize::from(y) == model::HEIGHT - 1 {
            let _ = writeln!(Log, "bench: frame rendered {total}");
        }
        r
    }
}
