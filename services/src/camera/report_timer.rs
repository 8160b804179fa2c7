//! When a stream sends its RTCP sender reports (RFC 3550 section 6.2).

use core::time::Duration;

use crate::time::Instant;

/// The interval between RTCP reports: RFC 3550 section 6.2's recommended
/// minimum of 5 seconds. One unicast sender has no one to synchronise with
/// by accident, so the interval is not randomised (section 6.3.1 draws it
/// from `[0.5, 1.5]` times this to keep many participants apart).
pub const REPORT_INTERVAL: Duration = Duration::from_secs(5);

/// When to send the next RTCP report: the first [`REPORT_INTERVAL`] / 2
/// after the stream starts (RFC 3550 section 6.2: "the initial delay ...
/// MAY be set to half the minimum interval"), then every
/// [`REPORT_INTERVAL`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReportTimer {
    next: Instant,
}

impl ReportTimer {
    /// A timer for a stream starting at `start`.
    pub fn new(start: Instant) -> ReportTimer {
        ReportTimer { next: start + REPORT_INTERVAL / 2 }
    }

    /// When the next report is due (a deadline for the caller's wait).
    pub const fn deadline(&self) -> Instant {
        self.next
    }

    /// Whether a report is due at `now`; when it is, the next one is
    /// scheduled [`REPORT_INTERVAL`] from `now`.
    pub fn poll(&mut self, now: Instant) -> bool {
        if now < self.next {
            return false;
        }
        self.next = now + REPORT_INTERVAL;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_go_out_half_an_interval_in_then_every_interval() {
        let mut t = ReportTimer::new(Instant::from_millis(1_000));
        assert_eq!(t.deadline(), Instant::from_millis(3_500));
        assert!(!t.poll(Instant::from_millis(3_499)));
        assert!(t.poll(Instant::from_millis(3_600)));
        assert_eq!(t.deadline(), Instant::from_millis(8_600));
        assert!(!t.poll(Instant::from_millis(8_000)));
    }
}
