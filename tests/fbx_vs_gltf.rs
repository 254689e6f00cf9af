//! docs/DESIGN.md §3 / issue 7: `cornell_seed_conventions.fbx` and its `.glb` twin (exported from the same
//! Blender scene) render the same image for the same seed: the mean of each channel within 1%
//! and the per-pixel difference far below the noise of the estimator.

mod common;

use common::shared_scene;
use std::sync::atomic::AtomicBool;
use trayecto::film::Image;
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene;
use trayecto::world::{World, WorldOptions};

fn render_file(path: &str, seed: u64) -> Image {
    let s = scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    let world = World::build(s.clone(), &WorldOptions::default()).unwrap();
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp: 64,
        seed,
        ..Default::default()
    };
    render(&world, &settings, &NoObserver, &AtomicBool::new(false))
        .unwrap()
        .image
}

/// Root-mean-square difference of two images, per channel, over all pixels.
fn rms(a: &Image, b: &Image) -> f64 {
    let n = a.data.len() as f64;
    (a.data
        .iter()
        .zip(&b.data)
        .map(|(p, q)| (*p - *q).length_squared() as f64)
        .sum::<f64>()
        / n)
        .sqrt()
}

/// The largest accepted ratio of the twins' per-pixel RMS difference (same seed) to the RMS
/// difference of two independent renders (seeds 7 and 8). Measured 0.251 (0.0206 / 0.0819): the
/// same random numbers make most pixels agree to ~0.002, and the exporters' rounding of vertices
/// sends a tail of paths (≈ 1 % of pixels) along different bounces. The renders are deterministic,
/// so the ratio is a fixed number, not a random one; shifting the FBX geometry by 0.01 along x
/// gives 0.343 and must fail.
const TWIN_NOISE_RATIO: f64 = 0.30;

#[test]
fn fbx_and_glb_twins_render_the_same_image() {
    let fbx = shared_scene("fbx/cornell_seed_conventions.fbx");
    let glb = shared_scene("fbx/cornell_seed_conventions.glb");
    let a = render_file(fbx.to_str().unwrap(), 7);
    let b = render_file(glb.to_str().unwrap(), 7);
    let (ma, mb) = (a.mean(), b.mean());
    for c in 0..3 {
        let rel = ((ma[c] - mb[c]) / mb[c]).abs();
        assert!(
            rel < 0.01,
            "channel {c}: FBX {} vs glTF {} ({rel:.4})",
            ma[c],
            mb[c]
        );
    }
    // Per pixel: the same seed and the same scene give the same random numbers per pixel, so the
    // twins' difference is far below the difference between two independent renders of the same
    // file (the noise level); only the exporters' rounding of vertices and values separates them.
    let c = render_file(fbx.to_str().unwrap(), 8);
    let (twin, noise) = (rms(&a, &b), rms(&a, &c));
    println!("per-pixel RMS difference: twins {twin:.5}, independent seeds {noise:.5}");
    assert!(
        twin <= TWIN_NOISE_RATIO * noise,
        "per-pixel RMS difference FBX vs glTF {twin:.5} exceeds the noise {noise:.5}"
    );
    // The ceiling light (emissive by name) is seen directly at the top centre.
    let light = a.get(32, 9);
    let expected = trayecto::math::Vec3::new(0.92, 0.70, 0.34) * 5.0;
    assert!((light - expected).abs().max_element() < 0.5, "{light}");
}
