//! A connection thread that panics mid-frame gives its frames back to its
//! service's quota, on the seed ports and on the page, over real TCP: the
//! board's frames come from a ring that panics when a row of one trap
//! light is copied (a stand-in for any defect met mid-frame).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use model::{render_frame, Light, FRAME_BYTES};
use rt_services::camera::sender::SlotSource;
use rt_services::seed::SEED_FRAMES;
use rt_services::web::WEB_FRAMES;
use rt_services::{encode_raw_request, FrameRing, FrameSource, RowEngine, SliceMemory, SoftwareRenderer};
use rt_services_std::board::{Board, Service, BOARD_SLOTS};
use rt_services_std::{Facts, SelfTest, Server};
use tungstenite::{Bytes, Message};

/// The light whose frame panics its connection's thread.
const TRAP: [i32; 3] = [777, 4096, -2048];

/// A frame ring whose `copy_row` panics for a frame of [`TRAP`].
struct Trapped<S> {
    ring: S,
    lights: Arc<Mutex<Vec<(usize, Light)>>>,
}

impl<S: SlotSource> FrameSource for Trapped<S> {
    type Frame = usize;
    type Error = S::Error;

    fn begin(&mut self, light: &Light) -> Result<Option<usize>, S::Error> {
        let frame = self.ring.begin(light)?;
        if let Some(f) = frame {
            let mut lights = self.lights.lock().unwrap_or_else(|e| e.into_inner());
            lights.retain(|(s, _)| *s != f);
            lights.push((f, *light));
        }
        Ok(frame)
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, S::Error> {
        self.ring.rows_ready(frame)
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        let trap = Light::from_raw(TRAP[0], TRAP[1], TRAP[2]).unwrap();
        let lights = self.lights.lock().unwrap_or_else(|e| e.into_inner()).clone();
        if y == 100 && lights.iter().any(|&(s, l)| s == frame && l == trap) {
            panic!("a defect met mid-frame (the test's trap)");
        }
        self.ring.copy_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: usize) {
        self.ring.end(frame)
    }
}

impl<S: SlotSource> SlotSource for Trapped<S> {
    fn set_held(&mut self, mask: u32) {
        self.ring.set_held(mask)
    }
}

fn board() -> Arc<Board> {
    let mem: &'static mut [u8] = Vec::leak(vec![0u8; BOARD_SLOTS * FRAME_BYTES]);
    let ring = FrameRing::<_, _, BOARD_SLOTS>::new(SliceMemory::new(0, mem), RowEngine::new(SoftwareRenderer));
    Board::new(Trapped { ring, lights: Arc::default() }, "software, trapped")
}

fn facts() -> Facts {
    Facts {
        renderer: "software".into(),
        link: "loopback".into(),
        mode: "software".into(),
        version: "test".into(),
        register_map: None,
        fpga_build: None,
        bridges: "none".into(),
        vga: "off".into(),
        address_from: "host".into(),
        self_test: SelfTest { result: "skipped", detail: "test".into() },
    }
}

/// Wait (at most 10 s) until `service` holds no frame.
fn until_none_held(board: &Board, service: Service) {
    let deadline = Instant::now() + Duration::from_secs(10);
    while board.held(service) > 0 {
        assert!(Instant::now() < deadline, "{service:?} still holds {} frames", board.held(service));
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// How long a client waits for the server to end a connection whose
/// thread panicked (its socket must not stay open, held by the reader
/// thread, until the client gives up).
const ENDS_WITHIN: Duration = Duration::from_secs(10);

/// Whether a read error is the client's own timeout, not the server's end.
fn timed_out(e: &std::io::Error) -> bool {
    matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut)
}

/// One frame over the seed port: the whole frame, or what came before
/// the connection ended; a panic if it did not end within [`ENDS_WITHIN`].
fn seed_frame(addr: SocketAddr, raw: [i32; 3]) -> Vec<u8> {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(ENDS_WITHIN)).expect("timeout");
    s.write_all(&encode_raw_request(raw)).expect("request");
    let mut out = Vec::new();
    if let Err(e) = s.read_to_end(&mut out) {
        assert!(!timed_out(&e), "the connection was not ended: {e} after {} bytes", out.len());
    }
    out
}

#[test]
fn a_seed_connection_that_panics_gives_its_frames_back() {
    let board = board();
    let server = Server::start_board("127.0.0.1:0".parse().unwrap(), board.clone(), facts(), false).unwrap();
    let got = seed_frame(server.frame_addr(), TRAP);
    assert!(got.len() < FRAME_BYTES, "the trapped frame came whole");
    until_none_held(&board, Service::Seed);
    // The quota is whole: as many clients at once as it holds each get
    // the model's frame.
    let clients: Vec<_> = (0..SEED_FRAMES as i32)
        .map(|i| {
            let addr = server.frame_addr();
            std::thread::spawn(move || (i, seed_frame(addr, [1024 * i, 4096, -2048])))
        })
        .collect();
    for c in clients {
        let (i, got) = c.join().unwrap();
        let want = render_frame(&Light::from_raw(1024 * i, 4096, -2048).unwrap());
        assert!(got == want, "client {i}: {} bytes, not the model's frame", got.len());
    }
}

#[test]
fn a_web_connection_that_panics_gives_its_frames_back() {
    let board = board();
    let mut server = Server::start_board("127.0.0.1:0".parse().unwrap(), board.clone(), facts(), false).unwrap();
    let web = server.start_web("127.0.0.1:0".parse().unwrap(), false).unwrap();
    let viewer = || {
        let stream = TcpStream::connect(web).expect("connect");
        stream.set_read_timeout(Some(ENDS_WITHIN)).expect("timeout");
        tungstenite::client(format!("ws://{web}/ws"), stream).expect("handshake").0
    };
    let mut trapped = viewer();
    trapped.send(Message::Binary(Bytes::copy_from_slice(&encode_raw_request(TRAP)))).expect("request");
    loop {
        match trapped.read() {
            Ok(Message::Binary(b)) => panic!("the trapped frame came whole ({} bytes)", b.len()),
            Ok(_) => {}
            Err(tungstenite::Error::Io(e)) if timed_out(&e) => panic!("the connection was not ended: {e}"),
            Err(_) => break,
        }
    }
    until_none_held(&board, Service::Web);
    // The page's quota is whole: a viewer per frame it holds, each gets
    // frame after frame.
    let mut viewers: Vec<_> = (0..WEB_FRAMES).map(|_| viewer()).collect();
    for round in 0..3 {
        for (i, ws) in viewers.iter_mut().enumerate() {
            let raw = [512 * (i as i32 + round), 4096, -2048];
            ws.send(Message::Binary(Bytes::copy_from_slice(&encode_raw_request(raw)))).expect("request");
            let got = loop {
                if let Message::Binary(b) = ws.read().expect("a frame") {
                    break b.to_vec();
                }
            };
            assert!(
                got == render_frame(&Light::from_raw(raw[0], raw[1], raw[2]).unwrap()),
                "viewer {i}, round {round}"
            );
        }
    }
}
