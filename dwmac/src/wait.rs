//! Bounded polling on an `embedded-hal` delay.

use embedded_hal::delay::DelayNs;

/// How long to keep polling, and how often.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timeout {
    /// Give up after about this many microseconds of delay.
    pub total_us: u32,
    /// Microseconds between two polls (at least 1).
    pub interval_us: u32,
}

impl Timeout {
    /// Poll every `interval_us` for at most `total_us`.
    pub const fn new(total_us: u32, interval_us: u32) -> Timeout {
        Timeout { total_us, interval_us: if interval_us == 0 { 1 } else { interval_us } }
    }

    /// How many times `done` is tried: once at the start and once after
    /// each interval.
    pub const fn polls(&self) -> u32 {
        self.total_us / self.interval_us + 1
    }
}

/// Poll `done` until it returns `Some`, at most [`Timeout::polls`] times,
/// sleeping `interval_us` between tries; `None` on time-out. The real time
/// taken is the delays plus the polls themselves, so at least `total_us`
/// before giving up.
pub fn wait_for<T>(delay: &mut impl DelayNs, timeout: Timeout, mut done: impl FnMut() -> Option<T>) -> Option<T> {
    for attempt in 0..timeout.polls() {
        if attempt > 0 {
            delay.delay_us(timeout.interval_us);
        }
        if let Some(v) = done() {
            return Some(v);
        }
    }
    None
}

#[cfg(test)]
pub(crate) mod fake {
    use embedded_hal::delay::DelayNs;

    /// A delay that only counts what it was asked to wait.
    #[derive(Default)]
    pub struct CountingDelay {
        pub calls: u32,
        pub total_ns: u64,
    }

    impl DelayNs for CountingDelay {
        fn delay_ns(&mut self, ns: u32) {
            self.calls += 1;
            self.total_ns += u64::from(ns);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::fake::CountingDelay;
    use super::*;

    #[test]
    fn returns_the_value_once_ready() {
        let mut delay = CountingDelay::default();
        let mut polls = 0;
        let v = wait_for(&mut delay, Timeout::new(1_000, 10), || {
            polls += 1;
            (polls == 3).then_some(42)
        });
        assert_eq!(v, Some(42));
        assert_eq!((polls, delay.calls), (3, 2));
    }

    #[test]
    fn gives_up_after_the_timeout() {
        let mut delay = CountingDelay::default();
        let mut polls = 0u32;
        let v: Option<()> = wait_for(&mut delay, Timeout::new(100, 10), || {
            polls += 1;
            None
        });
        assert_eq!(v, None);
        assert_eq!(polls, 11);
        assert_eq!(delay.total_ns, 100_000, "waited the whole timeout");
        assert_eq!(Timeout::new(5, 0).interval_us, 1, "interval at least 1 us");
    }
}
