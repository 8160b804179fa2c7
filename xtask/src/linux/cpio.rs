//! The kernel's initramfs format: cpio "newc" archives
//! (Linux `Documentation/driver-api/early-userspace/buffer-format.rst`):
//! each entry a 110-byte ASCII header (`070701` and thirteen 8-digit hex
//! fields), its NUL-terminated name and its data, name and data each padded
//! to 4 bytes; `TRAILER!!!` ends the archive.
//!
//! Written here rather than with `cpio(1)`: the test's archive holds a
//! device node (`/dev/console`), which cpio can only archive from a real one
//! made by root, and reading the installer's modules needs only the few
//! lines below.

use crate::support::Result;

const MAGIC: &[u8; 6] = b"070701";
const HEADER: usize = 110;
const TRAILER: &str = "TRAILER!!!";

/// File type bits of `mode` (inode(7)).
const S_IFMT: u32 = 0o170000;
const S_IFDIR: u32 = 0o040000;
const S_IFREG: u32 = 0o100000;
const S_IFCHR: u32 = 0o020000;

/// An archive being written.
#[derive(Default)]
pub struct Writer {
    bytes: Vec<u8>,
    next_inode: u32,
}

impl Writer {
    /// A directory (mode 755).
    pub fn dir(&mut self, path: &str) {
        self.entry(path, S_IFDIR | 0o755, (0, 0), &[]);
    }

    /// A regular file with permission bits `permissions`.
    pub fn file(&mut self, path: &str, permissions: u32, data: &[u8]) {
        self.entry(path, S_IFREG | (permissions & 0o7777), (0, 0), data);
    }

    /// A character device node (mode 600).
    pub fn char_device(&mut self, path: &str, major: u32, minor: u32) {
        self.entry(path, S_IFCHR | 0o600, (major, minor), &[]);
    }

    /// The archive, with its trailer.
    pub fn finish(mut self) -> Vec<u8> {
        self.entry(TRAILER, 0, (0, 0), &[]);
        self.bytes
    }

    fn entry(&mut self, path: &str, mode: u32, (rdev_major, rdev_minor): (u32, u32), data: &[u8]) {
        let name = path.trim_start_matches('/');
        self.next_inode += 1;
        let nlink = if mode & S_IFMT == S_IFDIR { 2 } else { 1 };
        let fields = [
            self.next_inode,
            mode,
            0, // uid
            0, // gid
            nlink,
            0, // mtime
            data.len() as u32,
            0, // devmajor
            0, // devminor
            rdev_major,
            rdev_minor,
            name.len() as u32 + 1,
            0, // check
        ];
        self.bytes.extend_from_slice(MAGIC);
        for field in fields {
            self.bytes.extend_from_slice(format!("{field:08x}").as_bytes());
        }
        self.bytes.extend_from_slice(name.as_bytes());
        self.bytes.push(0);
        self.pad();
        self.bytes.extend_from_slice(data);
        self.pad();
    }

    fn pad(&mut self) {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
    }
}

/// One entry read back.
#[derive(Debug, PartialEq, Eq)]
pub struct Entry<'a> {
    /// The path, as stored (no leading `/`).
    pub name: &'a str,
    pub mode: u32,
    pub data: &'a [u8],
}

impl Entry<'_> {
    /// A regular file.
    pub fn is_file(&self) -> bool {
        self.mode & S_IFMT == S_IFREG
    }
}

/// The entries of the newc archive `bytes`, up to its trailer.
pub fn entries(bytes: &[u8]) -> Result<Vec<Entry<'_>>> {
    let mut at = 0;
    let mut out = Vec::new();
    loop {
        let header = bytes.get(at..at + HEADER).ok_or(format!("cpio: archive ends at {at} with no trailer"))?;
        if &header[..6] != MAGIC {
            return Err(format!("cpio: no newc header at {at}"));
        }
        let field = |i: usize| -> Result<usize> {
            let hex = std::str::from_utf8(&header[6 + 8 * i..14 + 8 * i]).map_err(|_| "cpio: header not ASCII")?;
            usize::from_str_radix(hex, 16).map_err(|_| format!("cpio: bad field {hex:?} at {at}"))
        };
        let (mode, size, name_size) = (field(1)?, field(6)?, field(11)?);
        let name_at = at + HEADER;
        let name = bytes
            .get(name_at..name_at + name_size.saturating_sub(1))
            .and_then(|n| std::str::from_utf8(n).ok())
            .ok_or(format!("cpio: bad name at {name_at}"))?;
        let data_at = (name_at + name_size).next_multiple_of(4);
        if name == TRAILER {
            return Ok(out);
        }
        let data = bytes.get(data_at..data_at + size).ok_or(format!("cpio: {name}: data past the end"))?;
        out.push(Entry { name, mode: mode as u32, data });
        at = (data_at + size).next_multiple_of(4);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn what_is_written_reads_back() {
        let mut w = Writer::default();
        w.dir("/dev");
        w.char_device("/dev/console", 5, 1);
        w.file("/init", 0o755, b"#!");
        w.file("/modules/order", 0o644, b"a.ko\nb.ko\n");
        let bytes = w.finish();
        assert_eq!(bytes.len() % 4, 0);
        let read = entries(&bytes).unwrap();
        let names: Vec<&str> = read.iter().map(|e| e.name).collect();
        assert_eq!(names, ["dev", "dev/console", "init", "modules/order"]);
        assert_eq!(read[1].mode, 0o020600);
        assert_eq!(read[2], Entry { name: "init", mode: 0o100755, data: b"#!" });
        assert!(read[3].is_file() && !read[0].is_file());
        assert_eq!(read[3].data, b"a.ko\nb.ko\n");
    }

    #[test]
    fn a_device_number_is_in_the_rdev_fields() {
        let mut w = Writer::default();
        w.char_device("dev/console", 5, 1);
        let bytes = w.finish();
        // rdevmajor and rdevminor: the 10th and 11th fields.
        assert_eq!(&bytes[6 + 8 * 9..6 + 8 * 11], b"0000000500000001");
    }

    #[test]
    fn a_cut_archive_is_an_error() {
        let mut w = Writer::default();
        w.file("x", 0o644, b"data");
        let bytes = w.finish();
        assert!(entries(&bytes[..bytes.len() - 120]).is_err());
        assert!(entries(b"garbage").is_err());
    }
}
