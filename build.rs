//! Computes the render identity (`trayecto::RENDER_IDENTITY`): a SHA-256 of everything that
//! decides the image a build renders — the crate's source files (`src/**`), `Cargo.toml`,
//! `Cargo.lock` (the exact dependency versions), this script, the enabled features and the target.
//! Partial films (`.trp`) carry it in their header, and merging refuses parts whose identities
//! differ: two builds of the same version number can render different images. Only files are
//! read (no git), so a fresh clone or a source tarball builds alike.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            files_under(&p, out);
        } else {
            out.push(p);
        }
    }
}

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    // A directory makes cargo rerun the script when any file below it changes (by mtime);
    // with any rerun-if-changed line, other package files no longer trigger a rerun.
    for p in ["src", "Cargo.toml", "Cargo.lock", "build.rs"] {
        println!("cargo:rerun-if-changed={p}");
    }
    let mut files = Vec::new();
    files_under(&root.join("src"), &mut files);
    for p in ["Cargo.toml", "Cargo.lock", "build.rs"] {
        files.push(root.join(p));
    }
    let mut names: Vec<(String, PathBuf)> = files
        .into_iter()
        .map(|p| {
            // Relative, '/'-separated names: the identity does not depend on where the
            // checkout is or on the platform's separator.
            let rel = p.strip_prefix(&root).unwrap_or(&p);
            let name = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect::<Vec<_>>()
                .join("/");
            (name, p)
        })
        .collect();
    names.sort();
    let mut h = Sha256::new();
    for (name, path) in &names {
        // A missing file (e.g. no Cargo.lock in a tarball) hashes as absent, not as empty.
        match std::fs::read(path) {
            Ok(bytes) => {
                h.update(b"file\0");
                h.update(name.as_bytes());
                h.update(b"\0");
                h.update((bytes.len() as u64).to_le_bytes());
                h.update(&bytes);
            }
            Err(_) => {
                h.update(b"absent\0");
                h.update(name.as_bytes());
                h.update(b"\0");
            }
        }
    }
    let mut features: Vec<String> = std::env::vars()
        .filter_map(|(k, _)| k.strip_prefix("CARGO_FEATURE_").map(str::to_string))
        .collect();
    features.sort();
    h.update(format!("features\0{}\0", features.join(",")).as_bytes());
    h.update(format!("target\0{}\0", std::env::var("TARGET").unwrap_or_default()).as_bytes());
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    println!("cargo:rustc-env=TRAYECTO_RENDER_IDENTITY={hex}");
}
