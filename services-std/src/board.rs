//! One frame supply for every service, as on the board ([`Board`]): one
//! engine filling one ring, the seed port's, the page's and the camera's
//! frames all begun in it, each service within its quota (the firmware's
//! [`SEED_FRAMES`], [`WEB_FRAMES`], [`CAMERA_SLOTS`]), every call under one
//! lock. Each user holds a [`Share`], the [`FrameSource`] (and, for the
//! camera, [`SlotSource`]) its service runs on.
//!
//! `hps-linux` serves from a board whose engine is the FPGA behind the
//! bridge (or the simulated accelerator)
//! ([`Server::start_board`](crate::Server::start_board)).

use std::collections::VecDeque;
use std::fmt;
use std::sync::{Arc, Mutex, MutexGuard};

use model::Light;
use rt_services::camera::sender::{SlotSource, CAMERA_SLOTS};
use rt_services::seed::SEED_FRAMES;
use rt_services::web::WEB_FRAMES;
use rt_services::FrameSource;

/// Slots of a board's ring: the sum of its users' quotas (a board with a
/// VGA display keeps two more, as the firmware's `RING_SLOTS`).
pub const BOARD_SLOTS: usize = SEED_FRAMES + CAMERA_SLOTS + WEB_FRAMES;

/// Which service a [`Share`] serves: its quota.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Service {
    /// The seed and persistent ports: [`SEED_FRAMES`] among all clients.
    Seed,
    /// The web page's viewers: [`WEB_FRAMES`].
    Web,
    /// The network camera: [`CAMERA_SLOTS`].
    Camera,
}

impl Service {
    /// Frames the service's users hold at once, all together.
    pub const fn quota(self) -> usize {
        match self {
            Service::Seed => SEED_FRAMES,
            Service::Web => WEB_FRAMES,
            Service::Camera => CAMERA_SLOTS,
        }
    }

    const fn index(self) -> usize {
        match self {
            Service::Seed => 0,
            Service::Web => 1,
            Service::Camera => 2,
        }
    }
}

/// Why a frame failed, whatever renders it: the engine's own error, as
/// text (each engine has its own error type; a board holds any of them).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Failed(pub String);

impl fmt::Display for Failed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// What a board's frames come from: any [`SlotSource`] (a frame ring),
/// with its errors as text. Implemented for every `SlotSource + Send`; its
/// methods are named apart from [`FrameSource`]'s, which a [`Share`] also
/// has.
pub trait Frames: Send {
    /// [`FrameSource::begin`].
    fn begin_frame(&mut self, light: &Light) -> Result<Option<usize>, Failed>;
    /// [`FrameSource::rows_ready`].
    fn frame_rows(&mut self, frame: usize) -> Result<u16, Failed>;
    /// [`FrameSource::copy_row`].
    fn copy_frame_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize;
    /// [`FrameSource::end`].
    fn end_frame(&mut self, frame: usize);
    /// [`SlotSource::set_held`].
    fn hold_slots(&mut self, mask: u32);
    /// The board's own work between requests, called every few
    /// milliseconds by whoever runs the board ([`Board::tick`]); `clients`
    /// counts the frames its services hold. A line for the log, if one is
    /// due. Nothing by default (a board with a display and keys runs them
    /// here).
    fn tick(&mut self, clients: usize) -> Option<String> {
        let _ = clients;
        None
    }
    /// What the board says of itself now, where that changes while it
    /// runs ([`Live`]); `None`: what it said at start holds.
    fn live(&self) -> Option<Live> {
        None
    }
    /// The program is stopping: leave the hardware quiet (a display off,
    /// lights out). Nothing by default.
    fn shut_down(&mut self) {}
}

/// What a board with a display says of itself now, for `/status`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Live {
    /// The VGA output in words.
    pub vga: &'static str,
    /// The code its displays show (`ok`, `E1`..`E7`).
    pub code: &'static str,
}

impl<S: SlotSource + Send> Frames for S {
    fn begin_frame(&mut self, light: &Light) -> Result<Option<usize>, Failed> {
        FrameSource::begin(self, light).map_err(|e| Failed(e.to_string()))
    }

    fn frame_rows(&mut self, frame: usize) -> Result<u16, Failed> {
        FrameSource::rows_ready(self, frame).map_err(|e| Failed(e.to_string()))
    }

    fn copy_frame_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        FrameSource::copy_row(self, frame, y, offset, out)
    }

    fn end_frame(&mut self, frame: usize) {
        FrameSource::end(self, frame)
    }

    fn hold_slots(&mut self, mask: u32) {
        SlotSource::set_held(self, mask)
    }
}

struct Inner {
    frames: Box<dyn Frames>,
    /// Frames each service holds now, by [`Service::index`].
    held: [usize; 3],
    /// Each service's users waiting for a frame (their [`Share`] ids), in
    /// the order they first asked: first come, first served.
    waiting: [VecDeque<u64>; 3],
    /// The next share's id.
    next_share: u64,
    /// Frames begun so far.
    begun: u64,
}

/// The board's one frame supply.
pub struct Board {
    inner: Mutex<Inner>,
    /// What renders, for the log and `/status`.
    renderer: String,
}

impl fmt::Debug for Board {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Board({})", self.renderer)
    }
}

impl Board {
    /// A board whose frames come from `frames` (a ring of at least
    /// [`BOARD_SLOTS`] slots, so that every service gets its quota),
    /// described as `renderer` (e.g. `FPGA rows into the ring`).
    pub fn new(frames: impl Frames + 'static, renderer: impl Into<String>) -> Arc<Board> {
        Arc::new(Board {
            inner: Mutex::new(Inner {
                frames: Box::new(frames),
                held: [0; 3],
                waiting: Default::default(),
                next_share: 0,
                begun: 0,
            }),
            renderer: renderer.into(),
        })
    }

    /// A share of the frames for a user of `service`.
    pub fn share(self: &Arc<Board>, service: Service) -> Share {
        let id = {
            let mut inner = self.lock();
            inner.next_share += 1;
            inner.next_share
        };
        Share { board: self.clone(), service, id, open: Vec::new() }
    }

    /// What renders.
    pub fn renderer(&self) -> &str {
        &self.renderer
    }

    /// Frames begun so far, by every service.
    pub fn frames_begun(&self) -> u64 {
        self.lock().begun
    }

    /// Let the frames do their own work ([`Frames::tick`]), under the
    /// board's lock like every other call; the line to log, if any (to be
    /// written after the lock is let go).
    pub fn tick(&self) -> Option<String> {
        let mut inner = self.lock();
        let clients = inner.held.iter().sum();
        inner.frames.tick(clients)
    }

    /// Leave the hardware quiet before the program stops
    /// ([`Frames::shut_down`]).
    pub fn shut_down(&self) {
        self.lock().frames.shut_down()
    }

    /// What the board says of itself now ([`Frames::live`]).
    pub fn live(&self) -> Option<Live> {
        self.lock().frames.live()
    }

    /// Frames `service` holds now.
    pub fn held(&self, service: Service) -> usize {
        self.lock().held[service.index()]
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        // A user that panicked left the ring as it was (every call is one
        // ring operation): go on.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// One user's view of a [`Board`]: its service's quota, every call under
/// the board's lock. While the quota is full its users wait in the order
/// they first asked, as the page's viewers take turns: one that has just
/// ended a frame and asks again queues behind those already waiting. The
/// frames it began and has not ended are ended when it is dropped (and
/// its place in the queue given up), so a connection thread that panics
/// mid-frame gives its frames back instead of shrinking its service's
/// quota for good. A clone is a user of its own, with no frames.
#[derive(Debug)]
pub struct Share {
    board: Arc<Board>,
    service: Service,
    /// This user's place in its service's queue.
    id: u64,
    /// Frames begun through this share and not yet ended.
    open: Vec<usize>,
}

impl Clone for Share {
    fn clone(&self) -> Share {
        self.board.share(self.service)
    }
}

impl Drop for Share {
    fn drop(&mut self) {
        // `end` takes each out of `open`.
        while let Some(&frame) = self.open.last() {
            self.end(frame);
        }
        let id = self.id;
        self.board.lock().waiting[self.service.index()].retain(|&w| w != id);
    }
}

impl Share {
    /// The board it shares.
    pub fn board(&self) -> &Arc<Board> {
        &self.board
    }
}

impl FrameSource for Share {
    type Frame = usize;
    type Error = Failed;

    /// `Ok(None)` while the service holds its quota, no slot is free, or
    /// another of its users asked first and still waits (this one then
    /// waits behind it).
    fn begin(&mut self, light: &Light) -> Result<Option<usize>, Failed> {
        let mut inner = self.board.lock();
        let i = self.service.index();
        let first = inner.waiting[i].front().is_none_or(|&w| w == self.id);
        let frame = if first && inner.held[i] < self.service.quota() { inner.frames.begin_frame(light)? } else { None };
        match frame {
            Some(f) => {
                inner.held[i] += 1;
                inner.begun += 1;
                self.open.push(f);
                inner.waiting[i].retain(|&w| w != self.id);
            }
            None if !inner.waiting[i].contains(&self.id) => inner.waiting[i].push_back(self.id),
            None => {}
        }
        Ok(frame)
    }

    fn rows_ready(&mut self, frame: usize) -> Result<u16, Failed> {
        self.board.lock().frames.frame_rows(frame)
    }

    fn copy_row(&mut self, frame: usize, y: u16, offset: usize, out: &mut [u8]) -> usize {
        self.board.lock().frames.copy_frame_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: usize) {
        match self.open.iter().position(|&f| f == frame) {
            Some(k) => {
                self.open.swap_remove(k);
            }
            // Not this share's (or ended already): nothing to give back.
            None => return,
        }
        let mut inner = self.board.lock();
        let i = self.service.index();
        inner.held[i] = inner.held[i].saturating_sub(1);
        inner.frames.end_frame(frame)
    }
}

/// The camera's repair windows hold slots through its share (the only
/// service that does).
impl SlotSource for Share {
    fn set_held(&mut self, mask: u32) {
        self.board.lock().frames.hold_slots(mask)
    }
}

/// A board whose engine is hal-avalon's simulated accelerator, its frame
/// DMA writing a ring of [`BOARD_SLOTS`] in host memory (frame mode).
pub fn simulated() -> Arc<Board> {
    let mem = crate::SharedMemory::new(BOARD_SLOTS);
    let sim = crate::simulated_accelerator(mem.clone());
    let engine =
        hal_avalon::Accelerator::new(sim, hal_avalon::sim::CountingDelay::default(), hal_avalon::PollTimeout::DEFAULT);
    let ring = rt_services::FrameRing::<_, _, BOARD_SLOTS>::new(mem, engine);
    Board::new(ring, "simulated accelerator, frame DMA into the ring")
}

/// A board whose engine renders `rows` one row at a time into a ring of
/// [`BOARD_SLOTS`] in host memory (the FPGA's row registers, or the
/// model in software), described as `renderer`.
pub fn rows_into_ring<R>(rows: R, renderer: &str) -> Arc<Board>
where
    R: rt_services::RowSource + Send + 'static,
    R::Error: Copy + fmt::Display + fmt::Debug + Send,
{
    let mem = crate::SharedMemory::new(BOARD_SLOTS);
    let ring = rt_services::FrameRing::<_, _, BOARD_SLOTS>::new(mem, rt_services::RowEngine::new(rows));
    Board::new(ring, renderer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::FRAME_BYTES;
    use rt_services::{FrameRing, RowEngine, SliceMemory, SoftwareRenderer};

    fn light(x: i32) -> Light {
        Light::from_raw(x, 4096, -2048).unwrap()
    }

    fn board() -> Arc<Board> {
        let mem: &'static mut [u8] = Vec::leak(vec![0u8; BOARD_SLOTS * FRAME_BYTES]);
        let ring = FrameRing::<_, _, BOARD_SLOTS>::new(SliceMemory::new(0, mem), RowEngine::new(SoftwareRenderer));
        Board::new(ring, "software")
    }

    #[test]
    fn each_service_holds_at_most_its_quota_and_the_others_still_get_theirs() {
        let b = board();
        let mut seeds: Vec<Share> = (0..6).map(|_| b.share(Service::Seed)).collect();
        let mut begun = Vec::new();
        for (i, s) in seeds.iter_mut().enumerate() {
            if let Some(f) = s.begin(&light(i as i32)).unwrap() {
                begun.push((i, f));
            }
        }
        assert_eq!(begun.len(), SEED_FRAMES, "the seed clients share their quota");
        assert_eq!(b.held(Service::Seed), SEED_FRAMES);
        let mut web = b.share(Service::Web);
        let w: Vec<usize> = (0..WEB_FRAMES).map(|i| web.begin(&light(100 + i as i32)).unwrap().unwrap()).collect();
        assert_eq!(web.begin(&light(200)).unwrap(), None, "the page's quota");
        let mut cam = b.share(Service::Camera);
        for i in 0..CAMERA_SLOTS {
            assert!(cam.begin(&light(300 + i as i32)).unwrap().is_some(), "camera frame {i}");
        }
        assert_eq!(b.frames_begun(), BOARD_SLOTS as u64);
        // A seed client ending its frame (one still queued: the one being
        // rendered frees its slot only when it is done) lets another in:
        // the first that waited.
        let (i, f) = begun[SEED_FRAMES - 1];
        seeds[i].end(f);
        assert!(seeds[SEED_FRAMES].begin(&light(5)).unwrap().is_some());
        web.end(w[0]);
        assert_eq!(b.held(Service::Web), WEB_FRAMES - 1);
    }

    #[test]
    fn seed_clients_waiting_for_the_quota_are_served_first_come_first_served() {
        let b = board();
        let mut holders: Vec<Share> = (0..SEED_FRAMES).map(|_| b.share(Service::Seed)).collect();
        let held: Vec<usize> = holders.iter_mut().map(|s| s.begin(&light(0)).unwrap().unwrap()).collect();
        // Three more clients ask, in this order, while the quota is full.
        let mut waiting: Vec<Share> = (0..3).map(|_| b.share(Service::Seed)).collect();
        for w in waiting.iter_mut() {
            assert_eq!(w.begin(&light(1)).unwrap(), None, "the quota is full");
        }
        // A frame ends; the holder asks again at once, and so do the
        // waiting clients, last first: the first to have asked gets it.
        holders[0].end(held[0]);
        assert_eq!(holders[0].begin(&light(2)).unwrap(), None, "a holder asking again queues behind");
        assert_eq!(waiting[2].begin(&light(1)).unwrap(), None, "the third waits for the first");
        assert_eq!(waiting[1].begin(&light(1)).unwrap(), None, "the second waits for the first");
        let first = waiting[0].begin(&light(1)).unwrap().expect("the first to ask is served");
        // The next frame to end goes to the second, then the third, then
        // the holder that asked again.
        waiting[0].end(first);
        assert_eq!(waiting[2].begin(&light(1)).unwrap(), None);
        assert!(waiting[1].begin(&light(1)).unwrap().is_some(), "then the second");
        holders[1].end(held[1]);
        assert_eq!(holders[0].begin(&light(2)).unwrap(), None);
        assert!(waiting[2].begin(&light(1)).unwrap().is_some(), "then the third");
        // A waiting client that goes away gives up its place.
        let mut gone = b.share(Service::Seed);
        assert_eq!(gone.begin(&light(3)).unwrap(), None);
        drop(gone);
        holders[2].end(held[2]);
        assert!(holders[0].begin(&light(2)).unwrap().is_some(), "the holder's turn, the one gone skipped");
    }

    /// Beside the limit, the ordinary case: one client alone asks and is
    /// served at once, frame after frame, as many as the quota holds.
    #[test]
    fn a_client_alone_never_waits_behind_itself() {
        let b = board();
        let mut s = b.share(Service::Seed);
        for round in 0..3 {
            let frames: Vec<usize> = (0..SEED_FRAMES).map(|i| s.begin(&light(i as i32)).unwrap().unwrap()).collect();
            assert_eq!(s.begin(&light(99)).unwrap(), None, "round {round}: the quota");
            for f in frames {
                s.end(f);
            }
        }
    }

    #[test]
    fn a_frame_from_a_share_is_the_models() {
        let b = board();
        let mut s = b.share(Service::Seed);
        let l = light(1234);
        let f = s.begin(&l).unwrap().unwrap();
        while s.rows_ready(f).unwrap() < rt_services::frames::ROWS {}
        let mut want = vec![0u8; FRAME_BYTES];
        model::render_frame_rgb888(&l, (&mut want[..]).try_into().unwrap());
        let mut row = vec![0u8; model::ROW_BYTES];
        for y in 0..rt_services::frames::ROWS {
            assert_eq!(s.copy_row(f, y, 0, &mut row), model::ROW_BYTES);
            let at = usize::from(y) * model::ROW_BYTES;
            assert_eq!(row, want[at..at + model::ROW_BYTES], "row {y}");
        }
        s.end(f);
        assert_eq!(b.held(Service::Seed), 0);
    }

    #[test]
    fn a_connection_that_panics_mid_frame_gives_its_frames_back() {
        let b = board();
        let mut share = b.share(Service::Seed);
        let frame = share.begin(&light(1)).unwrap().expect("a frame");
        let _ = share.rows_ready(frame).unwrap();
        let died = std::thread::spawn(move || {
            let _held = share;
            panic!("a connection thread dies mid-frame");
        })
        .join();
        assert!(died.is_err());
        assert_eq!(b.held(Service::Seed), 0, "the quota is whole again");
        let mut again = b.share(Service::Seed);
        let frames: Vec<usize> = (0..SEED_FRAMES).map(|i| again.begin(&light(i as i32)).unwrap().unwrap()).collect();
        assert_eq!(frames.len(), SEED_FRAMES);
        // A clone holds none of the original's frames.
        let copy = again.clone();
        drop(copy);
        assert_eq!(b.held(Service::Seed), SEED_FRAMES);
        for f in frames {
            again.end(f);
            again.end(f); // a second end gives nothing back twice
        }
        assert_eq!(b.held(Service::Seed), 0);
    }
}
