// Platform Designer component top (rt_accel_hw.tcl): rt_top with the full
// AXI3 master signal set, and the VGA and board I/O conduits. Altera's AXI3
// master templates declare every signal, and which ones Platform Designer
// lets a master leave out is not documented, so the ones rt_top does not
// have are here, tied off: IDs 0 (one ID per direction, responses in
// order) and normal (unlocked) access. The frame DMA writes, the VGA
// reader reads (at most 4 read bursts outstanding); the conduits go
// straight through to the board's pins (de1_soc_top.sv).
module rt_accel #(
  parameter int unsigned LANES    = 1,
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2,
  parameter int unsigned BUILD_ID = 0
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
  // read address and data: the VGA reader
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
  output logic        axm_rready_o,
  // conduit vga: the DE1-SoC's VGA DAC and connector
  output logic        vga_clk_o,
  output logic        vga_hs_o,
  output logic        vga_vs_o,
  output logic        vga_blank_n_o,
  output logic        vga_sync_n_o,
  output logic [7:0]  vga_r_o,
  output logic [7:0]  vga_g_o,
  output logic [7:0]  vga_b_o,
  // conduit board: push buttons (active low), switches, red LEDs and the
  // six 7-segment displays (segments active low)
  input  logic [3:0]  key_n_i,
  input  logic [9:0]  sw_i,
  output logic [9:0]  ledr_o,
  output logic [6:0]  hex0_n_o,
  output logic [6:0]  hex1_n_o,
  output logic [6:0]  hex2_n_o,
  output logic [6:0]  hex3_n_o,
  output logic [6:0]  hex4_n_o,
  output logic [6:0]  hex5_n_o
);
  rt_top #(.LANES(LANES), .SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS), .BUILD_ID(BUILD_ID)) u_rt (
    .clk_i, .rst_ni,
    .avs_address_i, .avs_read_i, .avs_write_i, .avs_writedata_i, .avs_readdata_o,
    .axm_awaddr_o, .axm_awlen_o, .axm_awsize_o, .axm_awburst_o, .axm_awcache_o, .axm_awprot_o,
    .axm_awvalid_o, .axm_awready_i,
    .axm_wdata_o, .axm_wstrb_o, .axm_wlast_o, .axm_wvalid_o, .axm_wready_i,
    .axm_bresp_i, .axm_bvalid_i, .axm_bready_o,
    .axm_araddr_o, .axm_arlen_o, .axm_arsize_o, .axm_arburst_o, .axm_arcache_o, .axm_arprot_o,
    .axm_arvalid_o, .axm_arready_i,
    .axm_rdata_i, .axm_rresp_i, .axm_rlast_i, .axm_rvalid_i, .axm_rready_o,
    .vga_clk_o, .vga_hs_o, .vga_vs_o, .vga_blank_n_o, .vga_sync_n_o, .vga_r_o, .vga_g_o, .vga_b_o,
    .key_n_i, .sw_i, .ledr_o,
    .hex0_n_o, .hex1_n_o, .hex2_n_o, .hex3_n_o, .hex4_n_o, .hex5_n_o
  );

  assign axm_awid_o    = '0;
  assign axm_awlock_o  = '0;
  assign axm_wid_o     = '0;
  assign axm_arid_o    = '0;
  assign axm_arlock_o  = '0;

  // The responses' IDs carry nothing: one ID per direction.
  logic unused;
  assign unused = ^{axm_bid_i, axm_rid_i};
endmodule
