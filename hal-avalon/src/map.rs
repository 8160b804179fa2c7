//! The register map: the contract between the firmware and the FPGA.
//!
//! This module is the single source of truth for every address, offset and
//! bit of the accelerator; `fpga/` implements the same numbers.
//!
//! # Windows inside the lightweight bridge
//!
//! | window | bridge offset | size | contents |
//! |---|---|---|---|
//! | CSR block | [`CSR_OFFSET`] `0x0000` | 20 registers (`0x00..=0x4C`) | [`Csr`] |
//! | line buffer | [`LINE_BUFFER_OFFSET`] `0x1000` | [`LINE_WORDS`] x 32 bit | pixel `x` at `0x1000 + 4 * x`, word `0x00RRGGBB` |
//!
//! Every register is 32 bits wide and word aligned. Offsets of the bridge
//! window outside the twenty registers and the 480 line-buffer words are not
//! part of the contract, except that unmapped offsets of the CSR block read 0.
//!
//! Map version 2 adds the frame DMA (`0x1C..=0x28`) to version 1's row
//! registers (`0x00..=0x18`, unchanged): the ID register tells a driver which
//! it has ([`ID_VERSION_FRAMES`]). The frame abort and the stall limit
//! ([Stopping a frame](#stopping-a-frame)) belong to version 2: no
//! version 2 bitstream without them was ever released. Map version 3 adds
//! the VGA scan-out and the board I/O block (`0x2C..=0x48`,
//! [`ID_VERSION_VGA`]); earlier registers are unchanged. `BUILD_ID`
//! (`0x4C`) came later without a new version: it was an unmapped offset
//! before, which reads 0, the value that says "no build id recorded".
//!
//! # CSR block
//!
//! | offset | name | access | meaning |
//! |---|---|---|---|
//! | `0x00` | [`Csr::Control`] | W | bit 0 [`CONTROL_START`]: start a row (pulse; also clears a latched done); bit 1 [`CONTROL_CLEAR_DONE`]: clear done. Other bits ignored; with both bits set, start wins. Reads return 0. |
//! | `0x04` | [`Csr::Status`] | R | bit 0 [`STATUS_BUSY`]: a row or a frame is being rendered; bit 1 [`STATUS_DONE`]: sticky, set when a row finishes. Other bits read 0. Writes ignored. |
//! | `0x08` | [`Csr::RowY`] | R/W | row to render; only bits 8:0 ([`ROW_Y_MASK`]) are stored and read back. |
//! | `0x0C` | [`Csr::LightX`] | R/W | light x, Q13.10 in bits 23:0 ([`LIGHT_MASK`]); reads return the stored 24 bits sign-extended to 32. |
//! | `0x10` | [`Csr::LightY`] | R/W | light y, as light x. |
//! | `0x14` | [`Csr::LightZ`] | R/W | light z, as light x. |
//! | `0x18` | [`Csr::Id`] | R | [`ID_VALUE`] `0x5254_0003`: magic `0x5254` ("RT") in bits 31:16, map version 3 in bits 15:0. Writes ignored. |
//! | `0x1C` | [`Csr::FrameBase`] | R/W | bus address of the frame buffer; bits 31:3 stored ([`FRAME_BASE_MASK`]), bits 2:0 read 0. |
//! | `0x20` | [`Csr::FrameControl`] | W | bit 0 [`FRAME_CONTROL_START`]: render a whole frame for `LIGHT_*` into `FRAME_BASE` (ignored while busy); bit 1 [`FRAME_CONTROL_CLEAR_DONE`]: clear frame done; bit 2 [`FRAME_CONTROL_ABORT`]: stop the frame in progress (wins over the other bits). Reads 0. |
//! | `0x24` | [`Csr::FrameStatus`] | R | bit 0 [`FRAME_STATUS_BUSY`]: a frame is in progress (or stopping); bit 1 [`FRAME_STATUS_DONE`]: sticky, every row landed; bit 2 [`FRAME_STATUS_ERROR`]: sticky until the next frame, a write to memory failed or the memory stopped answering; bit 3 [`FRAME_STATUS_ABORTED`]: sticky until the next frame, the frame was stopped before its end (an abort or the stall limit). Writes ignored. |
//! | `0x28` | [`Csr::RowsDone`] | R | rows `0..n` of the current (or last) frame whose bytes have landed in memory, `0..=360`. Writes ignored. |
//! | `0x2C` | [`Csr::VgaControl`] | R/W | bit 0 [`VGA_CONTROL_ENABLE`]: scan frames out to the VGA port; bit 1 [`VGA_CONTROL_LETTERBOX`]: letterbox instead of full screen. Other bits read 0. |
//! | `0x30` | [`Csr::VgaBase`] | R/W | bus address of the frame to show (480 x 360 RGB888 wire bytes, as frame mode writes them); bits 31:3 stored ([`FRAME_BASE_MASK`]). Taken at the start of vertical blanking. |
//! | `0x34` | [`Csr::VgaStatus`] | R, W1C | bits 15:0 [`VGA_STATUS_FRAMES`]: frames scanned out since enable (wrapping); bit 16 [`VGA_STATUS_UNDERRUN`]: sticky, the reader was late and a line was cut; bit 17 [`VGA_STATUS_READ_ERROR`]: sticky, a read came back with an error; bit 18 [`VGA_STATUS_STALL`]: sticky, the memory answered no read for [`VGA_STALL_CYCLES`] (write 1 to clear each; enable clears them too). |
//! | `0x38` | [`Csr::Keys`] | R, W1C | bits 3:0 [`KEYS_DOWN`]: KEY3..KEY0 held down now (debounced; 1 = pressed, though the pins are active low); bits 7:4 [`KEYS_PRESSED`]: sticky, the key went down since last cleared (write 1 to clear). |
//! | `0x3C` | [`Csr::Switches`] | R | bits 9:0: SW9..SW0 (1 = up), synchronised. Writes ignored. |
//! | `0x40` | [`Csr::Leds`] | R/W | bits 9:0: LEDR9..LEDR0 (1 = lit). |
//! | `0x44` | [`Csr::HexLo`] | R/W | HEX0..HEX3, 7 bits each at bits `8n+6..8n` (segment a = bit 0 .. g = bit 6; 1 = lit: the RTL drives the active-low pins inverted). |
//! | `0x48` | [`Csr::HexHi`] | R/W | HEX4 in bits 6:0, HEX5 in bits 14:8, as [`Csr::HexLo`]. |
//! | `0x4C` | [`Csr::BuildId`] | R | the bitstream's build id, a synthesis parameter (`fpga/quartus/build.sh` sets the first 7 hex digits of the commit it was built from); 0: none recorded. Writes ignored. |
//!
//! # Behaviour
//!
//! * A start while idle latches `ROW_Y` and `LIGHT_*`, clears done and sets
//!   busy. Writes to those registers while busy change what they read back,
//!   not the row in progress.
//! * When the row is finished the line buffer holds it, busy clears and done
//!   sets. Done stays set until the next start or a clear_done; busy and done
//!   are never both set.
//! * A start while busy is ignored completely: no restart, the row in
//!   progress is unaffected. A clear_done while busy clears done (already 0)
//!   and leaves busy alone.
//! * Any 9-bit row is rendered, including rows `>= 360`: the accelerator
//!   computes exactly `model::render_row(row_y & 0x1ff, ..)`, extrapolating
//!   the camera. (The driver itself refuses rows `>= 360`.)
//! * The line buffer's contents are undefined while busy; after reset, before
//!   any row, it reads 0. It is read-only from the HPS side.
//!
//! # Frame mode
//!
//! * A frame start while idle latches `FRAME_BASE` and `LIGHT_*`, zeroes
//!   `ROWS_DONE`, clears frame done and error, and sets frame busy (and
//!   STATUS busy). It renders rows 0..359 into `FRAME_BASE + y * 1440` as
//!   RGB888 wire bytes ([`model::ROW_BYTES`] per row, pixel 0's R at the
//!   lowest address): the frame's bytes are exactly `model::render_frame`.
//! * `ROWS_DONE` counts rows whose every byte has been written *and
//!   acknowledged* by the memory: software may read rows below it at once
//!   (after a `dmb`). It never runs ahead of the data.
//! * When the last row has landed, busy clears and done sets. A failed
//!   write sets error and freezes `ROWS_DONE`; the frame still runs to its
//!   end (busy clears), done stays clear.
//! * A row start or a frame start while busy is ignored; the line buffer
//!   and `STATUS.done` are not part of frame mode.
//!
//! # VGA scan-out (map version 3)
//!
//! With [`VGA_CONTROL_ENABLE`] set the accelerator drives 640x480@60 (see
//! [`model::display`]) from the frame at `VGA_BASE`, read through its AXI
//! read master on the same FPGA-to-SDRAM port the frame DMA writes
//! through. `VGA_BASE` and the letterbox bit are latched at the start of
//! vertical blanking, the moment [`VGA_STATUS_FRAMES`] counts, so a frame
//! is never torn: once the counter has moved after a `VGA_BASE` write, the
//! new frame is on screen and the one before is no longer read. A line the
//! reader could not fetch in time is cut (black to its end) and sets
//! [`VGA_STATUS_UNDERRUN`]; the next frame starts over. The reader keeps at
//! most [`VGA_READS_IN_FLIGHT`] bursts outstanding. A read answered with an
//! error is not shown: the rest of that frame is black, as after an
//! underrun, and [`VGA_STATUS_READ_ERROR`] sets. When the memory answers no
//! read for [`VGA_STALL_CYCLES`] (the port held in reset), the reader
//! withdraws its request and forgets its bursts, as the frame DMA does at
//! its stall limit, sets [`VGA_STATUS_STALL`] and tries again at the next
//! frame. Disabled, the outputs are blank and black, VGA_CLK keeps running
//! so the DAC latches them, and the counter holds 0.
//!
//! # Board I/O (map version 3)
//!
//! Keys are synchronised and debounced in the fabric
//! ([`KEY_DEBOUNCE_CLOCKS`] of a stable level); switches are synchronised.
//! LEDs and 7-segment displays show what software wrote; all are 0 (dark)
//! after reset.
//!
//! # Stopping a frame
//!
//! A frame that cannot complete (the FPGA-to-SDRAM port held in reset, a
//! lost write response) must neither hold the accelerator nor land late in
//! a frame buffer that software has reused.
//!
//! * An abort ([`FRAME_CONTROL_ABORT`]) while a frame is in progress stops
//!   it: no new burst is issued, the bursts already announced on the bus are
//!   completed with every byte strobe off (AXI forbids withdrawing them; no
//!   byte is written), the outstanding write responses are collected, the
//!   renderer drains, and then busy clears with aborted set and done clear.
//!   `ROWS_DONE` keeps the rows that had landed. An abort while idle does
//!   nothing; a write with the abort bit never starts a frame. Once busy
//!   reads clear after an abort, nothing of that frame reaches memory any
//!   more and the buffer may be reused.
//! * Stall limit: when the memory makes no transfer on any write channel
//!   for [`FRAME_STALL_CYCLES`] fabric clocks while the DMA waits on it, the
//!   frame stops as by an abort and error sets as well. If the memory still
//!   answers nothing for another [`FRAME_STALL_CYCLES`] while stopping, the
//!   DMA withdraws its requests and goes idle anyway (error and aborted
//!   set): a frame never holds the accelerator longer than
//!   `2 * FRAME_STALL_CYCLES` past its last transfer.
//! * Row mode is available again as soon as busy clears.

/// Base address of the lightweight HPS-to-FPGA bridge window in the HPS
/// address map.
///
/// Source: Cyclone V Hard Processor System Technical Reference Manual,
/// "HPS Address Map" (the `LWFPGASLAVES` region, 0xFF20_0000 - 0xFF3F_FFFF).
pub const LW_BRIDGE_BASE: usize = 0xFF20_0000;

/// Size of the lightweight bridge window: 2 MiB (same TRM table).
pub const LW_BRIDGE_SIZE: usize = 2 << 20;

/// Offset of the CSR block inside the lightweight bridge window.
pub const CSR_OFFSET: usize = 0x0000;

/// Offset of the line-buffer window inside the lightweight bridge window.
pub const LINE_BUFFER_OFFSET: usize = 0x1000;

/// Words in the line buffer: one per pixel of a row.
pub const LINE_WORDS: usize = 480;

/// Rows of a frame; the driver refuses `row_y >= ROWS`.
pub const ROWS: u16 = 360;

/// Bridge offset of line-buffer word `x` (pixel `x` of the row).
pub const fn line_word_offset(x: usize) -> usize {
    LINE_BUFFER_OFFSET + 4 * x
}

// The line buffer is one row of the model's frame.
const _: () = assert!(LINE_WORDS == model::WIDTH && ROWS as usize == model::HEIGHT);
const _: () = assert!(line_word_offset(LINE_WORDS) <= LW_BRIDGE_SIZE);

/// The registers of the CSR block.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash)]
pub enum Csr {
    /// `0x00`, write-only: start pulse and clear_done.
    Control,
    /// `0x04`, read-only: busy and sticky done.
    Status,
    /// `0x08`, read/write: row to render, 9 bits.
    RowY,
    /// `0x0C`, read/write: light x, 24-bit Q13.10.
    LightX,
    /// `0x10`, read/write: light y, 24-bit Q13.10.
    LightY,
    /// `0x14`, read/write: light z, 24-bit Q13.10.
    LightZ,
    /// `0x18`, read-only: magic and version ([`ID_VALUE`]).
    Id,
    /// `0x1C`, read/write: frame buffer bus address, bits 31:3.
    FrameBase,
    /// `0x20`, write-only: frame start pulse and frame clear_done.
    FrameControl,
    /// `0x24`, read-only: frame busy, done, error.
    FrameStatus,
    /// `0x28`, read-only: rows of the frame that have landed.
    RowsDone,
    /// `0x2C`, read/write: VGA enable and layout.
    VgaControl,
    /// `0x30`, read/write: the frame to show, bits 31:3.
    VgaBase,
    /// `0x34`, read, write 1 to clear: frames scanned, underrun.
    VgaStatus,
    /// `0x38`, read, write 1 to clear: keys down and pressed.
    Keys,
    /// `0x3C`, read-only: switches.
    Switches,
    /// `0x40`, read/write: red LEDs.
    Leds,
    /// `0x44`, read/write: HEX0..HEX3 segments.
    HexLo,
    /// `0x48`, read/write: HEX4 and HEX5 segments.
    HexHi,
    /// `0x4C`, read-only: the bitstream's build id (0: none recorded).
    BuildId,
}

impl Csr {
    /// Every register, in address order.
    pub const ALL: [Csr; 20] = [
        Csr::Control,
        Csr::Status,
        Csr::RowY,
        Csr::LightX,
        Csr::LightY,
        Csr::LightZ,
        Csr::Id,
        Csr::FrameBase,
        Csr::FrameControl,
        Csr::FrameStatus,
        Csr::RowsDone,
        Csr::VgaControl,
        Csr::VgaBase,
        Csr::VgaStatus,
        Csr::Keys,
        Csr::Switches,
        Csr::Leds,
        Csr::HexLo,
        Csr::HexHi,
        Csr::BuildId,
    ];

    /// Byte offset of the register inside the CSR block.
    pub const fn offset(self) -> usize {
        match self {
            Csr::Control => 0x00,
            Csr::Status => 0x04,
            Csr::RowY => 0x08,
            Csr::LightX => 0x0C,
            Csr::LightY => 0x10,
            Csr::LightZ => 0x14,
            Csr::Id => 0x18,
            Csr::FrameBase => 0x1C,
            Csr::FrameControl => 0x20,
            Csr::FrameStatus => 0x24,
            Csr::RowsDone => 0x28,
            Csr::VgaControl => 0x2C,
            Csr::VgaBase => 0x30,
            Csr::VgaStatus => 0x34,
            Csr::Keys => 0x38,
            Csr::Switches => 0x3C,
            Csr::Leds => 0x40,
            Csr::HexLo => 0x44,
            Csr::HexHi => 0x48,
            Csr::BuildId => 0x4C,
        }
    }

    /// The register at byte offset `offset` of the CSR block (low two bits
    /// ignored, as on the 32-bit Avalon slave), or `None` if unmapped.
    pub const fn at_offset(offset: usize) -> Option<Csr> {
        match offset & !3 {
            0x00 => Some(Csr::Control),
            0x04 => Some(Csr::Status),
            0x08 => Some(Csr::RowY),
            0x0C => Some(Csr::LightX),
            0x10 => Some(Csr::LightY),
            0x14 => Some(Csr::LightZ),
            0x18 => Some(Csr::Id),
            0x1C => Some(Csr::FrameBase),
            0x20 => Some(Csr::FrameControl),
            0x24 => Some(Csr::FrameStatus),
            0x28 => Some(Csr::RowsDone),
            0x2C => Some(Csr::VgaControl),
            0x30 => Some(Csr::VgaBase),
            0x34 => Some(Csr::VgaStatus),
            0x38 => Some(Csr::Keys),
            0x3C => Some(Csr::Switches),
            0x40 => Some(Csr::Leds),
            0x44 => Some(Csr::HexLo),
            0x48 => Some(Csr::HexHi),
            0x4C => Some(Csr::BuildId),
            _ => None,
        }
    }
}

/// Size of the CSR block's address range (up to the line buffer).
pub const CSR_WINDOW: usize = LINE_BUFFER_OFFSET - CSR_OFFSET;

/// CONTROL bit 0: start a row (a pulse, not stored; also clears done).
pub const CONTROL_START: u32 = 1 << 0;
/// CONTROL bit 1: clear the sticky done bit.
pub const CONTROL_CLEAR_DONE: u32 = 1 << 1;

/// STATUS bit 0: a row or a frame is being rendered.
pub const STATUS_BUSY: u32 = 1 << 0;
/// STATUS bit 1: sticky; a row has finished since the last start or clear_done.
pub const STATUS_DONE: u32 = 1 << 1;
/// The STATUS bits that can be set; all others read 0.
pub const STATUS_MASK: u32 = STATUS_BUSY | STATUS_DONE;

/// The bits of ROW_Y that are stored (9-bit row counter).
pub const ROW_Y_MASK: u32 = model::trace::COORD_MASK as u32;

/// The bits of LIGHT_X/Y/Z that are stored (a 24-bit Q13.10 word).
pub const LIGHT_MASK: u32 = (1 << model::word::WORD_BITS) - 1;

/// Magic in ID bits 31:16: ASCII "RT".
pub const ID_MAGIC: u16 = 0x5254;
/// Register-map version in ID bits 15:0; this document describes version 3.
pub const ID_VERSION: u16 = 3;
/// The first map version with the frame DMA registers (version 1: rows only).
pub const ID_VERSION_FRAMES: u16 = 2;
/// The first map version with the VGA scan-out and the board I/O block.
pub const ID_VERSION_VGA: u16 = 3;
/// The value the ID register reads on a configured accelerator.
pub const ID_VALUE: u32 = (ID_MAGIC as u32) << 16 | ID_VERSION as u32;

/// What every read returns when nothing answers (an empty fabric or a
/// bridge that fails reads): all ones.
pub const BUS_ALL_ONES: u32 = 0xFFFF_FFFF;

/// Bits 31:24 of a line-buffer word; always 0 in a finished row
/// (`0x00RRGGBB`).
pub const PIXEL_RESERVED_MASK: u32 = 0xFF00_0000;

/// FRAME_BASE: the stored bits (the frame buffer is 8-byte aligned).
pub const FRAME_BASE_MASK: u32 = !7;
/// FRAME_CONTROL bit 0: start a frame.
pub const FRAME_CONTROL_START: u32 = 1 << 0;
/// FRAME_CONTROL bit 1: clear frame done.
pub const FRAME_CONTROL_CLEAR_DONE: u32 = 1 << 1;
/// FRAME_STATUS bit 0: a frame is in progress.
pub const FRAME_STATUS_BUSY: u32 = 1 << 0;
/// FRAME_STATUS bit 1: sticky; every row of the last frame landed.
pub const FRAME_STATUS_DONE: u32 = 1 << 1;
/// FRAME_STATUS bit 2: sticky until the next frame; a memory write failed.
pub const FRAME_STATUS_ERROR: u32 = 1 << 2;
/// FRAME_CONTROL bit 2: stop the frame in progress ([Stopping a frame](self#stopping-a-frame)).
pub const FRAME_CONTROL_ABORT: u32 = 1 << 2;
/// FRAME_STATUS bit 3: sticky until the next frame; the frame was stopped
/// before its end, by an abort or the stall limit.
pub const FRAME_STATUS_ABORTED: u32 = 1 << 3;
/// The FRAME_STATUS bits that can be set.
pub const FRAME_STATUS_MASK: u32 = FRAME_STATUS_BUSY | FRAME_STATUS_DONE | FRAME_STATUS_ERROR | FRAME_STATUS_ABORTED;
/// Fabric clocks without a transfer on any write channel, while the frame
/// DMA waits on the memory, after which the frame stops with an error:
/// 2^17 clocks, 2.6 ms at 50 MHz. A healthy FPGA-to-SDRAM port answers
/// within microseconds; a whole frame takes about 3.5 ms.
pub const FRAME_STALL_CYCLES: u32 = 1 << 17;
/// Bytes of one row in the frame buffer.
pub const FRAME_ROW_BYTES: u32 = model::ROW_BYTES as u32;
/// Bytes of one frame in the frame buffer.
pub const FRAME_BYTES: u32 = model::FRAME_BYTES as u32;

/// VGA_CONTROL bit 0: scan frames out to the VGA port.
pub const VGA_CONTROL_ENABLE: u32 = 1 << 0;
/// VGA_CONTROL bit 1: letterbox ([`model::display::Layout::Letterbox`])
/// instead of full screen.
pub const VGA_CONTROL_LETTERBOX: u32 = 1 << 1;
/// The VGA_CONTROL bits that are stored.
pub const VGA_CONTROL_MASK: u32 = VGA_CONTROL_ENABLE | VGA_CONTROL_LETTERBOX;
/// VGA_STATUS bits 15:0: frames scanned out since enable (wrapping).
pub const VGA_STATUS_FRAMES: u32 = 0xFFFF;
/// VGA_STATUS bit 16: sticky; a line was cut because the reader was late
/// (or a read failed: bits 17 and 18 say why).
pub const VGA_STATUS_UNDERRUN: u32 = 1 << 16;
/// VGA_STATUS bit 17: sticky; a read beat came back SLVERR or DECERR (its
/// data was not shown, the rest of that frame was black).
pub const VGA_STATUS_READ_ERROR: u32 = 1 << 17;
/// VGA_STATUS bit 18: sticky; the memory answered no read for
/// [`VGA_STALL_CYCLES`] and the reader gave up on its bursts.
pub const VGA_STATUS_STALL: u32 = 1 << 18;
/// The sticky VGA_STATUS flags (write 1 to clear each).
pub const VGA_STATUS_FLAGS: u32 = VGA_STATUS_UNDERRUN | VGA_STATUS_READ_ERROR | VGA_STATUS_STALL;
/// The VGA_STATUS bits that can be set.
pub const VGA_STATUS_MASK: u32 = VGA_STATUS_FRAMES | VGA_STATUS_FLAGS;
/// Fabric clocks the VGA reader waits on outstanding reads with no
/// handshake before it gives them up, as the frame DMA's
/// [`FRAME_STALL_CYCLES`] (2.6 ms, a sixth of a frame).
pub const VGA_STALL_CYCLES: u32 = 1 << 17;
/// Read bursts the VGA reader keeps in flight at most (AR handshake to the
/// RLAST beat): the read issuing capability `rt_accel_hw.tcl` declares.
pub const VGA_READS_IN_FLIGHT: u32 = 4;
/// Fabric clocks per VGA frame: 800 x 525 pixels, two 50 MHz clocks each
/// (16.8 ms).
pub const VGA_FRAME_CLOCKS: u32 = 800 * 525 * 2;
/// KEYS bits 3:0: keys held down now (debounced).
pub const KEYS_DOWN: u32 = 0xF;
/// KEYS bits 7:4: sticky, keys that went down since last cleared.
pub const KEYS_PRESSED: u32 = 0xF0;
/// Fabric clocks a key must hold a new level before KEYS follows it:
/// 2^20 clocks, 21 ms at 50 MHz (push-button bounce lasts a few ms).
pub const KEY_DEBOUNCE_CLOCKS: u32 = 1 << 20;
/// SWITCHES: the stored bits (SW9..SW0).
pub const SWITCHES_MASK: u32 = 0x3FF;
/// LEDS: the stored bits (LEDR9..LEDR0).
pub const LEDS_MASK: u32 = 0x3FF;
/// HEX_LO: the stored bits (four 7-bit displays, one per byte).
pub const HEX_LO_MASK: u32 = 0x7F7F_7F7F;
/// HEX_HI: the stored bits (two 7-bit displays).
pub const HEX_HI_MASK: u32 = 0x7F7F;
/// The fabric clock the accelerator runs on (Platform Designer's 50 MHz
/// clock source, fpga/quartus/soc_system.tcl).
pub const FABRIC_HZ: u32 = 50_000_000;

/// A light component as the LIGHT registers store it (bits 23:0).
pub const fn light_to_register(raw: i32) -> u32 {
    raw as u32 & LIGHT_MASK
}

/// A LIGHT register's stored bits as they read back: sign-extended from bit 23.
pub const fn light_from_register(bits: u32) -> i32 {
    ((bits << 8) as i32) >> 8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_round_trip() {
        for (i, csr) in Csr::ALL.into_iter().enumerate() {
            assert_eq!(csr.offset(), 4 * i);
            assert_eq!(Csr::at_offset(csr.offset()), Some(csr));
            assert_eq!(Csr::at_offset(csr.offset() + 3), Some(csr));
        }
        assert_eq!(Csr::at_offset(0x50), None);
        assert_eq!(Csr::at_offset(CSR_WINDOW - 4), None);
    }

    #[test]
    fn constants_match_the_decided_map() {
        assert_eq!(ID_VALUE, 0x5254_0003);
        assert_eq!(Csr::HexHi.offset(), 0x48);
        assert_eq!(VGA_FRAME_CLOCKS, 840_000);
        assert_eq!(Csr::RowsDone.offset(), 0x28);
        assert_eq!(FRAME_ROW_BYTES * 360, FRAME_BYTES);
        assert_eq!(ROW_Y_MASK, 0x1ff);
        assert_eq!(LIGHT_MASK, 0x00ff_ffff);
        assert_eq!(line_word_offset(0), 0x1000);
        assert_eq!(line_word_offset(479), 0x177C);
    }

    #[test]
    fn light_register_sign_extends() {
        for raw in [0, 1, -1, 1024, -2048, model::word::RAW_MIN, model::word::RAW_MAX] {
            assert_eq!(light_from_register(light_to_register(raw)), raw);
        }
        assert_eq!(light_to_register(-1), 0x00ff_ffff);
        assert_eq!(light_from_register(0xff80_0000), model::word::RAW_MIN);
        assert_eq!(light_from_register(0x1234_5678), 0x0034_5678);
    }
}
