//! Next-event estimation with sample reuse (`World::sample_light_reuse`, the path tracer's NEE):
//! one 2D number both chooses the light (its x, by the light's share of [0, 1)) and places the
//! point on it (x remapped within that share, and y). Against the choice from a number of its
//! own (`World::sample_light`), the estimate keeps its mean (unbiased) and, with a pixel's
//! stratified or Sobol samples, its variance drops, because each light gets a stratified set of
//! points instead of a random subset of the pixel's 2D points.

mod common;
use trayecto::geometry::primitive::{NO_LIGHT, PrimRef, SurfaceHit};
use trayecto::light::{EnvPdf, LightSamplerKind};
use trayecto::material::Material;
use trayecto::math::{Mat4, Vec2, Vec3, Vec4};
use trayecto::sampling::rng::Pcg32;
use trayecto::sampling::{SamplerKind, SamplerSetup};
use trayecto::scene::{CameraDesc, Mesh, Scene, Shape};
use trayecto::world::{World, WorldOptions};

/// A floor under four emitters of different sizes and radiances: two quads, a sphere, and a
/// mesh of 40 small triangles (more than 16 bounded lights with `bvh`).
fn scene() -> Scene {
    let mut s = Scene::default();
    common::add_floor(&mut s, 10.0, 0.5);
    let emit = |s: &mut Scene, name: &str, l: Vec3| {
        let mut m = Material::diffuse(name, Vec3::ZERO);
        m.emissive = l;
        s.add_material(m)
    };
    let a = emit(&mut s, "a", Vec3::new(4.0, 3.0, 2.0));
    let b = emit(&mut s, "b", Vec3::splat(12.0));
    let c = emit(&mut s, "c", Vec3::new(1.0, 2.0, 6.0));
    // Quads facing down (e1 × e2 points to -y).
    s.add_object(
        "quad a",
        Shape::Quad {
            corner: Vec3::new(-2.0, 2.0, -1.0),
            e1: Vec3::new(1.5, 0.0, 0.0),
            e2: Vec3::new(0.0, 0.0, 1.0),
        },
        Mat4::IDENTITY,
        a,
    );
    s.add_object(
        "quad b",
        Shape::Quad {
            corner: Vec3::new(1.0, 1.5, 0.5),
            e1: Vec3::new(0.4, 0.0, 0.0),
            e2: Vec3::new(0.0, 0.0, 0.6),
        },
        Mat4::IDENTITY,
        b,
    );
    s.add_object(
        "sphere c",
        Shape::Sphere {
            center: Vec3::new(0.0, 1.2, 2.0),
            radius: 0.3,
        },
        Mat4::IDENTITY,
        c,
    );
    let mut rng = Pcg32::new(3, 9);
    let mut positions = vec![];
    for _ in 0..40 {
        let p = Vec3::new(
            rng.next_f32() * 6.0 - 3.0,
            1.0 + rng.next_f32(),
            rng.next_f32() * 6.0 - 3.0,
        );
        // Facing down: counter-clockwise seen from below.
        positions.push(p);
        positions.push(p + Vec3::new(0.0, 0.0, 0.2));
        positions.push(p + Vec3::new(0.2, 0.0, 0.0));
    }
    let mesh = s.add_mesh(Mesh {
        name: "triangles".into(),
        indices: (0..40u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
        positions,
        ..Default::default()
    });
    s.add_object("triangles", Shape::Mesh(mesh), Mat4::IDENTITY, a);
    s.cameras.push(CameraDesc::look_at(
        "cam",
        Vec3::new(0.0, 8.0, 8.0),
        Vec3::ZERO,
        Vec3::Y,
        60.0,
    ));
    s
}

fn build(light_sampler: LightSamplerKind) -> World {
    World::build(
        scene(),
        &WorldOptions {
            light_sampler,
            default_light: Some(trayecto::light::default_light::DefaultLight::Off),
            ..Default::default()
        },
    )
    .unwrap()
}

fn receiver(p: Vec3) -> SurfaceHit {
    SurfaceHit {
        t: 1.0,
        p,
        p_error: Vec3::splat(1e-6),
        ng: Vec3::Y,
        ns: Vec3::Y,
        tangent: Vec3::X,
        bitangent_sign: 1.0,
        uv: [Vec2::ZERO; 2],
        duv: [trayecto::math::Vec4::ZERO; 2],
        color: Vec4::ONE,
        material: 0,
        light: NO_LIGHT,
        prim: PrimRef(0),
        time: 0.0,
    }
}

/// One light sample's estimate of the irradiance's luminance (shadow-tested).
fn estimate(world: &World, ls: Option<trayecto::light::LightSample>) -> f64 {
    let Some(ls) = ls else { return 0.0 };
    let cos = ls.wi.dot(Vec3::Y);
    if cos <= 0.0 || world.occluded(&ls.shadow) {
        return 0.0;
    }
    (trayecto::math::luminance(ls.li) * cos / (ls.pmf * ls.pdf)) as f64
}

/// For receivers on the floor: many "pixels" of `spp` samples of a sampler, each drawing a 1D
/// number and then a 2D one as the path tracer's NEE does; the pixel's mean irradiance estimate
/// with the separate choice (1D chooses, 2D places) and with reuse (2D chooses and places, 1D
/// spare). Returns the summed relative variances of the pixel means and checks that the
/// means agree.
fn compare(world: &World, kind: SamplerKind, seed: u64, spp: u32) -> (f64, f64) {
    let setup = SamplerSetup::new(kind, seed, spp);
    let mut rng = Pcg32::new(21, 4);
    let (mut var_sep, mut var_reuse) = (0.0, 0.0);
    for r in 0..12 {
        let p = Vec3::new(rng.next_f32() * 6.0 - 3.0, 0.0, rng.next_f32() * 6.0 - 3.0);
        let hit = receiver(p);
        let pixels = 1500u32;
        let mut stats = [(0.0f64, 0.0f64); 2];
        for px in 0..pixels {
            let key = setup.pixel_key((px, r));
            let mut means = [0.0f64; 2];
            for s in 0..spp {
                let mut st = setup.stream(key, s);
                let u1 = st.next_1d();
                let u2 = st.next_2d();
                means[0] += estimate(
                    world,
                    world.sample_light(&hit, Vec3::Y, u1, u2, EnvPdf::Full),
                );
                means[1] += estimate(
                    world,
                    world.sample_light_reuse(&hit, Vec3::Y, u2, u1, EnvPdf::Full, Vec3::ZERO),
                );
            }
            for k in 0..2 {
                let m = means[k] / spp as f64;
                stats[k].0 += m;
                stats[k].1 += m * m;
            }
        }
        let n = pixels as f64;
        let [(m0, v0), (m1, v1)] = stats.map(|(s, s2)| {
            let m = s / n;
            (m, (s2 / n - m * m).max(0.0))
        });
        // The same irradiance within 5 standard errors of the difference (plus 0.5 % for
        // rounding): reuse is unbiased.
        let se = ((v0 + v1) / n).sqrt();
        assert!(
            (m0 - m1).abs() <= 5.0 * se + 0.005 * m0,
            "{kind:?} at {p}: separate {m0} vs reuse {m1} (standard error {se})"
        );
        var_sep += v0 / (m0 * m0).max(1e-12);
        var_reuse += v1 / (m0 * m0).max(1e-12);
    }
    (var_sep, var_reuse)
}

/// The sampler seeds the variance ratios are averaged over, fixed before the eight-way tree's
/// results with them were seen (BENCHMARKS.md, "Tried, did not pay"). One seed's ratio is
/// noisy: with ZSobol on this 43-light scene it moved between 0.49 and 0.86 over seeds 1, 2, 3
/// and 5; the mean of eight is the estimator's, not one seed's, so the 0.8 bound is
/// a stricter test than it was on one seed.
const SEEDS: [u64; 8] = [6, 7, 8, 9, 10, 11, 12, 13];

/// The mean over [`SEEDS`] of reuse's summed relative variance over the separate choice's.
fn mean_ratio(world: &World, kind: SamplerKind) -> f64 {
    let mut sum = 0.0;
    for seed in SEEDS {
        let (sep, reuse) = compare(world, kind, seed, 16);
        println!("  {kind:?} seed {seed}: separate {sep:.4}, reuse {reuse:.4}");
        sum += reuse / sep;
    }
    sum / SEEDS.len() as f64
}

#[test]
fn reuse_keeps_the_mean_and_lowers_the_variance() {
    for light_sampler in [
        LightSamplerKind::Power,
        LightSamplerKind::Bvh,
        LightSamplerKind::Bvh8,
    ] {
        let world = build(light_sampler);
        assert_eq!(world.lights.sampler_kind(), light_sampler);
        for kind in [
            SamplerKind::Stratified,
            SamplerKind::Sobol,
            SamplerKind::ZSobol,
        ] {
            let ratio = mean_ratio(&world, kind);
            println!("{light_sampler:?} {kind:?}: mean variance ratio reuse / separate {ratio:.3}");
            if std::env::var("NOASSERT").is_ok() {
                continue;
            }
            assert!(
                ratio < 0.8,
                "{light_sampler:?} {kind:?}: reuse's variance is {ratio:.3} x the separate choice's, not below 0.8"
            );
        }
        // Independent numbers: no stratification to keep, the same variance within noise.
        let ratio = mean_ratio(&world, SamplerKind::Independent);
        println!("{light_sampler:?} Independent: mean variance ratio {ratio:.3}");
        assert!(
            (ratio - 1.0).abs() < 0.15,
            "{light_sampler:?} independent: variance ratio {ratio}"
        );
    }
}

/// A sphere light seen from outside is sampled over the cone it subtends (pbrt-v4's
/// `Sphere::Sample(ctx, u)`): at points facing it, with the sphere wholly above their horizon,
/// the irradiance estimates average to the analytic π·L·(r/d)²·cos β and vary only through the
/// cosine (area sampling of the whole sphere wastes half its samples on the far side: relative
/// variance above 1); and the pdf MIS computes for a BSDF-sampled hit on the sphere
/// (`emitter_pdf`) is the pdf the sample was drawn with, from far and from close up (the
/// small-cone branch below sin² 1.5° and the general one).
#[test]
fn sphere_lights_are_sampled_over_their_cone() {
    for (radius, height) in [(0.5f32, 2.0f32), (0.01, 3.0), (0.9, 1.0)] {
        let mut s = Scene::default();
        common::add_floor(&mut s, 10.0, 0.5);
        let mut m = Material::diffuse("emitter", Vec3::ZERO);
        m.emissive = Vec3::splat(3.0);
        let e = s.add_material(m);
        let center = Vec3::new(0.3, height, -0.2);
        s.add_object(
            "sphere",
            Shape::Sphere { center, radius },
            Mat4::IDENTITY,
            e,
        );
        s.cameras.push(CameraDesc::look_at(
            "cam",
            Vec3::new(0.0, 5.0, 5.0),
            Vec3::ZERO,
            Vec3::Y,
            60.0,
        ));
        let world = World::build(
            s,
            &WorldOptions {
                default_light: Some(trayecto::light::default_light::DefaultLight::Off),
                ..Default::default()
            },
        )
        .unwrap();
        let mut rng = Pcg32::new(8, 1);
        for p in [Vec3::ZERO, Vec3::new(0.7, 0.0, 0.4)] {
            let hit = receiver(p);
            let to_c = center - p;
            let d = to_c.length();
            let want = (std::f64::consts::PI * 3.0 * (radius as f64 / d as f64).powi(2))
                * (to_c.y / d) as f64;
            let n = 20_000;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            let mut misses = 0;
            for _ in 0..n {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let ls = world
                    .sample_light(&hit, Vec3::Y, 0.5, u, EnvPdf::Full)
                    .unwrap();
                // The pdf MIS would use for a BSDF-sampled ray in the same direction.
                // (A direction at the cone's very edge may graze past in f32: counted.)
                let ray = trayecto::geometry::Ray::new(p, ls.wi);
                match world.intersect(&ray) {
                    Some(on) if on.light != NO_LIGHT => {
                        let mis = world.emitter_pdf(p, Vec3::Y, &on);
                        assert!(
                            (mis / (ls.pmf * ls.pdf) - 1.0).abs() < 1e-3,
                            "r {radius}: emitter_pdf {mis} vs sampled {}",
                            ls.pmf * ls.pdf
                        );
                    }
                    other => {
                        misses += 1;
                        if misses < 3 {
                            println!(
                                "r {radius} at {p}: u {u:?} wi {} hit {:?}",
                                ls.wi,
                                other.map(|h| h.p)
                            );
                        }
                    }
                }
                let est = estimate(&world, Some(ls));
                sum += est;
                sum2 += est * est;
            }
            assert!(
                misses <= n / 1000,
                "r {radius} at {p}: {misses} of {n} directions miss"
            );
            let mean = sum / n as f64;
            let rel_var = (sum2 / n as f64 - mean * mean) / (mean * mean);
            assert!(
                (mean / want - 1.0).abs() < 0.01,
                "r {radius} at {p}: irradiance {mean}, analytic {want}"
            );
            assert!(
                rel_var < 0.3,
                "r {radius} at {p}: relative variance {rel_var}"
            );
        }
    }
}
