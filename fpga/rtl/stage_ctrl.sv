// Valid/ready control of a fixed-latency stage: the whole stage advances
// (en_o) when its output slot is empty or being taken, so a stall holds every
// register and nothing is dropped. With an always-ready sink it never stalls
// and the stage accepts one item per clock.
module stage_ctrl #(
  parameter int unsigned LAT = 1
) (
  input  logic clk_i,
  input  logic rst_ni,
  input  logic in_valid_i,
  output logic in_ready_o,
  output logic out_valid_o,
  input  logic out_ready_i,
  output logic en_o
);
  logic [LAT-1:0] vld_q;
  assign en_o = out_ready_i || !out_valid_o;
  assign in_ready_o = en_o;
  assign out_valid_o = vld_q[LAT-1];

  generate
  if (LAT == 1) begin : g_one
    always_ff @(posedge clk_i or negedge rst_ni) begin
      if (!rst_ni)   vld_q <= '0;
      else if (en_o) vld_q <= in_valid_i;
    end
  end else begin : g_many
    always_ff @(posedge clk_i or negedge rst_ni) begin
      if (!rst_ni)   vld_q <= '0;
      else if (en_o) vld_q <= {vld_q[LAT-2:0], in_valid_i};
    end
  end
  endgenerate
endmodule
