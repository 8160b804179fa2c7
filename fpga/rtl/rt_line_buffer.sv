// One bank of the line buffer: simple dual-port RAM, one write port for a
// lane and one registered read port for the Avalon slave. Written in the
// plain form (no reset, no read-during-write logic, registered read) that
// Quartus maps to M10K blocks.
module rt_line_buffer #(
  parameter int unsigned DEPTH = 480,
  parameter int unsigned WIDTH = 24
) (
  // Addresses are $clog2(DEPTH) bits, at least one.
  input  logic             clk_i,
  input  logic             we_i,
  input  logic [((DEPTH > 1) ? $clog2(DEPTH) : 1)-1:0] waddr_i,
  input  logic [WIDTH-1:0] wdata_i,
  input  logic [((DEPTH > 1) ? $clog2(DEPTH) : 1)-1:0] raddr_i,
  output logic [WIDTH-1:0] rdata_o
);
  logic [WIDTH-1:0] mem [DEPTH];
  always_ff @(posedge clk_i) begin
    if (we_i) mem[waddr_i] <= wdata_i;
    rdata_o <= mem[raddr_i];
  end
endmodule
