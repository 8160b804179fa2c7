# Raytracer boot script for the DE1-SoC (compiled into boot.scr by
# `cargo xtask sdcard`; U-Boot's distro boot runs it from the card's FAT
# partition and sets devtype, devnum and distro_bootpart).
echo raytracer: boot script on ${devtype} ${devnum}:${distro_bootpart}
if test -e ${devtype} ${devnum}:${distro_bootpart} raytracer.rbf; then
	echo raytracer: configuring the FPGA from raytracer.rbf
	load ${devtype} ${devnum}:${distro_bootpart} ${kernel_addr_r} raytracer.rbf
	fpga load 0 ${kernel_addr_r} ${filesize}
	# fpga load left the FPGA-to-SDRAM ports in reset. The patched
	# `bridge enable` applies the port configuration the FPGA image carries
	# (staticcfg.applycfg, from one I-cache line) while they are, then
	# releases the ports (fpgaportrst 0x311, from the patched handoff) and
	# the bridges.
	bridge enable
else
	echo raytracer: no raytracer.rbf: the firmware renders in software
fi
load ${devtype} ${devnum}:${distro_bootpart} 0x00100040 firmware.bin
# The firmware's entry cleans and turns off the caches itself; hand over
# with them clean and off anyway. `go` only branches: the I-cache may still
# hold lines of what was at the load address before (an earlier firmware
# after a reload), so invalidate it once the new image is in memory.
dcache flush
dcache off
icache flush
echo raytracer: starting the firmware at 0x00100040
go 0x00100040
