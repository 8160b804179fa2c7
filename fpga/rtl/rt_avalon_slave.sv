// Avalon-MM slave: the CSR block and the line-buffer window, with the
// register semantics of hal-avalon (src/map.rs, src/sim.rs), map version 3:
//   0x00 CONTROL W  bit0 start a row (also clears done), bit1 clear_done;
//                   start wins; a start while busy is ignored. Reads 0.
//   0x04 STATUS  R  bit0 busy (a row or a frame in progress), bit1 sticky
//                   row done.
//   0x08 ROW_Y   RW bits 8:0.
//   0x0C/0x10/0x14 LIGHT_X/Y/Z RW bits 23:0, read back sign-extended.
//   0x18 ID      R  0x5254_0003.
//   0x1C FRAME_BASE    RW bits 31:3 (byte address; bits 2:0 read 0).
//   0x20 FRAME_CONTROL W bit0 start a frame at FRAME_BASE with LIGHT_*
//                   (ignored while busy), bit1 clear frame done, bit2 abort
//                   the frame in progress (wins over bits 0 and 1). Reads 0.
//   0x24 FRAME_STATUS  R bit0 busy, bit1 sticky frame done (every row
//                   landed), bit2 sticky bus error or stall (until the next
//                   frame), bit3 sticky aborted (until the next frame).
//   0x28 ROWS_DONE     R rows of the current or last frame whose bytes
//                   have landed (write responses received), 0..360.
//   0x2C VGA_CONTROL RW bit0 enable, bit1 letterbox.
//   0x30 VGA_BASE    RW bits 31:3 (bits 2:0 read 0).
//   0x34 VGA_STATUS  R, W1C bits 15:0 frames since enable (wrapping), bit16
//                   sticky underrun, bit17 sticky read error (SLVERR or
//                   DECERR), bit18 sticky stall limit (write 1 clears each);
//                   enabling clears all.
//   0x38 KEYS        R, W1C bits 3:0 keys down (debounced), bits 7:4 sticky
//                   went down (write 1 clears).
//   0x3C SWITCHES    R bits 9:0.
//   0x40 LEDS        RW bits 9:0.
//   0x44 HEX_LO      RW HEX0..HEX3 at bits 8n+6..8n (1 = lit).
//   0x48 HEX_HI      RW HEX4 bits 6:0, HEX5 bits 14:8.
//   0x4C BUILD_ID    R  BUILD_ID, the bitstream's build id (a synthesis
//                   parameter; 0: none recorded, as the unmapped offset
//                   read before the register existed).
//   0x1000 + 4x  R  line buffer word x (x < 480), 0x00RRGGBB (row mode).
// Everything else reads 0. address_i is the word address; fixed read
// latency 1.
module rt_avalon_slave
  import rt_pkg::*;
#(
  parameter int unsigned LANES = 1,
  parameter logic [31:0] BUILD_ID = 32'h0
) (
  input  logic        clk_i,
  input  logic        rst_ni,
  // Avalon-MM slave (word addresses over an 8 KiB span)
  input  logic [10:0] address_i,
  input  logic        read_i,
  input  logic        write_i,
  input  logic [31:0] writedata_i,
  output logic [31:0] readdata_o,
  // to/from the row scheduler and the frame DMA
  output logic        row_start_o,
  output logic        frame_start_o,
  output logic        frame_clear_done_o,
  output logic        frame_abort_o,
  output coord_t      row_o,
  output vec3_t       light_o,
  output logic [31:3] frame_base_o,
  input  logic        busy_i,        // scheduler or DMA busy
  input  logic        row_finish_i,
  input  logic        frame_busy_i,  // DMA busy
  input  logic        frame_done_i,
  input  logic        frame_error_i,
  input  logic        frame_aborted_i,
  input  row_t        rows_landed_i,
  // VGA scan-out and board I/O (map version 3)
  output logic        vga_enable_o,
  output logic        vga_letterbox_o,
  output logic [31:3] vga_base_o,
  input  logic        vga_frame_i,     // a frame was scanned out
  input  logic        vga_underrun_i,  // a line was cut
  input  logic        vga_read_error_i,  // a read beat came back with an error
  input  logic        vga_stall_i,     // the reader gave up on its reads
  input  logic [3:0]  keys_down_i,
  input  logic [3:0]  keys_went_i,
  input  logic [9:0]  switches_i,
  output logic [9:0]  leds_o,
  output logic [31:0] hex_lo_o,
  output logic [15:0] hex_hi_o,
  // line-buffer read ports (slot 0), one per bank; IdxW bits (below)
  output logic [$clog2(Width/LANES)-1:0] lb_raddr_o,
  input  rgb_t [LANES-1:0] lb_rdata_i
);
  localparam int unsigned PerLane = Width / LANES;
  localparam int unsigned IdxW = $clog2(PerLane);
  localparam int unsigned LaneBits = $clog2(LANES);
  // Word offsets of the CSRs (byte offset / 4).
  localparam logic [10:0] AddrControl     = 11'h000;
  localparam logic [10:0] AddrStatus      = 11'h001;
  localparam logic [10:0] AddrRowY        = 11'h002;
  localparam logic [10:0] AddrLightX      = 11'h003;
  localparam logic [10:0] AddrLightY      = 11'h004;
  localparam logic [10:0] AddrLightZ      = 11'h005;
  localparam logic [10:0] AddrId          = 11'h006;
  localparam logic [10:0] AddrFrameBase   = 11'h007;
  localparam logic [10:0] AddrFrameCtl    = 11'h008;
  localparam logic [10:0] AddrFrameStatus = 11'h009;
  localparam logic [10:0] AddrRowsDone    = 11'h00a;
  localparam logic [10:0] AddrVgaControl  = 11'h00b;
  localparam logic [10:0] AddrVgaBase     = 11'h00c;
  localparam logic [10:0] AddrVgaStatus   = 11'h00d;
  localparam logic [10:0] AddrKeys        = 11'h00e;
  localparam logic [10:0] AddrSwitches    = 11'h00f;
  localparam logic [10:0] AddrLeds        = 11'h010;
  localparam logic [10:0] AddrHexLo       = 11'h011;
  localparam logic [10:0] AddrHexHi       = 11'h012;
  localparam logic [10:0] AddrBuildId     = 11'h013;

  coord_t row_q;
  vec3_t light_q;
  logic [31:3] base_q;
  logic done_q;
  logic [1:0] vga_ctl_q;
  logic [31:3] vga_base_q;
  logic [15:0] vga_frames_q;
  logic vga_underrun_q, vga_read_error_q, vga_stall_q;
  logic [3:0] keys_went_q;
  logic [9:0] leds_q;
  logic [31:0] hex_lo_q;
  logic [15:0] hex_hi_q;
  logic vga_enable_now;

  logic ctl_write, fctl_write;
  assign ctl_write = write_i && (address_i == AddrControl);
  assign fctl_write = write_i && (address_i == AddrFrameCtl);
  assign row_start_o = ctl_write && writedata_i[0] && !busy_i;
  assign frame_abort_o = fctl_write && writedata_i[2];
  assign frame_start_o = fctl_write && writedata_i[0] && !writedata_i[2] && !busy_i;
  assign frame_clear_done_o = fctl_write && !writedata_i[0] && writedata_i[1] && !writedata_i[2];
  // Enabling the scan-out (bit 0 rising) clears VGA_STATUS.
  logic [2:0] vga_status_w1c;  // VGA_STATUS bits 18:16 written with 1
  assign vga_status_w1c = (write_i && address_i == AddrVgaStatus) ? writedata_i[18:16] : 3'd0;
  assign vga_enable_now = write_i && (address_i == AddrVgaControl) && writedata_i[0] && !vga_ctl_q[0];

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      row_q        <= '0;
      light_q      <= '0;
      base_q       <= '0;
      done_q       <= 1'b0;
      vga_ctl_q      <= '0;
      vga_base_q     <= '0;
      vga_frames_q   <= '0;
      vga_underrun_q <= 1'b0;
      vga_read_error_q <= 1'b0;
      vga_stall_q    <= 1'b0;
      keys_went_q    <= '0;
      leds_q         <= '0;
      hex_lo_q       <= '0;
      hex_hi_q       <= '0;
    end else begin
      if (write_i) begin
        unique case (address_i)
          AddrRowY:      row_q     <= writedata_i[8:0];
          AddrLightX:    light_q.x <= writedata_i[23:0];
          AddrLightY:    light_q.y <= writedata_i[23:0];
          AddrLightZ:    light_q.z <= writedata_i[23:0];
          AddrFrameBase: base_q    <= writedata_i[31:3];
          AddrVgaControl: vga_ctl_q <= writedata_i[1:0];
          AddrVgaBase:   vga_base_q <= writedata_i[31:3];
          AddrLeds:      leds_q    <= writedata_i[9:0];
          AddrHexLo:     hex_lo_q  <= writedata_i & 32'h7f7f_7f7f;
          AddrHexHi:     hex_hi_q  <= writedata_i[15:0] & 16'h7f7f;
          default: ;
        endcase
      end
      // VGA_STATUS: counts and sticky flags; W1C (a new event wins);
      // enabling clears them.
      if (vga_enable_now) begin
        vga_frames_q <= '0;
        vga_underrun_q <= 1'b0;
        vga_read_error_q <= 1'b0;
        vga_stall_q <= 1'b0;
      end else begin
        if (vga_frame_i) vga_frames_q <= vga_frames_q + 16'd1;
        if (vga_underrun_i) vga_underrun_q <= 1'b1;
        else if (vga_status_w1c[0]) vga_underrun_q <= 1'b0;
        if (vga_read_error_i) vga_read_error_q <= 1'b1;
        else if (vga_status_w1c[1]) vga_read_error_q <= 1'b0;
        if (vga_stall_i) vga_stall_q <= 1'b1;
        else if (vga_status_w1c[2]) vga_stall_q <= 1'b0;
      end
      // KEYS bits 7:4: sticky went-down, W1C (a new press wins).
      keys_went_q <= keys_went_i
                   | (keys_went_q & ~((write_i && address_i == AddrKeys) ? writedata_i[7:4] : 4'd0));
      // A finishing row sets done after a same-cycle clear_done.
      if (row_finish_i) done_q <= 1'b1;
      else if (row_start_o) done_q <= 1'b0;
      else if (ctl_write && !writedata_i[0] && writedata_i[1]) done_q <= 1'b0;
    end
  end
  assign row_o = row_q;
  assign light_o = light_q;
  assign frame_base_o = base_q;
  assign vga_enable_o = vga_ctl_q[0];
  assign vga_letterbox_o = vga_ctl_q[1];
  assign vga_base_o = vga_base_q;
  assign leds_o = leds_q;
  assign hex_lo_o = hex_lo_q;
  assign hex_hi_o = hex_hi_q;

  // CONTROL bits 31:2 and the bits above each register's width are ignored.
  /* verilator lint_off UNUSEDSIGNAL */
  logic unused_wdata;
  assign unused_wdata = ^writedata_i[31:24];
  /* verilator lint_on UNUSEDSIGNAL */

  // ---- Reads (registered: fixed latency 1) ----------------------------------
  logic [9:0] lb_x;
  logic lb_sel;
  assign lb_x = address_i[9:0];
  assign lb_sel = address_i[10] && (lb_x < 10'(Width));
  assign lb_raddr_o = IdxW'(lb_x >> LaneBits);

  logic [31:0] csr_rdata_q;
  logic lb_sel_q;
  logic [LaneBits > 0 ? LaneBits - 1 : 0 : 0] bank_q;
  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      csr_rdata_q <= '0;
      lb_sel_q    <= 1'b0;
      bank_q      <= '0;
    end else if (read_i) begin
      lb_sel_q <= lb_sel;
      bank_q   <= LaneBits > 0 ? lb_x[LaneBits > 0 ? LaneBits - 1 : 0 : 0] : '0;
      unique case (address_i)
        AddrStatus:      csr_rdata_q <= {30'd0, done_q, busy_i};
        AddrRowY:        csr_rdata_q <= {23'd0, row_q};
        AddrLightX:      csr_rdata_q <= 32'(light_q.x);  // q_t is signed: sign-extends
        AddrLightY:      csr_rdata_q <= 32'(light_q.y);
        AddrLightZ:      csr_rdata_q <= 32'(light_q.z);
        AddrId:          csr_rdata_q <= IdValue;
        AddrFrameBase:   csr_rdata_q <= {base_q, 3'b000};
        AddrFrameStatus: csr_rdata_q <= {28'd0, frame_aborted_i, frame_error_i, frame_done_i, frame_busy_i};
        AddrRowsDone:    csr_rdata_q <= {23'd0, rows_landed_i};
        AddrVgaControl:  csr_rdata_q <= {30'd0, vga_ctl_q};
        AddrVgaBase:     csr_rdata_q <= {vga_base_q, 3'b000};
        AddrVgaStatus:   csr_rdata_q <= {13'd0, vga_stall_q, vga_read_error_q, vga_underrun_q, vga_frames_q};
        AddrKeys:        csr_rdata_q <= {24'd0, keys_went_q, keys_down_i};
        AddrSwitches:    csr_rdata_q <= {22'd0, switches_i};
        AddrLeds:        csr_rdata_q <= {22'd0, leds_q};
        AddrHexLo:       csr_rdata_q <= hex_lo_q;
        AddrHexHi:       csr_rdata_q <= {16'd0, hex_hi_q};
        AddrBuildId:     csr_rdata_q <= BUILD_ID;
        default:         csr_rdata_q <= '0;
      endcase
    end
  end
  assign readdata_o = lb_sel_q ? {8'd0, lb_rdata_i[bank_q]} : csr_rdata_q;
endmodule
