//! The board I/O driver against the simulated accelerator: the VGA
//! scan-out's registers and counter, keys, switches, LEDs and 7-segment
//! displays, and the driver as the monitor policy's panel.

use hal_avalon::board::{has_board_io, seg, segments, BoardIo, Keys, NoBoardIo, VgaStatus};
use hal_avalon::map::{
    Csr, ID_VALUE, KEY_DEBOUNCE_CLOCKS, LINE_WORDS, VGA_FRAME_CLOCKS, VGA_STATUS_READ_ERROR, VGA_STATUS_STALL,
    VGA_STATUS_UNDERRUN,
};
use hal_avalon::sim::SimAccelerator;
use hal_avalon::RegisterPort;
use model::display::Layout;
use rt_services::monitor::{Inputs, Panel, Refreshes};

/// A port whose ID register reads `id` and nothing else answers.
struct IdOnly(u32);

impl RegisterPort for IdOnly {
    fn read(&mut self, csr: Csr) -> u32 {
        if csr == Csr::Id {
            self.0
        } else {
            0
        }
    }
    fn write(&mut self, _: Csr, _: u32) {}
    fn read_line(&mut self, _: &mut [u32; LINE_WORDS]) {}
}

#[test]
fn open_needs_map_version_3() {
    assert!(has_board_io(ID_VALUE));
    assert!(!has_board_io(0x5254_0002));
    assert!(BoardIo::open(SimAccelerator::new()).is_ok(), "the simulated device reports version 3");
    assert_eq!(BoardIo::open(IdOnly(0x5254_0002)).err(), Some(NoBoardIo::OldMap { version: 2 }));
    assert_eq!(BoardIo::open(IdOnly(0xffff_ffff)).err(), Some(NoBoardIo::NotPresent { id: 0xffff_ffff }));
    assert!(BoardIo::open(IdOnly(0x5254_0004)).is_ok(), "later versions keep the block");
}

#[test]
fn the_scan_out_counts_refreshes_from_enable() {
    let mut io = BoardIo::open(SimAccelerator::new()).unwrap();
    assert_eq!(io.layout(), None, "off after reset");
    io.show(0x0410_0007);
    assert_eq!(io.base(), 0x0410_0000, "bits 2:0 dropped");
    io.enable(Layout::FullScreen);
    assert_eq!(io.layout(), Some(Layout::FullScreen));
    let mut sim = io.into_inner();
    sim.pass_clocks(3 * VGA_FRAME_CLOCKS + 5);
    let mut io = BoardIo::checked(sim);
    assert_eq!(io.status(), VgaStatus { frames: 3, ..VgaStatus::default() });
    io.enable(Layout::Letterbox);
    assert_eq!(io.layout(), Some(Layout::Letterbox));
    assert_eq!(io.status().frames, 3, "a layout change keeps the counter");
    io.clear_flags();
    io.disable();
    assert_eq!(io.layout(), None);
    io.enable(Layout::FullScreen);
    assert_eq!(io.status().frames, 0, "enable restarts the counter");
}

#[test]
fn the_scan_out_flags_read_back_reach_the_monitor_and_clear() {
    let mut sim = SimAccelerator::new();
    let mut io = BoardIo::checked(&mut sim);
    io.enable(Layout::FullScreen);
    sim.report_vga_fault(VGA_STATUS_READ_ERROR | VGA_STATUS_UNDERRUN);
    let mut io = BoardIo::checked(&mut sim);
    assert_eq!(io.status(), VgaStatus { underrun: true, read_error: true, ..VgaStatus::default() });
    assert_eq!(Panel::refreshes(&mut io), Refreshes { count: 0, underrun: true, port_fault: true });
    io.clear_flags();
    assert_eq!(io.status(), VgaStatus::default(), "write 1 clears each");
    sim.report_vga_fault(VGA_STATUS_STALL);
    let mut io = BoardIo::checked(&mut sim);
    assert_eq!(io.status(), VgaStatus { stalled: true, ..VgaStatus::default() });
    assert!(Panel::refreshes(&mut io).port_fault, "a stalled port is a fault");
    io.disable();
    io.enable(Layout::FullScreen);
    assert_eq!(io.status(), VgaStatus::default(), "enable clears the flags");
}

#[test]
fn keys_are_down_and_pressed_until_cleared() {
    let mut sim = SimAccelerator::new();
    sim.set_board_inputs(0b0101, 0x2a5);
    sim.pass_clocks(KEY_DEBOUNCE_CLOCKS);
    let mut io = BoardIo::checked(&mut sim);
    assert_eq!(io.switches(), 0x2a5);
    assert_eq!(io.keys(), Keys { down: 0b0101, pressed: 0b0101 });
    assert_eq!(io.take_keys(), Keys { down: 0b0101, pressed: 0b0101 });
    assert_eq!(io.keys(), Keys { down: 0b0101, pressed: 0 }, "pressed cleared, still down");
    sim.set_board_inputs(0, 0);
    sim.pass_clocks(KEY_DEBOUNCE_CLOCKS);
    let mut io = BoardIo::checked(&mut sim);
    assert_eq!(io.keys(), Keys::default());
    sim.set_board_inputs(0b1000, 0);
    sim.pass_clocks(KEY_DEBOUNCE_CLOCKS);
    sim.set_board_inputs(0, 0);
    sim.pass_clocks(KEY_DEBOUNCE_CLOCKS);
    let mut io = BoardIo::checked(&mut sim);
    assert_eq!(io.keys(), Keys { down: 0, pressed: 0b1000 }, "a press between two reads is kept");
    io.clear_pressed(0b0001);
    assert_eq!(io.keys().pressed, 0b1000, "only the keys named are cleared");
}

#[test]
fn leds_and_digits_read_back() {
    let mut io = BoardIo::open(SimAccelerator::new()).unwrap();
    io.set_leds(0xffff);
    assert_eq!(io.leds(), 0x3ff, "ten LEDs");
    io.set_digits([0x01, 0x02, 0x04, 0x08, 0x10, 0xff]);
    assert_eq!(io.digits(), [0x01, 0x02, 0x04, 0x08, 0x10, 0x7f], "seven segments each");
    io.set_text(*b"10.0.2");
    let d = io.digits();
    assert_eq!(d[5], segments(b'1').unwrap(), "HEX5 is the leftmost");
    assert_eq!(d[0], segments(b'2').unwrap());
    assert_eq!(d[3], seg::D, "'.' lights segment d");
    io.set_text(*b"?~ 8 -");
    assert_eq!(io.digits(), [seg::G, 0, 0x7f, 0, 0, 0], "unknown characters are blank");
}

#[test]
fn the_font() {
    use seg::*;
    let digits = [0x3f, 0x06, 0x5b, 0x4f, 0x66, 0x6d, 0x7d, 0x07, 0x7f, 0x6f];
    for (c, want) in (b'0'..=b'9').zip(digits) {
        assert_eq!(segments(c), Some(want), "{}", c as char);
    }
    let hex = [0x77, 0x7c, 0x39, 0x5e, 0x79, 0x71];
    for (c, want) in b"AbCdEF".iter().zip(hex) {
        assert_eq!(segments(*c), Some(want), "{}", *c as char);
    }
    assert_eq!(segments(b'-'), Some(G));
    assert_eq!(segments(b' '), Some(0));
    assert_eq!(segments(b'P'), Some(A | B | E | F | G));
    assert_eq!(segments(b'S'), segments(b'5'));
    assert_eq!(segments(b'#'), None);
    for c in 0..=255u8 {
        assert!(segments(c).is_none_or(|s| s < 0x80), "seven bits");
    }
}

#[test]
fn the_driver_is_the_monitor_policys_panel() {
    let mut sim = SimAccelerator::new();
    sim.set_board_inputs(0b0010, 0x21);
    sim.pass_clocks(KEY_DEBOUNCE_CLOCKS);
    let mut io = BoardIo::checked(&mut sim);
    assert_eq!(Panel::inputs(&mut io), Inputs { down: 0b0010, pressed: 0b0010, switches: 0x21 });
    assert_eq!(Panel::inputs(&mut io).pressed, 0, "reported once");
    Panel::show(&mut io, 0x0420_0000);
    Panel::scan_out(&mut io, Layout::Letterbox);
    Panel::set_leds(&mut io, 0b1011);
    Panel::set_text(&mut io, *b" 60FPS");
    sim.pass_clocks(2 * VGA_FRAME_CLOCKS);
    let board = *sim.board();
    assert_eq!((board.vga_base, board.vga_control, board.leds), (0x0420_0000, 0b11, 0b1011));
    let mut io = BoardIo::checked(&mut sim);
    assert_eq!(Panel::refreshes(&mut io), Refreshes { count: 2, ..Refreshes::default() });
    assert_eq!(io.digits()[0], segments(b'S').unwrap());
}
