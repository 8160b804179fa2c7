# Platform Designer system for the DE1-SoC: Cyclone V HPS (DDR3, EMAC1, SD,
# UART0, lightweight HPS-to-FPGA bridge) and the ray-tracer accelerator.
# Run with qsys-script (see build.sh); it writes soc_system.qsys.
#
# The accelerator's slave sits at base 0x0 of the lightweight bridge, so the
# CPU sees CSRs at 0xFF20_0000 and the line buffer at 0xFF20_1000
# (hal-avalon src/map.rs). Its AXI master writes frames through f2h_sdram0,
# whose address 0 is SDRAM address 0: FRAME_BASE is the CPU's physical
# address of the frame (the firmware's map is flat).
#
# The DDR3 settings are a known-good DE1-SoC set (see below); this script
# has not been run through Quartus here (fpga/README.md#quartus-integration).
package require -exact qsys 16.1

create_system soc_system
set_project_property DEVICE_FAMILY {Cyclone V}
set_project_property DEVICE {5CSEMA5F31C6}

# ---- 50 MHz fabric clock (CLOCK_50) -------------------------------------------
add_instance clk_0 clock_source
set_instance_parameter_value clk_0 clockFrequency {50000000.0}
set_instance_parameter_value clk_0 clockFrequencyKnown {1}
set_instance_parameter_value clk_0 resetSynchronousEdges {NONE}

# ---- HPS ----------------------------------------------------------------------
add_instance hps_0 altera_hps
# Bridges: the lightweight HPS-to-FPGA bridge (registers) and one 64-bit
# AXI-3 FPGA-to-SDRAM port, f2h_sdram0 (the frame DMA writes frames into
# HPS SDRAM; docs/frame-dma.md#port). With one AXI port at 64 bits the
# boot loader must write fpgaportrst = 0x311 (Cyclone V HPS TRM, SDRAM
# Controller Subsystem register map, fpgaportrst.portrstn: bits 3:0 read
# data ports 0-3, bits 7:4 write data ports 0-3, bits 13:8 command ports
# 0-5), which releases read port 0 (bit 0), write port 0 (bit 4) and
# command ports 0 and 1 (bits 8 and 9: the AXI port's read and write
# command ports); docs/frame-dma.md#boot-loader.
set_instance_parameter_value hps_0 LWH2F_Enable {true}
set_instance_parameter_value hps_0 S2F_Width {0}
set_instance_parameter_value hps_0 F2S_Width {0}
set_instance_parameter_value hps_0 F2SDRAM_Type {AXI-3}
set_instance_parameter_value hps_0 F2SDRAM_Width {64}
set_instance_parameter_value hps_0 F2SINTERRUPT_Enable {0}
# FPGA-side HPS interfaces nothing here uses, off explicitly so the system
# does not depend on a Quartus version's defaults:
# MPU standby/event signals to the fabric
set_instance_parameter_value hps_0 MPU_EVENTS_Enable {0}
# System Trace Macrocell stimulus port from the fabric
set_instance_parameter_value hps_0 STM_Enable {0}
# FPGA-to-HPS cold reset request
set_instance_parameter_value hps_0 F2SCLK_COLDRST_Enable {0}
# FPGA-to-HPS warm reset request
set_instance_parameter_value hps_0 F2SCLK_WARMRST_Enable {0}
# FPGA-to-HPS debug reset request
set_instance_parameter_value hps_0 F2SCLK_DBGRST_Enable {0}
# boot from FPGA (the HPS boots from the SD card)
set_instance_parameter_value hps_0 BOOTFROMFPGA_Enable {0}
# Peripherals the firmware uses (docs/platform.md#two-targets): EMAC1 RGMII,
# SD card, UART0.
set_instance_parameter_value hps_0 EMAC1_PinMuxing {HPS I/O Set 0}
set_instance_parameter_value hps_0 EMAC1_Mode {RGMII}
set_instance_parameter_value hps_0 SDIO_PinMuxing {HPS I/O Set 0}
set_instance_parameter_value hps_0 SDIO_Mode {4-bit Data}
set_instance_parameter_value hps_0 UART0_PinMuxing {HPS I/O Set 0}
set_instance_parameter_value hps_0 UART0_Mode {No Flow Control}
# DDR3: 2 x MT41K256M16 (x16, 15 row / 10 column / 3 bank bits), 32-bit bus,
# 400 MHz. The whole set is the Intel FPGA University Program's "DE1-SoC
# Computer" (Computer_System.tcl, Quartus 18.1), whose timing (CL 7, CWL 7,
# tRCD/tRP 13.125 ns, tRFC 300 ns) is also what mainline U-Boot's SPL
# programs for this board (board/terasic/de1-soc/qts/sdram_config.h).
set_instance_parameter_value hps_0 HPS_PROTOCOL {DDR3}
set_instance_parameter_value hps_0 MEM_VENDOR {Micron}
set_instance_parameter_value hps_0 MEM_CLK_FREQ {400.0}
set_instance_parameter_value hps_0 MEM_CLK_FREQ_MAX {800.0}
set_instance_parameter_value hps_0 MEM_DQ_WIDTH {32}
set_instance_parameter_value hps_0 MEM_DQ_PER_DQS {8}
set_instance_parameter_value hps_0 MEM_ROW_ADDR_WIDTH {15}
set_instance_parameter_value hps_0 MEM_COL_ADDR_WIDTH {10}
set_instance_parameter_value hps_0 MEM_BANKADDR_WIDTH {3}
set_instance_parameter_value hps_0 MEM_CS_WIDTH {1}
set_instance_parameter_value hps_0 MEM_CK_WIDTH {1}
set_instance_parameter_value hps_0 MEM_IF_DM_PINS_EN {1}
set_instance_parameter_value hps_0 MEM_IF_DQSN_EN {1}
set_instance_parameter_value hps_0 MEM_TCL {7}
set_instance_parameter_value hps_0 MEM_WTCL {7}
set_instance_parameter_value hps_0 MEM_DRV_STR {RZQ/6}
set_instance_parameter_value hps_0 MEM_RTT_NOM {RZQ/6}
set_instance_parameter_value hps_0 MEM_RTT_WR {Dynamic ODT off}
set_instance_parameter_value hps_0 MEM_TINIT_US {500}
set_instance_parameter_value hps_0 MEM_TMRD_CK {4}
set_instance_parameter_value hps_0 MEM_TRAS_NS {36.0}
set_instance_parameter_value hps_0 MEM_TRCD_NS {13.125}
set_instance_parameter_value hps_0 MEM_TRP_NS {13.125}
set_instance_parameter_value hps_0 MEM_TREFI_US {7.8}
set_instance_parameter_value hps_0 MEM_TRFC_NS {300.0}
set_instance_parameter_value hps_0 MEM_TWR_NS {15.0}
set_instance_parameter_value hps_0 MEM_TWTR {4}
set_instance_parameter_value hps_0 MEM_TFAW_NS {45.0}
set_instance_parameter_value hps_0 MEM_TRRD_NS {7.5}
set_instance_parameter_value hps_0 MEM_TRTP_NS {7.5}
# Device timing (the altera_hps names are TIMING_*, not MEM_*).
set_instance_parameter_value hps_0 TIMING_TIS {190}
set_instance_parameter_value hps_0 TIMING_TIH {140}
set_instance_parameter_value hps_0 TIMING_TDS {30}
set_instance_parameter_value hps_0 TIMING_TDH {65}
set_instance_parameter_value hps_0 TIMING_TDQSQ {125}
set_instance_parameter_value hps_0 TIMING_TQH {0.38}
set_instance_parameter_value hps_0 TIMING_TQHS {300}
set_instance_parameter_value hps_0 TIMING_TDQSCK {255}
set_instance_parameter_value hps_0 TIMING_TDQSS {0.25}
set_instance_parameter_value hps_0 TIMING_TDQSH {0.35}
set_instance_parameter_value hps_0 TIMING_TQSH {0.4}
set_instance_parameter_value hps_0 TIMING_TDSH {0.2}
set_instance_parameter_value hps_0 TIMING_TDSS {0.2}
# Board skews and delays of the DE1-SoC layout (same source).
set_instance_parameter_value hps_0 TIMING_BOARD_AC_SKEW {0.02}
set_instance_parameter_value hps_0 TIMING_BOARD_AC_TO_CK_SKEW {0.01}
set_instance_parameter_value hps_0 TIMING_BOARD_MAX_CK_DELAY {0.03}
set_instance_parameter_value hps_0 TIMING_BOARD_MAX_DQS_DELAY {0.02}
set_instance_parameter_value hps_0 TIMING_BOARD_SKEW_CKDQS_DIMM_MIN {0.06}
set_instance_parameter_value hps_0 TIMING_BOARD_SKEW_CKDQS_DIMM_MAX {0.12}
set_instance_parameter_value hps_0 TIMING_BOARD_SKEW_BETWEEN_DQS {0.06}
set_instance_parameter_value hps_0 TIMING_BOARD_SKEW_WITHIN_DQS {0.01}
set_instance_parameter_value hps_0 TIMING_BOARD_DQ_TO_DQS_SKEW {0.05}

# ---- Ray-tracer accelerator (rt_accel_hw.tcl) ---------------------------------
add_instance rt_accel_0 rt_accel
set_instance_parameter_value rt_accel_0 LANES {1}
# The build id the firmware logs and /status shows (BUILD_ID, 0x4C):
# build.sh passes the commit's first 7 hex digits; 0 when built otherwise.
if {[info exists ::env(RT_BUILD_ID)]} {
  set_instance_parameter_value rt_accel_0 BUILD_ID $::env(RT_BUILD_ID)
}

# ---- Connections --------------------------------------------------------------
add_connection clk_0.clk hps_0.h2f_lw_axi_clock
add_connection clk_0.clk rt_accel_0.clock
add_connection clk_0.clk_reset rt_accel_0.reset
add_connection hps_0.h2f_reset rt_accel_0.reset
add_connection hps_0.h2f_lw_axi_master rt_accel_0.s0
set_connection_parameter_value hps_0.h2f_lw_axi_master/rt_accel_0.s0 baseAddress {0x0000}
add_connection clk_0.clk hps_0.f2h_sdram0_clock
add_connection rt_accel_0.axm hps_0.f2h_sdram0_data
set_connection_parameter_value rt_accel_0.axm/hps_0.f2h_sdram0_data baseAddress {0x0000}

# ---- Exports ------------------------------------------------------------------
add_interface clk clock sink
set_interface_property clk EXPORT_OF clk_0.clk_in
add_interface reset reset sink
set_interface_property reset EXPORT_OF clk_0.clk_in_reset
add_interface memory conduit end
set_interface_property memory EXPORT_OF hps_0.memory
add_interface hps_io conduit end
set_interface_property hps_io EXPORT_OF hps_0.hps_io
# The accelerator's board pins. An exported conduit's ports are named
# <export>_<role> in the generated system (the Intel FPGA University
# Program's DE1-SoC Computer exports its VGA conduit as vga: vga_CLK,
# vga_HS, ..., vga_B in Computer_System.cmp), so these give vga_clk ...
# vga_b and board_key_n ... board_hex5_n (de1_soc_top.sv).
add_interface vga conduit end
set_interface_property vga EXPORT_OF rt_accel_0.vga
add_interface board conduit end
set_interface_property board EXPORT_OF rt_accel_0.board

save_system soc_system.qsys
