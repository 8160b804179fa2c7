//! The wire protocol from the client's side.

use std::fmt;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream, ToSocketAddrs};
use std::time::Duration;

use model::{Light, FRAME_BYTES};
use rt_services::{encode_request, persistent_port};

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
            ClientError::NoPersistentPort(a) => {
                write!(f, "{a}: the persistent port is the frame port + 1, and port 65535 has none")
            }
            ClientError::Io(what, e) if e.kind() == io::ErrorKind::WouldBlock => {
                write!(f, "{what}: no data from the server for {} s", READ_TIMEOUT.as_secs())
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

/// Resolve `HOST:PORT` to its first address.
pub fn resolve(server: &str) -> Result<SocketAddr, ClientError> {
    server
        .to_socket_addrs()
        .map_err(|e| ClientError::Resolve(server.into(), e))?
        .next()
        .ok_or_else(|| ClientError::Resolve(server.into(), io::ErrorKind::NotFound.into()))
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
    while got < out.len() {
        match stream.read(&mut out[got..]) {
            Ok(0) => return Err(ClientError::ShortFrame { frame: index, got }),
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
