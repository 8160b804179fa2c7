//! The module layering, checked against the sources so it cannot drift:
//! `main` -> `suite` -> the groups (`emulated`, `fpga`, `host`, `images`)
//! -> `support`.
//!
//! Every folder's `mod.rs`, and every other top-level file but `main.rs`
//! and this one, has a `//! May import:` line naming (in backticks) the
//! top-level modules it may use; its own is always allowed. Every path to
//! a top-level module (`crate::x`, or `super::` climbing to the crate
//! root; in a `use`, code or a doc link) must be on that list, nothing may
//! name the crate root's own items (`main.rs` is the top), `support` may
//! import only itself, and the rules must have no cycle.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The layer of `main.rs` and of this test: may import anything.
const TOP: [&str; 2] = ["main.rs", "layering.rs"];

/// The bottom layer.
const SUPPORT: &str = "support";

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn read(p: &Path) -> String {
    fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The `.rs` files under `dir`, with their module depth below the crate
/// root (`g/mod.rs` is 1, `g/x.rs` 2).
fn rust_files(dir: &Path, depth: usize, out: &mut Vec<(PathBuf, usize)>) {
    let entries = fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for e in entries {
        let p = e.expect("directory entry").path();
        if p.is_dir() {
            rust_files(&p, depth + 1, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            let d = if p.file_name().is_some_and(|n| n == "mod.rs") { depth } else { depth + 1 };
            out.push((p, d));
        }
    }
}

/// The backticked names on the `//! May import:` line (up to its first
/// full stop).
fn may_import(doc: &str) -> Option<BTreeSet<String>> {
    let line = doc.lines().find_map(|l| l.trim().strip_prefix("//! May import:"))?;
    let clause = line.split('.').next().unwrap_or("");
    Some(clause.split('`').skip(1).step_by(2).map(str::to_string).collect())
}

/// The leading identifier of `s`.
fn ident(s: &str) -> &str {
    let end = s.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(s.len());
    &s[..end]
}

/// The first segment after each `crate::` (every name of a `crate::{..}`
/// group), and after each run of `super::` at least `depth` long (a path
/// from the crate root), with its line number.
fn root_paths(text: &str, depth: usize) -> Vec<(usize, String, bool)> {
    let line_of = |at: usize| text[..at].matches('\n').count() + 1;
    let mut out = Vec::new();
    for (at, _) in text.match_indices("crate::") {
        if text[..at].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_' || c == '$') {
            continue;
        }
        let rest = &text[at + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let (mut level, mut end) = (0usize, group.len());
            for (i, c) in group.char_indices() {
                match c {
                    '{' => level += 1,
                    '}' if level == 0 => {
                        end = i;
                        break;
                    }
                    '}' => level -= 1,
                    _ => {}
                }
            }
            // Top-level items of the group: split on commas outside braces.
            let (mut level, mut start) = (0usize, 0usize);
            let inner = &group[..end];
            for (i, c) in inner.char_indices().chain(std::iter::once((inner.len(), ','))) {
                match c {
                    '{' => level += 1,
                    '}' => level -= 1,
                    ',' if level == 0 => {
                        let name = ident(inner[start..i].trim());
                        if !name.is_empty() {
                            out.push((line_of(at), name.to_string(), true));
                        }
                        start = i + 1;
                    }
                    _ => {}
                }
            }
        } else {
            out.push((line_of(at), ident(rest).to_string(), true));
        }
    }
    let mut at = 0;
    while let Some(i) = text[at..].find("super::") {
        let start = at + i;
        let mut rest = &text[start..];
        let mut ups = 0;
        while let Some(r) = rest.strip_prefix("super::") {
            ups += 1;
            rest = r;
        }
        // `super::` from a test module inside a file stays in that file; only
        // a climb to the crate root leaves the group. Its items other than
        // modules are only reachable from the top, so names are checked only
        // when they are modules (see the caller).
        if ups >= depth {
            out.push((line_of(start), ident(rest).to_string(), false));
        }
        at = text.len() - rest.len();
    }
    out
}

#[test]
fn modules_import_only_what_their_layer_allows() {
    let src = src();
    // Each top-level module (a folder or a file) and its rule.
    let mut rules: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut files: Vec<(String, PathBuf, usize)> = Vec::new();
    let mut problems = Vec::new();
    let entries = fs::read_dir(&src).unwrap_or_else(|e| panic!("{}: {e}", src.display()));
    for e in entries {
        let p = e.expect("directory entry").path();
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        if TOP.contains(&name.as_str()) {
            continue;
        }
        let (module, doc_file) = if p.is_dir() {
            (name.clone(), p.join("mod.rs"))
        } else {
            (name.trim_end_matches(".rs").to_string(), p.clone())
        };
        match may_import(&read(&doc_file)) {
            Some(allowed) => rules.insert(module.clone(), allowed),
            None => {
                problems.push(format!("{}: no `//! May import:` line", doc_file.display()));
                rules.insert(module.clone(), BTreeSet::new())
            }
        };
        if p.is_dir() {
            let mut found = Vec::new();
            rust_files(&p, 1, &mut found);
            files.extend(found.into_iter().map(|(f, d)| (module.clone(), f, d)));
        } else {
            files.push((module, p, 1));
        }
    }
    for want in ["support", "images", "emulated", "fpga", "host", "suite"] {
        assert!(rules.contains_key(want), "no top-level module {want}: the layering test needs updating");
    }
    // The rules: known names, support at the bottom, no cycle.
    for (module, allowed) in &rules {
        for a in allowed {
            if !rules.contains_key(a) {
                problems.push(format!("{module}: may import unknown module `{a}`"));
            }
        }
    }
    if rules[SUPPORT].iter().any(|a| a != SUPPORT) {
        problems.push(format!("support may import only itself, its doc says {:?}", rules[SUPPORT]));
    }
    fn reaches(rules: &BTreeMap<String, BTreeSet<String>>, from: &str, to: &str, seen: &mut BTreeSet<String>) -> bool {
        rules
            .get(from)
            .into_iter()
            .flatten()
            .filter(|n| *n != from)
            .any(|n| n == to || (seen.insert(n.clone()) && reaches(rules, n, to, seen)))
    }
    for module in rules.keys() {
        if reaches(&rules, module, module, &mut BTreeSet::new()) {
            problems.push(format!("{module}: the May import rules form a cycle through it"));
        }
    }
    // The sources against the rules.
    for (module, file, depth) in &files {
        let allowed = &rules[module];
        for (line, name, from_crate) in root_paths(&read(file), *depth) {
            let shown = file.strip_prefix(&src).unwrap_or(file).display();
            if rules.contains_key(&name) {
                if name != *module && !allowed.contains(&name) {
                    problems.push(format!("{shown}:{line}: uses `{name}`; {module} may import {allowed:?}"));
                }
            } else if from_crate {
                problems.push(format!("{shown}:{line}: uses `crate::{name}`, from the crate root (main.rs)"));
            }
        }
    }
    assert!(problems.is_empty(), "layering broken:\n{}", problems.join("\n"));
}

#[test]
fn the_checker_sees_every_form_of_path() {
    let text =
        "use crate::a::b;\nuse crate::{c::d, e};\nlet x = crate::f::g();\n/// [`crate::h`]\nuse super::super::i;\n";
    let got: Vec<_> = root_paths(text, 2).into_iter().map(|(l, n, _)| (l, n)).collect();
    let want = [(1, "a"), (2, "c"), (2, "e"), (3, "f"), (4, "h"), (5, "i")];
    assert_eq!(got, want.map(|(l, n)| (l, n.to_string())));
    assert!(root_paths("use super::x;", 2).is_empty(), "a sibling in the same folder");
    assert_eq!(
        may_import("//! May import: `support`, `images`. Not `fpga`."),
        Some(["support", "images"].map(String::from).into())
    );
}
