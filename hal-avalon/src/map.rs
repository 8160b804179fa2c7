//! The register map: the contract between the firmware and the FPGA.
//!
//! This module is the single source of truth for every address, offset and
//! bit of the accelerator; `fpga/` implements the same numbers.
//!
//! # Windows inside the lightweight bridge
//!
//! | window | bridge offset | size | contents |
//! |---|---|---|---|
//! | CSR block | [`CSR_OFFSET`] `0x0000` | 11 registers (`0x00..=0x28`) | [`Csr`] |
//! | line buffer | [`LINE_BUFFER_OFFSET`] `0x1000` | [`LINE_WORDS`] x 32 bit | pixel `x` at `0x1000 + 4 * x`, word `0x00RRGGBB` |
//!
//! Every register is 32 bits wide and word aligned. Offsets of the bridge
//! window outside the eleven registers and the 480 line-buffer words are not
//! part of the contract, except that unmapped offsets of the CSR block read 0.
//!
//! Map version 2 adds the frame DMA (`0x1C..=0x28`) to version 1's row
//! registers (`0x00..=0x18`, unchanged): the ID register tells a driver which
//! it has ([`ID_VERSION_FRAMES`]). The frame abort and the stall limit
//! ([Stopping a frame](#stopping-a-frame)) belong to version 2: no
//! version 2 bitstream without them was ever released.
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
//! | `0x18` | [`Csr::Id`] | R | [`ID_VALUE`] `0x5254_0002`: magic `0x5254` ("RT") in bits 31:16, map version 2 in bits 15:0. Writes ignored. |
//! | `0x1C` | [`Csr::FrameBase`] | R/W | bus address of the frame buffer; bits 31:3 stored ([`FRAME_BASE_MASK`]), bits 2:0 read 0. |
//! | `0x20` | [`Csr::FrameControl`] | W | bit 0 [`FRAME_CONTROL_START`]: render a whole frame for `LIGHT_*` into `FRAME_BASE` (ignored while busy); bit 1 [`FRAME_CONTROL_CLEAR_DONE`]: clear frame done; bit 2 [`FRAME_CONTROL_ABORT`]: stop the frame in progress (wins over the other bits). Reads 0. |
//! | `0x24` | [`Csr::FrameStatus`] | R | bit 0 [`FRAME_STATUS_BUSY`]: a frame is in progress (or stopping); bit 1 [`FRAME_STATUS_DONE`]: sticky, every row landed; bit 2 [`FRAME_STATUS_ERROR`]: sticky until the next frame, a write to memory failed or the memory stopped answering; bit 3 [`FRAME_STATUS_ABORTED`]: sticky until the next frame, the frame was stopped before its end (an abort or the stall limit). Writes ignored. |
//! | `0x28` | [`Csr::RowsDone`] | R | rows `0..n` of the current (or last) frame whose bytes have landed in memory, `0..=360`. Writes ignored. |
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
}

impl Csr {
    /// Every register, in address order.
    pub const ALL: [Csr; 11] = [
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
/// Register-map version in ID bits 15:0; this document describes version 2.
pub const ID_VERSION: u16 = 2;
/// The first map version with the frame DMA registers (version 1: rows only).
pub const ID_VERSION_FRAMES: u16 = 2;
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
        assert_eq!(Csr::at_offset(0x2C), None);
        assert_eq!(Csr::at_offset(CSR_WINDOW - 4), None);
    }

    #[test]
    fn constants_match_the_decided_map() {
        assert_eq!(ID_VALUE, 0x5254_0002);
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
