//! The board on its own: what the VGA monitor, the keys, the switches, the
//! LEDs and the 7-segment displays do (map version 3), as plain logic.
//!
//! Like the frame server it touches no hardware: [`Monitor::poll`] works on
//! a device that is a [`FrameSource`] (the frames), a [`Screen`] (the frame
//! ring's newest frame and pins) and a [`Panel`] (the board's registers),
//! and returns a [`Report`] once a second for the log.
//!
//! * **Scan-out** ([`Scanout`]): `VGA_BASE` names the newest complete frame,
//!   whichever request it was rendered for. A frame written there is
//!   *pending* until the display's refresh counter has moved after the
//!   write (the base is latched at the start of vertical blanking, the
//!   moment the counter moves); then it is *on screen* and the frame shown
//!   before is released. Both slots are pinned in the ring meanwhile, and
//!   a new base is written only while nothing is pending: at most one write
//!   per refresh, at most two slots pinned.
//! * **Attract mode** ([`Orbit`]): with no client request for
//!   [`RESUME_AFTER`], the monitor renders frames itself, one per refresh
//!   at most, the light orbiting the sphere as `rt-client orbit` moves it
//!   (radius 3, height 4 by default, starting on +x). Switches and keys:
//!
//!   | input | effect |
//!   |---|---|
//!   | SW4..SW0 | speed: `(SW[4:0] + 4) / 32` turns per second (all down: one turn in 8 s) |
//!   | SW9..SW5 | height: `4 + SW[9:5] / 4` world units (all down: 4) |
//!   | KEY0 | pause / run (a press) |
//!   | KEY1 | held: turn backward at twice the speed (paused too) |
//!   | KEY2 | held: turn forward at twice the speed (paused too) |
//!   | KEY3 | full screen / letterbox (a press) |
//!
//! * **7-segment displays** ([`Text`]): the board's IPv4 address, scrolling
//!   from right to left once, for the first seconds after the link comes up
//!   with its name first ([`name_and_address_text`]); then the frames per second the monitor shows, new
//!   frames that took effect ([`fps_text`], e.g. ` 60FPS`).
//! * **Caption** ([`caption`]): the board's name and address on attract
//!   mode's frames for [`caption::CAPTION_FOR`] after it reaches a new
//!   address (or takes a new name), bottom left, so that whoever looks at
//!   the monitor knows where to connect; clients' frames are never touched.
//! * **LEDs** ([`leds`]): [`LED_LINK`] (LEDR0), [`LED_FPGA`] (LEDR1),
//!   [`LED_SELF_TEST`] (LEDR2), [`LED_CLIENTS`] (LEDR3), [`LED_ATTRACT`]
//!   (LEDR4), [`LED_PAUSED`] (LEDR5), [`LED_UNDERRUN`] (LEDR9).

use core::fmt::{self, Write as _};
use core::time::Duration;

use model::display::Layout;
use model::{Light, ROW_BYTES};

use crate::frames::{Completed, FrameEngine, FrameMemory, FrameRing, FrameSource, ROWS};
use crate::time::Instant;

pub mod caption;
pub mod code;

pub use caption::Caption;
pub use code::Code;

/// Client requests keep attract mode off this long after the last one.
pub const RESUME_AFTER: Duration = Duration::from_secs(3);

/// Time per step of the scrolling address.
pub const ADDRESS_STEP: Duration = Duration::from_millis(250);

/// How often [`Monitor::poll`] returns a [`Report`].
pub const REPORT_EVERY: Duration = Duration::from_secs(1);

/// Characters on the six 7-segment displays.
pub const DIGITS: usize = 6;

/// LEDR0: the Ethernet link is up.
pub const LED_LINK: u16 = 1 << 0;
/// LEDR1: the FPGA renders (off: the software renderer).
pub const LED_FPGA: u16 = 1 << 1;
/// LEDR2: the accelerator passed the boot self-test.
pub const LED_SELF_TEST: u16 = 1 << 2;
/// LEDR3: at least one client is connected.
pub const LED_CLIENTS: u16 = 1 << 3;
/// LEDR4: attract mode: the board renders for the monitor itself.
pub const LED_ATTRACT: u16 = 1 << 4;
/// LEDR5: the attract orbit is paused (KEY0).
pub const LED_PAUSED: u16 = 1 << 5;
/// LEDR9: the scan-out has cut a line since it was enabled (underrun).
pub const LED_UNDERRUN: u16 = 1 << 9;

/// KEY0..KEY3 as bits of [`Inputs`].
pub const KEY0: u8 = 1 << 0;
/// KEY1.
pub const KEY1: u8 = 1 << 1;
/// KEY2.
pub const KEY2: u8 = 1 << 2;
/// KEY3.
pub const KEY3: u8 = 1 << 3;

/// Fabric clocks per display refresh over the fabric clock rate, 840,000 /
/// 50 MHz = 21 / 1,250 s (hal-avalon `VGA_FRAME_CLOCKS`, `FABRIC_HZ`).
const REFRESH_NUM: u64 = 21;
const REFRESH_DEN: u64 = 1_250;

/// The board's keys and switches as the policy sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Inputs {
    /// Keys held down now (bit n: KEYn).
    pub down: u8,
    /// Keys that went down since the last read (bit n: KEYn).
    pub pressed: u8,
    /// Switches up (bit n: SWn).
    pub switches: u16,
}

/// The display's counter and error flag (VGA_STATUS).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Refreshes {
    /// Refreshes since the scan-out was enabled (wrapping).
    pub count: u16,
    /// A line was cut since the scan-out was enabled.
    pub underrun: bool,
    /// The memory port failed the reader since the scan-out was enabled: a
    /// read answered with an error, or reads given up after the stall limit
    /// (VGA_STATUS bits 17 and 18; the port held in reset, for one).
    pub port_fault: bool,
}

/// The board's display and I/O registers (hal-avalon's `BoardIo` on map
/// version 3; a fake in tests).
pub trait Panel {
    /// The display's counter (0 until enabled).
    fn refreshes(&mut self) -> Refreshes;
    /// Show the frame at bus address `base` from the next vertical blanking.
    fn show(&mut self, base: u32);
    /// Scan out (enabling the display if it was off: the counter restarts
    /// at 0) in `layout`.
    fn scan_out(&mut self, layout: Layout);
    /// Keys and switches; clears the pressed keys it reports.
    fn inputs(&mut self) -> Inputs;
    /// Light the LEDs (bit n: LEDRn).
    fn set_leds(&mut self, leds: u16);
    /// Show `text` on the 7-segment displays, HEX5 (left) first: ASCII,
    /// characters the displays cannot show are blank.
    fn set_text(&mut self, text: [u8; DIGITS]);
}

/// What the display needs of the frames: the ring's newest complete frame
/// and its pins ([`FrameRing`]).
pub trait Screen {
    /// The newest complete frame, while its slot holds it.
    fn newest_complete(&self) -> Option<Completed>;
    /// Keep `slot` out of reuse.
    fn pin(&mut self, slot: usize);
    /// Let `slot` be reused.
    fn unpin(&mut self, slot: usize);
    /// Bus address of `slot`.
    fn slot_address(&self, slot: usize) -> u32;
    /// Change row `y` of the complete, not yet ended frame in `slot` in
    /// place ([`FrameRing::edit_row`]).
    fn edit_row(&mut self, slot: usize, y: u16, edit: &mut dyn FnMut(&mut [u8; ROW_BYTES]));
}

impl<M: FrameMemory, E: FrameEngine<M>, const SLOTS: usize> Screen for FrameRing<M, E, SLOTS> {
    fn newest_complete(&self) -> Option<Completed> {
        FrameRing::newest_complete(self)
    }
    fn pin(&mut self, slot: usize) {
        FrameRing::pin(self, slot)
    }
    fn unpin(&mut self, slot: usize) {
        FrameRing::unpin(self, slot)
    }
    fn slot_address(&self, slot: usize) -> u32 {
        FrameRing::slot_address(self, slot)
    }
    fn edit_row(&mut self, slot: usize, y: u16, edit: &mut dyn FnMut(&mut [u8; ROW_BYTES])) {
        FrameRing::edit_row(self, slot, y, edit)
    }
}

// ---- Scan-out ---------------------------------------------------------------------

/// What happened in one [`Scanout::poll`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScanStep {
    /// Refreshes counted since the last poll.
    pub refreshes: u32,
    /// The frame that took effect (went on screen), if one did.
    pub shown: Option<Completed>,
    /// A newer frame was written to `VGA_BASE` (now pending).
    pub written: Option<Completed>,
}

/// `VGA_BASE` following the newest complete frame, the slot on screen and
/// the pending one pinned.
#[derive(Clone, Copy, Debug, Default)]
pub struct Scanout {
    on_screen: Option<Completed>,
    /// Written to `VGA_BASE`, and the counter read right after the write.
    pending: Option<(Completed, u16)>,
    /// The counter at the last poll; `None` while disabled.
    last: Option<u16>,
    layout: Layout,
    underrun: bool,
    port_fault: bool,
    refreshes: u64,
    shown: u64,
}

impl Scanout {
    /// Disabled, nothing shown, full screen.
    pub const fn new() -> Scanout {
        Scanout {
            on_screen: None,
            pending: None,
            last: None,
            layout: Layout::FullScreen,
            underrun: false,
            port_fault: false,
            refreshes: 0,
            shown: 0,
        }
    }

    /// The frame on screen.
    pub fn on_screen(&self) -> Option<Completed> {
        self.on_screen
    }

    /// The frame written to `VGA_BASE`, waiting for vertical blanking.
    pub fn pending(&self) -> Option<Completed> {
        self.pending.map(|(c, _)| c)
    }

    /// Whether the scan-out is enabled (after the first frame).
    pub fn enabled(&self) -> bool {
        self.last.is_some()
    }

    /// Refreshes since enabled.
    pub fn refreshes(&self) -> u64 {
        self.refreshes
    }

    /// Frames that took effect since enabled.
    pub fn shown(&self) -> u64 {
        self.shown
    }

    /// The layout.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Whether the display has reported an underrun.
    pub fn underrun(&self) -> bool {
        self.underrun
    }

    /// Whether the display has reported a read error or a stalled port.
    pub fn port_fault(&self) -> bool {
        self.port_fault
    }

    /// Change the layout (written at once while enabled, else at enable).
    pub fn set_layout(&mut self, panel: &mut impl Panel, layout: Layout) {
        if layout != self.layout {
            self.layout = layout;
            if self.enabled() {
                panel.scan_out(layout);
            }
        }
    }

    /// Count refreshes; a pending frame whose refresh came is on screen (the
    /// one before is unpinned); with nothing pending, a newer complete frame
    /// is pinned and written to `VGA_BASE` (the first one enables the
    /// scan-out).
    pub fn poll<D: Screen + Panel>(&mut self, dev: &mut D) -> ScanStep {
        let mut step = ScanStep::default();
        if let Some(last) = self.last {
            let r = dev.refreshes();
            self.underrun |= r.underrun;
            self.port_fault |= r.port_fault;
            step.refreshes = u32::from(r.count.wrapping_sub(last));
            self.refreshes += u64::from(step.refreshes);
            self.last = Some(r.count);
            if let Some((frame, at)) = self.pending {
                if r.count != at {
                    self.pending = None;
                    if let Some(old) = self.on_screen.replace(frame) {
                        if old.slot != frame.slot {
                            dev.unpin(old.slot);
                        }
                    }
                    self.shown += 1;
                    step.shown = Some(frame);
                }
            }
        }
        if self.pending.is_none() {
            if let Some(newest) = dev.newest_complete() {
                if self.on_screen.is_none_or(|s| s.seq != newest.seq) {
                    dev.pin(newest.slot);
                    dev.show(dev.slot_address(newest.slot));
                    if self.last.is_none() {
                        dev.scan_out(self.layout);
                    }
                    // Read after the write: if the counter moved in between,
                    // the frame may already be on screen, and is taken for
                    // pending one refresh longer (never the other way).
                    let at = dev.refreshes().count;
                    if self.last.is_none() {
                        self.last = Some(at);
                    }
                    self.pending = Some((newest, at));
                    step.written = Some(newest);
                }
            }
        }
        step
    }
}

// ---- Attract mode: the orbit ------------------------------------------------------

/// The attract-mode light: an orbit around the y axis, radius 3, as
/// `rt-client orbit` moves it, driven by the switches and keys (module
/// docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Orbit {
    /// The angle from +x towards +z, in 2^-32 turns.
    angle: u32,
    paused: bool,
    layout: Layout,
}

/// Orbit radius, world units (`rt-client orbit`'s default).
pub const ORBIT_RADIUS: f64 = 3.0;

impl Orbit {
    /// On +x, running, full screen.
    pub const fn new() -> Orbit {
        Orbit { angle: 0, paused: false, layout: Layout::FullScreen }
    }

    /// The angle, in 2^-32 turns.
    pub fn angle(&self) -> u32 {
        self.angle
    }

    /// Whether KEY0 paused it.
    pub fn paused(&self) -> bool {
        self.paused
    }

    /// The layout KEY3 chose.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Key presses: KEY0 pauses or resumes, KEY3 toggles the layout.
    pub fn keys(&mut self, pressed: u8) {
        if pressed & KEY0 != 0 {
            self.paused = !self.paused;
        }
        if pressed & KEY3 != 0 {
            self.layout = match self.layout {
                Layout::FullScreen => Layout::Letterbox,
                Layout::Letterbox => Layout::FullScreen,
            };
        }
    }

    /// The angle step per refresh at `switches`' speed, in 2^-32 turns:
    /// `(SW[4:0] + 4) / 32` turns per second.
    pub fn step_per_refresh(switches: u16) -> u32 {
        let speed = u64::from(switches & 0x1f) + 4;
        ((speed << 32) * REFRESH_NUM / (32 * REFRESH_DEN)) as u32
    }

    /// The light's height at `switches`: `4 + SW[9:5] / 4` world units.
    pub fn height(switches: u16) -> f64 {
        4.0 + f64::from((switches >> 5) & 0x1f) / 4.0
    }

    /// Let `refreshes` display refreshes pass with keys `down` held and
    /// `switches` set.
    pub fn advance(&mut self, refreshes: u32, down: u8, switches: u16) {
        let rate: i64 = if down & KEY1 != 0 {
            -2
        } else if down & KEY2 != 0 {
            2
        } else if self.paused {
            0
        } else {
            1
        };
        let step = i64::from(Self::step_per_refresh(switches)) * rate * i64::from(refreshes);
        self.angle = self.angle.wrapping_add(step as u32);
    }

    /// The light now (`switches` set the height); always `Some`: radius 3
    /// and heights up to 11.75 are far inside the light's range.
    pub fn light(&self, switches: u16) -> Option<Light> {
        let (sin, cos) = sin_cos(self.angle);
        let (x, y, z) = (ORBIT_RADIUS * cos, Self::height(switches), ORBIT_RADIUS * sin);
        Light::from_world(x, y, z).ok()
    }
}

/// Sine and cosine of `angle` 2^-32 turns, to about 1e-7 (no `libm` in a
/// `no_std` crate): reduced to a quarter turn around 0, then Taylor series.
pub fn sin_cos(angle: u32) -> (f64, f64) {
    // The quadrant and the angle within it, centred: [-1/8, 1/8) turn.
    let shifted = angle.wrapping_add(1 << 29);
    let quadrant = shifted >> 30;
    let rest = (shifted & ((1 << 30) - 1)) as f64 - f64::from(1u32 << 29);
    let x = rest / 4_294_967_296.0 * core::f64::consts::TAU;
    let x2 = x * x;
    let s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0))));
    let c = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0)));
    match quadrant {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

// ---- Text and LEDs ----------------------------------------------------------------

/// Six characters for the 7-segment displays, HEX5 first.
pub type Text = [u8; DIGITS];

/// A buffer `write!` fills, cut at [`DIGITS`] characters.
struct TextBuf {
    text: Text,
    len: usize,
}

impl fmt::Write for TextBuf {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for b in s.bytes() {
            if self.len < DIGITS {
                self.text[self.len] = b;
                self.len += 1;
            }
        }
        Ok(())
    }
}

/// `fps` frames per second: ` 60FPS`, `  7FPS`, `999FPS` at most.
pub fn fps_text(fps: u32) -> Text {
    let mut t = TextBuf { text: [b' '; DIGITS], len: 0 };
    let _ = write!(t, "{:>3}FPS", fps.min(999));
    t.text
}

/// The address as it scrolls: step `step` of `a.b.c.d` entering from the
/// right, one character per step, until it has left on the left; `None`
/// once it has gone (after `len + 6` steps).
pub fn address_text(addr: [u8; 4], step: u64) -> Option<Text> {
    name_and_address_text("", addr, step)
}

/// The board's name and address as they scroll: `name.local a.b.c.d` (the
/// address alone without a name), as [`address_text`] scrolls the
/// address. Letters the displays cannot show (hal-avalon `board::segments`:
/// g, k, m, q, v, w, x, z among them) pass as blanks.
pub fn name_and_address_text(name: &str, addr: [u8; 4], step: u64) -> Option<Text> {
    let mut line = heapless::String::<{ SCROLL_BYTES }>::new();
    // The name is cut to fit; the address always does.
    let name = name.get(..name.len().min(SCROLL_BYTES - 24)).unwrap_or("");
    let _ = match name {
        "" => write!(line, "{}.{}.{}.{}", addr[0], addr[1], addr[2], addr[3]),
        _ => write!(line, "{name}.local {}.{}.{}.{}", addr[0], addr[1], addr[2], addr[3]),
    };
    let bytes = line.as_bytes();
    let len = bytes.len() as u64;
    if step >= len + DIGITS as u64 {
        return None;
    }
    let mut text = [b' '; DIGITS];
    for (i, c) in text.iter_mut().enumerate() {
        // Display i shows character (step + i - 6) of the line.
        let at = (step + i as u64).checked_sub(DIGITS as u64);
        if let Some(at) = at.filter(|a| *a < len) {
            *c = bytes[at as usize];
        }
    }
    Some(text)
}

/// Bytes of the longest scrolled line: a 63-byte mDNS label, `.local`, a
/// space and a dotted quad, with room to spare.
const SCROLL_BYTES: usize = 96;

/// What the firmware knows that the LEDs, the displays and the caption
/// show.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Status<'a> {
    /// The Ethernet link is up.
    pub link_up: bool,
    /// The FPGA renders frames (not switched off).
    pub fpga: bool,
    /// The boot self-test passed.
    pub self_test_passed: bool,
    /// Clients connected.
    pub clients: usize,
    /// The board's IPv4 address.
    pub address: [u8; 4],
    /// The board's host name (mDNS, without `.local`: `raytracer`).
    pub name: &'a str,
    /// What is wrong: shown on the 7-segment displays after the address.
    pub code: Code,
}

/// The LED bits for `status`, attract mode `attract`, the orbit `paused`,
/// an `underrun` seen.
pub fn leds(status: &Status<'_>, attract: bool, paused: bool, underrun: bool) -> u16 {
    let bit = |on: bool, b: u16| if on { b } else { 0 };
    bit(status.link_up, LED_LINK)
        | bit(status.fpga, LED_FPGA)
        | bit(status.self_test_passed, LED_SELF_TEST)
        | bit(status.clients > 0, LED_CLIENTS)
        | bit(attract, LED_ATTRACT)
        | bit(paused, LED_PAUSED)
        | bit(underrun, LED_UNDERRUN)
}

// ---- The whole policy -------------------------------------------------------------

/// Frames shown per second: new frames that took effect, counted over
/// whole seconds.
#[derive(Clone, Copy, Debug, Default)]
pub struct FpsCounter {
    window_start: Option<Instant>,
    in_window: u32,
    fps: u32,
}

impl FpsCounter {
    /// Nothing counted yet: 0 frames per second.
    pub const fn new() -> FpsCounter {
        FpsCounter { window_start: None, in_window: 0, fps: 0 }
    }

    /// `shown` more frames took effect by `now`; the rate of the last whole
    /// second.
    pub fn count(&mut self, now: Instant, shown: u32) -> u32 {
        let start = *self.window_start.get_or_insert(now);
        let elapsed = now.saturating_duration_since(start);
        if elapsed >= Duration::from_secs(2) {
            // Polled too rarely for whole seconds: the average.
            let ms = u64::try_from(elapsed.as_millis()).unwrap_or(u64::MAX);
            self.fps = u32::try_from(u64::from(self.in_window) * 1000 / ms).unwrap_or(u32::MAX);
            self.in_window = 0;
            self.window_start = Some(now);
        } else if elapsed >= Duration::from_secs(1) {
            self.fps = self.in_window;
            self.in_window = 0;
            self.window_start = Some(start + Duration::from_secs(1));
        }
        self.in_window += shown;
        self.fps
    }
}

/// Who a frame on screen was rendered for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// A network client's request.
    Client,
    /// Attract mode.
    Attract,
    /// Attract mode, with the board's name and address on it.
    AttractCaptioned,
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Origin::Client => "a client",
            Origin::Attract => "attract mode",
            Origin::AttractCaptioned => "attract mode, captioned",
        })
    }
}

/// The once-a-second summary for the log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Report {
    /// Frames that took effect since the scan-out was enabled.
    pub shown: u64,
    /// Display refreshes since enabled.
    pub refreshes: u64,
    /// The layout.
    pub layout: Layout,
    /// Frames per second on the display (last whole second).
    pub fps: u32,
    /// Attract mode on.
    pub attract: bool,
    /// The frame on screen, and who it was rendered for.
    pub on_screen: Option<(Light, Origin)>,
    /// The display cut a line since it was enabled.
    pub underrun: bool,
    /// The display's memory port failed (a read error or the stall limit).
    pub port_fault: bool,
}

impl fmt::Display for Report {
    /// `display: N frames shown, M refreshes, layout full, F fps, attract
    /// on, on screen: light (x, y, z) from a client`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let layout = match self.layout {
            Layout::FullScreen => "full",
            Layout::Letterbox => "letterbox",
        };
        write!(
            f,
            "display: {} frames shown, {} refreshes, layout {layout}, {} fps, attract {}",
            self.shown,
            self.refreshes,
            self.fps,
            if self.attract { "on" } else { "off" }
        )?;
        if let Some((light, origin)) = self.on_screen {
            let [x, y, z] = light.raw();
            write!(f, ", on screen: light ({x}, {y}, {z}) from {origin}")?;
        }
        if self.underrun {
            f.write_str(", underrun")?;
        }
        if self.port_fault {
            // docs/board-bring-up.md: the FPGA-to-SDRAM port out of reset.
            f.write_str(", memory port fault (check fpgaportrst)")?;
        }
        Ok(())
    }
}

/// The board's display, keys, switches, LEDs and 7-segment displays.
#[derive(Debug)]
pub struct Monitor {
    scanout: Scanout,
    orbit: Orbit,
    fps: FpsCounter,
    /// Attract mode's frame in progress (its slot), and its light.
    attract_frame: Option<(usize, Light)>,
    /// Attract frames completed, by completion number, newest last (to tell
    /// them from client frames on screen), and whether each was captioned.
    attract_done: [Option<(u32, bool)>; 4],
    /// Client requests seen, and when the count last moved.
    requests: u32,
    last_request: Option<Instant>,
    /// When the board last became reachable at a new address (the link up
    /// and an address it had not shown): the address scrolls from then.
    link_up_at: Option<Instant>,
    /// The scroll from `link_up_at` has gone by (the text is not made
    /// again on every poll).
    scrolled: bool,
    link_was_up: bool,
    /// The address last scrolled.
    address_shown: [u8; 4],
    /// The name and address on attract frames, until `caption_until`.
    caption: Caption,
    caption_until: Option<Instant>,
    /// The name in the caption (a new one draws it again).
    caption_name: heapless::String<{ caption::NAME_BYTES }>,
    leds: Option<u16>,
    text: Option<Text>,
    next_report: Option<Instant>,
}

impl Default for Monitor {
    fn default() -> Monitor {
        Monitor::new()
    }
}

impl Monitor {
    /// Attract mode on, nothing shown yet.
    pub const fn new() -> Monitor {
        Monitor {
            scanout: Scanout::new(),
            orbit: Orbit::new(),
            fps: FpsCounter::new(),
            attract_frame: None,
            attract_done: [None; 4],
            requests: 0,
            last_request: None,
            link_up_at: None,
            scrolled: false,
            link_was_up: false,
            address_shown: [0; 4],
            caption: Caption::new(),
            caption_until: None,
            caption_name: heapless::String::new(),
            leds: None,
            text: None,
            next_report: None,
        }
    }

    /// The scan-out state.
    pub fn scanout(&self) -> &Scanout {
        &self.scanout
    }

    /// The attract orbit.
    pub fn orbit(&self) -> &Orbit {
        &self.orbit
    }

    /// Whether attract mode is on at `now`: no client request for
    /// [`RESUME_AFTER`].
    pub fn attract(&self, now: Instant) -> bool {
        self.last_request.is_none_or(|t| now.saturating_duration_since(t) >= RESUME_AFTER)
    }

    /// One step of the main loop at `now`: `requests` counts the client
    /// requests begun so far (wrapping), `status` what the LEDs show.
    /// Attract frames are begun on `dev` as one more [`FrameSource`] user.
    /// Returns a [`Report`] every [`REPORT_EVERY`] once the display runs.
    pub fn poll<D>(&mut self, now: Instant, dev: &mut D, requests: u32, status: &Status<'_>) -> Option<Report>
    where
        D: FrameSource<Frame = usize> + Screen + Panel,
    {
        if requests != self.requests {
            self.requests = requests;
            self.last_request = Some(now);
        }
        self.track_address(now, status);
        self.track_caption(now, status);

        let inputs = dev.inputs();
        self.orbit.keys(inputs.pressed);
        self.scanout.set_layout(dev, self.orbit.layout());
        self.attract_progress(now, dev);
        let step = self.scanout.poll(dev);
        let attract = self.attract(now);
        if attract {
            self.orbit.advance(step.refreshes, inputs.down, inputs.switches);
        }
        self.attract_next(dev, attract, inputs.switches);
        let fps = self.fps.count(now, u32::from(step.shown.is_some()));

        let leds = leds(status, attract, self.orbit.paused(), self.scanout.underrun());
        self.show(now, dev, status, leds, fps);

        if !self.scanout.enabled() {
            return None;
        }
        let due = *self.next_report.get_or_insert(now + REPORT_EVERY);
        if now < due {
            return None;
        }
        self.next_report = Some(now + REPORT_EVERY);
        Some(self.report(now))
    }

    /// The LEDs and 7-segment displays alone, where the scan-out cannot
    /// run (the FPGA renders rows but cannot reach the frame memory, code
    /// [`Code::RowsOnly`]): the address scrolls, then the fault code
    /// stays; no attract mode.
    pub fn poll_panel<D: Panel>(&mut self, now: Instant, dev: &mut D, status: &Status<'_>) {
        self.track_address(now, status);
        let leds = leds(status, false, false, false);
        self.show(now, dev, status, leds, 0);
    }

    /// The address scrolls once the board has one on a link: DHCP (or the
    /// link-local claim) answers after the link comes up, and a new lease
    /// scrolls again.
    fn track_address(&mut self, now: Instant, status: &Status<'_>) {
        let reachable = status.link_up && status.address != [0; 4];
        if reachable && (!self.link_was_up || status.address != self.address_shown) {
            self.link_up_at = Some(now);
            self.scrolled = false;
            self.address_shown = status.address;
        }
        self.link_was_up = reachable;
    }

    /// The caption is drawn when the board becomes reachable at a new
    /// address (the moment the address starts to scroll) or takes a new
    /// name, and stays on attract frames for [`caption::CAPTION_FOR`].
    fn track_caption(&mut self, now: Instant, status: &Status<'_>) {
        let renamed = self.caption_name.as_str() != caption::fitting(status.name);
        // A rename while the board is unreachable waits for the address.
        if self.link_up_at == Some(now) || (renamed && self.link_up_at.is_some() && self.link_was_up) {
            self.caption.draw(status.name, status.address);
            self.caption_name.clear();
            // As cut to the line: `NAME_BYTES` hold it.
            let _ = self.caption_name.push_str(caption::fitting(status.name));
            self.caption_until = Some(now + caption::CAPTION_FOR);
        }
        if self.caption_until.is_some_and(|t| now >= t) {
            self.caption.clear();
            self.caption_until = None;
        }
    }

    /// Whether attract frames carry the caption now.
    pub fn captioning(&self) -> bool {
        self.caption.is_drawn()
    }

    /// Write the LEDs and the text where they changed: the address while
    /// it scrolls, then the fault code, or else the frames per second.
    fn show<D: Panel>(&mut self, now: Instant, dev: &mut D, status: &Status<'_>, leds: u16, fps: u32) {
        if self.leds != Some(leds) {
            dev.set_leds(leds);
            self.leds = Some(leds);
        }
        let scroll = self.link_up_at.filter(|_| !self.scrolled).and_then(|t| {
            let step = now.saturating_duration_since(t).as_millis() / ADDRESS_STEP.as_millis();
            name_and_address_text(status.name, status.address, u64::try_from(step).unwrap_or(u64::MAX))
        });
        self.scrolled = self.link_up_at.is_some() && scroll.is_none();
        let text = scroll.or_else(|| status.code.hex_text()).unwrap_or_else(|| fps_text(fps));
        if self.text != Some(text) {
            dev.set_text(text);
            self.text = Some(text);
        }
    }

    /// The summary at `now`.
    pub fn report(&self, now: Instant) -> Report {
        let on_screen = self.scanout.on_screen().map(|c| {
            let origin = match self.attract_done.iter().flatten().find(|(seq, _)| *seq == c.seq) {
                Some((_, true)) => Origin::AttractCaptioned,
                Some((_, false)) => Origin::Attract,
                None => Origin::Client,
            };
            (c.light, origin)
        });
        Report {
            shown: self.scanout.shown(),
            refreshes: self.scanout.refreshes(),
            layout: self.scanout.layout(),
            fps: self.fps.fps,
            attract: self.attract(now),
            on_screen,
            underrun: self.scanout.underrun(),
            port_fault: self.scanout.port_fault(),
        }
    }

    /// Attract mode's frame in progress: rows landed (the ring learns of
    /// completion here); a failed one is dropped.
    /// The caption goes onto a frame here, once, before the scan-out can
    /// see it (the scan-out polls after this in [`Monitor::poll`]).
    fn attract_progress<D: FrameSource<Frame = usize> + Screen>(&mut self, now: Instant, dev: &mut D) {
        let Some((slot, light)) = self.attract_frame else { return };
        match dev.rows_ready(slot) {
            Ok(rows) if rows < ROWS => {}
            Ok(_) => {
                if let Some(n) = dev.newest_complete().filter(|n| n.slot == slot && n.light == light) {
                    if !self.attract_done.iter().flatten().any(|(seq, _)| *seq == n.seq) {
                        let captioned = self.caption_until.is_some_and(|t| now < t);
                        if captioned {
                            let caption = &self.caption;
                            for y in caption.rows() {
                                dev.edit_row(slot, y, &mut |row| caption.stamp_row(y, row));
                            }
                        }
                        self.attract_done.rotate_left(1);
                        self.attract_done[self.attract_done.len() - 1] = Some((n.seq, captioned));
                    }
                }
            }
            Err(_) => {
                dev.end(slot);
                self.attract_frame = None;
            }
        }
    }

    /// Attract mode's own frames: a complete one is let go once the display
    /// has taken it (pinned) or a newer frame replaced it; a new one is
    /// begun when attract mode is on, nothing is pending on the display,
    /// and the light moved since the frame on screen: a frame per refresh
    /// at most.
    fn attract_next<D>(&mut self, dev: &mut D, attract: bool, switches: u16)
    where
        D: FrameSource<Frame = usize> + Screen,
    {
        if let Some((slot, light)) = self.attract_frame {
            match dev.rows_ready(slot) {
                Ok(rows) if rows >= ROWS => {
                    let taken = |c: Option<Completed>, seq: u32| c.is_some_and(|c| c.seq == seq);
                    let waiting =
                        dev.newest_complete().filter(|n| n.slot == slot && n.light == light).is_some_and(|n| {
                            !taken(self.scanout.pending(), n.seq) && !taken(self.scanout.on_screen(), n.seq)
                        });
                    if waiting {
                        return;
                    }
                    dev.end(slot);
                    self.attract_frame = None;
                }
                Ok(_) => return,
                Err(_) => {
                    dev.end(slot);
                    self.attract_frame = None;
                }
            }
        }
        if !attract || self.scanout.pending().is_some() {
            return;
        }
        let Some(light) = self.orbit.light(switches) else { return };
        if self.scanout.on_screen().is_some_and(|c| c.light == light) {
            return;
        }
        if let Ok(Some(slot)) = dev.begin(&light) {
            self.attract_frame = Some((slot, light));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::SliceMemory;
    use model::FRAME_BYTES;

    /// An engine that lands a whole frame per progress call and writes
    /// nothing.
    struct Instantly;

    impl FrameEngine<SliceMemory<'_>> for Instantly {
        type Error = &'static str;
        fn start(&mut self, _: &mut SliceMemory<'_>, _: usize, _: &Light) -> Result<(), &'static str> {
            Ok(())
        }
        fn progress(&mut self, _: &mut SliceMemory<'_>) -> Result<u16, &'static str> {
            Ok(ROWS)
        }
    }

    #[derive(Default)]
    struct FakePanel {
        count: u16,
        base: Option<u32>,
        control: Option<Layout>,
        enables: u32,
        inputs: Inputs,
        leds: u16,
        text: Text,
    }

    impl Panel for FakePanel {
        fn refreshes(&mut self) -> Refreshes {
            Refreshes { count: self.count, ..Refreshes::default() }
        }
        fn show(&mut self, base: u32) {
            self.base = Some(base);
        }
        fn scan_out(&mut self, layout: Layout) {
            if self.control.is_none() {
                self.enables += 1;
                self.count = 0;
            }
            self.control = Some(layout);
        }
        fn inputs(&mut self) -> Inputs {
            let i = self.inputs;
            self.inputs.pressed = 0;
            i
        }
        fn set_leds(&mut self, leds: u16) {
            self.leds = leds;
        }
        fn set_text(&mut self, text: Text) {
            self.text = text;
        }
    }

    /// A ring and a panel as one device, as the firmware puts them together.
    struct Dev<'m> {
        ring: FrameRing<SliceMemory<'m>, Instantly, 6>,
        panel: FakePanel,
    }

    impl FrameSource for Dev<'_> {
        type Frame = usize;
        type Error = &'static str;
        fn begin(&mut self, light: &Light) -> Result<Option<usize>, &'static str> {
            self.ring.begin(light)
        }
        fn rows_ready(&mut self, f: usize) -> Result<u16, &'static str> {
            self.ring.rows_ready(f)
        }
        fn copy_row(&mut self, f: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
            self.ring.copy_row(f, y, offset, out)
        }
        fn end(&mut self, f: usize) {
            self.ring.end(f)
        }
    }

    impl Screen for Dev<'_> {
        fn newest_complete(&self) -> Option<Completed> {
            self.ring.newest_complete()
        }
        fn pin(&mut self, slot: usize) {
            self.ring.pin(slot)
        }
        fn unpin(&mut self, slot: usize) {
            self.ring.unpin(slot)
        }
        fn slot_address(&self, slot: usize) -> u32 {
            self.ring.slot_address(slot)
        }
        fn edit_row(&mut self, slot: usize, y: u16, edit: &mut dyn FnMut(&mut [u8; ROW_BYTES])) {
            self.ring.edit_row(slot, y, edit)
        }
    }

    impl Panel for Dev<'_> {
        fn refreshes(&mut self) -> Refreshes {
            self.panel.refreshes()
        }
        fn show(&mut self, base: u32) {
            self.panel.show(base)
        }
        fn scan_out(&mut self, layout: Layout) {
            self.panel.scan_out(layout)
        }
        fn inputs(&mut self) -> Inputs {
            self.panel.inputs()
        }
        fn set_leds(&mut self, leds: u16) {
            self.panel.set_leds(leds)
        }
        fn set_text(&mut self, text: Text) {
            self.panel.set_text(text)
        }
    }

    const BASE: u32 = 0x0410_0000;

    fn dev(mem: &mut [u8]) -> Dev<'_> {
        Dev { ring: FrameRing::new(SliceMemory::new(BASE, mem), Instantly), panel: FakePanel::default() }
    }

    fn light(x: i32) -> Light {
        Light::from_raw(x, 4096, -2048).unwrap()
    }

    /// A client's whole frame: begun, rendered, ended.
    fn client_frame(d: &mut Dev<'_>, l: &Light) -> usize {
        let f = d.ring.begin(l).unwrap().unwrap();
        assert_eq!(d.ring.rows_ready(f).unwrap(), ROWS);
        d.ring.end(f);
        f
    }

    fn addr(slot: usize) -> u32 {
        BASE + (slot * FRAME_BYTES) as u32
    }

    #[test]
    fn the_newest_frame_is_pinned_written_and_on_screen_after_the_next_refresh() {
        let mut mem = vec![0u8; 6 * FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut s = Scanout::new();
        assert_eq!(s.poll(&mut d), ScanStep::default(), "no frame: nothing written, display off");
        assert_eq!(d.panel.enables, 0);

        let a = client_frame(&mut d, &light(1000));
        let step = s.poll(&mut d);
        assert_eq!(step.written.map(|c| c.slot), Some(a));
        assert_eq!((d.panel.base, d.panel.enables), (Some(addr(a)), 1), "base written, then enabled");
        assert!(d.ring.is_pinned(a), "pending: pinned");
        assert_eq!(s.poll(&mut d), ScanStep::default(), "no refresh yet: still pending");

        let b = client_frame(&mut d, &light(2000));
        assert_ne!(a, b);
        assert_eq!(s.poll(&mut d).written, None, "a is pending: b waits");
        assert!(!d.ring.is_pinned(b));

        d.panel.count += 1;
        let step = s.poll(&mut d);
        assert_eq!(step.shown.map(|c| c.slot), Some(a), "a took effect");
        assert_eq!(step.written.map(|c| c.slot), Some(b), "and b is written right after");
        assert_eq!((s.on_screen().map(|c| c.slot), s.pending().map(|c| c.slot)), (Some(a), Some(b)));
        assert!(d.ring.is_pinned(a) && d.ring.is_pinned(b), "on screen and pending: both pinned");
        assert_eq!(d.panel.base, Some(addr(b)));

        d.panel.count += 2;
        let step = s.poll(&mut d);
        assert_eq!((step.refreshes, step.shown.map(|c| c.slot)), (2, Some(b)));
        assert!(!d.ring.is_pinned(a), "a released once b is on screen");
        assert!(d.ring.is_pinned(b));
        assert_eq!((s.shown(), s.refreshes()), (2, 3));

        d.panel.count += 1;
        assert_eq!(s.poll(&mut d).shown, None, "nothing new: the same frame stays");
        assert_eq!(d.ring.free_slots(), 5, "only the frame on screen is out of use");
    }

    #[test]
    fn at_most_two_slots_are_pinned_however_fast_frames_complete() {
        let mut mem = vec![0u8; 6 * FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut s = Scanout::new();
        for k in 0..50 {
            client_frame(&mut d, &light(100 * k));
            s.poll(&mut d);
            if k % 3 == 0 {
                d.panel.count = d.panel.count.wrapping_add(1);
            }
            let pinned = (0..6).filter(|&i| d.ring.is_pinned(i)).count();
            assert!(pinned <= 2, "{pinned} pinned");
            assert!(d.ring.free_slots() >= 4);
        }
    }

    #[test]
    fn the_layout_is_written_when_it_changes() {
        let mut mem = vec![0u8; FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut s = Scanout::new();
        s.set_layout(&mut d, Layout::Letterbox);
        assert_eq!(d.panel.control, None, "not enabled yet: taken at enable");
        client_frame(&mut d, &light(0));
        s.poll(&mut d);
        assert_eq!(d.panel.control, Some(Layout::Letterbox));
        s.set_layout(&mut d, Layout::FullScreen);
        assert_eq!((d.panel.control, d.panel.enables), (Some(Layout::FullScreen), 1));
    }

    #[test]
    fn sin_cos_is_accurate() {
        for k in 0..4096u32 {
            let angle = k.wrapping_mul(1_048_573).wrapping_add(k * 7);
            let t = f64::from(angle) / 4_294_967_296.0 * std::f64::consts::TAU;
            let (s, c) = sin_cos(angle);
            assert!((s - t.sin()).abs() < 1e-7 && (c - t.cos()).abs() < 1e-7, "angle {angle}: {s} {c}");
        }
    }

    #[test]
    fn the_orbit_follows_rt_client_orbits_path() {
        // rt-client orbit: light k of n at angle k/n turn, radius 3, height 4.
        for k in 0..48u32 {
            let mut o = Orbit::new();
            o.angle = ((u64::from(k) << 32) / 48) as u32;
            let t = std::f64::consts::TAU * f64::from(k) / 48.0;
            let want = Light::from_world(3.0 * t.cos(), 4.0, 3.0 * t.sin()).unwrap().raw();
            let got = o.light(0).unwrap().raw();
            for (g, w) in got.into_iter().zip(want) {
                assert!((g - w).abs() <= 1, "k {k}: {got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn switches_set_speed_and_height() {
        let turn = 4_294_967_296.0;
        // All down: 1/8 turn per second, 59.52 refreshes per second.
        let per_second = f64::from(Orbit::step_per_refresh(0)) * 1250.0 / 21.0 / turn;
        assert!((per_second - 0.125).abs() < 1e-6, "{per_second}");
        let fastest = f64::from(Orbit::step_per_refresh(0x1f)) * 1250.0 / 21.0 / turn;
        assert!((fastest - 35.0 / 32.0).abs() < 1e-6);
        assert_eq!(Orbit::step_per_refresh(0x3e0), Orbit::step_per_refresh(0), "height switches only");
        assert_eq!((Orbit::height(0), Orbit::height(1 << 5), Orbit::height(0x3e0)), (4.0, 4.25, 11.75));
        assert_eq!(Orbit::new().light(0x3e0).unwrap().raw(), [3072, 12032, 0]);
    }

    #[test]
    fn keys_pause_turn_and_switch_the_layout() {
        let mut o = Orbit::new();
        let step = Orbit::step_per_refresh(0);
        o.advance(10, 0, 0);
        assert_eq!(o.angle(), 10 * step);
        o.keys(KEY0);
        assert!(o.paused());
        o.advance(10, 0, 0);
        assert_eq!(o.angle(), 10 * step, "paused");
        o.advance(5, KEY1, 0);
        assert_eq!(o.angle(), 0, "KEY1 held: backward at twice the speed, paused or not");
        o.advance(1, KEY1, 0);
        assert_eq!(o.angle(), (2 * step).wrapping_neg(), "past +x backwards");
        o.advance(1, KEY2, 0);
        assert_eq!(o.angle(), 0, "KEY2 held: forward at twice the speed");
        o.keys(KEY0);
        o.advance(1, KEY2, 0);
        assert_eq!(o.angle(), 2 * step, "running: KEY2 still twice the speed");
        assert_eq!(o.layout(), Layout::FullScreen);
        o.keys(KEY3);
        assert_eq!(o.layout(), Layout::Letterbox);
        o.keys(KEY3 | KEY0);
        assert_eq!((o.layout(), o.paused()), (Layout::FullScreen, true));
    }

    #[test]
    fn fps_and_address_text() {
        assert_eq!(&fps_text(60), b" 60FPS");
        assert_eq!(&fps_text(7), b"  7FPS");
        assert_eq!(&fps_text(5000), b"999FPS");
        let a = [192, 168, 1, 200];
        assert_eq!(&address_text(a, 0).unwrap(), b"      ");
        assert_eq!(&address_text(a, 1).unwrap(), b"     1");
        assert_eq!(&address_text(a, 6).unwrap(), b"192.16");
        assert_eq!(&address_text(a, 13).unwrap(), b".1.200");
        assert_eq!(&address_text(a, 18).unwrap(), b"0     ", "the last character leaving");
        assert_eq!(address_text(a, 19), None, "13 characters + 6: gone");
        // With a name: `raytracer.local 192.168.1.200`, 29 characters.
        let at = |step| name_and_address_text("raytracer", a, step);
        assert_eq!(&at(6).unwrap(), b"raytra");
        assert_eq!(&at(15).unwrap(), b".local");
        assert_eq!(&at(21).unwrap(), b" 192.1");
        assert_eq!(&at(34).unwrap(), b"0     ");
        assert_eq!(at(35), None, "29 characters + 6: gone");
        let long = "x".repeat(200);
        assert_eq!(
            &name_and_address_text(&long, a, 80).unwrap(),
            b"ocal 1",
            "a long name is cut, the address still shown"
        );
        assert_eq!(address_text([10, 0, 2, 15], 15), None);
    }

    #[test]
    fn fps_counts_frames_shown_per_whole_second() {
        let mut f = FpsCounter::new();
        for ms in 0..1000 {
            assert_eq!(f.count(Instant::from_millis(ms), u32::from(ms % 20 == 0)), 0, "first second");
        }
        assert_eq!(f.count(Instant::from_millis(1000), 0), 50);
        assert_eq!(f.count(Instant::from_millis(2000), 0), 0);
        assert_eq!(f.count(Instant::from_millis(9000), 0), 0);
    }

    #[test]
    fn led_bits() {
        let s = Status {
            link_up: true,
            fpga: true,
            self_test_passed: true,
            clients: 2,
            address: [0; 4],
            name: "",
            code: Code::Ok,
        };
        assert_eq!(leds(&s, false, false, false), 0b1111);
        assert_eq!(leds(&Status::default(), true, true, true), (1 << 4) | (1 << 5) | (1 << 9));
        let sw = Status { fpga: false, clients: 0, ..s };
        assert_eq!(leds(&sw, true, false, false), LED_LINK | LED_SELF_TEST | LED_ATTRACT);
    }

    #[test]
    fn in_row_mode_the_panel_shows_the_address_then_the_code_and_never_scans_out() {
        let mut panel = FakePanel::default();
        let mut m = Monitor::new();
        let status =
            Status { link_up: true, fpga: true, address: [10, 0, 2, 15], code: Code::RowsOnly, ..Status::default() };
        m.poll_panel(Instant::from_millis(0), &mut panel, &status);
        assert_eq!(&panel.text, b"      ", "the address scrolls first");
        assert_eq!(panel.leds, LED_LINK | LED_FPGA);
        m.poll_panel(Instant::from_millis(6 * 250), &mut panel, &status);
        assert_eq!(&panel.text, b"10.0.2");
        m.poll_panel(Instant::from_millis(30 * 250), &mut panel, &status);
        assert_eq!(&panel.text, b"Err  4", "then the code stays");
        assert_eq!((panel.enables, panel.base), (0, None), "no scan-out");
    }

    #[test]
    fn a_fault_code_replaces_the_frame_rate() {
        let mut mem = vec![0u8; 6 * FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut m = Monitor::new();
        let status = Status { code: Code::NoLink, ..Status::default() };
        m.poll(Instant::from_millis(0), &mut d, 0, &status);
        assert_eq!(&d.panel.text, b"Err  5");
    }

    #[test]
    fn the_address_shows_after_link_up_then_the_frame_rate() {
        let mut mem = vec![0u8; 6 * FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut m = Monitor::new();
        let mut status = Status { address: [10, 0, 2, 15], ..Status::default() };
        m.poll(Instant::from_millis(0), &mut d, 0, &status);
        assert_eq!(&d.panel.text, b"  0FPS", "no link: the frame rate");
        status.link_up = true;
        m.poll(Instant::from_millis(100), &mut d, 0, &status);
        assert_eq!(&d.panel.text, b"      ", "the address starts scrolling in");
        m.poll(Instant::from_millis(100 + 6 * 250), &mut d, 0, &status);
        assert_eq!(&d.panel.text, b"10.0.2");
        m.poll(Instant::from_millis(100 + 15 * 250), &mut d, 0, &status);
        assert_eq!(&d.panel.text[..3], b"  0", "gone: the frame rate again");
        assert_eq!(d.panel.leds & LED_LINK, LED_LINK);
    }

    #[test]
    fn the_address_scrolls_when_it_arrives_after_the_link_and_again_when_it_changes() {
        let mut mem = vec![0u8; 6 * FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut m = Monitor::new();
        let mut status = Status { link_up: true, ..Status::default() };
        m.poll(Instant::from_millis(0), &mut d, 0, &status);
        assert_eq!(&d.panel.text, b"  0FPS", "a link but no address yet (DHCP asking)");
        status.address = [169, 254, 7, 9];
        m.poll(Instant::from_millis(5_000), &mut d, 0, &status);
        m.poll(Instant::from_millis(5_000 + 7 * 250), &mut d, 0, &status);
        assert_eq!(&d.panel.text, b"69.254", "the link-local address, once claimed");
        m.poll(Instant::from_millis(30_000), &mut d, 0, &status);
        assert_eq!(&d.panel.text[..3], b"  0");
        status.address = [10, 0, 2, 15];
        m.poll(Instant::from_millis(31_000), &mut d, 0, &status);
        m.poll(Instant::from_millis(31_000 + 6 * 250), &mut d, 0, &status);
        assert_eq!(&d.panel.text, b"10.0.2", "a lease replaced it: shown again");
    }

    #[test]
    fn attract_mode_renders_for_the_display_and_pauses_for_clients() {
        let mut mem = vec![0u8; 6 * FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut m = Monitor::new();
        let status = Status::default();
        let at = Instant::from_millis;
        // Boot: attract mode renders the first orbit frame, which is shown.
        assert!(m.attract(at(0)));
        m.poll(at(0), &mut d, 0, &status);
        m.poll(at(1), &mut d, 0, &status);
        assert_eq!(m.scanout().pending().map(|c| c.light), Orbit::new().light(0));
        assert_eq!(d.panel.leds & LED_ATTRACT, LED_ATTRACT);
        // A frame per refresh while the light moves.
        let mut t = 2;
        for _ in 0..10 {
            d.panel.count += 1;
            m.poll(at(t), &mut d, 0, &status);
            m.poll(at(t + 1), &mut d, 0, &status);
            t += 17;
        }
        assert_eq!(m.scanout().shown(), 10);
        assert!(m.scanout().on_screen().unwrap().light != Orbit::new().light(0).unwrap(), "the light moved");
        let pinned = (0..6).filter(|&i| d.ring.is_pinned(i)).count();
        assert_eq!(pinned, 2);

        // A client's request: attract mode stops, the client's frame goes up.
        let client = light(-3000);
        let f = d.ring.begin(&client).unwrap().unwrap();
        m.poll(at(t), &mut d, 1, &status);
        assert!(!m.attract(at(t)));
        assert_eq!(d.ring.rows_ready(f).unwrap(), ROWS);
        d.ring.end(f);
        for _ in 0..3 {
            d.panel.count += 1;
            m.poll(at(t + 1), &mut d, 1, &status);
        }
        assert_eq!(m.scanout().on_screen().map(|c| c.light), Some(client), "the client's frame is on screen");
        let angle = m.orbit().angle();
        d.panel.count += 100;
        m.poll(at(t + 2_999), &mut d, 1, &status);
        assert_eq!(m.orbit().angle(), angle, "the orbit waits while clients drive the light");
        assert_eq!(m.scanout().on_screen().map(|c| c.light), Some(client));
        m.poll(at(t + 3_000), &mut d, 1, &status);
        let report = m.report(at(t + 3_000));
        assert!(report.attract, "resumed 3 s after the last request");
        assert_eq!(report.on_screen, Some((client, Origin::Client)));
        assert_eq!(
            report.to_string(),
            format!(
                "display: {} frames shown, {} refreshes, layout full, {} fps, attract on, on screen: light (-3000, 4096, -2048) from a client",
                report.shown, report.refreshes, report.fps
            )
        );
        for _ in 0..3 {
            d.panel.count += 1;
            m.poll(at(t + 3_001), &mut d, 1, &status);
        }
        let report = m.report(at(t + 3_001));
        assert_eq!(report.on_screen.map(|(_, o)| o), Some(Origin::Attract));
        assert_eq!(d.ring.free_slots(), 4, "on screen and pending only");
    }

    /// Rows `rows` of `slot` hold only `byte`.
    fn plain(d: &mut Dev<'_>, slot: usize, rows: core::ops::Range<u16>, byte: u8) -> bool {
        let mut row = [0u8; ROW_BYTES];
        rows.into_iter().all(|y| {
            d.ring.memory().read_row(slot, y, 0, &mut row);
            row.iter().all(|b| *b == byte)
        })
    }

    /// Every slot's bytes set to `byte`.
    fn fill(d: &mut Dev<'_>, byte: u8) {
        for slot in 0..6 {
            for y in 0..ROWS {
                d.ring.memory().write_row(slot, y, &[byte; ROW_BYTES]);
            }
        }
    }

    #[test]
    fn attract_frames_carry_the_name_and_address_for_their_first_seconds_and_clients_frames_never() {
        let mut mem = vec![0x80u8; 6 * FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut m = Monitor::new();
        let at = Instant::from_millis;
        let mut status = Status { link_up: true, address: [192, 168, 1, 57], name: "raytracer", ..Status::default() };
        let caption_rows = caption::FIRST_ROW..caption::FIRST_ROW + caption::BOX_ROWS as u16;
        // A refresh per poll, 17 ms apart, from poll `from`.
        let run = |m: &mut Monitor, d: &mut Dev<'_>, from: u64, polls: u64, requests: u32, status: &Status<'_>| {
            for t in from..from + polls {
                d.panel.count += 1;
                m.poll(at(t * 17), d, requests, status);
            }
        };
        run(&mut m, &mut d, 0, 4, 0, &status);
        assert!(m.captioning());
        let on_screen = m.scanout().on_screen().expect("an attract frame is on screen");
        assert!(!plain(&mut d, on_screen.slot, caption_rows.clone(), 0x80), "the frame on screen carries the caption");
        let report = m.report(at(4 * 17));
        assert_eq!(report.on_screen.map(|(_, o)| o), Some(Origin::AttractCaptioned));
        assert!(report.to_string().ends_with("from attract mode, captioned"), "{report}");
        assert!(plain(&mut d, on_screen.slot, 0..caption_rows.start, 0x80), "only the caption's rows change");
        assert!(plain(&mut d, on_screen.slot, caption_rows.end..ROWS, 0x80), "only the caption's rows change");
        let mut row = [0u8; ROW_BYTES];
        d.ring.memory().read_row(on_screen.slot, caption_rows.start + 12, 0, &mut row);
        assert!(row.contains(&0xff) && row.contains(&0x20), "white text on a darkened box");

        // A client's frame in the window is never stamped.
        fill(&mut d, 0x80);
        let client = client_frame(&mut d, &light(-3000));
        run(&mut m, &mut d, 4, 3, 1, &status);
        assert_eq!(m.scanout().on_screen().map(|c| c.slot), Some(client));
        assert!(plain(&mut d, client, 0..ROWS, 0x80), "the client's frame is as rendered");

        // Past the window (attract mode back on too): frames as rendered.
        let start = caption::CAPTION_FOR.as_millis() as u64 / 17 + 1;
        run(&mut m, &mut d, start, 4, 1, &status);
        assert!(!m.captioning());
        assert_eq!(m.report(at(start * 17)).on_screen.map(|(_, o)| o), Some(Origin::Attract));
        assert!((0..6).all(|s| plain(&mut d, s, 0..ROWS, 0x80)), "no caption after {:?}", caption::CAPTION_FOR);

        // A new address draws it again.
        status.address = [10, 0, 0, 9];
        run(&mut m, &mut d, start + 4, 4, 1, &status);
        assert!(m.captioning());
        let on_screen = m.scanout().on_screen().expect("an attract frame is on screen");
        assert!(!plain(&mut d, on_screen.slot, caption_rows, 0x80), "captioned again at a new address");

        // A new name (mDNS found another board by that name) draws it again
        // for another window; a name longer than the line only once.
        let before = m.caption_until;
        let long = "a-board-name-that-is-much-longer-than-the-line-holds-2";
        status.name = long;
        run(&mut m, &mut d, start + 8, 1, 1, &status);
        assert!(m.caption_until > before, "renamed: a new window");
        assert_eq!(m.caption_name.as_str(), caption::fitting(long));
        let drawn = m.caption_until;
        run(&mut m, &mut d, start + 9, 3, 1, &status);
        assert_eq!(m.caption_until, drawn, "the same long name is not drawn again");
    }

    #[test]
    fn the_report_names_a_memory_port_fault() {
        let r = Report {
            shown: 1,
            refreshes: 2,
            layout: Layout::FullScreen,
            fps: 0,
            attract: false,
            on_screen: None,
            underrun: true,
            port_fault: true,
        };
        assert_eq!(
            r.to_string(),
            "display: 1 frames shown, 2 refreshes, layout full, 0 fps, attract off, underrun, memory port fault (check fpgaportrst)"
        );
    }

    #[test]
    fn a_paused_orbit_renders_nothing_new_and_key3_switches_the_layout() {
        let mut mem = vec![0u8; 6 * FRAME_BYTES];
        let mut d = dev(&mut mem);
        let mut m = Monitor::new();
        let status = Status::default();
        let at = Instant::from_millis;
        d.panel.inputs.pressed = KEY0;
        m.poll(at(0), &mut d, 0, &status);
        for k in 1..10 {
            d.panel.count += 1;
            m.poll(at(k * 17), &mut d, 0, &status);
        }
        assert_eq!(m.scanout().shown(), 1, "paused: one frame, then nothing new");
        assert_eq!(d.panel.leds & LED_PAUSED, LED_PAUSED);
        d.panel.inputs.pressed = KEY3;
        m.poll(at(200), &mut d, 0, &status);
        assert_eq!(d.panel.control, Some(Layout::Letterbox));
    }
}
