//! `rt-client discover`: the boards on this network, found by mDNS/DNS-SD
//! (their `_raytracer._tcp` service, RFC 6763), each with its name,
//! address and what its `/status` says (version, renderer, fault code).

use std::collections::BTreeMap;
use std::net::{Ipv4Addr, SocketAddr};
use std::time::{Duration, Instant};

use mdns_sd::{ServiceDaemon, ServiceEvent};
use rt_services::web::WEB_PORT;

/// The seed protocol's DNS-SD service type, as the board announces it
/// (rt_services::mdns::responder).
pub const SERVICE: &str = "_raytracer._tcp.local.";

/// One board found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Board {
    /// Its mDNS host name (`raytracer.local.`).
    pub host: String,
    /// Its IPv4 address.
    pub address: Ipv4Addr,
    /// Its seed port.
    pub seed_port: u16,
    /// `/status`'s version, renderer and fault code (or why it had none).
    pub status: String,
}

/// Browse for `wait`; the boards found, by host name.
pub fn browse(wait: Duration) -> Result<Vec<Board>, String> {
    let daemon = ServiceDaemon::new().map_err(|e| format!("cannot start mDNS: {e}"))?;
    let events = daemon.browse(SERVICE).map_err(|e| format!("cannot browse {SERVICE}: {e}"))?;
    let until = Instant::now() + wait;
    let mut found: BTreeMap<String, (Ipv4Addr, u16)> = BTreeMap::new();
    loop {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break;
        }
        match events.recv_timeout(left) {
            Ok(ServiceEvent::ServiceResolved(info)) => {
                if let Some(a) = info.get_addresses_v4().into_iter().min() {
                    found.insert(info.get_hostname().to_string(), (*a, info.get_port()));
                }
            }
            Ok(_) => {}
            Err(_) => break,
        }
    }
    let _ = daemon.shutdown();
    Ok(found
        .into_iter()
        .map(|(host, (address, seed_port))| Board { status: status_of(address, &host), host, address, seed_port })
        .collect())
}

/// What the board's `/status` says, in a few words.
fn status_of(address: Ipv4Addr, host: &str) -> String {
    let name = host.trim_end_matches('.');
    match crate::doctor::get_status(SocketAddr::from((address, WEB_PORT)), name) {
        Ok(v) => {
            let text = |k: &str| v.get(k).and_then(|x| x.as_str()).unwrap_or("?").to_string();
            format!("version {}, renderer {}, code {}", text("version"), text("renderer"), text("code"))
        }
        Err(e) => format!("no /status: {e}"),
    }
}

/// The table `discover` prints.
pub fn table(boards: &[Board]) -> String {
    if boards.is_empty() {
        return "no board answered (is this computer on the board's network? mDNS needs UDP port 5353 open)\n"
            .to_string();
    }
    let mut out = String::new();
    for b in boards {
        out.push_str(&format!(
            "{}  {}  seed port {}  {}\n",
            b.host.trim_end_matches('.'),
            b.address,
            b.seed_port,
            b.status
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_has_a_line_per_board_and_says_when_there_is_none() {
        let b = Board {
            host: "raytracer-2.local.".into(),
            address: Ipv4Addr::new(192, 168, 7, 3),
            seed_port: 7878,
            status: "version 0.1.0, renderer fpga, code ok".into(),
        };
        assert_eq!(
            table(&[b]),
            "raytracer-2.local  192.168.7.3  seed port 7878  version 0.1.0, renderer fpga, code ok\n"
        );
        assert!(table(&[]).starts_with("no board answered"));
    }
}
