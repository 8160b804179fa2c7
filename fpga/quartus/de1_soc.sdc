# 50 MHz fabric clock (CLOCK_50); the accelerator runs on it.
create_clock -name CLOCK_50 -period 20.000 [get_ports CLOCK_50]
derive_pll_clocks
derive_clock_uncertainty
