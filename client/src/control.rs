//! The live viewer's pure parts: input events to a light position, and the
//! request coalescing that keeps the server at most one frame behind.

use std::collections::VecDeque;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::time::Duration;

use model::Light;

/// The light's position around the sphere's centre (0, 1, 0): azimuth in
/// the x-z plane from +x toward +z, elevation above the horizontal,
/// distance from the centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// Radians, any value (wraps).
    pub azimuth: f64,
    /// Radians, within [`ELEVATION`].
    pub elevation: f64,
    /// World units, within [`DISTANCE`].
    pub distance: f64,
}

/// Elevation limits: from a little below the horizon to almost overhead.
pub const ELEVATION: (f64, f64) = (-0.4, FRAC_PI_2 - 0.05);
/// Distance limits: outside the sphere (radius 1), and well inside the
/// Q13.10 range (|coordinate| < 8192).
pub const DISTANCE: (f64, f64) = (1.5, 200.0);
/// Radians per pixel of mouse drag.
pub const DRAG_RAD_PER_PX: f64 = 0.01;
/// Radians per arrow-key press.
pub const KEY_STEP_RAD: f64 = 5.0 * PI / 180.0;
/// Distance factor per wheel notch or PageUp/PageDown.
pub const ZOOM_STEP: f64 = 1.1;
/// Azimuth speed of the automatic orbit, radians per second.
pub const AUTO_RAD_PER_S: f64 = 0.6;

impl Orbit {
    /// The default: the light at (3, 4, -2), where `rt-client frame`'s
    /// examples put it.
    pub fn initial() -> Orbit {
        let (x, y, z) = (3.0f64, 4.0 - 1.0, -2.0f64);
        let d = (x * x + y * y + z * z).sqrt();
        Orbit { azimuth: z.atan2(x), elevation: (y / d).asin(), distance: d }.clamped()
    }

    fn clamped(self) -> Orbit {
        Orbit {
            azimuth: self.azimuth.rem_euclid(TAU),
            elevation: self.elevation.clamp(ELEVATION.0, ELEVATION.1),
            distance: self.distance.clamp(DISTANCE.0, DISTANCE.1),
        }
    }

    /// World position.
    pub fn position(&self) -> (f64, f64, f64) {
        let h = self.distance * self.elevation.cos();
        (h * self.azimuth.cos(), 1.0 + self.distance * self.elevation.sin(), h * self.azimuth.sin())
    }

    /// The light, always inside the Q13.10 range (the limits above).
    pub fn light(&self) -> Light {
        let (x, y, z) = self.position();
        // The limits keep every component below 202 in magnitude, far inside
        // the word range; should that ever fail, the default light stands in.
        Light::from_world(x, y, z).unwrap_or_else(|_| Orbit::initial().light())
    }
}

/// A key the viewer acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    /// Azimuth down.
    Left,
    /// Azimuth up.
    Right,
    /// Elevation up.
    Up,
    /// Elevation down.
    Down,
    /// Closer.
    PageUp,
    /// Farther.
    PageDown,
    /// Automatic orbit on/off.
    Space,
    /// Back to the initial position.
    R,
    /// Save the frame on screen as PNG.
    P,
    /// Quit.
    Escape,
}

impl Key {
    /// A key's name in scripts and `--help`.
    pub fn parse(name: &str) -> Option<Key> {
        Some(match name.to_ascii_lowercase().as_str() {
            "left" => Key::Left,
            "right" => Key::Right,
            "up" => Key::Up,
            "down" => Key::Down,
            "pageup" => Key::PageUp,
            "pagedown" => Key::PageDown,
            "space" => Key::Space,
            "r" => Key::R,
            "p" => Key::P,
            "escape" | "esc" => Key::Escape,
            _ => return None,
        })
    }
}

/// One input event.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Input {
    /// Mouse moved by (dx, dy) pixels with the left button held.
    Drag(f64, f64),
    /// Wheel notches (positive: away from the user, closer).
    Wheel(f64),
    /// A key press.
    Key(Key),
    /// Time passed (drives the automatic orbit).
    Tick(Duration),
}

/// What an input asks of the viewer besides moving the light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effect {
    /// Nothing else.
    None,
    /// Save the frame on screen.
    Save,
    /// Quit.
    Quit,
}

/// The light as the user steers it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Control {
    /// Where the light is.
    pub orbit: Orbit,
    /// Whether the automatic orbit runs.
    pub auto: bool,
}

impl Default for Control {
    fn default() -> Control {
        Control { orbit: Orbit::initial(), auto: false }
    }
}

impl Control {
    /// Apply one event.
    pub fn apply(&mut self, input: Input) -> Effect {
        let mut o = self.orbit;
        let mut effect = Effect::None;
        match input {
            Input::Drag(dx, dy) => {
                o.azimuth += dx * DRAG_RAD_PER_PX;
                o.elevation -= dy * DRAG_RAD_PER_PX;
            }
            Input::Wheel(n) => o.distance /= ZOOM_STEP.powf(n),
            Input::Key(Key::Left) => o.azimuth -= KEY_STEP_RAD,
            Input::Key(Key::Right) => o.azimuth += KEY_STEP_RAD,
            Input::Key(Key::Up) => o.elevation += KEY_STEP_RAD,
            Input::Key(Key::Down) => o.elevation -= KEY_STEP_RAD,
            Input::Key(Key::PageUp) => o.distance /= ZOOM_STEP,
            Input::Key(Key::PageDown) => o.distance *= ZOOM_STEP,
            Input::Key(Key::Space) => self.auto = !self.auto,
            Input::Key(Key::R) => {
                o = Orbit::initial();
                self.auto = false;
            }
            Input::Key(Key::P) => effect = Effect::Save,
            Input::Key(Key::Escape) => effect = Effect::Quit,
            Input::Tick(dt) => {
                if self.auto {
                    o.azimuth += AUTO_RAD_PER_S * dt.as_secs_f64();
                }
            }
        }
        // Non-finite input (a broken script) leaves the light where it was.
        if o.azimuth.is_finite() && o.elevation.is_finite() && o.distance.is_finite() {
            self.orbit = o.clamped();
        }
        effect
    }
}

/// Requests in flight: at most `depth` (the frame arriving and one queued
/// behind it), the newest wanted light waiting for a free place. A burst
/// of input therefore never builds a backlog at the server, and the frame
/// on screen belongs to a light wanted at most `depth` requests ago.
#[derive(Clone, Debug)]
pub struct Requests {
    depth: usize,
    in_flight: VecDeque<Request>,
    waiting: Option<Request>,
    newest: Option<Light>,
}

/// A request: its light and the tag of the input that asked for it.
pub type Request = (Light, u64);

/// The live viewer's depth: one frame arriving, one queued.
pub const DEPTH: usize = 2;

impl Requests {
    /// Nothing requested yet.
    pub fn new(depth: usize) -> Requests {
        Requests { depth: depth.max(1), in_flight: VecDeque::new(), waiting: None, newest: None }
    }

    /// The user wants `light` (tagged `tag`, e.g. the input event's number):
    /// the request to send now, if any. The same light as the newest is no
    /// new request.
    pub fn want(&mut self, light: Light, tag: u64) -> Option<Request> {
        if self.newest == Some(light) {
            return None;
        }
        self.newest = Some(light);
        if self.in_flight.len() < self.depth {
            self.in_flight.push_back((light, tag));
            Some((light, tag))
        } else {
            self.waiting = Some((light, tag));
            None
        }
    }

    /// A frame arrived: the request it answers, and the request to send now.
    pub fn arrived(&mut self) -> (Option<Request>, Option<Request>) {
        let done = self.in_flight.pop_front();
        let next = self.waiting.take();
        if let Some(n) = next {
            self.in_flight.push_back(n);
        }
        (done, next)
    }

    /// Requests in flight.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// A new connection: nothing in flight; the newest light is wanted again
    /// (the request to send).
    pub fn reconnected(&mut self) -> Option<Request> {
        self.in_flight.clear();
        let resend = self.waiting.take().or_else(|| self.newest.map(|l| (l, 0)));
        self.newest = None;
        resend.and_then(|(l, t)| self.want(l, t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn input() -> impl Strategy<Value = Input> {
        prop_oneof![
            (-5000.0f64..5000.0, -5000.0f64..5000.0).prop_map(|(x, y)| Input::Drag(x, y)),
            (-50.0f64..50.0).prop_map(Input::Wheel),
            prop::sample::select(vec![
                Key::Left,
                Key::Right,
                Key::Up,
                Key::Down,
                Key::PageUp,
                Key::PageDown,
                Key::Space,
                Key::R,
                Key::P,
                Key::Escape
            ])
            .prop_map(Input::Key),
            (0u64..10_000).prop_map(|ms| Input::Tick(Duration::from_millis(ms))),
            Just(Input::Drag(f64::NAN, 1.0)),
            Just(Input::Wheel(f64::INFINITY)),
        ]
    }

    proptest! {
        #[test]
        fn every_input_sequence_keeps_the_light_in_range(inputs in prop::collection::vec(input(), 0..200)) {
            let mut c = Control::default();
            for i in inputs {
                c.apply(i);
                let (x, y, z) = c.orbit.position();
                for v in [x, y, z] {
                    prop_assert!(v.abs() < 8191.0);
                }
                prop_assert!(Light::from_world(x, y, z).is_ok());
                prop_assert!(c.orbit.distance >= DISTANCE.0 && c.orbit.distance <= DISTANCE.1);
                prop_assert!(c.orbit.elevation >= ELEVATION.0 && c.orbit.elevation <= ELEVATION.1);
                // Above the plane or close to it, never inside the sphere.
                prop_assert!(((x * x) + (y - 1.0).powi(2) + z * z).sqrt() >= DISTANCE.0 - 1e-9);
            }
        }

        #[test]
        fn coalescing_never_queues_beyond_the_depth_and_the_newest_light_is_served(
            steps in prop::collection::vec(prop_oneof![(0i32..40).prop_map(Some), Just(None)], 1..300)
        ) {
            let mut r = Requests::new(DEPTH);
            let mut sent: Vec<u64> = Vec::new();
            let mut newest = None;
            let mut last = None;
            for (tag, step) in steps.iter().enumerate() {
                match step {
                    Some(v) => {
                        let l = Light::from_raw(*v * 64, 4096, 0).expect("in range");
                        if let Some((_, t)) = r.want(l, tag as u64) {
                            sent.push(t);
                        }
                        newest = Some(l);
                    }
                    None => {
                        let (done, next) = r.arrived();
                        if let Some((l, _)) = done {
                            last = Some(l);
                        }
                        if let Some((_, t)) = next {
                            sent.push(t);
                        }
                    }
                }
                prop_assert!(r.in_flight() <= DEPTH);
            }
            // Drain: every frame in flight arrives; the last one is the newest light.
            while r.in_flight() > 0 {
                if let (Some((l, _)), _) = r.arrived() {
                    last = Some(l);
                }
            }
            if newest.is_some() && !sent.is_empty() {
                prop_assert_eq!(last, newest, "the newest light is the last frame");
            }
        }
    }

    #[test]
    fn keys_and_drags_move_the_light_as_documented() {
        let mut c = Control::default();
        let a0 = c.orbit.azimuth;
        c.apply(Input::Key(Key::Right));
        assert!((c.orbit.azimuth - (a0 + KEY_STEP_RAD).rem_euclid(TAU)).abs() < 1e-12);
        let d0 = c.orbit.distance;
        c.apply(Input::Wheel(1.0));
        assert!(c.orbit.distance < d0, "the wheel away from the user brings it closer");
        c.apply(Input::Key(Key::Space));
        assert!(c.auto);
        let before = c.orbit;
        c.apply(Input::Tick(Duration::from_secs(1)));
        assert_ne!(c.orbit, before, "the automatic orbit moves");
        assert_eq!(c.apply(Input::Key(Key::P)), Effect::Save);
        assert_eq!(c.apply(Input::Key(Key::Escape)), Effect::Quit);
        c.apply(Input::Key(Key::R));
        assert_eq!(c, Control::default());
        assert_eq!(Orbit::initial().light().raw(), [3072, 4096, -2048], "starts at (3, 4, -2)");
    }

    #[test]
    fn a_burst_sends_two_and_the_last_after_them() {
        let mut r = Requests::new(DEPTH);
        let l = |v: i32| Light::from_raw(v, 0, 0).expect("in range");
        assert!(r.want(l(1), 1).is_some());
        assert!(r.want(l(2), 2).is_some());
        for v in 3..50 {
            assert!(r.want(l(v), v as u64).is_none(), "queued at the client, not the server");
        }
        assert_eq!(r.arrived(), (Some((l(1), 1)), Some((l(49), 49))), "the newest goes out next");
        assert_eq!(r.arrived(), (Some((l(2), 2)), None));
        assert_eq!(r.arrived(), (Some((l(49), 49)), None));
        assert!(r.want(l(49), 50).is_none(), "the same light again is no request");
        // Reconnect: the newest is wanted again.
        assert_eq!(r.reconnected(), Some((l(49), 0)));
    }
}
