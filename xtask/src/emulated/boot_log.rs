//! The expected boot log in docs/board-bring-up.md against the emulated
//! board's UART: the lines that do not depend on the board (the services
//! the firmware starts) must be what the firmware prints, so the document
//! cannot go stale as the services change.

use crate::support::tools::root;
use crate::support::Result;

/// Where the expected log is, and the heading of its section.
const DOC: &str = "docs/board-bring-up.md";
const SECTION: &str = "## Expected UART output";

/// Lines of the documented log that the emulated board prints whole.
const WHOLE: [&str; 4] = ["renderer: ", "web: ", "camera: ", "display: "];

/// Lines the emulated board prints whole but for the time they took at the
/// end (` (15 ms)`).
const TIMED: [&str; 1] = ["self-test: "];

/// `line` without a final ` (N ms)`.
fn untimed(line: &str) -> &str {
    match line.rsplit_once(" (") {
        Some((head, tail))
            if tail.strip_suffix(" ms)").is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit())) =>
        {
            head
        }
        _ => line,
    }
}

/// The `net:` line's words from here on do not depend on the board.
const NET_TAIL: &str = "listening on TCP";

/// The documented log: the indented block of the section, each line
/// without its indent and without a trailing `<- ...` note.
fn documented(doc: &str) -> Vec<String> {
    let Some(at) = doc.find(SECTION) else { return Vec::new() };
    let rest = &doc[at + SECTION.len()..];
    let end = rest.find("\n## ").unwrap_or(rest.len());
    rest[..end]
        .lines()
        .filter_map(|l| l.strip_prefix("    "))
        .map(|l| l.split("  <-").next().unwrap_or(l).trim_end().to_string())
        .filter(|l| !l.trim().is_empty())
        .collect()
}

/// The documented lines the emulated board's `uart` does not show, each
/// with why; empty when every checked line is there.
pub fn stale_lines(doc: &str, uart: &str) -> Vec<String> {
    let printed: Vec<&str> = uart.lines().map(str::trim_end).collect();
    let mut stale = Vec::new();
    let lines = documented(doc);
    if lines.is_empty() {
        return vec![format!("{DOC} has no expected log under {SECTION:?}")];
    }
    for line in &lines {
        if TIMED.iter().any(|p| line.starts_with(p)) {
            if !printed.iter().any(|p| untimed(p) == untimed(line)) {
                stale.push(format!("documented {line:?}, not printed (the time aside)"));
            }
        } else if WHOLE.iter().any(|p| line.starts_with(p)) {
            if !printed.contains(&line.as_str()) {
                stale.push(format!("documented {line:?}, not printed"));
            }
        } else if let (true, Some(at)) = (line.starts_with("net: "), line.find(NET_TAIL)) {
            let tail = &line[at..];
            if !printed.iter().any(|p| p.starts_with("net: ") && p.ends_with(tail)) {
                stale.push(format!("documented a net: line ending {tail:?}, not printed"));
            }
        }
    }
    // Every such line the firmware prints at boot is documented too.
    let boot = printed.iter().take_while(|l| !l.starts_with("link up"));
    for p in boot.filter(|p| WHOLE.iter().any(|w| p.starts_with(w))) {
        if !lines.iter().any(|l| l == p) {
            stale.push(format!("printed {p:?}, not documented"));
        }
    }
    stale
}

/// The suite's check on a boot of the frame-mode build over the simulated
/// accelerator (the one with the web page, the camera and the display).
pub fn check(uart: &str) -> Result<String> {
    let path = root().join(DOC);
    let doc = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let stale = stale_lines(&doc, uart);
    if !stale.is_empty() {
        return Err(format!("{DOC}'s expected boot log is stale:\n  {}", stale.join("\n  ")));
    }
    Ok(format!(
        "{DOC}'s expected boot log: {} lines, the services' lines as the emulated board prints them",
        documented(&doc).len()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC_TEXT: &str = "# x\n\n## Expected UART output\n\nSome words.\n\n    raytracer firmware 0.1.0 on de1-soc\n    net: 192.168.1.200/24 via 192.168.1.1, MAC 02-de-1c-50-c0-01, listening on TCP 7878 and 7879 (18 + 6 sockets)\n    web: page on TCP 80 (8 sockets)\n    link up: 1000 Mbit/s full duplex                   <- when the cable is connected\n\n## Next\n\n    web: not this one\n";

    #[test]
    fn the_documented_log_is_the_sections_indented_block_without_notes() {
        let lines = documented(DOC_TEXT);
        assert_eq!(lines.len(), 4);
        assert_eq!(lines[3], "link up: 1000 Mbit/s full duplex");
    }

    #[test]
    fn a_changed_or_an_undocumented_service_line_is_stale() {
        let uart = "raytracer firmware 0.1.0 on qemu-npcm750\nnet: 10.0.2.15/24 via 10.0.2.2, MAC 52-54-00-12-34-56, listening on TCP 7878 and 7879 (18 + 6 sockets)\nweb: page on TCP 80 (8 sockets)\nlink up: 1000 Mbit/s full duplex\n";
        assert!(stale_lines(DOC_TEXT, uart).is_empty(), "{:?}", stale_lines(DOC_TEXT, uart));
        let changed = uart.replace("(8 sockets)", "(9 sockets)");
        assert_eq!(stale_lines(DOC_TEXT, &changed).len(), 2, "documented and not printed, printed and not documented");
        let more = uart.replace("link up", "camera: RTSP on TCP 8554\nlink up");
        assert_eq!(stale_lines(DOC_TEXT, &more), ["printed \"camera: RTSP on TCP 8554\", not documented"]);
        let sockets = uart.replace("(18 + 6 sockets)", "(20 + 4 sockets)");
        assert_eq!(stale_lines(DOC_TEXT, &sockets).len(), 1);
    }

    #[test]
    fn the_self_tests_line_is_compared_without_its_time() {
        let doc = DOC_TEXT.replace("    link up", "    self-test: PASS: 9120 pixels (15 ms)\n    link up");
        let uart = "net: 10.0.2.15/24 via 10.0.2.2, MAC 52-54-00-12-34-56, listening on TCP 7878 and 7879 (18 + 6 sockets)\nself-test: PASS: 9120 pixels (977 ms)\nweb: page on TCP 80 (8 sockets)\n";
        assert!(stale_lines(&doc, uart).is_empty(), "{:?}", stale_lines(&doc, uart));
        let fail = uart.replace("PASS", "FAIL");
        assert_eq!(stale_lines(&doc, &fail).len(), 1);
        assert_eq!(untimed("a (b) (12 ms)"), "a (b)");
        assert_eq!(untimed("a (x ms)"), "a (x ms)");
    }

    #[test]
    fn the_repositorys_document_has_a_log_with_the_services_lines() {
        let doc = std::fs::read_to_string(root().join(DOC)).unwrap();
        let lines = documented(&doc);
        for prefix in WHOLE {
            assert!(lines.iter().any(|l| l.starts_with(prefix)), "no {prefix:?} line in {DOC}");
        }
    }
}
