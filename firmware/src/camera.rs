//! The board as a network camera: `rt_services::camera::service` (RTSP on
//! TCP port 8554, RTP/RTCP on UDP 5004/5005) over the frame ring, its rows
//! leaving zero-copy: each packet is one two-buffer descriptor of the
//! DesignWare MAC, buffer 1 the 62-byte header, buffer 2 the row where the
//! FPGA wrote it in the ring (`dwmac::Dwmac::send_split_run`). The CPU never
//! reads a pixel on this path.
//!
//! Coherence: the ring's rows are in DRAM when a packet points at them:
//! the FPGA-to-SDRAM port writes behind the caches, and the CPU cleans
//! everything it writes there (render.rs, `RingMemory`). The MAC reads
//! DRAM through the L3 interconnect, so no maintenance is needed here.

use dwmac::desc::ChecksumInsertion;
use dwmac::{DmaSync, Dwmac, SplitSeq};
use embedded_hal::delay::DelayNs;
use model::ROW_BYTES;
use rt_services::camera::frame_header::{HeaderTemplate, HEADER_PAD, HEADER_WORDS};
use rt_services::camera::packetiser::Packetiser;
use rt_services::camera::service::RowTransmitter;
use rt_services::camera::wire::rtp::RowPacket;

use crate::limits::RING_SLOTS;

// The header words' padding is the MAC's transmit skew.
const _: () = assert!(HEADER_PAD == dwmac::ring::TX_SKEW);

/// Rows out through the MAC's two-buffer descriptors.
pub struct ZeroCopy<'m, 'a, S, D> {
    /// The MAC.
    pub mac: &'m mut Dwmac<'a, S, D>,
    /// Bus address of each ring slot.
    pub slots: &'m [u32; RING_SLOTS],
    /// The newest descriptor pointing into each slot.
    pub in_flight: &'m mut [Option<SplitSeq>; RING_SLOTS],
    /// Rows dropped as malformed (never expected: headers are 62 bytes).
    pub refused: &'m mut u32,
    /// The checksum insertion of the first run's header, for all after it:
    /// every header is `frame_header::HeaderTemplate`'s (Ethernet II, IPv4 without
    /// fragments, UDP), which takes the same insertion.
    pub cic: Option<ChecksumInsertion>,
}

impl<S: DmaSync, D: DelayNs> RowTransmitter for ZeroCopy<'_, '_, S, D> {
    fn send_run(
        &mut self,
        template: &mut HeaderTemplate,
        session: &Packetiser,
        first: &RowPacket,
        count: u16,
        slot: usize,
    ) -> u16 {
        let Some(&base) = self.slots.get(slot) else {
            *self.refused += u32::from(count);
            return count;
        };
        let mac = &mut *self.mac;
        let cic = *self.cic.get_or_insert_with(|| mac.checksum_for(&template.current().bytes()));
        let payload = base + u32::from(first.row) * ROW_BYTES as u32;
        let run = self.mac.send_split_run(
            usize::from(count),
            HEADER_WORDS,
            cic,
            payload,
            ROW_BYTES as u32,
            ROW_BYTES,
            |k, out| out.copy_from_slice(&template.words(session, &first.nth(k as u16)).0),
        );
        match run {
            Ok((n, newest)) => {
                if newest.is_some() {
                    self.in_flight[slot] = newest;
                }
                // At most `count`: the run takes no more than it is given.
                n as u16
            }
            Err(_) => {
                // Never expected: every header is 62 bytes.
                *self.refused += u32::from(count);
                count
            }
        }
    }

    fn checksum_offload(&self) -> bool {
        self.mac.checksum_insertion() == ChecksumInsertion::Full
    }

    fn receive_waiting(&self) -> bool {
        self.mac.rx_waiting()
    }
}

/// The slots some descriptor still points into (bit `i`: slot `i`);
/// forgets the finished ones.
pub fn slots_in_flight<S: DmaSync, D: DelayNs>(
    mac: &mut Dwmac<'_, S, D>,
    in_flight: &mut [Option<SplitSeq>; RING_SLOTS],
) -> u32 {
    // One reclaim for all slots: split frames complete in ring order.
    let done = mac.split_completed();
    let mut mask = 0;
    for (i, seq) in in_flight.iter_mut().enumerate() {
        match *seq {
            Some(s) if s >= done => mask |= 1 << i,
            _ => *seq = None,
        }
    }
    mask
}
