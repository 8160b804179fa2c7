//! The board's status as `/status` answers it (JSON), and as the page
//! shows it beside the picture.

use core::fmt::{self, Write};

/// Viewers on each of the board's services.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct Viewers {
    /// WebSocket viewers of the page.
    pub web: usize,
    /// The most at once ([`WEB_VIEWERS`](super::WEB_VIEWERS) on the board).
    pub web_max: usize,
    /// Seed-protocol clients (both ports).
    pub seed: usize,
    /// RTSP sessions.
    pub rtsp: usize,
}

/// A snapshot of the board.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct BoardStatus<'a> {
    /// Seconds since boot.
    pub uptime_s: u64,
    /// Who renders: `"fpga"` (after its self-test), `"software"`, or
    /// `"simulated"` (hps-sim).
    pub renderer: &'a str,
    /// The Ethernet link (`"1000 Mbit/s full duplex"`, `"down"`).
    pub link: &'a str,
    /// Frames the renderer completed.
    pub frames_rendered: u64,
    /// Frames sent whole to viewers of every service.
    pub frames_sent: u64,
    /// Viewers now.
    pub viewers: Viewers,
    /// The RTSP port, for the page's stream URL.
    pub rtsp_port: u16,
    /// Who the board is on the network.
    pub identity: Identity<'a>,
    /// What the board found at boot and what its display does.
    pub health: Health<'a>,
}

/// What the board found at boot (kept from the boot log) and the state of
/// its display, for `/status`, the page and `rt-client doctor`
/// (docs/diagnostics.md lists the values).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Health<'a> {
    /// The boot self-test: `"pass"`, `"fail"` or `"skipped"`.
    pub self_test: &'a str,
    /// Its log line, or why it was skipped.
    pub self_test_detail: &'a str,
    /// How frames are made: `"frames"` (the FPGA's frame DMA), `"rows"`
    /// (the FPGA a row at a time over the bridge), `"software"` (the model
    /// on the CPU).
    pub mode: &'a str,
    /// The accelerator's register-map version, if one answered.
    pub register_map: Option<u16>,
    /// Its bitstream's build id (BUILD_ID: the commit's first 7 hex
    /// digits; 0: none recorded), if one answered.
    pub fpga_build: Option<u32>,
    /// The FPGA's bridges and its SDRAM port as the firmware read them
    /// (`"not a board"` off the board).
    pub bridges: &'a str,
    /// The VGA output: `"on"`, `"off: WHY"`, or a fault.
    pub vga: &'a str,
    /// The code the board's LEDs and displays show (`"ok"`, or `E1`..,
    /// docs/diagnostics.md).
    pub code: &'a str,
}

/// The last lines of the board's log, for `/log`.
pub trait LogTail {
    /// Copy the log's newest bytes into `out`, whole lines (from the start
    /// of a line) as far as they fit; returns the bytes copied.
    fn tail(&self, out: &mut [u8]) -> usize;
}

impl fmt::Debug for dyn LogTail + '_ {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("LogTail")
    }
}

/// A log with nothing in it.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoLog;

impl LogTail for NoLog {
    fn tail(&self, _out: &mut [u8]) -> usize {
        0
    }
}

/// The newest whole lines of a log held as two pieces, older then newer
/// (a ring's halves: `heapless::HistoryBuf::as_slices`), copied into
/// `out`: the oldest line that does not fit whole is left out, and so is
/// the first one if the ring has `wrapped` (its start was overwritten).
/// Returns the bytes copied.
pub fn copy_tail(pieces: [&[u8]; 2], wrapped: bool, out: &mut [u8]) -> usize {
    let total = pieces[0].len() + pieces[1].len();
    let byte = |i: usize| if i < pieces[0].len() { pieces[0][i] } else { pieces[1][i - pieces[0].len()] };
    let mut start = total.saturating_sub(out.len()).max(usize::from(wrapped)).min(total);
    if start > 0 {
        // Skip to just after the first line end at or after `start - 1`:
        // the line cut by the ring or by `out` is dropped whole.
        while start < total && byte(start - 1) != b'\n' {
            start += 1;
        }
    }
    for (o, i) in out.iter_mut().zip(start..total) {
        *o = byte(i);
    }
    total - start
}

/// Who the board is on the network, for the status page and
/// `rt-client discover` / `doctor`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Identity<'a> {
    /// The serving program's version (the firmware's, from its build).
    pub version: &'a str,
    /// The name it answers to (`NAME.local`).
    pub name: &'a str,
    /// Its IPv4 address, if it has one.
    pub address: Option<core::net::Ipv4Addr>,
    /// Where the address came from: `"dhcp"`, `"link-local"`, `"static"`
    /// (docs/networking.md), `"host"` (hps-sim), `"none"`.
    pub address_from: &'a str,
    /// Its MAC address, where it has one of its own (the firmware).
    pub mac: Option<[u8; 6]>,
    /// Where the MAC came from: `"settings"` (raytracer.txt's `mac=`),
    /// `"default"` (the firmware's own, the same on every board), `"none"`.
    pub mac_from: &'a str,
    /// Frames received from another device sending with this MAC (two
    /// boards from one card image; `snoop::MacClashes` with the `smoltcp`
    /// feature).
    pub mac_clashes: u32,
}

impl BoardStatus<'_> {
    /// The status as one JSON object (RFC 8259).
    pub fn write_json(&self, w: &mut impl Write) -> fmt::Result {
        let v = &self.viewers;
        write!(w, "{{\"uptime_s\":{},\"renderer\":", self.uptime_s)?;
        json_string(w, self.renderer)?;
        w.write_str(",\"link\":")?;
        json_string(w, self.link)?;
        write!(
            w,
            ",\"frames_rendered\":{},\"frames_sent\":{},\"viewers\":{{\"web\":{},\"web_max\":{},\"seed\":{},\"rtsp\":{}}},\"rtsp_port\":{}",
            self.frames_rendered, self.frames_sent, v.web, v.web_max, v.seed, v.rtsp, self.rtsp_port
        )?;
        // Then who the board is, and the closing brace.
        self.write_identity(w)
    }

    fn write_identity(&self, w: &mut impl Write) -> fmt::Result {
        let id = &self.identity;
        w.write_str(",\"version\":")?;
        json_string(w, id.version)?;
        w.write_str(",\"name\":")?;
        json_string(w, id.name)?;
        match id.address {
            Some(a) => write!(w, ",\"address\":\"{a}\"")?,
            None => w.write_str(",\"address\":null")?,
        }
        w.write_str(",\"address_from\":")?;
        json_string(w, id.address_from)?;
        match id.mac {
            Some(m) => {
                write!(w, ",\"mac\":\"{:02x}:{:02x}:{:02x}:{:02x}:{:02x}:{:02x}\"", m[0], m[1], m[2], m[3], m[4], m[5])?
            }
            None => w.write_str(",\"mac\":null")?,
        }
        w.write_str(",\"mac_from\":")?;
        json_string(w, id.mac_from)?;
        write!(w, ",\"mac_clashes\":{}", id.mac_clashes)?;
        self.write_health(w)
    }

    fn write_health(&self, w: &mut impl Write) -> fmt::Result {
        let h = &self.health;
        w.write_str(",\"self_test\":")?;
        json_string(w, h.self_test)?;
        w.write_str(",\"self_test_detail\":")?;
        json_string(w, h.self_test_detail)?;
        w.write_str(",\"mode\":")?;
        json_string(w, h.mode)?;
        match h.register_map {
            Some(v) => write!(w, ",\"register_map\":{v}")?,
            None => w.write_str(",\"register_map\":null")?,
        }
        match h.fpga_build {
            Some(b) => write!(w, ",\"fpga_build\":\"{b:07x}\"")?,
            None => w.write_str(",\"fpga_build\":null")?,
        }
        w.write_str(",\"bridges\":")?;
        json_string(w, h.bridges)?;
        w.write_str(",\"vga\":")?;
        json_string(w, h.vga)?;
        w.write_str(",\"code\":")?;
        json_string(w, h.code)?;
        w.write_char('}')
    }
}

/// A JSON string: quotes, backslashes and control characters escaped
/// (RFC 8259, section 7).
fn json_string(w: &mut impl Write, s: &str) -> fmt::Result {
    w.write_char('"')?;
    for c in s.chars() {
        match c {
            '"' => w.write_str("\\\"")?,
            '\\' => w.write_str("\\\\")?,
            c if u32::from(c) < 0x20 => write!(w, "\\u{:04x}", u32::from(c))?,
            c => w.write_char(c)?,
        }
    }
    w.write_char('"')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_tail_is_whole_lines_from_both_pieces() {
        let mut out = [0u8; 12];
        // Everything fits.
        let n = copy_tail([b"ab\n", b"cd\n"], false, &mut out);
        assert_eq!(&out[..n], b"ab\ncd\n");
        // The ring cut "line1": only whole lines are copied.
        let mut big = [0u8; 64];
        let n = copy_tail([b"ne1\nline2\n", b"line3\n"], true, &mut big);
        assert_eq!(&big[..n], b"line2\nline3\n");
        // `out` cuts "line1".
        let n = copy_tail([b"line1\nline2\n", b"line3\n"], false, &mut out);
        assert_eq!(&out[..n], b"line2\nline3\n");
        // A line too long for `out` alone: nothing rather than a piece.
        let n = copy_tail([b"", b"a very long line\n"], false, &mut out);
        assert_eq!(n, 0);
        assert_eq!(copy_tail([b"", b""], true, &mut out), 0);
    }

    #[test]
    fn the_status_is_the_json_the_page_reads() {
        let s = BoardStatus {
            uptime_s: 61,
            renderer: "fpga",
            link: "1000 Mbit/s \"full\"\n",
            frames_rendered: 7,
            frames_sent: 5,
            viewers: Viewers { web: 1, web_max: 4, seed: 2, rtsp: 3 },
            rtsp_port: 8554,
            identity: Identity {
                version: "0.1.0",
                name: "raytracer-2",
                address: Some(core::net::Ipv4Addr::new(169, 254, 7, 9)),
                address_from: "link-local",
                mac: Some([0x02, 0xde, 0x1c, 0x00, 0x46, 0x0a]),
                mac_from: "settings",
                mac_clashes: 3,
            },
            health: Health {
                self_test: "fail",
                self_test_detail: "self-test: FAIL: frame mode",
                mode: "rows",
                register_map: Some(3),
                fpga_build: Some(0x012_3abc),
                bridges: "lwhps2fpga out of reset",
                vga: "off: frame mode failed",
                code: "E1",
            },
        };
        let mut out = String::new();
        s.write_json(&mut out).unwrap();
        assert_eq!(
            out,
            r#"{"uptime_s":61,"renderer":"fpga","link":"1000 Mbit/s \"full\"\u000a","frames_rendered":7,"frames_sent":5,"viewers":{"web":1,"web_max":4,"seed":2,"rtsp":3},"rtsp_port":8554,"version":"0.1.0","name":"raytracer-2","address":"169.254.7.9","address_from":"link-local","mac":"02:de:1c:00:46:0a","mac_from":"settings","mac_clashes":3,"self_test":"fail","self_test_detail":"self-test: FAIL: frame mode","mode":"rows","register_map":3,"fpga_build":"0123abc","bridges":"lwhps2fpga out of reset","vga":"off: frame mode failed","code":"E1"}"#
        );
    }
}
