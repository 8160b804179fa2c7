//! Two boots of one firmware image under QEMU's `-icount` (the board's own
//! time is its instruction count, the same on every boot) must hand out
//! different session ids and SSRCs: the camera's generator is keyed with
//! when frames from the network arrived, which the board does not decide
//! (docs/streaming.md, "Session ids, SSRCs and sequence numbers").

use std::net::SocketAddr;

use crate::images::firmware::Guest;
use crate::support::rtsp_client::RtspSession;
use crate::support::Result;

/// One boot's first session: its id and its stream's SSRC.
fn first_session(elf: &std::path::Path) -> Result<(String, u32)> {
    let g = Guest::boot(elf, &["-icount", "shift=0"])?;
    let f = g.forwards.as_ref().ok_or("the guest has no forwarded ports")?;
    let rtsp = SocketAddr::from(([127, 0, 0, 1], f.rtsp));
    let s = RtspSession::open(rtsp, "/light/3,4,-2?fps=1", None).map_err(|e| format!("{e}\nUART:\n{}", g.uart()))?;
    let seen = (s.session_id().to_string(), s.ssrc);
    s.teardown()?;
    Ok(seen)
}

/// Boot `elf` twice under `-icount` and compare the first sessions.
pub fn run(elf: &std::path::Path) -> Result<String> {
    let a = first_session(elf)?;
    let b = first_session(elf)?;
    if a.0 == b.0 || a.1 == b.1 {
        return Err(format!(
            "two boots under -icount gave session {} / {} and SSRC {:08X} / {:08X}: the generator is not keyed \
             with anything the board does not decide",
            a.0, b.0, a.1, b.1
        ));
    }
    Ok(format!(
        "two boots under -icount: sessions {} and {}, SSRCs {:08X} and {:08X}, all different",
        a.0, b.0, a.1, b.1
    ))
}
