//! "A slow viewer slows only itself": a viewer that plays a stream inside
//! its RTSP connection and never reads ([`never_reading_viewer`]), and the
//! comparison of another viewer's rate alone and beside it
//! ([`slows_only_itself`]), shared by the emulated board's check
//! (`per-host`) and hps-sim's (`viewers`).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::thread;
use std::time::{Duration, Instant};

use super::Result;

/// Open an RTSP connection to `rtsp` with a 4 KiB receive buffer, `SETUP`
/// `url` interleaved and `PLAY` it, then never read: the stream stays
/// open until the returned connection is dropped.
pub fn never_reading_viewer(rtsp: SocketAddr, url: &str) -> Result<TcpStream> {
    let c = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).map_err(|e| e.to_string())?;
    c.set_recv_buffer_size(4096).map_err(|e| e.to_string())?;
    c.connect_timeout(&rtsp.into(), Duration::from_secs(5)).map_err(|e| e.to_string())?;
    let mut c: TcpStream = c.into();
    c.set_read_timeout(Some(Duration::from_secs(5))).map_err(|e| e.to_string())?;
    let setup =
        format!("SETUP {url}/trackID=0 RTSP/1.0\r\nCSeq: 1\r\nTransport: RTP/AVP/TCP;unicast;interleaved=0-1\r\n\r\n");
    c.write_all(setup.as_bytes()).map_err(|e| e.to_string())?;
    let mut head = Vec::new();
    let mut b = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        c.read_exact(&mut b).map_err(|e| format!("the laggard's SETUP: {e}"))?;
        head.push(b[0]);
    }
    let text = String::from_utf8_lossy(&head).into_owned();
    let session = text
        .lines()
        .find_map(|l| l.strip_prefix("Session: "))
        .and_then(|s| s.split(';').next())
        .ok_or(format!("the laggard's SETUP: {text:?}"))?
        .to_string();
    c.write_all(format!("PLAY {url} RTSP/1.0\r\nCSeq: 2\r\nSession: {session}\r\n\r\n").as_bytes())
        .map_err(|e| e.to_string())?;
    Ok(c)
}

/// The least share of its rate alone a viewer keeps beside a laggard.
pub const FLOOR: f64 = 0.9;

/// Compare a viewer's rate alone and beside a laggard that
/// `start_laggard` starts (and dropping it stops); `rate` measures the
/// viewer's frames a second over one phase; `who` names the check in its
/// lines.
///
/// Rates on a loaded machine swing by a third between phases of the same
/// conditions (seen under QEMU: 2.40 then 3.30, and 2.00 then 3.10
/// frames/s alone), and drift within a run: phases alternate, alone,
/// beside the laggard, alone, beside it, alone, and the two means are
/// compared; a miss is measured once more. A laggard that holds the
/// stream (one frame per stall limit) misses both.
pub fn slows_only_itself<L>(
    who: &str,
    rate: impl Fn() -> Result<f64>,
    start_laggard: impl Fn() -> Result<L>,
) -> Result<()> {
    for attempt in 1..=2 {
        let (mut alone, mut beside) = (vec![rate()?], vec![]);
        for _ in 0..2 {
            let laggard = start_laggard()?;
            beside.push(rate()?);
            drop(laggard);
            alone.push(rate()?);
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (alone_mean, beside_mean) = (mean(&alone), mean(&beside));
        let shown = |v: &[f64]| v.iter().map(|r| format!("{r:.2}")).collect::<Vec<_>>().join(", ");
        println!(
            "{who}: a UDP viewer: {} frames/s alone, {} beside a never-reading interleaved viewer of its stream \
             (means {alone_mean:.2} and {beside_mean:.2}: {:.0}%)",
            shown(&alone),
            shown(&beside),
            100.0 * beside_mean / alone_mean
        );
        if beside_mean >= FLOOR * alone_mean {
            return Ok(());
        }
        if attempt == 1 {
            println!("{who}: under {:.0}% of the rate alone: measuring once more", FLOOR * 100.0);
        } else {
            return Err(format!(
                "{who}: a never-reading viewer held a UDP viewer of its stream to {beside_mean:.2} frames/s \
                 (alone {alone_mean:.2}), twice"
            ));
        }
    }
    unreachable!("the second attempt returns")
}

/// The rate of a viewer already playing over the next `phase`, from
/// `frames`, its whole frames so far (waiting up to a minute for its
/// first).
pub fn rate_over(phase: Duration, frames: &impl Fn() -> usize) -> Result<f64> {
    let deadline = Instant::now() + Duration::from_secs(60);
    while frames() == 0 && Instant::now() < deadline {
        thread::sleep(Duration::from_millis(50));
    }
    if frames() == 0 {
        return Err("the viewer got no frame in 60 s".into());
    }
    let (start, before) = (Instant::now(), frames());
    thread::sleep(phase);
    Ok((frames() - before) as f64 / start.elapsed().as_secs_f64())
}
