// VGA scan-out, 640x480@60 (model/src/display.rs; hal-avalon map.rs "VGA
// scan-out"): the timing, a reader that fetches frame rows from SDRAM
// through the AXI3 read channels of the FPGA-to-SDRAM port, a two-row
// line buffer and the output registers for the ADV7123 DAC.
//
// * Pixel clock: 25 MHz as a clock enable of clk_i, exactly two clk_i
//   cycles a pixel. vga_clk_o comes from a register that toggles from reset
//   on, enabled or not (the ADV7123 latches only on its rising edges: a
//   stopped clock would hold the last pixel on the monitor); every other
//   output changes on the clk_i edge where vga_clk_o falls, so all are
//   stable around its rising edge (where the DAC latches).
// * Timing: 800 x 525; H 640 visible, 16 front porch, 96 sync, 48 back
//   porch; V 480, 10, 2, 33; both syncs active low; blank_n low and RGB
//   black outside the visible area.
// * Picture: full screen, display pixel (X, Y) shows frame pixel
//   (floor(3X/4), floor(3Y/4)); letterbox, frame pixel (X-80, Y-60) inside
//   [80,560)x[60,420), black elsewhere. Computed with adders, no DSP.
// * The reader fetches whole frame rows (1,440 bytes, 180 beats) in bursts
//   of at most 16 beats that never cross 4 KiB, at most READS_IN_FLIGHT
//   bursts outstanding (counted from AR to the RLAST beat: the read issuing
//   capability rt_accel_hw.tcl declares), unpacks the bytes into
//   12-byte words (four pixels) as they arrive (RREADY stays high) and
//   writes them to slot row % 2 of the line buffer. Row k may be fetched
//   once the display has finished every line of row k-2 (at the end of
//   each line's visible part it allows the row needed two lines later).
// * A picture pixel whose word has not arrived cuts its line (black to the
//   line's end) and pulses underrun_o. At the start of vertical blanking
//   (frame_o pulses) the base and the layout are latched and the reader
//   starts over: it waits for the bursts still outstanding (discarding
//   their data), then fetches the new frame from row 0.
// * A beat answered SLVERR or DECERR counts as an underrun: its data is not
//   shown, nor anything after it in that frame (lines cut, underrun_o), and
//   read_error_o pulses; the reader stops fetching until the next frame.
// * Stall limit: STALL_CYCLES clocks with bursts outstanding and no AR or R
//   handshake (a port that never answers, e.g. left in reset) and the reader
//   gives up on them, as the frame DMA does: ARVALID is withdrawn (the
//   documented last resort), the outstanding count forgotten, stall_o
//   pulses, and the rest of the frame is black; the next frame tries again.
// * Disabled: the timing rests at the start of vertical blanking (outputs
//   blank, black, syncs inactive, latched by the DAC on the still-running
//   vga_clk_o); enabling starts a frame there (latched
//   without a frame_o pulse), so the first frame_o comes one whole frame
//   later.
module rt_vga
  import rt_pkg::*;
#(
  parameter int unsigned READS_IN_FLIGHT = 4,        // rt_accel_hw.tcl readIssuingCapability
  parameter int unsigned STALL_CYCLES = 1 << 17       // hal-avalon VGA_STALL_CYCLES
) (
  input  logic        clk_i,
  input  logic        rst_ni,
  input  logic        enable_i,
  input  logic        letterbox_i,
  input  logic [31:3] base_i,
  output logic        frame_o,      // a frame was scanned out (start of vertical blanking)
  output logic        underrun_o,   // a line was cut
  output logic        read_error_o, // a read beat came back SLVERR/DECERR
  output logic        stall_o,      // outstanding reads given up (stall limit)
  // AXI3 read master
  output logic [31:0] araddr_o,
  output logic [3:0]  arlen_o,
  output logic [2:0]  arsize_o,
  output logic [1:0]  arburst_o,
  output logic [3:0]  arcache_o,
  output logic [2:0]  arprot_o,
  output logic        arvalid_o,
  input  logic        arready_i,
  input  logic [63:0] rdata_i,
  input  logic [1:0]  rresp_i,
  input  logic        rlast_i,
  input  logic        rvalid_i,
  output logic        rready_o,
  // VGA DAC
  output logic        vga_clk_o,
  output logic        vga_hs_o,
  output logic        vga_vs_o,
  output logic        vga_blank_n_o,
  output logic        vga_sync_n_o,
  output logic [7:0]  vga_r_o,
  output logic [7:0]  vga_g_o,
  output logic [7:0]  vga_b_o
);
  // Timing (model::display H_TIMING, V_TIMING).
  localparam int unsigned HVisible = 640;
  localparam int unsigned HSyncStart = 640 + 16;
  localparam int unsigned HSyncEnd = 640 + 16 + 96;
  localparam int unsigned HTotal = 800;
  localparam int unsigned VVisible = 480;
  localparam int unsigned VSyncStart = 480 + 10;
  localparam int unsigned VSyncEnd = 480 + 10 + 2;
  localparam int unsigned VTotal = 525;
  // Letterbox (model::display LETTERBOX_X/Y).
  localparam int unsigned LbX = 80;
  localparam int unsigned LbY = 60;
  // Line buffer: two row slots of 120 words of 12 bytes (four pixels).
  localparam int unsigned WordBytes = 12;
  localparam int unsigned RowWords = RowBytes / WordBytes;  // 120
  localparam int unsigned WordW = $clog2(RowWords);         // 7
  localparam int unsigned LbAw = WordW + 1;
  localparam int unsigned OutW = 10;                        // outstanding beats, 0..1023
  localparam int unsigned BurstsW = $clog2(READS_IN_FLIGHT + 1);
  localparam int unsigned StallW = $clog2(STALL_CYCLES) + 1;

  logic en_q, new_frame, frame_tick, pix_edge;
  logic phase_q;              // vga_clk_o; pixel edges where it falls
  logic [9:0] h_q, v_q;
  logic letterbox_q;
  logic [31:3] base_q;

  assign pix_edge = en_q && phase_q;
  assign frame_tick = pix_edge && (h_q == 10'(HTotal - 1)) && (v_q == 10'(VVisible - 1));
  assign new_frame = (enable_i && !en_q) || frame_tick;

  // ---- Timing ----------------------------------------------------------------
  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      en_q        <= 1'b0;
      phase_q     <= 1'b0;
      h_q         <= '0;
      v_q         <= 10'(VVisible);
      letterbox_q <= 1'b0;
      base_q      <= '0;
    end else begin
      en_q <= enable_i;
      phase_q <= !phase_q;
      if (!en_q) begin
        h_q <= '0;
        v_q <= 10'(VVisible);
      end else begin
        if (pix_edge) begin
          if (h_q == 10'(HTotal - 1)) begin
            h_q <= '0;
            v_q <= (v_q == 10'(VTotal - 1)) ? 10'd0 : v_q + 10'd1;
          end else begin
            h_q <= h_q + 10'd1;
          end
        end
      end
      if (new_frame) begin
        letterbox_q <= letterbox_i;
        base_q <= base_i;
      end
    end
  end
  assign frame_o = frame_tick;

  // ---- Mapping (model::display::frame_pixel) -----------------------------------
  // fy of a line: the frame row it shows, and whether it shows one.
  // floor(3d/4) for d < 640: 3d as an adder, no multiplier.
  /* verilator lint_off UNUSEDSIGNAL */
  function automatic logic [8:0] full_of(input logic [9:0] d);
    logic [11:0] t;
    t = {2'b00, d} + {1'b0, d, 1'b0};
    return t[10:2];
  endfunction
  /* verilator lint_on UNUSEDSIGNAL */

  logic in_x, in_y;
  logic [8:0] fx, fy;
  /* verilator lint_off UNUSEDSIGNAL */
  logic [9:0] lb_fx, lb_fy, ahead_lb;  // letterbox offsets; bit 9 only below the box
  /* verilator lint_on UNUSEDSIGNAL */
  assign lb_fx = h_q - 10'(LbX);
  assign lb_fy = v_q - 10'(LbY);
  always_comb begin : p_map
    if (letterbox_q) begin
      in_x = (h_q >= 10'(LbX)) && (h_q < 10'(LbX + Width));
      in_y = (v_q >= 10'(LbY)) && (v_q < 10'(LbY + Height));
      fx = lb_fx[8:0];
      fy = lb_fy[8:0];
    end else begin
      in_x = h_q < 10'(HVisible);
      in_y = v_q < 10'(VVisible);
      fx = full_of(h_q);
      fy = full_of(v_q);
    end
  end

  // The row needed two lines ahead, to allow the reader to fetch it.
  logic [9:0] ahead_v;
  logic [8:0] ahead_fy;
  logic ahead_in;
  assign ahead_lb = ahead_v - 10'(LbY);
  assign ahead_v = v_q + 10'd2;
  always_comb begin : p_ahead
    if (letterbox_q) begin
      ahead_in = (ahead_v >= 10'(LbY)) && (ahead_v < 10'(LbY + Height));
      ahead_fy = ahead_lb[8:0];
    end else begin
      ahead_in = ahead_v < 10'(VVisible);
      ahead_fy = full_of(ahead_v);
    end
  end

  // ---- Reader ----------------------------------------------------------------
  logic flush_q;              // waiting for outstanding beats of an old frame
  row_t allowed_q;            // highest row the reader may fetch
  row_t ar_row_q;             // row of the next burst
  logic [7:0] ar_beat_q;      // beats of that row already requested
  logic [31:3] ar_addr_q;     // address of the next burst
  logic [OutW-1:0] out_q;     // beats requested, not yet received
  logic [BurstsW-1:0] bursts_q;  // bursts issued (ARVALID raised), RLAST not yet received
  logic bad_q;                // an error beat or the stall limit: nothing more this frame
  logic [StallW-1:0] stall_q; // clocks with reads outstanding and no handshake
  logic arvalid_q;
  logic [31:3] araddr_q;
  logic [3:0] arlen_q;
  row_t rx_row_q;             // row being received (rows below it complete)
  logic [WordW-1:0] rx_word_q;  // words of that row written
  logic [63:0] acc_q;         // received bytes not yet written, lowest first
  logic [3:0] acc_n_q;        // bytes in acc_q: 0, 4 or 8

  // Next burst: at most 16 beats, the row's end, the 4 KiB boundary.
  logic [7:0] row_left;
  logic [9:0] page_left;
  logic [4:0] blen;
  always_comb begin : p_burst
    row_left = 8'(RowBeats) - ar_beat_q;
    page_left = 10'd512 - {1'b0, ar_addr_q[11:3]};
    blen = 5'(BurstBeats);
    if (row_left < 8'(BurstBeats)) blen = row_left[4:0];
    if (page_left < 10'(blen)) blen = page_left[4:0];
  end

  logic can_issue, ar_fire, r_fire, r_last, r_error, stalled, waiting;
  assign can_issue = en_q && !flush_q && !bad_q && !new_frame && (ar_row_q <= allowed_q)
                     && (ar_row_q < row_t'(Height)) && (bursts_q < BurstsW'(READS_IN_FLIGHT));
  assign ar_fire = arvalid_q && arready_i;
  assign r_fire = rvalid_i;  // rready_o is always high
  // Counted only while something is outstanding: beats of bursts given up
  // at the stall limit, should a slave still send them, cannot wrap the
  // counters (and lock the reader out).
  logic r_counted;
  assign r_counted = r_fire && (out_q != '0);
  assign r_last = r_fire && rlast_i && (bursts_q != '0);
  assign r_error = r_fire && rresp_i[1];  // SLVERR (2) or DECERR (3)
  assign waiting = arvalid_q || (bursts_q != '0);
  assign stalled = waiting && !(ar_fire || r_fire) && (stall_q == StallW'(STALL_CYCLES - 1));

  // Unpacking: a beat appends 8 bytes; 12 bytes make a word.
  logic [127:0] acc_new;
  logic [4:0] acc_new_n;
  always_comb begin : p_unpack
    unique case (acc_n_q)
      4'd4:    acc_new = {32'd0, rdata_i, acc_q[31:0]};
      4'd8:    acc_new = {rdata_i, acc_q[63:0]};
      default: acc_new = {64'd0, rdata_i};
    endcase
    acc_new_n = 5'(acc_n_q) + 5'd8;
  end

  logic lb_we;
  logic [LbAw-1:0] lb_waddr, lb_raddr;
  logic [8*WordBytes-1:0] lb_rdata;
  logic keep;  // the beat's data goes to the line buffer
  assign keep = r_fire && !flush_q && !bad_q && !r_error;
  assign lb_we = keep && (acc_new_n >= 5'(WordBytes));
  assign lb_waddr = {rx_row_q[0], rx_word_q};

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      flush_q   <= 1'b1;
      allowed_q <= '0;
      ar_row_q  <= '0;
      ar_beat_q <= '0;
      ar_addr_q <= '0;
      out_q     <= '0;
      bursts_q  <= '0;
      bad_q     <= 1'b0;
      stall_q   <= '0;
      read_error_o <= 1'b0;
      stall_o   <= 1'b0;
      arvalid_q <= 1'b0;
      araddr_q  <= '0;
      arlen_q   <= '0;
      rx_row_q  <= '0;
      rx_word_q <= '0;
      acc_q     <= '0;
      acc_n_q   <= '0;
    end else begin
      // AR: the payload holds until ARREADY.
      if (ar_fire) arvalid_q <= 1'b0;
      if (stalled) begin
        // The stall limit: withdraw the request, forget what is outstanding.
        arvalid_q <= 1'b0;
        out_q <= '0;
        bursts_q <= '0;
      end else if ((!arvalid_q || ar_fire) && can_issue) begin
        arvalid_q <= 1'b1;
        araddr_q <= ar_addr_q;
        arlen_q <= 4'(blen - 5'd1);
        ar_addr_q <= ar_addr_q + 29'(blen);
        if (8'(blen) == row_left) begin
          ar_beat_q <= '0;
          ar_row_q <= ar_row_q + row_t'(1);
        end else begin
          ar_beat_q <= ar_beat_q + 8'(blen);
        end
        out_q <= out_q + OutW'(blen) - OutW'(r_counted);
        bursts_q <= bursts_q + BurstsW'(1) - BurstsW'(r_last);
      end else begin
        out_q <= out_q - OutW'(r_counted);
        bursts_q <= bursts_q - BurstsW'(r_last);
      end
      if (!waiting || ar_fire || r_fire || stalled) stall_q <= '0;
      else stall_q <= stall_q + StallW'(1);
      // An error beat of this frame (not a discarded one of the last).
      if ((r_error && !flush_q) || stalled) bad_q <= 1'b1;
      read_error_o <= r_error && !flush_q;
      stall_o <= stalled;

      // R: unpack into the line buffer (discarded while flushing or bad).
      if (keep) begin
        if (acc_new_n >= 5'(WordBytes)) begin
          acc_q <= {32'd0, acc_new[127:96]};
          acc_n_q <= 4'(acc_new_n - 5'(WordBytes));
          if (rx_word_q == WordW'(RowWords - 1)) begin
            rx_word_q <= '0;
            rx_row_q <= rx_row_q + row_t'(1);
          end else begin
            rx_word_q <= rx_word_q + WordW'(1);
          end
        end else begin
          acc_q <= acc_new[63:0];
          acc_n_q <= 4'(acc_new_n);
        end
      end

      // The display allows the row it needs two lines ahead.
      if (pix_edge && h_q == 10'(HVisible - 1) && ahead_in && row_t'(ahead_fy) > allowed_q)
        allowed_q <= row_t'(ahead_fy);

      // A new frame (or disabled): start over once nothing is outstanding.
      if (new_frame || !en_q) begin
        flush_q <= 1'b1;
        bad_q <= 1'b0;
        allowed_q <= row_t'(1);
        rx_row_q <= '0;
        rx_word_q <= '0;
        acc_n_q <= '0;
      end else if (flush_q && out_q == '0 && !arvalid_q) begin
        flush_q <= 1'b0;
        ar_row_q <= '0;
        ar_beat_q <= '0;
        ar_addr_q <= base_q;
      end
    end
  end

  assign araddr_o = {araddr_q, 3'b000};
  assign arlen_o = arlen_q;
  assign arsize_o = 3'b011;    // 8 bytes per beat
  assign arburst_o = 2'b01;    // INCR
  assign arcache_o = 4'b0000;  // as the frame DMA's writes
  assign arprot_o = 3'b000;
  assign arvalid_o = arvalid_q;
  assign rready_o = 1'b1;

  // RRESP bit 0 (EXOKAY) means nothing for a read that is not exclusive.
  /* verilator lint_off UNUSEDSIGNAL */
  logic unused_r;
  assign unused_r = rresp_i[0];
  /* verilator lint_on UNUSEDSIGNAL */

  rt_line_buffer #(.DEPTH(2 * 128), .WIDTH(8 * WordBytes)) u_lb (
    .clk_i,
    .we_i(lb_we), .waddr_i(lb_waddr), .wdata_i(acc_new[8*WordBytes-1:0]),
    .raddr_i(lb_raddr), .rdata_o(lb_rdata)
  );

  // ---- Output ----------------------------------------------------------------
  // The word of pixel fx is read on the edge before the pixel edge, and
  // whether it had arrived is registered with it (a word written on that
  // edge does not count).
  logic [WordW-1:0] word;
  logic word_ok, word_ok_q;
  logic [1:0] lane_q;
  assign word = fx[8:2];
  assign lb_raddr = {fy[0], word};
  assign word_ok = (row_t'(fy) < rx_row_q) || ((row_t'(fy) == rx_row_q) && (word < rx_word_q));

  logic cut_q;
  logic hs_q, vs_q, blank_n_q;
  rgb_t rgb_q, px;
  logic show, late;
  always_comb begin : p_pixel
    unique case (lane_q)
      2'd1:    px = '{r: lb_rdata[31:24], g: lb_rdata[39:32], b: lb_rdata[47:40]};
      2'd2:    px = '{r: lb_rdata[55:48], g: lb_rdata[63:56], b: lb_rdata[71:64]};
      2'd3:    px = '{r: lb_rdata[79:72], g: lb_rdata[87:80], b: lb_rdata[95:88]};
      default: px = '{r: lb_rdata[7:0],   g: lb_rdata[15:8],  b: lb_rdata[23:16]};
    endcase
    show = in_x && in_y;
    late = show && (!word_ok_q || flush_q || bad_q);
  end

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      word_ok_q  <= 1'b0;
      lane_q     <= '0;
      cut_q      <= 1'b0;
      hs_q       <= 1'b1;
      vs_q       <= 1'b1;
      blank_n_q  <= 1'b0;
      rgb_q      <= '0;
      underrun_o <= 1'b0;
    end else begin
      word_ok_q <= word_ok;
      lane_q <= fx[1:0];
      underrun_o <= 1'b0;
      if (!en_q) begin
        // Blank and black, changed where vga_clk_o falls like every pixel,
        // so the DAC latches them at its next rising edge.
        cut_q <= 1'b0;
        if (phase_q) begin
          hs_q <= 1'b1;
          vs_q <= 1'b1;
          blank_n_q <= 1'b0;
          rgb_q <= '0;
        end
      end else if (pix_edge) begin
        hs_q <= !((h_q >= 10'(HSyncStart)) && (h_q < 10'(HSyncEnd)));
        vs_q <= !((v_q >= 10'(VSyncStart)) && (v_q < 10'(VSyncEnd)));
        blank_n_q <= (h_q < 10'(HVisible)) && (v_q < 10'(VVisible));
        if (h_q == 10'(HTotal - 1)) begin
          cut_q <= 1'b0;
        end else if (late && !cut_q) begin
          cut_q <= 1'b1;
          underrun_o <= 1'b1;
        end
        rgb_q <= (show && !late && !cut_q) ? px : '0;
      end
    end
  end

  assign vga_clk_o = phase_q;
  assign vga_hs_o = hs_q;
  assign vga_vs_o = vs_q;
  assign vga_blank_n_o = blank_n_q;
  assign vga_sync_n_o = 1'b0;
  assign vga_r_o = rgb_q.r;
  assign vga_g_o = rgb_q.g;
  assign vga_b_o = rgb_q.b;
endmodule
