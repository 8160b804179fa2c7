//! The wire protocol from the client's side.

use std::fmt;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream, ToSocketAddrs};
use std::time::Duration;

use model::{Light, FRAME_BYTES};
use rt_services::{encode_request, persistent_port, FRAME_PORT};

/// How long a read may stall before the client gives up on the server.
const READ_TIMEOUT: Duration = Duration::from_secs(30);

/// A client-side failure, worded for one line on the terminal.
#[derive(Debug)]
pub enum ClientError {
    /// The server address did not resolve.
    Resolve(String, io::Error),
    /// The TCP connection failed.
    Connect(SocketAddr, io::Error),
    /// The server closed after `got` of the frame's bytes.
    ShortFrame {
        /// Frame index within the run.
        frame: usize,
        /// Bytes of that frame received.
        got: usize,
    },
    /// The server sent more than it was asked for.
    ExtraBytes,
    /// What answered is another of the board's services, not its frame
    /// port: the answer began as `what`'s does.
    WrongService {
        /// Where it answered.
        addr: SocketAddr,
        /// Which service it looked like.
        what: &'static str,
    },
    /// The frame port has no port above it for the persistent protocol.
    NoPersistentPort(SocketAddr),
    /// Reading or writing failed.
    Io(&'static str, io::Error),
}

impl fmt::Display for ClientError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClientError::Resolve(s, e) => write!(f, "cannot resolve {s}: {e}"),
            ClientError::Connect(a, e) if e.kind() == io::ErrorKind::ConnectionRefused => {
                write!(f, "connection to {a} refused: is the server running?")
            }
            ClientError::Connect(a, e) => write!(f, "cannot connect to {a}: {e}"),
            ClientError::ShortFrame { frame, got } => write!(
                f,
                "short frame: the server closed after {got} of {FRAME_BYTES} bytes of frame {frame} \
                 (light out of range, or the server failed)"
            ),
            ClientError::ExtraBytes => f.write_str("the server sent bytes after the last frame"),
            ClientError::WrongService { addr, what } => write!(
                f,
                "{addr} answered as {what}, not as the frame port: give the board's frame port, \
                 HOST:{FRAME_PORT} (or the host alone)"
            ),
            ClientError::NoPersistentPort(a) => {
                write!(f, "{a}: the persistent port is the frame port + 1, and port 65535 has none")
            }
            ClientError::Io(what, e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                write!(
                    f,
                    "{what}: no data from the server for {} s (is it the board's frame port? does the board's \
                     /status page or UART say it renders?)",
                    READ_TIMEOUT.as_secs()
                )
            }
            ClientError::Io(what, e) => write!(f, "{what}: {e}"),
        }
    }
}

impl std::error::Error for ClientError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ClientError::Resolve(_, e) | ClientError::Connect(_, e) | ClientError::Io(_, e) => Some(e),
            _ => None,
        }
    }
}

/// `server` with `port` added when it names a host alone (`board.local`,
/// `192.168.1.20`, `::1`, `[::1]`).
pub fn with_port(server: &str, port: u16) -> String {
    let has_port = server.parse::<SocketAddr>().is_ok()
        || server.rsplit_once(':').is_some_and(|(h, p)| !h.contains(':') && p.parse::<u16>().is_ok());
    if has_port {
        server.to_string()
    } else if server.contains(':') && !server.starts_with('[') {
        format!("[{server}]:{port}")
    } else {
        format!("{server}:{port}")
    }
}

/// `server` with the frame port added when it names a host alone.
pub fn with_frame_port(server: &str) -> String {
    with_port(server, FRAME_PORT)
}

/// Resolve `HOST:PORT`, or `HOST` on the frame port, to its first address.
pub fn resolve(server: &str) -> Result<SocketAddr, ClientError> {
    let target = with_frame_port(server);
    target
        .to_socket_addrs()
        .map_err(|e| ClientError::Resolve(server.into(), e))?
        .next()
        .ok_or_else(|| ClientError::Resolve(server.into(), io::ErrorKind::NotFound.into()))
}

/// The service whose answer `bytes` begins like, if it is not a frame's:
/// the board's web page (HTTP) or its camera (RTSP).
fn service_of(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"HTTP/1.") {
        Some("a web server (the board's page is on port 80)")
    } else if bytes.starts_with(b"RTSP/1.") {
        Some("an RTSP server (the board's camera is on port 8554)")
    } else {
        None
    }
}

/// The persistent port's address: the frame port + 1 (a frame port of
/// 65535 has none).
pub fn persistent_addr(frame_addr: SocketAddr) -> Result<SocketAddr, ClientError> {
    persistent_port(frame_addr.port())
        .map(|p| SocketAddr::new(frame_addr.ip(), p))
        .ok_or(ClientError::NoPersistentPort(frame_addr))
}

/// Connect with the client's timeouts.
pub fn connect(addr: SocketAddr) -> Result<TcpStream, ClientError> {
    let s = TcpStream::connect_timeout(&addr, Duration::from_secs(10)).map_err(|e| ClientError::Connect(addr, e))?;
    s.set_read_timeout(Some(READ_TIMEOUT)).map_err(|e| ClientError::Io("socket setup", e))?;
    let _ = s.set_nodelay(true);
    Ok(s)
}

/// Read exactly one frame into `out`; `index` names it in errors.
pub fn read_frame(stream: &mut TcpStream, index: usize, out: &mut [u8]) -> Result<(), ClientError> {
    let mut got = 0;
    let wrong = |got: usize, out: &[u8], stream: &TcpStream| {
        let what = service_of(&out[..got])?;
        Some(ClientError::WrongService { addr: stream.peer_addr().ok()?, what })
    };
    while got < out.len() {
        match stream.read(&mut out[got..]) {
            Ok(0) => return Err(wrong(got, out, stream).unwrap_or(ClientError::ShortFrame { frame: index, got })),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) if e.kind() == io::ErrorKind::ConnectionReset => {
                return Err(ClientError::ShortFrame { frame: index, got })
            }
            Err(e) => return Err(ClientError::Io("receiving a frame", e)),
        }
    }
    Ok(())
}

/// Expect the server to close now.
pub fn expect_eof(stream: &mut TcpStream) -> Result<(), ClientError> {
    let mut byte = [0u8; 1];
    match stream.read(&mut byte) {
        Ok(0) => Ok(()),
        Ok(_) => Err(ClientError::ExtraBytes),
        Err(e) if e.kind() == io::ErrorKind::ConnectionReset => Ok(()),
        Err(e) => Err(ClientError::Io("waiting for the server to close", e)),
    }
}

/// One frame over the seed protocol (the frame port).
pub fn fetch_frame(addr: SocketAddr, light: &Light) -> Result<Vec<u8>, ClientError> {
    let mut s = connect(addr)?;
    s.write_all(&encode_request(light)).map_err(|e| ClientError::Io("sending the request", e))?;
    let mut frame = vec![0u8; FRAME_BYTES];
    read_frame(&mut s, 0, &mut frame)?;
    expect_eof(&mut s)?;
    Ok(frame)
}

/// Send a request on a persistent connection.
pub fn send_request(stream: &mut TcpStream, light: &Light) -> Result<(), ClientError> {
    stream.write_all(&encode_request(light)).map_err(|e| ClientError::Io("sending a request", e))
}

/// Tell the server no more requests will come.
pub fn finish_requests(stream: &TcpStream) -> Result<(), ClientError> {
    stream.shutdown(Shutdown::Write).map_err(|e| ClientError::Io("closing the request stream", e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    #[test]
    fn a_host_alone_means_the_frame_port() {
        assert_eq!(with_frame_port("192.168.1.20"), "192.168.1.20:7878");
        assert_eq!(with_frame_port("raytracer.local"), "raytracer.local:7878");
        assert_eq!(with_frame_port("::1"), "[::1]:7878");
        assert_eq!(with_frame_port("[::1]"), "[::1]:7878");
        assert_eq!(with_frame_port("127.0.0.1:9000"), "127.0.0.1:9000");
        assert_eq!(with_frame_port("[::1]:9000"), "[::1]:9000");
        assert_eq!(resolve("127.0.0.1").unwrap(), SocketAddr::from(([127, 0, 0, 1], FRAME_PORT)));
    }

    /// A server on another of the board's ports answers the 12 bytes with
    /// its own protocol's error and closes: named, not "short frame".
    #[test]
    fn the_web_page_or_the_camera_on_the_frame_port_is_named() {
        for (answer, named) in [
            (&b"HTTP/1.1 400 Bad Request\r\nConnection: close\r\n\r\n"[..], "web server"),
            (&b"RTSP/1.0 400 Bad Request\r\n\r\n"[..], "RTSP server"),
        ] {
            let listener = TcpListener::bind("127.0.0.1:0").unwrap();
            let addr = listener.local_addr().unwrap();
            let server = std::thread::spawn(move || {
                let (mut s, _) = listener.accept().unwrap();
                let mut request = [0u8; 12];
                s.read_exact(&mut request).unwrap();
                s.write_all(answer).unwrap();
            });
            let light = Light::from_raw(3072, 4096, -2048).unwrap();
            let e = fetch_frame(addr, &light).unwrap_err().to_string();
            server.join().unwrap();
            assert!(e.contains(named) && e.contains("not as the frame port"), "{e}");
        }
    }
}
