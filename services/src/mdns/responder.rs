//! The board's mDNS responder (RFC 6762) with its DNS-SD services (RFC
//! 6763), sans-IO: [`Responder::receive`] takes a datagram received on
//! UDP 5353, [`Responder::poll`] writes the next one to send; the caller
//! owns the socket (smoltcp on the board, `mdns::service`).
//!
//! What it does, by RFC 6762 section:
//!
//! * 8.1 probing: once the board has an address, three queries for
//!   `NAME.local` 250 ms apart (the first after 0-250 ms), the proposed A
//!   record in the authority section; an answer from another host names a
//!   conflict: the name becomes `NAME-2` (then `-3`, ...) and probing
//!   starts again. 8.2 simultaneous probes: the lexicographically later
//!   record wins; the loser waits a second and probes again.
//! * 8.3 announcing: every record twice, a second apart, unique records
//!   with the cache-flush bit (10.2); again whenever the address changes.
//! * 6 answering: A for `NAME.local`, PTR for the three service types and
//!   for `_services._dns-sd._udp.local`, SRV and TXT for each instance,
//!   with the additional records 6763 section 12 lists; 5.4 the QU bit and
//!   6.7 legacy unicast queries (source port not 5353: answered to the
//!   sender with its ID, the question repeated, TTLs at most 10 s)
//!   answered by unicast; 7.1 known-answer suppression; 6 a record
//!   multicast at most once a second, shared-record answers delayed
//!   20-120 ms; 9 a conflicting answer after probing starts probing again.
//!
//! Not done: IPv6 (the board has none), NSEC negative answers (6762 6.1),
//! goodbye packets when the name or address changes (the cache-flush bit
//! replaces the old address at every peer that hears the announcement),
//! duplicate question suppression (7.3), and answering several queries in
//! one aggregated response beyond the next one due.

use core::net::{Ipv4Addr, SocketAddrV4};
use core::time::Duration;

use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};

use super::wire::{
    Data, Entry, Message, Name, Record, Section, Writer, CLASS_IN, FLAG_AUTHORITATIVE, FLAG_RESPONSE, TYPE_A, TYPE_ANY,
    TYPE_PTR, TYPE_SRV, TYPE_TXT,
};
use crate::address::settings::{HostName, HOST_NAME_MAX};
use crate::time::Instant;

/// The mDNS port and group (RFC 6762 section 3).
pub const MDNS_PORT: u16 = 5353;
/// The IPv4 group.
pub const MDNS_GROUP: Ipv4Addr = Ipv4Addr::new(224, 0, 0, 251);

/// TTL of records naming a host (A, SRV): RFC 6762 section 10, 120 s.
pub const HOST_TTL: u32 = 120;
/// TTL of the other records (PTR, TXT): RFC 6762 section 10, 75 minutes.
pub const OTHER_TTL: u32 = 4500;
/// Legacy unicast answers' TTL cap (RFC 6762 section 6.7).
const LEGACY_TTL: u32 = 10;

/// Time between probes (RFC 6762 section 8.1).
const PROBE_INTERVAL: Duration = Duration::from_millis(250);
/// Conflicts within [`CONFLICT_WINDOW`] after which each new probe series
/// waits [`CONFLICT_BACKOFF`] (RFC 6762 section 8.1: fifteen in any ten
/// seconds, then at least five seconds before each further attempt), so a
/// host answering for every name cannot make the board rename in a loop.
const CONFLICT_BURST: usize = 15;
const CONFLICT_WINDOW: Duration = Duration::from_secs(10);
const CONFLICT_BACKOFF: Duration = Duration::from_secs(5);
/// Probes sent.
const PROBES: u8 = 3;
/// Time between announcements (section 8.3).
const ANNOUNCE_INTERVAL: Duration = Duration::from_secs(1);
/// Announcements sent.
const ANNOUNCEMENTS: u8 = 2;
/// A record is multicast at most this often (section 6)...
const MULTICAST_INTERVAL: Duration = Duration::from_secs(1);
/// ...except in answer to a probe (section 6: 250 ms).
const PROBE_ANSWER_INTERVAL: Duration = Duration::from_millis(250);
/// The loser of a simultaneous probe waits this long (section 8.2).
const PROBE_DEFER: Duration = Duration::from_secs(1);

/// The board's services as DNS-SD announces them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Services {
    /// The web page's port (`_http._tcp`, TXT `path=/`).
    pub http: u16,
    /// The camera's RTSP port (`_rtsp._tcp`, TXT `path=` the stream).
    pub rtsp: u16,
    /// The stream the RTSP record names (e.g. `/orbit`).
    pub rtsp_path: &'static str,
    /// The seed protocol's port (`_raytracer._tcp`).
    pub seed: u16,
}

/// The service types, as labels before `local`.
const SERVICE_TYPES: [[&str; 2]; 3] = [["_http", "_tcp"], ["_rtsp", "_tcp"], ["_raytracer", "_tcp"]];
/// The DNS-SD meta-query's name (RFC 6763 section 9).
const META: [&str; 4] = ["_services", "_dns-sd", "_udp", "local"];

/// Records the board answers for: the A record, a `_services` PTR per
/// service type, and per service its PTR, SRV and TXT.
const RECORDS: usize = 1 + 3 + 3 * 3;

/// Record `i`'s kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Address,
    /// `_services._dns-sd._udp.local` PTR to service type `s`.
    Meta(usize),
    /// Service type `s` PTR to its instance.
    Pointer(usize),
    /// Instance `s`'s SRV.
    Srv(usize),
    /// Instance `s`'s TXT.
    Txt(usize),
}

fn kind(i: usize) -> Kind {
    match i {
        0 => Kind::Address,
        1..=3 => Kind::Meta(i - 1),
        _ => {
            let s = (i - 4) / 3;
            match (i - 4) % 3 {
                0 => Kind::Pointer(s),
                1 => Kind::Srv(s),
                _ => Kind::Txt(s),
            }
        }
    }
}

/// A set of records, one bit each.
type Set = u16;

/// Where a datagram goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Destination {
    /// 224.0.0.251:5353.
    Multicast,
    /// One host (a QU or legacy query's sender).
    Unicast(SocketAddrV4),
}

/// What the responder is doing about its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// No address: silent.
    Idle,
    /// `sent` probes so far; the next step at `next`.
    Probing { sent: u8, next: Instant },
    /// The name is ours: `sent` announcements so far, the next at `next`.
    Announcing { sent: u8, next: Instant },
    /// Announced; answering.
    Running,
}

/// A unicast answer owed.
#[derive(Clone, Copy, Debug)]
struct Unicast {
    to: SocketAddrV4,
    /// Legacy (RFC 6762 section 6.7): the query's ID, and the record whose
    /// name and the type that were asked (repeated as the question).
    legacy: Option<(u16, usize, u16)>,
    answers: Set,
    additionals: Set,
}

/// What changed about the name, for the caller's log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NameEvent {
    /// The probes found nobody else: the name is the board's.
    Claimed,
    /// Another host has the name: the board takes the next one.
    Conflict,
}

/// The responder.
#[derive(Debug)]
pub struct Responder {
    base: HostName,
    name: HostName,
    suffix: u32,
    address: Option<Ipv4Addr>,
    services: Services,
    state: State,
    rng: ChaCha8Rng,
    last_multicast: [Option<Instant>; RECORDS],
    /// A multicast answer due at `.1`.
    pending: Option<(Set, Set, Instant)>,
    unicast: heapless::Deque<Unicast, 4>,
    event: Option<NameEvent>,
    /// Conflicts met (renames).
    pub conflicts: u32,
    /// When the last [`CONFLICT_BURST`] conflicts came.
    recent_conflicts: heapless::Deque<Instant, CONFLICT_BURST>,
}

impl Responder {
    /// A responder for `name` (`NAME.local`), silent until it has an
    /// address; `seed` jitters its timings.
    pub fn new(name: &HostName, services: Services, seed: u64) -> Responder {
        Responder {
            base: name.clone(),
            name: name.clone(),
            suffix: 1,
            address: None,
            services,
            state: State::Idle,
            rng: ChaCha8Rng::seed_from_u64(seed),
            last_multicast: [None; RECORDS],
            pending: None,
            unicast: heapless::Deque::new(),
            event: None,
            conflicts: 0,
            recent_conflicts: heapless::Deque::new(),
        }
    }

    /// The name it answers to (without `.local`): the settings' one, or
    /// that with `-N` after a conflict.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether the name is claimed (probing found no other host).
    pub fn is_claimed(&self) -> bool {
        matches!(self.state, State::Announcing { .. } | State::Running)
    }

    /// The last change of the name, once (for the log).
    pub fn take_event(&mut self) -> Option<NameEvent> {
        self.event.take()
    }

    /// The board's address changed: probe (first address) or announce the
    /// new one; `None` silences it.
    pub fn set_address(&mut self, now: Instant, address: Option<Ipv4Addr>) {
        if address == self.address {
            return;
        }
        self.address = address;
        self.pending = None;
        self.unicast.clear();
        self.state = match (address, self.state) {
            (None, _) => State::Idle,
            (Some(_), State::Running | State::Announcing { .. }) => State::Announcing { sent: 0, next: now },
            (Some(_), _) => self.first_probe(now),
        };
    }

    /// The link came up again, perhaps on another network: with an
    /// address, the name is probed and announced again (RFC 6762 section
    /// 8: on a link change a responder must probe and announce anew; the
    /// name may be taken there).
    pub fn link_up(&mut self, now: Instant) {
        if self.address.is_none() {
            return;
        }
        self.pending = None;
        self.unicast.clear();
        self.state = self.first_probe(now);
    }

    fn first_probe(&mut self, now: Instant) -> State {
        let jitter = Duration::from_millis(self.rng.next_u64() % 251);
        State::Probing { sent: 0, next: now + jitter }
    }

    /// When [`poll`](Self::poll) next has something to send.
    pub fn poll_at(&self) -> Option<Instant> {
        if !self.unicast.is_empty() {
            return Some(Instant::ZERO);
        }
        let state = match self.state {
            State::Probing { next, .. } | State::Announcing { next, .. } => Some(next),
            State::Idle | State::Running => None,
        };
        match (state, self.pending.map(|p| p.2)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Write the next datagram due at `now` into `buf`: where it goes and
    /// its length. Call until `None`.
    pub fn poll(&mut self, now: Instant, buf: &mut [u8]) -> Option<(Destination, usize)> {
        let address = self.address?;
        if let Some(u) = self.unicast.pop_front() {
            return self.write_unicast(&u, address, buf).map(|n| (Destination::Unicast(u.to), n));
        }
        match self.state {
            State::Probing { sent, next } if now >= next => {
                if sent < PROBES {
                    self.state = State::Probing { sent: sent + 1, next: now + PROBE_INTERVAL };
                    return self.write_probe(address, sent == 0, buf).map(|n| (Destination::Multicast, n));
                }
                self.state = State::Announcing { sent: 0, next: now };
                self.event = Some(NameEvent::Claimed);
                return self.poll(now, buf);
            }
            State::Announcing { sent, next } if now >= next => {
                let all: Set = (1 << RECORDS) - 1;
                self.state = if sent + 1 < ANNOUNCEMENTS {
                    State::Announcing { sent: sent + 1, next: now + ANNOUNCE_INTERVAL }
                } else {
                    State::Running
                };
                self.pending = None;
                return self.write_multicast(now, all, 0, address, buf);
            }
            _ => {}
        }
        match self.pending {
            Some((answers, additionals, due)) if now >= due => {
                self.pending = None;
                self.write_multicast(now, answers, additionals, address, buf)
            }
            _ => None,
        }
    }

    /// Take a datagram received from `from` on port 5353.
    pub fn receive(&mut self, now: Instant, from: SocketAddrV4, bytes: &[u8]) {
        let Some(address) = self.address else { return };
        if *from.ip() == address {
            return;
        }
        let Ok(msg) = Message::parse(bytes) else { return };
        // RFC 6762 section 6: a response not from port 5353 is silently
        // ignored (nor is a probe, section 8.1, from another port one):
        // one forged datagram from any program must not rename the board.
        let from_responder = from.port() == MDNS_PORT;
        if msg.header.is_response() && !from_responder {
            return;
        }
        if msg.header.is_response() {
            self.response(now, &msg, address);
        } else if self.is_claimed() {
            self.query(now, from, &msg, address);
        } else if matches!(self.state, State::Probing { .. }) && from_responder {
            self.rival_probe(now, &msg, address);
        }
    }

    /// Another host's response: a record for our name with other data is
    /// a conflict (RFC 6762 sections 8.1 and 9).
    fn response(&mut self, now: Instant, msg: &Message<'_>, address: Ipv4Addr) {
        let host = [self.name.as_str(), "local"];
        let conflict = msg.entries().map_while(Result::ok).any(|e| match e {
            Entry::Record(Section::Answer | Section::Additional, r) if msg.name_is(r.name, &host) => {
                r.rtype != TYPE_A || msg.a(&r) != Some(address)
            }
            _ => false,
        });
        if !conflict {
            return;
        }
        match self.state {
            State::Probing { .. } => self.rename(now),
            // Section 9: after probing, a conflict sends the name back to
            // probing (where the other host's answer renames it).
            State::Announcing { .. } | State::Running => self.state = self.first_probe(now),
            State::Idle => {}
        }
    }

    /// Another host probing for our name while we do (section 8.2): the
    /// lexicographically later A record data wins; the loser waits.
    fn rival_probe(&mut self, now: Instant, msg: &Message<'_>, address: Ipv4Addr) {
        let host = [self.name.as_str(), "local"];
        let theirs = msg.entries().map_while(Result::ok).find_map(|e| match e {
            Entry::Record(Section::Authority, r) if msg.name_is(r.name, &host) => Some(r),
            _ => None,
        });
        let Some(theirs) = theirs else { return };
        // Compared as class, type, data (8.2): ours is IN A.
        let ours = (CLASS_IN, TYPE_A, &address.octets()[..]);
        if (theirs.class, theirs.rtype, msg.data(&theirs)) > ours {
            self.state = State::Probing { sent: 0, next: now + PROBE_DEFER };
        }
    }

    fn rename(&mut self, now: Instant) {
        use core::fmt::Write;
        self.conflicts = self.conflicts.saturating_add(1);
        self.suffix = self.suffix.saturating_add(1);
        let mut tail: heapless::String<12> = heapless::String::new();
        let _ = write!(tail, "-{}", self.suffix);
        let keep = self.base.len().min(HOST_NAME_MAX - tail.len());
        let mut name = HostName::new();
        let _ = name.push_str(&self.base[..keep]);
        let _ = name.push_str(&tail);
        self.name = name;
        self.event = Some(NameEvent::Conflict);
        self.state = self.first_probe(now);
        if self.recent_conflicts.is_full() {
            self.recent_conflicts.pop_front();
        }
        let _ = self.recent_conflicts.push_back(now);
        let burst = self.recent_conflicts.front().is_some_and(|&first| now < first + CONFLICT_WINDOW);
        if self.recent_conflicts.is_full() && burst {
            self.state = State::Probing { sent: 0, next: now + CONFLICT_BACKOFF };
        }
    }

    /// A query: answer what it asks for that its known answers do not
    /// already hold.
    fn query(&mut self, now: Instant, from: SocketAddrV4, msg: &Message<'_>, address: Ipv4Addr) {
        let legacy = from.port() != MDNS_PORT;
        let mut answers: Set = 0;
        let mut unicast_asked = legacy;
        let mut is_probe = false;
        let mut legacy_question = None;
        for entry in msg.entries().map_while(Result::ok) {
            match entry {
                Entry::Question(q) if q.class == CLASS_IN || q.class == TYPE_ANY => {
                    for i in 0..RECORDS {
                        let (rtype, _, _) = self.record_meta(i);
                        if (q.qtype == rtype || q.qtype == TYPE_ANY) && self.record_named(msg, q.name, i) {
                            answers |= 1 << i;
                            unicast_asked |= q.unicast;
                            legacy_question.get_or_insert((i, q.qtype));
                        }
                    }
                }
                Entry::Record(Section::Answer, known) => answers &= !self.known(msg, &known, address),
                Entry::Record(Section::Authority, _) => is_probe = true,
                _ => {}
            }
        }
        if answers == 0 {
            return;
        }
        let additionals = self.additionals(answers) & !answers;
        if unicast_asked {
            let legacy = if legacy { legacy_question.map(|(i, t)| (msg.header.id, i, t)) } else { None };
            if self.unicast.is_full() {
                self.unicast.pop_front();
            }
            let _ = self.unicast.push_back(Unicast { to: from, legacy, answers, additionals });
            return;
        }
        // Shared records (PTR) wait 20-120 ms (section 6), unique ones and
        // probe defences go at once.
        let shared = (0..RECORDS).any(|i| answers & (1 << i) != 0 && !self.record_meta(i).2);
        let due = if shared && !is_probe { now + Duration::from_millis(20 + self.rng.next_u64() % 101) } else { now };
        let limit = if is_probe { PROBE_ANSWER_INTERVAL } else { MULTICAST_INTERVAL };
        let fresh = (0..RECORDS).filter(|i| answers & (1 << i) != 0).fold(0, |set: Set, i| {
            let recent = self.last_multicast[i].is_some_and(|t| now.saturating_duration_since(t) < limit);
            if recent {
                set
            } else {
                set | 1 << i
            }
        });
        if fresh == 0 {
            return;
        }
        self.pending = Some(match self.pending {
            Some((a, b, d)) => (a | fresh, (b | additionals) & !(a | fresh), d.min(due)),
            None => (fresh, additionals & !fresh, due),
        });
    }

    /// The records of ours that `known` (a known answer in a query) holds
    /// with at least half our TTL (RFC 6762 section 7.1).
    fn known(&self, msg: &Message<'_>, known: &Record, address: Ipv4Addr) -> Set {
        let mut set = 0;
        for i in 0..RECORDS {
            let (rtype, ttl, _) = self.record_meta(i);
            if known.rtype != rtype || known.ttl < ttl / 2 || !self.record_named(msg, known.name, i) {
                continue;
            }
            let same = match kind(i) {
                Kind::Address => msg.a(known) == Some(address),
                Kind::Meta(s) => msg.name_is(Name::at(known.data.0), &type_name(s)),
                Kind::Pointer(s) => msg.name_is(
                    Name::at(known.data.0),
                    &[self.name.as_str(), SERVICE_TYPES[s][0], SERVICE_TYPES[s][1], "local"],
                ),
                // SRV and TXT are unique records: rarely known answers.
                Kind::Srv(_) | Kind::Txt(_) => false,
            };
            if same {
                set |= 1 << i;
            }
        }
        set
    }

    /// What a response with `answers` carries besides (RFC 6763 section
    /// 12): a PTR's SRV, TXT and address; an SRV's address.
    fn additionals(&self, answers: Set) -> Set {
        let mut set = 0;
        for i in (0..RECORDS).filter(|i| answers & (1 << i) != 0) {
            match kind(i) {
                Kind::Pointer(s) => set |= 1 << (5 + 3 * s) | 1 << (6 + 3 * s) | 1,
                Kind::Srv(_) => set |= 1,
                Kind::Address | Kind::Meta(_) | Kind::Txt(_) => {}
            }
        }
        set
    }

    /// Record `i`'s type, TTL and whether it is unique (cache-flush).
    fn record_meta(&self, i: usize) -> (u16, u32, bool) {
        match kind(i) {
            Kind::Address => (TYPE_A, HOST_TTL, true),
            Kind::Meta(_) | Kind::Pointer(_) => (TYPE_PTR, OTHER_TTL, false),
            Kind::Srv(_) => (TYPE_SRV, HOST_TTL, true),
            Kind::Txt(_) => (TYPE_TXT, OTHER_TTL, true),
        }
    }

    /// Whether the name at `name` in `msg` is record `i`'s name.
    fn record_named(&self, msg: &Message<'_>, name: Name, i: usize) -> bool {
        let n = self.name.as_str();
        match kind(i) {
            Kind::Address => msg.name_is(name, &[n, "local"]),
            Kind::Meta(_) => msg.name_is(name, &META),
            Kind::Pointer(s) => msg.name_is(name, &type_name(s)),
            Kind::Srv(s) | Kind::Txt(s) => msg.name_is(name, &[n, SERVICE_TYPES[s][0], SERVICE_TYPES[s][1], "local"]),
        }
    }

    /// Write record `i` into `w`.
    fn write_record(&self, w: &mut Writer<'_>, section: Section, i: usize, address: Ipv4Addr, ttl_cap: u32) -> bool {
        let n = self.name.as_str();
        let host = [n, "local"];
        let (_, ttl, unique) = self.record_meta(i);
        let ttl = ttl.min(ttl_cap);
        // Legacy answers carry no cache-flush bit (section 6.7).
        let flush = unique && ttl_cap == u32::MAX;
        let r = match kind(i) {
            Kind::Address => w.record(section, &host, ttl, flush, Data::A(address)),
            Kind::Meta(s) => w.record(section, &META, ttl, flush, Data::Ptr(&type_name(s))),
            Kind::Pointer(s) => {
                let instance = [n, SERVICE_TYPES[s][0], SERVICE_TYPES[s][1], "local"];
                w.record(section, &type_name(s), ttl, flush, Data::Ptr(&instance))
            }
            Kind::Srv(s) => {
                let instance = [n, SERVICE_TYPES[s][0], SERVICE_TYPES[s][1], "local"];
                w.record(section, &instance, ttl, flush, Data::Srv(self.port(s), &host))
            }
            Kind::Txt(s) => {
                let instance = [n, SERVICE_TYPES[s][0], SERVICE_TYPES[s][1], "local"];
                let mut path: heapless::String<80> = heapless::String::new();
                let _ = path.push_str("path=");
                let _ = path.push_str(match s {
                    0 => "/",
                    1 => self.services.rtsp_path,
                    _ => "/",
                });
                let strings: &[&str] =
                    if s == 2 { &["protocol=seed", "frame=480x360 RGB888"] } else { &[path.as_str()] };
                w.record(section, &instance, ttl, flush, Data::Txt(strings))
            }
        };
        r.is_ok()
    }

    fn port(&self, s: usize) -> u16 {
        match s {
            0 => self.services.http,
            1 => self.services.rtsp,
            _ => self.services.seed,
        }
    }

    fn write_probe(&self, address: Ipv4Addr, unicast: bool, buf: &mut [u8]) -> Option<usize> {
        let host = [self.name.as_str(), "local"];
        let mut w = Writer::new(buf, 0, 0).ok()?;
        w.question(&host, TYPE_ANY, unicast).ok()?;
        w.record(Section::Authority, &host, HOST_TTL, false, Data::A(address)).ok()?;
        Some(w.len())
    }

    fn write_multicast(
        &mut self,
        now: Instant,
        answers: Set,
        additionals: Set,
        address: Ipv4Addr,
        buf: &mut [u8],
    ) -> Option<(Destination, usize)> {
        let mut w = Writer::new(buf, 0, FLAG_RESPONSE | FLAG_AUTHORITATIVE).ok()?;
        for i in (0..RECORDS).filter(|i| answers & (1 << i) != 0) {
            if self.write_record(&mut w, Section::Answer, i, address, u32::MAX) {
                self.last_multicast[i] = Some(now);
            }
        }
        for i in (0..RECORDS).filter(|i| additionals & (1 << i) != 0) {
            self.write_record(&mut w, Section::Additional, i, address, u32::MAX);
        }
        (!w.is_empty()).then(|| (Destination::Multicast, w.len()))
    }

    fn write_unicast(&self, u: &Unicast, address: Ipv4Addr, buf: &mut [u8]) -> Option<usize> {
        let (id, cap) = match u.legacy {
            Some((id, ..)) => (id, LEGACY_TTL),
            None => (0, u32::MAX),
        };
        let mut w = Writer::new(buf, id, FLAG_RESPONSE | FLAG_AUTHORITATIVE).ok()?;
        if let Some((_, i, qtype)) = u.legacy {
            let n = self.name.as_str();
            let wrote = match kind(i) {
                Kind::Address => w.question(&[n, "local"], qtype, false),
                Kind::Meta(_) => w.question(&META, qtype, false),
                Kind::Pointer(s) => w.question(&type_name(s), qtype, false),
                Kind::Srv(s) | Kind::Txt(s) => {
                    w.question(&[n, SERVICE_TYPES[s][0], SERVICE_TYPES[s][1], "local"], qtype, false)
                }
            };
            wrote.ok()?;
        }
        for i in (0..RECORDS).filter(|i| u.answers & (1 << i) != 0) {
            self.write_record(&mut w, Section::Answer, i, address, cap);
        }
        for i in (0..RECORDS).filter(|i| u.additionals & (1 << i) != 0) {
            self.write_record(&mut w, Section::Additional, i, address, cap);
        }
        Some(w.len())
    }
}

/// Service type `s`'s name.
fn type_name(s: usize) -> [&'static str; 3] {
    [SERVICE_TYPES[s][0], SERVICE_TYPES[s][1], "local"]
}
