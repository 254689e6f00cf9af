//! The image does not depend on the instruction set the renderer dispatches to at run time
//! (`TRAYECTO_SIMD`, docs/DESIGN.md "SIMD levels"): every level this CPU has renders the same
//! bits on scenes that reach each dispatch site — the geometry BVH's traversal on a 15k-triangle
//! mesh, the light BVH's descent (four- and eight-way) over hundreds of emissive triangles,
//! textures, normal maps and the environment map — in the wavefront loop (RGB) and in the
//! spectral scalar tracer (pbrt). A level the CPU lacks is skipped by name on stderr. The setting
//! is checked too: the render log names the level that ran, and an unknown level (AVX-512 spelt
//! other than `avx512`), a level the CPU lacks or the old `TRAYECTO_NO_AVX2` beside another
//! level is an error, not silently some other code.

mod common;

use std::process::{Command, Output};
use trayecto::math::SimdLevel;

fn run(scene: &str, out: &std::path::Path, extra: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_trayecto"));
    cmd.args(["render", scene, "-o"])
        .arg(out)
        .args(["--width", "48", "--height", "40", "--spp", "16"])
        .args(extra)
        .current_dir(common::repo_dir())
        .env_remove("TRAYECTO_SIMD")
        .env_remove("TRAYECTO_NO_AVX2");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("binary runs")
}

fn log(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The image's float bits at `level`, after checking that the log says `level` ran.
fn render(dir: &std::path::Path, scene: &str, extra: &[&str], level: SimdLevel) -> Vec<u32> {
    let out = dir.join(format!("{}.exr", level.name()));
    let o = run(scene, &out, extra, &[("TRAYECTO_SIMD", level.name())]);
    let log = log(&o);
    assert!(o.status.success(), "{scene} {extra:?} at {level}: {log}");
    assert!(
        log.contains(&format!("SIMD            {level} ")),
        "{scene} at {level}: the log does not say which code ran:\n{log}"
    );
    common::exr_bits(&out, scene)
}

#[test]
fn every_simd_level_renders_the_same_bits() {
    let dir = std::env::temp_dir().join(format!("trayecto-simd-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let levels: Vec<SimdLevel> = SimdLevel::ALL
        .into_iter()
        .filter(|l| {
            let has = l.available();
            if !has {
                eprintln!("SIMD level {l} skipped: this CPU does not have it");
            }
            has
        })
        .collect();
    let shared = |rel: &str| common::shared_scene(rel).display().to_string();
    let helmet = shared("gltf/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
    let emissive = shared("gltf/EmissiveStrengthTest/glTF-Binary/EmissiveStrengthTest.glb");
    let cases: Vec<(String, Vec<&str>)> = vec![
        // 15k triangles (BVH), 486 emissive triangles (eight-way light BVH), four textures with a
        // normal map, lit also by the default environment.
        (helmet.clone(), vec![]),
        (helmet, vec!["--light-sampler", "bvh"]),
        (emissive.clone(), vec!["--light-sampler", "bvh"]),
        (emissive, vec!["--light-sampler", "bvh8"]),
        ("scenes/mitsuba/envmap.toml".into(), vec![]),
        ("scenes/mitsuba/textured.toml".into(), vec![]),
        // The wave's bounce numbers (`sampling::sampler::WaveDraw`, an AVX2 copy hashing with
        // AVX-512 at `avx512`): stratified (above, 16 spp), and stratified then hashed past the
        // padded sampler's dimensions, with roulette's numbers from the second bounce.
        (
            "cornell".into(),
            vec!["--sampler", "padded", "--rr-depth", "1"],
        ),
        // Spectral, the scalar tracer: the wavefront loop does not run it.
        (
            shared("pbrt/veach-mis/scene-v4.pbrt"),
            vec!["--light-sampler", "bvh8"],
        ),
    ];
    for (scene, extra) in &cases {
        let first = render(&dir, scene, extra, levels[0]);
        for &level in &levels[1..] {
            let other = render(&dir, scene, extra, level);
            let differ = first.iter().zip(&other).filter(|(a, b)| a != b).count();
            assert!(
                differ == 0 && first.len() == other.len(),
                "{scene} {extra:?}: {level} differs from {} in {differ} of {} channels",
                levels[0],
                first.len()
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_simd_level_that_cannot_run_as_asked_is_an_error() {
    let dir = std::env::temp_dir().join(format!("trayecto-simd-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("bad.exr");
    let mut refused: Vec<(Vec<(&str, &str)>, &str)> = vec![
        (vec![("TRAYECTO_SIMD", "avx-512")], "AVX-512 is `avx512`"),
        (vec![("TRAYECTO_SIMD", "fastest")], "\"fastest\""),
        (
            vec![("TRAYECTO_SIMD", "avx2"), ("TRAYECTO_NO_AVX2", "1")],
            "TRAYECTO_NO_AVX2",
        ),
    ];
    for level in SimdLevel::ALL.into_iter().filter(|l| !l.available()) {
        refused.push((
            vec![("TRAYECTO_SIMD", level.name())],
            "this CPU does not have",
        ));
    }
    for (env, says) in &refused {
        let o = run("cornell", &out, &["-q"], env);
        let log = log(&o);
        assert!(!o.status.success(), "{env:?} rendered:\n{log}");
        assert!(
            log.contains(says),
            "{env:?}: the error lacks '{says}':\n{log}"
        );
        assert!(!out.exists(), "{env:?} wrote an image");
    }
    // The older switch alone is the portable code, and says so.
    let o = run("cornell", &out, &[], &[("TRAYECTO_NO_AVX2", "1")]);
    let log = log(&o);
    assert!(o.status.success(), "{log}");
    assert!(log.contains("SIMD            portable "), "{log}");
    let _ = std::fs::remove_dir_all(&dir);
}
