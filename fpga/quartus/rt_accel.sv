// Platform Designer component top (rt_accel_hw.tcl): rt_top with the full
// AXI3 master signal set. Altera's AXI3 master templates declare every
// signal, and which ones Platform Designer lets a write-only master leave
// out is not documented, so the unused ones are here, tied off: IDs 0,
// normal (unlocked) access, and a read channel that never issues.
module rt_accel #(
  parameter int unsigned LANES    = 1,
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic        clk_i,
  input  logic        rst_ni,
  input  logic [10:0] avs_address_i,
  input  logic        avs_read_i,
  input  logic        avs_write_i,
  input  logic [31:0] avs_writedata_i,
  output logic [31:0] avs_readdata_o,
  // write address
  output logic [0:0]  axm_awid_o,
  output logic [31:0] axm_awaddr_o,
  output logic [3:0]  axm_awlen_o,
  output logic [2:0]  axm_awsize_o,
  output logic [1:0]  axm_awburst_o,
  output logic [1:0]  axm_awlock_o,
  output logic [3:0]  axm_awcache_o,
  output logic [2:0]  axm_awprot_o,
  output logic        axm_awvalid_o,
  input  logic        axm_awready_i,
  // write data
  output logic [0:0]  axm_wid_o,
  output logic [63:0] axm_wdata_o,
  output logic [7:0]  axm_wstrb_o,
  output logic        axm_wlast_o,
  output logic        axm_wvalid_o,
  input  logic        axm_wready_i,
  // write response
  input  logic [0:0]  axm_bid_i,
  input  logic [1:0]  axm_bresp_i,
  input  logic        axm_bvalid_i,
  output logic        axm_bready_o,
  // read address and data: never used
  output logic [0:0]  axm_arid_o,
  output logic [31:0] axm_araddr_o,
  output logic [3:0]  axm_arlen_o,
  output logic [2:0]  axm_arsize_o,
  output logic [1:0]  axm_arburst_o,
  output logic [1:0]  axm_arlock_o,
  output logic [3:0]  axm_arcache_o,
  output logic [2:0]  axm_arprot_o,
  output logic        axm_arvalid_o,
  input  logic        axm_arready_i,
  input  logic [0:0]  axm_rid_i,
  input  logic [63:0] axm_rdata_i,
  input  logic [1:0]  axm_rresp_i,
  input  logic        axm_rlast_i,
  input  logic        axm_rvalid_i,
  output logic        axm_rready_o
);
  rt_top #(.LANES(LANES), .SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_rt (
    .clk_i, .rst_ni,
    .avs_address_i, .avs_read_i, .avs_write_i, .avs_writedata_i, .avs_readdata_o,
    .axm_awaddr_o, .axm_awlen_o, .axm_awsize_o, .axm_awburst_o, .axm_awcache_o, .axm_awprot_o,
    .axm_awvalid_o, .axm_awready_i,
    .axm_wdata_o, .axm_wstrb_o, .axm_wlast_o, .axm_wvalid_o, .axm_wready_i,
    .axm_bresp_i, .axm_bvalid_i, .axm_bready_o
  );

  assign axm_awid_o    = '0;
  assign axm_awlock_o  = '0;
  assign axm_wid_o     = '0;
  assign axm_arid_o    = '0;
  assign axm_araddr_o  = '0;
  assign axm_arlen_o   = '0;
  assign axm_arsize_o  = 3'd3;
  assign axm_arburst_o = 2'd1;
  assign axm_arlock_o  = '0;
  assign axm_arcache_o = '0;
  assign axm_arprot_o  = '0;
  assign axm_arvalid_o = 1'b0;
  assign axm_rready_o  = 1'b1;

  // The responses' IDs and the read channel carry nothing the master uses.
  logic unused;
  assign unused = ^{axm_bid_i, axm_arready_i, axm_rid_i, axm_rdata_i, axm_rresp_i, axm_rlast_i, axm_rvalid_i};
endmodule
