//! Materials, textures and every light type against Mitsuba 3. Each scene is a Trayecto
//! TOML file under scenes/mitsuba/; scripts/references/make_material_references.py translates the
//! same file into a Mitsuba scene dictionary and rendered the committed references
//! tests/references/mitsuba_NAME.exr (32768 spp, llvm_ad_rgb). For every scene: the per-channel
//! image means agree within 2%, and the RMSE against the reference falls from 4 to 64 spp as
//! Monte Carlo noise does (≈ 4×; a renderer with a bias comparable to its 64-spp noise fails the
//! ≥ 2.5× bound). Where the models differ on purpose (the spot light's soft edge), the difference
//! is asserted to stay at its measured, documented size (docs/src/correctness.md, "Agreement with
//! Mitsuba 3").

mod common;
use common::*;
use trayecto::film::Image;
use trayecto::film::output::read_exr;
use trayecto::integrator::PathSettings;
use trayecto::math::{Mat4, Vec3};
use trayecto::render::RenderSettings;
use trayecto::sampling::SamplerKind;
use trayecto::scene::{LightDesc, Scene};
use trayecto::world::{World, WorldOptions};

/// The environment map's rotation about +y, in degrees (the script uses the same).
const ENVMAP_ROTATION_DEG: f32 = 90.0;

fn scene(name: &str) -> Scene {
    let path = repo_dir().join(format!("scenes/mitsuba/{name}.toml"));
    let mut scene = trayecto::scene::load(path.to_str().unwrap()).expect("scene loads");
    assert!(
        scene.warnings.is_empty(),
        "{name}: unexpected warnings {:?}",
        scene.warnings
    );
    if name == "envmap" {
        // Scene files read only from their own folder, so the shared map is added here.
        scene.lights.push(LightDesc::Environment {
            name: "studio".into(),
            path: shared_scene("hdr/studio_small_03_1k.hdr"),
            scale: Vec3::ONE,
            mapping: Default::default(),
            transform: Mat4::from_rotation_y(ENVMAP_ROTATION_DEG.to_radians()),
        });
    }
    scene
}

fn reference(name: &str) -> Image {
    read_exr(&repo_dir().join(format!("tests/references/mitsuba_{name}.exr")))
        .expect("reference EXR")
}

fn settings(width: u32, height: u32, spp: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        spp,
        seed: 11,
        sampler: SamplerKind::Stratified,
        path: PathSettings {
            max_depth: 1024,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// RMSE over the pixels that `mask` keeps.
fn rmse_masked(img: &Image, reference: &Image, mask: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for ((p, q), &keep) in img.data.iter().zip(&reference.data).zip(mask) {
        if keep {
            s += (*p - *q).as_dvec3().length_squared();
            n += 3;
        }
    }
    (s / n as f64).sqrt()
}

/// Pixels entirely covered by geometry (all 4 × 4 sub-pixel rays of the raycast depth view hit).
///
/// Where the environment map is seen directly, the two renderers differ by design: Mitsuba's
/// `envmap` puts texel rows at v = j/(h − 1), Trayecto at texel centres (j + ½)/h
/// (docs/src/correctness.md). Along the studio lamps' edges, ~500 times brighter than the rest,
/// that half-texel shift is a per-pixel difference that no number of samples removes, so the
/// convergence check leaves those pixels (and the silhouettes, partly background) out; the mean
/// check keeps every pixel.
fn covered_pixels(scene: &Scene, width: u32, height: u32) -> Vec<bool> {
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .expect("scene builds");
    coverage(&world, width, height, &settings(width, height, 1))
        .into_iter()
        .map(|c| c == 1.0)
        .collect()
}

/// Renders `name` at 4 and 64 spp; returns (64-spp image, reference, rmse at 4, rmse at 64).
fn render_pair(name: &str, width: u32, height: u32) -> (Image, Image, f64, f64) {
    let reference = reference(name);
    assert_eq!((reference.width, reference.height), (width, height));
    let scene = scene(name);
    let low = render_scene(&scene, &settings(width, height, 4));
    let high = render_scene(&scene, &settings(width, height, 64));
    let (e_low, e_high) = if name == "envmap" {
        let mask = covered_pixels(&scene, width, height);
        assert!(
            mask.iter().filter(|&&m| m).count() > 500,
            "the spheres should cover a good part of the image"
        );
        (
            rmse_masked(&low, &reference, &mask),
            rmse_masked(&high, &reference, &mask),
        )
    } else {
        (rmse(&low, &reference), rmse(&high, &reference))
    };
    (high, reference, e_low, e_high)
}

fn agrees_and_converges(name: &str, width: u32, height: u32) {
    let (mut high, reference, e_low, e_high) = render_pair(name, width, height);
    if name == "envmap" {
        // The lamps' highlights on the polished sphere are a handful of pixels ~300 times
        // brighter than the image mean and hold a quarter of its sum; at 64 spp their
        // anti-aliasing noise alone moves the mean by up to ±5 % between seeds (measured, seeds
        // 11–15). The mean is therefore compared at 1024 spp (±1.2 %), where 2 % means something.
        high = render_scene(&scene(name), &settings(width, height, 1024));
    }
    let (m, r) = (high.mean(), reference.mean());
    println!(
        "{name}: mean {m} vs Mitsuba {r} (relative {:.4} {:.4} {:.4}); rmse {e_low:.4} at 4 spp, {e_high:.4} at 64 spp (ratio {:.2})",
        m.x / r.x - 1.0,
        m.y / r.y - 1.0,
        m.z / r.z - 1.0,
        e_low / e_high
    );
    assert_means_close(&high, &reference, 0.02, name);
    // 16× the samples: the error of an unbiased estimate falls ≈ 4×; demand at least 2.5×.
    assert!(
        e_high < e_low / 2.5,
        "{name}: error did not fall with samples: rmse {e_low} at 4 spp, {e_high} at 64 spp"
    );
}

#[test]
fn metals_match_mitsuba() {
    agrees_and_converges("metals", 96, 64);
}

/// pbrt-v4's conductor (RGB η, k, exact Fresnel; smooth, GGX α 0.2 and 0.5) against Mitsuba's
/// `conductor`/`roughconductor` with the same η, k (Mitsuba's Smith masking is uncorrelated, ours
/// height-correlated: a difference well inside the 2 % on the mean).
#[test]
fn conductors_match_mitsuba() {
    agrees_and_converges("conductors", 96, 64);
}

#[test]
fn glass_matches_mitsuba() {
    agrees_and_converges("glass", 96, 64);
}

#[test]
fn textured_plane_matches_mitsuba() {
    agrees_and_converges("textured", 64, 64);
}

#[test]
fn point_light_matches_mitsuba() {
    agrees_and_converges("point", 64, 64);
}

#[test]
fn hard_edged_spot_light_matches_mitsuba() {
    agrees_and_converges("spot", 64, 64);
}

#[test]
fn directional_light_and_emissive_sphere_match_mitsuba() {
    agrees_and_converges("directional", 64, 64);
}

#[test]
fn constant_environment_matches_mitsuba() {
    agrees_and_converges("constant_env", 64, 64);
}

#[test]
fn environment_map_matches_mitsuba() {
    agrees_and_converges("envmap", 64, 64);
}

/// Measured difference in the soft-edged spot (inner 10°, outer 30°): glTF's falloff, the square of
/// a linear ramp in cos θ, gives less light between the cones than Mitsuba's ramp linear in θ.
/// Trayecto / Mitsuba image means (4096 spp): R 0.804, G 0.821, B 0.850 (docs/src/correctness.md).
/// The test holds the difference at that size (±0.02), and checks that the rendering still
/// converges.
#[test]
fn soft_spot_light_differs_from_mitsuba_by_the_documented_falloff() {
    let (high, reference, e_low, e_high) = render_pair("spot_soft", 64, 64);
    let documented = [0.804f32, 0.821, 0.850];
    let (m, r) = (high.mean(), reference.mean());
    let ratio = [m.x / r.x, m.y / r.y, m.z / r.z];
    println!("spot_soft: Trayecto / Mitsuba means {ratio:?} (documented {documented:?})");
    for c in 0..3 {
        assert!(
            (ratio[c] - documented[c]).abs() < 0.02,
            "soft spot: channel {c} ratio {} vs documented {}",
            ratio[c],
            documented[c]
        );
    }
    // The falloffs differ only between the cones: the error still falls, but toward a floor.
    assert!(e_high < e_low, "rmse {e_low} at 4 spp, {e_high} at 64 spp");
}
