# 50 MHz fabric clock (CLOCK_50); the accelerator runs on it.
create_clock -name CLOCK_50 -period 20.000 [get_ports CLOCK_50]

# ---- VGA ---------------------------------------------------------------------
# VGA_CLK is a register output: rt_vga's phase_q toggles on every CLOCK_50
# edge, 25 MHz at the pin. Two generated clocks: the pixel clock on that
# register (CLOCK_50 divided by 2), then VGA_CLK on the port from the
# register. The Timing Analyzer does not carry a clock through a register's
# data path by itself; with the register declared as a clock source it
# traces CLOCK_50 -> phase_q -> pin, so the DAC's latch edge includes the
# register's clock-to-output and the pin's delay (Intel Quartus Prime Timing
# Analyzer user guide, "Generated Clocks": clock dividers and clock outputs
# as generated clocks).
create_generated_clock -name vga_pixel -source [get_ports CLOCK_50] -divide_by 2 [get_registers {*u_vga|phase_q}]
create_generated_clock -name VGA_CLK -source [get_registers {*u_vga|phase_q}] [get_ports VGA_CLK]

derive_pll_clocks
derive_clock_uncertainty

# The ADV7123 DAC latches R, G, B and BLANK_N at the rising edge of VGA_CLK.
# max: board delay (data) - board delay (clock) + tsu of the DAC
# min: board delay (data) - board delay (clock) - th of the DAC
# Figures from Terasic's System Builder DE1_SOC.sdc ("created by Terasic
# Tool"; public copy: theapi/de1-soc vga/DE1_SOC.sdc) and, identical, the
# Intel FPGA University Program's DE1_SoC_Computer.sdc (public copy:
# platatat/fractal). Both put them against a clock on the VGA_CLK port, as
# here. SYNC_N, the DAC's other control input, has no figures in either
# file: it takes BLANK_N's.
set_output_delay -clock VGA_CLK -max 0.220 [get_ports {VGA_R[*]}]
set_output_delay -clock VGA_CLK -min -1.506 [get_ports {VGA_R[*]}]
set_output_delay -clock VGA_CLK -max 0.212 [get_ports {VGA_G[*]}]
set_output_delay -clock VGA_CLK -min -1.519 [get_ports {VGA_G[*]}]
set_output_delay -clock VGA_CLK -max 0.264 [get_ports {VGA_B[*]}]
set_output_delay -clock VGA_CLK -min -1.519 [get_ports {VGA_B[*]}]
set_output_delay -clock VGA_CLK -max 0.215 [get_ports {VGA_BLANK_N}]
set_output_delay -clock VGA_CLK -min -1.485 [get_ports {VGA_BLANK_N}]
set_output_delay -clock VGA_CLK -max 0.215 [get_ports {VGA_SYNC_N}]
set_output_delay -clock VGA_CLK -min -1.485 [get_ports {VGA_SYNC_N}]
# The RTL changes R, G, B, BLANK_N and SYNC_N only at the CLOCK_50 edge
# where VGA_CLK falls, so the DAC latches them 20 ns later (the default
# setup relationship) and the next change comes 20 ns after its edge. By
# default the analyzer would also assume a change at the edge where
# VGA_CLK rises (a 0 ns hold relationship); moving the hold launch edge one
# CLOCK_50 period later states the real one, 20 ns. (Intel Quartus Prime
# Timing Analyzer user guide, multicycle exceptions: a hold multicycle with
# -end moves the latch edge, in latch-clock periods, as its example "End
# Multicycle Setup = 2 and End Multicycle Hold = 1" shows; -start moves
# the launch edge, in launch-clock periods.)
set_multicycle_path -hold -start 1 -from [get_clocks CLOCK_50] -to [get_clocks VGA_CLK]
# HS and VS go from the FPGA to the connector, not through the DAC (as
# Terasic's DE-series manuals describe their ADV7123 VGA circuits, e.g. the
# DE2's: "The VGA synchronization signals are provided directly from the
# ... FPGA"), and a monitor locks to them with a PLL: a few ns against a
# 40 ns pixel moves nothing on screen. No timing relation to check.
set_false_path -to [get_ports {VGA_HS VGA_VS}]

# ---- Board I/O -----------------------------------------------------------------
# KEY and SW are asynchronous to every clock: the accelerator synchronises
# them and debounces the keys (hal-avalon src/map.rs, "Board I/O").
set_false_path -from [get_ports {KEY[*] SW[*]}]
# LEDR and HEX0-5 hold what software wrote, for the eye: no timing relation.
set_false_path -to [get_ports {LEDR[*] HEX0[*] HEX1[*] HEX2[*] HEX3[*] HEX4[*] HEX5[*]}]
