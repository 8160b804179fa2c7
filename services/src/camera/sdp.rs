//! The session description `DESCRIBE` answers (SDP, RFC 4566): one video
//! stream of uncompressed RGB (RFC 4175) with the attributes players need.

use core::fmt::{self, Write};
use core::net::Ipv4Addr;

use model::{HEIGHT, WIDTH};

use super::url::{ControlUrl, Fps};

/// The RTP clock of the video payload (RFC 4175 section 6.1), Hz.
pub const RTP_CLOCK_HZ: u32 = 90_000;

/// The RTP payload type announced (a dynamic one, RFC 3551 section 6).
pub const PAYLOAD_TYPE: u8 = 96;

/// The payload type the description announces for RFC 4588 retransmission
/// (`a=rtpmap:97 rtx/90000`, `a=fmtp:97 apt=96`), under RTP/AVPF only.
///
/// The camera never sends it: it answers a NACK with the original packet
/// (same SSRC, sequence number and payload type 96). The announcement is
/// what GStreamer's rtspsrc needs to ask for repairs at all: its
/// `add_retransmission` (gst/rtsp/gstrtspsrc.c, 1.22) turns the jitter
/// buffer's retransmission requests on only when the SETUP answer's profile
/// is AVPF and the description maps an `rtx` payload type to the media's
/// with `apt`; without it rtspsrc sends no NACK, unicast or multicast. Its
/// `rtprtxreceive` passes packets of payload type 96 through, and the jitter
/// buffer takes a resent original as the late packet it is. FFmpeg reads
/// the `m=` line's first format only and ignores the other's attributes.
pub const RTX_PAYLOAD_TYPE: u8 = 97;

/// The RTP profile a client asked for (RFC 3551 AVP, or RFC 4585 AVPF with
/// early feedback: the NACKs the camera answers).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Profile {
    /// `RTP/AVP`.
    Avp,
    /// `RTP/AVPF`.
    Avpf,
}

impl Profile {
    /// The profile's name in a `Transport` header or an SDP `m=` line.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Avp => "RTP/AVP",
            Profile::Avpf => "RTP/AVPF",
        }
    }
}

/// A stream's multicast destination.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub struct Group {
    /// The group address.
    pub addr: Ipv4Addr,
    /// The RTP port (RTCP one above it).
    pub port: u16,
    /// The packets' time to live (RFC 1112: 1 keeps them on the link).
    pub ttl: u8,
}

/// What a description says.
#[derive(Clone, Copy, Debug)]
pub struct Description<'a> {
    /// The `o=` line's session id (random: a new description each time).
    pub session_id: u32,
    /// The server's address, in the `o=` line.
    pub server_ip: Ipv4Addr,
    /// The stream's rate: `exactframerate` (left out for `fps=max`).
    pub fps: Fps,
    /// The RTP profile of the `m=` line. `RTP/AVPF` (RFC 4585) announces
    /// generic NACKs (`a=rtcp-fb`) and reduced-size RTCP (`a=rtcp-rsize`,
    /// RFC 5506), both of which the camera takes; under `RTP/AVP` neither
    /// attribute is defined, so neither is written.
    pub profile: Profile,
    /// The multicast group the stream is sent to, if the URL asked for
    /// multicast: the `c=` line names it with its TTL (RFC 4566 section
    /// 5.7) and the `m=` line its port, so a receiver with nothing but this
    /// description can join. `None`: unicast, `c=IN IP4 0.0.0.0` and port
    /// 0 (the ports come with `SETUP`).
    pub group: Option<Group>,
    /// The stream's URL; `a=control` writes it as its control URL
    /// ([`ControlUrl`]).
    pub control: &'a str,
}

/// Write `d` into `out`.
pub fn write(out: &mut impl Write, d: &Description<'_>) -> fmt::Result {
    let (id, ip) = (d.session_id, d.server_ip);
    write!(out, "v=0\r\no=- {id} 1 IN IP4 {ip}\r\ns=raytracer\r\n")?;
    let port = match d.group {
        Some(g) => {
            write!(out, "c=IN IP4 {}/{}\r\n", g.addr, g.ttl)?;
            g.port
        }
        None => {
            out.write_str("c=IN IP4 0.0.0.0\r\n")?;
            0
        }
    };
    write!(out, "t=0 0\r\nm=video {port} {} {PAYLOAD_TYPE}", d.profile.name())?;
    if d.profile == Profile::Avpf {
        write!(out, " {RTX_PAYLOAD_TYPE}")?;
    }
    out.write_str("\r\n")?;
    write!(out, "a=rtpmap:{PAYLOAD_TYPE} raw/{RTP_CLOCK_HZ}\r\n")?;
    // RFC 4175 section 6.1 spells the colorimetry values BT601-5, BT709-2
    // and SMPTE240M; the model's colours are BT.709's.
    write!(out, "a=fmtp:{PAYLOAD_TYPE} sampling=RGB; width={WIDTH}; height={HEIGHT}; depth=8; colorimetry=BT709-2")?;
    if let Fps::Rate(n) = d.fps {
        write!(out, "; exactframerate={n}")?;
    }
    out.write_str("\r\n")?;
    if d.profile == Profile::Avpf {
        write!(out, "a=rtcp-fb:{PAYLOAD_TYPE} nack\r\na=rtcp-rsize\r\n")?;
        write!(
            out,
            "a=rtpmap:{RTX_PAYLOAD_TYPE} rtx/{RTP_CLOCK_HZ}\r\na=fmtp:{RTX_PAYLOAD_TYPE} apt={PAYLOAD_TYPE}\r\n"
        )?;
    }
    write!(out, "a=control:{}\r\n", ControlUrl(d.control))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(d: &Description<'_>) -> std::string::String {
        let mut s = std::string::String::new();
        write(&mut s, d).unwrap();
        s
    }

    #[test]
    fn a_unicast_description_is_exact() {
        let d = Description {
            session_id: 7,
            server_ip: Ipv4Addr::new(192, 168, 1, 200),
            fps: Fps::Rate(30),
            profile: Profile::Avp,
            group: None,
            control: "rtsp://192.168.1.200:8554/light/3,4,-2",
        };
        assert_eq!(
            text(&d),
            "v=0\r\no=- 7 1 IN IP4 192.168.1.200\r\ns=raytracer\r\nc=IN IP4 0.0.0.0\r\nt=0 0\r\n\
             m=video 0 RTP/AVP 96\r\na=rtpmap:96 raw/90000\r\n\
             a=fmtp:96 sampling=RGB; width=480; height=360; depth=8; colorimetry=BT709-2; exactframerate=30\r\n\
             a=control:rtsp://192.168.1.200:8554/light/3/4/-2\r\n"
        );
        let avpf = text(&Description { profile: Profile::Avpf, fps: Fps::Max, ..d });
        assert!(avpf.contains("m=video 0 RTP/AVPF 96 97\r\n"), "{avpf}");
        assert!(
            avpf.contains(
                "colorimetry=BT709-2\r\na=rtcp-fb:96 nack\r\na=rtcp-rsize\r\na=rtpmap:97 rtx/90000\r\na=fmtp:97 apt=96\r\n"
            ),
            "the rtx format GStreamer needs before it asks for repairs: {avpf}"
        );
    }

    #[test]
    fn a_multicast_description_names_the_group_its_ttl_and_port() {
        let group = Group { addr: Ipv4Addr::new(239, 255, 42, 1), port: 5006, ttl: 1 };
        let d = Description {
            session_id: 1,
            server_ip: Ipv4Addr::new(10, 0, 2, 15),
            fps: Fps::Rate(10),
            profile: Profile::Avp,
            group: Some(group),
            control: "rtsp://10.0.2.15:8554/orbit?multicast",
        };
        let s = text(&d);
        assert!(s.contains("\r\nc=IN IP4 239.255.42.1/1\r\nt=0 0\r\nm=video 5006 RTP/AVP 96\r\n"), "{s}");
    }
}
