//! The light orbiting the sphere, fetched over the persistent port with one
//! request always in flight beyond the frame being received.

use std::f64::consts::TAU;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use model::{Light, LightError, FRAME_BYTES};

use crate::net::{self, ClientError};
use crate::stats::RunStats;

/// Requests kept queued at the server beyond the frame arriving.
const IN_FLIGHT: usize = 1;

/// A circular light path: radius `radius` around the y axis at height
/// `height`, `frames` evenly spaced positions starting on +x.
#[derive(Clone, Copy, Debug)]
pub struct OrbitPath {
    /// Number of frames (positions).
    pub frames: usize,
    /// Orbit radius in world units.
    pub radius: f64,
    /// Light height in world units.
    pub height: f64,
}

impl OrbitPath {
    /// The light of frame `k`.
    pub fn light(&self, k: usize) -> Result<Light, LightError> {
        let angle = TAU * k as f64 / self.frames.max(1) as f64;
        Light::from_world(self.radius * angle.cos(), self.height, self.radius * angle.sin())
    }

    /// Every light of the path, validated before any request is sent.
    pub fn lights(&self) -> Result<Vec<Light>, LightError> {
        (0..self.frames).map(|k| self.light(k)).collect()
    }
}

/// Fetch one frame per light over the persistent port at `addr`, handing
/// each to `on_frame(index, rgb888)` as it completes. `on_frame` returns
/// `false` to stop early (the window was closed).
pub fn run(
    addr: SocketAddr,
    lights: &[Light],
    mut on_frame: impl FnMut(usize, &[u8]) -> bool,
) -> Result<RunStats, ClientError> {
    let mut stream = net::connect(addr)?;
    let start = Instant::now();
    let mut sent_at: Vec<Instant> = Vec::with_capacity(lights.len());
    let mut latencies: Vec<Duration> = Vec::with_capacity(lights.len());
    let mut frame = vec![0u8; FRAME_BYTES];
    let send = |stream: &mut _, k: usize, sent_at: &mut Vec<Instant>| -> Result<(), ClientError> {
        if let Some(l) = lights.get(k) {
            net::send_request(stream, l)?;
            sent_at.push(Instant::now());
            if k + 1 == lights.len() {
                net::finish_requests(stream)?;
            }
        }
        Ok(())
    };
    if lights.is_empty() {
        net::finish_requests(&stream)?;
    }
    for k in 0..=IN_FLIGHT {
        send(&mut stream, k, &mut sent_at)?;
    }
    for k in 0..lights.len() {
        net::read_frame(&mut stream, k, &mut frame)?;
        latencies.push(sent_at[k].elapsed());
        send(&mut stream, k + IN_FLIGHT + 1, &mut sent_at)?;
        if !on_frame(k, &frame) {
            return Ok(RunStats { elapsed: start.elapsed(), latencies });
        }
    }
    net::expect_eof(&mut stream)?;
    Ok(RunStats { elapsed: start.elapsed(), latencies })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_goes_round() {
        let p = OrbitPath { frames: 4, radius: 3.0, height: 4.0 };
        let raw: Vec<[i32; 3]> = p.lights().unwrap().iter().map(Light::raw).collect();
        assert_eq!(raw[0], [3072, 4096, 0]);
        assert_eq!(raw[1], [0, 4096, 3072]);
        assert_eq!(raw[2], [-3072, 4096, 0]);
        assert_eq!(raw[3], [0, 4096, -3072]);
        assert!(OrbitPath { frames: 2, radius: 9000.0, height: 0.0 }.lights().is_err());
    }
}
