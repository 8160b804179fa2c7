// Row scheduler: on an accepted start it feeds pixel x = k * LANES + l of the
// latched row to lane l (k = 0 .. 480 / LANES - 1, all lanes in lockstep),
// writes each lane's results into its line-buffer bank, and reports the row
// finished when all 480 pixels are written.
module rt_row_scheduler
  import rt_pkg::*;
#(
  parameter int unsigned LANES    = 1,
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2,
  localparam int unsigned PerLane = Width / LANES,
  localparam int unsigned BankAw = (PerLane > 1) ? $clog2(PerLane) : 1
) (
  input  logic                     clk_i,
  input  logic                     rst_ni,
  input  logic                     start_i,  // accepted start (only when idle)
  input  coord_t                   row_i,
  input  vec3_t                    light_i,
  output logic                     busy_o,
  output logic                     finish_o,  // pulse: the last pixel is written
  // line-buffer write ports, one bank per lane
  output logic [LANES-1:0]         lb_we_o,
  output logic [LANES-1:0][BankAw-1:0] lb_waddr_o,
  output rgb_t [LANES-1:0]         lb_wdata_o
);
  localparam int unsigned LaneBits = $clog2(LANES);
  if ((1 << LaneBits) != LANES || PerLane * LANES != Width) begin : g_lanes_check
    $error("LANES must be a power of two dividing 480");
  end

  coord_t row_q;
  vec3_t light_q;
  logic busy_q;
  logic [9:0] issue_q;    // pixels issued per lane
  logic [9:0] written_q;  // pixels written, all lanes
  logic [LANES-1:0] in_ready, out_valid;
  px_out_t [LANES-1:0] out;

  logic issue_valid, issue_fire;
  assign issue_valid = busy_q && (issue_q < 10'(PerLane));
  assign issue_fire = issue_valid && (&in_ready);

  logic [9:0] n_written;
  always_comb begin
    n_written = '0;
    for (int l = 0; l < int'(LANES); l++) n_written += 10'(out_valid[l]);
  end
  logic last;
  assign last = busy_q && (written_q + n_written == 10'(Width));

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      busy_q    <= 1'b0;
      issue_q   <= '0;
      written_q <= '0;
      row_q     <= '0;
      light_q   <= '0;
    end else if (start_i && !busy_q) begin
      busy_q    <= 1'b1;
      issue_q   <= '0;
      written_q <= '0;
      row_q     <= row_i;
      light_q   <= light_i;
    end else if (busy_q) begin
      if (issue_fire) issue_q <= issue_q + 10'd1;
      written_q <= written_q + n_written;
      if (last) busy_q <= 1'b0;
    end
  end
  assign busy_o = busy_q;
  assign finish_o = last;

  for (genvar l = 0; l < int'(LANES); l++) begin : g_lane
    pix_t pix;
    coord_t px;
    assign px = coord_t'(issue_q << LaneBits) + coord_t'(l);  // < 480: 9 bits
    assign pix = '{x: px, y: row_q};
    rt_lane #(.SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_lane (
      .clk_i, .rst_ni, .light_i(light_q),
      .in_valid_i(issue_fire), .in_ready_o(in_ready[l]), .in_i(pix),
      .out_valid_o(out_valid[l]), .out_ready_i(1'b1), .out_o(out[l])
    );
    assign lb_we_o[l] = out_valid[l];
    assign lb_waddr_o[l] = BankAw'(out[l].x >> LaneBits);
    assign lb_wdata_o[l] = out[l].rgb;
  end
endmodule
