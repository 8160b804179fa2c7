//! What every TCP service does with a connection on std: a cap on how many
//! are served at once, a reader thread feeding the serving thread, and a
//! close that does not lose the peer's last bytes.

use std::io::{self, Read};
use std::net::{Shutdown, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

/// How long a closing connection waits for the client's end of stream
/// before it is dropped (closing with unread input would reset the
/// connection and could cost the client the frame's tail).
const LINGER: Duration = Duration::from_secs(2);

/// Connections served at once, as the board has sockets: each costs two
/// threads (its own and its reader), so a flood of connections must not
/// start threads without bound. One more is closed at once, as the board
/// answers a SYN with no socket listening with a reset.
#[derive(Debug)]
pub(crate) struct ConnectionCap {
    open: AtomicUsize,
    max: usize,
}

/// One connection's place under a [`ConnectionCap`], given back on drop.
pub(crate) struct Place(Arc<ConnectionCap>);

impl ConnectionCap {
    pub(crate) fn new(max: usize) -> Arc<ConnectionCap> {
        Arc::new(ConnectionCap { open: AtomicUsize::new(0), max })
    }

    /// A place, if one is free.
    pub(crate) fn take(self: &Arc<Self>) -> Option<Place> {
        self.open
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| (n < self.max).then_some(n + 1))
            .ok()
            .map(|_| Place(self.clone()))
    }
}

impl Drop for Place {
    fn drop(&mut self) {
        self.0.open.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Input from the reader thread.
pub(crate) enum Input {
    Bytes(Vec<u8>),
    End,
}

/// Shuts a connection's socket when dropped: however its serving thread
/// ends (a panic too), the reader thread's copy of the socket then reads
/// its end and the peer sees the connection close, instead of both
/// waiting on a socket nobody serves.
pub(crate) struct ShutOnDrop<'a>(pub(crate) &'a TcpStream);

impl Drop for ShutOnDrop<'_> {
    fn drop(&mut self) {
        let _ = self.0.shutdown(Shutdown::Both);
    }
}

/// A thread that reads `stream` and hands over what it reads, then its end.
pub(crate) fn spawn_reader(mut stream: TcpStream) -> io::Result<Receiver<Input>> {
    let (tx, rx) = mpsc::sync_channel(64);
    thread::Builder::new().name("reader".into()).spawn(move || {
        let mut buf = [0u8; 4096];
        loop {
            match stream.read(&mut buf) {
                Ok(0) | Err(_) => {
                    let _ = tx.send(Input::End);
                    return;
                }
                Ok(n) => {
                    if tx.send(Input::Bytes(buf[..n].to_vec())).is_err() {
                        return;
                    }
                }
            }
        }
    })?;
    Ok(rx)
}

/// Send FIN after the queued bytes, then wait (bounded) for the client to
/// finish so no unread input turns the close into a reset; then shut the
/// socket, so that the reader thread (which holds a copy of it) ends even
/// when the client never closes its side.
pub(crate) fn close_gracefully(stream: &TcpStream, input: &Receiver<Input>, input_ended: bool) {
    let _ = stream.shutdown(Shutdown::Write);
    if !input_ended {
        let deadline = Instant::now() + LINGER;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match input.recv_timeout(left) {
                Ok(Input::Bytes(_)) => {}
                Ok(Input::End) | Err(_) => break,
            }
        }
    }
    let _ = stream.shutdown(Shutdown::Both);
}
