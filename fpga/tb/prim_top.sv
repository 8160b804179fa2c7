// Co-simulation wrapper for the arithmetic primitives: one instance of each,
// fed the same operands every clock, so the testbench can compare every
// output with model::arith after the primitive's latency (exported here).
module prim_top
  import rt_pkg::*;
#(
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic  clk_i,
  input  q_t    a_i,
  input  q_t    b_i,
  input  vec3_t va_i,
  input  vec3_t vb_i,
  input  wide_t wx_i,
  input  wide_t wy_i,
  input  wide_t wz_i,
  output q_t    mul_o,
  output q_t    div_o,
  output q_t    sqrt_o,
  output q_t    dot_o,
  output vec3_t cross_o,
  output vec3_t ndir_o,
  output q_t    nlen_o,
  output logic [7:0] lat_mul_o,
  output logic [7:0] lat_div_o,
  output logic [7:0] lat_sqrt_o,
  output logic [7:0] lat_dot_o,
  output logic [7:0] lat_cross_o,
  output logic [7:0] lat_norm_o
);
  fp_mul u_mul (.clk_i, .en_i(1'b1), .a_i, .b_i, .y_o(mul_o));
  fp_div #(.BPS(DIV_BPS)) u_div (.clk_i, .en_i(1'b1), .a_i, .b_i, .y_o(div_o));
  fp_sqrt #(.BPS(SQRT_BPS)) u_sqrt (.clk_i, .en_i(1'b1), .a_i, .y_o(sqrt_o));
  vec3_dot u_dot (.clk_i, .en_i(1'b1), .a_i(va_i), .b_i(vb_i), .y_o(dot_o));
  vec3_cross u_cross (.clk_i, .en_i(1'b1), .a_i(va_i), .b_i(vb_i), .y_o(cross_o));
  normalize #(.IN_W(WordBits + 1), .SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_norm (
    .clk_i, .en_i(1'b1), .vx_i(wx_i), .vy_i(wy_i), .vz_i(wz_i), .dir_o(ndir_o), .len_o(nlen_o)
  );
  assign lat_mul_o = 8'(FpMulLat);
  assign lat_div_o = 8'(fp_div_lat(DIV_BPS));
  assign lat_sqrt_o = 8'(fp_sqrt_lat(SQRT_BPS));
  assign lat_dot_o = 8'(DotLat);
  assign lat_cross_o = 8'(CrossLat);
  assign lat_norm_o = 8'(normalize_lat(SQRT_BPS, DIV_BPS));
endmodule
