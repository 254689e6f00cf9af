//! The documents serve the reader: README.md stays short, every relative link in README.md,
//! BENCHMARKS.md and the guide (docs/src, an mdBook source tree) leads to a file that exists, every
//! chapter is in the book's SUMMARY.md, and the documents cite papers, standards and the project's
//! own docs rather than a tracker's issue numbers or work sessions. (The options tables in the guide
//! are checked against clap by the binary's `readme` tests.)

use std::fs;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// README.md, BENCHMARKS.md and every `.md` file under docs/src.
fn documents() -> Vec<PathBuf> {
    let mut docs = vec![root().join("README.md"), root().join("BENCHMARKS.md")];
    let mut chapters: Vec<PathBuf> = fs::read_dir(root().join("docs/src"))
        .expect("docs/src exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    chapters.sort();
    docs.extend(chapters);
    docs
}

/// The text outside fenced code blocks, as (line number, line).
fn prose(text: &str) -> Vec<(usize, &str)> {
    let mut fenced = false;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            out.push((i + 1, line));
        }
    }
    out
}

/// The targets of the markdown links and images `[text](target)` on a line, without a title.
fn link_targets(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find("](") {
        let after = &rest[i + 2..];
        let Some(end) = after.find(')') else { break };
        let target = after[..end].split_whitespace().next().unwrap_or("");
        out.push(target);
        rest = &after[end..];
    }
    out
}

/// Relative targets must name an existing file or folder (a `#fragment` is not checked).
fn is_relative(target: &str) -> bool {
    !(target.is_empty()
        || target.starts_with('#')
        || target.contains("://")
        || target.starts_with("mailto:"))
}

#[test]
fn readme_is_under_300_lines() {
    let n = read(&root().join("README.md")).lines().count();
    assert!(
        n < 300,
        "README.md has {n} lines: move the detail into the guide (docs/src)"
    );
}

#[test]
fn every_relative_link_resolves() {
    let mut broken = Vec::new();
    let mut checked = 0;
    for doc in documents() {
        let text = read(&doc);
        let dir = doc.parent().unwrap();
        for (n, line) in prose(&text) {
            for target in link_targets(line).into_iter().filter(|t| is_relative(t)) {
                let file = target.split('#').next().unwrap();
                checked += 1;
                if !dir.join(file).exists() {
                    broken.push(format!("{}:{n}: {target}", doc.display()));
                }
            }
        }
        // mdBook's {{#include FILE[:lines]}} directives, inside code blocks too.
        for (n, line) in text.lines().enumerate() {
            if let Some(i) = line.find("{{#include ") {
                let arg = line[i + 11..].split("}}").next().unwrap().trim();
                let file = arg.split(':').next().unwrap();
                checked += 1;
                if !dir.join(file).is_file() {
                    broken.push(format!("{}:{}: include {file}", doc.display(), n + 1));
                }
            }
        }
    }
    assert!(
        checked > 50,
        "only {checked} links found: is the parser right?"
    );
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn the_summary_lists_every_chapter_and_only_existing_ones() {
    let src = root().join("docs/src");
    let summary = read(&src.join("SUMMARY.md"));
    let listed: Vec<&str> = summary
        .lines()
        .flat_map(link_targets)
        .filter(|t| is_relative(t))
        .collect();
    for t in &listed {
        assert!(
            src.join(t).is_file(),
            "SUMMARY.md lists {t}, which is missing"
        );
    }
    for doc in documents().iter().filter(|d| d.starts_with(&src)) {
        let name = doc.file_name().unwrap().to_str().unwrap();
        assert!(
            name == "SUMMARY.md" || listed.contains(&name),
            "docs/src/{name} is not in SUMMARY.md"
        );
    }
    assert!(root().join("docs/book.toml").is_file());
}

/// "issue #18", "issue 23", "session 16", "Sessions 10–11": the tracker and the diary are not
/// where a reader can follow them.
fn history_reference(line: &str) -> Option<String> {
    let lower = line.to_lowercase();
    for word in ["issue", "session"] {
        let mut from = 0;
        while let Some(i) = lower[from..].find(word) {
            let start = from + i;
            let after = &lower[start + word.len()..];
            let after = after.strip_prefix('s').unwrap_or(after);
            let after = after.trim_start_matches([' ', '#']);
            let before_ok = start == 0 || !lower.as_bytes()[start - 1].is_ascii_alphanumeric();
            if before_ok && after.starts_with(|c: char| c.is_ascii_digit()) {
                return Some(line[start..].chars().take(20).collect());
            }
            from = start + word.len();
        }
    }
    // A bare "#23" as a reference (not a heading, not a colour or an anchor).
    let bytes = line.as_bytes();
    for (i, &b) in bytes.iter().enumerate() {
        if b == b'#'
            && i > 0
            && bytes[i - 1] == b' '
            && bytes.get(i + 1).is_some_and(|c| c.is_ascii_digit())
            && bytes
                .get(i + 2)
                .is_some_and(|c| c.is_ascii_digit() || *c == b' ' || *c == b';')
        {
            return Some(line[i..].chars().take(12).collect());
        }
    }
    None
}

#[test]
fn documents_cite_no_issue_numbers_or_sessions() {
    let mut found = Vec::new();
    for doc in documents() {
        let text = read(&doc);
        for (n, line) in prose(&text) {
            if let Some(what) = history_reference(line) {
                found.push(format!("{}:{n}: {what}", doc.display()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "cite papers, standards or docs/, not the tracker or work sessions:\n{}",
        found.join("\n")
    );
}

#[test]
fn the_history_check_recognises_what_it_should() {
    assert!(history_reference("participating media (issue #18): homogeneous").is_some());
    assert!(history_reference("BENCHMARKS.md, \"Session 15: defaults\"").is_some());
    assert!(history_reference("(sessions 10–11, quick mode)").is_some());
    assert!(history_reference("and #17's glass slab").is_some());
    assert!(history_reference("the viewport's session ID, /api/viewport?session=ID").is_none());
    assert!(history_reference("## 2. Install").is_none());
}
