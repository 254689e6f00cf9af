//! The Sobol and Poisson-disk sample streams (issue 4): uniform over many pixels (chi-square, so
//! estimators stay unbiased), well spread within a pixel, and deterministic whatever the threads.

use std::sync::atomic::AtomicBool;
use trayecto::integrator::{Aov, IntegratorKind, ShadingModel};
use trayecto::math::Vec2;
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::sampling::{SampleStream, SamplerKind};
use trayecto::scene::builtin;
use trayecto::world::{World, WorldOptions};

const KINDS: [SamplerKind; 2] = [SamplerKind::Sobol, SamplerKind::PoissonDisk];

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
    let w = World::build(builtin::cornell(), &WorldOptions::default()).unwrap();
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
