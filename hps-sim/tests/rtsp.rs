//! hps-sim's network camera end to end on real sockets: a bare RTSP client
//! (requests written out by hand, as a player would send them) sets up a
//! stream, and the RTP rows it receives make the model's frame; a NACK
//! gets a lost row back; TEARDOWN stops the stream.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use hps_sim::HpsSim;
use model::{Light, FRAME_BYTES, ROW_BYTES};

const ROWS: usize = 360;

struct Rtsp {
    stream: TcpStream,
    reader: BufReader<TcpStream>,
    cseq: u32,
}

impl Rtsp {
    fn connect(addr: SocketAddr) -> Rtsp {
        let stream = TcpStream::connect(addr).unwrap();
        stream.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let reader = BufReader::new(stream.try_clone().unwrap());
        Rtsp { stream, reader, cseq: 0 }
    }

    /// Send a request, return (status, headers, body).
    fn request(
        &mut self,
        method: &str,
        url: &str,
        headers: &[(&str, &str)],
        body: &str,
    ) -> (u16, BTreeMap<String, String>, String) {
        self.cseq += 1;
        let mut req = format!("{method} {url} RTSP/1.0\r\nCSeq: {}\r\n", self.cseq);
        for (k, v) in headers {
            req += &format!("{k}: {v}\r\n");
        }
        if !body.is_empty() {
            req += &format!("Content-Length: {}\r\n", body.len());
        }
        req += "\r\n";
        req += body;
        self.stream.write_all(req.as_bytes()).unwrap();
        let mut line = String::new();
        self.reader.read_line(&mut line).unwrap();
        let status: u16 = line.split(' ').nth(1).unwrap().parse().unwrap();
        let mut headers = BTreeMap::new();
        loop {
            let mut h = String::new();
            self.reader.read_line(&mut h).unwrap();
            let h = h.trim_end();
            if h.is_empty() {
                break;
            }
            let (k, v) = h.split_once(':').unwrap();
            headers.insert(k.trim().to_ascii_lowercase(), v.trim().to_string());
        }
        let len: usize = headers.get("content-length").map_or(0, |v| v.parse().unwrap());
        let mut body = vec![0; len];
        std::io::Read::read_exact(&mut self.reader, &mut body).unwrap();
        assert_eq!(headers.get("cseq").map(String::as_str), Some(self.cseq.to_string().as_str()));
        (status, headers, String::from_utf8(body).unwrap())
    }
}

/// A pair of client UDP sockets on consecutive ports.
fn client_ports() -> (UdpSocket, UdpSocket) {
    for _ in 0..64 {
        let probe = UdpSocket::bind("127.0.0.1:0").unwrap();
        let port = probe.local_addr().unwrap().port() & !1;
        drop(probe);
        if let (Ok(a), Ok(b)) = (UdpSocket::bind(("127.0.0.1", port)), UdpSocket::bind(("127.0.0.1", port + 1))) {
            a.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            return (a, b);
        }
    }
    panic!("no UDP port pair");
}

struct Packet {
    ext_seq: u32,
    timestamp: u32,
    marker: bool,
    line: usize,
    row: Vec<u8>,
}

fn receive(rtp: &UdpSocket, ssrc: Option<u32>) -> Packet {
    let mut buf = [0u8; 2048];
    let n = rtp.recv(&mut buf).expect("an RTP packet");
    assert_eq!(n, 20 + ROW_BYTES);
    assert_eq!(buf[0], 0x80, "V=2, no padding, extension or CSRC");
    assert_eq!(buf[1] & 0x7f, 96);
    if let Some(ssrc) = ssrc {
        assert_eq!(u32::from_be_bytes(buf[8..12].try_into().unwrap()), ssrc);
    }
    assert_eq!(u16::from_be_bytes([buf[14], buf[15]]) as usize, ROW_BYTES, "line length");
    assert_eq!(&buf[18..20], &[0, 0], "C = 0, offset 0");
    Packet {
        ext_seq: u32::from(u16::from_be_bytes([buf[12], buf[13]])) << 16
            | u32::from(u16::from_be_bytes([buf[2], buf[3]])),
        timestamp: u32::from_be_bytes(buf[4..8].try_into().unwrap()),
        marker: buf[1] & 0x80 != 0,
        line: usize::from(u16::from_be_bytes([buf[16], buf[17]]) & 0x7fff),
        row: buf[20..n].to_vec(),
    }
}

struct Stream {
    _sim: HpsSim,
    rtsp: Rtsp,
    rtp: UdpSocket,
    rtcp: UdpSocket,
    session: String,
    ssrc: u32,
    /// The server's RTCP address (`server_port`'s second number).
    server_rtcp: SocketAddr,
    /// RTP-Info's `rtptime`: the timestamp of media time 0.
    rtp_time: u32,
}

fn setup(url: &str) -> Stream {
    let mut sim = HpsSim::start_quiet("127.0.0.1:0".parse().unwrap()).unwrap();
    let addr = sim.start_rtsp("127.0.0.1:0".parse().unwrap(), false).unwrap();
    let mut rtsp = Rtsp::connect(addr);
    let url = format!("rtsp://{addr}{url}");
    let (status, headers, _) = rtsp.request("OPTIONS", &url, &[], "");
    assert_eq!(status, 200);
    assert!(headers["public"].contains("SET_PARAMETER"));
    let (status, headers, sdp) = rtsp.request("DESCRIBE", &url, &[("Accept", "application/sdp")], "");
    assert_eq!(status, 200);
    assert_eq!(headers["content-type"], "application/sdp");
    assert!(sdp.contains("a=rtpmap:96 raw/90000"), "{sdp}");
    assert!(sdp.contains("sampling=RGB; width=480; height=360; depth=8"), "{sdp}");
    assert!(sdp.contains("a=rtcp-fb:96 nack"), "{sdp}");
    let (rtp, rtcp) = client_ports();
    let port = rtp.local_addr().unwrap().port();
    let transport = format!("RTP/AVP;unicast;client_port={}-{}", port, port + 1);
    let (status, headers, _) = rtsp.request("SETUP", &format!("{url}/trackID=0"), &[("Transport", &transport)], "");
    assert_eq!(status, 200);
    let session = headers["session"].split(';').next().unwrap().to_string();
    let transport = &headers["transport"];
    let ports = transport.split("server_port=").nth(1).unwrap().split(';').next().unwrap();
    let (rtp_port, rtcp_port) = ports.split_once('-').unwrap();
    assert_eq!(rtp_port.parse::<u16>().unwrap() + 1, rtcp_port.parse::<u16>().unwrap());
    let server_rtcp = SocketAddr::new(addr.ip(), rtcp_port.parse().unwrap());
    let ssrc = u32::from_str_radix(transport.split("ssrc=").nth(1).unwrap().split(';').next().unwrap(), 16).unwrap();
    let (status, headers, _) = rtsp.request("PLAY", &url, &[("Session", &session)], "");
    assert_eq!(status, 200);
    let rtp_time = headers["rtp-info"].split("rtptime=").nth(1).unwrap().split(';').next().unwrap().parse().unwrap();
    Stream { _sim: sim, rtsp, rtp, rtcp, session, ssrc, server_rtcp, rtp_time }
}

/// A generic NACK (RFC 4585 section 6.2.1) for `seqs`, one FCI entry each.
fn nack(media_ssrc: u32, seqs: &[u32]) -> Vec<u8> {
    let mut d = vec![0x81, 205];
    d.extend_from_slice(&(2 + seqs.len() as u16).to_be_bytes());
    d.extend_from_slice(&0x0bad_cafeu32.to_be_bytes());
    d.extend_from_slice(&media_ssrc.to_be_bytes());
    for &seq in seqs {
        d.extend_from_slice(&(seq as u16).to_be_bytes());
        d.extend_from_slice(&0u16.to_be_bytes());
    }
    d
}

/// A frame being received: its rows, their sequence numbers, whether its
/// marker came.
type Partial = (Vec<Option<Vec<u8>>>, Vec<u32>, bool);

/// A whole frame as a player with loss repair gets it: its rows by
/// timestamp, and once its marker arrived, NACKs for rows still missing
/// (a loaded host's socket buffer overflows now and then). Row `skip` is
/// dropped the first time, to be asked for. Returns the frame's timestamp,
/// its rows, their sequence numbers and how many rows came by repair.
fn whole_frame(s: &Stream, skip: Option<usize>) -> (u32, Vec<Vec<u8>>, Vec<u32>, usize) {
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut frames: BTreeMap<u32, Partial> = BTreeMap::new();
    let mut repaired = 0;
    loop {
        assert!(Instant::now() < deadline, "no whole frame within a minute");
        let p = receive(&s.rtp, Some(s.ssrc));
        let (rows, seqs, marked) =
            frames.entry(p.timestamp).or_insert_with(|| (vec![None; ROWS], vec![0; ROWS], false));
        assert_eq!(p.marker, p.line == ROWS - 1, "marker on the last row only");
        if *marked && rows[p.line].is_none() {
            repaired += 1;
        }
        seqs[p.line] = p.ext_seq;
        if Some(p.line) == skip && !*marked {
            // Dropped on purpose; asked for below.
        } else {
            rows[p.line] = Some(p.row);
        }
        *marked |= p.marker;
        if !*marked {
            continue;
        }
        // A frame's rows are numbered consecutively: any one row's number
        // gives all the others'.
        let (known, &seq) = seqs.iter().enumerate().find(|(y, _)| rows[*y].is_some()).unwrap_or((0, &seqs[0]));
        let missing: Vec<u32> = (0..ROWS)
            .filter(|&y| rows[y].is_none())
            .map(|y| seq.wrapping_sub(known as u32).wrapping_add(y as u32))
            .collect();
        if missing.is_empty() {
            let ts = p.timestamp;
            let (rows, seqs, _) = frames.remove(&ts).unwrap();
            return (ts, rows.into_iter().map(Option::unwrap).collect(), seqs, repaired);
        }
        if p.marker || p.timestamp != *frames.keys().last().unwrap() {
            s.rtcp.send_to(&nack(s.ssrc, &missing), s.server_rtcp).unwrap();
        }
    }
}

#[test]
fn a_fixed_light_stream_is_the_model_s_frame_and_a_nack_brings_a_row_back() {
    let light = Light::from_world(3.0, 4.0, -2.0).unwrap();
    let mut s = setup("/light/3,4,-2?fps=5");
    let (_ts, rows, seqs, repaired) = whole_frame(&s, Some(17));
    assert!(repaired >= 1, "row 17 came back by NACK");
    let seqs_in_order: Vec<u32> = (0..ROWS as u32).map(|i| seqs[0] + i).collect();
    assert_eq!(seqs, seqs_in_order, "one row per packet, consecutive numbers");
    let frame: Vec<u8> = rows.concat();
    assert_eq!(frame.len(), FRAME_BYTES);
    assert!(frame == model::render_frame(&light), "the stream's frame is the model's");
    let url = format!("rtsp://{}/", s.rtsp.stream.peer_addr().unwrap());
    let (status, _, _) = s.rtsp.request("TEARDOWN", &url, &[("Session", &s.session)], "");
    assert_eq!(status, 200);
    // Packets already in flight may still arrive; then the stream stops.
    s.rtp.set_read_timeout(Some(Duration::from_millis(500))).unwrap();
    let mut buf = [0u8; 2048];
    let mut after = 0;
    while s.rtp.recv(&mut buf).is_ok() {
        after += 1;
        assert!(after < 2 * ROWS, "the stream goes on after TEARDOWN");
    }
}

#[test]
fn a_live_stream_follows_set_parameter_and_an_orbit_frame_is_the_light_of_its_timestamp() {
    let mut s = setup("/live?fps=10");
    let moved = Light::from_world(-2.0, 3.0, 1.5).unwrap();
    let url = format!("rtsp://{}/live", s.rtsp.stream.peer_addr().unwrap());
    let session = s.session.clone();
    let headers = [("Session", session.as_str()), ("Content-Type", "text/parameters")];
    let (status, _, _) = s.rtsp.request("SET_PARAMETER", &url, &headers, "light: -2,3,1.5\r\n");
    assert_eq!(status, 200);
    let expected = model::render_frame(&moved);
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        assert!(Instant::now() < deadline, "no frame with the new light");
        let (_, rows, _, _) = whole_frame(&s, None);
        if rows.concat() == expected {
            break;
        }
    }

    // An orbit: the light of each frame is the orbit's at the frame's media
    // time, which its RTP timestamp tells (RTP-Info's rtptime at time 0).
    let spec = rt_services::camera::rtsp::StreamSpec::parse("rtsp://h/orbit?radius=3&height=4&period=2&fps=4").unwrap();
    let s = setup("/orbit?radius=3&height=4&period=2&fps=4");
    let (ts, rows, _, _) = whole_frame(&s, None);
    let (ts2, rows2, _, _) = whole_frame(&s, None);
    let origin = s.rtp_time;
    for (ts, rows) in [(ts, rows), (ts2, rows2)] {
        let t = Duration::from_micros(u64::from(ts.wrapping_sub(origin)) * 100 / 9);
        let light = spec.light_at(t, moved);
        assert!(rows.concat() == model::render_frame(&light), "the orbit's frame at {t:?}");
    }
    assert!(ts2.wrapping_sub(ts) >= 90_000 / 4 - 90, "4 frames a second: {} ticks apart", ts2.wrapping_sub(ts));
}
