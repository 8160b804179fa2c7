//! The multicast groups the board is in: the ones its services want (mDNS,
//! the camera's groups), joined with IGMP once there is an address to
//! report from, and reported again whenever the address or the link
//! changes; and the Ethernet groups the MAC's frame filter must pass.
//!
//! smoltcp 0.14 sends a group's IGMP membership report when it is joined,
//! but only if the interface has an IPv4 address then
//! (`igmp_report_packet` returns nothing without one), and marks the group
//! joined either way: a group joined at boot was never reported, and a
//! switch that snoops IGMP never forwarded it to the board. Nor does it
//! report again after an address change or a link-up (a cable moved to
//! another switch). It does answer IGMP queries (RFC 2236 section 3),
//! which arrive at 224.0.0.1, so the MAC must pass that group too.
//!
//! [`Membership`] joins only with an address, and on a new address or a
//! link-up reports every group again. smoltcp has no call that re-sends a
//! report, and sends one only for a group it does not have: so the groups
//! are left (smoltcp sends IGMPv2 Leave Group, RFC 2236 section 3) and,
//! once the interface has sent that, joined again (a report each).

use core::fmt::{Debug, Write};
use core::net::Ipv4Addr;

/// 224.0.0.1, where IGMP general queries go (RFC 1112 appendix I, RFC
/// 2236 section 3).
pub const ALL_SYSTEMS: Ipv4Addr = Ipv4Addr::new(224, 0, 0, 1);

/// Groups a [`Membership`] holds: the camera's streams and mDNS.
pub const MAX_GROUPS: usize = crate::camera::rtsp::MAX_SESSIONS + 1;

/// Joining and leaving groups on an interface (smoltcp's `Interface`; a
/// recorder in tests).
pub trait Groups {
    /// Why a join or leave failed.
    type Error: Debug;
    /// Join `group`: a membership report goes out when the interface next
    /// sends.
    fn join(&mut self, group: Ipv4Addr) -> Result<(), Self::Error>;
    /// Leave `group`.
    fn leave(&mut self, group: Ipv4Addr) -> Result<(), Self::Error>;
}

#[cfg(feature = "smoltcp")]
impl Groups for smoltcp::iface::Interface {
    type Error = smoltcp::iface::MulticastError;
    fn join(&mut self, group: Ipv4Addr) -> Result<(), Self::Error> {
        self.join_multicast_group(group)
    }
    fn leave(&mut self, group: Ipv4Addr) -> Result<(), Self::Error> {
        self.leave_multicast_group(group)
    }
}

/// The groups wanted, the groups joined, and the address and link they
/// were reported under.
#[derive(Clone, Debug, Default)]
pub struct Membership {
    wanted: heapless::Vec<Ipv4Addr, MAX_GROUPS>,
    joined: heapless::Vec<Ipv4Addr, MAX_GROUPS>,
    /// The address and link-up count the joined groups were reported
    /// under.
    reported: Option<(Ipv4Addr, u32)>,
    /// Changed since [`take_changed`](Self::take_changed) last said so.
    changed: bool,
    /// Changed since [`update`](Self::update) last brought the interface
    /// in line (a turn with nothing new costs a comparison).
    dirty: bool,
}

impl Membership {
    /// No group wanted.
    pub const fn new() -> Membership {
        Membership {
            wanted: heapless::Vec::new(),
            joined: heapless::Vec::new(),
            reported: None,
            changed: false,
            dirty: false,
        }
    }

    /// Want `group` (a no-op if wanted already); false when the table is
    /// full.
    pub fn want(&mut self, group: Ipv4Addr) -> bool {
        if self.wanted.contains(&group) {
            return true;
        }
        let pushed = self.wanted.push(group).is_ok();
        self.changed |= pushed;
        self.dirty |= pushed;
        pushed
    }

    /// Want `group` no longer.
    pub fn unwant(&mut self, group: Ipv4Addr) {
        if let Some(i) = self.wanted.iter().position(|g| *g == group) {
            self.wanted.swap_remove(i);
            self.changed = true;
            self.dirty = true;
        }
    }

    /// The groups wanted.
    pub fn wanted(&self) -> &[Ipv4Addr] {
        &self.wanted
    }

    /// The groups joined on the interface.
    pub fn joined(&self) -> &[Ipv4Addr] {
        &self.joined
    }

    /// The groups whose frames the MAC must pass: every group wanted
    /// (whether joined yet or not) and [`ALL_SYSTEMS`] for IGMP queries.
    pub fn filter_groups(&self) -> impl Iterator<Item = Ipv4Addr> + '_ {
        core::iter::once(ALL_SYSTEMS).chain(self.wanted.iter().copied())
    }

    /// Whether the wanted groups changed since the last call (the MAC's
    /// filter is then written again).
    pub fn take_changed(&mut self) -> bool {
        core::mem::take(&mut self.changed)
    }

    /// Bring the interface's groups in line with the wanted ones, for the
    /// interface's `address` and `link_ups` (how many times the link has
    /// come up; `None` while it is down). Call once a turn, before the
    /// interface's poll (which sends the reports).
    pub fn update<G: Groups>(
        &mut self,
        address: Option<Ipv4Addr>,
        link_ups: Option<u32>,
        iface: &mut G,
        log: &mut impl Write,
    ) {
        let now = address.zip(link_ups);
        if !self.dirty && self.reported == now {
            return;
        }
        self.dirty = false;
        if now.is_none() || (self.reported.is_some() && self.reported != now) {
            // No address or no link: nothing to report from, and a report
            // made now would be lost. A new address or a new link: leave
            // now, join again next turn (a report each), after the
            // interface's poll has sent the leaves and forgotten the
            // groups (a group still leaving when joined again would only
            // be marked joined, unreported).
            self.leave_all(iface, log);
            self.reported = None;
            return;
        }
        self.reported = now;
        while let Some(i) = self.joined.iter().position(|g| !self.wanted.contains(g)) {
            let g = self.joined.swap_remove(i);
            if let Err(e) = iface.leave(g) {
                let _ = writeln!(log, "net: leaving multicast group {g}: {e:?}");
            }
        }
        for &g in &self.wanted {
            if self.joined.contains(&g) {
                continue;
            }
            match iface.join(g) {
                Ok(()) => {
                    let _ = self.joined.push(g);
                }
                Err(e) => {
                    let _ = writeln!(log, "net: joining multicast group {g}: {e:?}");
                }
            }
        }
    }

    fn leave_all<G: Groups>(&mut self, iface: &mut G, log: &mut impl Write) {
        for g in self.joined.drain(..) {
            if let Err(e) = iface.leave(g) {
                let _ = writeln!(log, "net: leaving multicast group {g}: {e:?}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::String;
    use std::vec::Vec;

    /// What the interface was told, in order.
    #[derive(Default)]
    struct Recorder(Vec<(&'static str, Ipv4Addr)>);

    impl Groups for Recorder {
        type Error = ();
        fn join(&mut self, group: Ipv4Addr) -> Result<(), ()> {
            self.0.push(("join", group));
            Ok(())
        }
        fn leave(&mut self, group: Ipv4Addr) -> Result<(), ()> {
            self.0.push(("leave", group));
            Ok(())
        }
    }

    const MDNS: Ipv4Addr = Ipv4Addr::new(224, 0, 0, 251);
    const CAMERA: Ipv4Addr = Ipv4Addr::new(239, 255, 42, 1);
    const A: Ipv4Addr = Ipv4Addr::new(169, 254, 7, 9);
    const B: Ipv4Addr = Ipv4Addr::new(10, 0, 2, 77);

    fn turn(m: &mut Membership, address: Option<Ipv4Addr>, link: Option<u32>) -> Vec<(&'static str, Ipv4Addr)> {
        let mut iface = Recorder::default();
        m.update(address, link, &mut iface, &mut String::new());
        iface.0
    }

    /// Wanted at boot, joined (and so reported) only once the board has an
    /// address and a link.
    #[test]
    fn a_group_is_joined_once_there_is_an_address_and_a_link() {
        let mut m = Membership::new();
        assert!(m.want(MDNS));
        assert_eq!(turn(&mut m, None, Some(1)), []);
        assert_eq!(turn(&mut m, Some(A), None), []);
        assert_eq!(turn(&mut m, Some(A), Some(1)), [("join", MDNS)]);
        assert_eq!(turn(&mut m, Some(A), Some(1)), [], "steady: nothing");
        assert!(m.want(CAMERA));
        assert_eq!(turn(&mut m, Some(A), Some(1)), [("join", CAMERA)]);
        m.unwant(CAMERA);
        assert_eq!(turn(&mut m, Some(A), Some(1)), [("leave", CAMERA)]);
        assert_eq!(m.joined(), [MDNS]);
    }

    /// A new address (link-local, then DHCP's) or a link that came up
    /// again: every group left, then joined again the turn after, so that
    /// smoltcp reports each once more.
    #[test]
    fn a_new_address_or_link_reports_every_group_again() {
        let mut m = Membership::new();
        m.want(MDNS);
        m.want(CAMERA);
        turn(&mut m, Some(A), Some(1));
        assert_eq!(turn(&mut m, Some(B), Some(1)), [("leave", MDNS), ("leave", CAMERA)]);
        assert_eq!(turn(&mut m, Some(B), Some(1)), [("join", MDNS), ("join", CAMERA)]);
        assert_eq!(turn(&mut m, Some(B), Some(1)), []);
        // The cable out and in (another switch).
        assert_eq!(turn(&mut m, Some(B), None), [("leave", MDNS), ("leave", CAMERA)]);
        assert_eq!(turn(&mut m, Some(B), None), []);
        assert_eq!(turn(&mut m, Some(B), Some(2)), [("join", MDNS), ("join", CAMERA)]);
        // The link bounced between two turns: the count tells.
        assert_eq!(turn(&mut m, Some(B), Some(3)), [("leave", MDNS), ("leave", CAMERA)]);
        assert_eq!(turn(&mut m, Some(B), Some(3)), [("join", MDNS), ("join", CAMERA)]);
    }

    #[test]
    fn the_filter_passes_the_wanted_groups_and_all_systems_and_says_when_it_changed() {
        let mut m = Membership::new();
        assert_eq!(m.filter_groups().collect::<Vec<_>>(), [ALL_SYSTEMS]);
        m.want(MDNS);
        assert!(m.take_changed());
        assert!(!m.take_changed());
        m.want(MDNS);
        assert!(!m.take_changed(), "wanted already");
        assert_eq!(m.filter_groups().collect::<Vec<_>>(), [ALL_SYSTEMS, MDNS], "before it is joined");
        m.unwant(MDNS);
        assert!(m.take_changed());
    }
}
