//! The suite's cost, shown: each part of a run timed as it ends, and a
//! table of them, slowest first, with the total, when the run ends
//! (passed or not).

use std::time::{Duration, Instant};

use super::Result;

/// The parts of one run and how long each took.
pub struct Timings {
    started: Instant,
    parts: Vec<(String, Duration, bool)>,
}

impl Default for Timings {
    fn default() -> Timings {
        Timings::new()
    }
}

impl Timings {
    /// A run starting now.
    pub fn new() -> Timings {
        Timings { started: Instant::now(), parts: Vec::new() }
    }

    /// Run one part, named `name`: its start and its end (with the time it
    /// took) on lines of their own, and a row of the table.
    pub fn part<T>(&mut self, name: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        println!("==> [{name}]");
        let started = Instant::now();
        let result = f();
        let took = started.elapsed();
        let failed = result.is_err();
        println!("<== [{name}] {}: {}", if failed { "FAILED" } else { "done" }, seconds(took));
        self.parts.push((name.to_string(), took, failed));
        result
    }

    /// The table: every part, slowest first, then the total since the run
    /// began.
    pub fn table(&self) -> String {
        let mut rows: Vec<&(String, Duration, bool)> = self.parts.iter().collect();
        rows.sort_by_key(|r| std::cmp::Reverse(r.1));
        let width = rows.iter().map(|r| r.0.len()).max().unwrap_or(0).max("total".len());
        let mut text = format!("{:width$}  {:>9}\n", "step", "time");
        for (name, took, failed) in rows {
            let mark = if *failed { "  FAILED" } else { "" };
            text += &format!("{name:width$}  {:>9}{mark}\n", seconds(*took));
        }
        text += &format!("{:width$}  {:>9}", "total", seconds(self.started.elapsed()));
        text
    }
}

/// `d` as minutes and seconds (`12m 03s`), or seconds under a minute.
fn seconds(d: Duration) -> String {
    let s = d.as_secs();
    if s < 60 {
        format!("{:.1} s", d.as_secs_f64())
    } else {
        format!("{}m {:02}s", s / 60, s % 60)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_lists_the_slowest_first_and_marks_a_failure() {
        let mut t = Timings::new();
        t.part("quick", || Ok(())).unwrap();
        t.part("slow", || {
            std::thread::sleep(Duration::from_millis(30));
            Ok(())
        })
        .unwrap();
        assert!(t.part("broken", || -> Result<()> { Err("no".into()) }).is_err());
        let table = t.table();
        let lines: Vec<&str> = table.lines().collect();
        assert!(lines[1].starts_with("slow"), "{table}");
        assert!(lines.iter().any(|l| l.starts_with("broken") && l.ends_with("FAILED")), "{table}");
        assert!(lines.last().unwrap().starts_with("total"), "{table}");
        assert_eq!(lines.len(), 5, "{table}");
    }

    #[test]
    fn durations_read_as_minutes_past_one() {
        assert_eq!(seconds(Duration::from_millis(2500)), "2.5 s");
        assert_eq!(seconds(Duration::from_secs(723)), "12m 03s");
    }
}
