//! The board's mDNS responder against queries and responses built, and
//! answers read, with `simple-dns` (an independent DNS codec): probing,
//! conflicts and renaming, simultaneous probes, announcing, answers by
//! multicast and unicast, legacy queries, known-answer suppression, the
//! once-a-second limit, DNS-SD's meta-query, a changed address.

use std::net::{Ipv4Addr, SocketAddrV4};

use rt_services::address::settings::host_name;
use rt_services::mdns::responder::{Destination, NameEvent, Responder, Services, MDNS_PORT};
use rt_services::time::Instant;
use simple_dns::rdata::RData;
use simple_dns::{Name, Packet, PacketFlag, Question, ResourceRecord, CLASS, QTYPE, TYPE};

const BOARD: Ipv4Addr = Ipv4Addr::new(10, 0, 2, 15);
const PEER: SocketAddrV4 = SocketAddrV4::new(Ipv4Addr::new(10, 0, 2, 20), MDNS_PORT);
const SERVICES: Services = Services { http: 80, rtsp: 8554, rtsp_path: "/orbit", seed: 7878 };

fn ms(t: u64) -> Instant {
    Instant::from_millis(t)
}

fn responder() -> Responder {
    Responder::new(&host_name("raytracer").unwrap(), SERVICES, 7)
}

/// Everything sent from `from` to `to` (10 ms steps), parsed.
fn run(r: &mut Responder, from: u64, to: u64) -> Vec<(u64, Destination, Packet<'static>)> {
    let mut out = Vec::new();
    let mut t = from;
    while t <= to {
        let mut buf = [0u8; 1472];
        while let Some((dest, n)) = r.poll(ms(t), &mut buf) {
            // Leaked: a test's few messages, parsed in place for its life.
            let bytes: &'static [u8] = Box::leak(buf[..n].to_vec().into_boxed_slice());
            let packet = Packet::parse(bytes).expect("a well-formed message");
            out.push((t, dest, packet));
        }
        t += 10;
    }
    out
}

/// A claimed responder at 10.0.2.15, at t = 5 s.
fn claimed() -> Responder {
    let mut r = responder();
    r.set_address(ms(0), Some(BOARD));
    run(&mut r, 0, 5_000);
    assert!(r.is_claimed());
    r
}

fn query(id: u16, questions: &[(&str, TYPE, bool)], known: Vec<ResourceRecord<'static>>) -> Vec<u8> {
    let mut q = Packet::new_query(id);
    for (name, t, unicast) in questions {
        q.questions.push(Question::new(
            Name::new_unchecked(name).into_owned(),
            QTYPE::TYPE(*t),
            simple_dns::QCLASS::CLASS(CLASS::IN),
            *unicast,
        ));
    }
    q.answers = known;
    q.build_bytes_vec_compressed().unwrap()
}

fn a_of(p: &Packet<'_>) -> Vec<(String, Ipv4Addr)> {
    p.answers
        .iter()
        .chain(&p.additional_records)
        .filter_map(|r| match &r.rdata {
            RData::A(a) => Some((r.name.to_string(), Ipv4Addr::from(a.address))),
            _ => None,
        })
        .collect()
}

fn names(records: &[ResourceRecord<'_>]) -> Vec<(String, String)> {
    records
        .iter()
        .map(|r| {
            let data = match &r.rdata {
                RData::A(a) => Ipv4Addr::from(a.address).to_string(),
                RData::PTR(p) => p.0.to_string(),
                RData::SRV(s) => format!("{} {}", s.port, s.target),
                RData::TXT(t) => format!("{:?}", t.attributes()),
                other => format!("{other:?}"),
            };
            (r.name.to_string(), data)
        })
        .collect()
}

#[test]
fn it_probes_three_times_then_announces_every_record_twice() {
    let mut r = responder();
    assert!(run(&mut r, 0, 3_000).is_empty(), "silent without an address");
    r.set_address(ms(3_000), Some(BOARD));
    let sent = run(&mut r, 3_000, 8_000);
    assert_eq!(sent.len(), 5, "{:?}", sent.iter().map(|s| s.0).collect::<Vec<_>>());
    for (t, dest, p) in &sent[..3] {
        assert_eq!(*dest, Destination::Multicast);
        assert!(!p.has_flags(PacketFlag::RESPONSE), "a probe is a query ({t})");
        assert_eq!(p.questions[0].qname.to_string(), "raytracer.local");
        assert_eq!(p.questions[0].qtype, QTYPE::ANY);
        let proposed = names(&p.name_servers);
        assert_eq!(proposed, [("raytracer.local".to_string(), BOARD.to_string())], "the proposed record");
    }
    assert!(sent[0].2.questions[0].unicast_response, "the first probe asks for unicast");
    assert!(sent[0].0 - 3_000 <= 250, "the first probe within 250 ms");
    assert_eq!(sent[1].0 - sent[0].0, 250);
    assert_eq!(sent[2].0 - sent[1].0, 250);
    assert_eq!(r.take_event(), Some(NameEvent::Claimed));
    let (t3, t4) = (sent[3].0, sent[4].0);
    assert_eq!(t4 - t3, 1_000, "announcements a second apart");
    for (_, dest, p) in &sent[3..] {
        assert_eq!(*dest, Destination::Multicast);
        assert!(p.has_flags(PacketFlag::RESPONSE) && p.has_flags(PacketFlag::AUTHORITATIVE_ANSWER));
        let all = names(&p.answers);
        assert_eq!(all.len(), 13, "{all:?}");
        for want in [
            ("raytracer.local", "10.0.2.15"),
            ("_services._dns-sd._udp.local", "_http._tcp.local"),
            ("_services._dns-sd._udp.local", "_rtsp._tcp.local"),
            ("_services._dns-sd._udp.local", "_raytracer._tcp.local"),
            ("_http._tcp.local", "raytracer._http._tcp.local"),
            ("raytracer._http._tcp.local", "80 raytracer.local"),
            ("raytracer._rtsp._tcp.local", "8554 raytracer.local"),
            ("raytracer._raytracer._tcp.local", "7878 raytracer.local"),
        ] {
            assert!(all.iter().any(|(n, d)| n == want.0 && d == want.1), "{want:?} in {all:?}");
        }
        let a = p.answers.iter().find(|r| r.rdata.type_code() == TYPE::A).unwrap();
        assert!(a.cache_flush && a.ttl == 120, "a unique record, 120 s");
        let ptr = p.answers.iter().find(|r| r.rdata.type_code() == TYPE::PTR).unwrap();
        assert!(!ptr.cache_flush && ptr.ttl == 4500, "a shared record, 75 minutes");
        let rtsp_txt =
            names(&p.answers).into_iter().find(|(n, d)| n == "raytracer._rtsp._tcp.local" && d.contains("path"));
        assert!(rtsp_txt.is_some_and(|(_, d)| d.contains("/orbit")), "the stream's path");
    }
}

#[test]
fn a_host_already_answering_for_the_name_makes_it_take_the_next() {
    let mut r = responder();
    r.set_address(ms(0), Some(BOARD));
    let first = run(&mut r, 0, 260);
    assert!(!first.is_empty());
    // Another board answers its probe: raytracer.local is 10.0.2.16.
    let mut answer = Packet::new_reply(0);
    answer.set_flags(PacketFlag::AUTHORITATIVE_ANSWER);
    answer.answers.push(ResourceRecord::new(
        Name::new_unchecked("raytracer.local"),
        CLASS::IN,
        120,
        RData::A(Ipv4Addr::new(10, 0, 2, 16).into()),
    ));
    r.receive(ms(300), PEER, &answer.build_bytes_vec().unwrap());
    assert_eq!(r.take_event(), Some(NameEvent::Conflict));
    assert_eq!(r.name(), "raytracer-2");
    let sent = run(&mut r, 300, 5_000);
    assert_eq!(sent[0].2.questions[0].qname.to_string(), "raytracer-2.local", "probing the new name");
    assert!(r.is_claimed());
    let announced = names(&sent.last().unwrap().2.answers);
    assert!(announced.iter().any(|(n, d)| n == "raytracer-2.local" && d == "10.0.2.15"), "{announced:?}");
    assert!(announced.iter().any(|(n, _)| n == "raytracer-2._http._tcp.local"), "the instances follow");
    assert_eq!(r.conflicts, 1);
}

#[test]
fn of_two_simultaneous_probes_the_later_address_wins() {
    for (rival, we_defer) in [(Ipv4Addr::new(10, 0, 2, 200), true), (Ipv4Addr::new(10, 0, 2, 3), false)] {
        let mut r = responder();
        r.set_address(ms(0), Some(BOARD));
        run(&mut r, 0, 260);
        let mut probe = Packet::new_query(0);
        probe.questions.push(Question::new(
            Name::new_unchecked("raytracer.local"),
            QTYPE::ANY,
            simple_dns::QCLASS::CLASS(CLASS::IN),
            false,
        ));
        probe.name_servers.push(ResourceRecord::new(
            Name::new_unchecked("raytracer.local"),
            CLASS::IN,
            120,
            RData::A(rival.into()),
        ));
        r.receive(ms(270), PEER, &probe.build_bytes_vec().unwrap());
        let next = run(&mut r, 270, 1_200);
        if we_defer {
            assert!(next.is_empty(), "the loser waits a second: {:?}", next.iter().map(|s| s.0).collect::<Vec<_>>());
            assert!(!r.is_claimed());
        } else {
            assert!(!next.is_empty() && r.is_claimed(), "the winner goes on");
        }
    }
}

#[test]
fn a_query_is_answered_by_multicast_once_a_second_and_a_qu_query_by_unicast() {
    let mut r = claimed();
    r.receive(ms(6_000), PEER, &query(0, &[("RAYTRACER.local", TYPE::A, false)], vec![]));
    let sent = run(&mut r, 6_000, 6_000);
    assert_eq!(sent.len(), 1, "a unique record: at once");
    assert_eq!(sent[0].1, Destination::Multicast);
    assert_eq!(a_of(&sent[0].2), [("raytracer.local".into(), BOARD)]);
    r.receive(ms(6_500), PEER, &query(0, &[("raytracer.local", TYPE::A, false)], vec![]));
    assert!(run(&mut r, 6_500, 6_900).is_empty(), "multicast at most once a second");
    r.receive(ms(7_100), PEER, &query(0, &[("raytracer.local", TYPE::A, false)], vec![]));
    assert_eq!(run(&mut r, 7_100, 7_100).len(), 1);
    r.receive(ms(7_200), PEER, &query(0, &[("_http._tcp.local", TYPE::PTR, true)], vec![]));
    let sent = run(&mut r, 7_200, 7_200);
    assert_eq!(sent.len(), 1);
    assert_eq!(sent[0].1, Destination::Unicast(PEER), "the QU bit");
    let p = &sent[0].2;
    assert_eq!(names(&p.answers), [("_http._tcp.local".into(), "raytracer._http._tcp.local".into())]);
    let extra = names(&p.additional_records);
    assert!(extra.iter().any(|(n, d)| n == "raytracer._http._tcp.local" && d == "80 raytracer.local"), "{extra:?}");
    assert!(extra.iter().any(|(n, d)| n == "raytracer._http._tcp.local" && d.contains("path")), "{extra:?}");
    assert!(extra.iter().any(|(n, d)| n == "raytracer.local" && d == "10.0.2.15"), "{extra:?}");
}

#[test]
fn a_shared_answer_waits_twenty_to_a_hundred_and_twenty_milliseconds() {
    let mut r = claimed();
    r.receive(ms(6_000), PEER, &query(0, &[("_rtsp._tcp.local", TYPE::PTR, false)], vec![]));
    let sent = run(&mut r, 6_000, 6_500);
    assert_eq!(sent.len(), 1);
    assert!((6_020..=6_120).contains(&sent[0].0), "sent at {}", sent[0].0);
    assert_eq!(names(&sent[0].2.answers), [("_rtsp._tcp.local".into(), "raytracer._rtsp._tcp.local".into())]);
}

#[test]
fn a_legacy_query_gets_its_id_its_question_and_short_ttls() {
    let mut r = claimed();
    let legacy = SocketAddrV4::new(Ipv4Addr::new(10, 0, 2, 20), 40_000);
    r.receive(ms(6_000), legacy, &query(0x4242, &[("raytracer.local", TYPE::A, false)], vec![]));
    let sent = run(&mut r, 6_000, 6_000);
    assert_eq!(sent.len(), 1);
    assert_eq!(sent[0].1, Destination::Unicast(legacy));
    let p = &sent[0].2;
    assert_eq!(p.id(), 0x4242);
    assert_eq!(p.questions.len(), 1);
    assert_eq!(p.questions[0].qname.to_string(), "raytracer.local");
    assert!(p.answers.iter().all(|a| a.ttl <= 10 && !a.cache_flush), "{:?}", p.answers);
}

#[test]
fn known_answers_with_half_their_ttl_left_are_not_repeated() {
    let mut r = claimed();
    let known = |ttl| {
        vec![ResourceRecord::new(
            Name::new_unchecked("_http._tcp.local"),
            CLASS::IN,
            ttl,
            RData::PTR(simple_dns::rdata::PTR(Name::new_unchecked("raytracer._http._tcp.local"))),
        )]
    };
    r.receive(ms(6_000), PEER, &query(0, &[("_http._tcp.local", TYPE::PTR, false)], known(4_000)));
    assert!(run(&mut r, 6_000, 6_500).is_empty(), "the querier knows it");
    r.receive(ms(7_000), PEER, &query(0, &[("_http._tcp.local", TYPE::PTR, false)], known(1_000)));
    assert_eq!(run(&mut r, 7_000, 7_500).len(), 1, "under half the TTL left: answered");
}

#[test]
fn the_meta_query_lists_the_three_service_types() {
    let mut r = claimed();
    r.receive(ms(6_000), PEER, &query(0, &[("_services._dns-sd._udp.local", TYPE::PTR, true)], vec![]));
    let sent = run(&mut r, 6_000, 6_000);
    let mut types: Vec<String> = names(&sent[0].2.answers).into_iter().map(|(_, d)| d).collect();
    types.sort();
    assert_eq!(types, ["_http._tcp.local", "_raytracer._tcp.local", "_rtsp._tcp.local"]);
}

#[test]
fn a_new_address_is_announced_and_another_name_is_not_answered() {
    let mut r = claimed();
    r.receive(ms(6_000), PEER, &query(0, &[("other.local", TYPE::A, false)], vec![]));
    assert!(run(&mut r, 6_000, 7_000).is_empty());
    r.set_address(ms(7_000), Some(Ipv4Addr::new(192, 168, 0, 9)));
    let sent = run(&mut r, 7_000, 9_000);
    assert_eq!(sent.len(), 2, "announced twice");
    assert_eq!(a_of(&sent[0].2), [("raytracer.local".into(), Ipv4Addr::new(192, 168, 0, 9))]);
    assert!(r.is_claimed(), "no new probing for the same name");
}

#[test]
fn after_the_claim_another_host_claiming_the_name_sends_it_back_to_probing() {
    let mut r = claimed();
    let mut answer = Packet::new_reply(0);
    answer.answers.push(ResourceRecord::new(
        Name::new_unchecked("raytracer.local"),
        CLASS::IN,
        120,
        RData::A(Ipv4Addr::new(10, 0, 2, 99).into()),
    ));
    r.receive(ms(6_000), PEER, &answer.build_bytes_vec().unwrap());
    assert!(!r.is_claimed(), "probing again");
    // Its answer to our probe then renames us.
    run(&mut r, 6_000, 6_300);
    r.receive(ms(6_300), PEER, &answer.build_bytes_vec().unwrap());
    assert_eq!(r.name(), "raytracer-2");
    // Our own address in a response is no conflict.
    let mut r = claimed();
    let mut echo = Packet::new_reply(0);
    echo.answers.push(ResourceRecord::new(
        Name::new_unchecked("raytracer.local"),
        CLASS::IN,
        120,
        RData::A(BOARD.into()),
    ));
    r.receive(ms(6_000), PEER, &echo.build_bytes_vec().unwrap());
    assert!(r.is_claimed());
}

/// The link came up again (perhaps on another network): the name is
/// probed three times and announced twice anew (RFC 6762 section 8), and
/// the name may be lost there; without an address, nothing is sent.
#[test]
fn a_link_that_comes_up_again_means_probing_and_announcing_anew() {
    let mut r = claimed();
    r.link_up(ms(6_000));
    assert!(!r.is_claimed(), "probing again");
    let sent = run(&mut r, 6_000, 9_000);
    let probes = sent.iter().filter(|(_, _, p)| !p.has_flags(PacketFlag::RESPONSE)).count();
    let announcements = sent.iter().filter(|(_, _, p)| p.has_flags(PacketFlag::RESPONSE)).count();
    assert_eq!((probes, announcements), (3, 2), "{:?}", sent.iter().map(|s| s.0).collect::<Vec<_>>());
    assert!(r.is_claimed());
    let mut r = responder();
    r.link_up(ms(0));
    assert!(run(&mut r, 0, 3_000).is_empty(), "silent without an address");
}

/// An answer claiming `name` (A 10.0.2.16), as another host would send.
fn claiming(name: &str) -> Vec<u8> {
    let mut answer = Packet::new_reply(0);
    answer.set_flags(PacketFlag::AUTHORITATIVE_ANSWER);
    answer.answers.push(ResourceRecord::new(
        Name::new_unchecked(name),
        CLASS::IN,
        120,
        RData::A(Ipv4Addr::new(10, 0, 2, 16).into()),
    ));
    answer.build_bytes_vec().unwrap()
}

/// A response from a port other than 5353 is not a responder's (RFC 6762
/// section 6: silently ignored): one forged datagram neither renames a
/// probing board nor sends a claimed one back to probing.
#[test]
fn a_response_from_another_port_than_5353_changes_nothing() {
    let forger = SocketAddrV4::new(*PEER.ip(), 40_000);
    let mut r = responder();
    r.set_address(ms(0), Some(BOARD));
    run(&mut r, 0, 260);
    r.receive(ms(300), forger, &claiming("raytracer.local"));
    assert_eq!((r.take_event(), r.name()), (None, "raytracer"));
    run(&mut r, 300, 5_000);
    assert!(r.is_claimed());
    r.receive(ms(5_000), forger, &claiming("raytracer.local"));
    assert!(r.is_claimed(), "still claimed");
    r.receive(ms(5_000), PEER, &claiming("raytracer.local"));
    assert!(!r.is_claimed(), "the same from port 5353 is a conflict");
}

/// A host that answers for every name the board tries: after fifteen
/// conflicts within ten seconds each new probe waits five seconds (RFC
/// 6762 section 8.1), rather than a rename every 250 ms for ever.
#[test]
fn fifteen_conflicts_in_ten_seconds_slow_the_probes_to_one_every_five_seconds() {
    let mut r = responder();
    r.set_address(ms(0), Some(BOARD));
    let mut t = 0;
    let mut gaps = Vec::new();
    for _ in 0..17 {
        // Up to the name's first probe, answered at once.
        let from = t;
        while run(&mut r, t, t).is_empty() {
            t += 10;
            assert!(t - from < 6_000, "no probe");
        }
        gaps.push(t - from);
        t += 10;
        let name = format!("{}.local", r.name());
        r.receive(ms(t), PEER, &claiming(&name));
    }
    assert_eq!(r.conflicts, 17);
    assert!(gaps[1..15].iter().all(|&g| g <= 260), "the first fifteen at once: {gaps:?}");
    assert!(gaps[15..].iter().all(|&g| g >= 5_000), "then five seconds each: {gaps:?}");
}
