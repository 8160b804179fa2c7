//! Which requests the board answers at all: the `Host` and `Origin`
//! checks that keep other web sites out.
//!
//! Browsers apply no same-origin rule to WebSockets: any page a person
//! opens can connect to `ws://<board>/ws` and drive the renderer. RFC 6455
//! (section 10.2) leaves the check to the server, through the `Origin`
//! field a browser sends with every handshake: an upgrade whose origin is
//! not the page's own host is refused (403). Programs that are not
//! browsers send no `Origin` and are let in.
//!
//! A DNS-rebinding page (a name of the attacker's that first resolves to
//! the attacker's server, then to the board) passes any origin check, since
//! the browser thinks both are one origin; what gives it away is the name
//! in `Host`. Only names the board has are answered: its host name, with
//! or without `.local`, and `localhost`. An IP literal is always answered:
//! rebinding needs a name, and the board is reached by address through
//! port forwards and NAT (the emulated board behind QEMU's user network is
//! `127.0.0.1:8080`) whose address it cannot know.

use core::net::IpAddr;

/// The host part of a `Host` value or an origin's authority: without the
/// port, without the brackets of an IPv6 literal, without a final dot.
fn host_part(authority: &str) -> &str {
    let host = if let Some(rest) = authority.strip_prefix('[') {
        rest.split_once(']').map_or(rest, |(h, _)| h)
    } else {
        authority.rsplit_once(':').map_or(authority, |(h, _)| h)
    };
    host.strip_suffix('.').unwrap_or(host)
}

/// Whether a request's `Host` names this board, whose host name is `name`
/// (as announced by mDNS, without `.local`). A request with no `Host`
/// (HTTP/1.0) is answered: browsers always send one.
pub fn host_is_ours(host: Option<&str>, name: &str) -> bool {
    let Some(host) = host else { return true };
    let h = host_part(host);
    if h.parse::<IpAddr>().is_ok() || h.eq_ignore_ascii_case("localhost") {
        return true;
    }
    let bare = match h.len().checked_sub(".local".len()) {
        Some(cut) if h.is_char_boundary(cut) && h[cut..].eq_ignore_ascii_case(".local") => &h[..cut],
        _ => h,
    };
    !name.is_empty() && bare.eq_ignore_ascii_case(name)
}

/// Whether a WebSocket handshake may go on: no `Origin` (not a browser),
/// or an `http:`/`https:` origin whose authority is the request's `Host`
/// (the board's own page). `null` (a sandboxed or file page) is refused.
pub fn origin_is_ours(origin: Option<&str>, host: Option<&str>) -> bool {
    let Some(origin) = origin else { return true };
    let Some(host) = host else { return false };
    let authority = origin.strip_prefix("http://").or_else(|| origin.strip_prefix("https://"));
    authority.is_some_and(|a| a.eq_ignore_ascii_case(host))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_boards_names_and_any_address_are_ours_and_other_names_are_not() {
        for host in [
            "raytracer",
            "raytracer.local",
            "RayTracer.Local.",
            "raytracer.local:80",
            "192.168.1.20",
            "10.0.2.15:80",
            "127.0.0.1:8080",
            "[::1]:8080",
            "[fe80::1]",
            "localhost:8080",
        ] {
            assert!(host_is_ours(Some(host), "raytracer"), "{host}");
        }
        for host in ["evil.example", "raytracer.evil.example", "raytracer2.local", "local", "", "192.168.1.20.nip.io"] {
            assert!(!host_is_ours(Some(host), "raytracer"), "{host}");
        }
        assert!(host_is_ours(None, "raytracer"), "HTTP/1.0 without Host");
        assert!(!host_is_ours(Some("anything"), ""), "no name: only addresses");
    }

    #[test]
    fn only_the_pages_own_origin_or_none_may_open_a_websocket() {
        assert!(origin_is_ours(None, Some("raytracer.local")));
        assert!(origin_is_ours(Some("http://raytracer.local"), Some("raytracer.local")));
        assert!(origin_is_ours(Some("http://127.0.0.1:8080"), Some("127.0.0.1:8080")));
        assert!(!origin_is_ours(Some("http://evil.example"), Some("raytracer.local")));
        assert!(!origin_is_ours(Some("http://127.0.0.1:8081"), Some("127.0.0.1:8080")));
        assert!(!origin_is_ours(Some("null"), Some("raytracer.local")));
        assert!(!origin_is_ours(Some("file://"), Some("raytracer.local")));
        assert!(!origin_is_ours(Some("http://raytracer.local"), None));
    }
}
