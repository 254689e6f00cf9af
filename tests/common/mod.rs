//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The shared folder with third-party test scenes (`shared/scenes/...`): `$TRAYECTO_SHARED` if set,
/// else the first `shared` directory containing `scenes` found walking up from the crate root
/// (`/work/shared` beside the worktrees, `../shared` beside a CI clone). Panics if there is none:
/// a missing scene is a test failure, never a silent skip.
pub fn shared_dir() -> PathBuf {
    if let Ok(p) = std::env::var("TRAYECTO_SHARED") {
        let p = PathBuf::from(p);
        assert!(
            p.join("scenes").is_dir(),
            "TRAYECTO_SHARED={} has no scenes folder",
            p.display()
        );
        return p;
    }
    let mut dir = Some(PathBuf::from(env!("CARGO_MANIFEST_DIR")));
    while let Some(d) = dir {
        let cand = d.join("shared");
        if cand.join("scenes").is_dir() {
            return cand;
        }
        dir = d.parent().map(PathBuf::from);
    }
    panic!(
        "no shared/scenes directory above {}; set TRAYECTO_SHARED",
        env!("CARGO_MANIFEST_DIR")
    );
}

/// A file under `shared/scenes`, which must exist.
pub fn shared_scene(rel: &str) -> PathBuf {
    let p = shared_dir().join("scenes").join(rel);
    assert!(p.is_file(), "missing shared test scene {}", p.display());
    p
}
