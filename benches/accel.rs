//! The thesis's acceleration comparison (§5.3.6, Fig. 5.44–5.46): the same textured multi-mesh scene
//! rendered with no acceleration structure (every ray tests every primitive), the uniform grid and
//! the BVH, at a fixed resolution and sample count, printing build and render times and the
//! speed-up ratios.
//!
//! `cargo bench --bench accel` runs the full comparison (about half a minute on two cores);
//! `cargo bench --bench accel -- --quick` a smaller one. Under `cargo test` (no `--bench`
//! argument) it only renders a tiny version to check that it runs.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};
use trayecto::accel::AccelKind;
use trayecto::integrator::{IntegratorKind, ShadingModel};
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene::testscenes;
use trayecto::world::{World, WorldOptions};

struct Run {
    build: Duration,
    render: Duration,
    rays: u64,
    image: Vec<trayecto::math::Vec3>,
}

fn run(scene: &trayecto::scene::Scene, accel: AccelKind, s: &RenderSettings, reps: u32) -> Run {
    let mut best: Option<Run> = None;
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        let world = World::build(
            scene.clone(),
            &WorldOptions {
                accel,
                ..Default::default()
            },
        )
        .expect("scene builds");
        let build = t.elapsed();
        let out = render(&world, s, &NoObserver, &AtomicBool::new(false)).expect("render");
        let r = Run {
            build,
            render: out.render_time,
            rays: out.stats.rays + out.stats.shadow_rays,
            image: out.image.data,
        };
        if best.as_ref().is_none_or(|b| r.render < b.render) {
            best = Some(r);
        }
    }
    best.expect("at least one run")
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let bench = args.iter().any(|a| a == "--bench");
    let quick = args.iter().any(|a| a == "--quick");
    // (spheres per side, rings per sphere, width, height, spp, repetitions)
    let (k, detail, w, h, spp, reps) = if !bench {
        (2, 6, 16, 12, 1, 1)
    } else if quick {
        (3, 16, 64, 48, 1, 1)
    } else {
        (4, 16, 96, 72, 1, 3)
    };
    let scene = testscenes::textured_spheres(k, detail);
    let mut settings = RenderSettings {
        width: w,
        height: h,
        spp,
        integrator: IntegratorKind::Whitted {
            shading: ShadingModel::Pbr,
        },
        ..Default::default()
    };
    settings.path.max_depth = 4;
    println!(
        "scene '{}': {} triangles + {} analytic shapes; {}x{} at {} spp, whitted mode, {} threads",
        scene.name,
        scene.triangle_count(),
        scene
            .objects
            .iter()
            .filter(|o| !matches!(o.shape, trayecto::scene::Shape::Mesh(_)))
            .count(),
        w,
        h,
        spp,
        rayon::current_num_threads()
    );
    let mut results = Vec::new();
    for (name, accel) in [
        ("none", AccelKind::None),
        ("grid", AccelKind::Grid),
        ("bvh", AccelKind::Bvh),
    ] {
        let r = run(
            &scene,
            accel,
            &settings,
            if accel == AccelKind::None { 1 } else { reps },
        );
        println!(
            "{name:>5}: build {:>9.3} ms   render {:>9.3} s   {:>7.3} Mrays/s",
            r.build.as_secs_f64() * 1e3,
            r.render.as_secs_f64(),
            r.rays as f64 / r.render.as_secs_f64() / 1e6
        );
        results.push((name, r));
    }
    for (_, r) in &results[1..] {
        assert!(
            r.image == results[0].1.image,
            "accelerators must give identical images"
        );
    }
    let t = |i: usize| results[i].1.render.as_secs_f64();
    println!(
        "speed-up: grid {:.1}x over none, bvh {:.1}x over none, bvh {:.2}x over grid",
        t(0) / t(1),
        t(0) / t(2),
        t(1) / t(2)
    );
}
