//! The Cyclone V EMAC's receive frame filter, applied by the relay in
//! front of the emulated board: QEMU's npcm-gmac passes every frame to the
//! guest (hw/net/npcm_gmac.c, `gmac_receive`: "TODO -- Implement all frame
//! filtering"), so a driver that programs the filter wrong works in QEMU
//! and goes deaf on the board. The relay follows what the firmware writes
//! to the MAC (QEMU's `npcm_gmac_reg_write` trace event, in a file) and
//! drops what the silicon would drop.
//!
//! The rules, from the Synopsys DesignWare GMAC 3.70a as the Cyclone V HPS
//! has it (Cyclone V HPS Technical Reference Manual, EMAC register map:
//! `MAC_Frame_Filter` at 0x004, `Hash_Table_Reg0..7` at 0x500..0x51C,
//! `MAC_Address0..127`; Linux's `dwmac1000.h` and
//! `dwmac1000_core.c::dwmac1000_set_filter` program the same; the board's
//! device tree, Linux `socfpga.dtsi`, says 256 hash bins and 128 perfect
//! filter entries):
//!
//! - PR (bit 0) passes everything; so does RA (bit 31, filter result only
//!   reported).
//! - A broadcast passes unless DBF (bit 5).
//! - A multicast destination passes with PM (bit 4); otherwise with HMC
//!   (bit 2) it must hit the hash table (or, with HPF, bit 10, the perfect
//!   filter too); without HMC only the perfect filter.
//! - A unicast destination likewise with HUC (bit 1) and the hash.
//! - The perfect filter: Address0 (always on), Address1..127 where AE (bit
//!   31 of the high word) is set. DAIF (bit 3) inverts the result.
//! - The hash: the bin is the top 8 bits of the bit-reversed CRC-32 of the
//!   destination; `Hash_Table_Reg(bin >> 5)`, bit `bin & 31`.
//!
//! Not modelled (the firmware sets none of them): per-byte masks of the
//! address registers, source address filtering, VLAN and L3/L4 filters.

use std::io::{Read, Seek, SeekFrom};
use std::path::PathBuf;

/// `MAC_Frame_Filter` bits (Cyclone V HPS TRM, EMAC `MAC_Frame_Filter`).
const PR: u32 = 1 << 0;
const HUC: u32 = 1 << 1;
const HMC: u32 = 1 << 2;
const DAIF: u32 = 1 << 3;
const PM: u32 = 1 << 4;
const DBF: u32 = 1 << 5;
const HPF: u32 = 1 << 10;
const RA: u32 = 1 << 31;

/// Register offsets (Cyclone V HPS TRM, EMAC register map).
const FRAME_FILTER: u64 = 0x004;
const HASH_TABLE: u64 = 0x500;
/// Address0..15 at 0x40 + 8n, Address16..127 at 0x800 + 8(n - 16).
const ADDRESSES_LOW: u64 = 0x040;
const ADDRESSES_HIGH: u64 = 0x800;
const ADDRESS_COUNT: usize = 128;
/// AE in an address's high word.
const ADDRESS_ENABLE: u32 = 1 << 31;

/// The filter's registers as the firmware last wrote them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MacFilter {
    frame_filter: u32,
    hash: [u32; 8],
    /// (high, low) words of each address register.
    addresses: Vec<(u32, u32)>,
}

impl Default for MacFilter {
    /// The reset values: filter 0, hash 0, Address0 all ones (the TRM's
    /// reset value 0x0000FFFF / 0xFFFFFFFF), the others off.
    fn default() -> MacFilter {
        let mut addresses = vec![(0x0000_ffff, 0xffff_ffff); ADDRESS_COUNT];
        addresses[1..].fill((0, 0));
        MacFilter { frame_filter: 0, hash: [0; 8], addresses }
    }
}

/// The hash bin of destination `mac` (256 bins).
pub fn hash_bin(mac: [u8; 6]) -> u8 {
    // bitrev32(crc32) >> 24 is the low byte of the CRC, bit-reversed.
    (crc32fast::hash(&mac) as u8).reverse_bits()
}

impl MacFilter {
    /// The firmware wrote `value` at `offset`.
    pub fn write(&mut self, offset: u64, value: u32) {
        // (register number, high word?): high at +0, low at +4.
        let (n, high) = match offset {
            FRAME_FILTER => {
                self.frame_filter = value;
                return;
            }
            o if (HASH_TABLE..HASH_TABLE + 32).contains(&o) && o.is_multiple_of(4) => {
                self.hash[((o - HASH_TABLE) / 4) as usize] = value;
                return;
            }
            o if (ADDRESSES_LOW..ADDRESSES_LOW + 16 * 8).contains(&o) && o.is_multiple_of(4) => {
                let k = (o - ADDRESSES_LOW) / 4;
                (k as usize / 2, k.is_multiple_of(2))
            }
            o if (ADDRESSES_HIGH..ADDRESSES_HIGH + 112 * 8).contains(&o) && o.is_multiple_of(4) => {
                let k = (o - ADDRESSES_HIGH) / 4;
                (16 + k as usize / 2, k.is_multiple_of(2))
            }
            _ => return,
        };
        if high {
            self.addresses[n].0 = value;
        } else {
            self.addresses[n].1 = value;
        }
    }

    /// Whether address register `n` holds `mac` and is on.
    fn address_matches(&self, n: usize, mac: [u8; 6]) -> bool {
        let (high, low) = self.addresses[n];
        let on = n == 0 || high & ADDRESS_ENABLE != 0;
        let held = [low as u8, (low >> 8) as u8, (low >> 16) as u8, (low >> 24) as u8, high as u8, (high >> 8) as u8];
        on && held == mac
    }

    fn perfect(&self, mac: [u8; 6]) -> bool {
        (0..ADDRESS_COUNT).any(|n| self.address_matches(n, mac))
    }

    fn hashed(&self, mac: [u8; 6]) -> bool {
        let bin = hash_bin(mac);
        self.hash[usize::from(bin >> 5)] & (1 << (bin & 31)) != 0
    }

    /// Whether a frame to `destination` reaches the DMA.
    pub fn passes(&self, destination: [u8; 6]) -> bool {
        let f = self.frame_filter;
        if f & (PR | RA) != 0 {
            return true;
        }
        if destination == [0xff; 6] {
            return f & DBF == 0;
        }
        let multicast = destination[0] & 1 != 0;
        if multicast && f & PM != 0 {
            return true;
        }
        let by_hash = if multicast { f & HMC != 0 } else { f & HUC != 0 };
        let perfect = || {
            let hit = self.perfect(destination);
            if f & DAIF != 0 {
                !hit
            } else {
                hit
            }
        };
        if by_hash {
            self.hashed(destination) || (f & HPF != 0 && perfect())
        } else {
            perfect()
        }
    }
}

/// A [`MacFilter`] kept up to date from QEMU's trace file: the QEMU
/// argument `-trace npcm_gmac_reg_write,file=PATH` writes one line per
/// register write, `npcm_gmac_reg_write /machine/soc/gmac[0]: offset:
/// 0x0004 value: 0x0404` (QEMU hw/net/trace-events).
pub struct FilterFollower {
    path: PathBuf,
    read: u64,
    partial: String,
    /// The filter as of the last line read.
    pub filter: MacFilter,
}

impl FilterFollower {
    /// Follow `path` (it may not exist yet: the MAC is then as reset).
    pub fn new(path: PathBuf) -> FilterFollower {
        FilterFollower { path, read: 0, partial: String::new(), filter: MacFilter::default() }
    }

    /// The QEMU arguments that write the trace this follows.
    pub fn qemu_args(&self) -> [String; 2] {
        ["-trace".into(), format!("npcm_gmac_reg_write,file={}", self.path.display())]
    }

    /// Read what QEMU wrote since the last call.
    pub fn catch_up(&mut self) {
        let Ok(mut file) = std::fs::File::open(&self.path) else { return };
        if file.seek(SeekFrom::Start(self.read)).is_err() {
            return;
        }
        let mut text = String::new();
        let Ok(n) = file.read_to_string(&mut text) else { return };
        self.read += n as u64;
        self.partial.push_str(&text);
        while let Some(end) = self.partial.find('\n') {
            let line: String = self.partial.drain(..=end).collect();
            if let Some((offset, value)) = parse_write(&line) {
                self.filter.write(offset, value);
            }
        }
    }
}

impl Drop for FilterFollower {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// `(offset, value)` of a `npcm_gmac_reg_write` line of the first GMAC.
fn parse_write(line: &str) -> Option<(u64, u32)> {
    let rest = line.split("npcm_gmac_reg_write ").nth(1)?;
    if !rest.contains("gmac[0]") {
        return None;
    }
    let hex = |key: &str| {
        let after = rest.split(key).nth(1)?.trim_start();
        let digits = after.strip_prefix("0x")?.split(|c: char| !c.is_ascii_hexdigit()).next()?;
        u64::from_str_radix(digits, 16).ok()
    };
    Some((hex("offset:")?, u32::try_from(hex("value:")?).ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    const OWN: [u8; 6] = [0x52, 0x54, 0x00, 0x12, 0x34, 0x56];
    const MDNS: [u8; 6] = [0x01, 0x00, 0x5e, 0x00, 0x00, 0xfb];
    const ALL_HOSTS: [u8; 6] = [0x01, 0x00, 0x5e, 0x00, 0x00, 0x01];

    fn programmed(filter: u32) -> MacFilter {
        let mut f = MacFilter::default();
        f.write(0x40, 0x5634);
        f.write(0x44, 0x1200_5452);
        f.write(FRAME_FILTER, filter);
        f
    }

    /// The bins of the groups the board joins, as Linux's
    /// `bitrev32(~crc32_le(~0, addr, 6)) >> 24` gives them (computed
    /// independently with Python's zlib.crc32).
    #[test]
    fn the_hash_bins_are_linux_s() {
        assert_eq!(hash_bin(MDNS), 192);
        assert_eq!(hash_bin(ALL_HOSTS), 128);
    }

    /// Filter 0 (what the firmware wrote before this model existed): own
    /// unicast and broadcast pass, every multicast frame is dropped.
    #[test]
    fn filter_zero_drops_every_multicast_frame() {
        let f = programmed(0);
        assert!(f.passes(OWN));
        assert!(f.passes([0xff; 6]));
        assert!(!f.passes(MDNS));
        assert!(!f.passes(ALL_HOSTS));
        assert!(!f.passes([0x02, 0, 0, 0, 0, 1]), "another host's unicast");
    }

    #[test]
    fn the_hash_passes_the_groups_whose_bins_are_set_and_pm_passes_all() {
        let mut f = programmed(HMC | HPF);
        f.write(HASH_TABLE + 4 * 6, 1);
        assert!(f.passes(MDNS));
        assert!(!f.passes(ALL_HOSTS));
        assert!(f.passes(OWN), "HPF: the perfect filter still passes own unicast");
        let f = programmed(PM);
        assert!(f.passes(MDNS) && f.passes(ALL_HOSTS));
        assert!(!f.passes([0x02, 0, 0, 0, 0, 1]));
        assert!(!programmed(DBF).passes([0xff; 6]));
        assert!(programmed(PR).passes([0x02, 0, 0, 0, 0, 1]));
    }

    #[test]
    fn a_reset_mac_takes_broadcast_only_and_an_enabled_address_register_counts() {
        let f = MacFilter::default();
        assert!(!f.passes(OWN));
        assert!(f.passes([0xff; 6]));
        let mut f = programmed(0);
        // Address1 = 01:00:5e:00:00:fb, enabled.
        f.write(0x48, ADDRESS_ENABLE | 0xfb00);
        f.write(0x4c, 0x005e_0001);
        assert!(f.passes(MDNS));
        f.write(0x48, 0xfb00);
        assert!(!f.passes(MDNS), "AE clear");
    }

    #[test]
    fn trace_lines_are_followed_as_written() {
        let dir = std::env::temp_dir().join(format!("rt-mac-filter-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("gmac.trace");
        let mut follower = FilterFollower::new(path.clone());
        follower.catch_up();
        assert_eq!(follower.filter, MacFilter::default(), "no file yet: as reset");
        std::fs::write(
            &path,
            "npcm_gmac_reg_write /machine/soc/gmac[0]: offset: 0x0040 value: 0x5634\n\
             npcm_gmac_reg_write /machine/soc/gmac[0]: offset: 0x0044 value: 0x12005452\n\
             npcm_gmac_reg_write /machine/soc/gmac[1]: offset: 0x0004 value: 0x0001\n\
             npcm_gmac_reg_write /machine/soc/gmac[0]: offset: 0x0518 val",
        )
        .unwrap();
        follower.catch_up();
        assert!(follower.filter.passes(OWN));
        assert!(!follower.filter.passes(MDNS), "the second GMAC's write is not this one's");
        use std::io::Write;
        let mut file = std::fs::OpenOptions::new().append(true).open(&path).unwrap();
        writeln!(file, "ue: 0x0001").unwrap();
        writeln!(file, "npcm_gmac_reg_write /machine/soc/gmac[0]: offset: 0x0004 value: 0x0404").unwrap();
        follower.catch_up();
        assert!(follower.filter.passes(MDNS), "a line split across two reads");
        drop(follower);
        assert!(!path.exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
