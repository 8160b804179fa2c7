//! HTTP/1.1 request heads (RFC 9112) as the board's page needs them:
//! parsed by httparse within fixed caps, and the response heads it sends.
//!
//! Only `GET` and `HEAD` are served, bodies are refused, and every response
//! closes the connection (`Connection: close`): the page's three files,
//! `/status` and the WebSocket upgrade each take one connection, which
//! keeps a socket's life short and its state small.

use core::fmt::Write;

use heapless::Vec;

/// The most bytes of a request head (request line and header fields)
/// kept; a head that does not fit is refused with 414 (request line) or
/// 431 (header fields). Browsers send 400 to 800 bytes.
pub const HEAD_BYTES: usize = 2048;

/// The longest request target; longer is refused with 414. The page's
/// longest is `/?light=X,Y,Z` with three long decimals.
pub const TARGET_BYTES: usize = 256;

/// The most header fields; more is refused with 431.
pub const HEADER_FIELDS: usize = 32;

/// Room for a response head or a small generated body.
pub const OUT_BYTES: usize = 1024;

/// The status codes the server answers with.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Status {
    /// 101: the WebSocket handshake's answer.
    SwitchingProtocols,
    /// 200.
    Ok,
    /// 304: the page file the client holds ([`Request::if_none_match`]) is
    /// the one served.
    NotModified,
    /// 400: not HTTP/1.x as RFC 9112 has it (or a bad WebSocket upgrade).
    BadRequest,
    /// 403: a `Host` that is not the board's, or a WebSocket upgrade from
    /// a page of another origin.
    Forbidden,
    /// 404: no such file.
    NotFound,
    /// 405: a method other than GET and HEAD.
    MethodNotAllowed,
    /// 408: the head did not arrive in time.
    RequestTimeout,
    /// 413: a request with a body.
    ContentTooLarge,
    /// 414: a request target longer than [`TARGET_BYTES`].
    UriTooLong,
    /// 426: a WebSocket version other than 13.
    UpgradeRequired,
    /// 431: header fields beyond [`HEAD_BYTES`] or [`HEADER_FIELDS`].
    HeaderFieldsTooLarge,
    /// 503: every web viewer's place is taken.
    ServiceUnavailable,
}

impl Status {
    /// The numeric code.
    pub const fn code(self) -> u16 {
        match self {
            Status::SwitchingProtocols => 101,
            Status::Ok => 200,
            Status::NotModified => 304,
            Status::BadRequest => 400,
            Status::Forbidden => 403,
            Status::NotFound => 404,
            Status::MethodNotAllowed => 405,
            Status::RequestTimeout => 408,
            Status::ContentTooLarge => 413,
            Status::UriTooLong => 414,
            Status::UpgradeRequired => 426,
            Status::HeaderFieldsTooLarge => 431,
            Status::ServiceUnavailable => 503,
        }
    }

    /// The reason phrase (RFC 9110, section 15).
    pub const fn reason(self) -> &'static str {
        match self {
            Status::SwitchingProtocols => "Switching Protocols",
            Status::Ok => "OK",
            Status::NotModified => "Not Modified",
            Status::BadRequest => "Bad Request",
            Status::Forbidden => "Forbidden",
            Status::NotFound => "Not Found",
            Status::MethodNotAllowed => "Method Not Allowed",
            Status::RequestTimeout => "Request Timeout",
            Status::ContentTooLarge => "Content Too Large",
            Status::UriTooLong => "URI Too Long",
            Status::UpgradeRequired => "Upgrade Required",
            Status::HeaderFieldsTooLarge => "Request Header Fields Too Large",
            Status::ServiceUnavailable => "Service Unavailable",
        }
    }
}

/// GET or HEAD: the methods served.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Method {
    /// The resource.
    Get,
    /// Its head only.
    Head,
}

/// What a request asks to upgrade to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Upgrade {
    /// Nothing: plain HTTP.
    None,
    /// A valid WebSocket opening handshake (RFC 6455, section 4.2.1) with
    /// this `Sec-WebSocket-Key` (24 base64 characters).
    WebSocket([u8; 24]),
}

/// A request head that parsed within the caps.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Request<'a> {
    /// GET or HEAD.
    pub method: Method,
    /// The target's path.
    pub path: &'a str,
    /// The target's query, without the `?`.
    pub query: Option<&'a str>,
    /// `Accept-Encoding` names gzip (with a non-zero weight).
    pub accepts_gzip: bool,
    /// A WebSocket handshake.
    pub upgrade: Upgrade,
    /// The `Host` field's value (none in HTTP/1.0 without one).
    pub host: Option<&'a str>,
    /// The `Origin` field's value: the page that opened the request, sent
    /// by browsers with every WebSocket handshake (RFC 6455, section 4.1).
    pub origin: Option<&'a str>,
    /// The `If-None-Match` field's value: the entity tags the client holds.
    pub if_none_match: Option<&'a str>,
    /// Bytes of the head (what follows is not part of it).
    pub len: usize,
}

/// What [`parse`] made of the bytes so far.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Parsed<'a> {
    /// The head is not complete yet.
    Partial,
    /// A complete head.
    Request(Request<'a>),
    /// A head to refuse with this status (and close).
    Refuse(Status),
}

/// Parse a request head from `buf`; `full` says `buf` holds
/// [`HEAD_BYTES`] and will not grow (a head that is still partial is too
/// large).
pub fn parse(buf: &[u8], full: bool) -> Parsed<'_> {
    let mut fields = [httparse::EMPTY_HEADER; HEADER_FIELDS];
    let mut req = httparse::Request::new(&mut fields);
    let len = match req.parse(buf) {
        Ok(s) => s,
        Err(httparse::Error::TooManyHeaders) => return Parsed::Refuse(Status::HeaderFieldsTooLarge),
        Err(_) => return Parsed::Refuse(Status::BadRequest),
    };
    let httparse::Status::Complete(len) = len else {
        if !full {
            // A target already past the cap need not wait for the rest.
            return match req.path {
                Some(p) if p.len() > TARGET_BYTES => Parsed::Refuse(Status::UriTooLong),
                _ => Parsed::Partial,
            };
        }
        let line_complete = buf.windows(2).any(|w| w == b"\r\n") || buf.contains(&b'\n');
        return Parsed::Refuse(if line_complete { Status::HeaderFieldsTooLarge } else { Status::UriTooLong });
    };
    let (Some(method), Some(target), Some(version)) = (req.method, req.path, req.version) else {
        return Parsed::Refuse(Status::BadRequest);
    };
    if target.len() > TARGET_BYTES {
        return Parsed::Refuse(Status::UriTooLong);
    }
    let method = match method {
        "GET" => Method::Get,
        "HEAD" => Method::Head,
        _ => return Parsed::Refuse(Status::MethodNotAllowed),
    };
    if !target.starts_with('/') {
        return Parsed::Refuse(Status::BadRequest);
    }
    let (path, query) = match target.split_once('?') {
        Some((p, q)) => (p, Some(q)),
        None => (target, None),
    };
    let mut host = 0;
    let (mut host_value, mut origin, mut if_none_match) = (None, None, None);
    let mut accepts_gzip = false;
    let mut upgrade_websocket = false;
    let mut connection_upgrade = false;
    let mut key = None;
    let mut ws_version = None;
    for f in req.headers.iter() {
        let name = f.name;
        let value = core::str::from_utf8(f.value).unwrap_or("");
        if name.eq_ignore_ascii_case("host") {
            host += 1;
            host_value = Some(value.trim());
        } else if name.eq_ignore_ascii_case("origin") {
            origin = Some(value.trim());
        } else if name.eq_ignore_ascii_case("if-none-match") {
            if_none_match = Some(value.trim());
        } else if name.eq_ignore_ascii_case("content-length") {
            // A body we would have to read (or a malformed length).
            if value.trim() != "0" {
                return Parsed::Refuse(Status::ContentTooLarge);
            }
        } else if name.eq_ignore_ascii_case("transfer-encoding") {
            return Parsed::Refuse(Status::ContentTooLarge);
        } else if name.eq_ignore_ascii_case("accept-encoding") {
            accepts_gzip |= accepts(value, "gzip");
        } else if name.eq_ignore_ascii_case("upgrade") {
            upgrade_websocket |= has_token(value, "websocket");
        } else if name.eq_ignore_ascii_case("connection") {
            connection_upgrade |= has_token(value, "upgrade");
        } else if name.eq_ignore_ascii_case("sec-websocket-key") {
            key = Some(value.trim());
        } else if name.eq_ignore_ascii_case("sec-websocket-version") {
            ws_version = Some(value.trim());
        }
    }
    // RFC 9112, section 3.2: exactly one Host in HTTP/1.1.
    if (version == 1 && host != 1) || host > 1 {
        return Parsed::Refuse(Status::BadRequest);
    }
    let upgrade = if upgrade_websocket || key.is_some() {
        // RFC 6455, section 4.2.1: GET, HTTP/1.1, Upgrade and Connection,
        // a 16-byte key in base64; section 4.4: version 13 or 426.
        if method != Method::Get || version != 1 || !upgrade_websocket || !connection_upgrade {
            return Parsed::Refuse(Status::BadRequest);
        }
        if ws_version != Some("13") {
            return Parsed::Refuse(Status::UpgradeRequired);
        }
        match key.and_then(websocket_key) {
            Some(k) => Upgrade::WebSocket(k),
            None => return Parsed::Refuse(Status::BadRequest),
        }
    } else {
        Upgrade::None
    };
    Parsed::Request(Request {
        method,
        path,
        query,
        accepts_gzip,
        upgrade,
        host: host_value,
        origin,
        if_none_match,
        len,
    })
}

/// A `Sec-WebSocket-Key` that decodes to 16 bytes, as sent.
fn websocket_key(value: &str) -> Option<[u8; 24]> {
    use base64::Engine;
    let bytes: [u8; 24] = value.as_bytes().try_into().ok()?;
    let mut decoded = [0u8; 18];
    match base64::engine::general_purpose::STANDARD.decode_slice(bytes, &mut decoded) {
        Ok(16) => Some(bytes),
        _ => None,
    }
}

/// An `If-None-Match` list (RFC 9110, section 13.1.2) names `etag` (weak
/// comparison: a `W/` prefix is ignored), or is `*`.
pub fn etag_listed(list: &str, etag: &str) -> bool {
    list.trim() == "*" || list.split(',').any(|t| t.trim().trim_start_matches("W/") == etag)
}

/// A comma-separated list holds `token` (case-insensitive).
fn has_token(list: &str, token: &str) -> bool {
    list.split(',').any(|t| t.trim().eq_ignore_ascii_case(token))
}

/// An `Accept-Encoding` list accepts `coding` (RFC 9110, section 12.5.3):
/// named without `q=0`.
fn accepts(list: &str, coding: &str) -> bool {
    list.split(',').any(|item| {
        let mut parts = item.split(';');
        let name = parts.next().unwrap_or("").trim();
        let zero = parts.any(|p| {
            let p = p.trim();
            p.strip_prefix("q=")
                .or_else(|| p.strip_prefix("Q="))
                .is_some_and(|q| q.trim_end_matches(['0', '.']).is_empty())
        });
        name.eq_ignore_ascii_case(coding) && !zero
    })
}

/// Room for a response head or a small body.
pub type Out = Vec<u8, OUT_BYTES>;

/// Write a response head to `out`: status line, `Content-Length` (when
/// `length` is given), `Connection: close` (but for 101), the extra fields,
/// then the blank line. Fails only if `out` is too small (a bug: every head
/// is far smaller).
pub fn head(out: &mut Out, status: Status, length: Option<usize>, extra: &[(&str, &str)]) -> core::fmt::Result {
    let mut w = Writer(out);
    write!(w, "HTTP/1.1 {} {}\r\n", status.code(), status.reason())?;
    if let Some(n) = length {
        write!(w, "Content-Length: {n}\r\n")?;
    }
    if status != Status::SwitchingProtocols {
        w.write_str("Connection: close\r\n")?;
        // No answer of the board's is to be read as another type.
        w.write_str("X-Content-Type-Options: nosniff\r\n")?;
    }
    for (name, value) in extra {
        write!(w, "{name}: {value}\r\n")?;
    }
    w.write_str("\r\n")
}

/// `core::fmt::Write` into a byte vector (heapless's `Vec` has none).
pub struct Writer<'a, const N: usize = OUT_BYTES>(pub &'a mut Vec<u8, N>);

impl<const N: usize> Write for Writer<'_, N> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0.extend_from_slice(s.as_bytes()).map_err(|_| core::fmt::Error)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(text: &str) -> Parsed<'_> {
        parse(text.as_bytes(), false)
    }

    const UPGRADE: &str = "GET /ws HTTP/1.1\r\nHost: board\r\nUpgrade: websocket\r\nConnection: keep-alive, Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";

    #[test]
    fn a_browser_request_parses_with_its_query_and_encodings() {
        let text = "GET /?light=3,4,-2 HTTP/1.1\r\nHost: 10.0.0.2\r\nAccept-Encoding: gzip, deflate, br\r\n\r\n";
        let Parsed::Request(r) = request(text) else { panic!("{:?}", request(text)) };
        assert_eq!((r.method, r.path, r.query), (Method::Get, "/", Some("light=3,4,-2")));
        assert!(r.accepts_gzip);
        assert_eq!(r.upgrade, Upgrade::None);
    }

    #[test]
    fn gzip_with_zero_weight_is_not_accepted() {
        assert!(accepts("gzip;q=1.0, br", "gzip"));
        assert!(!accepts("gzip;q=0, br", "gzip"));
        assert!(!accepts("gzip; q=0.000", "gzip"));
        assert!(!accepts("x-gzip2", "gzip"));
    }

    #[test]
    fn a_websocket_handshake_parses_and_a_bad_one_is_refused() {
        let Parsed::Request(r) = request(UPGRADE) else { panic!() };
        assert_eq!(r.upgrade, Upgrade::WebSocket(*b"dGhlIHNhbXBsZSBub25jZQ=="));
        let v12 = UPGRADE.replace("Version: 13", "Version: 12");
        assert_eq!(request(&v12), Parsed::Refuse(Status::UpgradeRequired));
        let short = UPGRADE.replace("dGhlIHNhbXBsZSBub25jZQ==", "c2hvcnQ=");
        assert_eq!(request(&short), Parsed::Refuse(Status::BadRequest));
        let no_conn = UPGRADE.replace("keep-alive, Upgrade", "keep-alive");
        assert_eq!(request(&no_conn), Parsed::Refuse(Status::BadRequest));
        let head = UPGRADE.replace("GET", "HEAD");
        assert_eq!(request(&head), Parsed::Refuse(Status::BadRequest));
    }

    #[test]
    fn each_kind_of_bad_request_gets_its_status() {
        assert_eq!(request("GET / HTTP/1.1\r\nHost: a\r\n"), Parsed::Partial);
        assert_eq!(request("POST / HTTP/1.1\r\nHost: a\r\n\r\n"), Parsed::Refuse(Status::MethodNotAllowed));
        assert_eq!(request("GET / HTTP/1.1\r\n\r\n"), Parsed::Refuse(Status::BadRequest));
        assert_eq!(request("GET / HTTP/1.1\r\nHost: a\r\nHost: b\r\n\r\n"), Parsed::Refuse(Status::BadRequest));
        assert_eq!(request("\x16\x03\x01\x02\x00\x01"), Parsed::Refuse(Status::BadRequest));
        assert_eq!(request("GET * HTTP/1.1\r\nHost: a\r\n\r\n"), Parsed::Refuse(Status::BadRequest));
        assert_eq!(
            request("GET / HTTP/1.1\r\nHost: a\r\nContent-Length: 1048576\r\n\r\n"),
            Parsed::Refuse(Status::ContentTooLarge)
        );
        let long = format!("GET /{} HTTP/1.1\r\n", "a".repeat(TARGET_BYTES));
        assert_eq!(request(&long), Parsed::Refuse(Status::UriTooLong));
        let many: String = (0..=HEADER_FIELDS).map(|i| format!("X-{i}: y\r\n")).collect();
        let text = format!("GET / HTTP/1.1\r\nHost: a\r\n{many}\r\n");
        assert_eq!(request(&text), Parsed::Refuse(Status::HeaderFieldsTooLarge));
    }

    #[test]
    fn a_head_that_fills_the_buffer_is_too_large_by_its_line_or_its_fields() {
        let line = format!("GET /{}", "a".repeat(HEAD_BYTES));
        assert_eq!(parse(&line.as_bytes()[..HEAD_BYTES], true), Parsed::Refuse(Status::UriTooLong));
        let fields = format!("GET / HTTP/1.1\r\nX-Long: {}", "b".repeat(HEAD_BYTES));
        assert_eq!(parse(&fields.as_bytes()[..HEAD_BYTES], true), Parsed::Refuse(Status::HeaderFieldsTooLarge));
    }

    #[test]
    fn a_response_head_is_well_formed() {
        let mut out = Out::new();
        head(&mut out, Status::NotFound, Some(10), &[("Content-Type", "text/plain")]).unwrap();
        assert_eq!(
            core::str::from_utf8(&out).unwrap(),
            "HTTP/1.1 404 Not Found\r\nContent-Length: 10\r\nConnection: close\r\nX-Content-Type-Options: nosniff\r\nContent-Type: text/plain\r\n\r\n"
        );
    }

    proptest::proptest! {
        #[test]
        fn no_bytes_make_the_parser_panic(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..HEAD_BYTES)) {
            let _ = parse(&bytes, bytes.len() == HEAD_BYTES);
        }
    }
}
