//! The wavefront path loop (`integrator::wavefront`, docs/DESIGN.md §6, "Wavefront path loop")
//! renders bit for bit what the scalar path tracer renders, on scenes that exercise its stages:
//! textures and normal maps, MIS between light and BSDF samples with several lights, many
//! emitters, an environment map, delta lights, transmission and specular chains, the depth
//! limit and clamping, and each sampler's way of handing out the bounces' numbers (drawn for the
//! whole wave or path by path). Each scene is rendered with the loop forced each way
//! (`TRAYECTO_PATH_LOOP`) and with the portable and the widest SIMD code this CPU has
//! (`TRAYECTO_SIMD`; tests/simd.rs covers each level by name), and every float of the four images
//! must be the same bits.

mod common;

use std::process::Command;

fn render(
    dir: &std::path::Path,
    scene: &str,
    extra: &[&str],
    path_loop: &str,
    avx2: bool,
) -> Vec<u32> {
    let out = dir.join(format!("{path_loop}-{avx2}.exr"));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_trayecto"));
    cmd.args(["render", scene, "-o"])
        .arg(&out)
        .args(["--width", "40", "--height", "32", "-q"])
        .args(extra)
        .current_dir(common::repo_dir())
        .env("TRAYECTO_PATH_LOOP", path_loop);
    cmd.env_remove("TRAYECTO_NO_AVX2");
    if avx2 {
        cmd.env_remove("TRAYECTO_SIMD");
    } else {
        cmd.env("TRAYECTO_SIMD", "portable");
    }
    if !extra.contains(&"--spp") {
        // A square power of two: the stratified sampler's bounce numbers are drawn for the
        // whole wave (`sampling::sampler::WaveDraw`).
        cmd.args(["--spp", "16"]);
    }
    let o = cmd.output().expect("binary runs");
    assert!(
        o.status.success(),
        "{scene} {extra:?} ({path_loop}): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    common::exr_bits(&out, scene)
}

#[test]
fn the_wavefront_loop_renders_the_scalar_tracers_image_bit_for_bit() {
    let dir = std::env::temp_dir().join(format!("trayecto-wavefront-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let shared = |rel: &str| common::shared_scene(rel).display().to_string();
    let cases: Vec<(String, Vec<&str>)> = vec![
        ("cornell".into(), vec![]),
        ("cornell".into(), vec!["--max-depth", "0"]),
        (
            "cornell".into(),
            vec!["--clamp-indirect", "0.5", "--rr-depth", "1"],
        ),
        ("cornell".into(), vec!["--no-mis"]),
        // Bounce numbers drawn by each path as it goes: a sample count whose grid is not a
        // power of two, and a sampler the wave's kernel does not cover.
        ("cornell".into(), vec!["--spp", "8"]),
        ("cornell".into(), vec!["--sampler", "zsobol"]),
        // Stratified then hashed numbers from the third bounce on (`--rr-depth 1`: roulette's
        // numbers too).
        (
            "cornell".into(),
            vec!["--sampler", "padded", "--rr-depth", "1"],
        ),
        (
            shared("gltf/BoxTextured/glTF-Binary/BoxTextured.glb"),
            vec![],
        ),
        (
            shared("gltf/NormalTangentTest/glTF/NormalTangentTest.gltf"),
            vec![],
        ),
        (
            shared("gltf/TransmissionTest/glTF-Binary/TransmissionTest.glb"),
            vec![],
        ),
        (
            shared("gltf/EmissiveStrengthTest/glTF-Binary/EmissiveStrengthTest.glb"),
            vec![],
        ),
        // pbrt files render spectrally (the scalar tracer's) unless `--rgb`.
        (shared("pbrt/veach-mis/scene-v4.pbrt"), vec!["--rgb"]),
        (shared("pbrt/veach-mis/scene-v4.pbrt"), vec![]),
        ("scenes/mitsuba/envmap.toml".into(), vec![]),
        ("scenes/mitsuba/point.toml".into(), vec!["--transparent"]),
        ("scenes/mitsuba/glass.toml".into(), vec![]),
    ];
    for (scene, extra) in &cases {
        let scalar = render(&dir, scene, extra, "scalar", true);
        for (path_loop, avx2) in [("wavefront", true), ("wavefront", false), ("scalar", false)] {
            let other = render(&dir, scene, extra, path_loop, avx2);
            let differ = scalar.iter().zip(&other).filter(|(a, b)| a != b).count();
            assert!(
                differ == 0 && scalar.len() == other.len(),
                "{scene} {extra:?}: {path_loop} (AVX2 {avx2}) differs from the scalar loop in \
                 {differ} of {} channels",
                scalar.len()
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
