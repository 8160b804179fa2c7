//! A row source with a fallback: rows from a primary source (the FPGA
//! accelerator) and, for any row it fails, from a fallback (the model on the
//! CPU). A primary that fails [`WEDGED_AFTER`] rows in a row is switched off
//! for good, so a wedged accelerator costs its time-outs a few times, not on
//! every row of every frame.

use crate::frames::rows::RowSource;
use model::{Light, WIDTH};

/// Consecutive failed rows after which the primary source is switched off.
pub const WEDGED_AFTER: u32 = 3;

/// What happened since the last [`Fallback::take_event`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FallbackEvent<E> {
    /// The primary failed rows (rendered by the fallback instead); `error`
    /// is the last failure, `total` the failed rows so far.
    RowsFailed {
        /// The last error.
        error: E,
        /// Rows failed since start-up.
        total: u32,
    },
    /// The primary failed [`WEDGED_AFTER`] rows in a row and is off for good.
    SwitchedOff {
        /// The last error.
        error: E,
    },
}

/// Rows from `P`, or from `F` where `P` fails.
pub struct Fallback<P: RowSource, F> {
    /// Kept after it is switched off: its device may have more than rows
    /// to offer (the board's LEDs and displays name the fault).
    primary: Option<P>,
    active: bool,
    fallback: F,
    consecutive: u32,
    total: u32,
    event: Option<FallbackEvent<P::Error>>,
}

impl<P: RowSource, F: RowSource> Fallback<P, F> {
    /// `primary` first, `fallback` where it fails.
    pub fn new(primary: Option<P>, fallback: F) -> Fallback<P, F> {
        let active = primary.is_some();
        Fallback { primary, active, fallback, consecutive: 0, total: 0, event: None }
    }

    /// Whether the primary source is still in use.
    pub fn primary_active(&self) -> bool {
        self.active
    }

    /// The primary source, while it is in use.
    pub fn primary(&mut self) -> Option<&mut P> {
        self.primary.as_mut().filter(|_| self.active)
    }

    /// The primary source, switched off or not (its device may have more
    /// than rows to offer: board I/O).
    pub fn primary_kept(&mut self) -> Option<&mut P> {
        self.primary.as_mut()
    }

    /// The event to report since the last call, if any (a switch-off is
    /// reported once).
    pub fn take_event(&mut self) -> Option<FallbackEvent<P::Error>> {
        self.event.take()
    }
}

impl<P: RowSource, F: RowSource> RowSource for Fallback<P, F>
where
    P::Error: Copy,
{
    type Error = F::Error;

    fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), F::Error> {
        if let Some(primary) = self.primary.as_mut().filter(|_| self.active) {
            match primary.render_row(y, light, out) {
                Ok(()) => {
                    self.consecutive = 0;
                    return Ok(());
                }
                Err(error) => {
                    self.total = self.total.saturating_add(1);
                    self.consecutive += 1;
                    self.event = Some(if self.consecutive >= WEDGED_AFTER {
                        self.active = false;
                        FallbackEvent::SwitchedOff { error }
                    } else {
                        FallbackEvent::RowsFailed { error, total: self.total }
                    });
                }
            }
        }
        self.fallback.render_row(y, light, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::rows::SoftwareRenderer;

    /// Fails the rows it is told to.
    struct Flaky {
        fail: fn(u16) -> bool,
    }

    impl RowSource for Flaky {
        type Error = u16;
        fn render_row(&mut self, y: u16, light: &Light, out: &mut [u32; WIDTH]) -> Result<(), u16> {
            if (self.fail)(y) {
                out.fill(0xdead);
                return Err(y);
            }
            model::render_row(y, light, out);
            Ok(())
        }
    }

    fn light() -> Light {
        Light::from_world(3.0, 4.0, -2.0).unwrap()
    }

    #[test]
    fn failed_rows_come_from_the_fallback_and_a_wedge_switches_off_once() {
        let mut rows = Fallback::new(Some(Flaky { fail: |y| y == 7 || y >= 100 }), SoftwareRenderer);
        let (mut got, mut want) = ([0u32; WIDTH], [0u32; WIDTH]);
        for y in 0..100 {
            rows.render_row(y, &light(), &mut got).unwrap();
            model::render_row(y, &light(), &mut want);
            assert_eq!(got, want, "row {y} is right either way");
            if y == 7 {
                assert_eq!(rows.take_event(), Some(FallbackEvent::RowsFailed { error: 7, total: 1 }));
            }
        }
        assert!(rows.primary_active(), "one failure between good rows is not a wedge");
        for y in 100..103 {
            rows.render_row(y, &light(), &mut got).unwrap();
        }
        assert_eq!(rows.take_event(), Some(FallbackEvent::SwitchedOff { error: 102 }));
        assert!(!rows.primary_active());
        assert!(rows.primary().is_none(), "off for rows");
        assert!(rows.primary_kept().is_some(), "kept for its board I/O");
        for y in 103..360 {
            rows.render_row(y, &light(), &mut got).unwrap();
        }
        assert_eq!(rows.take_event(), None, "reported once");
    }
}
