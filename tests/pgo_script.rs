//! `scripts/pgo-build.sh` (the profile-guided release build that `bench/compare.py` times) is not
//! run by the test suite: it builds the crate twice. These tests check what can be checked
//! without building: the script parses, and it refuses an unusable `llvm-profdata` up front, with
//! exit code 2 and a message naming the tool, before compiling anything.

use std::path::Path;
use std::process::Command;

fn script() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/pgo-build.sh")
}

#[test]
fn pgo_script_parses() {
    let out = Command::new("bash")
        .arg("-n")
        .arg(script())
        .output()
        .expect("bash runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn pgo_script_refuses_a_missing_profdata_before_building() {
    let out = Command::new("bash")
        .arg(script())
        .env("LLVM_PROFDATA", "/nonexistent/llvm-profdata")
        .output()
        .expect("bash runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(
        stderr.contains("no usable llvm-profdata") && stderr.contains("/nonexistent/llvm-profdata"),
        "stderr: {stderr}"
    );
    assert!(
        !stderr.contains("[pgo] 1/3"),
        "it started building: {stderr}"
    );
    assert!(out.stdout.is_empty(), "no binary path may be printed");
}
