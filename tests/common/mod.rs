//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The shared folder that holds `scenes/`: `$TRAYECTO_SHARED` if set, else the first ancestor of
/// the crate root with a `shared/scenes` inside (`/work/shared` beside `/work/main`; `../shared`
/// beside CI's clone). Panics (a test failure, never a skip) if it cannot be found.
pub fn shared_dir() -> PathBuf {
    if let Ok(dir) = std::env::var("TRAYECTO_SHARED") {
        let p = PathBuf::from(dir);
        assert!(
            p.join("scenes").is_dir(),
            "TRAYECTO_SHARED={} has no scenes/ folder",
            p.display()
        );
        return p;
    }
    let mut dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    loop {
        let candidate = dir.join("shared");
        if candidate.join("scenes").is_dir() {
            return candidate;
        }
        if !dir.pop() {
            panic!(
                "no shared/scenes folder above {} (set TRAYECTO_SHARED)",
                env!("CARGO_MANIFEST_DIR")
            );
        }
    }
}
