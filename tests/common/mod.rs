//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// The folder holding the third-party test scenes (`shared/`): `$TRAYECTO_SHARED` if set, else
/// the first ancestor of the crate root that contains `shared/scenes`. Missing is a failure.
pub fn shared_dir() -> PathBuf {
    if let Some(p) = std::env::var_os("TRAYECTO_SHARED") {
        let p = PathBuf::from(p);
        assert!(
            p.join("scenes").is_dir(),
            "TRAYECTO_SHARED={} has no scenes/ folder",
            p.display()
        );
        return p;
    }
    let mut dir: Option<&Path> = Some(Path::new(env!("CARGO_MANIFEST_DIR")));
    while let Some(d) = dir {
        if d.join("shared").join("scenes").is_dir() {
            return d.join("shared");
        }
        dir = d.parent();
    }
    panic!(
        "no shared/scenes folder above {}; set TRAYECTO_SHARED",
        env!("CARGO_MANIFEST_DIR")
    );
}

/// A file under `shared/scenes/`, which must exist.
pub fn scene_file(rel: &str) -> PathBuf {
    let p = shared_dir().join("scenes").join(rel);
    assert!(p.is_file(), "missing test scene {}", p.display());
    p
}
