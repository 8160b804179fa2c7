//! The page's files, compiled in: each as written (`services/web/`) and
//! gzip-compressed at build time (`services/build.rs`), served compressed
//! to a browser that accepts it (every current one does).

/// One file of the page.
#[derive(Clone, Copy, Debug)]
pub struct Asset {
    /// Its path on the server.
    pub path: &'static str,
    /// Its `Content-Type`.
    pub content_type: &'static str,
    /// The file as written.
    pub raw: &'static [u8],
    /// The same, gzip-compressed.
    pub gzip: &'static [u8],
    /// Its entity tag (RFC 9110, section 8.8.3): the CRC-32 of the file as
    /// written, quoted, made by the build script.
    pub etag: &'static str,
}

macro_rules! asset {
    ($path:literal, $file:literal, $type:literal) => {
        Asset {
            path: $path,
            content_type: $type,
            raw: include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/web/", $file)),
            gzip: include_bytes!(concat!(env!("OUT_DIR"), "/", $file, ".gz")),
            etag: include_str!(concat!(env!("OUT_DIR"), "/", $file, ".etag")),
        }
    };
}

/// Every file of the page (the build script compresses the same names).
pub const ASSETS: [Asset; 3] = [
    asset!("/", "index.html", "text/html; charset=utf-8"),
    asset!("/page.js", "page.js", "text/javascript; charset=utf-8"),
    asset!("/page.css", "page.css", "text/css; charset=utf-8"),
];

/// The file at `path` (without its query), if there is one.
pub fn find(path: &str) -> Option<&'static Asset> {
    let path = if path == "/index.html" { "/" } else { path };
    ASSETS.iter().find(|a| a.path == path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn every_compressed_file_inflates_to_the_file_as_written_and_is_smaller() {
        for a in ASSETS {
            let mut inflated = Vec::new();
            flate2::read::GzDecoder::new(a.gzip).read_to_end(&mut inflated).expect("valid gzip");
            assert_eq!(inflated, a.raw, "{}", a.path);
            assert!(a.gzip.len() < a.raw.len(), "{}: {} >= {}", a.path, a.gzip.len(), a.raw.len());
        }
    }

    #[test]
    fn each_file_has_an_entity_tag_of_its_own_made_from_its_bytes() {
        for a in ASSETS {
            assert_eq!(a.etag, format!("\"{:08x}\"", crc32fast::hash(a.raw)), "{}", a.path);
        }
        assert_ne!(ASSETS[0].etag, ASSETS[1].etag);
    }

    #[test]
    fn the_page_is_found_at_its_paths_and_nothing_else() {
        assert_eq!(find("/").map(|a| a.path), Some("/"));
        assert_eq!(find("/index.html").map(|a| a.path), Some("/"));
        assert_eq!(find("/page.js").map(|a| a.content_type), Some("text/javascript; charset=utf-8"));
        assert!(find("/../etc/passwd").is_none());
        assert!(find("/page.js/").is_none());
    }
}
