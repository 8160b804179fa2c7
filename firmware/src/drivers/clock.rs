//! A monotonic microsecond clock, used for every bounded wait.

/// A monotonic clock in microseconds since an arbitrary origin.
pub trait Clock {
    /// Microseconds since the origin.
    fn now_us(&self) -> u64;
}

/// Poll `done` until it returns `Some`, or until `timeout_us` has passed on
/// `clock`; `None` on time-out. `done` is always tried at least once.
pub fn wait_for<T>(clock: &impl Clock, timeout_us: u64, mut done: impl FnMut() -> Option<T>) -> Option<T> {
    let start = clock.now_us();
    loop {
        if let Some(v) = done() {
            return Some(v);
        }
        if clock.now_us().wrapping_sub(start) >= timeout_us {
            return done();
        }
        core::hint::spin_loop();
    }
}

#[cfg(test)]
pub(crate) mod fake {
    use core::cell::Cell;

    /// A clock that advances by `step` microseconds on every reading.
    pub struct SteppingClock {
        pub now: Cell<u64>,
        pub step: u64,
    }

    impl SteppingClock {
        pub fn new(step: u64) -> Self {
            SteppingClock { now: Cell::new(0), step }
        }
    }

    impl super::Clock for SteppingClock {
        fn now_us(&self) -> u64 {
            let t = self.now.get();
            self.now.set(t + self.step);
            t
        }
    }
}

#[cfg(test)]
mod tests {
    use super::fake::SteppingClock;
    use super::*;

    #[test]
    fn wait_for_returns_the_value_once_ready() {
        let clock = SteppingClock::new(10);
        let mut polls = 0;
        let v = wait_for(&clock, 1_000, || {
            polls += 1;
            (polls == 3).then_some(42)
        });
        assert_eq!(v, Some(42));
        assert_eq!(polls, 3);
    }

    #[test]
    fn wait_for_gives_up_after_the_timeout() {
        let clock = SteppingClock::new(10);
        let mut polls = 0u32;
        let v: Option<()> = wait_for(&clock, 100, || {
            polls += 1;
            None
        });
        assert_eq!(v, None);
        assert!((10..=13).contains(&polls), "{polls} polls");
    }
}
