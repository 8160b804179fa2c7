//! The log: text goes into a ring buffer at once and reaches the UART from
//! the main loop, as fast as the UART's FIFO takes it, never waiting.
//!
//! At 115,200 baud a 60-character line takes 5 ms to send; written a byte at
//! a time with a wait for the holding register, every log line would stall
//! the main loop (and the network) for that long.

use core::fmt;

use heapless::Deque;

/// Where the ring drains to: a transmitter that says how many bytes it
/// takes without waiting.
pub trait Transmit {
    /// Bytes that can be pushed now without waiting.
    fn room(&mut self) -> usize;
    /// Push one byte (only after [`room`](Self::room) said there is room).
    fn push(&mut self, byte: u8);
}

/// A log ring of `N` bytes. Text that does not fit is dropped (and counted)
/// rather than waited for.
pub struct LogRing<const N: usize> {
    bytes: Deque<u8, N>,
    dropped: u32,
}

impl<const N: usize> Default for LogRing<N> {
    fn default() -> Self {
        LogRing::new()
    }
}

impl<const N: usize> LogRing<N> {
    /// An empty ring.
    pub const fn new() -> LogRing<N> {
        LogRing { bytes: Deque::new(), dropped: 0 }
    }

    /// Bytes waiting.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// Whether nothing waits.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Bytes dropped because the ring was full.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }

    fn push(&mut self, b: u8) {
        if self.bytes.push_back(b).is_err() {
            self.dropped = self.dropped.saturating_add(1);
        }
    }

    /// Move bytes to `tx` while it has room; returns how many moved. Never
    /// waits: a full FIFO ends the call.
    pub fn drain(&mut self, tx: &mut impl Transmit) -> usize {
        let mut moved = 0;
        loop {
            let room = tx.room();
            if room == 0 {
                return moved;
            }
            for _ in 0..room {
                let Some(b) = self.bytes.pop_front() else {
                    return moved;
                };
                tx.push(b);
                moved += 1;
            }
        }
    }
}

/// Queue text, turning `\n` into `\r\n` for terminals.
impl<const N: usize> fmt::Write for LogRing<N> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for b in s.bytes() {
            if b == b'\n' {
                self.push(b'\r');
            }
            self.push(b);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::fmt::Write;

    /// A FIFO that takes `room` bytes per readiness, `ready` times.
    struct Fifo {
        sent: Vec<u8>,
        room: usize,
        ready: u32,
        room_calls: u32,
    }

    impl Transmit for Fifo {
        fn room(&mut self) -> usize {
            self.room_calls += 1;
            if self.ready == 0 {
                return 0;
            }
            self.ready -= 1;
            self.room
        }
        fn push(&mut self, byte: u8) {
            self.sent.push(byte)
        }
    }

    #[test]
    fn drains_only_while_the_fifo_has_room() {
        let mut ring = LogRing::<64>::new();
        writeln!(ring, "frame {} done", 12).unwrap();
        assert_eq!(ring.len(), 15, "\\n became \\r\\n");
        let mut fifo = Fifo { sent: vec![], room: 4, ready: 2, room_calls: 0 };
        assert_eq!(ring.drain(&mut fifo), 8, "two FIFO loads of 4");
        assert_eq!(fifo.sent, b"frame 12");
        assert_eq!(fifo.room_calls, 3, "asked once more, found it full, returned");
        fifo.ready = 100;
        assert_eq!(ring.drain(&mut fifo), 7);
        assert_eq!(fifo.sent, b"frame 12 done\r\n");
        assert!(ring.is_empty());
    }

    #[test]
    fn a_full_ring_drops_instead_of_waiting() {
        let mut ring = LogRing::<8>::new();
        ring.write_str("0123456789").unwrap();
        assert_eq!((ring.len(), ring.dropped()), (8, 2));
        let mut stuck = Fifo { sent: vec![], room: 16, ready: 0, room_calls: 0 };
        assert_eq!(ring.drain(&mut stuck), 0, "a UART that never drains costs one LSR read");
        assert_eq!(stuck.room_calls, 1);
    }
}
