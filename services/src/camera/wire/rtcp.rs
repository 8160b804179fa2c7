//! RTCP packets for the camera (RFC 3550 section 6, RFC 4585): sender
//! reports, an SDES CNAME, BYE, receiver reports, and the receivers' generic
//! NACKs. Formats only; when to send a report is
//! [`ReportTimer`](crate::camera::report_timer::ReportTimer)'s.

use core::time::Duration;

use super::rtp::{front, BufferTooShort};

/// RTCP packet type of a sender report (RFC 3550 section 6.4.1).
pub const RTCP_SR: u8 = 200;
/// RTCP packet type of a receiver report (RFC 3550 section 6.4.2).
pub const RTCP_RR: u8 = 201;
/// RTCP packet type of source description items (RFC 3550 section 6.5).
pub const RTCP_SDES: u8 = 202;
/// RTCP packet type of transport-layer feedback (RFC 4585 section 6.1).
pub const RTCP_RTPFB: u8 = 205;
/// The FMT of a generic NACK in transport-layer feedback (RFC 4585
/// section 6.2.1).
pub const FMT_GENERIC_NACK: u8 = 1;

/// Bytes of a sender report without report blocks (RFC 3550 section
/// 6.4.1): header 4, SSRC 4, sender info 20.
pub const SENDER_REPORT_BYTES: usize = 28;

/// Seconds from the NTP era 0 origin (1900-01-01) to the Unix epoch.
const NTP_UNIX_OFFSET: u64 = 2_208_988_800;

/// The 64-bit NTP timestamp (RFC 3550 section 4: seconds since 1900 in the
/// high 32 bits, the fraction in the low 32; era 0 wraps in 2036) of a wall
/// clock reading `since_unix_epoch`.
pub const fn ntp_timestamp(since_unix_epoch: Duration) -> u64 {
    let secs = since_unix_epoch.as_secs().wrapping_add(NTP_UNIX_OFFSET) & 0xffff_ffff;
    let frac = ((since_unix_epoch.subsec_nanos() as u64) << 32) / 1_000_000_000;
    secs << 32 | frac
}

/// The first word of an RTCP packet: V = 2, padding, the count (or FMT)
/// field, the packet type, and the length in 32-bit words minus one (RFC
/// 3550 section 6.4.1).
fn rtcp_header(count: u8, pt: u8, bytes: usize) -> [u8; 4] {
    let words = (bytes / 4 - 1) as u16;
    let [hi, lo] = words.to_be_bytes();
    [2 << 6 | (count & 0x1f), pt, hi, lo]
}

/// An RTCP sender report without reception report blocks (RFC 3550
/// section 6.4.1): the stream's sender never receives RTP, so RC = 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SenderReport {
    /// The sender's SSRC.
    pub ssrc: u32,
    /// The wall clock when the report was made, NTP format
    /// ([`ntp_timestamp`]).
    pub ntp_timestamp: u64,
    /// The same instant on the RTP clock, with the data packets' offset.
    pub rtp_timestamp: u32,
    /// RTP data packets sent since the session started (wrapping).
    pub packet_count: u32,
    /// RTP payload octets sent since the session started (wrapping; the
    /// RFC 4175 payload headers and the rows, not the RTP headers).
    pub octet_count: u32,
}

impl SenderReport {
    /// Write the report, [`SENDER_REPORT_BYTES`] bytes, into the front of
    /// `out`; returns the bytes written. An RTCP compound packet begins
    /// with it (RFC 3550 section 6.1); [`write_sdes_cname`] writes the
    /// CNAME that should follow.
    pub fn write(&self, out: &mut [u8]) -> Result<usize, BufferTooShort> {
        let out = front(out, SENDER_REPORT_BYTES)?;
        out[0..4].copy_from_slice(&rtcp_header(0, RTCP_SR, SENDER_REPORT_BYTES));
        out[4..8].copy_from_slice(&self.ssrc.to_be_bytes());
        out[8..16].copy_from_slice(&self.ntp_timestamp.to_be_bytes());
        out[16..20].copy_from_slice(&self.rtp_timestamp.to_be_bytes());
        out[20..24].copy_from_slice(&self.packet_count.to_be_bytes());
        out[24..28].copy_from_slice(&self.octet_count.to_be_bytes());
        Ok(SENDER_REPORT_BYTES)
    }
}

/// Bytes of an SDES packet with one chunk holding one CNAME of
/// `cname_len` octets: header 4, SSRC 4, item type and length 2, the text,
/// and 1 to 4 null octets ending the item list at a 32-bit boundary (RFC
/// 3550 section 6.5).
pub const fn sdes_cname_bytes(cname_len: usize) -> usize {
    8 + ((2 + cname_len) / 4 + 1) * 4
}

/// Write an SDES packet with `ssrc`'s CNAME item (RFC 3550 section 6.5.1:
/// every compound RTCP packet carries one, after the report) into the
/// front of `out`; returns the bytes written ([`sdes_cname_bytes`]). A
/// CNAME longer than 255 octets (the item's length field) is cut there.
pub fn write_sdes_cname(ssrc: u32, cname: &[u8], out: &mut [u8]) -> Result<usize, BufferTooShort> {
    let cname = cname.get(..255).unwrap_or(cname);
    let n = sdes_cname_bytes(cname.len());
    let out = front(out, n)?;
    out[0..4].copy_from_slice(&rtcp_header(1, RTCP_SDES, n));
    out[4..8].copy_from_slice(&ssrc.to_be_bytes());
    out[8] = 1; // CNAME
    out[9] = cname.len() as u8;
    out[10..10 + cname.len()].copy_from_slice(cname);
    out[10 + cname.len()..].fill(0);
    Ok(n)
}

/// RTCP packet type of a goodbye (RFC 3550 section 6.6).
pub const RTCP_BYE: u8 = 203;

/// Bytes of a BYE for one SSRC, without a reason.
pub const BYE_BYTES: usize = 8;

/// Write a BYE for `ssrc` (RFC 3550 section 6.6: the source leaves; it
/// goes last in a compound packet that begins with a report) into the
/// front of `out`; returns the bytes written ([`BYE_BYTES`]).
pub fn write_bye(ssrc: u32, out: &mut [u8]) -> Result<usize, BufferTooShort> {
    let out = front(out, BYE_BYTES)?;
    out[0..4].copy_from_slice(&rtcp_header(1, RTCP_BYE, BYE_BYTES));
    out[4..8].copy_from_slice(&ssrc.to_be_bytes());
    Ok(BYE_BYTES)
}

/// The round trip a receiver's report block shows (RFC 3550 section
/// 6.4.1, "the source can compute the round-trip propagation delay"): the
/// block's LSR and DLSR against `now_ntp`, the sender's wall clock when the
/// report arrived, in the NTP format its sender reports used. `None` for a
/// block of another source, or before the receiver had a sender report
/// (LSR 0), or an answer from the future.
pub fn round_trip(datagram: &[u8], media_ssrc: u32, now_ntp: u64) -> Option<Duration> {
    if !valid_compound(datagram) {
        return None;
    }
    let mut rest = datagram;
    while let Some(&[b0, pt, hi, lo]) = rest.first_chunk::<4>() {
        let len = (usize::from(u16::from_be_bytes([hi, lo])) + 1) * 4;
        let packet = rest.get(..len)?;
        rest = &rest[len..];
        // Report blocks follow the sender info of an SR or the SSRC of an RR.
        let blocks_at = match pt {
            RTCP_SR => 28,
            RTCP_RR => 8,
            _ => continue,
        };
        for k in 0..usize::from(b0 & 0x1f) {
            let Some(block) = packet.get(blocks_at + 24 * k..blocks_at + 24 * (k + 1)) else { break };
            let word = |i: usize| u32::from_be_bytes([block[i], block[i + 1], block[i + 2], block[i + 3]]);
            if word(0) != media_ssrc || word(16) == 0 {
                continue;
            }
            let (lsr, dlsr) = (word(16), word(20));
            // The middle 32 bits of the NTP timestamp: 1/65536 s units.
            let arrival = (now_ntp >> 16) as u32;
            let rtt = arrival.wrapping_sub(lsr).wrapping_sub(dlsr);
            if rtt >= 1 << 31 {
                return None;
            }
            return Some(Duration::from_micros(u64::from(rtt) * 1_000_000 / 65_536));
        }
    }
    None
}

/// Bytes of a receiver report with one report block.
pub const RECEIVER_REPORT_BYTES: usize = 32;

/// Write a receiver report (RFC 3550 section 6.4.2) from `reporter` about
/// `media` into the front of `out`: one report block whose loss, highest
/// sequence number and jitter fields are left zero (this receiver repairs
/// its losses and keeps no such counts), with `lsr`,
/// the middle 32 bits of the last sender report's NTP timestamp, and
/// `dlsr`, the time since it arrived in 1/65536 s (both 0 before one
/// arrived), so the sender can measure the round trip ([`round_trip`]).
/// Returns the bytes written.
pub fn write_receiver_report(
    reporter: u32,
    media: u32,
    lsr: u32,
    dlsr: u32,
    out: &mut [u8],
) -> Result<usize, BufferTooShort> {
    let out = front(out, RECEIVER_REPORT_BYTES)?;
    out[0..4].copy_from_slice(&rtcp_header(1, RTCP_RR, RECEIVER_REPORT_BYTES));
    out[4..8].copy_from_slice(&reporter.to_be_bytes());
    out[8..12].copy_from_slice(&media.to_be_bytes());
    // Fraction and cumulative lost, extended highest sequence number, jitter.
    out[12..24].fill(0);
    out[24..28].copy_from_slice(&lsr.to_be_bytes());
    out[28..32].copy_from_slice(&dlsr.to_be_bytes());
    Ok(RECEIVER_REPORT_BYTES)
}

/// The middle 32 bits of the NTP timestamp of the sender report of `ssrc`
/// in `datagram`, what a receiver report's LSR echoes (RFC 3550 section
/// 6.4.1).
pub fn sender_report_lsr(datagram: &[u8], ssrc: u32) -> Option<u32> {
    if !valid_compound(datagram) {
        return None;
    }
    let mut rest = datagram;
    while let Some(&[_, pt, hi, lo]) = rest.first_chunk::<4>() {
        let len = (usize::from(u16::from_be_bytes([hi, lo])) + 1) * 4;
        let packet = rest.get(..len)?;
        rest = &rest[len..];
        if pt == RTCP_SR && packet.len() >= SENDER_REPORT_BYTES {
            let word = |i: usize| u32::from_be_bytes([packet[i], packet[i + 1], packet[i + 2], packet[i + 3]]);
            if word(4) == ssrc {
                return Some(word(8) << 16 | word(12) >> 16);
            }
        }
    }
    None
}

/// The extended sequence numbers a receiver reports lost in the generic
/// NACKs (RFC 4585 section 6.2.1) of one RTCP datagram.
///
/// The datagram may be a compound packet (RFC 3550 section 6.1: receiver
/// report first, SDES, then the feedback) or a reduced-size one holding
/// the NACK alone (RFC 5506). It is first checked as a whole the way RFC
/// 3550 appendix A.2 checks a compound packet: every packet's version 2,
/// its length inside the datagram, padding only on the last one, and the
/// lengths adding up to the datagram's; anything else yields nothing.
/// Only packet type 205 with FMT 1 for media source `media_ssrc` counts;
/// other packets and other feedback are skipped.
///
/// Each FCI entry (PID, BLP) yields PID, then PID + 1 + i for each set bit
/// i of BLP, lowest first. The 16-bit numbers are resolved against the
/// sender's newest extended sequence number: to the one at most 32,767
/// packets back with those low 16 bits; numbers ahead of it (never sent)
/// are dropped. Duplicates are not removed. At most
/// [`MAX_NACKED_PER_DATAGRAM`] numbers come out of one datagram, however
/// many it lists: a 1,500-byte NACK could otherwise ask for some 6,000
/// resends of 1,502 bytes each.
#[derive(Clone, Debug)]
pub struct NackRequests<'a> {
    /// The packets after the current one.
    rest: &'a [u8],
    /// The FCI entries of the current NACK not read yet.
    fci: &'a [u8],
    media_ssrc: u32,
    highest: u32,
    pid: u16,
    /// Offsets from `pid` still to yield: bit 0 the PID, bit i + 1 BLP's
    /// bit i.
    pending: u32,
    /// Numbers still allowed out.
    budget: u16,
}

/// The most sequence numbers [`NackRequests`] yields for one datagram:
/// 256, seven tenths of a frame (a receiver that lost more than that of a
/// frame lost the stream, not a few rows; it asks again later). A
/// 1,500-byte NACK could otherwise ask for some 6,000 resends.
pub const MAX_NACKED_PER_DATAGRAM: u16 = 256;

/// Whether `data` is a well-formed run of RTCP packets (RFC 3550 appendix
/// A.2, less the rule that the first be a report: RFC 5506 allows a
/// feedback packet alone).
pub fn valid_compound(mut data: &[u8]) -> bool {
    if data.is_empty() {
        return false;
    }
    while !data.is_empty() {
        let Some(&[b0, _, hi, lo]) = data.first_chunk::<4>() else {
            return false;
        };
        let len = (usize::from(u16::from_be_bytes([hi, lo])) + 1) * 4;
        let Some(packet) = data.get(..len) else {
            return false;
        };
        data = &data[len..];
        if b0 >> 6 != 2 {
            return false;
        }
        if b0 & 0x20 != 0 {
            // Padding: only on the last packet, at least one octet, and no
            // more than the packet's body.
            let pad = usize::from(packet[len - 1]);
            if !data.is_empty() || pad == 0 || pad > len - 4 {
                return false;
            }
        }
    }
    true
}

impl<'a> NackRequests<'a> {
    /// The lost packets `datagram` asks `media_ssrc` to send again, the
    /// sender's newest extended sequence number being `highest` (`None`
    /// before the first packet: nothing to resend).
    pub fn new(datagram: &'a [u8], media_ssrc: u32, highest: Option<u32>) -> NackRequests<'a> {
        let rest = match highest {
            Some(_) if valid_compound(datagram) => datagram,
            _ => &[],
        };
        NackRequests {
            rest,
            fci: &[],
            media_ssrc,
            highest: highest.unwrap_or(0),
            pid: 0,
            pending: 0,
            budget: MAX_NACKED_PER_DATAGRAM,
        }
    }

    /// The extended sequence number with low 16 bits `seq16` at most 32,767
    /// packets back from the newest, if there is one.
    fn resolve(&self, seq16: u16) -> Option<u32> {
        let back = (self.highest as u16).wrapping_sub(seq16);
        (back < 0x8000).then(|| self.highest.wrapping_sub(u32::from(back)))
    }

    /// The same, yielding at most `limit` numbers rather than
    /// [`MAX_NACKED_PER_DATAGRAM`] (a receiver's own tests read back all
    /// it asked for).
    pub fn with_limit(mut self, limit: u16) -> NackRequests<'a> {
        self.budget = limit;
        self
    }

    /// Move to the next NACK for our media source; false at the end.
    fn next_nack(&mut self) -> bool {
        while let Some(&[b0, pt, hi, lo]) = self.rest.first_chunk::<4>() {
            // valid_compound checked every length and the padding.
            let len = (usize::from(u16::from_be_bytes([hi, lo])) + 1) * 4;
            let Some(packet) = self.rest.get(..len) else {
                break;
            };
            self.rest = &self.rest[len..];
            let pad = if b0 & 0x20 != 0 { usize::from(packet[len - 1]) } else { 0 };
            let body = packet.get(..len.saturating_sub(pad)).unwrap_or(&[]);
            if pt != RTCP_RTPFB || b0 & 0x1f != FMT_GENERIC_NACK {
                continue;
            }
            let Some(&[s0, s1, s2, s3]) = body.get(8..12).and_then(|b| b.first_chunk::<4>()) else {
                continue;
            };
            if u32::from_be_bytes([s0, s1, s2, s3]) == self.media_ssrc {
                self.fci = &body[12..];
                return true;
            }
        }
        self.rest = &[];
        false
    }
}

impl Iterator for NackRequests<'_> {
    type Item = u32;

    fn next(&mut self) -> Option<u32> {
        self.budget = self.budget.checked_sub(1)?;
        loop {
            if self.pending != 0 {
                let offset = self.pending.trailing_zeros();
                self.pending &= self.pending - 1;
                if let Some(seq) = self.resolve(self.pid.wrapping_add(offset as u16)) {
                    return Some(seq);
                }
            } else if let Some((&[p0, p1, b0, b1], rest)) = self.fci.split_first_chunk::<4>() {
                self.fci = rest;
                self.pid = u16::from_be_bytes([p0, p1]);
                self.pending = 1 | u32::from(u16::from_be_bytes([b0, b1])) << 1;
            } else if !self.next_nack() {
                return None;
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn a_sender_report_is_byte_exact() {
        let ntp = ntp_timestamp(Duration::new(1_700_000_000, 500_000_000));
        assert_eq!(ntp, (1_700_000_000 + 2_208_988_800) << 32 | 0x8000_0000);
        let sr = SenderReport {
            ssrc: 0x1234_5678,
            ntp_timestamp: ntp,
            rtp_timestamp: 0xa000_0000 + 225_000,
            packet_count: 360,
            octet_count: 360 * 1_448,
        };
        let mut out = [0u8; 32];
        assert_eq!(sr.write(&mut out), Ok(28));
        #[rustfmt::skip]
        assert_eq!(out[..28], [
            0x80, 200, 0x00, 0x06,                          // V=2, RC=0, SR, 7 words
            0x12, 0x34, 0x56, 0x78,
            0xe8, 0xfe, 0x6f, 0x80, 0x80, 0x00, 0x00, 0x00, // NTP: 3,908,988,800.5 s
            0xa0, 0x03, 0x6e, 0xe8,                         // RTP timestamp
            0x00, 0x00, 0x01, 0x68,                         // 360 packets
            0x00, 0x07, 0xf4, 0x40,                         // 521,280 octets
        ]);
        assert_eq!(sr.write(&mut [0; 27]), Err(BufferTooShort { needed: 28 }));
    }

    #[test]
    fn an_sdes_cname_ends_on_a_word_with_a_null() {
        let mut out = [0xffu8; 24];
        assert_eq!(write_sdes_cname(0x0102_0304, b"rt@board", &mut out), Ok(20));
        #[rustfmt::skip]
        assert_eq!(out[..20], [
            0x81, 202, 0x00, 0x04, 1, 2, 3, 4,
            1, 8, b'r', b't', b'@', b'b', b'o', b'a', b'r', b'd',
            0, 0,
        ]);
        assert_eq!(sdes_cname_bytes(2), 16, "2 + 2 octets fill a word: a whole word of nulls after");
        assert_eq!(write_sdes_cname(1, &[b'x'; 300], &mut [0; 300]), Ok(sdes_cname_bytes(255)));
    }

    /// An RTCP generic NACK (RFC 4585 section 6.2.1) from `sender` about
    /// `media`, with FCI entries `(pid, blp)`.
    pub(crate) fn nack(sender: u32, media: u32, entries: &[(u16, u16)]) -> Vec<u8> {
        let words = 2 + entries.len();
        let mut v = vec![0x81, 205];
        v.extend_from_slice(&(words as u16).to_be_bytes());
        v.extend_from_slice(&sender.to_be_bytes());
        v.extend_from_slice(&media.to_be_bytes());
        for (pid, blp) in entries {
            v.extend_from_slice(&pid.to_be_bytes());
            v.extend_from_slice(&blp.to_be_bytes());
        }
        v
    }

    /// An empty receiver report from `ssrc` (RFC 3550 section 6.4.2).
    fn rr(ssrc: u32) -> Vec<u8> {
        let mut v = vec![0x80, 201, 0, 1];
        v.extend_from_slice(&ssrc.to_be_bytes());
        v
    }

    fn nacked(datagram: &[u8], highest: u32) -> Vec<u32> {
        NackRequests::new(datagram, 0x1234_5678, Some(highest)).collect()
    }

    #[test]
    fn a_compound_nack_yields_the_pid_and_its_blp_bits() {
        let mut d = rr(0xdead_beef);
        d.extend(nack(0xdead_beef, 0x1234_5678, &[(0x1234, 0b1000_0000_0000_0101)]));
        assert_eq!(nacked(&d, 0x0002_1300), [0x0002_1234, 0x0002_1235, 0x0002_1237, 0x0002_1244]);
    }

    #[test]
    fn pids_resolve_into_the_last_32768_packets_across_the_wrap() {
        let d = nack(1, 0x1234_5678, &[(0xfff0, 0), (0xffff, 0b11), (0x0010, 0), (0x8010, 0)]);
        // Newest 0x0003_0010: 0xfff0 is in the previous high half, 0xffff
        // + 1 wraps into this one, 0x0010 is the newest itself and 0x8010
        // is 32,768 back: too far (it would as well be ahead).
        assert_eq!(nacked(&d, 0x0003_0010), [0x0002_fff0, 0x0002_ffff, 0x0003_0000, 0x0003_0001, 0x0003_0010]);
        assert_eq!(nacked(&nack(1, 0x1234_5678, &[(0x0011, 0)]), 0x0003_0010), [0; 0], "never sent");
        assert_eq!(nacked(&nack(1, 0x1234_5678, &[(0x8011, 0)]), 0x0003_0010), [0x0002_8011], "32,767 back");
        assert_eq!(NackRequests::new(&d, 0x1234_5678, None).count(), 0, "nothing sent yet");
    }

    #[test]
    fn other_packets_and_other_sources_are_skipped() {
        let mut d = rr(9);
        d.extend([0x81, 202, 0, 2, 0, 0, 0, 9, 1, 1, b'x', 0]); // SDES CNAME
        d.extend(nack(9, 0x0bad_0bad, &[(5, 0)])); // another stream
        let mut pli = nack(9, 0x1234_5678, &[]);
        pli[1] = 206; // PSFB, FMT 1: a picture loss indication
        d.extend(pli);
        let mut twcc = nack(9, 0x1234_5678, &[(6, 0)]);
        twcc[0] = 0x8f; // RTPFB FMT 15
        d.extend(twcc);
        d.extend(nack(9, 0x1234_5678, &[(7, 0), (9, 0)]));
        assert_eq!(nacked(&d, 100), [7, 9]);
    }

    #[test]
    fn padding_on_the_last_packet_is_not_fci() {
        let mut d = nack(9, 0x1234_5678, &[(7, 0), (0, 4)]);
        d[0] |= 0x20; // the last entry's word is now padding: 00 00 00 04
        assert_eq!(nacked(&d, 100), [7]);
    }

    #[test]
    fn one_datagram_asks_for_a_bounded_number_of_resends() {
        let d = nack(9, 0x1234_5678, &[(100, 0xffff); 300]);
        assert_eq!(nacked(&d, 200).len(), usize::from(MAX_NACKED_PER_DATAGRAM), "not 300 x 17");
        assert_eq!(nacked(&nack(9, 0x1234_5678, &[(100, 0xffff); 2]), 200).len(), 34);
    }

    #[test]
    fn malformed_datagrams_yield_nothing() {
        let good = nack(9, 0x1234_5678, &[(7, 0)]);
        assert_eq!(nacked(&good, 100), [7]);
        let mut cases: Vec<Vec<u8>> = vec![vec![], good[..good.len() - 1].to_vec()];
        let mut v1 = good.clone();
        v1[0] = 0x41; // version 1
        cases.push(v1);
        let mut long = good.clone();
        long[3] = 9; // past the end
        cases.push(long);
        let mut trailing = good.clone();
        trailing.extend([0x80, 201]); // half a header after
        cases.push(trailing);
        let mut pad_first = good.clone();
        pad_first[0] |= 0x20;
        pad_first.extend(rr(9));
        cases.push(pad_first);
        let mut pad_zero = good.clone();
        pad_zero[0] |= 0x20;
        *pad_zero.last_mut().unwrap() = 0;
        cases.push(pad_zero);
        let mut pad_huge = good.clone();
        pad_huge[0] |= 0x20;
        *pad_huge.last_mut().unwrap() = 200;
        cases.push(pad_huge);
        for (i, c) in cases.iter().enumerate() {
            assert_eq!(nacked(c, 100), [0; 0], "case {i}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            failure_persistence: None, ..proptest::test_runner::Config::default()
        })]

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..600),
                                    highest: u32) {
            let n = NackRequests::new(&bytes, 0x1234_5678, Some(highest)).count();
            proptest::prop_assert!(n <= 17 * (bytes.len() / 4));
        }

        #[test]
        fn random_nacks_yield_their_bits(entries in proptest::collection::vec((0u16..2000, proptest::num::u16::ANY), 0..40),
                                         pad in 0u8..8, tail in proptest::collection::vec(proptest::num::u8::ANY, 0..40)) {
            // Well-formed NACKs, then random bytes (valid or not).
            let mut d = nack(1, 0x1234_5678, &entries);
            let plain = nack(1, 0x1234_5678, &entries);
            if pad > 0 {
                let pad = usize::from(pad) * 4;
                d[0] |= 0x20;
                d.resize(d.len() + pad, 0);
                *d.last_mut().unwrap() = pad as u8;
                let words = (d.len() / 4 - 1) as u16;
                d[2..4].copy_from_slice(&words.to_be_bytes());
            }
            let expected: Vec<u32> = entries.iter().flat_map(|&(pid, blp)| {
                core::iter::once(u32::from(pid))
                    .chain((0..16).filter(move |i| blp & (1 << i) != 0).map(move |i| u32::from(pid) + 1 + i))
            }).filter(|&s| s <= 3_000).collect();
            let all = |d: &[u8]| NackRequests::new(d, 0x1234_5678, Some(3_000)).with_limit(u16::MAX).collect::<Vec<_>>();
            proptest::prop_assert_eq!(all(&d), expected.clone());
            proptest::prop_assert_eq!(all(&plain), expected.clone());
            let capped = nacked(&d, 3_000);
            proptest::prop_assert_eq!(&capped[..], &expected[..expected.len().min(usize::from(MAX_NACKED_PER_DATAGRAM))]);
            let mut with_tail = d.clone();
            with_tail.extend(&tail);
            let _ = nacked(&with_tail, 3_000);
        }

        #[test]
        fn mutated_compounds_never_panic(flips in proptest::collection::vec((0usize..64, proptest::num::u8::ANY), 1..6),
                                         highest: u32) {
            let mut d = rr(9);
            d.extend(nack(9, 0x1234_5678, &[(7, 0xffff), (40_000, 1)]));
            d.extend(nack(9, 0x1234_5678, &[(8, 3)]));
            for (at, byte) in flips {
                let i = at % d.len();
                d[i] = byte;
            }
            let n = NackRequests::new(&d, 0x1234_5678, Some(highest)).count();
            proptest::prop_assert!(n <= 3 * 17);
        }
    }

    #[test]
    fn a_receiver_report_echoing_the_sender_report_gives_the_round_trip() {
        // An SR at wall time 10 s, answered 30 ms later, arriving 50 ms after it went.
        let ntp = ntp_timestamp(Duration::from_secs(10));
        let mut sr = [0u8; SENDER_REPORT_BYTES];
        let report =
            SenderReport { ssrc: 0x1234_5678, ntp_timestamp: ntp, rtp_timestamp: 0, packet_count: 0, octet_count: 0 };
        report.write(&mut sr).unwrap();
        let lsr = sender_report_lsr(&sr, 0x1234_5678).unwrap();
        assert_eq!(sender_report_lsr(&sr, 7), None, "another source's");
        let mut rr = [0u8; RECEIVER_REPORT_BYTES];
        let dlsr = 30 * 65_536 / 1_000;
        write_receiver_report(9, 0x1234_5678, lsr, dlsr, &mut rr).unwrap();
        let rtt = round_trip(&rr, 0x1234_5678, ntp_timestamp(Duration::from_millis(10_050))).unwrap();
        assert!((19..=21).contains(&rtt.as_millis()), "{rtt:?}");
        assert_eq!(round_trip(&rr, 0x999, ntp), None);
        let mut zero = rr;
        zero[24..28].fill(0);
        assert_eq!(round_trip(&zero, 0x1234_5678, ntp), None, "no SR seen yet");
    }
}
