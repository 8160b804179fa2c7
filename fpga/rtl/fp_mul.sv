// fp_mul (model/src/arith.rs): sat((a * b + 2^9) >>> 10) of the exact 48-bit
// product. Latency rt_pkg::FpMulLat = 2: the product register (the DSP block's
// output register) and the round/saturate register.
module fp_mul
  import rt_pkg::*;
(
  input  logic clk_i,
  input  logic en_i,
  input  q_t   a_i,
  input  q_t   b_i,
  output q_t   y_o
);
  // Signed operands at their own width, extended by the 48-bit target:
  // the exact product in one 27x27 DSP block.
  logic signed [47:0] p_q;
  always_ff @(posedge clk_i) begin
    if (en_i) begin
      p_q <= a_i * b_i;
      y_o <= qround(64'(p_q));
    end
  end
endmodule
