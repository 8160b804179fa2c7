//! RTSP/1.0 on the wire (RFC 2326): a request's fields, the `Transport`
//! header, and responses written into the caller's buffer. No state: a
//! connection's input is framed by [`super::connection`], and
//! [`super::Server`] decides what to answer.

use core::fmt::{self, Write};
use core::net::IpAddr;

use super::{Status, MAX_URL_BYTES};
use crate::camera::sdp::Profile;

/// The `Content-Length` of a header block: 0 if absent, `None` if malformed,
/// beyond 9 digits or given twice with different values.
pub(super) fn content_length(head: &[u8]) -> Option<usize> {
    let mut found: Option<usize> = None;
    for line in head.split(|&b| b == b'\n').skip(1) {
        let Some(colon) = line.iter().position(|&b| b == b':') else { continue };
        if !line[..colon].trim_ascii().eq_ignore_ascii_case(b"content-length") {
            continue;
        }
        let value = line[colon + 1..].trim_ascii();
        if value.is_empty() || value.len() > 9 || !value.iter().all(u8::is_ascii_digit) {
            return None;
        }
        let n = value.iter().fold(0usize, |n, d| n * 10 + usize::from(d - b'0'));
        if found.is_some_and(|f| f != n) {
            return None;
        }
        found = Some(n);
    }
    Some(found.unwrap_or(0))
}

// ---- Requests -----------------------------------------------------------------------

/// A request's fields the server reads.
pub(super) struct Request<'a> {
    pub method: &'a str,
    pub url: &'a str,
    pub cseq: &'a str,
    pub session: Option<&'a str>,
    pub transport: Option<&'a str>,
    /// `Require`: options the client needs the server to support (RFC
    /// 2326 section 12.32); this server supports none.
    pub require: Option<&'a str>,
}

/// Parse a header block; the error is the status to answer and the `CSeq`
/// to echo, if it was readable.
pub(super) fn parse_request(head: &[u8]) -> Result<Request<'_>, (Status, Option<&str>)> {
    let text = core::str::from_utf8(head).map_err(|_| (Status::BadRequest, None))?;
    let mut lines = text.split('\n').map(|l| l.strip_suffix('\r').unwrap_or(l));
    let request_line = lines.next().unwrap_or("");
    let (mut cseq, mut session, mut transport, mut require) = (None, None, None, None);
    let mut malformed = false;
    for line in lines {
        if line.is_empty() {
            break;
        }
        let Some((name, value)) = line.split_once(':') else {
            malformed = true;
            continue;
        };
        if name.is_empty() || !name.bytes().all(is_token_byte) {
            malformed = true;
            continue;
        }
        let value = value.trim_matches([' ', '\t']);
        let slot = if name.eq_ignore_ascii_case("cseq") {
            &mut cseq
        } else if name.eq_ignore_ascii_case("session") {
            &mut session
        } else if name.eq_ignore_ascii_case("transport") {
            &mut transport
        } else if name.eq_ignore_ascii_case("require") {
            &mut require
        } else {
            continue;
        };
        if slot.is_none() {
            *slot = Some(value);
        }
    }
    let cseq = cseq.filter(|c| !c.is_empty() && c.len() <= 10 && c.bytes().all(|b| b.is_ascii_digit()));
    let Some(cseq) = cseq else { return Err((Status::BadRequest, None)) };
    let bad = Err((Status::BadRequest, Some(cseq)));
    if malformed {
        return bad;
    }
    let mut parts = request_line.splitn(3, ' ');
    let (Some(method), Some(url), Some(version)) = (parts.next(), parts.next(), parts.next()) else { return bad };
    if method.is_empty()
        || !method.bytes().all(is_token_byte)
        || url.is_empty()
        || url.len() > MAX_URL_BYTES
        || !url.bytes().all(|b| b.is_ascii_graphic())
    {
        return bad;
    }
    if version != "RTSP/1.0" {
        let other_version = version
            .strip_prefix("RTSP/")
            .is_some_and(|v| !v.is_empty() && v.bytes().all(|b| b.is_ascii_digit() || b == b'.') && v.contains('.'));
        return Err((if other_version { Status::VersionNotSupported } else { Status::BadRequest }, Some(cseq)));
    }
    Ok(Request { method, url, cseq, session, transport, require })
}

fn is_token_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b"!#$%&'*+-.^_`|~".contains(&b)
}

// ---- The Transport header -----------------------------------------------------------

/// How a session's RTP reaches its client.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Transport {
    /// RTP and RTCP over UDP to the client's address, these ports.
    Udp {
        /// The client's RTP port.
        rtp_port: u16,
        /// The client's RTCP port.
        rtcp_port: u16,
    },
    /// RTP and RTCP inside the RTSP connection (RFC 2326 section 10.12), on
    /// these channels: for clients behind NAT or a firewall.
    Interleaved {
        /// The channel of RTP packets.
        rtp_channel: u8,
        /// The channel of RTCP packets.
        rtcp_channel: u8,
    },
    /// RTP and RTCP to the stream's multicast group (the server's choice of
    /// group, port and TTL): one copy of each packet for every receiver.
    Multicast,
}

/// The first acceptable transport of a `Transport` header (its
/// alternatives are in the client's order of preference, RFC 2326 section
/// 12.39), with the profile asked for; `None` if none is (recording, an
/// unknown profile, UDP without client ports, a destination other than
/// the client's own for unicast, the same port or channel for RTP and
/// RTCP). `client` is the address the request came from.
pub(super) fn parse_transport(header: &str, client: IpAddr) -> Option<(Transport, Profile)> {
    header.split(',').find_map(|spec| {
        let mut params = spec.split(';').map(str::trim);
        let Proto { profile, tcp } = proto(params.next()?)?;
        let (mut multicast, mut ports, mut channels) = (false, None, None);
        for p in params {
            let (name, value) = p.split_once('=').unwrap_or((p, ""));
            let value = value.trim_matches('"');
            if name.eq_ignore_ascii_case("multicast") {
                multicast = true;
            } else if name.eq_ignore_ascii_case("mode") {
                if !value.eq_ignore_ascii_case("play") {
                    return None;
                }
            } else if name.eq_ignore_ascii_case("client_port") {
                ports = Some(pair(value)?);
            } else if name.eq_ignore_ascii_case("interleaved") {
                let (a, b) = pair(value)?;
                channels = Some((u8::try_from(a).ok()?, u8::try_from(b).ok()?));
            } else if name.eq_ignore_ascii_case("destination") && !multicast {
                // A unicast stream goes to the client that asked only: a
                // destination elsewhere would make the board a flooder.
                if value.parse::<IpAddr>().ok() != Some(client) {
                    return None;
                }
            }
        }
        let transport = match (tcp, multicast, ports, channels) {
            (true, false, _, channels) => {
                let (rtp_channel, rtcp_channel) = channels.unwrap_or((0, 1));
                if rtp_channel == rtcp_channel {
                    return None;
                }
                Transport::Interleaved { rtp_channel, rtcp_channel }
            }
            (false, true, _, _) => Transport::Multicast,
            (false, false, Some((a, b)), _) if a != 0 && b != 0 && a != b => {
                Transport::Udp { rtp_port: a, rtcp_port: b }
            }
            _ => return None,
        };
        Some((transport, profile))
    })
}

/// A transport's protocol part: the profile and whether it is over TCP.
struct Proto {
    profile: Profile,
    tcp: bool,
}

/// `RTP/AVP`, `RTP/AVP/UDP`, `RTP/AVP/TCP` and the same for `RTP/AVPF`,
/// any case.
fn proto(text: &str) -> Option<Proto> {
    let mut parts = text.split('/');
    if !parts.next()?.eq_ignore_ascii_case("RTP") {
        return None;
    }
    let profile = match parts.next()? {
        p if p.eq_ignore_ascii_case("AVP") => Profile::Avp,
        p if p.eq_ignore_ascii_case("AVPF") => Profile::Avpf,
        _ => return None,
    };
    let tcp = match parts.next() {
        None => false,
        Some(l) if l.eq_ignore_ascii_case("UDP") => false,
        Some(l) if l.eq_ignore_ascii_case("TCP") => true,
        Some(_) => return None,
    };
    parts.next().is_none().then_some(Proto { profile, tcp })
}

/// `a-b` or `a` (then `b` = `a + 1`), as ports or channels.
fn pair(value: &str) -> Option<(u16, u16)> {
    let n = |s: &str| s.trim().parse::<u16>().ok();
    match value.split_once('-') {
        Some((a, b)) => Some((n(a)?, n(b)?)),
        None => {
            let a = n(value)?;
            Some((a, a.checked_add(1)?))
        }
    }
}

// ---- Responses ----------------------------------------------------------------------

/// A `fmt::Write` into a byte slice that remembers running out of room.
pub(super) struct Out<'a> {
    pub buf: &'a mut [u8],
    pub len: usize,
    pub overflow: bool,
}

impl Write for Out<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let end = self.len + s.len();
        if end > self.buf.len() {
            self.overflow = true;
            return Err(fmt::Error);
        }
        self.buf[self.len..end].copy_from_slice(s.as_bytes());
        self.len = end;
        Ok(())
    }
}

/// Status line and `CSeq`. Write errors are caught by `Out::overflow`.
pub(super) fn status_line(out: &mut impl Write, status: Status, cseq: Option<&str>) {
    let _ = write!(out, "RTSP/1.0 {} {}\r\n", status.code(), status.reason());
    if let Some(c) = cseq {
        let _ = write!(out, "CSeq: {c}\r\n");
    }
}

/// An answer of the status line and CSeq alone, as every error answer is.
pub(super) fn bare_answer(out: &mut impl Write, status: Status, cseq: Option<&str>) -> Status {
    status_line(out, status, cseq);
    let _ = out.write_str("\r\n");
    status
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transports_parse_in_the_clients_order() {
        let udp = Transport::Udp { rtp_port: 6000, rtcp_port: 6001 };
        let client = IpAddr::V4(core::net::Ipv4Addr::new(10, 0, 0, 7));
        let t = |h: &str| parse_transport(h, client);
        assert_eq!(t("RTP/AVP;unicast;client_port=6000-6001"), Some((udp, Profile::Avp)));
        assert_eq!(t("RTP/AVP/UDP;unicast;client_port=6000"), Some((udp, Profile::Avp)));
        assert_eq!(t("rtp/avpf;unicast;client_port=6000-6001"), Some((udp, Profile::Avpf)));
        let tcp = Transport::Interleaved { rtp_channel: 4, rtcp_channel: 5 };
        assert_eq!(t("RTP/AVP/TCP;unicast;interleaved=4-5"), Some((tcp, Profile::Avp)));
        let first = Transport::Interleaved { rtp_channel: 0, rtcp_channel: 1 };
        assert_eq!(t("RTP/AVP/TCP;unicast"), Some((first, Profile::Avp)), "the server picks 0-1");
        assert_eq!(
            t("RTP/AVP;multicast;destination=239.1.1.1;port=5000-5001;ttl=4"),
            Some((Transport::Multicast, Profile::Avp))
        );
        assert_eq!(
            t("RTP/SAVP;unicast;client_port=1-2,RTP/AVP/TCP;interleaved=2-3"),
            Some((Transport::Interleaved { rtp_channel: 2, rtcp_channel: 3 }, Profile::Avp)),
            "the first acceptable alternative"
        );
        assert_eq!(
            t("RTP/AVP;unicast;client_port=6000-6001;destination=10.0.0.7"),
            Some((udp, Profile::Avp)),
            "a destination that is the client itself"
        );
        for bad in [
            "RTP/AVP;unicast",
            "RTP/AVP;unicast;client_port=0-1",
            "RTP/AVP;unicast;client_port=6000;mode=record",
            "RTP/AVP;unicast;client_port=6000;destination=10.9.9.9",
            "RTP/AVP/SCTP;client_port=6000",
            "RTP/AVP/TCP;interleaved=300-301",
            "RTP/AVP/TCP;interleaved=0-0",
            "RTP/AVP;unicast;client_port=6000-6000",
            "RTP/AVP;unicast;client_port=6000;destination=not-an-address",
            "RTP/AVP/UDP/X;client_port=6000",
            "RAW/RAW/UDP;client_port=6000",
            "",
        ] {
            assert_eq!(t(bad), None, "{bad}");
        }
    }
}
