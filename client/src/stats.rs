//! Throughput and per-frame latency of a run.

use std::time::Duration;

use model::FRAME_BYTES;

/// Figures of a finished run.
#[derive(Debug, Clone)]
pub struct RunStats {
    /// Wall time from the first request to the last byte.
    pub elapsed: Duration,
    /// Per frame: from its request leaving to its last byte arriving.
    pub latencies: Vec<Duration>,
}

impl RunStats {
    /// Frames per second over the run.
    pub fn frames_per_second(&self) -> f64 {
        self.latencies.len() as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }

    /// Megabytes (10^6 bytes) of frame data per second.
    pub fn megabytes_per_second(&self) -> f64 {
        self.frames_per_second() * FRAME_BYTES as f64 / 1e6
    }

    /// Minimum, median and maximum latency (zero for an empty run).
    pub fn latency_min_median_max(&self) -> (Duration, Duration, Duration) {
        let mut l = self.latencies.clone();
        l.sort();
        match (l.first(), l.get(l.len() / 2), l.last()) {
            (Some(a), Some(b), Some(c)) => (*a, *b, *c),
            _ => Default::default(),
        }
    }

    /// The one-paragraph report printed after a run.
    pub fn report(&self) -> String {
        let (min, med, max) = self.latency_min_median_max();
        format!(
            "{} frames in {:.2} s: {:.1} frames/s, {:.1} MB/s\nlatency per frame: min {:.1} ms, median {:.1} ms, max {:.1} ms",
            self.latencies.len(),
            self.elapsed.as_secs_f64(),
            self.frames_per_second(),
            self.megabytes_per_second(),
            ms(min),
            ms(med),
            ms(max)
        )
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures() {
        let s = RunStats {
            elapsed: Duration::from_secs(2),
            latencies: [30, 10, 20, 50].map(Duration::from_millis).to_vec(),
        };
        assert_eq!(s.frames_per_second(), 2.0);
        assert!((s.megabytes_per_second() - 1.0368).abs() < 1e-9);
        let (a, b, c) = s.latency_min_median_max();
        assert_eq!((a, b, c), (Duration::from_millis(10), Duration::from_millis(30), Duration::from_millis(50)));
        assert!(s.report().contains("2.0 frames/s"));
    }
}
