//! The server's clock: milliseconds since an origin the adapter picks.

use core::ops::Add;
use core::time::Duration;

/// The one limit for every service on work a peer left unfinished: a
/// request not whole (the seed protocol's 12 bytes, the page's HTTP head,
/// an RTSP request) this long after its first byte closes its connection,
/// and a TCP handshake not finished this long is dropped (`tcp`). A client
/// on any network finishes both within a few round trips; one that sends
/// half and waits holds a socket no longer.
pub const REQUEST_LIMIT: Duration = Duration::from_secs(5);

/// A point in time, in whole milliseconds since the adapter's origin (the
/// firmware's boot, a host session's start).
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug, Default)]
pub struct Instant {
    millis: u64,
}

impl Instant {
    /// The origin.
    pub const ZERO: Instant = Instant { millis: 0 };

    /// `millis` milliseconds after the origin.
    pub const fn from_millis(millis: u64) -> Instant {
        Instant { millis }
    }

    /// Milliseconds since the origin.
    pub const fn millis(self) -> u64 {
        self.millis
    }

    /// Time from `earlier` to `self`, zero if `earlier` is later.
    pub const fn saturating_duration_since(self, earlier: Instant) -> Duration {
        Duration::from_millis(self.millis.saturating_sub(earlier.millis))
    }
}

impl Add<Duration> for Instant {
    type Output = Instant;

    /// Saturates at the end of time instead of overflowing.
    fn add(self, d: Duration) -> Instant {
        let ms = u64::try_from(d.as_millis()).unwrap_or(u64::MAX);
        Instant { millis: self.millis.saturating_add(ms) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arithmetic_saturates() {
        let t = Instant::from_millis(1_000);
        assert_eq!((t + Duration::from_millis(500)).millis(), 1_500);
        assert_eq!((t + Duration::MAX).millis(), u64::MAX);
        assert_eq!(t.saturating_duration_since(Instant::from_millis(4_000)), Duration::ZERO);
        assert_eq!(Instant::from_millis(4_000).saturating_duration_since(t), Duration::from_secs(3));
    }
}
