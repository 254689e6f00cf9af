//! Cornell box benchmark (not a test): time and rays per second for the built-in scene at
//! 512×512, 64 spp with all cores, and the thread-scaling ratio against one thread.
//!
//! Run: `cargo bench --bench cornell` (set `TRAYECTO_BENCH_SPP` to change the sample count).

use std::sync::atomic::AtomicBool;
use std::time::Instant;
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene::builtin;
use trayecto::world::{World, WorldOptions};

fn main() {
    let spp: u32 = std::env::var("TRAYECTO_BENCH_SPP")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(64);
    let t = Instant::now();
    let world = World::build(builtin::cornell(), &WorldOptions::default()).expect("cornell builds");
    let build = t.elapsed();
    let cancel = AtomicBool::new(false);
    let run = |threads: Option<usize>, spp: u32| {
        let settings = RenderSettings {
            width: 512,
            height: 512,
            spp,
            threads,
            ..Default::default()
        };
        render(&world, &settings, &NoObserver, &cancel).expect("render")
    };
    let all = run(None, spp);
    let threads = rayon::current_num_threads();
    println!("cornell 512x512 @ {spp} spp, {threads} threads");
    println!("  build            {:>10.3} ms", build.as_secs_f64() * 1e3);
    println!(
        "  render           {:>10.3} s",
        all.render_time.as_secs_f64()
    );
    println!(
        "  rays             {:>10} ({} closest-hit, {} shadow)",
        all.stats.rays + all.stats.shadow_rays,
        all.stats.rays,
        all.stats.shadow_rays
    );
    println!(
        "  throughput       {:>10.2} Mrays/s",
        all.rays_per_second() / 1e6
    );
    println!(
        "  samples          {:>10.2} Msamples/s",
        512.0 * 512.0 * spp as f64 / all.render_time.as_secs_f64() / 1e6
    );
    // Thread scaling against the one-thread baseline, at a quarter of the samples.
    let quarter = (spp / 4).max(1);
    let one = run(Some(1), quarter);
    let many = run(None, quarter);
    println!(
        "  scaling          {:>10.2}x with {threads} threads vs 1 ({:.2} vs {:.2} Mrays/s)",
        many.rays_per_second() / one.rays_per_second(),
        many.rays_per_second() / 1e6,
        one.rays_per_second() / 1e6
    );
}
