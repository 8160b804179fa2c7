//! What the board found at boot, kept for `/status` and the fault code
//! (rt_services::monitor::code): the boot log says it once, this keeps it.

use core::fmt::Write;

use heapless::String;
use rt_services::monitor::code::Facts;

/// The boot's findings.
#[derive(Debug, Default)]
pub struct BootFacts {
    /// An accelerator answered the probe.
    pub fpga_answers: bool,
    /// Its register-map version.
    pub register_map: Option<u16>,
    /// Its bitstream's build id (0: none recorded).
    pub fpga_build: Option<u32>,
    /// `"pass"`, `"fail"` or `"skipped"`.
    pub self_test: &'static str,
    /// The self-test's log line, or why it was skipped.
    pub self_test_detail: String<240>,
    /// The self-test passed in row mode (or there was none to fail).
    pub rows_passed: bool,
    /// It passed in frame mode too (or the map has no frame mode).
    pub frames_passed: bool,
    /// The bridges and the SDRAM port as read at boot.
    pub bridges: String<96>,
}

impl BootFacts {
    /// Nothing found yet.
    pub fn new() -> BootFacts {
        BootFacts { self_test: "skipped", bridges: str_of("not a board"), ..BootFacts::default() }
    }

    /// Keep `line` as the self-test's detail (cut to fit).
    pub fn set_detail(&mut self, line: impl core::fmt::Display) {
        self.self_test_detail.clear();
        let _ = write!(Cut(&mut self.self_test_detail), "{line}");
    }

    /// The facts the fault code is made of, with the run's own.
    pub fn facts(&self, fpga_in_use: bool, link_up: bool, has_address: bool, vga_fault: bool) -> Facts {
        Facts {
            fpga_answers: self.fpga_answers,
            rows_passed: self.rows_passed,
            frames_passed: self.frames_passed,
            fpga_in_use,
            link_up,
            has_address,
            vga_fault,
        }
    }
}

/// A bitstream's build id in words: `build 0123abc`, or `no build id`
/// for 0 (a bitstream built without one, or from before the register).
pub struct BuildId(pub u32);

impl core::fmt::Display for BuildId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            0 => f.write_str("no build id"),
            id => write!(f, "build {id:07x}"),
        }
    }
}

/// `s` as a bounded string (cut to fit).
pub fn str_of<const N: usize>(s: &str) -> String<N> {
    let mut out = String::new();
    let _ = Cut(&mut out).write_str(s);
    out
}

/// Writes what fits and drops the rest (a log line kept for `/status`
/// may be cut, never refused).
struct Cut<'a, const N: usize>(&'a mut String<N>);

impl<const N: usize> Write for Cut<'_, N> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for c in s.chars() {
            if self.0.push(c).is_err() {
                break;
            }
        }
        Ok(())
    }
}
