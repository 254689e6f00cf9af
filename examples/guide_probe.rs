//! How well can a path-guiding SD-tree leaf sample one point's incident radiance, given records
//! from around it? A diagnostic for `--guiding` (docs/DESIGN.md "Path guiding";
//! BENCHMARKS.md "Path guiding"):
//!
//! ```sh
//! cargo run --release --example guide_probe -- SCENE X,Y,Z NX,NY,NZ [HALF] [RECORDS] [DEPTH]
//! ```
//!
//! At the surface point X,Y,Z with normal N (a diffuse surface is assumed: the BSDF is the cosine),
//! records are made at points drawn uniformly in the square of half-side HALF (metres, 0.05 by
//! default) about it: a direction from the cosine (first iteration) or from the one-sample
//! mixture of the cosine (α = 0.3) and the guide learned so far, and the radiance arriving
//! along it, estimated by the path tracer from the next surface on and without that surface's
//! own emission (next-event estimation samples emitters; the guide learns indirect light, as
//! the renderer's records do; DEPTH bounces from that surface on, the scene's default when not
//! given: 1 keeps the light that surface reflects once). Five doubling iterations of RECORDS·2ᵏ records (20 000 by default)
//! train a `Learner` exactly as a guided render does. Then the one-bounce estimator of
//! ∫ Lᵢ cos/π dω at the point is run 40 000 times with cosine sampling and with the mixtures
//! α = 0.5 and 0.3, and its relative variance printed: what the guide buys per sample when its
//! records are dense around the point.
use std::error::Error;

use trayecto::geometry::Ray;
use trayecto::geometry::primitive::NO_LIGHT;
use trayecto::integrator::RayStats;
use trayecto::integrator::guiding::{Learner, Record, normal_bin};
use trayecto::integrator::path::{PathSettings, radiance};
use trayecto::math::{Frame, Vec2, Vec3, luminance};
use trayecto::sampling::rng::Pcg32;
use trayecto::sampling::warp::{cosine_hemisphere, cosine_hemisphere_pdf};
use trayecto::sampling::{SampleStream, SamplerKind};
use trayecto::world::{World, WorldOptions};

fn vec3(s: &str) -> Result<Vec3, Box<dyn Error>> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("{s}: expected x,y,z").into()),
    }
}

const ALPHA: f32 = 0.3;

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: guide_probe SCENE X,Y,Z NX,NY,NZ [HALF] [RECORDS] [DEPTH]".into());
    }
    let world = World::build(trayecto::scene::load(&args[0])?, &WorldOptions::default())?;
    let p0 = vec3(&args[1])?;
    let n = vec3(&args[2])?.normalize();
    let half: f32 = args.get(3).map_or(Ok(0.05), |s| s.parse())?;
    let per_iteration: usize = args.get(4).map_or(Ok(20_000), |s| s.parse())?;
    let frame = Frame::from_normal(n);
    let bin = normal_bin(n, n);
    let mut set = PathSettings::default();
    if let Some(d) = args.get(5) {
        set.max_depth = d.parse()?;
    }
    let mut stats = RayStats::default();
    let mut rng = Pcg32::new(7, 11);
    let mut stream_index = 0u32;
    // Radiance arriving at `p` from direction `d`, without the emission of the surface it meets.
    let mut incident = |p: Vec3, d: Vec3| -> f32 {
        stream_index += 1;
        let mut s = SampleStream::new(SamplerKind::Independent, 5, (stream_index, 0), 0, 1);
        let ray = Ray::new(p + n * 1e-3, d);
        let mut l = radiance(&world, &ray, &mut s, &set, &mut stats);
        if let Some(hit) = world.intersect(&ray)
            && hit.light != NO_LIGHT
        {
            l -= world.emitted(&hit, -d);
        }
        luminance(l).max(0.0)
    };
    let (t1, t2) = (frame.to_world(Vec3::X), frame.to_world(Vec3::Y));
    let b = world.bounds;
    let mut learner = Learner::new(b.min, b.max);
    for k in 0..5u32 {
        let guide = learner.guide();
        let mut records = Vec::new();
        for _ in 0..per_iteration << k {
            let (a, c) = (rng.next_f32() - 0.5, rng.next_f32() - 0.5);
            let p = p0 + (t1 * a + t2 * c) * (2.0 * half);
            let mix = guide.as_ref().and_then(|g| g.mix_in(p, bin));
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let d = match &mix {
                Some(m) if rng.next_f32() >= ALPHA => m.guide.sample(m.leaf, u),
                _ => frame.to_world(cosine_hemisphere(u)),
            };
            let cos = d.dot(n);
            if cos <= 0.0 {
                continue;
            }
            let pdf_bsdf = cosine_hemisphere_pdf(cos);
            let (pdf_guide, alpha) = match &mix {
                Some(m) => (m.guide.pdf(m.leaf, d), ALPHA),
                None => (0.0, 1.0),
            };
            records.push(Record {
                p,
                bin,
                wi: d,
                radiance: incident(p, d),
                // A white Lambertian surface: f·cos = cos/π, the cosine density.
                f_cos: pdf_bsdf,
                pdf_bsdf,
                pdf_guide,
                pdf: alpha * pdf_bsdf + (1.0 - alpha) * pdf_guide,
                alpha,
            });
        }
        learner.learn(&records, 1 << k);
        let g = learner.guide().ok_or("no guide after an iteration")?;
        println!(
            "iteration {k}: {} records, {} leaves, {} quadtree nodes",
            records.len(),
            g.leaf_count(),
            g.quad_node_count()
        );
    }
    let g = learner.guide().ok_or("no guide")?;
    let m = g
        .mix_in(p0, bin)
        .ok_or("the point's leaf learned no radiance")?;
    let samples = 40_000;
    for alpha in [1.0f32, 0.5, ALPHA] {
        let (mut s1, mut s2, mut lit) = (0f64, 0f64, 0u32);
        for _ in 0..samples {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let d = if rng.next_f32() < alpha {
                frame.to_world(cosine_hemisphere(u))
            } else {
                g.sample(m.leaf, u)
            };
            let cos = d.dot(n);
            let v = if cos > 0.0 {
                // f·cos of a white Lambertian surface, which is the cosine density.
                let f_cos = cosine_hemisphere_pdf(cos);
                let q = alpha * f_cos + (1.0 - alpha) * g.pdf(m.leaf, d);
                let l = incident(p0, d);
                lit += (l > 0.0) as u32;
                (l * f_cos / q) as f64
            } else {
                0.0
            };
            s1 += v;
            s2 += v * v;
        }
        let mean = s1 / samples as f64;
        let var = s2 / samples as f64 - mean * mean;
        let what = if alpha == 1.0 {
            "cosine".to_string()
        } else {
            format!("mixture, α = {alpha}")
        };
        println!(
            "{what}: mean {mean:.5}, relative variance {:.3}, samples meeting light {:.3}",
            var / (mean * mean),
            lit as f64 / samples as f64
        );
    }
    Ok(())
}
