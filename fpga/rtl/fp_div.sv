// fp_div (model/src/arith.rs): sat(trunc((a << 10) / b)), truncating toward
// zero; b = 0 gives MAX for a >= 0 and MIN for a < 0. Magnitudes are divided
// (|a| << 10 by |b|) and the quotient negated when the signs differ.
// Only 24 quotient bits are computed: a quotient >= 2^24 (|a| >= |b| << 14)
// saturates whatever its low bits are, so it is flagged up front instead.
// Latency rt_pkg::fp_div_lat(BPS).
module fp_div
  import rt_pkg::*;
#(
  parameter int unsigned BPS = 2  // quotient bits per pipeline stage
) (
  input  logic clk_i,
  input  logic en_i,
  input  q_t   a_i,
  input  q_t   b_i,
  output q_t   y_o
);
  localparam int unsigned DivLat = udiv_lat(WordBits, BPS);

  logic [WordBits-1:0] mag_a, mag_b;
  always_comb begin
    mag_a = a_i[WordBits-1] ? WordBits'(-qext(a_i)) : a_i;  // |MIN| = 2^23 fits unsigned
    mag_b = b_i[WordBits-1] ? WordBits'(-qext(b_i)) : b_i;
  end

  logic [WordBits-1:0] mag_a_q, mag_b_q;
  logic neg_q, bzero_q, apos_q, ovf_q;
  always_ff @(posedge clk_i) begin
    if (en_i) begin
      mag_a_q <= mag_a;
      mag_b_q <= mag_b;
      neg_q   <= a_i[WordBits-1] ^ b_i[WordBits-1];
      bzero_q <= (b_i == '0);
      apos_q  <= !a_i[WordBits-1];
      // quotient >= 2^24  <=>  |a| << 10 >= |b| << 24  <=>  |a| >= |b| << 14
      ovf_q   <= {14'd0, mag_a} >= {mag_b, 14'd0};
    end
  end

  logic [WordBits-1:0] quo;
  udiv_pipe #(.N_W(34), .D_W(WordBits), .Q_W(WordBits), .BPS(BPS)) u_div (
    .clk_i, .en_i,
    .n_i({mag_a_q, 10'd0}),
    .d_i(mag_b_q),
    .q_o(quo)
  );

  logic neg_d, bzero_d, apos_d, ovf_d;
  pipe_delay #(.WIDTH(4), .DEPTH(DivLat)) u_flags (
    .clk_i, .en_i,
    .d_i({neg_q, bzero_q, apos_q, ovf_q}),
    .q_o({neg_d, bzero_d, apos_d, ovf_d})
  );

  always_ff @(posedge clk_i) begin
    if (en_i) begin
      if (bzero_d)    y_o <= apos_d ? QMax : QMin;
      else if (ovf_d) y_o <= neg_d ? QMin : QMax;
      else            y_o <= qsat(neg_d ? -64'($unsigned(quo)) : 64'($unsigned(quo)));
    end
  end
endmodule
