//! The VGA scan-out and the board I/O block (map version 3,
//! [`ID_VERSION_VGA`]): a small driver over any [`RegisterPort`].
//!
//! [`BoardIo::open`] checks the ID register for map version 3 or later;
//! after that every call is one or two register accesses and never fails
//! (a bus that stops answering reads all ones, which shows as keys down and
//! switches up, nothing worse). [`segments`] is the 7-segment font.
//!
//! ```
//! # #[cfg(feature = "sim")] {
//! use hal_avalon::board::{BoardIo, segments};
//! use hal_avalon::sim::SimAccelerator;
//! use model::display::Layout;
//!
//! let mut io = BoardIo::open(SimAccelerator::new()).expect("map version 3"); // ok: the simulated device reports map version 3
//! io.show(0x0410_0000);
//! io.enable(Layout::FullScreen);
//! io.set_text(*b" 60FPS");
//! assert_eq!(io.digits()[0], segments(b'S').unwrap_or(0));
//! # }
//! ```

use model::display::Layout;

use crate::map::{
    Csr, FRAME_BASE_MASK, HEX_HI_MASK, HEX_LO_MASK, ID_MAGIC, ID_VERSION_VGA, KEYS_DOWN, KEYS_PRESSED, LEDS_MASK,
    SWITCHES_MASK, VGA_CONTROL_ENABLE, VGA_CONTROL_LETTERBOX, VGA_STATUS_FLAGS, VGA_STATUS_FRAMES,
    VGA_STATUS_READ_ERROR, VGA_STATUS_STALL, VGA_STATUS_UNDERRUN,
};
use crate::port::RegisterPort;

/// Segment bits of a 7-segment digit: bit 0 = segment a (top) .. bit 6 =
/// g (middle), clockwise from the top (a, b, c, d, e, f), 1 = lit.
pub mod seg {
    /// Top.
    pub const A: u8 = 1 << 0;
    /// Top right.
    pub const B: u8 = 1 << 1;
    /// Bottom right.
    pub const C: u8 = 1 << 2;
    /// Bottom.
    pub const D: u8 = 1 << 3;
    /// Bottom left.
    pub const E: u8 = 1 << 4;
    /// Top left.
    pub const F: u8 = 1 << 5;
    /// Middle.
    pub const G: u8 = 1 << 6;
}

/// The segments that show `c`, or `None` for a character the displays
/// cannot show: `0-9`, `A-F` (either case; `b` and `d` lower case as
/// usual), `H`, `I`, `L`, `n`, `o`, `P`, `r`, `S`, `t`, `U`, `u`, `y`, `-`,
/// `_`, space (blank) and `.`. The DE1-SoC's displays have no decimal
/// point: `.` lights segment d alone, low like a point (as `_` does).
pub const fn segments(c: u8) -> Option<u8> {
    use seg::*;
    Some(match c {
        b'0' | b'O' => A | B | C | D | E | F,
        b'1' | b'I' => B | C,
        b'2' => A | B | D | E | G,
        b'3' => A | B | C | D | G,
        b'4' => B | C | F | G,
        b'5' | b'S' | b's' => A | C | D | F | G,
        b'6' => A | C | D | E | F | G,
        b'7' => A | B | C,
        b'8' => A | B | C | D | E | F | G,
        b'9' => A | B | C | D | F | G,
        b'A' | b'a' => A | B | C | E | F | G,
        b'B' | b'b' => C | D | E | F | G,
        b'C' => A | D | E | F,
        b'c' => D | E | G,
        b'D' | b'd' => B | C | D | E | G,
        b'E' | b'e' => A | D | E | F | G,
        b'F' | b'f' => A | E | F | G,
        b'H' | b'h' => B | C | E | F | G,
        b'L' | b'l' => D | E | F,
        b'N' | b'n' => C | E | G,
        b'o' => C | D | E | G,
        b'P' | b'p' => A | B | E | F | G,
        b'R' | b'r' => E | G,
        b'T' | b't' => D | E | F | G,
        b'U' => B | C | D | E | F,
        b'u' => C | D | E,
        b'Y' | b'y' => B | C | D | F | G,
        b'-' => G,
        b'_' | b'.' => D,
        b' ' => 0,
        _ => return None,
    })
}

/// VGA_STATUS as read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VgaStatus {
    /// Frames scanned out since enable (wrapping at 16 bits).
    pub frames: u16,
    /// A line was cut since enable or the last clear.
    pub underrun: bool,
    /// A read beat came back SLVERR or DECERR since enable or the last
    /// clear.
    pub read_error: bool,
    /// The reader gave up on a port that answered nothing (stall limit).
    pub stalled: bool,
}

/// KEYS as read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Keys {
    /// Keys held down now (bit n: KEYn).
    pub down: u8,
    /// Keys that went down since last cleared (bit n: KEYn).
    pub pressed: u8,
}

/// Why [`BoardIo::open`] refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoBoardIo {
    /// No ray tracer answered: the ID register read this.
    NotPresent {
        /// The ID register.
        id: u32,
    },
    /// A ray tracer whose register map predates the VGA block.
    OldMap {
        /// Its map version.
        version: u16,
    },
}

impl core::fmt::Display for NoBoardIo {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            NoBoardIo::NotPresent { id } => write!(f, "no ray tracer answers (ID {id:#010x})"),
            NoBoardIo::OldMap { version } => {
                write!(f, "register map version {version} has no VGA or board I/O (needs {ID_VERSION_VGA})")
            }
        }
    }
}

/// The VGA scan-out, keys, switches, LEDs and 7-segment displays behind
/// `P`.
#[derive(Debug)]
pub struct BoardIo<P> {
    port: P,
}

/// Whether ID register value `id` names a ray tracer with the VGA and board
/// I/O block.
pub const fn has_board_io(id: u32) -> bool {
    id >> 16 == ID_MAGIC as u32 && (id & 0xffff) as u16 >= ID_VERSION_VGA
}

impl<P: RegisterPort> BoardIo<P> {
    /// The block behind `port`, if its ID register says map version 3 or
    /// later. Reads ID only.
    pub fn open(mut port: P) -> Result<BoardIo<P>, NoBoardIo> {
        let id = port.read(Csr::Id);
        if id >> 16 != u32::from(ID_MAGIC) {
            return Err(NoBoardIo::NotPresent { id });
        }
        match (id & 0xffff) as u16 {
            v if v >= ID_VERSION_VGA => Ok(BoardIo { port }),
            version => Err(NoBoardIo::OldMap { version }),
        }
    }

    /// The block behind `port`, whose ID the caller has already checked
    /// ([`has_board_io`]); touches nothing.
    pub fn checked(port: P) -> BoardIo<P> {
        BoardIo { port }
    }

    /// The port back.
    pub fn into_inner(self) -> P {
        self.port
    }

    /// Scan frames out in `layout` (enabling restarts the frame counter at
    /// 0 and clears the underrun; already enabled, only the layout changes).
    pub fn enable(&mut self, layout: Layout) {
        let letterbox = match layout {
            Layout::FullScreen => 0,
            Layout::Letterbox => VGA_CONTROL_LETTERBOX,
        };
        self.port.write(Csr::VgaControl, VGA_CONTROL_ENABLE | letterbox);
    }

    /// Stop the scan-out: blank, black, counter 0.
    pub fn disable(&mut self) {
        self.port.write(Csr::VgaControl, 0);
    }

    /// The layout while enabled, `None` while disabled.
    pub fn layout(&mut self) -> Option<Layout> {
        let control = self.port.read(Csr::VgaControl);
        (control & VGA_CONTROL_ENABLE != 0).then_some(if control & VGA_CONTROL_LETTERBOX != 0 {
            Layout::Letterbox
        } else {
            Layout::FullScreen
        })
    }

    /// Show the frame at bus address `base` (8-byte aligned: bits 2:0 are
    /// dropped) from the next vertical blanking on.
    pub fn show(&mut self, base: u32) {
        self.port.write(Csr::VgaBase, base & FRAME_BASE_MASK);
    }

    /// The base last written.
    pub fn base(&mut self) -> u32 {
        self.port.read(Csr::VgaBase)
    }

    /// The frame counter and the sticky flags.
    pub fn status(&mut self) -> VgaStatus {
        let s = self.port.read(Csr::VgaStatus);
        VgaStatus {
            frames: (s & VGA_STATUS_FRAMES) as u16,
            underrun: s & VGA_STATUS_UNDERRUN != 0,
            read_error: s & VGA_STATUS_READ_ERROR != 0,
            stalled: s & VGA_STATUS_STALL != 0,
        }
    }

    /// Clear the sticky flags (underrun, read error, stall).
    pub fn clear_flags(&mut self) {
        self.port.write(Csr::VgaStatus, VGA_STATUS_FLAGS);
    }

    /// The keys.
    pub fn keys(&mut self) -> Keys {
        let k = self.port.read(Csr::Keys);
        Keys { down: (k & KEYS_DOWN) as u8, pressed: ((k & KEYS_PRESSED) >> 4) as u8 }
    }

    /// Clear the pressed flags of `keys` (bit n: KEYn).
    pub fn clear_pressed(&mut self, keys: u8) {
        self.port.write(Csr::Keys, (u32::from(keys) << 4) & KEYS_PRESSED);
    }

    /// The keys, their pressed flags cleared (only those read as set, so a
    /// press in between is not lost).
    pub fn take_keys(&mut self) -> Keys {
        let k = self.keys();
        if k.pressed != 0 {
            self.clear_pressed(k.pressed);
        }
        k
    }

    /// The switches (bit n: SWn up).
    pub fn switches(&mut self) -> u16 {
        (self.port.read(Csr::Switches) & SWITCHES_MASK) as u16
    }

    /// Light the LEDs (bit n: LEDRn; bits above 9 ignored).
    pub fn set_leds(&mut self, leds: u16) {
        self.port.write(Csr::Leds, u32::from(leds) & LEDS_MASK);
    }

    /// The LEDs as last written.
    pub fn leds(&mut self) -> u16 {
        (self.port.read(Csr::Leds) & LEDS_MASK) as u16
    }

    /// Set the six displays' segments, `digits[n]` on HEXn (HEX0 is the
    /// rightmost), [`seg`] bits.
    pub fn set_digits(&mut self, digits: [u8; 6]) {
        let lo = u32::from_le_bytes([digits[0], digits[1], digits[2], digits[3]]) & HEX_LO_MASK;
        let hi = u32::from_le_bytes([digits[4], digits[5], 0, 0]) & HEX_HI_MASK;
        self.port.write(Csr::HexLo, lo);
        self.port.write(Csr::HexHi, hi);
    }

    /// The six displays' segments as last written, HEX0 first.
    pub fn digits(&mut self) -> [u8; 6] {
        let [a, b, c, d] = self.port.read(Csr::HexLo).to_le_bytes();
        let [e, f, _, _] = self.port.read(Csr::HexHi).to_le_bytes();
        [a, b, c, d, e, f]
    }

    /// Show `text` (ASCII, left to right: `text[0]` on HEX5) in the
    /// [`segments`] font; characters it lacks are blank.
    pub fn set_text(&mut self, text: [u8; 6]) {
        let mut digits = [0; 6];
        for (i, c) in text.into_iter().enumerate() {
            digits[5 - i] = segments(c).unwrap_or_default();
        }
        self.set_digits(digits);
    }
}

/// The block as the monitor policy's panel.
#[cfg(feature = "services")]
impl<P: RegisterPort> rt_services::monitor::Panel for BoardIo<P> {
    fn refreshes(&mut self) -> rt_services::monitor::Refreshes {
        let s = self.status();
        rt_services::monitor::Refreshes { count: s.frames, underrun: s.underrun, port_fault: s.read_error || s.stalled }
    }

    fn show(&mut self, base: u32) {
        BoardIo::show(self, base)
    }

    fn scan_out(&mut self, layout: Layout) {
        self.enable(layout)
    }

    fn inputs(&mut self) -> rt_services::monitor::Inputs {
        let keys = self.take_keys();
        rt_services::monitor::Inputs { down: keys.down, pressed: keys.pressed, switches: self.switches() }
    }

    fn set_leds(&mut self, leds: u16) {
        BoardIo::set_leds(self, leds)
    }

    fn set_text(&mut self, text: [u8; 6]) {
        BoardIo::set_text(self, text)
    }
}
