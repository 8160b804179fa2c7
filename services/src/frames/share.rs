//! How services share one ring: each class of user gets a fixed number of
//! slots, so none can take the slots another needs.
//!
//! The ring's slots are used by:
//!
//! * the display: the frame on screen and the one waiting for vertical
//!   blanking (pins, [`FrameRing::pin`](super::FrameRing::pin)), at most
//!   two;
//! * the network camera: per stream the frame being sent and the one
//!   before it, which the repair window holds (the camera keeps to that by
//!   construction: `camera::sender`), at most two a stream;
//! * the seed frame server: one frame per request being rendered or sent,
//!   as many as it has clients unless something bounds it: [`Quota`].
//!
//! A ring of at least the sum of those bounds always has a slot for each
//! class's next frame (once the engine has finished any frame abandoned
//! mid-render). docs/streaming.md, "Slot arithmetic", has the figures.

use model::Light;

use super::FrameSource;

/// A [`FrameSource`] that lets its user hold at most `limit` frames at
/// once (begun and not yet ended); a `begin` beyond it answers `Ok(None)`,
/// as a full ring does, and the user asks again later.
pub struct Quota<'a, S> {
    source: &'a mut S,
    /// Frames begun through this quota and not yet ended.
    held: &'a mut usize,
    limit: usize,
}

impl<'a, S> Quota<'a, S> {
    /// `source`, as seen by a user who may hold `limit` frames; `held`
    /// counts them and lives as long as the user does (it is the user's
    /// state, lent for each call).
    pub fn new(source: &'a mut S, held: &'a mut usize, limit: usize) -> Quota<'a, S> {
        Quota { source, held, limit }
    }
}

impl<S: FrameSource> FrameSource for Quota<'_, S> {
    type Frame = S::Frame;
    type Error = S::Error;

    fn begin(&mut self, light: &Light) -> Result<Option<S::Frame>, S::Error> {
        if *self.held >= self.limit {
            return Ok(None);
        }
        let frame = self.source.begin(light)?;
        if frame.is_some() {
            *self.held += 1;
        }
        Ok(frame)
    }

    fn rows_ready(&mut self, frame: S::Frame) -> Result<u16, S::Error> {
        self.source.rows_ready(frame)
    }

    fn copy_row(&mut self, frame: S::Frame, y: u16, offset: usize, out: &mut [u8]) -> usize {
        self.source.copy_row(frame, y, offset, out)
    }

    fn end(&mut self, frame: S::Frame) {
        *self.held = self.held.saturating_sub(1);
        self.source.end(frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::{FrameRing, RowEngine, SliceMemory, SoftwareRenderer};
    use model::FRAME_BYTES;

    #[test]
    fn a_user_past_its_quota_waits_and_leaves_the_rest_to_others() {
        let mut mem = vec![0u8; 4 * FRAME_BYTES];
        let mut ring = FrameRing::<_, _, 4>::new(SliceMemory::new(0, &mut mem), RowEngine::new(SoftwareRenderer));
        let l = Light::from_world(3.0, 4.0, -2.0).unwrap();
        let mut seed_held = 0;
        let mut seed = Quota::new(&mut ring, &mut seed_held, 2);
        let a = seed.begin(&l).unwrap().unwrap();
        let _b = seed.begin(&l).unwrap().unwrap();
        assert_eq!(seed.begin(&l).unwrap(), None, "two at most");
        while seed.rows_ready(a).unwrap() < crate::frames::ROWS {}
        seed.end(a);
        let c = seed.begin(&l).unwrap();
        assert!(c.is_some(), "one ended: one more");
        assert_eq!(seed_held, 2);
        assert_eq!(ring.free_slots(), 2, "the others' two slots stayed free");
    }
}
