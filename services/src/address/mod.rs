//! The board's IPv4 address on any network, with no rebuild: where it
//! comes from and how it is claimed.
//!
//! * [`settings`]: the settings file on the card (`raytracer.txt`): a static
//!   address, a host name, a MAC address.
//! * [`link_local`]: an IPv4 link-local address (RFC 3927) while no DHCP
//!   server answers, so a laptop on a cable straight to the board reaches
//!   it.
//! * `assign` (feature `smoltcp`): both bound to smoltcp with its DHCPv4
//!   client (RFC 2131: renewing at T1, rebinding at T2): one
//!   [`Assignment`] at a time on the interface, a lease winning over a
//!   link-local address, every change reported so that the services and
//!   the displays follow it.

use core::fmt;
use core::net::Ipv4Addr;

#[cfg(feature = "smoltcp")]
pub mod assign;
pub mod link_local;
pub mod settings;

/// Where the address in use came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// The settings file.
    Static,
    /// A DHCP server's lease.
    Dhcp,
    /// Claimed on the link (RFC 3927): no DHCP server answered.
    LinkLocal,
}

impl Origin {
    /// A short word for logs and the status page.
    pub const fn as_str(self) -> &'static str {
        match self {
            Origin::Static => "static",
            Origin::Dhcp => "dhcp",
            Origin::LinkLocal => "link-local",
        }
    }
}

/// The address the board has, and how it reaches other networks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Assignment {
    /// The address.
    pub address: Ipv4Addr,
    /// Its network's prefix length.
    pub prefix_len: u8,
    /// The default gateway, if there is one.
    pub gateway: Option<Ipv4Addr>,
    /// Where it came from.
    pub origin: Origin,
}

impl fmt::Display for Assignment {
    /// `10.0.2.15/24 via 10.0.2.2 (dhcp)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.address, self.prefix_len)?;
        if let Some(g) = self.gateway {
            write!(f, " via {g}")?;
        }
        write!(f, " ({})", self.origin.as_str())
    }
}
