//! The log: every connection's lines to stderr, prefixed with its id, and
//! the newest of them kept for `/log`, as the board keeps its UART log.

use std::collections::VecDeque;
use std::fmt;
use std::sync::Mutex;

/// Log lines of one connection to stderr, prefixed with its id (or nowhere).
pub struct Log {
    id: u64,
    verbose: bool,
    line: String,
}

impl Log {
    /// The log of connection `id`; `verbose: false` discards it.
    pub fn new(id: u64, verbose: bool) -> Log {
        Log { id, verbose, line: String::new() }
    }
}

impl fmt::Write for Log {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        if !self.verbose {
            return Ok(());
        }
        self.line.push_str(s);
        while let Some(end) = self.line.find('\n') {
            let line = format!("[{}] {}", self.id, &self.line[..end]);
            eprintln!("{line}");
            keep(&line);
            self.line.drain(..=end);
        }
        Ok(())
    }
}

/// Bytes of log history kept for `/log`, as on the board.
pub const HISTORY_BYTES: usize = 8192;

/// The newest [`HISTORY_BYTES`] of the log, whole lines, every
/// connection's (the board's UART log is one too).
static HISTORY: Mutex<VecDeque<u8>> = Mutex::new(VecDeque::new());

/// Keep `line` in the history.
fn keep(line: &str) {
    let mut h = HISTORY.lock().unwrap_or_else(|e| e.into_inner());
    h.extend(line.as_bytes());
    h.push_back(b'\n');
    let over = h.len().saturating_sub(HISTORY_BYTES);
    h.drain(..over);
}

/// The log's newest lines, for `/log`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Tail;

impl rt_services::web::status::LogTail for Tail {
    fn tail(&self, out: &mut [u8]) -> usize {
        let h = HISTORY.lock().unwrap_or_else(|e| e.into_inner());
        let (old, new) = h.as_slices();
        rt_services::web::status::copy_tail([old, new], h.len() == HISTORY_BYTES, out)
    }
}
