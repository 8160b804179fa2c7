// Ray-tracer accelerator: Avalon-MM slave (CSRs + line-buffer window), row
// scheduler with LANES fully pipelined lanes, and the banked line buffer.
// Default LANES = 2: two lanes use 82 of the 87 DSP blocks and about 29k of
// the 32,075 ALMs (high estimate); a third lane cannot fit (fpga/README.md).
module rt_top
  import rt_pkg::*;
#(
  parameter int unsigned LANES    = 2,  // power of two dividing 480
  parameter int unsigned SQRT_BPS = 2,  // root bits per square-root stage
  parameter int unsigned DIV_BPS  = 2   // quotient bits per divider stage
) (
  input  logic        clk_i,
  input  logic        rst_ni,
  input  logic [10:0] avs_address_i,
  input  logic        avs_read_i,
  input  logic        avs_write_i,
  input  logic [31:0] avs_writedata_i,
  output logic [31:0] avs_readdata_o
);
  localparam int unsigned PerLane = Width / LANES;
  localparam int unsigned BankAw = (PerLane > 1) ? $clog2(PerLane) : 1;

  logic start, busy, finish;
  coord_t row;
  vec3_t light;
  logic [LANES-1:0] lb_we;
  logic [LANES-1:0][BankAw-1:0] lb_waddr;
  rgb_t [LANES-1:0] lb_wdata, lb_rdata;
  logic [BankAw-1:0] lb_raddr;

  rt_avalon_slave #(.LANES(LANES)) u_slave (
    .clk_i, .rst_ni,
    .address_i(avs_address_i), .read_i(avs_read_i), .write_i(avs_write_i),
    .writedata_i(avs_writedata_i), .readdata_o(avs_readdata_o),
    .start_o(start), .row_o(row), .light_o(light), .busy_i(busy), .finish_i(finish),
    .lb_raddr_o(lb_raddr), .lb_rdata_i(lb_rdata)
  );

  rt_row_scheduler #(.LANES(LANES), .SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_sched (
    .clk_i, .rst_ni,
    .start_i(start), .row_i(row), .light_i(light),
    .busy_o(busy), .finish_o(finish),
    .lb_we_o(lb_we), .lb_waddr_o(lb_waddr), .lb_wdata_o(lb_wdata)
  );

  for (genvar l = 0; l < int'(LANES); l++) begin : g_bank
    rt_line_buffer #(.DEPTH(PerLane), .WIDTH($bits(rgb_t))) u_lb (
      .clk_i,
      .we_i(lb_we[l]), .waddr_i(lb_waddr[l]), .wdata_i(lb_wdata[l]),
      .raddr_i(lb_raddr), .rdata_o(lb_rdata[l])
    );
  end
endmodule
