# Raytracer boot script for the DE1-SoC (compiled into boot.scr by
# `cargo xtask sdcard`; U-Boot's distro boot runs it from the card's FAT
# partition and sets devtype, devnum and distro_bootpart).
echo raytracer: boot script on ${devtype} ${devnum}:${distro_bootpart}
if test -e ${devtype} ${devnum}:${distro_bootpart} raytracer.rbf; then
	echo raytracer: configuring the FPGA from raytracer.rbf
	load ${devtype} ${devnum}:${distro_bootpart} ${kernel_addr_r} raytracer.rbf
	if fpga load 0 ${kernel_addr_r} ${filesize}; then
		# fpga load left the FPGA-to-SDRAM ports in reset. The patched
		# `bridge enable` applies the port configuration the FPGA image
		# carries (staticcfg.applycfg, from one I-cache line) while they
		# are, then releases the ports (fpgaportrst 0x311, from the patched
		# handoff) and the bridges.
		bridge enable
	else
		echo raytracer: fpga load FAILED: the FPGA is not configured.
		echo raytracer: check the MSEL switches, SW10: 00000 (all ON) for an
		echo raytracer: uncompressed raytracer.rbf, 01010 for a compressed one; and that the
		echo raytracer: .rbf was built for the DE1-SoC's 5CSEMA5F31C6 (docs/quick-start.md).
		echo raytracer: booting without the FPGA: the firmware renders in software.
	fi
else
	echo raytracer: no raytracer.rbf: the firmware renders in software
fi
# The board's settings (docs/networking.md): raytracer.txt, handed to the
# firmware at 0x04900000 (firmware/memory.x, HANDOFF): "RTCF", the file's
# length, the text, at most 0xff8 bytes of it (the 4 KiB area less the
# header: a longer file must not overwrite what follows; the firmware reads
# what fits and says the file is too long). The header is cleared first
# and its word written last, so that no earlier boot's copy is taken for
# this one's.
mw.l 0x04900000 0
if test -e ${devtype} ${devnum}:${distro_bootpart} raytracer.txt; then
	size ${devtype} ${devnum}:${distro_bootpart} raytracer.txt
	mw.l 0x04900004 ${filesize}
	load ${devtype} ${devnum}:${distro_bootpart} 0x04900008 raytracer.txt 0xff8
	mw.l 0x04900000 0x46435452
	echo raytracer: settings from raytracer.txt (${filesize} bytes, hex)
else
	echo raytracer: no raytracer.txt: DHCP, then link-local; name raytracer
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
