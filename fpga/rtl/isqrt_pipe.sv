// Pipelined restoring integer square root, BPS root bits per stage:
// root = floor(sqrt(n)) for a 2*R_W-bit radicand (model arith::isqrt).
// Latency rt_pkg::isqrt_lat(R_W, BPS).
module isqrt_pipe #(
  parameter int unsigned R_W = 15,
  parameter int unsigned BPS = 2
) (
  input  logic             clk_i,
  input  logic             en_i,
  input  logic [2*R_W-1:0] n_i,
  output logic [R_W-1:0]   root_o
);
  localparam int unsigned Stages = (R_W + BPS - 1) / BPS;
  localparam int unsigned RemW = R_W + 3;  // rem <= 2*root < 2^(R_W+1), shifted by 2

  // The last stage's remainder and radicand bits are dropped.
  /* verilator lint_off UNUSEDSIGNAL */
  logic [Stages:0][RemW-1:0]  rem;
  logic [Stages:0][2*R_W-1:0] low;  // radicand bit pairs still to bring down
  /* verilator lint_on UNUSEDSIGNAL */
  logic [Stages:0][R_W-1:0]   root;

  assign rem[0] = '0;
  assign low[0] = n_i;
  assign root[0] = '0;

  generate
  genvar s;
  for (s = 0; s < Stages; s = s + 1) begin : g_stage
    logic [RemW-1:0] r, trial;
    logic [2*R_W-1:0] l;
    logic [R_W-1:0] q;
    always_comb begin : p_step
      r = rem[s];
      l = low[s];
      q = root[s];
      trial = '0;
      for (int i = 0; i < int'(BPS); i++) begin
        if (s * int'(BPS) + i < int'(R_W)) begin
          r = {r[RemW-3:0], l[2*R_W-1 -: 2]};
          l = l << 2;
          trial = (RemW'(q) << 2) | RemW'(1);
          if (r >= trial) begin
            r = r - trial;
            q = {q[R_W-2:0], 1'b1};
          end else begin
            q = {q[R_W-2:0], 1'b0};
          end
        end
      end
    end
    logic [RemW-1:0] r_q;
    logic [2*R_W-1:0] l_q;
    logic [R_W-1:0] q_q;
    always_ff @(posedge clk_i) begin
      if (en_i) begin
        r_q <= r;
        l_q <= l;
        q_q <= q;
      end
    end
    assign rem[s+1] = r_q;
    assign low[s+1] = l_q;
    assign root[s+1] = q_q;
  end
  endgenerate

  assign root_o = root[Stages];
endmodule
