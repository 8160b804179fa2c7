//! The part of the DNS message format (RFC 1035 section 4; RFC 6762 for
//! the mDNS bits) the responder needs: reading questions and records out
//! of a received message, names compared where they lie (compression
//! pointers followed, RFC 1035 section 4.1.4), and writing a response.
//!
//! Hand-written rather than taken from `domain` (NLnet Labs) or
//! `simple-dns`: the board answers about twenty fixed names with four
//! record types and no heap; a reader that compares names in place and a
//! writer into a caller's buffer are some 300 lines, where those crates
//! bring general message building and (for `domain` without alloc) octet
//! builders the firmware would carry for nothing. The host tests check
//! this code against `simple-dns`, an independent codec.

use core::net::Ipv4Addr;

/// Record types (RFC 1035 section 3.2.2, RFC 2782, RFC 6763).
pub const TYPE_A: u16 = 1;
/// PTR.
pub const TYPE_PTR: u16 = 12;
/// TXT.
pub const TYPE_TXT: u16 = 16;
/// AAAA (never answered: the board has no IPv6).
pub const TYPE_AAAA: u16 = 28;
/// SRV (RFC 2782).
pub const TYPE_SRV: u16 = 33;
/// ANY, in a question (RFC 1035 section 3.2.3).
pub const TYPE_ANY: u16 = 255;
/// Class IN.
pub const CLASS_IN: u16 = 1;
/// Top bit of a question's class: a unicast response is asked for (RFC 6762
/// section 5.4); of a record's class: cache-flush (section 10.2).
pub const CLASS_TOP_BIT: u16 = 0x8000;

/// Header flags: a response.
pub const FLAG_RESPONSE: u16 = 0x8000;
/// Header flags: authoritative answer (RFC 6762 section 18.4: set in every
/// response).
pub const FLAG_AUTHORITATIVE: u16 = 0x0400;

/// Most compression pointers followed in one name: more is a loop.
const MAX_JUMPS: usize = 16;

/// The message was malformed (truncated, a bad label or pointer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Malformed;

/// A received message's fixed header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// The message ID.
    pub id: u16,
    /// The flags word.
    pub flags: u16,
    /// Questions.
    pub questions: u16,
    /// Answer records.
    pub answers: u16,
    /// Authority records.
    pub authorities: u16,
    /// Additional records.
    pub additionals: u16,
}

impl Header {
    /// Whether it is a response (QR set).
    pub fn is_response(&self) -> bool {
        self.flags & FLAG_RESPONSE != 0
    }
}

/// A name inside a message: where it starts (it may continue through
/// compression pointers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Name {
    at: usize,
}

impl Name {
    /// The name starting at byte `at` of the message (a PTR's or SRV's
    /// data holds one).
    pub const fn at(at: usize) -> Name {
        Name { at }
    }
}

/// A question.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Question {
    /// Its name.
    pub name: Name,
    /// The type asked for.
    pub qtype: u16,
    /// The class, without the unicast-response bit.
    pub class: u16,
    /// The unicast-response (QU) bit.
    pub unicast: bool,
}

/// A resource record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Record {
    /// Its name.
    pub name: Name,
    /// Its type.
    pub rtype: u16,
    /// Its class, without the cache-flush bit.
    pub class: u16,
    /// Time to live, seconds.
    pub ttl: u32,
    /// Where its data lies in the message.
    pub data: (usize, usize),
}

/// A received message, read lazily.
#[derive(Clone, Copy, Debug)]
pub struct Message<'a> {
    bytes: &'a [u8],
    /// Its header.
    pub header: Header,
}

fn be16(b: &[u8], at: usize) -> Result<u16, Malformed> {
    Ok(u16::from_be_bytes([*b.get(at).ok_or(Malformed)?, *b.get(at + 1).ok_or(Malformed)?]))
}

fn be32(b: &[u8], at: usize) -> Result<u32, Malformed> {
    Ok(u32::from(be16(b, at)?) << 16 | u32::from(be16(b, at + 2)?))
}

impl<'a> Message<'a> {
    /// Read the header of `bytes`.
    pub fn parse(bytes: &'a [u8]) -> Result<Message<'a>, Malformed> {
        let header = Header {
            id: be16(bytes, 0)?,
            flags: be16(bytes, 2)?,
            questions: be16(bytes, 4)?,
            answers: be16(bytes, 6)?,
            authorities: be16(bytes, 8)?,
            additionals: be16(bytes, 10)?,
        };
        Ok(Message { bytes, header })
    }

    /// The questions and then every record (answers, authorities,
    /// additionals, in order), each with its section.
    pub fn entries(&self) -> Entries<'a> {
        Entries { msg: *self, at: 12, index: 0 }
    }

    /// The end of the name at `at` in the message (past its last label or
    /// its pointer).
    fn skip_name(&self, mut at: usize) -> Result<usize, Malformed> {
        loop {
            let len = *self.bytes.get(at).ok_or(Malformed)?;
            match len {
                0 => return Ok(at + 1),
                l if l & 0xc0 == 0xc0 => {
                    self.bytes.get(at + 1).ok_or(Malformed)?;
                    return Ok(at + 2);
                }
                l if l & 0xc0 != 0 => return Err(Malformed),
                l => at += 1 + usize::from(l),
            }
        }
    }

    /// The labels of `name`, in order, through compression pointers.
    pub fn labels(&self, name: Name) -> Labels<'a> {
        Labels { bytes: self.bytes, at: name.at, jumps: 0, failed: false }
    }

    /// Whether `name` is `expected` (labels; ASCII case ignored, RFC 1035
    /// section 2.3.3). A malformed name equals nothing.
    pub fn name_is(&self, name: Name, expected: &[&str]) -> bool {
        let mut labels = self.labels(name);
        for want in expected {
            match labels.next() {
                Some(got) if got.eq_ignore_ascii_case(want.as_bytes()) => {}
                _ => return false,
            }
        }
        labels.next().is_none() && !labels.failed
    }

    /// The record data's bytes.
    pub fn data(&self, record: &Record) -> &'a [u8] {
        &self.bytes[record.data.0..record.data.1]
    }

    /// An A record's address.
    pub fn a(&self, record: &Record) -> Option<Ipv4Addr> {
        let d = self.data(record);
        (record.rtype == TYPE_A && d.len() == 4).then(|| Ipv4Addr::new(d[0], d[1], d[2], d[3]))
    }
}

/// Which part of the message an entry is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Section {
    /// The question section.
    Question,
    /// The answer section.
    Answer,
    /// The authority section (a probe's proposed records).
    Authority,
    /// The additional section.
    Additional,
}

/// A question or a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    /// A question.
    Question(Question),
    /// A record, and its section.
    Record(Section, Record),
}

/// The entries of a message, in order; stops at the first malformed one.
pub struct Entries<'a> {
    msg: Message<'a>,
    at: usize,
    index: u32,
}

impl Iterator for Entries<'_> {
    type Item = Result<Entry, Malformed>;

    fn next(&mut self) -> Option<Self::Item> {
        let h = self.msg.header;
        let q = u32::from(h.questions);
        let total = q + u32::from(h.answers) + u32::from(h.authorities) + u32::from(h.additionals);
        if self.index >= total {
            return None;
        }
        let index = self.index;
        self.index += 1;
        let r = self.read(index, q);
        if r.is_err() {
            self.index = total;
        }
        Some(r)
    }
}

impl Entries<'_> {
    fn read(&mut self, index: u32, questions: u32) -> Result<Entry, Malformed> {
        let b = self.msg.bytes;
        let name = Name { at: self.at };
        let at = self.msg.skip_name(self.at)?;
        let rtype = be16(b, at)?;
        let class = be16(b, at + 2)?;
        if index < questions {
            self.at = at + 4;
            return Ok(Entry::Question(Question {
                name,
                qtype: rtype,
                class: class & !CLASS_TOP_BIT,
                unicast: class & CLASS_TOP_BIT != 0,
            }));
        }
        let ttl = be32(b, at + 4)?;
        let len = usize::from(be16(b, at + 8)?);
        let start = at + 10;
        let end = start.checked_add(len).filter(|e| *e <= b.len()).ok_or(Malformed)?;
        self.at = end;
        let h = self.msg.header;
        let answers = questions + u32::from(h.answers);
        let section = if index < answers {
            Section::Answer
        } else if index < answers + u32::from(h.authorities) {
            Section::Authority
        } else {
            Section::Additional
        };
        Ok(Entry::Record(section, Record { name, rtype, class: class & !CLASS_TOP_BIT, ttl, data: (start, end) }))
    }
}

/// The labels of a name, through compression pointers.
pub struct Labels<'a> {
    bytes: &'a [u8],
    at: usize,
    jumps: usize,
    /// A bad label, pointer or loop ended the walk.
    pub failed: bool,
}

impl<'a> Iterator for Labels<'a> {
    type Item = &'a [u8];

    fn next(&mut self) -> Option<&'a [u8]> {
        loop {
            let Some(&len) = self.bytes.get(self.at) else {
                self.failed = true;
                return None;
            };
            match len {
                0 => return None,
                l if l & 0xc0 == 0xc0 => {
                    let Some(&low) = self.bytes.get(self.at + 1) else {
                        self.failed = true;
                        return None;
                    };
                    self.jumps += 1;
                    if self.jumps > MAX_JUMPS {
                        self.failed = true;
                        return None;
                    }
                    self.at = usize::from(l & 0x3f) << 8 | usize::from(low);
                }
                l if l & 0xc0 != 0 => {
                    self.failed = true;
                    return None;
                }
                l => {
                    let start = self.at + 1;
                    let Some(label) = self.bytes.get(start..start + usize::from(l)) else {
                        self.failed = true;
                        return None;
                    };
                    self.at = start + usize::from(l);
                    return Some(label);
                }
            }
        }
    }
}

/// The buffer was too small for the message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Full;

/// A message written into a caller's buffer: the header, then questions
/// or records, counted as they are added. Names are written whole (no
/// compression: every receiver reads both, RFC 1035 section 4.1.4).
pub struct Writer<'b> {
    buf: &'b mut [u8],
    len: usize,
    counts: [u16; 4],
}

/// Record data to write.
#[derive(Clone, Copy, Debug)]
pub enum Data<'a> {
    /// An IPv4 address.
    A(Ipv4Addr),
    /// A name (its labels).
    Ptr(&'a [&'a str]),
    /// Priority 0, weight 0, this port, this target.
    Srv(u16, &'a [&'a str]),
    /// Character strings (each at most 255 bytes).
    Txt(&'a [&'a str]),
}

impl Data<'_> {
    /// The record type of the data.
    pub fn rtype(&self) -> u16 {
        match self {
            Data::A(_) => TYPE_A,
            Data::Ptr(_) => TYPE_PTR,
            Data::Srv(..) => TYPE_SRV,
            Data::Txt(_) => TYPE_TXT,
        }
    }
}

impl<'b> Writer<'b> {
    /// Begin a message with `id` and `flags`.
    pub fn new(buf: &'b mut [u8], id: u16, flags: u16) -> Result<Writer<'b>, Full> {
        let mut w = Writer { buf, len: 0, counts: [0; 4] };
        w.put(&id.to_be_bytes())?;
        w.put(&flags.to_be_bytes())?;
        w.put(&[0; 8])?;
        Ok(w)
    }

    fn put(&mut self, bytes: &[u8]) -> Result<(), Full> {
        let end = self.len + bytes.len();
        self.buf.get_mut(self.len..end).ok_or(Full)?.copy_from_slice(bytes);
        self.len = end;
        Ok(())
    }

    fn name(&mut self, labels: &[&str]) -> Result<(), Full> {
        for l in labels {
            let len = u8::try_from(l.len()).ok().filter(|n| *n <= 63).ok_or(Full)?;
            self.put(&[len])?;
            self.put(l.as_bytes())?;
        }
        self.put(&[0])
    }

    /// Add a question (`unicast`: the QU bit). Questions must come first.
    pub fn question(&mut self, name: &[&str], qtype: u16, unicast: bool) -> Result<(), Full> {
        let mark = self.len;
        let r = self.name(name).and_then(|()| {
            self.put(&qtype.to_be_bytes())?;
            self.put(&(CLASS_IN | if unicast { CLASS_TOP_BIT } else { 0 }).to_be_bytes())
        });
        self.commit(mark, 0, r)
    }

    /// Add a record to `section` (answers, then authorities, then
    /// additionals: in that order). `flush`: the cache-flush bit, for the
    /// board's unique records (RFC 6762 section 10.2).
    pub fn record(
        &mut self,
        section: Section,
        name: &[&str],
        ttl: u32,
        flush: bool,
        data: Data<'_>,
    ) -> Result<(), Full> {
        let mark = self.len;
        let r = self.record_bytes(name, ttl, flush, data);
        let index = match section {
            Section::Question => 0,
            Section::Answer => 1,
            Section::Authority => 2,
            Section::Additional => 3,
        };
        self.commit(mark, index, r)
    }

    fn record_bytes(&mut self, name: &[&str], ttl: u32, flush: bool, data: Data<'_>) -> Result<(), Full> {
        self.name(name)?;
        self.put(&data.rtype().to_be_bytes())?;
        self.put(&(CLASS_IN | if flush { CLASS_TOP_BIT } else { 0 }).to_be_bytes())?;
        self.put(&ttl.to_be_bytes())?;
        let length_at = self.len;
        self.put(&[0, 0])?;
        match data {
            Data::A(a) => self.put(&a.octets())?,
            Data::Ptr(target) => self.name(target)?,
            Data::Srv(port, target) => {
                self.put(&[0, 0, 0, 0])?;
                self.put(&port.to_be_bytes())?;
                self.name(target)?;
            }
            Data::Txt(strings) => {
                for s in strings {
                    let len = u8::try_from(s.len()).map_err(|_| Full)?;
                    self.put(&[len])?;
                    self.put(s.as_bytes())?;
                }
                if strings.is_empty() {
                    // RFC 6763 section 6.1: an empty TXT holds one empty string.
                    self.put(&[0])?;
                }
            }
        }
        let len = u16::try_from(self.len - length_at - 2).map_err(|_| Full)?;
        self.buf[length_at..length_at + 2].copy_from_slice(&len.to_be_bytes());
        Ok(())
    }

    /// Count the entry written since `mark`, or undo it if it did not fit.
    fn commit(&mut self, mark: usize, index: usize, r: Result<(), Full>) -> Result<(), Full> {
        match r {
            Ok(()) => {
                self.counts[index] += 1;
                let at = 4 + 2 * index;
                self.buf[at..at + 2].copy_from_slice(&self.counts[index].to_be_bytes());
                Ok(())
            }
            Err(e) => {
                self.len = mark;
                Err(e)
            }
        }
    }

    /// Records (and questions) written so far.
    pub fn entries(&self) -> usize {
        self.counts.iter().map(|c| usize::from(*c)).sum()
    }

    /// The message's length so far.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing but the header was written.
    pub fn is_empty(&self) -> bool {
        self.entries() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HOST: [&str; 2] = ["raytracer", "local"];

    #[test]
    fn a_written_response_reads_back_with_an_independent_codec() {
        let mut buf = [0u8; 512];
        let mut w = Writer::new(&mut buf, 0, FLAG_RESPONSE | FLAG_AUTHORITATIVE).unwrap();
        w.record(Section::Answer, &HOST, 120, true, Data::A(Ipv4Addr::new(10, 0, 2, 15))).unwrap();
        let instance = ["raytracer", "_http", "_tcp", "local"];
        w.record(Section::Answer, &["_http", "_tcp", "local"], 4500, false, Data::Ptr(&instance)).unwrap();
        w.record(Section::Additional, &instance, 120, true, Data::Srv(80, &HOST)).unwrap();
        w.record(Section::Additional, &instance, 4500, true, Data::Txt(&["path=/"])).unwrap();
        let len = w.len();
        let packet = simple_dns::Packet::parse(&buf[..len]).expect("simple-dns reads it");
        assert_eq!(packet.answers.len(), 2);
        assert_eq!(packet.additional_records.len(), 2);
        assert_eq!(packet.answers[0].name.to_string(), "raytracer.local");
        assert!(packet.answers[0].cache_flush);
        match &packet.answers[0].rdata {
            simple_dns::rdata::RData::A(a) => assert_eq!(Ipv4Addr::from(a.address), Ipv4Addr::new(10, 0, 2, 15)),
            other => panic!("{other:?}"),
        }
        match &packet.additional_records[0].rdata {
            simple_dns::rdata::RData::SRV(s) => {
                assert_eq!((s.port, s.target.to_string().as_str()), (80, "raytracer.local"))
            }
            other => panic!("{other:?}"),
        }
        match &packet.additional_records[1].rdata {
            simple_dns::rdata::RData::TXT(t) => {
                let attrs = t.attributes();
                assert_eq!(attrs.get("path"), Some(&Some("/".to_string())));
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_compressed_query_from_an_independent_codec_is_read() {
        let mut q = simple_dns::Packet::new_query(7);
        q.questions.push(simple_dns::Question::new(
            simple_dns::Name::new_unchecked("_rtsp._tcp.local"),
            simple_dns::TYPE::PTR.into(),
            simple_dns::CLASS::IN.into(),
            true,
        ));
        q.questions.push(simple_dns::Question::new(
            simple_dns::Name::new_unchecked("RayTracer.local"),
            simple_dns::TYPE::A.into(),
            simple_dns::CLASS::IN.into(),
            false,
        ));
        let bytes = q.build_bytes_vec_compressed().unwrap();
        let m = Message::parse(&bytes).unwrap();
        assert_eq!(m.header.id, 7);
        let questions: Vec<Question> = m
            .entries()
            .map(|e| match e.unwrap() {
                Entry::Question(q) => q,
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(questions.len(), 2);
        assert!(m.name_is(questions[0].name, &["_rtsp", "_tcp", "local"]));
        assert_eq!((questions[0].qtype, questions[0].unicast), (TYPE_PTR, true));
        assert!(m.name_is(questions[1].name, &HOST), "case ignored");
        assert!(!m.name_is(questions[1].name, &["raytracer"]));
        assert_eq!((questions[1].qtype, questions[1].unicast), (TYPE_A, false));
    }

    #[test]
    fn pointer_loops_and_truncation_are_malformed_not_a_hang() {
        // One question whose name points at itself.
        let looped = [0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0xc0, 12, 0, 1, 0, 1];
        let m = Message::parse(&looped).unwrap();
        let Some(Ok(Entry::Question(q))) = m.entries().next() else { panic!() };
        assert!(!m.name_is(q.name, &HOST));
        assert!(m.labels(q.name).count() == 0);
        // A record whose data runs past the end.
        let mut buf = [0u8; 64];
        let mut w = Writer::new(&mut buf, 0, FLAG_RESPONSE).unwrap();
        w.record(Section::Answer, &HOST, 120, true, Data::A(Ipv4Addr::LOCALHOST)).unwrap();
        let len = w.len();
        let m = Message::parse(&buf[..len - 1]).unwrap();
        assert_eq!(m.entries().next(), Some(Err(Malformed)));
        assert_eq!(Message::parse(&buf[..5]).err(), Some(Malformed));
    }

    #[test]
    fn a_record_that_does_not_fit_is_left_out_whole() {
        let mut buf = [0u8; 50];
        let mut w = Writer::new(&mut buf, 0, FLAG_RESPONSE).unwrap();
        w.record(Section::Answer, &HOST, 120, true, Data::A(Ipv4Addr::LOCALHOST)).unwrap();
        let len = w.len();
        assert_eq!(w.record(Section::Answer, &HOST, 120, true, Data::Txt(&["a long string"])), Err(Full));
        assert_eq!((w.len(), w.entries()), (len, 1));
    }

    proptest::proptest! {
        /// Any bytes: reading never panics or loops.
        #[test]
        fn any_bytes_are_read_without_panic(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..300)) {
            if let Ok(m) = Message::parse(&bytes) {
                for e in m.entries().take(64) {
                    if let Ok(Entry::Question(q)) = e {
                        let _ = m.name_is(q.name, &HOST);
                    }
                    if let Ok(Entry::Record(_, r)) = e {
                        let _ = m.labels(r.name).count();
                        let _ = m.a(&r);
                    }
                }
            }
        }
    }
}
