// fp_sqrt (model/src/arith.rs): floor(sqrt(a << 10)) for a > 0, 0 otherwise.
// The 33-bit radicand gives a 17-bit root that always fits a word.
// Latency rt_pkg::fp_sqrt_lat(BPS).
module fp_sqrt
  import rt_pkg::*;
#(
  parameter int unsigned BPS = 2  // root bits per pipeline stage
) (
  input  logic clk_i,
  input  logic en_i,
  input  q_t   a_i,
  output q_t   y_o
);
  logic [33:0] rad_q;
  always_ff @(posedge clk_i) begin
    if (en_i) rad_q <= (a_i > 0) ? {1'b0, a_i[WordBits-2:0], 10'd0} : '0;
  end

  logic [16:0] root;
  isqrt_pipe #(.R_W(17), .BPS(BPS)) u_isqrt (
    .clk_i, .en_i,
    .n_i(rad_q),
    .root_o(root)
  );
  assign y_o = q_t'({7'd0, root});
endmodule
