//! Emission sampling of every light type (pbrt-v4 `SampleLe` / `PDF_Le` / `Phi`): the origins and
//! directions `Light::sample_le` draws must follow the densities `Light::pdf_le` reports
//! (chi-square, as in tests/bsdf_chi2.rs: cells of equal measure, the density integrated over
//! each cell by a sub-grid quadrature, cells expecting under 5 samples pooled, p against 1 %
//! after a Šidák correction), and the power those rays carry on average,
//! E[Le · |cos θ| / (pdf_pos · pdf_dir)], must be each light's `Light::phi`, which is itself
//! checked against the closed forms (point 4πI; spot 2πI[(1 − cos θi) + (cos θi − cos θo)·k];
//! area π·A·L, twice for two sides; uniform 4π·πr²·L; directional πr²·E) and, for image
//! environments, against the texel table. Light samples toward a point (`sample_li`) must report
//! the pdf `pdf_li` / `le_pdf` gives the same point or direction.

mod common;

use std::sync::Arc;
use trayecto::geometry::Ray;
use trayecto::light::{
    DirectionalLight, EnvMap, EnvMapping, EnvPdf, EnvironmentLight, Light, LightScene, PointLight,
    SpotLight, UniformLight,
};
use trayecto::material::Material;
use trayecto::math::{Frame, Mat3, Mat4, PI, Vec2, Vec3};
use trayecto::sampling::rng::Pcg32;
use trayecto::scene::{Scene, Shape, SpotFalloff};
use trayecto::world::{World, WorldOptions};

/// Chi-square tests this file runs (Šidák correction); [`chi2_cells`] counts them.
const N_TESTS: usize = 17;
static RUNS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
const N_SAMPLES: usize = 200_000;

/// Pearson's test of `observed` counts against `expected` probabilities (per cell, summing to
/// at most 1; the rest is where the density is zero). Up to `stray` of the samples may land in
/// cells of zero expectation (a density with an edge inside a cell the quadrature missed).
fn chi2_cells(name: &str, observed: &[f64], expected: &[f64], stray: f64) {
    let run = RUNS.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1;
    assert!(run <= N_TESTS, "{name}: test {run} but N_TESTS = {N_TESTS}");
    let n: f64 = observed.iter().sum();
    assert!(n > 0.9 * N_SAMPLES as f64, "{name}: only {n} samples");
    let cells: Vec<(f64, f64)> = expected
        .iter()
        .map(|e| e * n)
        .zip(observed.iter().copied())
        .collect();
    let outside: f64 = cells.iter().filter(|c| c.0 == 0.0).map(|c| c.1).sum();
    assert!(
        outside <= stray * n,
        "{name}: {outside} samples where the density is zero"
    );
    let (stat, dof, p) = common::stats::pearson(&cells);
    let alpha = 1.0 - (1.0 - 0.01f64).powf(1.0 / N_TESTS as f64);
    assert!(
        p > alpha,
        "{name}: chi-square rejects the sampler (stat {stat:.1}, dof {dof}, p {p:.3e})"
    );
}

const N_COS: usize = 32;
const N_PHI: usize = 64;
const SUB: usize = 16;

/// Cell of a unit direction given in a local frame: (cos θ, φ) cells of equal solid angle.
fn sphere_cell(w: Vec3) -> usize {
    let c = ((w.z.clamp(-1.0, 1.0) + 1.0) * 0.5 * N_COS as f32) as usize;
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let p = (phi / (2.0 * PI) * N_PHI as f32) as usize;
    c.min(N_COS - 1) * N_PHI + p.min(N_PHI - 1)
}

/// Chi-square of directions (unit, world space) against the solid-angle density `pdf`, binned in
/// `frame` (whose z is the axis the density is symmetric about, so its edges fall on cells).
fn chi2_directions(
    name: &str,
    frame: Frame,
    mut sample: impl FnMut(&mut Pcg32) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f32,
) {
    let mut rng = Pcg32::new(0x1e, name.len() as u64 * 31 + 7);
    let mut observed = vec![0.0; N_COS * N_PHI];
    for _ in 0..N_SAMPLES {
        if let Some(w) = sample(&mut rng) {
            observed[sphere_cell(frame.to_local(w))] += 1.0;
        }
    }
    let (dc, dp) = (
        2.0 / N_COS as f64,
        2.0 * std::f64::consts::PI / N_PHI as f64,
    );
    let mut expected = vec![0.0; N_COS * N_PHI];
    for ci in 0..N_COS {
        for pi in 0..N_PHI {
            let mut s = 0.0;
            for a in 0..SUB {
                for b in 0..SUB {
                    let c = -1.0 + dc * (ci as f64 + (a as f64 + 0.5) / SUB as f64);
                    let p = dp * (pi as f64 + (b as f64 + 0.5) / SUB as f64);
                    let r = (1.0 - c * c).max(0.0).sqrt();
                    let local = Vec3::new((r * p.cos()) as f32, (r * p.sin()) as f32, c as f32);
                    s += pdf(frame.to_world(local)) as f64;
                }
            }
            expected[ci * N_PHI + pi] = s / (SUB * SUB) as f64 * dc * dp;
        }
    }
    chi2_cells(name, &observed, &expected, 1e-4);
}

/// Chi-square of points on a disk of radius `radius` about `center` in the plane of `frame`'s
/// x and y, against a constant area density `pdf_pos`: cells of equal area in (r², φ).
fn chi2_disk(
    name: &str,
    center: Vec3,
    radius: f32,
    frame: Frame,
    mut sample: impl FnMut(&mut Pcg32) -> Option<Vec3>,
    pdf_pos: f32,
) {
    const NR: usize = 16;
    const NP: usize = 32;
    let mut rng = Pcg32::new(0xd15c, name.len() as u64 * 17 + 3);
    let mut observed = vec![0.0; NR * NP];
    for _ in 0..N_SAMPLES {
        let Some(p) = sample(&mut rng) else { continue };
        let local = frame.to_local(p - center) / radius;
        assert!(
            local.z.abs() < 1e-3,
            "{name}: origin off the disk plane: {local}"
        );
        let r2 = local.x * local.x + local.y * local.y;
        let mut phi = local.y.atan2(local.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let i = ((r2 * NR as f32) as usize).min(NR - 1);
        let j = ((phi / (2.0 * PI) * NP as f32) as usize).min(NP - 1);
        observed[i * NP + j] += 1.0;
    }
    // Each cell has area πR² / (NR·NP).
    let cell = pdf_pos as f64 * std::f64::consts::PI * (radius as f64).powi(2) / (NR * NP) as f64;
    chi2_cells(name, &observed, &vec![cell; NR * NP], 0.0);
}

/// Emitted radiance of the emitters of [`emitter_world`], by material index, and their sides.
const EMITTERS: [(&str, [f32; 3], f32); 4] = [
    ("one-sided quad", [1.0, 2.0, 3.0], 1.0),
    ("two-sided quad", [0.5, 0.25, 4.0], 2.0),
    ("sphere", [3.0, 1.0, 0.5], 1.0),
    ("textured quad", [2.0, 2.0, 2.0], 1.0),
];

/// The textured quad's 2×2 texture (bilinear, repeating: its mean over the quad is the texels'
/// mean, 0.6 0.45 0.55).
const TEXELS: [[f32; 3]; 4] = [
    [1.0, 0.2, 0.5],
    [0.1, 0.9, 0.3],
    [0.5, 0.5, 0.9],
    [0.8, 0.2, 0.5],
];

/// Emitters for the area-light tests, lit by nothing else: a one-sided quad, a two-sided quad, a
/// sphere and a quad with an emissive texture (materials 0 to 3, as [`EMITTERS`]).
fn emitter_world() -> World {
    use trayecto::material::texture::{FilterMode, Texture, TextureRef, WrapMode};
    let mut scene = Scene {
        default_light: Some(trayecto::scene::DefaultLight::Off),
        ..Default::default()
    };
    scene.textures.push(Texture {
        name: "emission".into(),
        width: 2,
        height: 2,
        texels: TEXELS
            .map(|t| trayecto::math::Vec4::new(t[0], t[1], t[2], 1.0))
            .to_vec()
            .into(),
        wrap_s: WrapMode::Repeat,
        wrap_t: WrapMode::Repeat,
        filter: FilterMode::Bilinear,
        mipmap: false,
        mips: Vec::new(),
        procedural: None,
        layout: Default::default(),
    });
    let ids: Vec<usize> = EMITTERS
        .iter()
        .map(|&(name, l, sides)| {
            let mut m = Material::diffuse(name, Vec3::ZERO);
            m.emissive = Vec3::from_array(l);
            m.double_sided = sides == 2.0;
            if name == "textured quad" {
                m.emissive_texture = Some(TextureRef::new(0));
            }
            scene.add_material(m)
        })
        .collect();
    let quads = [
        (
            ids[0],
            Vec3::new(-1.0, 2.0, -0.5),
            Vec3::new(2.0, 0.3, 0.0),
            Vec3::new(0.0, 0.0, 1.5),
        ),
        (
            ids[1],
            Vec3::new(2.0, -1.0, -1.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.2, 0.0, 2.0),
        ),
        (
            ids[3],
            Vec3::new(-1.0, -2.0, 1.0),
            Vec3::new(1.5, 0.0, 0.0),
            Vec3::new(0.0, 0.2, -1.0),
        ),
    ];
    for (k, (m, corner, e1, e2)) in quads.into_iter().enumerate() {
        scene.add_object(
            &format!("quad {k}"),
            Shape::Quad { corner, e1, e2 },
            Mat4::IDENTITY,
            m,
        );
    }
    scene.add_object(
        "sphere",
        Shape::Sphere {
            center: Vec3::new(-2.0, 0.5, 1.0),
            radius: 0.7,
        },
        Mat4::IDENTITY,
        ids[2],
    );
    World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap()
}

/// Lights not made of geometry, each with its power in closed form given the scene's bounding
/// radius `r`.
fn analytic_lights(r: f32) -> Vec<(&'static str, Light, Vec3)> {
    let tau = 2.0 * PI;
    let i = Vec3::new(2.0, 1.0, 0.5);
    let spot = |falloff| SpotLight {
        position: Vec3::new(0.3, 1.0, -0.2),
        direction: Vec3::new(0.2, -1.0, 0.3).normalize(),
        intensity: i,
        cos_inner: 0.9,
        // On a cell edge of the direction histogram (cos θ = −1 + 28/16).
        cos_outer: 0.75,
        falloff,
    };
    let e = Vec3::new(1.5, 1.0, 0.25);
    let l = Vec3::new(0.2, 0.4, 0.6);
    vec![
        (
            "point",
            Light::Point(PointLight {
                position: Vec3::new(1.0, 2.0, 3.0),
                intensity: i,
            }),
            i * (2.0 * tau),
        ),
        (
            "spot (glTF ramp)",
            Light::Spot(spot(SpotFalloff::SquaredRamp)),
            i * (tau * ((1.0 - 0.9) + (0.9 - 0.75) / 3.0)),
        ),
        (
            "spot (pbrt smoothstep)",
            Light::Spot(spot(SpotFalloff::Smoothstep)),
            i * (tau * ((1.0 - 0.9) + (0.9 - 0.75) / 2.0)),
        ),
        (
            "directional",
            Light::Directional(DirectionalLight {
                direction: Vec3::new(-0.3, -1.0, 0.1).normalize(),
                irradiance: e,
            }),
            e * (PI * r * r),
        ),
        (
            "uniform",
            Light::Uniform(UniformLight { radiance: l }),
            l * (4.0 * PI * PI * r * r),
        ),
    ]
}

/// A small environment image with smooth and sharp features, and a rotation that is not the
/// identity.
fn environment(mapping: EnvMapping) -> EnvironmentLight {
    let (w, h) = (24u32, 16u32);
    let mut texels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let sun = if (5..7).contains(&x) && (3..5).contains(&y) {
                20.0
            } else {
                0.0
            };
            texels.push(Vec3::new(
                0.5 + 0.4 * (u * 2.0 * PI).sin() + sun,
                0.3 + 0.2 * v + sun,
                0.1 + 0.3 * (v * PI).cos().abs(),
            ));
        }
    }
    let rotation = Mat3::from_rotation_y(0.7) * Mat3::from_rotation_x(-0.3);
    EnvironmentLight {
        map: Arc::new(EnvMap::from_texels_mapped(
            w,
            h,
            texels,
            Vec3::new(1.0, 0.8, 1.2),
            rotation,
            mapping,
        )),
    }
}

/// The mean of Le · |cos| / (pdf_pos · pdf_dir) over `n` emitted rays, and its standard error.
fn estimated_power(light: &Light, scene: &LightScene, n: usize, seed: u64) -> (Vec3, Vec3) {
    let mut rng = Pcg32::new(seed, 11);
    let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
    for _ in 0..n {
        let u1 = Vec2::new(rng.next_f32(), rng.next_f32());
        let u2 = Vec2::new(rng.next_f32(), rng.next_f32());
        let Some(s) = light.sample_le(scene, u1, u2) else {
            continue;
        };
        let pdf = s.pdf_pos * s.pdf_dir;
        if pdf.is_nan() || pdf <= 0.0 {
            continue;
        }
        let v = s.le * (s.cos() / pdf);
        for (k, x) in v.to_array().into_iter().enumerate() {
            sum[k] += x as f64;
            sum2[k] += (x as f64) * (x as f64);
        }
    }
    let n = n as f64;
    let mean = sum.map(|s| s / n);
    let se: Vec<f64> = (0..3)
        .map(|k| ((sum2[k] / n - mean[k] * mean[k]).max(0.0) / n).sqrt())
        .collect();
    (
        Vec3::new(mean[0] as f32, mean[1] as f32, mean[2] as f32),
        Vec3::new(se[0] as f32, se[1] as f32, se[2] as f32),
    )
}

fn assert_power(name: &str, light: &Light, scene: &LightScene, rel_bias: f32) {
    let phi = light.phi(scene);
    let (est, se) = estimated_power(light, scene, 400_000, name.len() as u64);
    for k in 0..3 {
        let tol = 5.0 * se[k] + rel_bias * phi[k] + 1e-6;
        assert!(
            (est[k] - phi[k]).abs() <= tol,
            "{name}: sample_le estimates power {est} ± {se}, phi says {phi}"
        );
    }
}

fn assert_close(name: &str, got: Vec3, want: Vec3) {
    assert!(
        (got - want).abs().max_element() <= 1e-4 * want.abs().max_element(),
        "{name}: phi {got}, closed form {want}"
    );
}

/// The power sample_le carries is phi, and phi is the closed form, for point, spot (both ramps),
/// directional and uniform lights, and area lights (one- and two-sided quads, a sphere, a
/// textured quad).
#[test]
fn emitted_power_is_phi_for_analytic_and_area_lights() {
    let world = emitter_world();
    let scene = world.light_scene();
    for (name, light, want) in analytic_lights(scene.radius) {
        assert_close(name, light.phi(&scene), want);
        assert_power(name, &light, &scene, 1e-4);
    }
    assert_eq!(world.lights().len(), 4);
    for light in world.lights() {
        let area = light.as_area().unwrap();
        let (name, l, sides) = EMITTERS[area.material as usize];
        let mut l = Vec3::from_array(l);
        if name == "textured quad" {
            l *= TEXELS.iter().map(|t| Vec3::from_array(*t)).sum::<Vec3>() / 4.0;
        }
        let a = world.geometry.area(area.prim);
        assert_close(name, light.phi(&scene), l * (PI * sides * a));
        assert_power(name, light, &scene, 1e-4);
    }
}

/// Image environments: phi is π r² times the texel table's integral, and what sample_le
/// carries agrees (the equal-area map exactly, being piecewise constant; the equirectangular
/// map's bilinear filter moves the integral slightly).
#[test]
fn emitted_power_is_phi_for_image_environments() {
    let world = emitter_world();
    let scene = world.light_scene();
    for (name, mapping, bias) in [
        ("equal-area environment", EnvMapping::EqualArea, 1e-4),
        (
            "equirectangular environment",
            EnvMapping::Equirectangular,
            0.01,
        ),
    ] {
        let light = Light::Environment(environment(mapping));
        // The table by brute force: the mean radiance over many uniform directions.
        let mut rng = Pcg32::new(3, 5);
        let mut sum = Vec3::ZERO;
        let n = 400_000;
        for _ in 0..n {
            let d =
                trayecto::sampling::warp::uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            sum += light.le(d).unwrap();
        }
        let integral = sum / n as f32 * (4.0 * PI);
        let phi = light.phi(&scene);
        let want = integral * (PI * scene.radius * scene.radius);
        assert!(
            (phi - want).abs().max_element() <= 0.03 * want.max_element(),
            "{name}: phi {phi}, uniform estimate {want}"
        );
        assert_power(name, &light, &scene, bias);
    }
}

/// Directions of sample_le follow pdf_le's direction density: points and spots about their
/// position, area lights about their normal (in the local frame of each sampled point, since
/// pdf_le's direction density depends only on the normal), lights at infinity over the sphere.
#[test]
fn emitted_directions_follow_pdf_le() {
    let world = emitter_world();
    let scene = world.light_scene();
    let u4 = |r: &mut Pcg32| {
        (
            Vec2::new(r.next_f32(), r.next_f32()),
            Vec2::new(r.next_f32(), r.next_f32()),
        )
    };
    for (name, light, _) in analytic_lights(scene.radius) {
        if matches!(light, Light::Directional(_)) {
            continue; // a delta in direction
        }
        let axis = match &light {
            Light::Spot(s) => s.direction,
            _ => Vec3::Z,
        };
        chi2_directions(
            &format!("{name} directions"),
            Frame::from_normal(axis),
            |r| {
                let (u1, u2) = u4(r);
                light.sample_le(&scene, u1, u2).map(|s| s.ray.d)
            },
            |w| light.pdf_le(&scene, Vec3::ZERO, w).1,
        );
    }
    for mapping in [EnvMapping::EqualArea, EnvMapping::Equirectangular] {
        let light = Light::Environment(environment(mapping));
        chi2_directions(
            &format!("{mapping:?} environment directions"),
            Frame::from_normal(Vec3::Y),
            |r| {
                let (u1, u2) = u4(r);
                light.sample_le(&scene, u1, u2).map(|s| s.ray.d)
            },
            |w| light.pdf_le(&scene, Vec3::ZERO, w).1,
        );
    }
    for (k, light) in world.lights().iter().enumerate() {
        // In the frame of the sampled point's normal: its direction density is a function of
        // the local direction alone.
        chi2_directions(
            &format!("area light {k} directions"),
            Frame::from_normal(Vec3::Z),
            |r| {
                let (u1, u2) = u4(r);
                let s = light.sample_le(&scene, u1, u2)?;
                assert!(s.le.max_element() > 0.0, "area light {k}: no radiance");
                Some(Frame::from_normal(s.n).to_local(s.ray.d))
            },
            |w| light.pdf_le(&scene, Vec3::Z, w).1,
        );
    }
}

/// Origins of sample_le follow pdf_le's position density: uniform by area on area lights (a
/// quad's parameter square, a sphere's equal-area cells) and on the scene's bounding disk for
/// lights at infinity.
#[test]
fn emitted_origins_follow_pdf_le() {
    let world = emitter_world();
    let scene = world.light_scene();
    let u4 = |r: &mut Pcg32| {
        (
            Vec2::new(r.next_f32(), r.next_f32()),
            Vec2::new(r.next_f32(), r.next_f32()),
        )
    };
    let mut infinite: Vec<(String, Light)> = analytic_lights(scene.radius)
        .into_iter()
        .filter(|(_, l, _)| l.is_infinite())
        .map(|(n, l, _)| (n.to_string(), l))
        .collect();
    infinite.push((
        "equal-area environment".into(),
        Light::Environment(environment(EnvMapping::EqualArea)),
    ));
    for (name, light) in &infinite {
        // Origins are on the disk through the centre perpendicular to the ray, moved back by
        // the radius: bring them back along the ray and bin them in the disk of that direction.
        // One direction for the test (the disk turns with it): condition on u1.
        let u1 = Vec2::new(0.3, 0.6);
        let d = light.sample_le(&scene, u1, Vec2::splat(0.5)).unwrap().ray.d;
        chi2_disk(
            &format!("{name} origins"),
            scene.center,
            scene.radius,
            Frame::from_normal(d),
            |r| {
                let u2 = Vec2::new(r.next_f32(), r.next_f32());
                let s = light.sample_le(&scene, u1, u2)?;
                Some(s.ray.o + s.ray.d * scene.radius)
            },
            light.pdf_le(&scene, Vec3::ZERO, d).0,
        );
    }
    // Quads: the parameter square of each, cells of equal area.
    for (k, light) in world.lights().iter().enumerate() {
        let prim = light.as_area().unwrap().prim;
        if prim.kind() != trayecto::geometry::PrimitiveKind::Quad {
            continue;
        }
        let q = &world.geometry.quads[prim.index()].shape;
        let (corner, e1, e2) = (
            q.point(0.0, 0.0).0,
            q.point(1.0, 0.0).0,
            q.point(0.0, 1.0).0,
        );
        let (e1, e2) = (e1 - corner, e2 - corner);
        let n = e1.cross(e2);
        const N: usize = 24;
        let mut rng = Pcg32::new(9, k as u64);
        let mut observed = vec![0.0; N * N];
        let mut pdf_pos = 0.0;
        for _ in 0..N_SAMPLES {
            let (u1, u2) = u4(&mut rng);
            let Some(s) = light.sample_le(&scene, u1, u2) else {
                continue;
            };
            pdf_pos = light.pdf_le(&scene, s.n, s.ray.d).0;
            // Solve o = corner + a e1 + b e2 (the origin is offset off the surface by a
            // rounding-size amount along the normal).
            let rel = s.ray.o - corner;
            let a = rel.cross(e2).dot(n) / n.length_squared();
            let b = e1.cross(rel).dot(n) / n.length_squared();
            let i = ((a.clamp(0.0, 1.0) * N as f32) as usize).min(N - 1);
            let j = ((b.clamp(0.0, 1.0) * N as f32) as usize).min(N - 1);
            observed[i * N + j] += 1.0;
        }
        let cell = pdf_pos as f64 * n.length() as f64 / (N * N) as f64;
        chi2_cells(
            &format!("quad light {k} origins"),
            &observed,
            &vec![cell; N * N],
            0.0,
        );
    }
    // The sphere: cells of equal solid angle about its centre are cells of equal area.
    let sphere = world
        .lights()
        .iter()
        .find(|l| l.as_area().unwrap().prim.kind() == trayecto::geometry::PrimitiveKind::Sphere)
        .unwrap();
    let s = &world.geometry.spheres[sphere.as_area().unwrap().prim.index()].shape;
    let (center, radius) = (s.center, s.radius);
    let mut rng = Pcg32::new(21, 2);
    let mut observed = vec![0.0; N_COS * N_PHI];
    let mut pdf_pos = 0.0;
    for _ in 0..N_SAMPLES {
        let (u1, u2) = u4(&mut rng);
        let Some(s) = sphere.sample_le(&scene, u1, u2) else {
            continue;
        };
        pdf_pos = sphere.pdf_le(&scene, s.n, s.ray.d).0;
        observed[sphere_cell((s.ray.o - center).normalize())] += 1.0;
    }
    let cell = pdf_pos as f64 * 4.0 * std::f64::consts::PI * (radius as f64).powi(2)
        / (N_COS * N_PHI) as f64;
    chi2_cells(
        "sphere light origins",
        &observed,
        &vec![cell; N_COS * N_PHI],
        0.0,
    );
}

/// A light sample toward a point reports the pdf that pdf_li (area lights, with the point found
/// by tracing the sample's direction) and le_pdf (environments) give the same point or
/// direction.
#[test]
fn sample_li_pdf_is_pdf_li() {
    let world = emitter_world();
    let scene = world.light_scene();
    let mut hit = trayecto::geometry::SurfaceHit {
        t: 1.0,
        ..trayecto::geometry::SurfaceHit::EMPTY
    };
    let mut rng = Pcg32::new(4, 4);
    let mut checked = 0;
    for p in [Vec3::new(0.2, 0.1, 0.3), Vec3::new(-0.5, -1.0, 2.0)] {
        hit.p = p;
        for light in world.lights() {
            for _ in 0..2000 {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let Some(ls) =
                    light.sample_li(&scene, &hit, Vec3::ZERO, u, EnvPdf::Full, Vec3::ZERO)
                else {
                    continue;
                };
                // The first surface along the sample's direction, if it is this light's.
                let Some(found) = world.intersect(&Ray::new(p, ls.wi)) else {
                    continue;
                };
                if found.prim != light.as_area().unwrap().prim {
                    continue;
                }
                let pdf = light.pdf_li(&world.geometry, p, &found, || 1.0);
                assert!(
                    (pdf - ls.pdf).abs() <= 2e-3 * ls.pdf,
                    "pdf_li {pdf}, sample_li {} from {p}",
                    ls.pdf
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 5000, "{checked}");
    // The equal-area map's pdf is a texel's constant; the equirectangular one's has sin θ of the
    // sampled map coordinates, which the round trip through the direction rounds (most near
    // the poles).
    for (mapping, tol) in [
        (EnvMapping::EqualArea, 1e-4),
        (EnvMapping::Equirectangular, 2e-2),
    ] {
        let light = Light::Environment(environment(mapping));
        for env in [EnvPdf::Full, EnvPdf::Compensated] {
            for _ in 0..2000 {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let Some(ls) = light.sample_li(&scene, &hit, Vec3::ZERO, u, env, Vec3::ZERO) else {
                    continue;
                };
                let (_, pdf) = light.le_pdf(ls.wi, env, Vec3::ZERO).unwrap();
                assert!(
                    (pdf - ls.pdf).abs() <= tol * ls.pdf,
                    "{mapping:?} {env:?}: le_pdf {pdf}, sample_li {}",
                    ls.pdf
                );
            }
        }
    }
}

/// An emissive texture in spectral mode is an illuminant spectrum per texel (pbrt-v4
/// `DiffuseAreaLight::L` with an image: the texel RGB at the hit becomes an
/// `RGBIlluminantSpectrum`): a quad of the 2 × 2 [`TEXELS`] (nearest filtering) filling the
/// frame, seen head-on and lit by nothing else, renders spectrally as its RGB render does, per
/// quadrant (the central 2 × 2 pixels of each, away from the texel edges), within the
/// upsampling table's round trip (RGB → spectrum × D65 → RGB: 1.2 % of the largest channel,
/// docs/DESIGN.md) plus 4 standard errors of the colour noise; measured at most 0.0027 off.
/// Each quadrant shows its own texel (the texture is not replaced by a constant).
#[test]
fn emissive_textures_are_illuminant_spectra_per_texel_in_spectral_mode() {
    use trayecto::material::texture::{FilterMode, Texture, TextureRef, WrapMode};
    use trayecto::render::RenderSettings;
    use trayecto::scene::CameraDesc;
    let mut scene = Scene {
        default_light: Some(trayecto::scene::DefaultLight::Off),
        ..Default::default()
    };
    scene.textures.clear();
    scene.textures.push(Texture {
        name: "emission".into(),
        width: 2,
        height: 2,
        texels: TEXELS
            .map(|t| trayecto::math::Vec4::new(t[0], t[1], t[2], 1.0))
            .to_vec()
            .into(),
        wrap_s: WrapMode::Repeat,
        wrap_t: WrapMode::Repeat,
        filter: FilterMode::Nearest,
        mipmap: false,
        mips: Vec::new(),
        procedural: None,
        layout: Default::default(),
    });
    let mut m = Material::diffuse("textured emitter", Vec3::ZERO);
    m.emissive = Vec3::ONE;
    m.emissive_texture = Some(TextureRef::new(0));
    let id = scene.add_material(m);
    scene.add_object(
        "quad",
        Shape::Quad {
            corner: Vec3::new(-1.0, -1.0, 0.0),
            e1: Vec3::new(2.0, 0.0, 0.0),
            e2: Vec3::new(0.0, 2.0, 0.0),
        },
        Mat4::IDENTITY,
        id,
    );
    scene.cameras.push(CameraDesc::look_at(
        "c",
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::ZERO,
        Vec3::Y,
        30.0,
    ));
    let world = World::build(scene, &WorldOptions::default()).unwrap();
    let render = |spectral: bool, spp: u32| {
        let mut s = RenderSettings {
            width: 8,
            height: 8,
            spp,
            ..Default::default()
        };
        s.path.spectral = spectral;
        common::render_world(&world, &s).data
    };
    // Mean and standard error of the central 2 × 2 pixels of each 4 × 4 quadrant.
    let quadrants = |px: &[Vec3]| -> Vec<(Vec3, Vec3)> {
        [(0, 0), (4, 0), (0, 4), (4, 4)]
            .iter()
            .map(|&(x0, y0)| {
                let v: Vec<Vec3> = (1..3)
                    .flat_map(|y| (1..3).map(move |x| px[(y0 + y) * 8 + x0 + x]))
                    .collect();
                let m = v.iter().copied().sum::<Vec3>() / 4.0;
                let var = v.iter().map(|p| (*p - m) * (*p - m)).sum::<Vec3>() / 3.0;
                (m, (var / 4.0).powf(0.5))
            })
            .collect()
    };
    let rgb = quadrants(&render(false, 4));
    let spectral = quadrants(&render(true, 256));
    let mut seen = Vec::new();
    for (k, ((r, _), (s, se))) in rgb.iter().zip(&spectral).enumerate() {
        let texel = TEXELS
            .iter()
            .map(|t| Vec3::from_array(*t))
            .min_by(|a, b| (*a - *r).length().total_cmp(&(*b - *r).length()))
            .unwrap();
        assert!(
            (texel - *r).abs().max_element() < 1e-4,
            "quadrant {k}: RGB {r:?} is not a texel"
        );
        seen.push(texel.to_array());
        let tol = *se * 4.0 + Vec3::splat(0.012 * r.max_element());
        eprintln!("quadrant {k}: RGB {r:?}, spectral {s:?} (tolerance {tol:?})");
        assert!(
            (*s - *r).abs().cmple(tol).all(),
            "quadrant {k}: spectral {s:?} vs RGB {r:?} (tolerance {tol:?})"
        );
    }
    seen.sort_by(|a, b| a.partial_cmp(b).unwrap());
    seen.dedup();
    assert_eq!(seen.len(), 4, "{seen:?}");
}

/// Emitters on moving primitives (`common::cornell_with_moving_emitters`: a quad, a mesh and a
/// sphere, keyed in the one world) are sampled where they are at the receiver's time: a light sample's direction, traced
/// at that time, meets the light, and the density pdf_li gives that hit (at the hit's time)
/// is the sample's. A light path starts on the sphere where it is at its time: its origin on the
/// sphere of that time's centre and radius, its position density one over that sphere's area.
#[test]
fn moving_emitters_are_sampled_at_the_time() {
    use trayecto::world::motion::TimeOptions;
    let world = World::build_posed(
        common::cornell_with_moving_emitters(),
        &WorldOptions {
            time: TimeOptions {
                shutter: Some([0.0, 1.0]),
                steps: 4,
                ..Default::default()
            },
            ..Default::default()
        },
    )
    .unwrap();
    let scene = world.light_scene();
    let mut rng = Pcg32::new(9, 2);
    let mut hit = trayecto::geometry::SurfaceHit {
        t: 1.0,
        ..trayecto::geometry::SurfaceHit::EMPTY
    };
    let moving: Vec<usize> = (0..world.lights().len())
        .filter(|&i| world.lights()[i].as_area().is_some_and(|a| a.moves()))
        .collect();
    assert_eq!(
        moving.len(),
        4,
        "the panel's two triangles, the ball and the ceiling light"
    );
    for t in [0.05f32, 0.37, 0.5, 0.93] {
        hit.time = t;
        let (mut sampled, mut met, mut checked) = (0, 0, 0);
        // Points in the open, clear of the boxes.
        for p in [Vec3::new(0.0, -0.2, 0.5), Vec3::new(0.6, 0.2, -0.5)] {
            hit.p = p;
            for &i in &moving {
                let light = &world.lights()[i];
                for _ in 0..500 {
                    let u = Vec2::new(rng.next_f32(), rng.next_f32());
                    let Some(ls) =
                        light.sample_li(&scene, &hit, Vec3::ZERO, u, EnvPdf::Full, Vec3::ZERO)
                    else {
                        continue;
                    };
                    // The first surface along the sample's direction at time t: an emitter
                    // (this light, or another in front of it); sampled where it is not at t,
                    // the light would be missed most of the time, for the walls.
                    let Some(found) = world.intersect(&Ray::new(p, ls.wi).with_time(t)) else {
                        continue;
                    };
                    sampled += 1;
                    if found.light == trayecto::geometry::primitive::NO_LIGHT {
                        continue;
                    }
                    met += 1;
                    if found.prim != light.as_area().unwrap().prim {
                        // Another emitter in front of the sampled point, not the sampled point
                        // on another surface.
                        let dist = (ls.shadow.o + ls.shadow.d - p).length();
                        assert!(
                            found.t < 0.99 * dist,
                            "time {t}: the sample toward light {i} lies on another emitter"
                        );
                        continue;
                    }
                    let pdf = light.pdf_li(&world.geometry, p, &found, || 1.0);
                    assert!(
                        (pdf - ls.pdf).abs() <= 2e-3 * ls.pdf,
                        "time {t}: pdf_li {pdf}, sample_li {}",
                        ls.pdf
                    );
                    checked += 1;
                }
            }
        }
        assert!(
            sampled > 3900 && met as f64 >= 0.99 * sampled as f64 && checked > 2000,
            "time {t}: of {sampled} samples toward the lights {met} met an emitter, {checked} \
             their own"
        );
        // The ball: centre (0.25, 0.35, −0.3 + 0.6 t), radius 0.06 (1 + t/2); linear in t, so
        // its keys' interpolation is exact.
        let ball = *moving
            .iter()
            .find(|&&i| {
                world.lights()[i].as_area().unwrap().prim.kind()
                    == trayecto::geometry::PrimitiveKind::Sphere
            })
            .unwrap();
        let (c, r) = (
            Vec3::new(0.25, 0.35, -0.3 + 0.6 * t),
            0.06 * (1.0 + 0.5 * t),
        );
        let posed = world.lights.posed(ball, t);
        for _ in 0..200 {
            let u1 = Vec2::new(rng.next_f32(), rng.next_f32());
            let u2 = Vec2::new(rng.next_f32(), rng.next_f32());
            let le = posed.sample_le(&scene, u1, u2).unwrap();
            assert!(((le.ray.o - c).length() - r).abs() < 1e-4, "time {t}");
            assert_eq!(le.ray.time, t);
            let area = 4.0 * PI * r * r;
            assert!((le.pdf_pos * area - 1.0).abs() < 1e-3, "time {t}");
            let (pos, _) = posed.pdf_le(&scene, le.n, le.ray.d);
            assert_eq!(pos, le.pdf_pos);
        }
    }
}
