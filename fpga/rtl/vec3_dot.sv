// vec3_dot (model/src/arith.rs): the three exact products are summed at full
// width and rounded once, sat((ax*bx + ay*by + az*bz + 2^9) >>> 10); not the
// sum of three fp_mul. Latency rt_pkg::DotLat = 2.
module vec3_dot
  import rt_pkg::*;
(
  input  logic  clk_i,
  input  logic  en_i,
  input  vec3_t a_i,
  input  vec3_t b_i,
  output q_t    y_o
);
  // Signed 24 x 24-bit products into 48-bit targets (q_t members are signed).
  logic signed [47:0] px_q, py_q, pz_q;
  always_ff @(posedge clk_i) begin
    if (en_i) begin
      px_q <= a_i.x * b_i.x;
      py_q <= a_i.y * b_i.y;
      pz_q <= a_i.z * b_i.z;
      y_o  <= qround(64'(px_q) + 64'(py_q) + 64'(pz_q));
    end
  end
endmodule
