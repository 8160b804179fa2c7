//! What the smoltcp services share (feature `smoltcp`): the buffers a
//! caller lends each TCP socket.

use smoltcp::socket::tcp;

/// The buffers of one TCP socket: `TX` bytes to transmit, `RX` to receive.
/// The transmit buffer comes first and is cache-line aligned: the services
/// copy rows into it a whole number of words at a time, so the copies stay
/// word aligned. Each service names its sizes (`seed::service`,
/// `web::service`).
#[repr(C, align(32))]
pub struct SocketBuffers<const TX: usize, const RX: usize> {
    tx: [u8; TX],
    rx: [u8; RX],
}

impl<const TX: usize, const RX: usize> SocketBuffers<TX, RX> {
    /// Zeroed buffers (usable in a `static`).
    pub const fn new() -> Self {
        SocketBuffers { tx: [0; TX], rx: [0; RX] }
    }

    /// A TCP socket on these buffers.
    pub fn socket(&mut self) -> tcp::Socket<'_> {
        tcp::Socket::new(tcp::SocketBuffer::new(&mut self.rx[..]), tcp::SocketBuffer::new(&mut self.tx[..]))
    }
}

impl<const TX: usize, const RX: usize> Default for SocketBuffers<TX, RX> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transmit_buffer_is_first_and_cache_line_aligned() {
        let b: Box<SocketBuffers<64, 8>> = Box::default();
        assert_eq!(core::mem::align_of::<SocketBuffers<64, 8>>(), 32);
        assert_eq!(b.tx.as_ptr() as usize, &*b as *const _ as usize);
        assert_eq!(b.rx.as_ptr() as usize, b.tx.as_ptr() as usize + 64);
    }
}
