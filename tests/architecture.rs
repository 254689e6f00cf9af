//! The layout docs/DESIGN.md §1 promises, checked on the source itself: no import circle among
//! `src/` files and no import from a lower stage to a higher one (`scripts/check-imports.py`
//! builds the file-level graph), and integrators that ask lights and media through their
//! methods instead of matching on what kind of light or medium they hold.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn the_import_graph_has_no_cycle_and_no_upward_import() {
    let out = Command::new("python3")
        .arg(repo().join("scripts/check-imports.py"))
        .arg("--src")
        .arg(repo().join("src"))
        .output()
        .expect("python3 runs scripts/check-imports.py (the test script's machine has Python 3)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "scripts/check-imports.py found import cycles or upward imports:\n{stdout}{stderr}"
    );
    // The summary line proves the script walked the tree (an empty graph would also be acyclic).
    let files: usize = stdout
        .lines()
        .rev()
        .find_map(|l| {
            let (_, rest) = l.split_once(" imports between ")?;
            rest.split_whitespace().next()?.parse().ok()
        })
        .unwrap_or_else(|| panic!("no summary line in the script's output:\n{stdout}"));
    assert!(
        files >= 100,
        "only {files} files in the import graph:\n{stdout}"
    );
}

fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(rust_files(&path));
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
    out.sort();
    out
}

/// The names an integrator must not spell: the variants of `enum Light` (each light owns its
/// sampling, pdfs and emission) and the fields of `Medium` that only the medium's own methods
/// and the world's media queries read. Taken from the enum's source, so a new light type is
/// covered without editing this test.
fn forbidden_names() -> Vec<String> {
    let light = std::fs::read_to_string(repo().join("src/light/mod.rs")).unwrap();
    let start = light
        .find("pub enum Light {")
        .expect("enum Light in src/light/mod.rs");
    let body = &light[start..start + light[start..].find("\n}").unwrap()];
    let mut names: Vec<String> = body
        .lines()
        .skip(1)
        .map(str::trim)
        .filter(|l| !l.starts_with("//") && !l.is_empty())
        .filter_map(|l| {
            let variant: String = l.chars().take_while(|c| c.is_alphanumeric()).collect();
            (!variant.is_empty()).then(|| format!("Light::{variant}"))
        })
        .collect();
    assert!(names.len() >= 6, "parsed too few light variants: {names:?}");
    names.extend([".grid".to_string(), "media.active".to_string()]);
    names
}

#[test]
fn integrators_do_not_match_on_light_or_medium_kinds() {
    let forbidden = forbidden_names();
    let mut found = Vec::new();
    for file in rust_files(&repo().join("src/integrator")) {
        let text = std::fs::read_to_string(&file).unwrap();
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            for name in &forbidden {
                let at = code.find(name.as_str());
                // `.grid` only as a whole field name (not `.grid_le`, `.grid_x`).
                let whole = at.is_some_and(|k| {
                    !code[k + name.len()..].starts_with(|c: char| c.is_alphanumeric() || c == '_')
                });
                if whole {
                    found.push(format!("{}:{}: {}", file.display(), i + 1, line.trim()));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "integrators name light or medium kinds:\n{}",
        found.join("\n")
    );
}

/// The check above can fail: the same scan finds what it forbids in a line written that way.
#[test]
fn the_variant_scan_sees_a_match_on_a_light() {
    let forbidden = forbidden_names();
    let line = "match light { Light::Point(p) => p.sample_li(x), _ => None }";
    assert!(forbidden.iter().any(|n| line.contains(n.as_str())));
    assert!(forbidden.iter().any(|n| n == "Light::Environment"));
}
