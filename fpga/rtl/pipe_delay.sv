// Fixed delay line with a clock enable: aligns side data with a pipelined
// primitive of the same latency. DEPTH = 0 is a wire.
module pipe_delay #(
  parameter int unsigned WIDTH = 1,
  parameter int unsigned DEPTH = 1
) (
  input  logic             clk_i,
  input  logic             en_i,
  input  logic [WIDTH-1:0] d_i,
  output logic [WIDTH-1:0] q_o
);
  generate
  if (DEPTH == 0) begin : g_wire
    assign q_o = d_i;
    /* verilator lint_off UNUSEDSIGNAL */
    logic unused;
    assign unused = clk_i ^ en_i;
    /* verilator lint_on UNUSEDSIGNAL */
  end else begin : g_regs
    // One packed vector: Verilator simulates packed shift registers fastest.
    logic [DEPTH*WIDTH-1:0] sr_q;
    if (DEPTH == 1) begin : g_one
      always_ff @(posedge clk_i) if (en_i) sr_q <= d_i;
    end else begin : g_many
      always_ff @(posedge clk_i) if (en_i) sr_q <= {sr_q[(DEPTH-1)*WIDTH-1:0], d_i};
    end
    assign q_o = sr_q[DEPTH*WIDTH-1 -: WIDTH];
  end
  endgenerate
endmodule
