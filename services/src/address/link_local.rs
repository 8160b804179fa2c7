//! An IPv4 link-local address (RFC 3927), claimed when no DHCP server
//! answers: what lets a laptop cabled straight to the board reach it with
//! no settings on either side, as printers and cameras do.
//!
//! Sans-IO: [`LinkLocal`] is told the time and the ARP packets received
//! ([`ArpSeen`]) and says which ARP packet to send next ([`ArpSend`]); the
//! caller puts them on the wire and configures the address once
//! [`LinkLocal::address`] has one. The steps and timings are RFC 3927's
//! (section 2.2 probe, 2.4 announce, 2.5 defend; constants from section 9):
//!
//! 1. pick an address in 169.254.1.0 - 169.254.254.255 from a generator
//!    seeded with the MAC (the same board tends to get the same address);
//! 2. wait 0-[`PROBE_WAIT`], then send [`PROBE_NUM`] ARP probes (sender IP
//!    0.0.0.0) [`PROBE_MIN`]-[`PROBE_MAX`] apart, and wait [`ANNOUNCE_WAIT`];
//!    any ARP from another host with the address as sender, or another
//!    host's probe for it, is a conflict: pick again (after
//!    [`MAX_CONFLICTS`] conflicts, one try a [`RATE_LIMIT_INTERVAL`]);
//! 3. claim it: [`ANNOUNCE_NUM`] announcements [`ANNOUNCE_INTERVAL`] apart;
//! 4. defend it: another host's ARP claiming it is answered with an
//!    announcement, unless the last defence was within [`DEFEND_INTERVAL`],
//!    in which case the address is given up and the choice begins again.
//!    A probe for it is answered the same way (smoltcp answers no ARP
//!    request from 0.0.0.0, so the other host would not learn it is taken).

use core::net::Ipv4Addr;
use core::time::Duration;

use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};

use crate::time::Instant;

/// RFC 3927, section 9: the longest wait before the first probe.
pub const PROBE_WAIT: Duration = Duration::from_secs(1);
/// RFC 3927, section 9: probes sent.
pub const PROBE_NUM: u8 = 3;
/// RFC 3927, section 9: least time between probes.
pub const PROBE_MIN: Duration = Duration::from_secs(1);
/// RFC 3927, section 9: most time between probes.
pub const PROBE_MAX: Duration = Duration::from_secs(2);
/// RFC 3927, section 9: wait after the last probe before the claim.
pub const ANNOUNCE_WAIT: Duration = Duration::from_secs(2);
/// RFC 3927, section 9: announcements sent.
pub const ANNOUNCE_NUM: u8 = 2;
/// RFC 3927, section 9: time between announcements.
pub const ANNOUNCE_INTERVAL: Duration = Duration::from_secs(2);
/// RFC 3927, section 9: conflicts before the rate limit.
pub const MAX_CONFLICTS: u32 = 10;
/// RFC 3927, section 9: one try this often after [`MAX_CONFLICTS`].
pub const RATE_LIMIT_INTERVAL: Duration = Duration::from_secs(60);
/// RFC 3927, section 9: least time between two defences.
pub const DEFEND_INTERVAL: Duration = Duration::from_secs(10);

/// First and count of the addresses chosen from: 169.254.1.0 to
/// 169.254.254.255 (RFC 3927, section 2.1; the first and last 256 are
/// reserved).
const FIRST: u32 = u32::from_be_bytes([169, 254, 1, 0]);
const COUNT: u32 = 254 * 256 - 256;

/// An ARP packet received, as far as the claim cares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArpSeen {
    /// The sender's hardware address.
    pub sender_mac: [u8; 6],
    /// The sender's IPv4 address (0.0.0.0 in a probe).
    pub sender_ip: Ipv4Addr,
    /// The address asked about.
    pub target_ip: Ipv4Addr,
}

/// An ARP packet to broadcast now: a request from the board's MAC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArpSend {
    /// Who has this address? Sender IP 0.0.0.0, target the address.
    Probe(Ipv4Addr),
    /// This address is mine: sender and target IP the address.
    Announce(Ipv4Addr),
}

/// What the claim is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Not claiming (a lease or a static address is in use).
    Stopped,
    /// Probing `candidate`: `sent` probes so far, the next step at `next`.
    Probing { candidate: Ipv4Addr, sent: u8, next: Instant },
    /// `address` is ours: `sent` announcements so far, the next at `next`.
    Claimed { address: Ipv4Addr, sent: u8, next: Instant },
}

/// The link-local claim of one interface.
#[derive(Clone, Debug)]
pub struct LinkLocal {
    mac: [u8; 6],
    rng: ChaCha8Rng,
    state: State,
    conflicts: u32,
    last_defence: Option<Instant>,
    /// Answers owed to other hosts' probes for our address.
    owed: bool,
}

impl LinkLocal {
    /// Nothing claimed yet. The address generator is seeded with `mac`
    /// (RFC 3927, section 2.1: the same host tends to pick the same
    /// address); the timings' jitter comes from the same generator.
    pub fn new(mac: [u8; 6]) -> LinkLocal {
        let mut seed = [0u8; 8];
        seed[..6].copy_from_slice(&mac);
        LinkLocal {
            mac,
            rng: ChaCha8Rng::seed_from_u64(u64::from_le_bytes(seed)),
            state: State::Stopped,
            conflicts: 0,
            last_defence: None,
            owed: false,
        }
    }

    /// Begin (or keep) claiming an address: the link is up and there is no
    /// lease. Does nothing if a claim is already under way.
    pub fn start(&mut self, now: Instant) {
        if self.state == State::Stopped {
            self.pick(now);
        }
    }

    /// Stop claiming and give up any address: a DHCP lease won.
    pub fn stop(&mut self) {
        self.state = State::Stopped;
        self.owed = false;
    }

    /// The link came up again, perhaps on another network (a cable
    /// moved): an address held, or being probed, is probed again from the
    /// start before it is used (RFC 5227 section 2.1: probe whenever the
    /// link may have changed; RFC 3927 section 2.1 keeps the same address
    /// where it is free).
    pub fn link_up(&mut self, now: Instant) {
        let candidate = match self.state {
            State::Claimed { address, .. } => address,
            State::Probing { candidate, .. } => candidate,
            State::Stopped => return,
        };
        let wait = self.between(Duration::ZERO, PROBE_WAIT);
        self.owed = false;
        self.state = State::Probing { candidate, sent: 0, next: now + wait };
    }

    /// Whether a claim is under way or held.
    pub fn is_running(&self) -> bool {
        self.state != State::Stopped
    }

    /// The address claimed, once the probes found no one using it.
    pub fn address(&self) -> Option<Ipv4Addr> {
        match self.state {
            State::Claimed { address, .. } => Some(address),
            _ => None,
        }
    }

    /// Conflicts met since the board started.
    pub fn conflicts(&self) -> u32 {
        self.conflicts
    }

    /// Learn from a received ARP packet: a conflict with the candidate or
    /// the address held, or a probe to answer.
    pub fn on_arp(&mut self, now: Instant, arp: &ArpSeen) {
        if arp.sender_mac == self.mac {
            return;
        }
        match self.state {
            State::Stopped => {}
            State::Probing { candidate, .. } => {
                let probe_for_it = arp.sender_ip.is_unspecified() && arp.target_ip == candidate;
                if arp.sender_ip == candidate || probe_for_it {
                    self.conflicts = self.conflicts.saturating_add(1);
                    self.pick(now);
                }
            }
            State::Claimed { address, .. } => {
                if arp.sender_ip == address {
                    let recent = self.last_defence.is_some_and(|t| now.saturating_duration_since(t) < DEFEND_INTERVAL);
                    if recent {
                        // Section 2.5 (b): a second conflict within the
                        // interval: give the address up, choose again.
                        self.conflicts = self.conflicts.saturating_add(1);
                        self.last_defence = None;
                        self.pick(now);
                    } else {
                        self.last_defence = Some(now);
                        self.owed = true;
                    }
                } else if arp.sender_ip.is_unspecified() && arp.target_ip == address {
                    self.owed = true;
                }
            }
        }
    }

    /// The next ARP packet to send at `now`, if one is due; call until
    /// `None`.
    pub fn poll(&mut self, now: Instant) -> Option<ArpSend> {
        match self.state {
            State::Stopped => None,
            State::Probing { candidate, sent, next } if now >= next => {
                if sent < PROBE_NUM {
                    let sent = sent + 1;
                    let wait = if sent < PROBE_NUM { self.between(PROBE_MIN, PROBE_MAX) } else { ANNOUNCE_WAIT };
                    self.state = State::Probing { candidate, sent, next: now + wait };
                    Some(ArpSend::Probe(candidate))
                } else {
                    // Section 2.4: no conflict in the probes: the address
                    // is ours; announce it.
                    self.conflicts = 0;
                    self.state = State::Claimed { address: candidate, sent: 1, next: now + ANNOUNCE_INTERVAL };
                    Some(ArpSend::Announce(candidate))
                }
            }
            State::Probing { .. } => None,
            State::Claimed { address, sent, next } => {
                if sent < ANNOUNCE_NUM && now >= next {
                    self.state = State::Claimed { address, sent: sent + 1, next: now + ANNOUNCE_INTERVAL };
                    self.owed = false;
                    Some(ArpSend::Announce(address))
                } else if self.owed {
                    self.owed = false;
                    Some(ArpSend::Announce(address))
                } else {
                    None
                }
            }
        }
    }

    /// When [`poll`](Self::poll) next has something to send, if ever
    /// without a received packet.
    pub fn poll_at(&self) -> Option<Instant> {
        match self.state {
            State::Stopped => None,
            State::Probing { next, .. } => Some(next),
            State::Claimed { .. } if self.owed => Some(Instant::ZERO),
            State::Claimed { sent, next, .. } => (sent < ANNOUNCE_NUM).then_some(next),
        }
    }

    /// Choose a new candidate and schedule its first probe.
    fn pick(&mut self, now: Instant) {
        let candidate = Ipv4Addr::from(FIRST + self.rng.next_u32() % COUNT);
        let wait = if self.conflicts >= MAX_CONFLICTS {
            RATE_LIMIT_INTERVAL
        } else {
            self.between(Duration::ZERO, PROBE_WAIT)
        };
        self.owed = false;
        self.state = State::Probing { candidate, sent: 0, next: now + wait };
    }

    /// A uniformly random time in `low..=high`, in whole milliseconds.
    fn between(&mut self, low: Duration, high: Duration) -> Duration {
        let span = u64::try_from((high - low).as_millis()).unwrap_or(0);
        low + Duration::from_millis(self.rng.next_u64() % (span + 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAC: [u8; 6] = [0x02, 0xde, 0x1c, 0, 0, 1];
    const OTHER: [u8; 6] = [0x02, 0, 0, 0, 0, 9];

    fn ms(t: u64) -> Instant {
        Instant::from_millis(t)
    }

    /// Run the claim from `from` to `to` in 10 ms steps, answering nothing;
    /// every packet sent, with its time.
    fn run(ll: &mut LinkLocal, from: u64, to: u64) -> Vec<(u64, ArpSend)> {
        let mut sent = Vec::new();
        let mut t = from;
        while t <= to {
            while let Some(p) = ll.poll(ms(t)) {
                sent.push((t, p));
            }
            t += 10;
        }
        sent
    }

    fn is_link_local(a: Ipv4Addr) -> bool {
        let o = a.octets();
        o[0] == 169 && o[1] == 254 && (1..=254).contains(&o[2])
    }

    #[test]
    fn an_unanswered_claim_probes_three_times_then_announces_twice_within_rfc_timings() {
        let mut ll = LinkLocal::new(MAC);
        ll.start(ms(0));
        let sent = run(&mut ll, 0, 20_000);
        let a = ll.address().expect("claimed");
        assert!(is_link_local(a), "{a}");
        let kinds: Vec<_> = sent.iter().map(|(_, p)| *p).collect();
        assert_eq!(
            kinds,
            [ArpSend::Probe(a), ArpSend::Probe(a), ArpSend::Probe(a), ArpSend::Announce(a), ArpSend::Announce(a)]
        );
        let t: Vec<u64> = sent.iter().map(|(t, _)| *t).collect();
        assert!(t[0] <= 1_000, "first probe within PROBE_WAIT: {t:?}");
        for gap in [t[1] - t[0], t[2] - t[1]] {
            assert!((1_000..=2_010).contains(&gap), "probes PROBE_MIN..PROBE_MAX apart: {t:?}");
        }
        assert!((2_000..=2_010).contains(&(t[3] - t[2])), "ANNOUNCE_WAIT after the last probe: {t:?}");
        assert!((2_000..=2_010).contains(&(t[4] - t[3])), "ANNOUNCE_INTERVAL: {t:?}");
        assert!(t[3] <= 7_010, "claimed within 7 s of the start: {t:?}");
        assert_eq!(ll.poll_at(), None, "nothing more to send unasked");
    }

    #[test]
    fn the_same_mac_picks_the_same_address_and_another_mac_another() {
        let claim = |mac| {
            let mut ll = LinkLocal::new(mac);
            ll.start(ms(0));
            run(&mut ll, 0, 10_000);
            ll.address()
        };
        assert_eq!(claim(MAC), claim(MAC));
        assert_ne!(claim(MAC), claim(OTHER));
    }

    #[test]
    fn a_host_using_the_candidate_or_probing_for_it_makes_the_claim_pick_again() {
        for other_is_probing in [false, true] {
            let mut ll = LinkLocal::new(MAC);
            ll.start(ms(0));
            let first = run(&mut ll, 0, 1_500);
            let ArpSend::Probe(candidate) = first[0].1 else { panic!("{first:?}") };
            let sender_ip = if other_is_probing { Ipv4Addr::UNSPECIFIED } else { candidate };
            ll.on_arp(ms(1_500), &ArpSeen { sender_mac: OTHER, sender_ip, target_ip: candidate });
            assert_eq!(ll.conflicts(), 1);
            run(&mut ll, 1_510, 20_000);
            let claimed = ll.address().expect("claimed after the conflict");
            assert_ne!(claimed, candidate, "probing other={other_is_probing}");
        }
    }

    #[test]
    fn our_own_packets_echoed_back_are_no_conflict() {
        let mut ll = LinkLocal::new(MAC);
        ll.start(ms(0));
        let first = run(&mut ll, 0, 1_500);
        let ArpSend::Probe(candidate) = first[0].1 else { panic!("{first:?}") };
        ll.on_arp(ms(1_500), &ArpSeen { sender_mac: MAC, sender_ip: Ipv4Addr::UNSPECIFIED, target_ip: candidate });
        run(&mut ll, 1_510, 20_000);
        assert_eq!(ll.address(), Some(candidate));
    }

    #[test]
    fn after_ten_conflicts_one_try_a_minute() {
        let mut ll = LinkLocal::new(MAC);
        ll.start(ms(0));
        let mut t = 0;
        for _ in 0..MAX_CONFLICTS {
            let sent = run(&mut ll, t, t + 1_000);
            let ArpSend::Probe(c) = sent[0].1 else { panic!("{sent:?}") };
            t += 1_010;
            ll.on_arp(ms(t), &ArpSeen { sender_mac: OTHER, sender_ip: c, target_ip: c });
        }
        assert_eq!(ll.conflicts(), MAX_CONFLICTS);
        assert!(run(&mut ll, t + 10, t + 59_990).is_empty(), "rate limited");
        assert!(matches!(run(&mut ll, t + 60_000, t + 60_010)[..], [(_, ArpSend::Probe(_))]));
    }

    #[test]
    fn a_claimed_address_is_defended_once_then_given_up_on_a_second_conflict_within_ten_seconds() {
        let mut ll = LinkLocal::new(MAC);
        ll.start(ms(0));
        run(&mut ll, 0, 20_000);
        let a = ll.address().expect("claimed");
        let claim = ArpSeen { sender_mac: OTHER, sender_ip: a, target_ip: a };
        ll.on_arp(ms(30_000), &claim);
        assert_eq!(ll.poll(ms(30_000)), Some(ArpSend::Announce(a)), "defended");
        assert_eq!(ll.poll(ms(30_000)), None);
        ll.on_arp(ms(45_000), &claim);
        assert_eq!(ll.poll(ms(45_000)), Some(ArpSend::Announce(a)), "defended again: 15 s later");
        ll.on_arp(ms(50_000), &claim);
        assert_eq!(ll.address(), None, "given up: a second conflict 5 s after the defence");
        run(&mut ll, 50_000, 70_000);
        assert!(ll.address().is_some_and(|b| b != a));
    }

    #[test]
    fn a_probe_for_our_address_is_answered_and_a_stopped_claim_sends_nothing() {
        let mut ll = LinkLocal::new(MAC);
        ll.start(ms(0));
        run(&mut ll, 0, 20_000);
        let a = ll.address().expect("claimed");
        ll.on_arp(ms(21_000), &ArpSeen { sender_mac: OTHER, sender_ip: Ipv4Addr::UNSPECIFIED, target_ip: a });
        assert_eq!(ll.poll_at(), Some(Instant::ZERO), "due at once");
        assert_eq!(ll.poll(ms(21_000)), Some(ArpSend::Announce(a)));
        assert_eq!(ll.address(), Some(a), "a probe is no conflict");
        ll.stop();
        assert_eq!(ll.address(), None);
        assert!(run(&mut ll, 21_000, 40_000).is_empty());
        assert!(!ll.is_running());
    }
}
