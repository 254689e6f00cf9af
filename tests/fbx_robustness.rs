//! Bad FBX input gives clean errors naming the file, never a panic: truncated files, other files
//! renamed `.fbx`, text FBX, and a deterministic mutation run (truncations and byte flips) over
//! the shared FBX scenes.

mod common;

use common::shared_scene;
use std::path::{Path, PathBuf};
use trayecto::scene::{self, fbx};

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto_fbx_{tag}_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn load_err(path: &Path) -> String {
    match scene::load(path.to_str().unwrap()) {
        Ok(_) => panic!("{} loaded", path.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn truncated_and_renamed_files_give_clean_errors() {
    let dir = temp_dir("errors");
    let good = std::fs::read(shared_scene("fbx/cornell_seed_conventions.fbx")).unwrap();
    let cut = dir.join("truncated.fbx");
    std::fs::write(&cut, &good[..good.len() / 2]).unwrap();
    let e = load_err(&cut);
    assert!(
        e.contains("truncated.fbx") && e.contains("truncated"),
        "{e}"
    );

    let png = dir.join("picture.fbx");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR not really a png").unwrap();
    let e = load_err(&png);
    assert!(
        e.contains("picture.fbx") && e.contains("not a binary FBX"),
        "{e}"
    );

    let ascii = dir.join("text.fbx");
    std::fs::write(
        &ascii,
        "; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n}\n",
    )
    .unwrap();
    let e = load_err(&ascii);
    assert!(e.contains("text.fbx") && e.contains("ASCII"), "{e}");

    let empty = dir.join("empty.fbx");
    std::fs::write(&empty, b"").unwrap();
    assert!(load_err(&empty).contains("empty.fbx"));

    // The command line exits non-zero with a one-line cause naming the file.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_trayecto"))
        .args(["info", cut.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("truncated.fbx"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A small deterministic generator (PCG-style LCG) so the mutation run is reproducible.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 33
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn no_panic(data: &[u8], what: &str) {
    let r = std::panic::catch_unwind(|| {
        let _ = fbx::load_bytes(data, "mutant.fbx", None);
    });
    assert!(r.is_ok(), "the loader panicked on {what}");
}

#[test]
fn mutated_files_never_panic() {
    for name in [
        "fbx/cornell_seed_conventions.fbx",
        "fbx/cornell_seed_conventions_lights.fbx",
    ] {
        let good = std::fs::read(shared_scene(name)).unwrap();
        assert!(fbx::load_bytes(&good, name, None).is_ok());
        let mut rng = Lcg(0x5eed_f0b0 ^ good.len() as u64);
        // Truncations: evenly spread, plus every length inside the header and the last bytes.
        let mut cuts: Vec<usize> = (0..64).map(|i| i * good.len() / 64).collect();
        cuts.extend(0..40);
        cuts.extend(good.len() - 40..good.len());
        for c in cuts {
            // The last ~200 bytes are the footer after the closing null record, not content.
            if c + 200 < good.len() {
                let r = fbx::load_bytes(&good[..c], name, None);
                assert!(r.is_err(), "truncated at {c} of {} loaded", good.len());
            }
            no_panic(&good[..c], &format!("{name} truncated at {c}"));
        }
        // Byte flips: single random bytes, and bursts in the header region where lengths live.
        for i in 0..300 {
            let mut m = good.clone();
            let flips = 1 + (i % 4);
            for _ in 0..flips {
                let at = if i % 3 == 0 {
                    rng.below(m.len().min(4096))
                } else {
                    rng.below(m.len())
                };
                m[at] ^= 1 + rng.below(255) as u8;
            }
            no_panic(&m, &format!("{name} mutation {i}"));
        }
        // Length fields set to extremes: every u32 that looks like an offset or count.
        for i in 0..120 {
            let mut m = good.clone();
            let at = 27 + rng.below(m.len() - 31);
            let v: u32 = match i % 4 {
                0 => u32::MAX,
                1 => 0,
                2 => 0x7fff_ffff,
                _ => rng.next() as u32,
            };
            m[at..at + 4].copy_from_slice(&v.to_le_bytes());
            no_panic(&m, &format!("{name} u32 {v:#x} at {at}"));
        }
    }
}
