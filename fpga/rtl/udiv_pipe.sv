// Pipelined unsigned restoring division, BPS quotient bits per stage:
// q = floor(n / d) for Q_W quotient bits. Precondition (the caller's range
// reduction guarantees it): n >> Q_W < d, so the quotient fits Q_W bits and
// the upper dividend bits seed the remainder. d = 0 gives all ones (callers
// mask that case). Latency rt_pkg::udiv_lat(Q_W, BPS).
module udiv_pipe #(
  parameter int unsigned N_W = 34,
  parameter int unsigned D_W = 24,
  parameter int unsigned Q_W = 24,
  parameter int unsigned BPS = 2
) (
  input  logic           clk_i,
  input  logic           en_i,
  input  logic [N_W-1:0] n_i,
  input  logic [D_W-1:0] d_i,
  output logic [Q_W-1:0] q_o
);
  localparam int unsigned Stages = (Q_W + BPS - 1) / BPS;

  // The last stage's remainder, dividend and divisor are dropped.
  /* verilator lint_off UNUSEDSIGNAL */
  logic [Stages:0][D_W-1:0] rem;
  logic [Stages:0][Q_W-1:0] low;  // dividend bits still to shift in
  logic [Stages:0][Q_W-1:0] quo;
  logic [Stages:0][D_W-1:0] div;
  /* verilator lint_on UNUSEDSIGNAL */

  assign rem[0] = D_W'(n_i[N_W-1:Q_W]);
  assign low[0] = n_i[Q_W-1:0];
  assign quo[0] = '0;
  assign div[0] = d_i;

  generate
  genvar s;
  for (s = 0; s < Stages; s = s + 1) begin : g_stage
    logic [D_W-1:0] r;
    logic [Q_W-1:0] l, q;
    logic [D_W:0] r2;
    always_comb begin : p_step
      r = rem[s];
      l = low[s];
      q = quo[s];
      r2 = '0;
      for (int i = 0; i < int'(BPS); i++) begin
        if (s * int'(BPS) + i < int'(Q_W)) begin
          r2 = {r, l[Q_W-1]};
          l = l << 1;
          if (r2 >= {1'b0, div[s]}) begin
            r2 = r2 - {1'b0, div[s]};
            q = {q[Q_W-2:0], 1'b1};
          end else begin
            q = {q[Q_W-2:0], 1'b0};
          end
          r = r2[D_W-1:0];
        end
      end
    end
    logic [D_W-1:0] r_q, d_q;
    logic [Q_W-1:0] l_q, q_q;
    always_ff @(posedge clk_i) begin
      if (en_i) begin
        r_q <= r;
        l_q <= l;
        q_q <= q;
        d_q <= div[s];
      end
    end
    assign rem[s+1] = r_q;
    assign low[s+1] = l_q;
    assign quo[s+1] = q_q;
    assign div[s+1] = d_q;
  end
  endgenerate

  assign q_o = quo[Stages];
endmodule
