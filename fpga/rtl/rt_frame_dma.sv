// Frame DMA: writes each finished row of a frame as packed RGB888 wire bytes
// (1,440 bytes, pixel 0's R at the lowest address) to base + row * 1440
// through a 64-bit AXI3 write master (the HPS FPGA-to-SDRAM port,
// docs/frame-dma.md).
//
// * Rows arrive in order from the scheduler, row r in line-buffer slot
//   r % LbSlots; the packer reads one pixel per clock, turns 8 pixels into
//   3 beats, and gives the slot back as soon as it has read it, so the
//   scheduler renders rows k + 1 .. k + 3 while row k is written.
// * Bursts of at most 16 beats never cross a 128-byte boundary (so never a
//   4 KiB one, AXI3 A3.4.1) nor a row end; AW and W walk the same burst
//   sequence, AW only for rows whose data is being packed, at most
//   MaxBursts outstanding.
// * rows_landed_o counts rows whose every burst has its write response:
//   the AXI FPGA-to-SDRAM port answers once the write is ordered before any
//   later access to the same address (Intel EMIF handbook, "MPFE operation
//   ordering"), so the counter never runs ahead of data the CPU can read.
// * W beats of a burst go out as soon as its AW is presented, without
//   waiting for AWREADY (AXI3 A3.3.1: a master must not wait for AWREADY
//   before asserting WVALID), never ahead of it; AW stays valid until
//   accepted. Platform Designer's AXI master network interface, in front
//   of every f2h_sdram port, takes a W beat only while AWVALID is high and
//   accepts AW with the burst's WLAST beat.
// * A response other than OKAY sets error_o (sticky until the next frame)
//   and freezes rows_landed_o; the frame still runs to its end, so busy
//   always clears. done_o is set in the same clock as busy clears when no
//   response failed (sticky until the next frame or clear_done_i).
// * Stopping (hal-avalon map.rs, "Stopping a frame"): abort_i, or
//   STALL_CYCLES clocks without a transfer on any write channel while the
//   DMA waits on the memory (which also sets error_o), stops the frame: no
//   new burst, the bursts already announced finish with WSTRB 0, the
//   outstanding responses are collected, then busy clears with aborted_o
//   set; rows_landed_o stops counting. If the memory stays silent for
//   another STALL_CYCLES while stopping, the DMA withdraws its requests and
//   goes idle anyway. stop_o pulses when a stop begins (the scheduler stops
//   issuing rows).
module rt_frame_dma
  import rt_pkg::*;
#(
  parameter int unsigned LANES = 1,
  parameter int unsigned STALL_CYCLES = 1 << 17  // hal-avalon FRAME_STALL_CYCLES
) (
  input  logic              clk_i,
  input  logic              rst_ni,
  input  logic              start_i,         // a frame starts (scheduler idle)
  input  logic [31:3]       base_i,          // byte address / 8
  input  logic              clear_done_i,    // FRAME_CONTROL clear_done
  input  logic              abort_i,         // FRAME_CONTROL abort
  input  logic              row_done_i,      // the scheduler wrote a row ...
  input  slot_t             row_done_slot_i, // ... into this slot
  output logic [LbSlots-1:0] slot_release_o, // the packer has read a slot
  output logic [SlotW+$clog2(Width/LANES)-1:0] lb_raddr_o,  // line-buffer read, all banks: {slot, index}
  input  rgb_t [LANES-1:0]  lb_rdata_i,
  output logic              busy_o,
  output logic              done_o,
  output row_t              rows_landed_o,
  output logic              error_o,
  output logic              aborted_o,       // sticky until the next frame
  output logic              stop_o,          // a stop begins (pulse)
  // AXI3 write master (no read channels)
  output logic [31:0]       awaddr_o,
  output logic [3:0]        awlen_o,
  output logic [2:0]        awsize_o,
  output logic [1:0]        awburst_o,
  output logic [3:0]        awcache_o,
  output logic [2:0]        awprot_o,
  output logic              awvalid_o,
  input  logic              awready_i,
  output logic [63:0]       wdata_o,
  output logic [7:0]        wstrb_o,
  output logic              wlast_o,
  output logic              wvalid_o,
  input  logic              wready_i,
  input  logic [1:0]        bresp_i,
  input  logic              bvalid_i,
  output logic              bready_o
);
  localparam int unsigned PerLane = Width / LANES;
  localparam int unsigned IdxW = $clog2(PerLane);
  localparam int unsigned LaneBits = $clog2(LANES);
  localparam int unsigned LaneSelW = (LaneBits > 0) ? LaneBits : 1;  // bank select, one bit at least
  localparam int unsigned MaxBursts = 16;
  localparam int unsigned OutstandingW = $clog2(MaxBursts) + 1;  // 0..MaxBursts
  localparam int unsigned FifoDepth = 8;
  localparam int unsigned FifoCntW = $clog2(FifoDepth) + 1;      // 0..FifoDepth
  localparam int unsigned StallW = $clog2(STALL_CYCLES) + 1;     // 0..STALL_CYCLES

  logic active_q, done_q;
  logic stopping_q;           // no new bursts; announced ones finish blank
  logic aborted_q;
  logic w_blank_q;            // W beats go out with every strobe off
  logic [StallW-1:0] stall_q; // clocks waiting on the memory without a transfer

  // ---- Rows waiting in the line buffer ---------------------------------------
  logic [LbSlots-1:0] filled_q;  // slot holds a finished row not yet packed
  slot_t pslot_q;             // slot the packer reads
  row_t prow_q;               // row the packer reads (rows before it are packed)
  logic [9:0] px_q;           // pixel reads issued in the row
  logic rd_q;                 // a read was issued last clock ...
  logic [LaneSelW-1:0] rd_lane_q;  // ... from this bank
  logic rd_last_q;            // ... and it was the row's last pixel

  // ---- Packer and beat FIFO ------------------------------------------------------
  logic [127:0] acc_q;        // bytes in stream order, lowest first
  logic [4:0] acc_n_q;        // valid bytes in acc_q (0..10)
  logic [63:0] fifo_q [FifoDepth];
  logic [FifoCntW-1:0] fifo_n_q;
  logic [$clog2(FifoDepth)-1:0] fifo_rd_q, fifo_wr_q;

  logic can_read, push, pop;
  assign can_read = active_q && !stopping_q && filled_q[pslot_q] && (px_q < 10'(Width))
                    && (fifo_n_q < FifoCntW'(FifoDepth - 2));
  assign lb_raddr_o = {pslot_q, IdxW'(px_q >> LaneBits)};

  rgb_t rd_pixel;
  always_comb begin : p_bank_select
    rd_pixel = lb_rdata_i[0];
    for (int l = 0; l < int'(LANES); l++) if (LaneBits > 0 && rd_lane_q == LaneSelW'(l)) rd_pixel = lb_rdata_i[l];
  end

  // Append R, G, B at the next three byte positions; a full beat leaves.
  logic [127:0] acc_in;
  logic [4:0] acc_n_in;
  always_comb begin
    acc_in = acc_q;
    acc_n_in = acc_n_q;
    if (rd_q) begin
      acc_in = acc_q | (128'({rd_pixel.b, rd_pixel.g, rd_pixel.r}) << (8 * acc_n_q));
      acc_n_in = acc_n_q + 5'd3;
    end
  end
  assign push = acc_n_in >= 5'd8;

  // ---- Burst walk, shared by AW and W -------------------------------------------
  // A burst starts at row beat `inrow` of a row, at beat `beat16` of its
  // 128-byte block (byte address bits 6:3).
  function automatic logic [4:0] burst_len(input logic [3:0] beat16, input logic [7:0] inrow);
    logic [4:0] to_boundary;
    logic [7:0] to_row_end;
    to_boundary = 5'(BurstBeats) - 5'(beat16);
    to_row_end = 8'(RowBeats) - inrow;
    return (8'(to_boundary) < to_row_end) ? to_boundary : to_row_end[4:0];
  endfunction

  // AW side
  logic [31:0] aw_addr_q;
  logic [7:0] aw_inrow_q;
  row_t aw_row_q;
  logic aw_pending_q;          // awvalid held
  logic [4:0] aw_len_q;
  logic aw_last_of_row_q;
  logic [OutstandingW-1:0] outstanding_q;
  // B bookkeeping: one entry per outstanding burst, "last burst of its row".
  logic [MaxBursts-1:0] blast_q;
  logic [$clog2(MaxBursts)-1:0] b_wr_q, b_rd_q;

  // AW only for rows whose data is packed or in the line buffer.
  logic aw_may;
  assign aw_may = active_q && !stopping_q && !aw_pending_q && (aw_row_q < row_t'(Height))
                  && (aw_row_q < prow_q || (aw_row_q == prow_q && filled_q[pslot_q]))
                  && (outstanding_q < OutstandingW'(MaxBursts));
  // Beats of bursts whose address was accepted, and beats sent. W runs up
  // to the end of the burst whose address is presented, never further
  // (AXI3 allows more, but not every slave likes it).
  logic [16:0] aw_beats_q, w_beats_q, announced;
  assign announced = aw_beats_q + (aw_pending_q ? 17'(aw_len_q) : 17'd0);

  // W side
  logic [31:0] w_addr_q;
  logic [7:0] w_inrow_q;
  logic [4:0] w_left_q;        // beats left in the open burst (0: none open)
  logic [4:0] w_len_now;
  assign w_len_now = (w_left_q != 0) ? w_left_q : burst_len(w_addr_q[6:3], w_inrow_q);
  assign wvalid_o = active_q && (w_beats_q < announced) && (w_blank_q || fifo_n_q != 0);
  // Blank beats carry zeros: the FIFO slot under the read pointer may be
  // refilled while a blank beat waits, and a waiting beat's payload must
  // not change (AXI3 A3.2.1).
  assign wdata_o = w_blank_q ? 64'd0 : fifo_q[fifo_rd_q];
  assign wstrb_o = w_blank_q ? 8'h00 : 8'hff;
  assign wlast_o = (w_len_now == 5'd1);
  logic w_fire;
  assign w_fire = wvalid_o && wready_i;
  assign pop = w_fire && !w_blank_q;

  // B side
  row_t rows_acked_q;          // rows whose bursts all answered (errors too)
  row_t rows_landed_q;
  logic error_q;
  assign bready_o = 1'b1;
  logic b_fire;
  assign b_fire = bvalid_i && (outstanding_q != 0);

  // ---- Stopping ---------------------------------------------------------------------
  logic aw_fire, waiting, stalled, stop_now, drained;
  assign aw_fire = awvalid_o && awready_i;
  // Something is owed by the memory: an address or a beat presented, or a
  // response outstanding.
  assign waiting = aw_pending_q || wvalid_o || (outstanding_q != 0);
  assign stalled = waiting && !(aw_fire || w_fire || b_fire) && (stall_q == StallW'(STALL_CYCLES - 1));
  assign stop_now = active_q && !stopping_q && (abort_i || stalled);
  assign drained = stopping_q && !aw_pending_q && (w_beats_q == aw_beats_q) && (outstanding_q == 0);

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      active_q <= 1'b0;
      done_q <= 1'b0;
      filled_q <= '0;
      pslot_q <= '0;
      prow_q <= '0;
      px_q <= '0;
      rd_q <= 1'b0;
      rd_lane_q <= '0;
      rd_last_q <= 1'b0;
      acc_q <= '0;
      acc_n_q <= '0;
      fifo_n_q <= '0;
      fifo_rd_q <= '0;
      fifo_wr_q <= '0;
      aw_addr_q <= '0;
      aw_inrow_q <= '0;
      aw_row_q <= '0;
      aw_pending_q <= 1'b0;
      aw_len_q <= '0;
      aw_last_of_row_q <= 1'b0;
      outstanding_q <= '0;
      blast_q <= '0;
      b_wr_q <= '0;
      b_rd_q <= '0;
      w_addr_q <= '0;
      w_inrow_q <= '0;
      w_left_q <= '0;
      aw_beats_q <= '0;
      w_beats_q <= '0;
      rows_acked_q <= '0;
      rows_landed_q <= '0;
      error_q <= 1'b0;
      stopping_q <= 1'b0;
      aborted_q <= 1'b0;
      w_blank_q <= 1'b0;
      stall_q <= '0;
    end else if (start_i && !active_q) begin
      active_q <= 1'b1;
      done_q <= 1'b0;
      stopping_q <= 1'b0;
      aborted_q <= 1'b0;
      w_blank_q <= 1'b0;
      stall_q <= '0;
      filled_q <= '0;
      pslot_q <= '0;
      prow_q <= '0;
      px_q <= '0;
      rd_q <= 1'b0;
      acc_q <= '0;
      acc_n_q <= '0;
      fifo_n_q <= '0;
      fifo_rd_q <= '0;
      fifo_wr_q <= '0;
      aw_addr_q <= {base_i, 3'b000};
      aw_inrow_q <= '0;
      aw_row_q <= '0;
      aw_pending_q <= 1'b0;
      outstanding_q <= '0;
      b_wr_q <= '0;
      b_rd_q <= '0;
      w_addr_q <= {base_i, 3'b000};
      w_inrow_q <= '0;
      w_left_q <= '0;
      aw_beats_q <= '0;
      w_beats_q <= '0;
      rows_acked_q <= '0;
      rows_landed_q <= '0;
      error_q <= 1'b0;
    end else if (!active_q) begin
      if (clear_done_i) done_q <= 1'b0;
    end else if (stopping_q && stalled) begin
      // The memory answers nothing even now: withdraw and go idle.
      active_q <= 1'b0;
      aborted_q <= 1'b1;
      error_q <= 1'b1;
      aw_pending_q <= 1'b0;
      outstanding_q <= '0;
      stall_q <= '0;
    end else if (drained) begin
      active_q <= 1'b0;
      aborted_q <= 1'b1;
    end else begin
      if (stop_now) begin
        stopping_q <= 1'b1;
        if (stalled) error_q <= 1'b1;
      end
      // Strobes go off from the first beat presented after the stop; a
      // beat already waiting for WREADY keeps its payload.
      if (!(wvalid_o && !wready_i)) w_blank_q <= stopping_q || stop_now;
      if (!waiting || aw_fire || w_fire || b_fire || stalled) stall_q <= '0;
      else stall_q <= stall_q + StallW'(1);

      // Rows finished by the scheduler.
      if (row_done_i) filled_q[row_done_slot_i] <= 1'b1;

      // Packer reads.
      rd_q <= can_read;
      rd_lane_q <= px_q[LaneBits > 0 ? LaneBits - 1 : 0 : 0];
      rd_last_q <= can_read && (px_q == 10'(Width - 1));
      if (can_read) px_q <= px_q + 10'd1;
      if (rd_last_q) begin
        // The row's last pixel is in the packer: the slot is free again.
        filled_q[pslot_q] <= row_done_i && (row_done_slot_i == pslot_q);
        pslot_q <= pslot_q + slot_t'(1);
        prow_q <= prow_q + row_t'(1);
        px_q <= '0;
      end
      acc_q <= push ? (acc_in >> 64) : acc_in;
      acc_n_q <= push ? (acc_n_in - 5'd8) : acc_n_in;
      if (push) begin
        fifo_q[fifo_wr_q] <= acc_in[63:0];
        fifo_wr_q <= fifo_wr_q + 1'b1;
      end
      if (pop) fifo_rd_q <= fifo_rd_q + 1'b1;
      fifo_n_q <= fifo_n_q + FifoCntW'(push) - FifoCntW'(pop);

      // AW: one burst at a time, held until accepted.
      if (aw_may) begin
        aw_pending_q <= 1'b1;
        aw_len_q <= burst_len(aw_addr_q[6:3], aw_inrow_q);
        aw_last_of_row_q <= (aw_inrow_q + 8'(burst_len(aw_addr_q[6:3], aw_inrow_q))) == 8'(RowBeats);
      end
      if (aw_fire) begin
        aw_pending_q <= 1'b0;
        aw_beats_q <= aw_beats_q + 17'(aw_len_q);
        blast_q[b_wr_q] <= aw_last_of_row_q;
        b_wr_q <= b_wr_q + 1'b1;
        aw_addr_q <= aw_addr_q + (32'(aw_len_q) << 3);  // 8 bytes per beat
        if (aw_last_of_row_q) begin
          aw_inrow_q <= '0;
          aw_row_q <= aw_row_q + row_t'(1);
        end else begin
          aw_inrow_q <= aw_inrow_q + 8'(aw_len_q);
        end
      end
      outstanding_q <= outstanding_q + OutstandingW'(aw_fire)
                                     - OutstandingW'(b_fire);

      // W: walk the same bursts as AW.
      if (w_fire) begin
        w_beats_q <= w_beats_q + 17'd1;
        w_left_q <= w_len_now - 5'd1;
        w_addr_q <= w_addr_q + 32'd8;
        w_inrow_q <= (w_inrow_q == 8'(RowBeats - 1)) ? 8'd0 : w_inrow_q + 8'd1;
      end

      // B: count rows; an error freezes the landed count.
      if (b_fire) begin
        b_rd_q <= b_rd_q + 1'b1;
        if (bresp_i != 2'b00) error_q <= 1'b1;
        if (blast_q[b_rd_q]) begin
          rows_acked_q <= rows_acked_q + row_t'(1);
          // A row whose last burst answered after a stop may have blank
          // beats: only rows answered before it count.
          if (!error_q && !stopping_q && bresp_i == 2'b00) rows_landed_q <= rows_landed_q + row_t'(1);
          if (rows_acked_q == row_t'(Height - 1) && !stopping_q) begin
            active_q <= 1'b0;
            done_q <= !error_q && bresp_i == 2'b00;
          end
        end
      end
    end
  end

  assign slot_release_o = rd_last_q ? (LbSlots'(1) << pslot_q) : '0;
  assign awaddr_o = aw_addr_q;
  assign awlen_o = 4'(aw_len_q - 5'd1);
  assign awsize_o = 3'b011;     // 8 bytes per beat
  assign awburst_o = 2'b01;     // INCR
  assign awcache_o = 4'b0000;   // device non-bufferable: the response comes from the end point
  assign awprot_o = 3'b000;
  assign awvalid_o = aw_pending_q;
  assign busy_o = active_q;
  assign done_o = done_q;
  assign rows_landed_o = rows_landed_q;
  assign error_o = error_q;
  assign aborted_o = aborted_q;
  assign stop_o = stop_now;
endmodule
