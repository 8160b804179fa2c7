//! Accelerator faults in the middle of a frame, with the firmware's frame
//! path composed as on the board (firmware/src/render.rs): the frame ring
//! over a fallback engine whose primary is the driver (simulated
//! accelerator, frame DMA into shared memory) behind the stall watchdog, and
//! whose fallback is the software renderer. Two persistent clients are
//! served at once; a fault strikes while the first client's frame renders.
//!
//! Checked: the affected client gets its frames byte-exact up to the fault
//! and then a clean close (a cut frame, never wrong bytes); the other client
//! keeps getting byte-exact frames; the failed frame is aborted, and a
//! device that cannot confirm it stopped (stuck, vanished) is switched off
//! at once with its frame's slot kept out of use until an abort succeeds;
//! the software renderer serves on.

use std::cell::Cell;
use std::rc::Rc;
use std::time::Duration;

use hal_avalon::sim::{CountingDelay, Fault, SimAccelerator};
use hal_avalon::{Accelerator, PollTimeout};
use hps_sim::FRAME_SLOTS;
use model::{render_frame, Light, FRAME_BYTES, ROW_BYTES};
use rt_services::frames::fallback::WEDGED_AFTER;
use rt_services::seed::server::{drive, Action, Mode, Session};
use rt_services::{FallbackEngine, FrameRing, FrameSource, Instant, RowEngine, SoftwareRenderer, Watchdog};
use rt_services_std::SharedMemory;

type Clock = Rc<Cell<u64>>;

fn light(i: usize) -> Light {
    let l = [(3.0, 4.0, -2.0), (-4.0, 6.0, -3.0), (0.5, 5.0, -1.0), (2.0, 1.0, -2.5)][i % 4];
    Light::from_world(l.0, l.1, l.2).expect("in range")
}

/// One client: its session and what it received.
struct Client {
    session: Session<usize>,
    input: Vec<u8>,
    received: Vec<u8>,
    closed: Option<String>,
}

/// The clients, whether the accelerator was switched off, and the slots
/// left quarantined (a failed frame the device could not confirm stopped).
fn run(fault: Fault, fault_at_row: u16) -> (Vec<Client>, bool, usize) {
    let mem = SharedMemory::new(FRAME_SLOTS);
    let mut sim = SimAccelerator::with_memory(mem.clone(), 1);
    sim.set_frame_rows_per_poll(2);
    let accel = Accelerator::new(sim, CountingDelay::default(), PollTimeout::DEFAULT);
    let now: Clock = Rc::new(Cell::new(0));
    let clock = {
        let now = now.clone();
        move || Instant::from_millis(now.get())
    };
    let engine = FallbackEngine::new(
        Some(Watchdog::new(accel, clock, Duration::from_millis(500))),
        RowEngine::new(SoftwareRenderer),
    );
    let mut ring = FrameRing::<_, _, FRAME_SLOTS>::new(mem, engine);
    // Client 0 asks for 6 frames, client 1 for 8.
    let mut clients: Vec<Client> = [6usize, 8]
        .iter()
        .enumerate()
        .map(|(c, &n)| {
            let session = Session::new(Mode::Persistent, Instant::from_millis(0));
            let input: Vec<u8> = (0..n).flat_map(|i| rt_services::encode_request(&light(i + c))).collect();
            Client { session, input, received: Vec::new(), closed: None }
        })
        .collect();
    let mut faulted = false;
    for _ in 0..2_000_000 {
        now.set(now.get() + 1);
        // The fault strikes once, while the first frame (client 0's, in
        // slot 0) is being rendered.
        if !faulted && ring.rows_ready(0).is_ok_and(|rows| (fault_at_row..300).contains(&rows)) {
            if let Some(w) = ring.engine().primary() {
                w.engine().port_mut().set_fault(Some(fault));
            }
            faulted = true;
        }
        for c in clients.iter_mut().filter(|c| c.closed.is_none()) {
            // Requests as the session takes them (it queues a few), then EOF.
            if !c.input.is_empty() && c.session.wants_requests() {
                let n = c.session.receive(Instant::from_millis(now.get()), &c.input);
                c.input.drain(..n);
                if c.input.is_empty() {
                    c.session.receive_eof();
                }
            }
            // The transport takes one row per pass, like a socket whose
            // buffer drains at the wire's pace.
            let mut budget = ROW_BYTES;
            let action = drive(
                &mut c.session,
                Instant::from_millis(now.get()),
                &mut ring,
                |fill| {
                    let mut buf = [0u8; ROW_BYTES];
                    let n = fill(&mut buf[..budget]);
                    budget -= n;
                    c.received.extend_from_slice(&buf[..n]);
                    n
                },
                &mut String::new(),
            );
            if let Action::Close(reason) = action {
                c.closed = Some(reason.to_string());
            }
        }
        if clients.iter().all(|c| c.closed.is_some()) {
            break;
        }
    }
    let switched_off = !ring.engine().primary_active();
    // A frame abandoned while rendering is given back once the engine is
    // done with it (or has failed it): let time pass and the ring pump.
    for _ in 0..10_000 {
        now.set(now.get() + 1);
        let _ = ring.rows_ready(0);
    }
    let quarantined = ring.quarantined_slots();
    assert_eq!(ring.free_slots() + quarantined, FRAME_SLOTS, "every slot given back or quarantined");
    if quarantined > 0 {
        // Once the device answers again, an abort succeeds and the slot
        // returns when one is wanted.
        if let Some(w) = ring.engine().primary().map(|w| w.engine()) {
            w.port_mut().set_fault(None);
        }
    }
    (clients, switched_off, quarantined)
}

/// The client got whole frames equal to the model's for its requests,
/// then possibly part of one (never a wrong byte).
fn check_prefix(c: &Client, first_light: usize) -> usize {
    for (k, chunk) in c.received.chunks(FRAME_BYTES).enumerate() {
        let want = render_frame(&light(first_light + k));
        assert!(chunk == &want[..chunk.len()], "frame {k} has wrong bytes");
    }
    c.received.len() / FRAME_BYTES
}

#[test]
fn faults_mid_frame_close_the_affected_client_and_the_rest_goes_on() {
    // A stuck device and a vanished one (every read all ones): the frame
    // under way fails, the device is switched off, software serves on.
    for fault in [Fault::StuckBusy, Fault::Absent] {
        let (clients, switched_off, quarantined) = run(fault, 40);
        assert_eq!(quarantined, 1, "{fault:?}: the failed frame's slot stays out of use");
        let whole0 = check_prefix(&clients[0], 0);
        let whole1 = check_prefix(&clients[1], 1);
        assert_eq!(whole1, 8, "{fault:?}: the other client's frames; closed: {:?}", clients[1].closed);
        assert_eq!(clients[1].closed.as_deref(), Some("done"));
        let why = clients[0].closed.as_deref().unwrap_or("never closed");
        assert!(whole0 < 6 && why.contains("rendering row"), "{fault:?}: client 0 got {whole0} frames, closed: {why}");
        assert!(
            switched_off,
            "{fault:?}: a device that cannot stop its frame is switched off (or {WEDGED_AFTER} failures)"
        );
    }
    // A device that never sets done but writes every row: frame mode only
    // needs the rows; everyone is served, the accelerator stays on.
    let (clients, switched_off, quarantined) = run(Fault::DoneNeverSet, 40);
    assert_eq!(quarantined, 0);
    assert_eq!((check_prefix(&clients[0], 0), check_prefix(&clients[1], 1)), (6, 8));
    assert!(!switched_off);
}
