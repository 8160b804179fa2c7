//! The board's fault code: one number for what is wrong, the same on the
//! 7-segment displays (`Err  N`), in the HPS LED's blinks (N blinks, then
//! a pause; a heartbeat when all is well), on the UART and in `/status`.
//! docs/diagnostics.md lists every code and what to check.
//!
//! The HPS LED is on the HPS's own GPIO, so it speaks when the FPGA does
//! not answer and the FPGA's displays are dark.

use core::fmt;
use core::time::Duration;

use super::Text;
use crate::time::Instant;

/// What is wrong, most fundamental first: when several hold, the first
/// is shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Code {
    /// Nothing: frames from the FPGA's frame DMA, a link, an address.
    #[default]
    Ok,
    /// E1: no accelerator answers (FPGA not configured, bridge in reset,
    /// another design loaded): frames come from the software renderer.
    NoFpga,
    /// E2: the accelerator failed its boot self-test in row mode (or in
    /// frame mode with the same pixel wrong in row mode): the software
    /// renderer makes every frame.
    SelfTestFailed,
    /// E3: the accelerator was switched off after frames failed in a row.
    SwitchedOff,
    /// E4: frame mode failed its self-test and row mode passed: the FPGA
    /// renders rows over the bridge (slower), the VGA output is off. Check
    /// that the FPGA-to-SDRAM port is out of reset (`fpgaportrst`).
    RowsOnly,
    /// E5: the Ethernet link is down.
    NoLink,
    /// E6: a link but no IPv4 address yet (no DHCP answer, link-local
    /// claim in progress).
    NoAddress,
    /// E7: the VGA scan-out's memory reads failed.
    VgaFault,
}

/// What the firmware knows, for [`Code::of`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Facts {
    /// An accelerator answered the probe.
    pub fpga_answers: bool,
    /// It passed the self-test in row mode.
    pub rows_passed: bool,
    /// It passed in frame mode too (or has no frame mode).
    pub frames_passed: bool,
    /// It is still in use (not switched off after failures).
    pub fpga_in_use: bool,
    /// The Ethernet link is up.
    pub link_up: bool,
    /// The board has an IPv4 address.
    pub has_address: bool,
    /// The VGA scan-out reported a memory fault.
    pub vga_fault: bool,
}

impl Code {
    /// The code for `facts`: the first that holds, in the order above.
    pub fn of(facts: &Facts) -> Code {
        if !facts.fpga_answers {
            Code::NoFpga
        } else if !facts.rows_passed {
            Code::SelfTestFailed
        } else if !facts.fpga_in_use {
            Code::SwitchedOff
        } else if !facts.frames_passed {
            Code::RowsOnly
        } else if !facts.link_up {
            Code::NoLink
        } else if !facts.has_address {
            Code::NoAddress
        } else if facts.vga_fault {
            Code::VgaFault
        } else {
            Code::Ok
        }
    }

    /// The number shown (0: all well).
    pub fn number(self) -> u8 {
        match self {
            Code::Ok => 0,
            Code::NoFpga => 1,
            Code::SelfTestFailed => 2,
            Code::SwitchedOff => 3,
            Code::RowsOnly => 4,
            Code::NoLink => 5,
            Code::NoAddress => 6,
            Code::VgaFault => 7,
        }
    }

    /// `"ok"` or `"E1"`..`"E7"`, as `/status` names it.
    pub fn as_str(self) -> &'static str {
        ["ok", "E1", "E2", "E3", "E4", "E5", "E6", "E7"][usize::from(self.number())]
    }

    /// What it means, in a few words.
    pub fn meaning(self) -> &'static str {
        match self {
            Code::Ok => "all well",
            Code::NoFpga => "no accelerator answers: software renderer",
            Code::SelfTestFailed => "the accelerator failed its self-test: software renderer",
            Code::SwitchedOff => "the accelerator was switched off after failed frames: software renderer",
            Code::RowsOnly => "frame mode failed its self-test: FPGA in row mode, VGA off (check fpgaportrst)",
            Code::NoLink => "no Ethernet link",
            Code::NoAddress => "no IPv4 address yet",
            Code::VgaFault => "the VGA output's memory reads failed (check fpgaportrst)",
        }
    }

    /// The 7-segment text: `Err  N` (none when all is well).
    pub fn hex_text(self) -> Option<Text> {
        let n = self.number();
        (n != 0).then(|| {
            let mut t = [b' '; super::DIGITS];
            t[..3].copy_from_slice(b"Err");
            t[super::DIGITS - 1] = b'0' + n;
            t
        })
    }
}

impl fmt::Display for Code {
    /// `ok: all well` / `E5: no Ethernet link`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.as_str(), self.meaning())
    }
}

/// A blink's time lit, and the dark time between blinks.
pub const BLINK_ON: Duration = Duration::from_millis(200);
/// Dark time between two blinks of a code.
pub const BLINK_OFF: Duration = Duration::from_millis(300);
/// Dark time after a code's blinks, before they repeat.
pub const CODE_PAUSE: Duration = Duration::from_millis(1500);
/// The heartbeat's period: two short flashes (100 ms, 100 ms apart) a
/// second.
pub const HEARTBEAT: Duration = Duration::from_secs(1);

/// Whether the HPS LED is lit at `now` for `code`: a heartbeat (lit 0-100
/// ms and 200-300 ms of every second) when all is well, else `N` blinks
/// of [`BLINK_ON`] spaced by [`BLINK_OFF`], then [`CODE_PAUSE`] dark.
pub fn hps_led(code: Code, now: Instant) -> bool {
    let ms = now.millis();
    let n = u64::from(code.number());
    if n == 0 {
        let t = ms % HEARTBEAT.as_millis() as u64;
        return t < 100 || (200..300).contains(&t);
    }
    let (on, off) = (BLINK_ON.as_millis() as u64, BLINK_OFF.as_millis() as u64);
    let cycle = n * (on + off) + CODE_PAUSE.as_millis() as u64;
    let t = ms % cycle;
    t < n * (on + off) && t % (on + off) < on
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_well() -> Facts {
        Facts {
            fpga_answers: true,
            rows_passed: true,
            frames_passed: true,
            fpga_in_use: true,
            link_up: true,
            has_address: true,
            vga_fault: false,
        }
    }

    #[test]
    fn the_most_fundamental_fault_is_the_one_shown() {
        assert_eq!(Code::of(&all_well()), Code::Ok);
        type Fault = fn(&mut Facts);
        let cases: [(Fault, Code); 7] = [
            (|f| f.vga_fault = true, Code::VgaFault),
            (|f| f.has_address = false, Code::NoAddress),
            (|f| f.link_up = false, Code::NoLink),
            (|f| f.frames_passed = false, Code::RowsOnly),
            (|f| f.fpga_in_use = false, Code::SwitchedOff),
            (|f| f.rows_passed = false, Code::SelfTestFailed),
            (|f| f.fpga_answers = false, Code::NoFpga),
        ];
        // Each fault alone gives its code; piled up, the last (most
        // fundamental) wins.
        let mut piled = all_well();
        for (set, code) in cases {
            let mut alone = all_well();
            set(&mut alone);
            assert_eq!(Code::of(&alone), code);
            set(&mut piled);
            assert_eq!(Code::of(&piled), code);
        }
    }

    #[test]
    fn codes_read_the_same_everywhere() {
        assert_eq!(Code::RowsOnly.as_str(), "E4");
        assert_eq!(Code::RowsOnly.hex_text(), Some(*b"Err  4"));
        assert_eq!(Code::Ok.hex_text(), None);
        assert_eq!(Code::NoLink.to_string(), "E5: no Ethernet link");
        for n in 1..=7u8 {
            let code = [
                Code::NoFpga,
                Code::SelfTestFailed,
                Code::SwitchedOff,
                Code::RowsOnly,
                Code::NoLink,
                Code::NoAddress,
                Code::VgaFault,
            ][usize::from(n - 1)];
            assert_eq!(code.number(), n);
            assert_eq!(code.as_str(), alloc_free_code(n));
            // Every character is one the displays can show.
            assert!(code.hex_text().unwrap().iter().all(|&c| hal_avalon_shows(c)));
        }
    }

    fn alloc_free_code(n: u8) -> String {
        format!("E{n}")
    }

    /// The characters `hal_avalon::board::segments` shows (that crate is
    /// not a dependency of this one).
    fn hal_avalon_shows(c: u8) -> bool {
        c.is_ascii_digit() || b"Er ".contains(&c)
    }

    /// Lit milliseconds of `code` in `[0, ms)`, and the number of times it
    /// lights up.
    fn trace(code: Code, ms: u64) -> (u64, u32) {
        let (mut lit, mut flashes, mut was) = (0, 0, false);
        for t in 0..ms {
            let on = hps_led(code, Instant::from_millis(t));
            lit += u64::from(on);
            flashes += u32::from(on && !was);
            was = on;
        }
        (lit, flashes)
    }

    #[test]
    fn the_hps_led_beats_when_well_and_blinks_the_code_otherwise() {
        // Heartbeat: two 100 ms flashes a second.
        assert_eq!(trace(Code::Ok, 3000), (600, 6));
        // E5: five blinks in a 4 s cycle, then dark for 1.5 s.
        let cycle = 5 * 500 + 1500;
        assert_eq!(trace(Code::NoLink, cycle), (5 * 200, 5));
        assert!(!(2500..cycle).any(|t| hps_led(Code::NoLink, Instant::from_millis(t))));
        // E1 repeats: one blink per 2 s.
        assert_eq!(trace(Code::NoFpga, 4000), (400, 2));
    }
}
