# 50 MHz fabric clock (CLOCK_50); the accelerator runs on it.
create_clock -name CLOCK_50 -period 20.000 [get_ports CLOCK_50]
derive_pll_clocks
derive_clock_uncertainty
# LEDR[0] shows a reset state to the eye: no timing relation.
set_false_path -to [get_ports {LEDR[*]}]
