//! Statistical tests of the path tracer's estimator: closed-form furnaces, agreement of every
//! NEE/MIS/RR/sampler/secondary configuration (they change noise, never the expectation),
//! determinism across thread counts and independence from the scene's scale.

mod common;
use common::*;
use trayecto::film::Image;
use trayecto::integrator::PathSettings;
use trayecto::material::Material;
use trayecto::math::{Mat4, Vec3};
use trayecto::render::RenderSettings;
use trayecto::sampling::SamplerKind;
use trayecto::scene::{CameraDesc, Scene, Shape, builtin};

fn base(w: u32, spp: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: w,
        spp,
        seed: 3,
        ..Default::default()
    }
}

fn with_path(mut s: RenderSettings, f: impl FnOnce(&mut PathSettings)) -> RenderSettings {
    f(&mut s.path);
    s
}

/// A closed sphere seen from inside, every point emitting `le` (both sides) and reflecting with
/// `albedo`: the radiance everywhere is le / (1 − albedo) (the geometric series of bounces).
fn emissive_sphere_furnace(albedo: f32, le: f32) -> Scene {
    let mut s = Scene::default();
    let mut m = Material::diffuse("furnace", Vec3::splat(albedo));
    m.emissive = Vec3::splat(le);
    m.double_sided = true;
    let id = s.add_material(m);
    s.add_object(
        "sphere",
        Shape::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        },
        Mat4::IDENTITY,
        id,
    );
    s.cameras.push(CameraDesc::look_at(
        "in",
        Vec3::new(0.1, 0.2, 0.3),
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::Y,
        60.0,
    ));
    s
}

/// A closed box of six inward-facing quads, for the same closed-form check on flat emitters.
fn emissive_box_furnace(albedo: f32, le: f32, double_sided: bool, inward: bool) -> Scene {
    let mut s = Scene::default();
    let mut m = Material::diffuse("furnace", Vec3::splat(albedo));
    m.emissive = Vec3::splat(le);
    m.double_sided = double_sided;
    let id = s.add_material(m);
    let faces = [
        ([-1.0, -1.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0]),
        ([-1.0, 1.0, -1.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]),
        ([-1.0, -1.0, -1.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]),
        ([-1.0, -1.0, 1.0], [0.0, 2.0, 0.0], [2.0, 0.0, 0.0]),
        ([-1.0, -1.0, -1.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]),
        ([1.0, -1.0, -1.0], [0.0, 0.0, 2.0], [0.0, 2.0, 0.0]),
    ];
    for (i, (c, a, b)) in faces.into_iter().enumerate() {
        let (a, b) = if inward { (a, b) } else { (b, a) };
        s.add_object(
            &format!("face{i}"),
            Shape::Quad {
                corner: Vec3::from(c),
                e1: Vec3::from(a),
                e2: Vec3::from(b),
            },
            Mat4::IDENTITY,
            id,
        );
    }
    s.cameras.push(CameraDesc::look_at(
        "in",
        Vec3::new(0.2, -0.1, 0.5),
        Vec3::new(0.3, 0.1, -1.0),
        Vec3::Y,
        70.0,
    ));
    s
}

fn configs() -> Vec<(&'static str, PathSettings)> {
    let d = PathSettings::default();
    vec![
        ("nee+mis", d),
        ("nee, no mis", PathSettings { mis: false, ..d }),
        ("no nee", PathSettings { nee: false, ..d }),
        ("rr from bounce 0", PathSettings { rr_depth: 0, ..d }),
        (
            "rr from bounce 0, PBRT's q = max throughput",
            PathSettings {
                rr_depth: 0,
                rr_scale: 1.0,
                ..d
            },
        ),
        (
            "no rr",
            PathSettings {
                rr_depth: 1000,
                max_depth: 200,
                ..d
            },
        ),
        ("secondary 3", PathSettings { secondary: 3, ..d }),
    ]
}

/// The image mean equals the closed form to within four standard errors, the standard error being
/// estimated from the pixels (each pixel is an independent estimate); and the render must be
/// precise enough for that to mean something: four standard errors at most `tol` of the value.
fn assert_uniform(img: &Image, expected: f32, tol: f32, what: &str) {
    let n = img.data.len() as f64;
    for c in 0..3 {
        let mean = img.data.iter().map(|p| p[c] as f64).sum::<f64>() / n;
        let var = img
            .data
            .iter()
            .map(|p| (p[c] as f64 - mean).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        let bound = 4.0 * (var / n).sqrt();
        println!(
            "{what}: channel {c} mean {mean:.4}, 4 standard errors {bound:.4} ({:.2} % of {expected})",
            100.0 * bound / expected as f64
        );
        assert!(
            bound <= (tol * expected) as f64,
            "{what}: too noisy to test (4 standard errors = {bound:.4}, allowed {})",
            tol * expected
        );
        assert!(
            (mean - expected as f64).abs() <= bound.max(1e-5 * expected as f64),
            "{what}: mean {mean:.4} vs closed form {expected} (4 standard errors = {bound:.4})"
        );
    }
}

#[test]
fn furnace_sphere_returns_le_over_one_minus_albedo() {
    let scene = emissive_sphere_furnace(0.5, 1.0);
    for (name, p) in configs() {
        let img = render_scene(&scene, &with_path(base(24, 32), |s| *s = p));
        assert_uniform(&img, 2.0, 0.01, name);
    }
}

#[test]
fn furnace_box_returns_le_over_one_minus_albedo() {
    let scene = emissive_box_furnace(0.8, 0.5, false, true);
    // NEE without MIS is left out here (the sphere furnace above covers it): near the box's edges
    // a light sample on the adjacent face has a geometry term cos·cos/d² that grows without bound,
    // so that estimator's variance is infinite and its mean over a finite image swings by ±5 %
    // from seed to seed (measured 2.45–2.55 for seeds 3–6). In the sphere the geometry term between
    // two points of the sphere is the constant 1/(4R²), so there it is tested tightly.
    // 96 spp (was 48): with roulette from bounce 0 at albedo 0.8 deep bounces carry the image,
    // and at 48 spp the precision guard (4 standard errors ≤ 1.5 %) read 1.22 % with the
    // stratified sampler and 1.56 % with the padded one, 0.82 % and 1.09 % at 96 spp
    // (BENCHMARKS.md, "Tried, did not pay"): the mean is now checked to within ±0.8–1.1 %.
    for (name, p) in configs().into_iter().filter(|(n, _)| *n != "nee, no mis") {
        let img = render_scene(&scene, &with_path(base(24, 96), |s| *s = p));
        assert_uniform(&img, 2.5, 0.015, name);
    }
}

#[test]
fn emission_is_one_sided_unless_double_sided() {
    // Faces pointing outwards: the camera inside sees only their back sides, which do not emit.
    let dark = render_scene(&emissive_box_furnace(0.8, 0.5, false, false), &base(16, 4));
    assert_eq!(dark.mean(), Vec3::ZERO);
    let lit = render_scene(&emissive_box_furnace(0.8, 0.5, true, false), &base(24, 32));
    assert_uniform(&lit, 2.5, 0.015, "double-sided outward faces");
}

/// Spectral mode (docs/DESIGN.md "Spectral rendering") changes how colour is carried, not the
/// expectation of a grey scene: a grey albedo is the constant spectrum, an RGB-white emitter is
/// D65, and the film's CIE projection of D65 is white, so the furnace still reads le / (1 − a)
/// in every channel (within the D65 → sRGB white's 0.2 %). The integrators without a spectral
/// path (VCM here) refuse it by name.
#[test]
fn spectral_furnace_renders_the_rgb_closed_form() {
    let scene = emissive_sphere_furnace(0.5, 1.0);
    let spectral = |s: RenderSettings| with_path(s, |p| p.spectral = true);
    let img = render_scene(&scene, &spectral(base(24, 32)));
    assert_uniform(&img, 2.0, 0.02, "spectral");
    // SPPM: one set of wavelengths per iteration, shared by its visible points and photons
    // (the photons carry half the radiance here: with their emission left RGB they would read
    // an equal-energy white, 20 % off in red). Every pixel of an iteration shares its
    // wavelengths, so the colour noise is the image mean's, not the pixels' spread: the bound is
    // on the channel means directly, against RGB SPPM's own (1.971 in every channel here, 1.5 %
    // under the closed form after 64 iterations of a consistent estimator; spectral
    // 1.959–1.974).
    let rgb_sppm = RenderSettings {
        integrator: trayecto::integrator::IntegratorKind::Sppm,
        ..base(16, 64)
    };
    let sppm = with_path(rgb_sppm.clone(), |p| p.spectral = true);
    let (rgb, mean) = (
        render_scene(&scene, &rgb_sppm).mean(),
        render_scene(&scene, &sppm).mean(),
    );
    println!("SPPM furnace: channel means RGB {rgb:?}, spectral {mean:?} (closed form 2)");
    assert!(
        (rgb - trayecto::math::Vec3::splat(2.0)).abs().max_element() < 0.06,
        "{rgb:?}"
    );
    assert!(
        (mean - rgb).abs().max_element() < 0.03,
        "spectral SPPM furnace: channel means {mean:?}, RGB SPPM's {rgb:?}"
    );
    let world = trayecto::world::World::build(scene, &Default::default()).unwrap();
    // An integrator without a spectral path (the thesis's Whitted: its local shading models are
    // RGB) is refused by name rather than rendered in RGB.
    let whitted = RenderSettings {
        integrator: trayecto::integrator::IntegratorKind::Whitted {
            shading: Default::default(),
        },
        ..spectral(base(8, 1))
    };
    let e = trayecto::render::check_media_settings(&world, &whitted).unwrap_err();
    assert!(e.to_string().contains("spectral"), "{e}");
}

#[test]
fn max_depth_truncates_the_series_exactly() {
    // With N bounces the furnace sums le · (1 + a + … + a^N).
    let scene = emissive_sphere_furnace(0.5, 1.0);
    for n in [0u32, 1, 2, 5] {
        let img = render_scene(
            &scene,
            &with_path(base(16, 32), |s| {
                s.max_depth = n;
                s.rr_depth = 1000;
            }),
        );
        let expected: f32 = (0..=n).map(|k| 0.5f32.powi(k as i32)).sum();
        assert_uniform(&img, expected, 0.01, &format!("max depth {n}"));
    }
}

#[test]
fn nee_mis_and_sampler_settings_agree_on_the_cornell_box() {
    let scene = builtin::cornell();
    let reference = render_scene(&scene, &base(64, 256));
    let variants = [
        ("no mis", with_path(base(64, 256), |s| s.mis = false)),
        ("no nee", with_path(base(64, 512), |s| s.nee = false)),
        (
            "independent",
            RenderSettings {
                sampler: SamplerKind::Independent,
                ..base(64, 256)
            },
        ),
        (
            "rr from bounce 1",
            with_path(base(64, 256), |s| s.rr_depth = 1),
        ),
    ];
    for (name, settings) in variants {
        let img = render_scene(&scene, &settings);
        assert_means_close(&img, &reference, 0.015, name);
    }
}

#[test]
fn image_is_identical_for_any_thread_count() {
    let scene = builtin::cornell();
    let one = render_scene(
        &scene,
        &RenderSettings {
            threads: Some(1),
            ..base(40, 8)
        },
    );
    let two = render_scene(
        &scene,
        &RenderSettings {
            threads: Some(2),
            ..base(40, 8)
        },
    );
    let three = render_scene(
        &scene,
        &RenderSettings {
            threads: Some(3),
            ..base(40, 8)
        },
    );
    assert!(
        one == two && two == three,
        "images differ between thread counts"
    );
    let other_seed = render_scene(
        &scene,
        &RenderSettings {
            seed: 4,
            threads: Some(2),
            ..base(40, 8)
        },
    );
    assert!(one != other_seed, "the seed must change the noise");
}

#[test]
fn results_do_not_depend_on_scene_scale() {
    let reference = render_scene(&builtin::cornell(), &base(48, 64));
    for scale in [1e-3f32, 1e4] {
        let mut scene = builtin::cornell();
        let m = Mat4::from_scale(Vec3::splat(scale));
        for o in &mut scene.objects {
            o.transform = m * o.transform;
        }
        for c in &mut scene.cameras {
            c.camera_to_world = m * c.camera_to_world * Mat4::from_scale(Vec3::splat(1.0 / scale));
            c.focus_distance *= scale;
        }
        let img = render_scene(&scene, &base(48, 64));
        assert_means_close(&img, &reference, 0.01, &format!("scale {scale}"));
        // No self-intersection acne: no pixel darker than half of the unscaled one on the walls.
        let (p, q) = (img.get(24, 30), reference.get(24, 30));
        assert!(p.x > 0.5 * q.x, "scale {scale}: {p} vs {q}");
    }
}

/// The Cornell box with its light quad replaced by an equivalent emitter of another kind.
fn cornell_with_light(shape: impl Fn(&mut Scene) -> Shape) -> Scene {
    let mut scene = builtin::cornell();
    let i = scene
        .objects
        .iter()
        .position(|o| o.name == "light")
        .unwrap();
    scene.objects[i].shape = shape(&mut scene);
    scene
}

#[test]
fn triangle_mesh_and_quad_emitters_agree() {
    // Two triangles covering the same rectangle as the light quad: NEE samples emissive
    // triangles by area, the quad as one parallelogram; the expected images are the same.
    let quad = render_scene(&builtin::cornell(), &base(48, 128));
    let tris = cornell_with_light(|s| {
        let (c, e1, e2) = (
            Vec3::new(-0.23, 0.99, -0.18),
            Vec3::new(0.46, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.38),
        );
        let mesh = trayecto::scene::Mesh {
            name: "light-mesh".into(),
            positions: vec![c, c + e1, c + e1 + e2, c + e2],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        };
        Shape::Mesh(s.add_mesh(mesh))
    });
    let world = trayecto::world::World::build(
        tris.clone(),
        &trayecto::world::WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(world.emissive_triangle_count(), 2);
    let img = render_world(&world, &base(48, 128));
    assert_means_close(&img, &quad, 0.015, "triangle light vs quad light");
}
