//! Scripted input for `rt-client live --script FILE`: one timed event per
//! line, replayed instead of the mouse and keys.
//!
//!     # milliseconds from the start, then the event
//!     0     key space
//!     500   drag 40 -10
//!     800   wheel 1
//!     1500  key r
//!     2000  quit
//!
//! Events: `drag DX DY` (pixels, left button held), `wheel N` (notches,
//! positive brings the light closer), `key NAME` (left, right, up, down,
//! pageup, pagedown, space, r, p, escape), `quit` (the same as escape).
//! When the script ends the viewer waits for the frame of the last light,
//! then closes.

use std::time::Duration;

use crate::control::{Input, Key};

/// A parsed script.
#[derive(Clone, Debug, PartialEq)]
pub struct Script {
    events: Vec<(Duration, Input)>,
    next: usize,
}

impl Script {
    /// Parse `text`; errors name the line.
    pub fn parse(text: &str) -> Result<Script, String> {
        let mut events = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let err = |what: &str| format!("script line {}: {what}: {line}", n + 1);
            let mut w = line.split_whitespace();
            let ms: u64 = w.next().and_then(|t| t.parse().ok()).ok_or_else(|| err("no time in milliseconds"))?;
            let num = |v: Option<&str>| v.and_then(|t| t.parse::<f64>().ok()).filter(|v| v.is_finite());
            let input = match w.next() {
                Some("drag") => {
                    let (dx, dy) = (num(w.next()), num(w.next()));
                    Input::Drag(dx.ok_or_else(|| err("drag DX DY"))?, dy.ok_or_else(|| err("drag DX DY"))?)
                }
                Some("wheel") => Input::Wheel(num(w.next()).ok_or_else(|| err("wheel N"))?),
                Some("key") => Input::Key(w.next().and_then(Key::parse).ok_or_else(|| err("unknown key"))?),
                Some("quit") => Input::Key(Key::Escape),
                _ => return Err(err("unknown event")),
            };
            if w.next().is_some() {
                return Err(err("extra words"));
            }
            if events.last().is_some_and(|(t, _)| *t > Duration::from_millis(ms)) {
                return Err(err("times must not go back"));
            }
            events.push((Duration::from_millis(ms), input));
        }
        Ok(Script { events, next: 0 })
    }

    /// The events due by `elapsed`; `None` once all have been taken.
    pub fn due(&mut self, elapsed: Duration) -> Option<Vec<Input>> {
        if self.next >= self.events.len() {
            return None;
        }
        let mut out = Vec::new();
        while let Some((t, i)) = self.events.get(self.next) {
            if *t > elapsed {
                break;
            }
            out.push(*i);
            self.next += 1;
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scripts_parse_and_replay_in_time() {
        let mut s = Script::parse("# demo\n0 key space\n500 drag 40 -10\n500 wheel 1\n2000 quit\n").expect("valid");
        assert_eq!(s.due(Duration::ZERO), Some(vec![Input::Key(Key::Space)]));
        assert_eq!(s.due(Duration::from_millis(499)), Some(vec![]));
        assert_eq!(s.due(Duration::from_millis(600)), Some(vec![Input::Drag(40.0, -10.0), Input::Wheel(1.0)]));
        assert_eq!(s.due(Duration::from_secs(3)), Some(vec![Input::Key(Key::Escape)]));
        assert_eq!(s.due(Duration::from_secs(4)), None);
    }

    #[test]
    fn bad_lines_are_named() {
        for (text, what) in [
            ("x key r", "no time"),
            ("0 jump", "unknown event"),
            ("0 key f5", "unknown key"),
            ("0 drag 1", "drag DX DY"),
            ("0 drag 1 nan", "drag DX DY"),
            ("5 key r\n4 key r", "go back"),
            ("0 quit now", "extra words"),
        ] {
            let e = Script::parse(text).expect_err(text);
            assert!(e.contains(what), "{text}: {e}");
        }
    }
}
