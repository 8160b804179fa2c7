//! Where frames go: one PNG, a numbered PNG sequence, or an animated GIF.

use std::fs::{self, File};
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Sender};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame, RgbImage, RgbaImage};
use model::{HEIGHT, WIDTH};

/// GIF frame time: 24 frames per second, the target rate.
const GIF_FRAME_MS: u32 = 1000 / 24;
/// NeuQuant sampling factor for GIF palettes (1 best .. 30 fastest).
const GIF_SPEED: i32 = 10;

/// An RGB888 wire frame as an image.
pub fn to_image(rgb: &[u8]) -> Result<RgbImage, String> {
    RgbImage::from_raw(WIDTH as u32, HEIGHT as u32, rgb.to_vec()).ok_or_else(|| "frame has the wrong size".into())
}

/// Save one frame as PNG.
pub fn save_png(rgb: &[u8], path: &Path) -> Result<(), String> {
    to_image(rgb)?.save(path).map_err(|e| format!("writing {}: {e}", path.display()))
}

/// A sink for the frames of a run; encoding runs on its own thread behind
/// an unbounded queue, so a slow encoder (a GIF takes tens of ms a frame)
/// never holds back the reader and the stream's rate is measured apart
/// from it. The frames wait in memory meanwhile (518,400 bytes each).
pub struct FrameSink {
    tx: Option<Sender<Vec<u8>>>,
    worker: Option<JoinHandle<Result<Written, String>>>,
}

/// What a [`FrameSink`] wrote, and the time its encoder was busy.
pub struct Written {
    /// One line: what was written where.
    pub summary: String,
    /// Time spent encoding and writing, summed over the frames.
    pub busy: Duration,
}

impl FrameSink {
    /// A sink writing `out`: a GIF when it ends in `.gif`, else a directory
    /// of `frame_NNN.png`. `None` discards frames.
    pub fn new(out: Option<PathBuf>) -> Result<FrameSink, String> {
        let Some(out) = out else {
            return Ok(FrameSink { tx: None, worker: None });
        };
        let (tx, rx) = mpsc::channel::<Vec<u8>>();
        let is_gif = out.extension().is_some_and(|e| e.eq_ignore_ascii_case("gif"));
        let worker = if is_gif {
            let file = File::create(&out).map_err(|e| format!("creating {}: {e}", out.display()))?;
            thread::spawn(move || {
                let mut gif = GifEncoder::new_with_speed(BufWriter::new(file), GIF_SPEED);
                gif.set_repeat(Repeat::Infinite).map_err(|e| e.to_string())?;
                let (mut n, mut busy) = (0, Duration::ZERO);
                for rgb in rx {
                    let began = Instant::now();
                    let rgba = RgbaImage::from_fn(WIDTH as u32, HEIGHT as u32, |x, y| {
                        let i = (y as usize * WIDTH + x as usize) * 3;
                        image::Rgba([rgb[i], rgb[i + 1], rgb[i + 2], 255])
                    });
                    let delay = Delay::from_numer_denom_ms(GIF_FRAME_MS, 1);
                    gif.encode_frame(Frame::from_parts(rgba, 0, 0, delay))
                        .map_err(|e| format!("writing {}: {e}", out.display()))?;
                    n += 1;
                    busy += began.elapsed();
                }
                Ok(Written { summary: format!("wrote {} ({n} frames)", out.display()), busy })
            })
        } else {
            fs::create_dir_all(&out).map_err(|e| format!("creating {}: {e}", out.display()))?;
            thread::spawn(move || {
                let (mut n, mut busy) = (0, Duration::ZERO);
                for rgb in rx {
                    let began = Instant::now();
                    save_png(&rgb, &out.join(format!("frame_{n:03}.png")))?;
                    n += 1;
                    busy += began.elapsed();
                }
                Ok(Written { summary: format!("wrote {n} PNG frames to {}", out.display()), busy })
            })
        };
        Ok(FrameSink { tx: Some(tx), worker: Some(worker) })
    }

    /// Queue a frame for writing.
    pub fn push(&mut self, rgb: &[u8]) -> Result<(), String> {
        match &self.tx {
            Some(tx) => tx.send(rgb.to_vec()).map_err(|_| self.failure()),
            None => Ok(()),
        }
    }

    fn failure(&mut self) -> String {
        self.tx = None;
        match self.worker.take().map(|w| w.join()) {
            Some(Ok(Err(e))) => e,
            _ => "the frame writer stopped".into(),
        }
    }

    /// Wait for every frame to be written; returns what was written.
    pub fn finish(mut self) -> Result<Option<Written>, String> {
        self.tx = None;
        match self.worker.take().map(|w| w.join()) {
            None => Ok(None),
            Some(Ok(r)) => r.map(Some),
            Some(Err(_)) => Err("the frame writer panicked".into()),
        }
    }
}
