# Platform Designer component: the ray-tracer accelerator (rt_top).
#
# One 32-bit Avalon-MM slave, word addressing over an 8 KiB span:
#   0x0000 CSR block (CONTROL, STATUS, ROW_Y, LIGHT_X/Y/Z, ID)
#   0x1000 line buffer, 480 words 0x00RRGGBB
# Connect it to hps_0.h2f_lw_axi_master at base 0x0000_0000: the CPU then
# sees it at 0xFF20_0000 (hal-avalon's CSR_OFFSET / LINE_BUFFER_OFFSET).
# Fixed read latency 1, no waitrequest, no byte enables (32-bit accesses
# only, as the driver makes).
package require -exact qsys 16.1

set_module_property NAME rt_accel
set_module_property DISPLAY_NAME "Ray tracer accelerator"
set_module_property VERSION 1.0
set_module_property GROUP "Ray tracer"
set_module_property DESCRIPTION "Fixed-point ray tracer, one 480-pixel row per start (register map: hal-avalon)"
set_module_property EDITABLE false
set_module_property INTERNAL false
set_module_property OPAQUE_ADDRESS_MAP true
set_module_property ELABORATION_CALLBACK ""

# ---- Files (paths relative to this file) ----------------------------------
add_fileset QUARTUS_SYNTH QUARTUS_SYNTH "" ""
set_fileset_property QUARTUS_SYNTH TOP_LEVEL rt_top
set rtl_dir [file join [file dirname [info script]] .. rtl]
set fh [open [file join $rtl_dir files.f] r]
foreach f [split [read $fh] "\n"] {
    set f [string trim $f]
    if {$f eq "" || [string index $f 0] eq "#"} { continue }
    add_fileset_file $f SYSTEM_VERILOG PATH [file join ../rtl $f] [expr {$f eq "rt_top.sv"}]
}
close $fh

# ---- Parameters -------------------------------------------------------------
add_parameter LANES INTEGER 2
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
