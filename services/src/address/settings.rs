//! The board's settings file: `raytracer.txt` on the card's FAT partition,
//! which boot.cmd hands to the firmware (docs/networking.md, "Settings").
//!
//! One `key=value` a line; `#` starts a comment, on a line of its own or
//! after a value; blank lines are ignored; a UTF-8 byte order mark (as
//! Windows Notepad may write) is skipped. Keys:
//!
//! | key        | value                                  | default                      |
//! |------------|----------------------------------------|------------------------------|
//! | `ip`       | `dhcp`, or `A.B.C.D/N` (static)        | `dhcp` (then link-local)     |
//! | `gateway`  | `A.B.C.D` (with a static `ip`)         | none                         |
//! | `hostname` | 1-63 of `a-z`, `0-9`, `-`              | [`DEFAULT_HOST_NAME`]        |
//! | `mac`      | `xx:xx:xx:xx:xx:xx`, unicast           | the board's ([`Settings::mac`]) |
//!
//! A line the parser cannot use (a bad byte costs its line only) is
//! skipped and named in [`Settings::problems`], so that the board says
//! what it ignored (on the UART and its status page) instead of refusing
//! to start. A file longer than the hand-off area ([`Settings::parse_handed`])
//! is read as far as it fits, and named as too long.
//!
//! [`DEFAULT_HOST_NAME`]: crate::DEFAULT_HOST_NAME

use core::fmt;
use core::net::Ipv4Addr;

/// Most problems kept: more are counted, not described.
pub const PROBLEMS: usize = 4;

/// Longest host name: one DNS label (RFC 1035, section 2.3.4).
pub const HOST_NAME_MAX: usize = 63;

/// A host name: one DNS label of lower-case letters, digits and hyphens,
/// not starting or ending with a hyphen (RFC 952 / RFC 1123 section 2.1).
pub type HostName = heapless::String<HOST_NAME_MAX>;

/// How the board takes its IPv4 address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AddressMode {
    /// DHCP; an IPv4 link-local address while there is no lease.
    Automatic,
    /// This address and prefix length, and the default gateway if any.
    Static {
        /// The address.
        address: Ipv4Addr,
        /// Its network's prefix length.
        prefix_len: u8,
        /// The default gateway, if the file names one.
        gateway: Option<Ipv4Addr>,
    },
}

/// A line of the file that was not used, and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Problem {
    /// The line's number, from 1.
    pub line: u16,
    /// What was wrong with it.
    pub kind: ProblemKind,
}

/// What was wrong with a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProblemKind {
    /// Not `key=value`.
    NotKeyValue,
    /// A key this firmware does not know.
    UnknownKey,
    /// `ip` is neither `dhcp` nor `A.B.C.D/N` with N from 1 to 32 and an
    /// address a host can have (not 0.0.0.0, loopback, multicast or
    /// broadcast).
    BadAddress,
    /// `gateway` is not on the static address's network.
    GatewayOutsideSubnet,
    /// The file is longer than the firmware reads: its end was not read.
    TooLong,
    /// `gateway` is not an IPv4 address.
    BadGateway,
    /// `gateway` without a static `ip`: DHCP brings its own.
    GatewayWithoutStaticAddress,
    /// `hostname` is not one DNS label of `a-z`, `0-9` and `-`.
    BadHostName,
    /// `mac` is not six hex bytes, or is a group (multicast) or zero address.
    BadMac,
    /// The text is not UTF-8.
    NotText,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let why = match self.kind {
            ProblemKind::NotKeyValue => "not key=value",
            ProblemKind::UnknownKey => "unknown key (ip, gateway, hostname, mac)",
            ProblemKind::BadAddress => "ip must be dhcp or A.B.C.D/N (N 1-32; not 0.0.0.0, 127.x, multicast)",
            ProblemKind::GatewayOutsideSubnet => "gateway is not on the ip's network",
            ProblemKind::TooLong => "the file is longer than the 4088 bytes read: the rest ignored",
            ProblemKind::BadGateway => "gateway must be A.B.C.D",
            ProblemKind::GatewayWithoutStaticAddress => "gateway needs a static ip (DHCP gives its own)",
            ProblemKind::BadHostName => "hostname: 1-63 of a-z, 0-9 and -, not starting or ending with -",
            ProblemKind::BadMac => "mac must be xx:xx:xx:xx:xx:xx, unicast, not zero",
            ProblemKind::NotText => "not UTF-8 text",
        };
        write!(f, "line {}: {why}", self.line)
    }
}

/// The settings, as read: every key the file left out has its default.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Settings {
    /// How the address is taken.
    pub address: AddressMode,
    /// The name the board answers to (`NAME.local`), if the file sets one.
    pub hostname: Option<HostName>,
    /// The MAC address, if the file sets one; else the board's own.
    pub mac: Option<[u8; 6]>,
    /// Lines skipped (the first [`PROBLEMS`]).
    pub problems: heapless::Vec<Problem, PROBLEMS>,
    /// Lines skipped in all.
    pub problem_count: u16,
}

impl Default for Settings {
    fn default() -> Settings {
        Settings {
            address: AddressMode::Automatic,
            hostname: None,
            mac: None,
            problems: heapless::Vec::new(),
            problem_count: 0,
        }
    }
}

impl Settings {
    /// Read the file's bytes. Never fails: what cannot be used is named in
    /// [`problems`](Self::problems) and left at its default.
    pub fn parse(bytes: &[u8]) -> Settings {
        let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
        let mut s = Settings::default();
        let mut gateway: Option<(u16, Ipv4Addr)> = None;
        for (i, line) in bytes.split(|&b| b == b'\n').enumerate() {
            let n = u16::try_from(i + 1).unwrap_or(u16::MAX);
            let Ok(line) = core::str::from_utf8(line) else {
                s.note(n, ProblemKind::NotText);
                continue;
            };
            // A comment runs to the end of the line, after a value too (no
            // value has a `#`).
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let Some((key, value)) = line.split_once('=') else {
                s.note(n, ProblemKind::NotKeyValue);
                continue;
            };
            let value = value.trim();
            match key.trim() {
                "ip" => match parse_address(value) {
                    Some(mode) => s.address = mode,
                    None => s.note(n, ProblemKind::BadAddress),
                },
                "gateway" => match value.parse() {
                    Ok(g) => gateway = Some((n, g)),
                    Err(_) => s.note(n, ProblemKind::BadGateway),
                },
                "hostname" => match host_name(value) {
                    Some(h) => s.hostname = Some(h),
                    None => s.note(n, ProblemKind::BadHostName),
                },
                "mac" => match parse_mac(value) {
                    Some(m) => s.mac = Some(m),
                    None => s.note(n, ProblemKind::BadMac),
                },
                _ => s.note(n, ProblemKind::UnknownKey),
            }
        }
        if let Some((n, g)) = gateway {
            match &mut s.address {
                AddressMode::Static { address, prefix_len, gateway } => {
                    let mask = u32::MAX.checked_shl(32 - u32::from(*prefix_len)).unwrap_or(0);
                    if u32::from(*address) & mask == u32::from(g) & mask && g != *address {
                        *gateway = Some(g);
                    } else {
                        s.note(n, ProblemKind::GatewayOutsideSubnet);
                    }
                }
                AddressMode::Automatic => s.note(n, ProblemKind::GatewayWithoutStaticAddress),
            }
        }
        s
    }

    /// Read the first `bytes` of a file `length` bytes long (the hand-off
    /// area holds 4088): a file cut short is read up to its last whole
    /// line and named as too long.
    pub fn parse_handed(bytes: &[u8], length: usize) -> Settings {
        if length <= bytes.len() {
            return Settings::parse(&bytes[..length]);
        }
        let whole = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |end| end + 1);
        let mut s = Settings::parse(&bytes[..whole]);
        s.note(0, ProblemKind::TooLong);
        s
    }

    fn note(&mut self, line: u16, kind: ProblemKind) {
        self.problem_count = self.problem_count.saturating_add(1);
        let _ = self.problems.push(Problem { line, kind });
    }
}

fn parse_address(value: &str) -> Option<AddressMode> {
    if value.eq_ignore_ascii_case("dhcp") {
        return Some(AddressMode::Automatic);
    }
    let (address, len) = value.split_once('/')?;
    let prefix_len = len.parse().ok().filter(|l| (1..=32).contains(l))?;
    let address: Ipv4Addr = address.parse().ok()?;
    let host =
        !address.is_unspecified() && !address.is_loopback() && !address.is_multicast() && !address.is_broadcast();
    host.then_some(AddressMode::Static { address, prefix_len, gateway: None })
}

/// `value` as a host name, lower-cased, if it is one DNS label of letters,
/// digits and hyphens (RFC 1123, section 2.1) not starting or ending with
/// a hyphen.
pub fn host_name(value: &str) -> Option<HostName> {
    let ok = !value.is_empty()
        && value.len() <= HOST_NAME_MAX
        && value.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
        && !value.starts_with('-')
        && !value.ends_with('-');
    if !ok {
        return None;
    }
    let mut name = HostName::new();
    for c in value.chars() {
        name.push(c.to_ascii_lowercase()).ok()?;
    }
    Some(name)
}

/// Six hex bytes split by `:` or `-`; a group address (lowest bit of the
/// first byte set) or all zeros is refused: a station needs a unicast one
/// (IEEE 802, section 8.2).
pub fn parse_mac(value: &str) -> Option<[u8; 6]> {
    let mut mac = [0u8; 6];
    let mut parts = value.split([':', '-']);
    for byte in &mut mac {
        let part = parts.next()?;
        if part.len() != 2 {
            return None;
        }
        *byte = u8::from_str_radix(part, 16).ok()?;
    }
    (parts.next().is_none() && mac[0] & 1 == 0 && mac != [0; 6]).then_some(mac)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn an_empty_file_means_dhcp_and_the_boards_own_name_and_mac() {
        assert_eq!(Settings::parse(b""), Settings::default());
        assert_eq!(Settings::parse(b"# only a comment\n\n").address, AddressMode::Automatic);
    }

    #[test]
    fn every_key_is_read() {
        let s = Settings::parse(
            b"# lab bench 3\nip=192.168.0.50/24\ngateway = 192.168.0.1\nhostname=Bench3\nmac=02:de:1c:00:00:03\n",
        );
        assert_eq!(
            s.address,
            AddressMode::Static {
                address: Ipv4Addr::new(192, 168, 0, 50),
                prefix_len: 24,
                gateway: Some(Ipv4Addr::new(192, 168, 0, 1))
            }
        );
        assert_eq!(s.hostname.as_deref(), Some("bench3"));
        assert_eq!(s.mac, Some([0x02, 0xde, 0x1c, 0, 0, 3]));
        assert!(s.problems.is_empty(), "{:?}", s.problems);
        assert_eq!(Settings::parse(b"ip=DHCP\r\n").address, AddressMode::Automatic, "CR LF and upper case");
    }

    /// The quick-start's own example (docs/quick-start.md), written by
    /// Notepad: a byte order mark, CR LF, comments after the values.
    #[test]
    fn a_bom_and_comments_after_values_are_read_as_a_person_means_them() {
        let s = Settings::parse(
            b"\xef\xbb\xbfip=dhcp                 # or: ip=192.168.0.50/24 and gateway=192.168.0.1\r\n\
              hostname=raytracer      # reach it as raytracer.local\r\n",
        );
        assert!(s.problems.is_empty(), "{:?}", s.problems);
        assert_eq!((s.address, s.hostname.as_deref()), (AddressMode::Automatic, Some("raytracer")));
    }

    /// A bad byte costs its own line, not the file.
    #[test]
    fn a_line_that_is_not_utf8_is_named_and_the_others_read() {
        let s = Settings::parse(b"hostname=bench\nip=10.0.0.\xff/24\nmac=02:de:1c:00:00:03\n");
        assert_eq!(s.hostname.as_deref(), Some("bench"));
        assert_eq!(s.mac, Some([0x02, 0xde, 0x1c, 0, 0, 3]));
        assert_eq!(s.problems.iter().map(|p| (p.line, p.kind)).collect::<Vec<_>>(), [(2, ProblemKind::NotText)]);
    }

    /// Static addresses a host cannot use are refused, and a gateway off
    /// the address's network (the board could never reach it).
    #[test]
    fn a_static_address_must_be_usable_and_its_gateway_on_its_network() {
        for bad in ["ip=127.0.0.5/8", "ip=10.0.0.5/0", "ip=10.0.0.5/33", "ip=0.0.0.0/24", "ip=224.0.0.5/24"] {
            let s = Settings::parse(bad.as_bytes());
            assert_eq!((s.address, s.problems[0].kind), (AddressMode::Automatic, ProblemKind::BadAddress), "{bad}");
        }
        let s = Settings::parse(b"ip=192.168.0.50/24\ngateway=192.168.1.1\n");
        assert_eq!(s.problems[0].kind, ProblemKind::GatewayOutsideSubnet);
        assert!(matches!(s.address, AddressMode::Static { gateway: None, .. }));
        let s = Settings::parse(b"ip=10.1.2.3/32\ngateway=10.1.2.3\n");
        assert_eq!(s.problems[0].kind, ProblemKind::GatewayOutsideSubnet, "its own address is no gateway");
        let s = Settings::parse(b"ip=10.1.2.3/8\ngateway=10.200.0.1\n");
        assert!(s.problems.is_empty(), "{:?}", s.problems);
    }

    /// A file longer than the hand-off area: its whole lines that fit are
    /// read, the cut one is not, and the file is named as too long.
    #[test]
    fn a_file_cut_short_keeps_its_whole_lines_and_says_it_was_too_long() {
        let s = Settings::parse_handed(b"hostname=bench\nmac=02:de:1c:00:00:0", 9_000);
        assert_eq!((s.hostname.as_deref(), s.mac), (Some("bench"), None), "the cut line is not read");
        assert_eq!(s.problems.iter().map(|p| (p.line, p.kind)).collect::<Vec<_>>(), [(0, ProblemKind::TooLong)]);
        assert!(s.problems[0].to_string().contains("longer than"));
        let whole = Settings::parse_handed(b"hostname=bench\nrest", 15);
        assert_eq!((whole.hostname.as_deref(), whole.problem_count), (Some("bench"), 0), "length within the bytes");
    }

    #[test]
    fn a_bad_line_is_named_and_the_rest_still_read() {
        let s = Settings::parse(
            b"ip=192.168.0.300/24\nhostname=-x\nmac=01:00:5e:00:00:01\ncolour=blue\njust words\ngateway=10.0.0.1\nhostname=ok\n",
        );
        assert_eq!(s.address, AddressMode::Automatic);
        assert_eq!(s.hostname.as_deref(), Some("ok"));
        assert_eq!(s.mac, None);
        let kinds: Vec<_> = s.problems.iter().map(|p| (p.line, p.kind)).collect();
        assert_eq!(
            kinds,
            [
                (1, ProblemKind::BadAddress),
                (2, ProblemKind::BadHostName),
                (3, ProblemKind::BadMac),
                (4, ProblemKind::UnknownKey)
            ]
        );
        assert_eq!(s.problem_count, 6, "the line without '=' and the gateway without a static ip count too");
        assert_eq!(
            s.problems[0].to_string(),
            "line 1: ip must be dhcp or A.B.C.D/N (N 1-32; not 0.0.0.0, 127.x, multicast)"
        );
    }

    #[test]
    fn macs_and_names_at_their_limits() {
        assert_eq!(parse_mac("02-00-00-00-00-01"), Some([2, 0, 0, 0, 0, 1]));
        for bad in ["00:00:00:00:00:00", "03:00:00:00:00:01", "02:00:00:00:00", "02:00:00:00:00:01:02", "2:0:0:0:0:1"] {
            assert_eq!(parse_mac(bad), None, "{bad}");
        }
        assert!(host_name(&"a".repeat(63)).is_some());
        assert!(host_name(&"a".repeat(64)).is_none());
        for bad in ["", "a.b", "a_b", "x-", "é"] {
            assert!(host_name(bad).is_none(), "{bad}");
        }
        assert_eq!(Settings::parse(b"ip=0.0.0.0/0\n").problems[0].kind, ProblemKind::BadAddress);
        assert_eq!(Settings::parse(&[0xff, 0xfe]).problems[0].kind, ProblemKind::NotText);
    }

    proptest! {
        /// Whatever the card holds, reading it neither panics nor keeps an
        /// invalid value.
        #[test]
        fn any_bytes_are_read_without_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            let s = Settings::parse(&bytes);
            if let Some(h) = &s.hostname {
                prop_assert!(host_name(h).is_some());
            }
            if let Some(m) = s.mac {
                prop_assert!(m[0] & 1 == 0);
            }
            prop_assert!(usize::from(s.problem_count) >= s.problems.len());
        }
    }
}
