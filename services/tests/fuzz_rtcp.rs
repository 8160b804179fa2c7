//! Hostile input for the camera's RTCP and repair path: the RTP sender
//! serving four sessions (unicast and multicast, shared and separate
//! streams) over a frame source that only counts slots, fed random RTCP
//! datagrams (generic NACKs for the right SSRC and the wrong one, receiver
//! reports echoing a sender report, random bytes, mutated compounds) from
//! the clients' addresses and ports and from strangers', ICMP port
//! unreachable, pauses, plays and time. Checked: no panic; a resent packet
//! is byte for byte the packet first sent under its number; a packet goes
//! again to an output at most once per round trip (two resends never
//! within the shortest one); an output's resends stay within its budget (a quarter of
//! what it was sent, plus what it starts with); a stranger's datagram makes
//! nothing go; every stream holds two slots at most.
//!
//! `cargo test -p rt-services --test fuzz_rtcp` runs proptest's default 256
//! cases; `cargo xtask fuzz` runs a million (release build).

mod common;

use common::Slots;
use std::collections::HashMap;

use std::net::{IpAddr, Ipv4Addr, SocketAddr};

use model::Light;
use proptest::prelude::*;
use rt_services::camera::packetiser::Packetiser;
use rt_services::camera::rtsp::{
    Client, ConnId, EndReason, Fps, Fresh, LightSource as Kind, Profile, SessionId, StreamSpec, Streams, Transport,
};
use rt_services::camera::sender::{
    self, Bound, Camera, Dest, Multicast, RtpSink, CAMERA_SLOTS, MIN_ROUND_TRIP, REPAIR_BURST, REPAIR_SHARE,
    SLOTS_PER_STREAM,
};
use rt_services::camera::wire::rtcp::{ntp_timestamp, sender_report_lsr, write_receiver_report, SenderReport};
use rt_services::camera::wire::rtp::{RowPacket, HEADER_BYTES};
use rt_services::{FrameSource, Instant};

const CLIENTS: [IpAddr; 2] = [IpAddr::V4(Ipv4Addr::new(10, 0, 0, 1)), IpAddr::V4(Ipv4Addr::new(10, 0, 0, 2))];
const STRANGER: IpAddr = IpAddr::V4(Ipv4Addr::new(10, 0, 0, 66));

/// Packets remembered per output (more than a repair window's worth).
const KEPT: usize = 4096;

/// What went to one destination: each packet's header by sequence number
/// (the last [`KEPT`]), when it last went again, the counts.
struct Out {
    dest: Dest,
    first: Vec<Option<(u32, [u8; HEADER_BYTES])>>,
    last_resend: Vec<Option<(u32, u64)>>,
    sent: u64,
    resent: u64,
}

/// What went out, and what was wrong with it.
#[derive(Default)]
struct Wire {
    now: u64,
    outs: Vec<Out>,
    too_soon: Vec<(Dest, u32, u64)>,
    differs: Vec<(Dest, u32)>,
    lsr: HashMap<u32, u32>,
    /// Packets sent since the last check (a stranger's datagram must make none).
    fresh: u64,
    /// The newest sequence number sent.
    newest: u32,
}

impl Wire {
    fn out(&mut self, dest: Dest) -> &mut Out {
        let i = match self.outs.iter().position(|o| o.dest == dest) {
            Some(i) => i,
            None => {
                self.outs.push(Out {
                    dest,
                    first: vec![None; KEPT],
                    last_resend: vec![None; KEPT],
                    sent: 0,
                    resent: 0,
                });
                self.outs.len() - 1
            }
        };
        &mut self.outs[i]
    }
}

impl RtpSink for Wire {
    fn send_rows<S: FrameSource<Frame = usize>>(
        &mut self,
        to: &Dest,
        p: &Packetiser,
        first: &RowPacket,
        count: u16,
        _: usize,
        _: &mut S,
    ) -> u16 {
        let now = self.now;
        for k in 0..count {
            let packet = first.nth(k);
            let mut h = [0u8; HEADER_BYTES];
            p.emit(&packet, &mut h).expect("20 bytes");
            self.fresh += 1;
            if packet.seq.wrapping_sub(self.newest) < 1 << 31 {
                self.newest = packet.seq;
            }
            let at = packet.seq as usize % KEPT;
            let mut problem = None;
            let o = self.out(*to);
            match o.first[at] {
                Some((seq, original)) if seq == packet.seq => {
                    if original != h {
                        problem = Some(Err(packet.seq));
                    }
                    if let Some((seq, t)) = o.last_resend[at] {
                        if seq == packet.seq && now - t < MIN_ROUND_TRIP.as_millis() as u64 {
                            problem = Some(Ok((packet.seq, now - t)));
                        }
                    }
                    o.last_resend[at] = Some((packet.seq, now));
                    o.resent += 1;
                }
                _ => {
                    o.first[at] = Some((packet.seq, h));
                    o.sent += 1;
                }
            }
            match problem {
                Some(Err(seq)) => self.differs.push((*to, seq)),
                Some(Ok((seq, gap))) => self.too_soon.push((*to, seq, gap)),
                None => {}
            }
        }
        count
    }
    fn send_rtcp(&mut self, _: &Dest, datagram: &[u8]) -> bool {
        if datagram.len() >= 8 {
            let ssrc = u32::from_be_bytes([datagram[4], datagram[5], datagram[6], datagram[7]]);
            if let Some(lsr) = sender_report_lsr(datagram, ssrc) {
                self.lsr.insert(ssrc, lsr);
            }
        }
        true
    }
}

#[derive(Clone, Debug)]
enum Event {
    /// Time passes (ms).
    Wait(u64),
    /// The sender is polled.
    Poll(u8),
    /// A NACK from client `.0`'s port `.1` for the stream of session `.2`
    /// (or a wrong SSRC), entries (offset back from the newest, BLP).
    Nack(usize, u16, usize, bool, Vec<(u16, u16)>),
    /// A receiver report from client `.0` echoing the sender report, `.2` ms later.
    Report(usize, u16, usize, u32),
    /// Random bytes from client `.0` or a stranger.
    Junk(Option<usize>, u16, Vec<u8>),
    /// A NACK from a stranger.
    StrangerNack(usize, Vec<(u16, u16)>),
    /// ICMP port unreachable about client `.0`'s port, quoting the SSRC of
    /// session `.2`'s stream (4: an SSRC of none).
    Unreachable(usize, u16, usize),
    /// Session `.0` pauses or plays.
    Toggle(usize),
}

fn entries() -> impl Strategy<Value = Vec<(u16, u16)>> {
    prop::collection::vec((0u16..1_200, any::<u16>()), 0..40)
}

fn event() -> impl Strategy<Value = Event> {
    let port = prop_oneof![Just(6001u16), Just(7001u16), any::<u16>()];
    prop_oneof![
        3 => (0u64..120).prop_map(Event::Wait),
        4 => (1u8..4).prop_map(Event::Poll),
        6 => (0usize..2, port.clone(), 0usize..4, prop::bool::weighted(0.9), entries())
            .prop_map(|(c, p, s, right, e)| Event::Nack(c, p, s, right, e)),
        1 => (0usize..2, port.clone(), 0usize..4, 0u32..200_000).prop_map(|(c, p, s, d)| Event::Report(c, p, s, d)),
        1 => (prop::option::of(0usize..2), port.clone(), prop::collection::vec(any::<u8>(), 0..120))
            .prop_map(|(c, p, j)| Event::Junk(c, p, j)),
        2 => (0usize..4, entries()).prop_map(|(s, e)| Event::StrangerNack(s, e)),
        1 => (0usize..2, port, 0usize..5).prop_map(|(c, p, s)| Event::Unreachable(c, p, s)),
        1 => (0usize..4).prop_map(Event::Toggle),
    ]
}

fn nack(sender: u32, media: u32, newest: u32, entries: &[(u16, u16)]) -> Vec<u8> {
    let mut d = vec![0x81, 205];
    d.extend_from_slice(&(2 + entries.len() as u16).to_be_bytes());
    d.extend_from_slice(&sender.to_be_bytes());
    d.extend_from_slice(&media.to_be_bytes());
    for &(back, blp) in entries {
        d.extend_from_slice(&(newest.wrapping_sub(u32::from(back)) as u16).to_be_bytes());
        d.extend_from_slice(&blp.to_be_bytes());
    }
    d
}

fn run(events: &[Event]) -> Result<(), TestCaseError> {
    let mut camera: Box<Camera> = Box::new(Camera::new());
    let light = Light::from_world(3.0, 4.0, -2.0).unwrap();
    let multicast = Some(Multicast { group: Ipv4Addr::new(239, 255, 42, 1), base_port: 5006, ttl: 1 });
    camera.configure(sender::Config {
        live_light: light,
        multicast,
        cname: sender::Cname::for_address(std::net::Ipv4Addr::new(10, 0, 0, 9)),
    });
    let mut source = Slots::default();
    let mut wire = Wire::default();
    // Sessions: two of one stream from client 0 (UDP ports 6000, 7000),
    // one multicast from client 1, one of another stream from client 1.
    // Paced, so that time (not the number of polls) makes frames.
    let fixed = StreamSpec { light: Kind::Light(light), fps: Fps::Rate(30), multicast: false };
    let other = StreamSpec { light: Kind::Light(light), fps: Fps::Rate(20), multicast: false };
    let setups = [
        (fixed, Transport::Udp { rtp_port: 6000, rtcp_port: 6001 }, 0),
        (fixed, Transport::Udp { rtp_port: 7000, rtcp_port: 7001 }, 0),
        (fixed, Transport::Multicast, 1),
        (other, Transport::Udp { rtp_port: 6000, rtcp_port: 6001 }, 1),
    ];
    let mut playing = [true; 4];
    {
        let mut b = Bound { camera: &mut camera, source: &mut source, now: Instant::from_millis(0), wall: 0 };
        for (i, (spec, transport, c)) in setups.iter().enumerate() {
            let client = Client { addr: CLIENTS[*c], conn: ConnId(i as u32) };
            let fresh = Fresh { ssrc: 0x1000 + i as u32, seq: 60_000, rtptime: 7 };
            b.setup(SessionId(i as u64 + 1), spec, *transport, Profile::Avpf, client, fresh).expect("room");
            b.play(SessionId(i as u64 + 1)).expect("plays");
        }
    }
    let mut ended = Vec::new();
    for e in events {
        let now = Instant::from_millis(wire.now);
        let wall = ntp_timestamp(std::time::Duration::from_millis(wire.now));
        match e {
            Event::Wait(ms) => wire.now += ms,
            Event::Poll(n) => {
                for _ in 0..*n {
                    camera.poll(now, wall, &mut source, &mut wire);
                }
            }
            Event::Nack(c, port, s, right, es) => {
                let ssrc = camera.ssrc(SessionId(*s as u64 + 1)).unwrap_or(0);
                let media = if *right { ssrc } else { ssrc ^ 0x5a5a };
                let d = nack(9, media, wire.newest, es);
                camera.rtcp_received(SocketAddr::new(CLIENTS[*c], *port), &d, now, wall, &mut source, &mut wire);
            }
            Event::Report(c, port, s, delay) => {
                let ssrc = camera.ssrc(SessionId(*s as u64 + 1)).unwrap_or(0);
                let lsr = wire.lsr.get(&ssrc).copied().unwrap_or(0);
                let mut rr = [0u8; 32];
                write_receiver_report(9, ssrc, lsr, *delay, &mut rr).expect("32 bytes");
                camera.rtcp_received(SocketAddr::new(CLIENTS[*c], *port), &rr, now, wall, &mut source, &mut wire);
            }
            Event::Junk(c, port, bytes) => {
                let from = c.map_or(STRANGER, |c| CLIENTS[c]);
                camera.rtcp_received(SocketAddr::new(from, *port), bytes, now, wall, &mut source, &mut wire);
            }
            Event::StrangerNack(s, es) => {
                let ssrc = camera.ssrc(SessionId(*s as u64 + 1)).unwrap_or(0);
                let mut d = nack(9, ssrc, wire.newest, es);
                let sr = SenderReport { ssrc: 9, ntp_timestamp: 0, rtp_timestamp: 0, packet_count: 0, octet_count: 0 };
                let mut compound = [0u8; 28];
                sr.write(&mut compound).expect("28 bytes");
                d.splice(0..0, compound);
                wire.fresh = 0;
                camera.rtcp_received(SocketAddr::new(STRANGER, 6001), &d, now, wall, &mut source, &mut wire);
                prop_assert_eq!(wire.fresh, 0, "a stranger's NACK made packets go");
            }
            Event::Unreachable(c, port, s) => {
                let ssrc = camera.ssrc(SessionId(*s as u64 + 1)).unwrap_or(0xdead_beef);
                camera.unreachable(CLIENTS[*c], *port, ssrc, now, &mut source)
            }
            Event::Toggle(s) => {
                let id = SessionId(*s as u64 + 1);
                let mut b = Bound { camera: &mut camera, source: &mut source, now, wall };
                if playing[*s] {
                    b.pause(id);
                } else {
                    let _ = b.play(id);
                }
                playing[*s] = !playing[*s];
            }
        }
        while let Some((s, _)) = camera.take_ended() {
            ended.push(s);
        }
        prop_assert!(wire.differs.is_empty(), "a resent packet differs: {:?}", wire.differs);
        prop_assert!(wire.too_soon.is_empty(), "resent within the shortest round trip: {:?}", wire.too_soon);
        for o in &wire.outs {
            // An output of several sessions (the group) has one budget; a
            // UDP output's repairs go to its destination only.
            let allowed = o.sent / u64::from(REPAIR_SHARE) + u64::from(REPAIR_BURST) / 2 + 1;
            prop_assert!(o.resent <= allowed, "{:?}: {} resent for {} sent", o.dest, o.resent, o.sent);
        }
        let held = source.held.count_ones() as usize;
        prop_assert!(
            held <= SLOTS_PER_STREAM * camera.streams().max(1),
            "{} slots held by {} streams",
            held,
            camera.streams()
        );
        prop_assert!(held <= CAMERA_SLOTS);
    }
    // The sessions the sender ended itself were its own; the rest end now.
    let mut b = Bound { camera: &mut camera, source: &mut source, now: Instant::from_millis(wire.now), wall: 0 };
    for s in 1..=4u64 {
        if !ended.contains(&SessionId(s)) {
            b.end(SessionId(s), EndReason::Teardown);
        }
    }
    prop_assert_eq!((camera.streams(), camera.outputs()), (0, 0));
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn the_repair_path_survives_hostile_rtcp(events in prop::collection::vec(event(), 0..60)) {
        run(&events)?;
    }
}
