//! Frame mode under Linux on a stand-in system: a u-dma-buf buffer (a
//! sysfs entry and a file standing in for `/dev/udmabuf0`), the SDRAM
//! controller's `fpgaportrst` in a /dev/mem stand-in, and the accelerator
//! behind the mapped registers (the device model answering through the
//! bridge's stand-in file, as in `mapped_registers.rs`), its frame DMA
//! writing into the buffer's file through a mapping of its own. So the
//! code that maps the buffer, hands the DMA its physical addresses and
//! reads the rows back is the code tested, and an address or offset wrong
//! in it gives wrong frames here.

mod support;

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use hal_avalon::map::{Csr, LW_BRIDGE_BASE, LW_BRIDGE_SIZE, VGA_CONTROL_ENABLE};
use hal_avalon::sim::{DmaTarget, SimAccelerator};
use hps_linux::frame_memory::RING_BYTES;
use hps_linux::preflight::{self, Finding, Report, System};
use hps_linux::serve;
use memmap2::MmapRaw;
use model::FRAME_BYTES;
use rt_services::monitor::{LED_ATTRACT, LED_FPGA, LED_LINK, LED_SELF_TEST};
use rt_services_std::Server;
use soc::cyclone_v::{FPGAPORTRST, FPGAPORTRST_RELEASED};
use support::{http_get, map_view, model_frame, seed_frame, through_dev_mem, Answered, BUSY_POLLS};
use tempfile::TempDir;

/// Where the stand-in buffer lies in the board's physical address space.
const PHYS: u32 = 0x3000_0000;

/// The stand-in system: `sysfs/class/u-dma-buf/udmabuf0`, `dev/udmabuf0`
/// and a /dev/mem holding `fpgaportrst`.
struct Stand {
    _dir: TempDir,
    sys: System,
}

fn stand(ports: u32) -> Stand {
    let dir = tempfile::tempdir().unwrap();
    let sys = System { sysfs: dir.path().join("sys"), dev: dir.path().join("dev"), dev_mem: dir.path().join("mem") };
    let class = sys.sysfs.join("class/u-dma-buf/udmabuf0");
    std::fs::create_dir_all(&class).unwrap();
    std::fs::write(class.join("phys_addr"), format!("{PHYS:#010x}\n")).unwrap();
    std::fs::write(class.join("size"), format!("{RING_BYTES}\n")).unwrap();
    std::fs::create_dir_all(&sys.dev).unwrap();
    std::fs::File::create(sys.dev.join("udmabuf0")).and_then(|f| f.set_len(RING_BYTES)).unwrap();
    let page_end = (FPGAPORTRST as u64 | 0xfff) + 1;
    std::fs::File::create(&sys.dev_mem).and_then(|f| f.set_len(page_end)).unwrap();
    poke(&sys.dev_mem, FPGAPORTRST as u64, ports);
    Stand { _dir: dir, sys }
}

fn poke(file: &Path, at: u64, value: u32) {
    use std::os::unix::fs::FileExt;
    let f = std::fs::OpenOptions::new().write(true).open(file).unwrap();
    f.write_all_at(&value.to_le_bytes(), at).unwrap();
}

/// The SDRAM behind the FPGA-to-SDRAM port: the buffer's file, seen
/// through a mapping of the device model's own at physical [`PHYS`].
/// `answers` false is a port held in reset (no write ever completes); the
/// test may change it while the board runs.
struct Sdram {
    view: MmapRaw,
    answers: Arc<AtomicBool>,
}

impl DmaTarget for Sdram {
    fn write(&mut self, addr: u32, bytes: &[u8]) -> bool {
        let Some(at) = addr.checked_sub(PHYS).map(|a| a as usize) else { return false };
        if at + bytes.len() > self.view.len() {
            return false;
        }
        // SAFETY: in bounds (checked); the mapping lives as long as
        // `self`. The code under test reads these bytes through its own
        // mapping, only after the frame's counter covered them.
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), self.view.as_mut_ptr().add(at), bytes.len()) };
        true
    }

    fn answers(&self) -> bool {
        self.answers.load(Ordering::Relaxed)
    }
}

fn report() -> Report {
    Report {
        fpga: Finding::Good("stand-in".into()),
        bridge: Finding::Good("stand-in".into()),
        window: "stand-in".into(),
        register_map: hal_avalon::map::ID_VERSION,
        build_id: 0,
    }
}

/// The accelerator behind the mapped registers, its DMA into `s`'s buffer.
fn accelerator(s: &Stand, answers: bool) -> Answered<Sdram> {
    accelerator_with(s, Arc::new(AtomicBool::new(answers)))
}

fn accelerator_with(s: &Stand, answers: Arc<AtomicBool>) -> Answered<Sdram> {
    let (bridge, window) = through_dev_mem();
    let view = map_view(&s.sys.dev.join("udmabuf0"), 0, RING_BYTES as usize);
    let sim = SimAccelerator::with_memory(Sdram { view, answers }, BUSY_POLLS);
    Answered { port: window.into_port().unwrap(), bridge, sim }
}

/// A view of the bridge's stand-in file behind an accelerator: the
/// registers as the last access left them (a write's value, or the
/// model's answer to a read), after the accelerator is given away.
struct Registers(MmapRaw);

impl Registers {
    fn of(a: &Answered<Sdram>) -> Registers {
        Registers(map_view(&a.bridge.dir.path().join("mem"), LW_BRIDGE_BASE as u64, LW_BRIDGE_SIZE))
    }

    fn word(&self, csr: Csr) -> *mut u32 {
        let at = csr.offset();
        assert!(at + 4 <= self.0.len());
        self.0.as_mut_ptr().wrapping_add(at).cast::<u32>()
    }

    fn get(&self, csr: Csr) -> u32 {
        // SAFETY: in bounds (asserted), 4-byte aligned in a page-aligned
        // mapping that lives as long as `self`; the board is called from
        // this thread only, so no access is under way.
        unsafe { self.word(csr).read_volatile() }
    }

    /// Put a marker where a write would land, to see whether one does.
    fn set(&self, csr: Csr, value: u32) {
        // SAFETY: as in `get`.
        unsafe { self.word(csr).write_volatile(value) }
    }
}

#[test]
fn frames_land_in_the_dma_buffer_and_are_served_from_it() {
    let s = stand(FPGAPORTRST_RELEASED);
    let ring = serve::frame_memory(&s.sys).expect("the buffer fits the ring");
    let (board, facts) = serve::fpga(accelerator(&s, true), &report(), Ok(ring)).expect("the self-test passes");
    assert_eq!((facts.self_test.result, facts.mode.as_str()), ("pass", "frames"), "{}", facts.self_test.detail);
    assert!(facts.self_test.detail.contains("frame mode"), "{}", facts.self_test.detail);
    let sim = Server::start_board("127.0.0.1:0".parse().unwrap(), board, facts, false).unwrap();
    let addr = sim.frame_addr();
    let lights = [[3072, 4096, -2048], [-5120, 6144, 1024]];
    let clients: Vec<_> = lights.iter().map(|&raw| std::thread::spawn(move || (raw, seed_frame(addr, raw)))).collect();
    for c in clients {
        let (raw, frame) = c.join().unwrap();
        assert!(frame == model_frame(raw), "the frame for {raw:?} is the model's");
    }
    // The frames went through the buffer's file: a slot of it holds the
    // last one served byte for byte (an earlier one's slot may be reused).
    let last = [1500, 2500, 700];
    assert!(seed_frame(addr, last) == model_frame(last));
    let bytes = std::fs::read(s.sys.dev.join("udmabuf0")).unwrap();
    let want = model_frame(last);
    assert!(bytes.chunks(FRAME_BYTES).any(|slot| slot == &want[..]), "a slot of the buffer holds the frame");
}

#[test]
fn a_frame_dma_that_never_lands_falls_back_to_rows_and_says_why() {
    let s = stand(FPGAPORTRST_RELEASED);
    let ring = serve::frame_memory(&s.sys).unwrap();
    let (board, facts) = serve::fpga(accelerator(&s, false), &report(), Ok(ring)).expect("rows still work");
    assert_eq!(facts.mode, "rows");
    let detail = &facts.self_test.detail;
    assert!(detail.contains("FAIL: frame mode") && detail.contains("fpgaportrst"), "{detail}");
    let sim = Server::start_board("127.0.0.1:0".parse().unwrap(), board, facts, false).unwrap();
    let raw = [1500, 2500, 700];
    assert!(seed_frame(sim.frame_addr(), raw) == model_frame(raw), "rows give the model's frame");
}

#[test]
fn sdram_ports_in_reset_keep_frame_mode_from_being_tried() {
    let s = stand(0);
    assert!(matches!(preflight::sdram_ports(&s.sys), Finding::Bad(_)));
    let why = serve::frame_memory(&s.sys).unwrap_err();
    assert!(why.contains("fpgaportrst 0x0") && why.contains("held in reset"), "{why}");
    let (_, facts) = serve::fpga(accelerator(&s, true), &report(), Err(why)).expect("rows");
    assert_eq!(facts.mode, "rows");
    assert!(facts.self_test.detail.contains("held in reset"), "{}", facts.self_test.detail);
    // Without /dev/mem the ports are not known, and the self-test decides.
    std::fs::remove_file(&s.sys.dev_mem).unwrap();
    assert!(matches!(preflight::sdram_ports(&s.sys), Finding::Unknown(_)));
    assert!(serve::frame_memory(&s.sys).is_ok());
}

#[test]
fn a_buffer_whose_device_cannot_be_opened_is_said() {
    let s = stand(FPGAPORTRST_RELEASED);
    std::fs::remove_file(s.sys.dev.join("udmabuf0")).unwrap();
    let why = serve::frame_memory(&s.sys).unwrap_err();
    assert!(why.contains("udmabuf0") && why.contains("rendering rows"), "{why}");
}

/// The board's own work as on bare metal: attract mode renders into the
/// buffer and the scan-out is pointed at the frame there; the LEDs say
/// link, FPGA, self-test passed, attract mode; `/status` follows live.
/// (What the displays show first is the host's address scrolling in from
/// blank: not checked here; the policy's own tests in rt-services cover
/// it.)
#[test]
fn the_monitor_shows_attract_frames_from_the_buffer_and_lights_the_leds() {
    let s = stand(FPGAPORTRST_RELEASED);
    let ring = serve::frame_memory(&s.sys).unwrap();
    let accel = accelerator(&s, true);
    let reg = Registers::of(&accel);
    let (board, facts) = serve::fpga(accel, &report(), Ok(ring)).expect("the self-test passes");
    assert_eq!(facts.vga, "starting");
    assert_eq!(board.live().map(|l| l.vga), Some("starting"));
    // What the self-test left in the buffer goes: a frame found there
    // later was rendered since.
    std::fs::write(s.sys.dev.join("udmabuf0"), vec![0u8; RING_BYTES as usize]).unwrap();
    for _ in 0..5_000 {
        board.tick();
        if reg.get(Csr::VgaControl) & VGA_CONTROL_ENABLE != 0 {
            break;
        }
    }
    assert_ne!(reg.get(Csr::VgaControl) & VGA_CONTROL_ENABLE, 0, "the scan-out is enabled once a frame is complete");
    let base = reg.get(Csr::VgaBase);
    assert!(
        (PHYS..PHYS + RING_BYTES as u32).contains(&base) && ((base - PHYS) as usize).is_multiple_of(FRAME_BYTES),
        "VGA_BASE {base:#x} is a slot of the buffer"
    );
    let bytes = std::fs::read(s.sys.dev.join("udmabuf0")).unwrap();
    let shown = &bytes[(base - PHYS) as usize..][..FRAME_BYTES];
    assert!(shown.iter().filter(|&&b| b != 0).count() > FRAME_BYTES / 2, "the frame shown was rendered there");
    let want = LED_LINK | LED_FPGA | LED_SELF_TEST | LED_ATTRACT;
    assert_eq!(reg.get(Csr::Leds) as u16 & want, want, "LEDs {:#x}", reg.get(Csr::Leds));
    let live = board.live().expect("a board with a display says how it is");
    assert_eq!(live.vga, "on");
    // `/status` says it as it is now, not as it was at start.
    let mut sim = Server::start_board("127.0.0.1:0".parse().unwrap(), board.clone(), facts, false).unwrap();
    let http = sim.start_web("127.0.0.1:0".parse().unwrap(), false).unwrap();
    let status = http_get(http, "/status");
    assert!(status.contains("\"vga\":\"on\""), "{status}");
    assert!(["ok", "E6"].contains(&live.code), "all well, or no address on this machine: {}", live.code);
    // Stopping leaves the hardware quiet: no scan-out, no lights.
    board.shut_down();
    assert_eq!(reg.get(Csr::VgaControl) & VGA_CONTROL_ENABLE, 0);
    assert_eq!(reg.get(Csr::Leds), 0);
}

/// In row mode the ring is the process's memory, which the FPGA cannot
/// read: no scan-out, no attract mode; the LEDs and displays still run.
/// Rows for want of frame memory are no fault (no E4 on the displays).
#[test]
fn rows_keep_the_scan_out_off_and_the_leds_on() {
    let s = stand(FPGAPORTRST_RELEASED);
    let accel = accelerator(&s, true);
    let reg = Registers::of(&accel);
    let (board, facts) = serve::fpga(accel, &report(), Err("no buffer here".into())).expect("rows");
    assert!(facts.vga.starts_with("off: rows"), "{}", facts.vga);
    // No row may start from here on: a write to CONTROL would replace this.
    reg.set(Csr::Control, 0xdead_beef);
    reg.set(Csr::VgaControl, 0);
    for _ in 0..200 {
        board.tick();
    }
    assert_eq!(reg.get(Csr::Control), 0xdead_beef, "no attract frame is rendered");
    assert_eq!(reg.get(Csr::VgaControl) & VGA_CONTROL_ENABLE, 0);
    assert_eq!(reg.get(Csr::Leds) as u16 & (LED_FPGA | LED_ATTRACT), LED_FPGA, "LEDs {:#x}", reg.get(Csr::Leds));
    let code = board.live().map(|l| l.code);
    assert!(matches!(code, Some("ok" | "E6")), "{code:?}");
}

/// A frame path that failed its self-test is E4 on the displays and in
/// `/status`, as the firmware shows it.
#[test]
fn a_failed_frame_path_shows_e4() {
    let s = stand(FPGAPORTRST_RELEASED);
    let ring = serve::frame_memory(&s.sys).unwrap();
    let (board, _) = serve::fpga(accelerator(&s, false), &report(), Ok(ring)).expect("rows");
    board.tick();
    assert_eq!(board.live().map(|l| l.code), Some("E4"));
}

/// A frame DMA that stops landing rows while the program runs fails each
/// frame (here by the DMA's own stall error; a frame that stalls with no
/// error is cut by the watchdog, `serve::STALL_LIMIT`) instead of holding
/// every frame begun after it; after three in a row the accelerator is
/// switched off (E3, said once in the log) and the software renderer
/// serves the model's frames.
#[test]
fn a_frame_dma_that_stalls_later_is_cut_then_switched_off() {
    let s = stand(FPGAPORTRST_RELEASED);
    let ring = serve::frame_memory(&s.sys).unwrap();
    let answers = Arc::new(AtomicBool::new(true));
    let accel = accelerator_with(&s, answers.clone());
    let (board, facts) = serve::fpga(accel, &report(), Ok(ring)).expect("the self-test passes");
    let sim = Server::start_board("127.0.0.1:0".parse().unwrap(), board.clone(), facts, false).unwrap();
    let raw = [1500, 2500, 700];
    assert!(seed_frame(sim.frame_addr(), raw) == model_frame(raw), "frames while the DMA lands them");
    answers.store(false, Ordering::Relaxed);
    let mut cut = 0;
    let mut said = Vec::new();
    for _ in 0..6 {
        let frame = seed_frame(sim.frame_addr(), raw);
        said.extend(board.tick());
        if frame.len() < FRAME_BYTES {
            cut += 1;
            continue;
        }
        assert!(frame == model_frame(raw), "a whole frame is the model's");
        break;
    }
    assert_eq!(cut, 3, "three stalled frames cut, then the software renderer's");
    assert!(said.iter().any(|l| l.contains("switched off")), "{said:?}");
    assert_eq!(board.live().map(|l| l.code), Some("E3"));
}
