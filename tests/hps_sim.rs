//! The simulated board over real TCP, driven with raw `TcpStream`s: the seed
//! protocol byte for byte, the persistent port, and every bad-input case.

use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::thread;
use std::time::{Duration, Instant};

use hps_sim::{HpsSim, RenderMode};
use model::{render_frame, Light, FRAME_BYTES};
use rt_services::{encode_raw_request, encode_request};

fn sim() -> HpsSim {
    HpsSim::start("127.0.0.1:0".parse().expect("address")).expect("hps-sim starts")
}

/// The simulated board in both modes: frame DMA into memory, and rows.
fn sims() -> [(RenderMode, HpsSim); 2] {
    [RenderMode::Frames, RenderMode::Rows]
        .map(|m| (m, HpsSim::start_with("127.0.0.1:0".parse().expect("address"), m, false).expect("hps-sim starts")))
}

fn light(x: f64, y: f64, z: f64) -> Light {
    Light::from_world(x, y, z).expect("in range")
}

fn model_frame(l: &Light) -> Vec<u8> {
    render_frame(l)
}

fn connect(addr: SocketAddr) -> TcpStream {
    let s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(30))).expect("timeout");
    s
}

/// Everything the server sends until it closes.
fn read_all(mut s: TcpStream) -> Vec<u8> {
    let mut out = Vec::new();
    s.read_to_end(&mut out).expect("read until the server closes");
    out
}

fn raw_request(x: i32, y: i32, z: i32) -> [u8; 12] {
    encode_raw_request([x, y, z])
}

#[test]
fn seed_port_is_byte_exact_for_several_lights() {
    for (mode, sim) in sims() {
        for l in [light(3.0, 4.0, -2.0), light(-2.5, 1.5, 1.5), light(1500.0, 2000.0, -1000.0)] {
            let mut s = connect(sim.frame_addr());
            s.write_all(&encode_request(&l)).expect("send request");
            let got = read_all(s);
            assert_eq!(got.len(), 518_400, "12 bytes in, 518,400 out, then EOF");
            assert!(got == model_frame(&l), "frame equals the model for {l:?} ({mode:?})");
        }
    }
}

#[test]
fn seed_port_takes_the_request_in_pieces() {
    for (_mode, sim) in sims() {
        let l = light(0.0, 3.0, 3.0);
        let mut s = connect(sim.frame_addr());
        for piece in encode_request(&l).chunks(5) {
            s.write_all(piece).expect("send");
            thread::sleep(Duration::from_millis(20));
        }
        assert!(read_all(s) == model_frame(&l));
    }
}

#[test]
fn persistent_port_answers_pipelined_requests_in_order() {
    for (mode, sim) in sims() {
        let lights = [light(3.0, 3.0, 0.0), light(0.0, 3.0, 3.0), light(-3.0, 3.0, 0.0)];
        let mut s = connect(sim.persistent_addr());
        for l in &lights {
            s.write_all(&encode_request(l)).expect("send");
        }
        s.shutdown(Shutdown::Write).expect("half close");
        let got = read_all(s);
        assert_eq!(got.len(), 3 * FRAME_BYTES);
        for (i, l) in lights.iter().enumerate() {
            assert!(got[i * FRAME_BYTES..(i + 1) * FRAME_BYTES] == model_frame(l)[..], "frame {i} ({mode:?})");
        }
    }
}

#[test]
fn out_of_range_light_gets_no_frame_and_the_next_client_is_served() {
    for (_mode, sim) in sims() {
        for bad in [raw_request(1 << 23, 0, 0), raw_request(0, -(1 << 23) - 1, 0), raw_request(0, 0, i32::MAX)] {
            for addr in [sim.frame_addr(), sim.persistent_addr()] {
                let mut s = connect(addr);
                s.write_all(&bad).expect("send");
                assert!(read_all(s).is_empty(), "zero frame bytes, then close");
            }
        }
        // The edges of the range are valid.
        let edge = raw_request(-(1 << 23), (1 << 23) - 1, 0);
        let mut s = connect(sim.frame_addr());
        s.write_all(&edge).expect("send");
        assert_eq!(read_all(s).len(), FRAME_BYTES);
    }
}

#[test]
fn request_cut_short_by_eof_is_dropped() {
    let sim = sim();
    for addr in [sim.frame_addr(), sim.persistent_addr()] {
        let mut s = connect(addr);
        s.write_all(&[0, 0, 12, 0, 0]).expect("send");
        s.shutdown(Shutdown::Write).expect("half close");
        assert!(read_all(s).is_empty());
    }
}

#[test]
fn idle_half_sent_request_is_dropped_after_five_seconds() {
    let sim = sim();
    let mut s = connect(sim.frame_addr());
    s.write_all(&[0, 0, 12]).expect("send");
    let sent = Instant::now();
    let got = read_all(s);
    let waited = sent.elapsed();
    assert!(got.is_empty());
    // The server's bound is 5 s from the last byte; it must not drop sooner.
    assert!(waited >= Duration::from_millis(4_900), "dropped after {waited:?}");
}

#[test]
fn client_vanishing_mid_frame_does_not_disturb_the_next() {
    for (_mode, sim) in sims() {
        let l = light(3.0, 4.0, -2.0);
        let mut quitter = connect(sim.frame_addr());
        quitter.write_all(&encode_request(&l)).expect("send");
        let mut some = vec![0u8; 50_000];
        quitter.read_exact(&mut some).expect("first rows");
        drop(quitter);
        let mut next = connect(sim.frame_addr());
        next.write_all(&encode_request(&l)).expect("send");
        assert!(read_all(next) == model_frame(&l));
    }
}

#[test]
fn two_clients_at_once_are_both_served() {
    for (_mode, sim) in sims() {
        let (a, b) = (light(2.0, 3.0, -1.0), light(-2.0, 3.0, -1.0));
        // Both connect and ask before either reads.
        let mut sa = connect(sim.frame_addr());
        let mut sb = connect(sim.persistent_addr());
        sa.write_all(&encode_request(&a)).expect("send a");
        sb.write_all(&encode_request(&b)).expect("send b");
        sb.shutdown(Shutdown::Write).expect("half close b");
        let ta = thread::spawn(move || read_all(sa));
        let tb = thread::spawn(move || read_all(sb));
        assert!(ta.join().expect("client a") == model_frame(&a));
        assert!(tb.join().expect("client b") == model_frame(&b));
    }
}

#[test]
fn two_hundred_clients_at_once_are_each_served_or_refused_and_the_next_is_served() {
    let sim = sim();
    let lights = [light(3.0, 4.0, -2.0), light(-4.0, 6.0, -3.0), light(0.5, 0.2, -1.0)];
    let want: Vec<Vec<u8>> = lights.iter().map(model_frame).collect();
    let addr = sim.frame_addr();
    let clients: Vec<_> = (0..200)
        .map(|i| {
            let l = lights[i % 3];
            thread::spawn(move || -> Option<Vec<u8>> {
                let mut s = TcpStream::connect(addr).ok()?;
                s.set_read_timeout(Some(Duration::from_secs(120))).ok()?;
                let _ = s.write_all(&encode_request(&l));
                let mut got = Vec::new();
                let _ = s.read_to_end(&mut got);
                Some(got)
            })
        })
        .collect();
    let (mut served, mut refused) = (0, 0);
    for (i, c) in clients.into_iter().enumerate() {
        match c.join().expect("client thread") {
            Some(got) if got.is_empty() => refused += 1,
            Some(got) => {
                assert!(got == want[i % 3], "client {i}: {} bytes, not its whole frame", got.len());
                served += 1;
            }
            None => refused += 1,
        }
    }
    println!("hps-sim: 200 clients at once: {served} served byte-exact, {refused} refused");
    assert_eq!(served + refused, 200);
    assert!(served > 0);
    // The very next client is served.
    let mut s = connect(addr);
    s.write_all(&encode_request(&lights[0])).expect("request");
    assert!(read_all(s) == want[0]);
}
