# Platform Designer component: the ray-tracer accelerator (rt_accel.sv:
# rt_top with the whole AXI3 master signal set, and the VGA and board I/O
# conduits).
#
# One 32-bit Avalon-MM slave, word addressing over an 8 KiB span:
#   0x0000 CSR block (CONTROL, STATUS, ROW_Y, LIGHT_X/Y/Z, ID, FRAME_*)
#   0x1000 line buffer, 480 words 0x00RRGGBB
# one AXI3 master (64-bit data, bursts of at most 16 beats) that the frame
# DMA writes through (at most 16 writes outstanding) and the VGA reader
# reads through (at most 4 read bursts outstanding): connect it to
# hps_0.f2h_sdram0_data (F2SDRAM_Type AXI-3, F2SDRAM_Width 64); and two
# conduits for the board's pins, vga and board (export both).
# Connect the slave to hps_0.h2f_lw_axi_master at base 0x0000_0000: the CPU then
# sees it at 0xFF20_0000 (hal-avalon's CSR_OFFSET / LINE_BUFFER_OFFSET).
# Fixed read latency 1, no waitrequest, no byte enables (32-bit accesses
# only, as the driver makes).
package require -exact qsys 16.1

set_module_property NAME rt_accel
set_module_property DISPLAY_NAME "Ray tracer accelerator"
set_module_property VERSION 1.0
set_module_property GROUP "Ray tracer"
set_module_property DESCRIPTION "Fixed-point ray tracer: a 480-pixel row per start, or whole frames written to SDRAM (register map: hal-avalon)"
set_module_property EDITABLE false
set_module_property INTERNAL false
set_module_property OPAQUE_ADDRESS_MAP true
set_module_property ELABORATION_CALLBACK ""

# ---- Files (paths relative to this file) ----------------------------------
add_fileset QUARTUS_SYNTH QUARTUS_SYNTH "" ""
set_fileset_property QUARTUS_SYNTH TOP_LEVEL rt_accel
set rtl_dir [file join [file dirname [info script]] .. rtl]
set fh [open [file join $rtl_dir files.f] r]
foreach f [split [read $fh] "\n"] {
    set f [string trim $f]
    if {$f eq "" || [string index $f 0] eq "#"} { continue }
    add_fileset_file $f SYSTEM_VERILOG PATH [file join ../rtl $f]
}
close $fh
add_fileset_file rt_accel.sv SYSTEM_VERILOG PATH rt_accel.sv TOP_LEVEL_FILE

# ---- Parameters -------------------------------------------------------------
add_parameter LANES INTEGER 1
set_parameter_property LANES DISPLAY_NAME "Lanes (power of two dividing 480)"
set_parameter_property LANES ALLOWED_RANGES {1 2 4}
set_parameter_property LANES HDL_PARAMETER true
add_parameter SQRT_BPS INTEGER 2
set_parameter_property SQRT_BPS DISPLAY_NAME "Square-root bits per pipeline stage"
set_parameter_property SQRT_BPS ALLOWED_RANGES {1 2 3 4}
set_parameter_property SQRT_BPS HDL_PARAMETER true
add_parameter DIV_BPS INTEGER 2
set_parameter_property DIV_BPS DISPLAY_NAME "Divider bits per pipeline stage"
set_parameter_property DIV_BPS ALLOWED_RANGES {1 2 3 4}
set_parameter_property DIV_BPS HDL_PARAMETER true
add_parameter BUILD_ID INTEGER 0
set_parameter_property BUILD_ID DISPLAY_NAME "Build id (BUILD_ID register; 0: none)"
set_parameter_property BUILD_ID ALLOWED_RANGES 0:268435455
set_parameter_property BUILD_ID HDL_PARAMETER true

# ---- Clock and reset ----------------------------------------------------------
add_interface clock clock end
set_interface_property clock clockRate 0
add_interface_port clock clk_i clk Input 1

add_interface reset reset end
set_interface_property reset associatedClock clock
set_interface_property reset synchronousEdges DEASSERT
add_interface_port reset rst_ni reset_n Input 1

# ---- Avalon-MM slave ----------------------------------------------------------
add_interface s0 avalon end
set_interface_property s0 addressUnits WORDS
set_interface_property s0 associatedClock clock
set_interface_property s0 associatedReset reset
set_interface_property s0 bitsPerSymbol 8
set_interface_property s0 maximumPendingReadTransactions 0
set_interface_property s0 readLatency 1
set_interface_property s0 readWaitTime 0
set_interface_property s0 writeWaitTime 0
set_interface_property s0 timingUnits Cycles
set_interface_property s0 ENABLED true
add_interface_port s0 avs_address_i address Input 11
add_interface_port s0 avs_read_i read Input 1
add_interface_port s0 avs_write_i write Input 1
add_interface_port s0 avs_writedata_i writedata Input 32
add_interface_port s0 avs_readdata_o readdata Output 32
set_interface_assignment s0 embeddedsw.configuration.isFlash 0
set_interface_assignment s0 embeddedsw.configuration.isMemoryDevice 0

# ---- AXI3 master: the frame DMA (writes) and the VGA reader (reads) -------
# Every AXI3 signal is declared, as Altera's own AXI3 master templates do
# (merlin axi_interface.tcl); rt_accel.sv ties off the IDs and the locks.
# The reader has at most 4 read bursts in flight, the DMA at most 16
# writes: 20 in all.
add_interface axm axi start
set_interface_property axm associatedClock clock
set_interface_property axm associatedReset reset
set_interface_property axm readIssuingCapability 4
set_interface_property axm writeIssuingCapability 16
set_interface_property axm combinedIssuingCapability 20
set_interface_property axm ENABLED true
foreach {port role dir width} {
    axm_awid_o awid Output 1     axm_awaddr_o awaddr Output 32   axm_awlen_o awlen Output 4
    axm_awsize_o awsize Output 3 axm_awburst_o awburst Output 2  axm_awlock_o awlock Output 2
    axm_awcache_o awcache Output 4 axm_awprot_o awprot Output 3  axm_awvalid_o awvalid Output 1
    axm_awready_i awready Input 1
    axm_wid_o wid Output 1       axm_wdata_o wdata Output 64     axm_wstrb_o wstrb Output 8
    axm_wlast_o wlast Output 1   axm_wvalid_o wvalid Output 1    axm_wready_i wready Input 1
    axm_bid_i bid Input 1        axm_bresp_i bresp Input 2       axm_bvalid_i bvalid Input 1
    axm_bready_o bready Output 1
    axm_arid_o arid Output 1     axm_araddr_o araddr Output 32   axm_arlen_o arlen Output 4
    axm_arsize_o arsize Output 3 axm_arburst_o arburst Output 2  axm_arlock_o arlock Output 2
    axm_arcache_o arcache Output 4 axm_arprot_o arprot Output 3  axm_arvalid_o arvalid Output 1
    axm_arready_i arready Input 1
    axm_rid_i rid Input 1        axm_rdata_i rdata Input 64      axm_rresp_i rresp Input 2
    axm_rlast_i rlast Input 1    axm_rvalid_i rvalid Input 1     axm_rready_o rready Output 1
} {
    add_interface_port axm $port $role $dir $width
}

# ---- Conduits to the board's pins (exported as vga and board) ---------------
# Platform Designer names an exported conduit's ports <export>_<role>:
# vga_clk ... vga_b, board_key_n ... board_hex5_n (de1_soc_top.sv). The
# outputs are registers on the clock above (50 MHz): VGA_CLK is a 25 MHz
# toggle, R/G/B/BLANK_N/SYNC_N change at the edge where it falls
# (de1_soc.sdc); KEY and SW are synchronised inside.
add_interface vga conduit end
set_interface_property vga associatedClock clock
set_interface_property vga associatedReset reset
set_interface_property vga ENABLED true
add_interface_port vga vga_clk_o clk Output 1
add_interface_port vga vga_hs_o hs Output 1
add_interface_port vga vga_vs_o vs Output 1
add_interface_port vga vga_blank_n_o blank_n Output 1
add_interface_port vga vga_sync_n_o sync_n Output 1
add_interface_port vga vga_r_o r Output 8
add_interface_port vga vga_g_o g Output 8
add_interface_port vga vga_b_o b Output 8

add_interface board conduit end
set_interface_property board associatedClock clock
set_interface_property board associatedReset reset
set_interface_property board ENABLED true
add_interface_port board key_n_i key_n Input 4
add_interface_port board sw_i sw Input 10
add_interface_port board ledr_o ledr Output 10
add_interface_port board hex0_n_o hex0_n Output 7
add_interface_port board hex1_n_o hex1_n Output 7
add_interface_port board hex2_n_o hex2_n Output 7
add_interface_port board hex3_n_o hex3_n Output 7
add_interface_port board hex4_n_o hex4_n Output 7
add_interface_port board hex5_n_o hex5_n Output 7
