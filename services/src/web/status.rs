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
            },
        };
        let mut out = String::new();
        s.write_json(&mut out).unwrap();
        assert_eq!(
            out,
            r#"{"uptime_s":61,"renderer":"fpga","link":"1000 Mbit/s \"full\"\u000a","frames_rendered":7,"frames_sent":5,"viewers":{"web":1,"web_max":4,"seed":2,"rtsp":3},"rtsp_port":8554,"version":"0.1.0","name":"raytracer-2","address":"169.254.7.9","address_from":"link-local"}"#
        );
    }
}
