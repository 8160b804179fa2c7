// Row scheduler: feeds pixel x = k * LANES + l of a row to lane l (k = 0 ..
// 480 / LANES - 1, all lanes in lockstep) and writes each lane's results
// into its line-buffer bank. Two modes:
//
//   row mode   (row_start_i): one row, into line-buffer slot 0; done when
//              all 480 pixels are written (row_finish_o). The seed's
//              register interface reads it from there.
//   frame mode (frame_start_i): rows 0..359 back to back, row r into slot
//              r % LbSlots, so the pipeline latency is paid once per frame.
//              A row is issued into a slot only once the frame DMA has given
//              it back (slot_release_i) after packing the row before; each
//              finished row is announced with row_done_o / row_done_slot_o.
//
// Outputs come back in issue order (fixed-latency lanes, never stalled), so
// the write side tells rows apart by counting pixels. An abort (the frame
// DMA stopping a frame) ends issuing at once; the scheduler is idle when
// the pixels already in the lanes have come out.
module rt_row_scheduler
  import rt_pkg::*;
#(
  parameter int unsigned LANES    = 1,
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic                     clk_i,
  input  logic                     rst_ni,
  input  logic                     row_start_i,    // accepted only when idle
  input  coord_t                   row_i,
  input  logic                     frame_start_i,  // accepted only when idle
  input  logic                     abort_i,        // frame mode: stop issuing
  input  vec3_t                    light_i,
  input  logic [LbSlots-1:0]       slot_release_i, // DMA done reading a slot
  output logic                     busy_o,
  output logic                     row_finish_o,   // row mode: the row is written
  output logic                     row_done_o,     // frame mode: a row is written
  output slot_t                    row_done_slot_o,
  // line-buffer write ports, one bank per lane: {slot, x / LANES}
  output logic [LANES-1:0]         lb_we_o,
  output logic [LANES-1:0][SlotW+$clog2(Width/LANES)-1:0] lb_waddr_o,
  output rgb_t [LANES-1:0]         lb_wdata_o
);
  localparam int unsigned PerLane = Width / LANES;
  localparam int unsigned IdxW = $clog2(PerLane);
  localparam int unsigned LaneBits = $clog2(LANES);
  // Elaboration check for simulation and lint only (Quartus never sees it).
  // synthesis translate_off
  generate
  if ((1 << LaneBits) != LANES || PerLane * LANES != Width) begin : g_lanes_check
    $error("LANES must be a power of two dividing 480");
  end
  endgenerate
  // synthesis translate_on

  logic   frame_q;     // the current job is a frame
  logic   issuing_q;   // rows left to issue
  coord_t irow_q;      // row being issued (its y)
  slot_t  islot_q;     // slot the row being issued goes to
  logic   iopen_q;     // the row being issued has claimed its slot
  logic [9:0] ik_q;    // pixels issued per lane in the row
  logic [9:0] wpix_q;  // pixels written of the row being written
  slot_t  wslot_q;     // slot the row being written goes to
  logic [9:0] pend_q;  // issue beats not yet written (fewer than the lane latency)
  logic [LbSlots-1:0] held_q;  // slots holding a row the DMA has not released
  vec3_t  light_q;
  logic [LANES-1:0] in_ready, out_valid;
  px_out_t [LANES-1:0] out;

  // A row may start issuing once its slot is free (always so in row mode:
  // the register interface reads slot 0 after the row, before the next).
  logic slot_ok, issue_valid, issue_fire, row_issued;
  assign slot_ok = !frame_q || iopen_q || !held_q[islot_q];
  assign issue_valid = issuing_q && slot_ok;
  assign issue_fire = issue_valid && (&in_ready);
  assign row_issued = issue_fire && (ik_q == 10'(PerLane - 1));

  logic [9:0] n_written;
  always_comb begin : p_count_written
    n_written = '0;
    for (int l = 0; l < int'(LANES); l++) n_written += 10'(out_valid[l]);
  end
  logic row_written;
  assign row_written = (n_written != 0) && (wpix_q + n_written == 10'(Width));

  logic idle;
  assign idle = !issuing_q && (pend_q == '0);

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      frame_q    <= 1'b0;
      issuing_q  <= 1'b0;
      irow_q     <= '0;
      islot_q    <= '0;
      iopen_q    <= 1'b0;
      ik_q       <= '0;
      wpix_q     <= '0;
      wslot_q    <= '0;
      pend_q     <= '0;
      held_q     <= '0;
      light_q    <= '0;
    end else begin
      held_q <= held_q & ~slot_release_i;
      if (idle && (row_start_i || frame_start_i)) begin
        frame_q   <= frame_start_i && !row_start_i;
        issuing_q <= 1'b1;
        irow_q    <= frame_start_i && !row_start_i ? '0 : row_i;
        islot_q   <= '0;
        iopen_q   <= 1'b0;
        ik_q      <= '0;
        wpix_q    <= '0;
        wslot_q   <= '0;
        light_q   <= light_i;
        // Rows an aborted frame left in the line buffer are forgotten.
        held_q    <= '0;
      end else begin
        // Lanes run in lockstep: one issue beat in, one write beat out.
        pend_q <= pend_q + 10'(issue_fire) - 10'(out_valid[0]);
        if (abort_i && frame_q) issuing_q <= 1'b0;
        if (issue_fire) begin
          if (frame_q && !iopen_q) begin
            iopen_q <= 1'b1;
            held_q[islot_q] <= 1'b1;
          end
          if (row_issued) begin
            ik_q    <= '0;
            iopen_q <= 1'b0;
            islot_q <= frame_q ? islot_q + slot_t'(1) : '0;
            irow_q  <= irow_q + 9'd1;
            if (!frame_q || irow_q == coord_t'(Height - 1) || abort_i) issuing_q <= 1'b0;
          end else begin
            ik_q <= ik_q + 10'd1;
          end
        end
        if (n_written != 0) begin
          if (row_written) begin
            wpix_q  <= '0;
            wslot_q <= frame_q ? wslot_q + slot_t'(1) : '0;
          end else begin
            wpix_q <= wpix_q + n_written;
          end
        end
      end
    end
  end
  assign busy_o = !idle;
  assign row_finish_o = row_written && !frame_q;
  assign row_done_o = row_written && frame_q;
  assign row_done_slot_o = wslot_q;

  generate
  genvar l;
  for (l = 0; l < int'(LANES); l = l + 1) begin : g_lane
    pix_t pix;
    coord_t px;
    assign px = coord_t'(ik_q << LaneBits) + coord_t'(l);  // < 480: 9 bits
    assign pix = '{x: px, y: irow_q};
    rt_lane #(.SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_lane (
      .clk_i, .rst_ni, .light_i(light_q),
      .in_valid_i(issue_fire), .in_ready_o(in_ready[l]), .in_i(pix),
      .out_valid_o(out_valid[l]), .out_ready_i(1'b1), .out_o(out[l])
    );
    assign lb_we_o[l] = out_valid[l];
    assign lb_waddr_o[l] = {wslot_q, IdxW'(out[l].x >> LaneBits)};
    assign lb_wdata_o[l] = out[l].rgb;
  end
  endgenerate
endmodule
