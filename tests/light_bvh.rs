//! The light BVH (`--light-sampler bvh`, `light::bvh`): the probability MIS uses for a light
//! (`emitter_pdf`, `LightSet::pmf`) is exactly the probability with which it is chosen, the
//! choices follow those probabilities (chi-square), images agree with the power sampler's
//! (both unbiased) with less noise on a many-light scene, and they do not depend on the thread
//! count.

mod common;
use common::*;
use trayecto::geometry::Ray;
use trayecto::geometry::primitive::{NO_LIGHT, PrimRef, PrimitiveKind, SurfaceHit};
use trayecto::light::{EnvPdf, Light, LightSamplerKind};
use trayecto::material::Material;
use trayecto::math::{Mat4, Vec2, Vec3, Vec4};
use trayecto::render::RenderSettings;
use trayecto::sampling::rng::Pcg32;
use trayecto::scene::{CameraDesc, LightDesc, Mesh, Scene, Shape, SpotFalloff};
use trayecto::world::{World, WorldOptions};

/// A floor and many small emitters of every kind: 240 triangles scattered and tilted above the
/// floor (one- and two-sided, of different radiances), quads, a sphere, a box, point and spot
/// lights, and an ambient light at infinity.
fn many_lights(ambient: bool) -> Scene {
    let mut s = Scene::default();
    add_floor(&mut s, 20.0, 0.6);
    let mut rng = Pcg32::new(11, 5);
    let mut mats = vec![];
    for (k, double_sided) in [(0, false), (1, true), (2, false)] {
        let mut m = Material::diffuse(&format!("emitter {k}"), Vec3::splat(0.3));
        m.emissive = [
            Vec3::new(6.0, 4.0, 2.0),
            Vec3::new(1.0, 2.0, 5.0),
            Vec3::splat(20.0),
        ][k];
        m.double_sided = double_sided;
        mats.push(s.add_material(m));
    }
    for (k, &m) in mats.iter().enumerate() {
        let mut positions = vec![];
        for _ in 0..80 {
            let c = Vec3::new(
                rng.next_f32() * 36.0 - 18.0,
                0.3 + rng.next_f32() * 1.5,
                rng.next_f32() * 36.0 - 18.0,
            );
            // Smaller for the brightest material, so the powers differ by orders of magnitude.
            let size = if k == 2 { 0.1 } else { 0.4 };
            for _ in 0..3 {
                positions.push(
                    c + Vec3::new(
                        rng.next_f32() - 0.5,
                        rng.next_f32() - 0.5,
                        rng.next_f32() - 0.5,
                    ) * size,
                );
            }
        }
        let mesh = s.add_mesh(Mesh {
            name: format!("triangles {k}"),
            indices: (0..80u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
            positions,
            ..Default::default()
        });
        s.add_object(
            &format!("triangles {k}"),
            Shape::Mesh(mesh),
            Mat4::IDENTITY,
            m,
        );
    }
    s.add_object(
        "quad light",
        Shape::Quad {
            corner: Vec3::new(-1.0, 3.0, -1.0),
            e1: Vec3::new(0.0, 0.0, 0.5),
            e2: Vec3::new(0.5, 0.0, 0.0),
        },
        Mat4::IDENTITY,
        mats[0],
    );
    s.add_object(
        "sphere light",
        Shape::Sphere {
            center: Vec3::new(2.0, 1.0, -2.0),
            radius: 0.2,
        },
        Mat4::IDENTITY,
        mats[1],
    );
    s.add_object(
        "box light",
        Shape::Cuboid {
            min: Vec3::new(-2.5, 0.5, 2.0),
            max: Vec3::new(-2.2, 0.7, 2.4),
        },
        Mat4::IDENTITY,
        mats[0],
    );
    s.lights.push(LightDesc::Point {
        name: "point".into(),
        position: Vec3::new(1.0, 2.0, 1.0),
        intensity: Vec3::splat(3.0),
    });
    s.lights.push(LightDesc::Spot {
        name: "spot".into(),
        position: Vec3::new(-1.0, 2.5, 1.5),
        direction: Vec3::new(0.2, -1.0, 0.1),
        intensity: Vec3::splat(8.0),
        inner_angle: 0.3,
        outer_angle: 0.6,
        falloff: SpotFalloff::SquaredRamp,
    });
    if ambient {
        s.lights.push(LightDesc::Ambient {
            name: "sky".into(),
            radiance: Vec3::splat(0.05),
        });
    }
    s.cameras.push(CameraDesc::look_at(
        "cam",
        Vec3::new(0.0, 14.0, 16.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::Y,
        60.0,
    ));
    s
}

fn build(scene: &Scene, sampler: LightSamplerKind) -> World {
    World::build(
        scene.clone(),
        &WorldOptions {
            light_sampler: sampler,
            default_light: Some(trayecto::light::default_light::DefaultLight::Off),
            ..Default::default()
        },
    )
    .unwrap()
}

fn receiver(p: Vec3, n: Vec3) -> SurfaceHit {
    SurfaceHit {
        t: 1.0,
        p,
        p_error: Vec3::splat(1e-6),
        ng: if n == Vec3::ZERO { Vec3::Y } else { n },
        ns: if n == Vec3::ZERO { Vec3::Y } else { n },
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

/// Receivers on the floor, in the air among the emitters (with a normal, and without one as in
/// a medium), and far away.
fn receivers(rng: &mut Pcg32) -> Vec<(Vec3, Vec3)> {
    let mut v = vec![];
    for k in 0..60 {
        let p = Vec3::new(
            rng.next_f32() * 40.0 - 20.0,
            if k % 3 == 0 {
                1e-3
            } else {
                rng.next_f32() * 3.0
            },
            rng.next_f32() * 40.0 - 20.0,
        );
        let n = match k % 3 {
            0 => Vec3::Y,
            1 => Vec3::new(
                rng.next_f32() - 0.5,
                rng.next_f32() - 0.5,
                rng.next_f32() - 0.5,
            )
            .normalize(),
            _ => Vec3::ZERO,
        };
        v.push((p, n));
    }
    v.push((Vec3::new(40.0, 30.0, -50.0), Vec3::X));
    v
}

#[test]
fn auto_uses_the_bvh_for_many_lights_and_power_for_few() {
    let scene = many_lights(true);
    // `auto`'s tree is the eight-way one (BENCHMARKS.md, "Tried, did not pay"); `bvh` is
    // still the four-way tree.
    assert_eq!(
        build(&scene, LightSamplerKind::Auto).lights.sampler_kind(),
        LightSamplerKind::Bvh8
    );
    assert_eq!(
        build(&scene, LightSamplerKind::Bvh).lights.sampler_kind(),
        LightSamplerKind::Bvh
    );
    let cornell = trayecto::scene::builtin::cornell();
    let w = World::build(
        cornell,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    assert_eq!(w.lights.sampler_kind(), LightSamplerKind::Power);
}

/// The probability a light is chosen with equals, bit for bit, the one `LightSet::pmf` gives for
/// it; for area lights `emitter_pdf` at the point the shadow ray reaches is the sample's pmf × pdf
/// (the pdf recomputed from the hit, so to rounding); lights are never chosen where their pmf is 0.
#[test]
fn sampled_pmf_equals_emitter_pdf() {
    for kind in [LightSamplerKind::Bvh, LightSamplerKind::Bvh8] {
        sampled_pmf_equals_emitter_pdf_with(kind);
    }
}

fn sampled_pmf_equals_emitter_pdf_with(kind: LightSamplerKind) {
    let world = build(&many_lights(true), kind);
    assert_eq!(world.lights.sampler_kind(), kind);
    let lights = &world.lights;
    assert!(lights.lights.len() > 240);
    let mut rng = Pcg32::new(3, 9);
    let (mut area_checked, mut chosen) = (0, 0);
    for (p, n) in receivers(&mut rng) {
        for _ in 0..300 {
            let u = rng.next_f32();
            let u2 = Vec2::new(rng.next_f32(), rng.next_f32());
            let Some((index, pmf)) = lights.choose(p, n, u) else {
                continue;
            };
            chosen += 1;
            assert!(pmf > 0.0);
            let again = lights.pmf(index as u32, p, n);
            assert_eq!(
                pmf.to_bits(),
                again.to_bits(),
                "light {index} at {p} {n}: sampled pmf {pmf}, pmf() {again}"
            );
            // The same choice through the world query, then the hit its shadow ray reaches.
            let hit = receiver(p, n);
            let Some(ls) = world.sample_light(&hit, n, u, u2, EnvPdf::Full) else {
                continue;
            };
            assert_eq!(ls.pmf.to_bits(), pmf.to_bits());
            // Flat emitters: the first surface along the sample's direction is the sampled
            // point (on a sphere or box it may be a nearer face of the same emitter).
            let flat = matches!(
                lights.lights[index],
                Light::Area(a) if matches!(a.prim.kind(), PrimitiveKind::Triangle | PrimitiveKind::Quad)
            );
            if !flat {
                continue;
            }
            let mut ray = Ray::new(ls.shadow.o, ls.wi);
            ray.t_max = f32::INFINITY;
            let Some(h) = world.intersect(&ray) else {
                continue;
            };
            if h.light != index as u32 {
                continue; // another emitter or the floor is in the way
            }
            let pdf = world.emitter_pdf(p, n, &h);
            let want = ls.pmf * ls.pdf;
            assert!(
                (pdf - want).abs() <= 2e-3 * want,
                "light {index}: emitter_pdf {pdf}, sample pmf·pdf {want}"
            );
            area_checked += 1;
        }
    }
    assert!(
        chosen > 15_000 && area_checked > 500,
        "{chosen} {area_checked}"
    );
}

/// Upper tail of the chi-square distribution with `k` degrees of freedom at 10⁻⁵ significance
/// (Wilson–Hilferty approximation, z = 4.265).
fn chi2_critical(k: f64) -> f64 {
    let z = 4.265;
    k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

/// The choices follow the pmf: per receiver, 200 000 choices counted per light against
/// N · pmf (cells with fewer than 5 expected pooled), and the pmfs sum to 1; for the four- and
/// the eight-way tree.
#[test]
fn chi_square_over_emitter_choice() {
    for kind in [LightSamplerKind::Bvh, LightSamplerKind::Bvh8] {
        chi_square_over_emitter_choice_with(kind);
    }
}

fn chi_square_over_emitter_choice_with(kind: LightSamplerKind) {
    let world = build(&many_lights(true), kind);
    let lights = &world.lights;
    let n_lights = lights.lights.len();
    let mut rng = Pcg32::new(5, 1);
    let spots = [
        (Vec3::new(0.3, 1e-3, 0.2), Vec3::Y),
        (Vec3::new(-10.0, 1.5, 5.0), Vec3::ZERO),
        (
            Vec3::new(12.0, 1.0, -9.0),
            Vec3::new(1.0, -1.0, 0.0).normalize(),
        ),
    ];
    for (p, n) in spots {
        let pmf: Vec<f64> = (0..n_lights)
            .map(|i| lights.pmf(i as u32, p, n) as f64)
            .collect();
        // Below 1 where the walk can reach a node none of whose children can light p: it then
        // chooses nothing (`None`), which is counted as a cell of its own.
        let total: f64 = pmf.iter().sum();
        assert!(
            total <= 1.0 + 1e-5 && total > 0.5,
            "pmfs sum to {total} at {p}"
        );
        let zero = pmf.iter().filter(|&&q| q == 0.0).count();
        let samples = 200_000usize;
        let mut counts = vec![0u64; n_lights];
        let mut none = 0u64;
        for _ in 0..samples {
            match lights.choose(p, n, rng.next_f32()) {
                Some((i, _)) => counts[i] += 1,
                None => none += 1,
            }
        }
        let mut stat = 0.0;
        let mut cells = 0usize;
        let (mut pooled_obs, mut pooled_exp) = (0.0, 0.0);
        for i in 0..n_lights {
            let expected = pmf[i] * samples as f64;
            if expected == 0.0 {
                assert_eq!(counts[i], 0, "light {i} chosen with pmf 0");
                continue;
            }
            if expected < 5.0 {
                pooled_obs += counts[i] as f64;
                pooled_exp += expected;
                continue;
            }
            stat += (counts[i] as f64 - expected).powi(2) / expected;
            cells += 1;
        }
        let none_exp = (1.0 - total).max(0.0) * samples as f64;
        if none_exp >= 5.0 {
            stat += (none as f64 - none_exp).powi(2) / none_exp;
            cells += 1;
        } else {
            pooled_obs += none as f64;
            pooled_exp += none_exp;
        }
        if pooled_exp > 0.0 {
            stat += (pooled_obs - pooled_exp).powi(2) / pooled_exp;
            cells += 1;
        }
        let crit = chi2_critical((cells - 1) as f64);
        assert!(
            stat < crit,
            "{kind:?} at {p}: chi² {stat:.1} over {cells} cells, critical {crit:.1}"
        );
        // The importance is not uniform: the tree concentrates on some lights (and the floor
        // point sees one-sided emitters from behind, which get 0).
        let max = pmf.iter().cloned().fold(0.0, f64::max);
        assert!(max > 20.0 / n_lights as f64, "max pmf {max}");
        if n == Vec3::Y {
            assert!(zero > 0);
        }
    }
}

fn settings(spp: u32) -> RenderSettings {
    RenderSettings {
        width: 32,
        height: 24,
        spp,
        seed: 1,
        threads: Some(2),
        ..Default::default()
    }
}

/// Both samplers are unbiased, so their converged images agree (channel means within 2 % at
/// 2048 spp: over four seeds each sampler's means spread by 0.3–1.1 %, the small bright emitters'
/// fireflies; at 256 spp they move the means by up to 6 %), and the light BVH's image is the
/// same with one thread and with two.
#[test]
fn bvh_images_agree_with_power_and_do_not_depend_on_threads() {
    let scene = many_lights(false);
    let power = build(&scene, LightSamplerKind::Power);
    let bvh = build(&scene, LightSamplerKind::Bvh);
    let bvh8 = build(&scene, LightSamplerKind::Bvh8);
    let mut s = settings(256);
    s.path.max_depth = 2;
    let converged = |w: &World, seed: u64| {
        let mut r = s.clone();
        r.spp = 2048;
        r.seed = seed;
        render_world(w, &r)
    };
    let reference = converged(&power, 99);
    assert_means_close(
        &converged(&bvh, 5),
        &reference,
        0.02,
        "bvh vs power at 2048 spp",
    );
    assert_means_close(
        &converged(&bvh8, 5),
        &reference,
        0.02,
        "bvh8 vs power at 2048 spp",
    );
    let mut one = s.clone();
    one.threads = Some(1);
    one.spp = 16;
    let mut two = one.clone();
    two.threads = Some(2);
    for world in [&bvh, &bvh8] {
        let (a, b) = (render_world(world, &one), render_world(world, &two));
        assert!(
            a.data
                .iter()
                .zip(&b.data)
                .all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits)),
            "the light BVH's image depends on the thread count ({:?})",
            world.lights.sampler_kind()
        );
    }
}

/// The purpose of the tree: next-event estimates of the direct irradiance at points on the
/// floor (one light sample each, shadow-tested, L·cos/(pmf·pdf)) have the same mean with both
/// samplers (unbiased) and a much smaller variance with the light BVH, which favours the nearby
/// emitters the power sampler picks as rarely as the far ones. (The images' RMSE hardly shows
/// it: there, pixels straddling the emitters the camera sees dominate.)
#[test]
fn bvh_next_event_estimates_have_lower_variance() {
    let scene = many_lights(false);
    let power = build(&scene, LightSamplerKind::Power);
    let bvh = build(&scene, LightSamplerKind::Bvh);
    let mut rng = Pcg32::new(17, 2);
    let (mut var_power, mut var_bvh) = (0.0f64, 0.0f64);
    for _ in 0..40 {
        let p = Vec3::new(
            rng.next_f32() * 30.0 - 15.0,
            1e-3,
            rng.next_f32() * 30.0 - 15.0,
        );
        let hit = receiver(p, Vec3::Y);
        let mut stats = vec![];
        for world in [&power, &bvh] {
            let n = 20_000;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let u = rng.next_f32();
                let u2 = Vec2::new(rng.next_f32(), rng.next_f32());
                let Some(ls) = world.sample_light(&hit, Vec3::Y, u, u2, EnvPdf::Full) else {
                    continue;
                };
                let cos = ls.wi.dot(Vec3::Y);
                if cos <= 0.0 || world.occluded(&ls.shadow) {
                    continue;
                }
                let pdf = if ls.delta { ls.pmf } else { ls.pmf * ls.pdf };
                let e = (trayecto::math::luminance(ls.li) * cos / pdf) as f64;
                sum += e;
                sum2 += e * e;
            }
            let mean = sum / n as f64;
            let var = (sum2 / n as f64 - mean * mean).max(0.0);
            stats.push((mean, var, (var / n as f64).sqrt()));
        }
        let ((m_p, v_p, se_p), (m_b, v_b, se_b)) = (stats[0], stats[1]);
        // Same irradiance within 5 standard errors (plus a relative 1 % for rounding).
        assert!(
            (m_p - m_b).abs() <= 5.0 * (se_p * se_p + se_b * se_b).sqrt() + 0.01 * m_p,
            "irradiance at {p}: power {m_p} ± {se_p}, bvh {m_b} ± {se_b}"
        );
        var_power += v_p / (m_p * m_p).max(1e-12);
        var_bvh += v_b / (m_p * m_p).max(1e-12);
    }
    assert!(
        var_bvh < 0.5 * var_power,
        "mean relative variance of one light sample: bvh {var_bvh:.3}, power {var_power:.3}"
    );
    println!(
        "relative variance per light sample, summed over 40 points: bvh {var_bvh:.3}, power {var_power:.3}"
    );
}
