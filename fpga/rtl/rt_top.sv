// Ray-tracer accelerator: Avalon-MM slave (CSRs + line-buffer window), row
// scheduler with LANES fully pipelined lanes, the banked line buffer (four
// row slots per bank), and the frame DMA with its AXI3 write master.
// Default LANES = 1: in frame mode one lane renders about 289 frames/s at
// 50 MHz, more than Gigabit Ethernet carries, at about half the DSP blocks
// and logic of two (fpga/README.md, docs/frame-dma.md). The VGA scan-out
// (rt_vga) owns the AXI read channels of the same port; the board I/O block
// (rt_board_io) the keys, switches, LEDs and 7-segment displays.
module rt_top
  import rt_pkg::*;
#(
  parameter int unsigned LANES    = 1,  // power of two dividing 480
  parameter int unsigned SQRT_BPS = 2,  // root bits per square-root stage
  parameter int unsigned DIV_BPS  = 2,  // quotient bits per divider stage
  parameter logic [31:0] BUILD_ID = 32'h0  // read at BUILD_ID (0x4C); 0: none
) (
  input  logic        clk_i,
  input  logic        rst_ni,
  // Avalon-MM slave: the registers (lightweight HPS-to-FPGA bridge)
  input  logic [10:0] avs_address_i,
  input  logic        avs_read_i,
  input  logic        avs_write_i,
  input  logic [31:0] avs_writedata_i,
  output logic [31:0] avs_readdata_o,
  // AXI3 write master: frames into HPS SDRAM (FPGA-to-SDRAM port)
  output logic [31:0] axm_awaddr_o,
  output logic [3:0]  axm_awlen_o,
  output logic [2:0]  axm_awsize_o,
  output logic [1:0]  axm_awburst_o,
  output logic [3:0]  axm_awcache_o,
  output logic [2:0]  axm_awprot_o,
  output logic        axm_awvalid_o,
  input  logic        axm_awready_i,
  output logic [63:0] axm_wdata_o,
  output logic [7:0]  axm_wstrb_o,
  output logic        axm_wlast_o,
  output logic        axm_wvalid_o,
  input  logic        axm_wready_i,
  input  logic [1:0]  axm_bresp_i,
  input  logic        axm_bvalid_i,
  output logic        axm_bready_o,
  // AXI3 read master: the VGA scan-out reads frames from HPS SDRAM
  output logic [31:0] axm_araddr_o,
  output logic [3:0]  axm_arlen_o,
  output logic [2:0]  axm_arsize_o,
  output logic [1:0]  axm_arburst_o,
  output logic [3:0]  axm_arcache_o,
  output logic [2:0]  axm_arprot_o,
  output logic        axm_arvalid_o,
  input  logic        axm_arready_i,
  input  logic [63:0] axm_rdata_i,
  input  logic [1:0]  axm_rresp_i,
  input  logic        axm_rlast_i,
  input  logic        axm_rvalid_i,
  output logic        axm_rready_o,
  // VGA DAC (ADV7123), 640x480@60
  output logic        vga_clk_o,
  output logic        vga_hs_o,
  output logic        vga_vs_o,
  output logic        vga_blank_n_o,
  output logic        vga_sync_n_o,
  output logic [7:0]  vga_r_o,
  output logic [7:0]  vga_g_o,
  output logic [7:0]  vga_b_o,
  // Board I/O
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
  localparam int unsigned PerLane = Width / LANES;
  localparam int unsigned IdxW = $clog2(PerLane);
  localparam int unsigned BankAw = SlotW + IdxW;

  logic row_start, frame_start, frame_clear_done, sched_busy, dma_busy, dma_done, row_finish, row_done;
  logic frame_error, frame_abort, frame_aborted, frame_stop;
  slot_t row_done_slot;
  logic [LbSlots-1:0] slot_release;
  row_t rows_landed;
  coord_t row;
  vec3_t light;
  logic [31:3] frame_base;
  logic [LANES-1:0] lb_we;
  logic [LANES-1:0][BankAw-1:0] lb_waddr;
  rgb_t [LANES-1:0] lb_wdata, lb_rdata;
  logic [IdxW-1:0] slave_raddr;
  logic [BankAw-1:0] dma_raddr, lb_raddr;
  logic vga_enable, vga_letterbox, vga_frame, vga_underrun, vga_read_error, vga_stall;
  logic [31:3] vga_base;
  logic [3:0] keys_down, keys_went;
  logic [9:0] switches, leds;
  logic [31:0] hex_lo;
  logic [15:0] hex_hi;

  rt_avalon_slave #(.LANES(LANES), .BUILD_ID(BUILD_ID)) u_slave (
    .clk_i, .rst_ni,
    .address_i(avs_address_i), .read_i(avs_read_i), .write_i(avs_write_i),
    .writedata_i(avs_writedata_i), .readdata_o(avs_readdata_o),
    .row_start_o(row_start), .frame_start_o(frame_start), .frame_clear_done_o(frame_clear_done),
    .frame_abort_o(frame_abort),
    .row_o(row), .light_o(light),
    .frame_base_o(frame_base), .busy_i(sched_busy || dma_busy), .row_finish_i(row_finish),
    .frame_busy_i(dma_busy), .frame_done_i(dma_done), .frame_error_i(frame_error),
    .frame_aborted_i(frame_aborted), .rows_landed_i(rows_landed),
    .vga_enable_o(vga_enable), .vga_letterbox_o(vga_letterbox), .vga_base_o(vga_base),
    .vga_frame_i(vga_frame), .vga_underrun_i(vga_underrun),
    .vga_read_error_i(vga_read_error), .vga_stall_i(vga_stall),
    .keys_down_i(keys_down), .keys_went_i(keys_went), .switches_i(switches),
    .leds_o(leds), .hex_lo_o(hex_lo), .hex_hi_o(hex_hi),
    .lb_raddr_o(slave_raddr), .lb_rdata_i(lb_rdata)
  );

  rt_vga u_vga (
    .clk_i, .rst_ni,
    .enable_i(vga_enable), .letterbox_i(vga_letterbox), .base_i(vga_base),
    .frame_o(vga_frame), .underrun_o(vga_underrun), .read_error_o(vga_read_error), .stall_o(vga_stall),
    .araddr_o(axm_araddr_o), .arlen_o(axm_arlen_o), .arsize_o(axm_arsize_o), .arburst_o(axm_arburst_o),
    .arcache_o(axm_arcache_o), .arprot_o(axm_arprot_o), .arvalid_o(axm_arvalid_o), .arready_i(axm_arready_i),
    .rdata_i(axm_rdata_i), .rresp_i(axm_rresp_i), .rlast_i(axm_rlast_i), .rvalid_i(axm_rvalid_i),
    .rready_o(axm_rready_o),
    .vga_clk_o, .vga_hs_o, .vga_vs_o, .vga_blank_n_o, .vga_sync_n_o, .vga_r_o, .vga_g_o, .vga_b_o
  );

  rt_board_io u_io (
    .clk_i, .rst_ni,
    .key_n_i, .sw_i,
    .keys_down_o(keys_down), .keys_went_o(keys_went), .switches_o(switches),
    .leds_i(leds), .hex_lo_i(hex_lo), .hex_hi_i(hex_hi),
    .ledr_o, .hex0_n_o, .hex1_n_o, .hex2_n_o, .hex3_n_o, .hex4_n_o, .hex5_n_o
  );

  rt_row_scheduler #(.LANES(LANES), .SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_sched (
    .clk_i, .rst_ni,
    .row_start_i(row_start), .row_i(row), .frame_start_i(frame_start), .abort_i(frame_stop), .light_i(light),
    .slot_release_i(slot_release),
    .busy_o(sched_busy), .row_finish_o(row_finish), .row_done_o(row_done), .row_done_slot_o(row_done_slot),
    .lb_we_o(lb_we), .lb_waddr_o(lb_waddr), .lb_wdata_o(lb_wdata)
  );

  rt_frame_dma #(.LANES(LANES)) u_dma (
    .clk_i, .rst_ni,
    .start_i(frame_start), .base_i(frame_base), .clear_done_i(frame_clear_done), .abort_i(frame_abort),
    .row_done_i(row_done), .row_done_slot_i(row_done_slot), .slot_release_o(slot_release),
    .lb_raddr_o(dma_raddr), .lb_rdata_i(lb_rdata),
    .busy_o(dma_busy), .done_o(dma_done), .rows_landed_o(rows_landed), .error_o(frame_error),
    .aborted_o(frame_aborted), .stop_o(frame_stop),
    .awaddr_o(axm_awaddr_o), .awlen_o(axm_awlen_o), .awsize_o(axm_awsize_o), .awburst_o(axm_awburst_o),
    .awcache_o(axm_awcache_o), .awprot_o(axm_awprot_o), .awvalid_o(axm_awvalid_o), .awready_i(axm_awready_i),
    .wdata_o(axm_wdata_o), .wstrb_o(axm_wstrb_o), .wlast_o(axm_wlast_o), .wvalid_o(axm_wvalid_o),
    .wready_i(axm_wready_i), .bresp_i(axm_bresp_i), .bvalid_i(axm_bvalid_i), .bready_o(axm_bready_o)
  );

  // The line buffer's read port: the DMA's during a frame, else the
  // register interface's (slot 0).
  assign lb_raddr = dma_busy ? dma_raddr : {SlotW'(0), slave_raddr};

  generate
  genvar l;
  for (l = 0; l < int'(LANES); l = l + 1) begin : g_bank
    rt_line_buffer #(.DEPTH(1 << BankAw), .WIDTH($bits(rgb_t))) u_lb (
      .clk_i,
      .we_i(lb_we[l]), .waddr_i(lb_waddr[l]), .wdata_i(lb_wdata[l]),
      .raddr_i(lb_raddr), .rdata_o(lb_rdata[l])
    );
  end
  endgenerate
endmodule
