//! Stream URLs: which light a stream renders and how often, as the path
//! and query of an RTSP URL name it (`camera::rtsp`'s module docs list
//! them).

use core::time::Duration;

use heapless::String;
use model::Light;

use crate::orbit::{Orbit, DEFAULT_HEIGHT, DEFAULT_PERIOD, DEFAULT_RADIUS};

/// Frames per second when the URL gives no `fps`.
pub const DEFAULT_FPS: u16 = 30;

/// The highest `fps=N`.
pub const MAX_FPS: u16 = 1000;

/// How often a stream sends a frame.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Fps {
    /// `fps=N`: `N` frames per second, `1..=`[`MAX_FPS`].
    Rate(u16),
    /// `fps=max`: each frame as soon as the one before it is out.
    Max,
}

impl Fps {
    /// The time between frames (`None` for [`Fps::Max`]).
    pub fn interval(self) -> Option<Duration> {
        match self {
            Fps::Rate(n) => Some(Duration::from_secs(1) / u32::from(n.max(1))),
            Fps::Max => None,
        }
    }
}

/// Where a stream's light comes from.
#[derive(Clone, Copy, PartialEq, Debug)]
pub enum LightSource {
    /// `/light/X,Y,Z`: a fixed light.
    Light(Light),
    /// `/orbit`: the light orbiting the sphere.
    Orbit(Orbit),
    /// `/live`: the light `SET_PARAMETER` set last.
    Live,
}

/// A parsed stream URL: the light and the frame rate.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct StreamSpec {
    /// Where the light comes from.
    pub light: LightSource,
    /// The frame rate.
    pub fps: Fps,
    /// `multicast` in the query: the description names the stream's
    /// multicast group. Not part of what the stream is: a multicast and a
    /// unicast viewer of one light at one rate share its frames
    /// ([`StreamSpec::same_frames`]).
    pub multicast: bool,
}

/// Why a URL names no stream.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum UrlError {
    /// The path is none of the streams (404).
    NotFound,
    /// The path is a stream but a parameter is unknown, malformed or out of
    /// range (400).
    BadParameter,
}

impl StreamSpec {
    /// The stream an RTSP URL names (module docs), `rtsp://HOST[:PORT]/...`
    /// or an absolute path `/...`.
    pub fn parse(url: &str) -> Result<StreamSpec, UrlError> {
        let rest = match url.get(..7) {
            Some(scheme) if scheme.eq_ignore_ascii_case("rtsp://") => {
                let after = &url[7..];
                match after.find(['/', '?']) {
                    Some(i) => &after[i..],
                    None => "",
                }
            }
            _ => url,
        };
        let rest = rest.strip_suffix("/trackID=0").unwrap_or(rest);
        let (path, query) = match rest.split_once('?') {
            Some((p, q)) => (p, q),
            None => (rest, ""),
        };
        let path = path.strip_suffix('/').unwrap_or(path);
        let mut fps = Fps::Rate(DEFAULT_FPS);
        let mut multicast = false;
        let (mut radius, mut height, mut period) = (DEFAULT_RADIUS, DEFAULT_HEIGHT, DEFAULT_PERIOD);
        let kind = match path {
            "/live" => Kind::Live,
            "/orbit" => Kind::Orbit,
            _ => match path.strip_prefix("/light/") {
                Some(xyz) => Kind::Light(parse_light(xyz)?),
                None => return Err(UrlError::NotFound),
            },
        };
        for pair in query.split('&').filter(|p| !p.is_empty()) {
            if pair == "multicast" {
                multicast = true;
                continue;
            }
            let (key, value) = pair.split_once('=').ok_or(UrlError::BadParameter)?;
            match (key, kind) {
                ("fps", _) => fps = parse_fps(value)?,
                ("radius", Kind::Orbit) => radius = parse_number(value)?,
                ("height", Kind::Orbit) => height = parse_number(value)?,
                ("period", Kind::Orbit) => {
                    period = Duration::try_from_secs_f64(parse_number(value)?).map_err(|_| UrlError::BadParameter)?
                }
                _ => return Err(UrlError::BadParameter),
            }
        }
        let light = match kind {
            Kind::Light(l) => LightSource::Light(l),
            Kind::Live => LightSource::Live,
            Kind::Orbit => LightSource::Orbit(Orbit::new(radius, height, period).map_err(|_| UrlError::BadParameter)?),
        };
        Ok(StreamSpec { light, fps, multicast })
    }

    /// Whether viewers of `self` and of `other` see the same frames: the
    /// same light (or orbit) at the same rate. A live stream's light is its
    /// session's own, so live streams never share.
    pub fn same_frames(&self, other: &StreamSpec) -> bool {
        self.light != LightSource::Live && self.light == other.light && self.fps == other.fps
    }

    /// The stream's light `t` into the stream (media time: the RTP
    /// timestamp's advance since `PLAY` over [`RTP_CLOCK_HZ`](super::sdp::RTP_CLOCK_HZ), pauses left
    /// out); `live` is the light `SET_PARAMETER` set last (or
    /// [`Config::live_light`](super::sender::Config::live_light)), used by [`LightSource::Live`].
    pub fn light_at(&self, t: Duration, live: Light) -> Light {
        match self.light {
            LightSource::Light(l) => l,
            LightSource::Orbit(o) => o.light_at(t),
            LightSource::Live => live,
        }
    }
}

/// The path part of a stream URL, before its parameters are read.
#[derive(Clone, Copy)]
enum Kind {
    Light(Light),
    Orbit,
    Live,
}

/// `X,Y,Z` in world units, percent-encoded commas (`%2C`) allowed, or
/// `X/Y/Z` as the control URL writes it ([`ControlUrl`]).
fn parse_light(text: &str) -> Result<Light, UrlError> {
    let mut decoded: String<64> = String::new();
    let mut bytes = text.bytes();
    while let Some(b) = bytes.next() {
        let c = if b == b'%' {
            let hex = |d: Option<u8>| d.and_then(|d| char::from(d).to_digit(16));
            let (hi, lo) = (hex(bytes.next()), hex(bytes.next()));
            match (hi, lo) {
                (Some(hi), Some(lo)) => (hi * 16 + lo) as u8,
                _ => return Err(UrlError::BadParameter),
            }
        } else {
            b
        };
        let c = if b == b'/' { b',' } else { c };
        if !c.is_ascii() || decoded.push(char::from(c)).is_err() {
            return Err(UrlError::BadParameter);
        }
    }
    decoded.parse::<Light>().map_err(|_| UrlError::BadParameter)
}

/// A stream URL as its control URL: the SDP's `a=control`, which players
/// set the stream up with and which `RTP-Info` names the stream by again.
/// A light's commas (or `%2C`) become slashes (`/light/3/4/-2`): the
/// header separates streams with `,` and parameters with `;` (RFC 2326,
/// section 12.33), and GStreamer and FFmpeg compare its URL with their
/// `SETUP` URL byte for byte without decoding escapes, so the control URL
/// holds neither and needs no escape. Everything else is written as given.
#[derive(Clone, Copy, Debug)]
pub struct ControlUrl<'a>(pub &'a str);

impl core::fmt::Display for ControlUrl<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let url = self.0;
        let path_end = url.find('?').unwrap_or(url.len());
        let Some(light_at) = url[..path_end].find("/light/") else { return f.write_str(url) };
        let start = light_at + "/light/".len();
        f.write_str(&url[..start])?;
        let mut rest = &url[start..path_end];
        while !rest.is_empty() {
            if rest.starts_with(',') {
                f.write_str("/")?;
                rest = &rest[1..];
            } else if rest.get(..3).is_some_and(|e| e.eq_ignore_ascii_case("%2C")) {
                f.write_str("/")?;
                rest = &rest[3..];
            } else {
                let next = rest.find([',', '%']).map_or(rest.len(), |i| i.max(1));
                f.write_str(&rest[..next])?;
                rest = &rest[next..];
            }
        }
        f.write_str(&url[path_end..])
    }
}

fn parse_number(text: &str) -> Result<f64, UrlError> {
    text.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or(UrlError::BadParameter)
}

fn parse_fps(text: &str) -> Result<Fps, UrlError> {
    if text.eq_ignore_ascii_case("max") {
        return Ok(Fps::Max);
    }
    match text.parse::<u16>() {
        Ok(n) if (1..=MAX_FPS).contains(&n) && text.bytes().all(|b| b.is_ascii_digit()) => Ok(Fps::Rate(n)),
        _ => Err(UrlError::BadParameter),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(x: f64, y: f64, z: f64) -> Light {
        Light::from_world(x, y, z).unwrap()
    }

    #[test]
    fn stream_urls_parse() {
        let fixed = StreamSpec::parse("rtsp://board:8554/light/3,4,-2").unwrap();
        assert_eq!(
            fixed,
            StreamSpec { light: LightSource::Light(light(3.0, 4.0, -2.0)), fps: Fps::Rate(30), multicast: false }
        );
        let spec = |u| StreamSpec::parse(u);
        assert_eq!(spec("rtsp://board/light/0.5,2,-1.25?fps=60").unwrap().fps, Fps::Rate(60));
        assert_eq!(spec("/light/3%2C4%2c-2/").unwrap(), fixed, "an absolute path, encoded commas, a trailing slash");
        assert_eq!(spec("RTSP://board:8554/light/3,4,-2/trackID=0").unwrap(), fixed);
        assert_eq!(
            spec("rtsp://10.0.0.2:8554/live").unwrap(),
            StreamSpec { light: LightSource::Live, fps: Fps::Rate(30), multicast: false }
        );
        assert_eq!(spec("rtsp://h/live?fps=max").unwrap().fps, Fps::Max);
        assert_eq!(spec("rtsp://h/live?fps=MAX/trackID=0").unwrap().fps, Fps::Max);
        let orbit = |r, h, p| LightSource::Orbit(Orbit::new(r, h, Duration::from_secs_f64(p)).unwrap());
        assert_eq!(spec("rtsp://h/orbit").unwrap().light, orbit(3.0, 4.0, 2.0), "rt-client orbit's defaults");
        assert_eq!(spec("rtsp://h/orbit?").unwrap().light, orbit(3.0, 4.0, 2.0));
        assert_eq!(spec("rtsp://h/orbit?height=6").unwrap().light, orbit(3.0, 6.0, 2.0));
        let full = spec("rtsp://h:8554/orbit?radius=5&height=-1.5&period=8&fps=12").unwrap();
        assert_eq!(full, StreamSpec { light: orbit(5.0, -1.5, 8.0), fps: Fps::Rate(12), multicast: false });
        assert_eq!(spec("rtsp://h/orbit?period=0.5&&radius=2").unwrap().light, orbit(2.0, 4.0, 0.5));
        let group = spec("rtsp://h/light/3,4,-2?multicast&fps=30").unwrap();
        assert!(group.multicast && group.same_frames(&fixed) && fixed.same_frames(&group));
        assert!(!spec("/live").unwrap().same_frames(&spec("/live").unwrap()), "a live light is its session's");
        assert!(!fixed.same_frames(&spec("/light/3,4,-2?fps=31").unwrap()));
        assert_eq!(Fps::Rate(30).interval(), Some(Duration::from_nanos(33_333_333)));
        assert_eq!(Fps::Max.interval(), None);
    }

    #[test]
    fn bad_stream_urls_are_told_apart() {
        for url in ["rtsp://h", "rtsp://h/", "*", "rtsp://h/lights/1,2,3", "rtsp://h/light", "rtsp://h/orbit/x", "live"]
        {
            assert_eq!(StreamSpec::parse(url), Err(UrlError::NotFound), "{url}");
        }
        for url in [
            "rtsp://h/light/1,2",
            "rtsp://h/light/1,2,3,4",
            "rtsp://h/light/1,x,3",
            "rtsp://h/light/9000,0,0",
            "rtsp://h/light/1%2,2,3",
            "rtsp://h/light/1%E2%82%AC,2,3",
            "rtsp://h/live?fps=0",
            "rtsp://h/live?fps=1001",
            "rtsp://h/live?fps=+5",
            "rtsp://h/live?fps",
            "rtsp://h/live?radius=3",
            "rtsp://h/light/1,2,3?period=3",
            "rtsp://h/orbit?radius=9000",
            "rtsp://h/orbit?radius=nan",
            "rtsp://h/orbit?height=inf",
            "rtsp://h/orbit?period=0",
            "rtsp://h/orbit?period=-1",
            "rtsp://h/orbit?period=1e30",
            "rtsp://h/orbit?colour=red",
            "rtsp://h/orbit?multicast=1",
        ] {
            assert_eq!(StreamSpec::parse(url), Err(UrlError::BadParameter), "{url}");
        }
    }

    #[test]
    fn the_light_of_a_stream_at_a_time() {
        let live = light(1.0, 2.0, 3.0);
        let fixed = StreamSpec::parse("/light/3,4,-2").unwrap();
        assert_eq!(fixed.light_at(Duration::from_secs(99), live), light(3.0, 4.0, -2.0));
        let orbit = StreamSpec::parse("/orbit?period=4").unwrap();
        assert_eq!(orbit.light_at(Duration::ZERO, live), light(3.0, 4.0, 0.0));
        assert_eq!(orbit.light_at(Duration::from_secs(1), live), light(0.0, 4.0, 3.0));
        assert_eq!(orbit.light_at(Duration::from_secs(6), live), light(-3.0, 4.0, 0.0));
        assert_eq!(StreamSpec::parse("/live").unwrap().light_at(Duration::from_secs(5), live), live);
    }
}
