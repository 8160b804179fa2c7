// normalize (model/src/arith.rs) by power-of-two range reduction, one 30-bit
// integer square root, one reciprocal 2^33 / len_w and three multiplies:
//   m = max|v|, k = bit length of m, s = k - 14, w = v >>> s (or v << -s),
//   len_w = isqrt(w.w), recip = floor(2^33 / len_w),
//   dir = sat((w * recip + 2^22) >>> 23), len = sat(len_w << s) (or >> -s).
// After reduction |w| <= 2^14, so len_w is in [2^13, 28378] and recip in
// [302705, 2^20]: the squares fit 18x18 multipliers, the reciprocal 21 bits.
// m = 0 gives the zero vector and length 0.
// Latency rt_pkg::normalize_lat(SQRT_BPS, DIV_BPS).
module normalize
  import rt_pkg::*;
#(
  parameter int unsigned IN_W     = 25,  // component width (WideVec3: 25 bits)
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic                   clk_i,
  input  logic                   en_i,
  input  logic signed [IN_W-1:0] vx_i,
  input  logic signed [IN_W-1:0] vy_i,
  input  logic signed [IN_W-1:0] vz_i,
  output vec3_t                  dir_o,
  output q_t                     len_o
);
  localparam int TopBit = 13;  // NORMALIZE_TOP_BIT
  localparam int WW = 15;      // |w| <= 2^14: 15-bit signed
  localparam int SW = 7;       // shift amount s in [-13, IN_W - 14]
  localparam int SqrtLat = isqrt_lat(15, SQRT_BPS);
  localparam int DivLat = udiv_lat(21, DIV_BPS);

  typedef logic signed [IN_W-1:0] in_t;
  typedef logic signed [WW-1:0] w_t;
  typedef logic signed [SW-1:0] s_t;

  function automatic logic [IN_W-1:0] mag(input in_t v);
    return v[IN_W-1] ? IN_W'(-v) : v;  // |-2^(IN_W-1)| fits unsigned
  endfunction

  // Cycle 1: magnitudes and their maximum.
  in_t vx_q, vy_q, vz_q;
  logic [IN_W-1:0] m_q;
  logic [IN_W-1:0] ax, ay, az, axy, m;
  always_comb begin
    ax = mag(vx_i);
    ay = mag(vy_i);
    az = mag(vz_i);
    axy = (ax > ay) ? ax : ay;
    m = (axy > az) ? axy : az;
  end
  always_ff @(posedge clk_i) begin
    if (en_i) begin
      m_q <= m;
      vx_q <= vx_i;
      vy_q <= vy_i;
      vz_q <= vz_i;
    end
  end

  // Cycle 2: bit length, shift, range reduction.
  // Only the low WW bits survive: |w| <= 2^14 by construction.
  /* verilator lint_off UNUSEDSIGNAL */
  function automatic w_t reduce(input in_t v, input s_t s);
    in_t r;
    if (s >= 0) r = v >>> s;
    else        r = v <<< (-s);
    return WW'(r);
  endfunction
  /* verilator lint_on UNUSEDSIGNAL */

  w_t wx_q, wy_q, wz_q;
  s_t s_q;
  logic zero_q;
  s_t s;
  always_comb begin : p_bit_length
    int k;
    k = 0;
    for (int i = 0; i < int'(IN_W); i++) if (m_q[i]) k = i + 1;
    s = s_t'(k - (TopBit + 1));
  end
  always_ff @(posedge clk_i) begin
    if (en_i) begin
      s_q <= s;
      zero_q <= (m_q == '0);
      wx_q <= reduce(vx_q, s);
      wy_q <= reduce(vy_q, s);
      wz_q <= reduce(vz_q, s);
    end
  end

  // Cycles 3-4: squares, then their exact sum (< 2^30). |w| <= 2^14, so a
  // square is at most 2^28: the signed 15 x 15-bit product, extended to the
  // 29-bit target, is exact.
  logic [28:0] sx_q, sy_q, sz_q;
  logic [29:0] q_q;
  always_ff @(posedge clk_i) begin
    if (en_i) begin
      sx_q <= wx_q * wx_q;
      sy_q <= wy_q * wy_q;
      sz_q <= wz_q * wz_q;
      q_q <= 30'(sx_q) + 30'(sy_q) + 30'(sz_q);
    end
  end
  // w, s, zero wait for the sum (1 cycle), isqrt, reciprocal.
  w_t wx_d, wy_d, wz_d;
  s_t s_d;
  logic zero_d;
  pipe_delay #(.WIDTH(3 * WW + SW + 1), .DEPTH(2 + SqrtLat + DivLat)) u_wdelay (
    .clk_i, .en_i,
    .d_i({wx_q, wy_q, wz_q, s_q, zero_q}),
    .q_o({wx_d, wy_d, wz_d, s_d, zero_d})
  );

  logic [14:0] len_w;
  isqrt_pipe #(.R_W(15), .BPS(SQRT_BPS)) u_isqrt (
    .clk_i, .en_i, .n_i(q_q), .root_o(len_w)
  );

  logic [20:0] recip;
  udiv_pipe #(.N_W(34), .D_W(15), .Q_W(21), .BPS(DIV_BPS)) u_recip (
    .clk_i, .en_i, .n_i(34'h2_0000_0000), .d_i(len_w), .q_o(recip)
  );
  logic [14:0] len_w_d;
  pipe_delay #(.WIDTH(15), .DEPTH(DivLat + 1)) u_ldelay (
    .clk_i, .en_i, .d_i(len_w), .q_o(len_w_d)
  );

  // Cycle: w * recip (15 x 22 bits signed, the reciprocal with a zero sign
  // bit) into 37-bit targets; then round half up and saturate.
  logic signed [36:0] px_q, py_q, pz_q;
  s_t s_m;
  logic zero_m;
  always_ff @(posedge clk_i) begin
    if (en_i) begin
      px_q <= wx_d * $signed({1'b0, recip});
      py_q <= wy_d * $signed({1'b0, recip});
      pz_q <= wz_d * $signed({1'b0, recip});
      s_m <= s_d;
      zero_m <= zero_d;
    end
  end

  function automatic q_t round23(input logic signed [36:0] p);
    return qsat((64'(p) + 64'sd4194304) >>> 23);
  endfunction

  always_ff @(posedge clk_i) begin
    if (en_i) begin
      if (zero_m) begin
        dir_o <= '0;
        len_o <= '0;
      end else begin
        dir_o.x <= round23(px_q);
        dir_o.y <= round23(py_q);
        dir_o.z <= round23(pz_q);
        if (s_m >= 0) len_o <= qsat(64'(len_w_d) << s_m);
        else          len_o <= q_t'(24'(len_w_d) >> (-s_m));
      end
    end
  end
endmodule
