# Raytracer boot script for the DE1-SoC (compiled into boot.scr by
# `cargo xtask sdcard`; U-Boot's distro boot runs it from the card's FAT
# partition and sets devtype, devnum and distro_bootpart).
echo raytracer: boot script on ${devtype} ${devnum}:${distro_bootpart}
if test -e ${devtype} ${devnum}:${distro_bootpart} raytracer.rbf; then
	echo raytracer: configuring the FPGA from raytracer.rbf
	load ${devtype} ${devnum}:${distro_bootpart} ${kernel_addr_r} raytracer.rbf
	fpga load 0 ${kernel_addr_r} ${filesize}
	# fpga load left the FPGA-to-SDRAM ports in reset: apply the port
	# configuration the FPGA image carries (staticcfg.applycfg, with
	# membl = 2) while they are, then `bridge enable` releases the bridges
	# and the ports (fpgaportrst 0x311, from the patched handoff).
	mw 0xffc2505c 0xa
	bridge enable
else
	echo raytracer: no raytracer.rbf: the firmware renders in software
fi
load ${devtype} ${devnum}:${distro_bootpart} 0x00100040 firmware.bin
# The firmware's entry cleans and turns off the caches itself; hand over
# with them clean and off anyway.
dcache flush
dcache off
echo raytracer: starting the firmware at 0x00100040
go 0x00100040
