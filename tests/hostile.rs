//! The fuzzing regression corpus: every file under `tests/hostile/<target>/` goes through the
//! entry point of the fuzz target of that name (`fuzz/entries.rs`, the very function the
//! cargo-fuzz target calls), so an input a fuzzer or a reader once crashed stays a test. Each
//! must return — `Ok` or a clean error — without a panic, within the time limit below.
//! docs/src/fuzzing.md says how to add a case.

#[path = "../fuzz/entries.rs"]
mod entries;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The promise for a hostile file under 1 MB: an answer within 20 s (the test profile is optimised).
const TIME_LIMIT: Duration = Duration::from_secs(20);

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/hostile")
}

/// Runs every case of `dir` through `entry`; returns the failures (file: what happened).
fn run_cases(dir: &Path, entry: entries::Entry) -> Vec<String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file() && p.file_name().is_none_or(|n| n != "README.md"))
        .collect();
    files.sort();
    let mut failures = Vec::new();
    for f in files {
        let data = std::fs::read(&f).unwrap();
        let t = Instant::now();
        let r = std::panic::catch_unwind(|| entry(&data));
        let took = t.elapsed();
        match r {
            Err(e) => {
                let msg = e
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                failures.push(format!("{}: panicked: {msg}", f.display()));
            }
            Ok(()) if took > TIME_LIMIT => {
                failures.push(format!("{}: took {took:?}", f.display()));
            }
            Ok(()) => {}
        }
    }
    failures
}

/// Every folder of the corpus is named after a target, and every case of it returns.
#[test]
fn every_hostile_input_is_answered_without_a_panic() {
    let mut failures = Vec::new();
    let mut cases = 0;
    for e in std::fs::read_dir(corpus()).unwrap() {
        let dir = e.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        let Some((_, entry)) = entries::TARGETS.iter().find(|(n, _)| *n == name) else {
            panic!(
                "tests/hostile/{name}: no fuzz entry point of that name in fuzz/entries.rs ({:?})",
                entries::TARGETS.iter().map(|t| t.0).collect::<Vec<_>>()
            );
        };
        cases += std::fs::read_dir(&dir).unwrap().count();
        failures.extend(run_cases(&dir, *entry));
    }
    assert!(cases > 0, "the corpus is empty");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every entry point is a `[[bin]]` of the fuzz crate, so scripts/fuzz.sh fuzzes it.
#[test]
fn every_entry_point_is_a_fuzz_target() {
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/Cargo.toml"))
            .unwrap();
    for (name, _) in entries::TARGETS {
        assert!(
            manifest.contains(&format!(
                "name = \"{name}\"\npath = \"fuzz_targets/{name}.rs\""
            )),
            "fuzz/Cargo.toml has no [[bin]] {name}"
        );
    }
}
