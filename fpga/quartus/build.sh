#!/bin/sh
# Build the DE1-SoC FPGA image: Platform Designer system, Quartus compile,
# and the .rbf the firmware's boot steps load (U-Boot `fpga load`, see
# docs/board-bring-up.md).
#
# Needs Quartus Prime (Lite is enough for the 5CSEMA5) with Cyclone V
# support and Platform Designer on PATH: quartus_sh, qsys-script,
# qsys-generate, quartus_cpf. Written for 18.1; not run on this project's
# CI machine (no Quartus there).
#
# Usage: fpga/quartus/build.sh [--compressed]
#   --compressed: compressed .rbf (MSEL set for compressed FPP on the board)
set -eu
cd "$(dirname "$0")"
COMPRESS=off
[ "${1:-}" = "--compressed" ] && COMPRESS=on

# The bitstream's build id (BUILD_ID register): the commit's first 7 hex
# digits, 0 outside a git checkout.
RT_BUILD_ID=$(printf '%d' "0x$( (git rev-parse HEAD 2>/dev/null || echo 0) | cut -c1-7)")
export RT_BUILD_ID
echo "build id $(printf '%07x' "$RT_BUILD_ID")"

# 1. Platform Designer: system from the script, then HDL generation. The
#    search path lets it find rt_accel_hw.tcl in this directory.
qsys-script --script=soc_system.tcl --search-path="$PWD,\$"
qsys-generate soc_system.qsys --synthesis=VERILOG --search-path="$PWD,\$" \
  --output-directory=soc_system

# 2. Analysis and synthesis, then the HPS DDR3 pin assignments (the script
#    needs the synthesised netlist to find the memory pins).
quartus_map de1_soc
# quartus_sta runs the pin script directly (under quartus_sh it relaunches
# itself and its exit status is lost).
quartus_sta -t soc_system/synthesis/submodules/hps_sdram_p0_pin_assignments.tcl de1_soc

# 3. The full compile flow with those assignments in the .qsf: synthesis
#    again, fit, assembler, timing analysis; as Intel's GHRD Makefile does
#    after its pin-assignment step (`quartus_sh --flow compile`).
quartus_sh --flow compile de1_soc

# 4. Raw binary for U-Boot's `fpga load` (and for the FPGA manager).
quartus_cpf -c -o bitstream_compression=$COMPRESS \
  output_files/de1_soc.sof output_files/soc_system.rbf
echo "wrote $(pwd)/output_files/soc_system.rbf"
echo "preloader handoff files: $(pwd)/hps_isw_handoff/ (bsp-editor input)"
