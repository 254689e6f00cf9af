//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The project's shared folder (third-party test scenes live in `shared/scenes`): the
/// `TRAYECTO_SHARED` environment variable if set, else the first ancestor of the crate root that
/// contains `shared/scenes`. A missing folder fails the test: it is never a silent skip.
pub fn shared_dir() -> PathBuf {
    if let Some(p) = std::env::var_os("TRAYECTO_SHARED") {
        let p = PathBuf::from(p);
        assert!(
            p.join("scenes").is_dir(),
            "TRAYECTO_SHARED={} has no scenes folder",
            p.display()
        );
        return p;
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    for dir in root.ancestors() {
        let candidate = dir.join("shared");
        if candidate.join("scenes").is_dir() {
            return candidate;
        }
    }
    panic!(
        "no shared/scenes folder above {}; set TRAYECTO_SHARED",
        root.display()
    );
}
