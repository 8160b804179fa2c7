// vec3_cross (model/src/arith.rs): each component is a difference of two exact
// products rounded once, c.x = sat((ay*bz - az*by + 2^9) >>> 10), cyclically.
// Latency rt_pkg::CrossLat = 2.
module vec3_cross
  import rt_pkg::*;
(
  input  logic  clk_i,
  input  logic  en_i,
  input  vec3_t a_i,
  input  vec3_t b_i,
  output vec3_t y_o
);
  // Signed 24 x 24-bit products into 48-bit targets (q_t members are signed).
  logic signed [47:0] p_q [6];
  always_ff @(posedge clk_i) begin
    if (en_i) begin
      p_q[0] <= a_i.y * b_i.z;
      p_q[1] <= a_i.z * b_i.y;
      p_q[2] <= a_i.z * b_i.x;
      p_q[3] <= a_i.x * b_i.z;
      p_q[4] <= a_i.x * b_i.y;
      p_q[5] <= a_i.y * b_i.x;
      y_o.x  <= qround(64'(p_q[0]) - 64'(p_q[1]));
      y_o.y  <= qround(64'(p_q[2]) - 64'(p_q[3]));
      y_o.z  <= qround(64'(p_q[4]) - 64'(p_q[5]));
    end
  end
endmodule
