//! The Sobol and Poisson-disk sample streams (issue 4): uniform over many pixels (chi-square, so
//! estimators stay unbiased), well spread within a pixel, and deterministic whatever the threads.

use std::sync::atomic::AtomicBool;
use trayecto::integrator::{Aov, IntegratorKind, ShadingModel};
use trayecto::math::Vec2;
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::sampling::{SampleStream, SamplerKind, SamplerSetup};
use trayecto::scene::builtin;
use trayecto::world::{World, WorldOptions};

/// Stratified too: its 2D requests are multi-jittered (sub-strata by hashed permutations), so
/// its uniformity is checked like the others'.
const KINDS: [SamplerKind; 4] = [
    SamplerKind::Stratified,
    SamplerKind::Sobol,
    SamplerKind::PoissonDisk,
    SamplerKind::ZSobol,
];

/// Pearson's statistic of `counts` against a uniform expectation.
fn chi2(counts: &[u32]) -> f64 {
    let n: u32 = counts.iter().sum();
    let e = n as f64 / counts.len() as f64;
    counts.iter().map(|&c| (c as f64 - e).powi(2) / e).sum()
}

#[test]
fn streams_are_uniform_over_pixels() {
    // 64 × 64 pixels × 16 samples; 2D requests in an 8 × 8 histogram (63 degrees of freedom,
    // 0.1% critical value 103.4) and 1D requests in 32 bins (31 dof, critical value 61.1).
    for kind in KINDS {
        for spp in [16u32, 5] {
            let mut h2a = vec![0u32; 64];
            let mut h2b = vec![0u32; 64];
            let mut h1 = vec![0u32; 32];
            for y in 0..64 {
                for x in 0..64 {
                    for s in 0..spp {
                        let mut st = SampleStream::new(kind, 9, (x, y), s, spp);
                        let a = st.next_2d();
                        let u = st.next_1d();
                        let b = st.next_2d();
                        for (h, p) in [(&mut h2a, a), (&mut h2b, b)] {
                            assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                            h[(p.y * 8.0) as usize * 8 + (p.x * 8.0) as usize] += 1;
                        }
                        h1[(u * 32.0) as usize] += 1;
                    }
                }
            }
            for (name, h, crit) in [
                ("2D first", &h2a, 103.4),
                ("2D later", &h2b, 103.4),
                ("1D", &h1, 61.1),
            ] {
                let c = chi2(h);
                assert!(c < crit, "{kind:?} spp {spp} {name}: chi2 {c}");
            }
        }
    }
}

#[test]
fn sobol_pixel_samples_are_stratified() {
    // 16 Owen-scrambled Sobol points: one per 4×4 cell, one per 16×1 and 1×16 stratum.
    for (x, y) in [(0, 0), (5, 9), (100, 3)] {
        let pts: Vec<Vec2> = (0..16)
            .map(|s| SampleStream::new(SamplerKind::Sobol, 1, (x, y), s, 16).next_2d())
            .collect();
        for (nx, ny) in [(4usize, 4usize), (16, 1), (1, 16), (2, 8), (8, 2)] {
            let mut seen = vec![0; 16];
            for p in &pts {
                seen[(p.y * ny as f32) as usize * nx + (p.x * nx as f32) as usize] += 1;
            }
            assert!(seen.iter().all(|&c| c == 1), "{nx}x{ny}: {seen:?}");
        }
    }
}

/// ZSobol (Ahmed & Wonka 2020): one sequence over the image in Morton order. A pixel's
/// power-of-two samples are stratified like Sobol's, and — the point of the Morton order — the
/// samples of an aligned 2^k × 2^k block of pixels are together one (0, m, 2)-net: every
/// elementary interval of the unit square holds exactly one of them, so neighbouring pixels do
/// not repeat each other's sample positions. A broken Morton order or index scramble fails the
/// block check; per-pixel random scrambles (plain `sobol`) fail it too.
#[test]
fn zsobol_pixels_and_pixel_blocks_are_stratified() {
    let setup = |spp| SamplerSetup::new(SamplerKind::ZSobol, 4, spp).for_image(64, 48);
    // Every (0, m, 2)-net elementary interval shape for n = 2^m points.
    let is_net = |pts: &[Vec2]| {
        let n = pts.len();
        let m = n.trailing_zeros();
        (0..=m).all(|bx| {
            let (nx, ny) = (1usize << bx, 1usize << (m - bx));
            let mut seen = vec![false; n];
            pts.iter().all(|p| {
                let c = (p.y * ny as f32) as usize * nx + (p.x * nx as f32) as usize;
                !std::mem::replace(&mut seen[c], true)
            })
        })
    };
    let strata_1d = |us: &[f32]| {
        let mut seen = vec![false; us.len()];
        us.iter()
            .all(|&u| !std::mem::replace(&mut seen[(u * us.len() as f32) as usize], true))
    };
    // One pixel, 16 and 8 samples (even and odd log2 spp), in the first and a later dimension.
    for spp in [16u32, 8] {
        let st = setup(spp);
        for px in [(0u32, 0u32), (13, 7), (63, 47)] {
            let key = st.pixel_key(px);
            let draws: Vec<(Vec2, f32, Vec2)> = (0..spp)
                .map(|s| {
                    let mut z = st.stream(key, s);
                    (z.next_2d(), z.next_1d(), z.next_2d())
                })
                .collect();
            let a: Vec<Vec2> = draws.iter().map(|d| d.0).collect();
            let u: Vec<f32> = draws.iter().map(|d| d.1).collect();
            let b: Vec<Vec2> = draws.iter().map(|d| d.2).collect();
            assert!(is_net(&a) && is_net(&b), "spp {spp} pixel {px:?}");
            assert!(strata_1d(&u), "spp {spp} pixel {px:?} 1D");
        }
    }
    // Aligned pixel blocks: 4×4 pixels at 1 spp (16 points), 2×2 pixels at 4 spp (16 points),
    // 2×2 pixels at 2 spp (8 points, odd log2 spp).
    for (spp, side) in [(1u32, 4u32), (4, 2), (2, 2)] {
        let st = setup(spp);
        for (bx, by) in [(0u32, 0u32), (8, 4), (20, 12)] {
            let mut pts = Vec::new();
            let mut us = Vec::new();
            for y in by..by + side {
                for x in bx..bx + side {
                    let key = st.pixel_key((x, y));
                    for s in 0..spp {
                        let mut z = st.stream(key, s);
                        z.skip(3);
                        pts.push(z.next_2d());
                        us.push(z.next_1d());
                    }
                }
            }
            assert!(is_net(&pts), "spp {spp} block at ({bx}, {by})");
            assert!(strata_1d(&us), "spp {spp} block at ({bx}, {by}) 1D");
        }
    }
    // Plain per-pixel Sobol has no such joint structure: the same 4×4 block at 1 spp is not a
    // net (checked so the block test above means something).
    let sobol = SamplerSetup::new(SamplerKind::Sobol, 4, 1);
    let pts: Vec<Vec2> = (0..16)
        .map(|i| sobol.stream(sobol.pixel_key((i % 4, i / 4)), 0).next_2d())
        .collect();
    assert!(!is_net(&pts));
}

#[test]
fn poisson_pixel_samples_keep_their_distance() {
    // Minimum toroidal distance between a pixel's samples, against white noise.
    let min_dist = |kind: SamplerKind, spp: u32, px: (u32, u32)| {
        let pts: Vec<Vec2> = (0..spp)
            .map(|s| SampleStream::new(kind, 3, px, s, spp).next_2d())
            .collect();
        let mut m = f32::INFINITY;
        for i in 0..pts.len() {
            for j in 0..i {
                let mut d = (pts[i] - pts[j]).abs();
                d = d.min(Vec2::ONE - d);
                m = m.min(d.length());
            }
        }
        m
    };
    for spp in [8u32, 32] {
        let hex = (2.0 / (3f32.sqrt() * spp as f32)).sqrt();
        let (mut poisson, mut random) = (0.0, 0.0);
        for i in 0..50 {
            let p = min_dist(SamplerKind::PoissonDisk, spp, (i, 7));
            assert!(p > 0.5 * hex, "spp {spp} pixel {i}: {p} vs {hex}");
            poisson += p;
            random += min_dist(SamplerKind::Independent, spp, (i, 7));
        }
        assert!(poisson > 2.0 * random, "{poisson} vs {random}");
    }
}

#[test]
fn new_samplers_render_deterministically_for_any_thread_count() {
    let w = World::build(
        builtin::cornell(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    for kind in KINDS {
        for integrator in [
            IntegratorKind::Path,
            IntegratorKind::Raycast {
                aov: Aov::Shaded,
                shading: ShadingModel::Pbr,
            },
        ] {
            let img = |threads| {
                let s = RenderSettings {
                    width: 24,
                    height: 16,
                    spp: 6,
                    sampler: kind,
                    integrator,
                    threads: Some(threads),
                    ..Default::default()
                };
                render(&w, &s, &NoObserver, &AtomicBool::new(false))
                    .unwrap()
                    .image
                    .data
            };
            assert!(img(1) == img(2), "{kind:?} {integrator:?}");
        }
    }
}
