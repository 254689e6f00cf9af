//! Stochastic progressive photon mapping (docs/DESIGN.md, integrators) against the Mitsuba 3
//! reference of the Cornell box: it converges (the error falls with iterations, the bias at the
//! test's budget is bounded), its image is a function of the seed and the settings for any
//! thread count, and what it cannot do (split frames, media) is refused with the reason.

mod common;
use common::*;
use std::sync::atomic::AtomicBool;
use trayecto::film::Image;
use trayecto::film::output::read_exr;
use trayecto::integrator::photon_grid::PointGrid;
use trayecto::integrator::sppm::{PhotonSettings, PixelState};
use trayecto::integrator::vcm::radius as vcm_radius;
use trayecto::integrator::{IntegratorKind, PathSettings};
use trayecto::math::Vec3;
use trayecto::render::{NoObserver, RangeStart, RenderSettings, render_range};
use trayecto::sampling::SamplerKind;
use trayecto::sampling::rng::Pcg32;
use trayecto::scene::builtin;
use trayecto::world::World;

fn sppm(width: u32, height: u32, iterations: u32, max_depth: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        spp: iterations,
        seed: 3,
        sampler: SamplerKind::Stratified,
        integrator: IntegratorKind::Sppm,
        path: PathSettings {
            max_depth,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// The Cornell box by SPPM converges to Mitsuba's reference: the 8 × 8 block error at 16
/// iterations is below 2/3 of the error at 4 (measured: 0.072 and 0.026), and the image means are within 3 % (the bias at
/// this budget: the initial radius blurs the corners' darkening, and the radius has shrunk by
/// only ~(2/3)^(1/2) per doubling of a pixel's photons).
#[test]
fn sppm_converges_to_mitsuba_on_the_cornell_box() {
    let scene = builtin::cornell();
    let world = World::build(scene, &Default::default()).unwrap();
    let reference = read_exr(&repo_dir().join("tests/references/cornell_128.exr")).unwrap();
    let low = render_world(&world, &sppm(128, 128, 4, 1024));
    let high = render_world(&world, &sppm(128, 128, 16, 1024));
    let (e_low, e_high) = (
        block_error(&low, &reference),
        block_error(&high, &reference),
    );
    eprintln!("sppm block error: {e_low} at 4 iterations, {e_high} at 16");
    assert_means_close(&high, &reference, 0.03, "sppm, 16 iterations");
    assert!(
        e_high < 0.06 && e_high < e_low * (2.0 / 3.0),
        "block error {e_low} at 4 iterations, {e_high} at 16"
    );
}

/// Direct lighting only (depth 1): no photon is used, the visible points' light samples match
/// the direct-only reference.
#[test]
fn sppm_direct_lighting_matches_the_direct_reference() {
    let reference = read_exr(&repo_dir().join("tests/references/cornell_128_direct.exr")).unwrap();
    let img = render_scene(&builtin::cornell(), &sppm(128, 128, 4, 1));
    assert_means_close(&img, &reference, 0.02, "sppm, depth 1");
}

/// The same frame with 1 and 2 threads (and a Gaussian filter, and photons per iteration
/// spanning several chunks) is the same film bit for bit; a sample range that does not start at
/// 0 is refused, as are media and a non-positive radius.
#[test]
fn sppm_film_is_a_function_of_seed_and_settings() {
    let world = World::build(builtin::cornell(), &Default::default()).unwrap();
    let base = RenderSettings {
        threads: Some(1),
        filter: trayecto::film::filter::Filter::new(trayecto::film::filter::FilterKind::Gaussian),
        photon: PhotonSettings {
            photons_per_iteration: Some(9000),
            radius: Some(0.08),
            ..Default::default()
        },
        ..sppm(24, 20, 3, 6)
    };
    let cancel = AtomicBool::new(false);
    let range = |s: &RenderSettings, samples: std::ops::Range<u32>| {
        render_range(
            &world,
            s,
            RangeStart {
                samples,
                resume: None,
            },
            &NoObserver,
            &cancel,
        )
    };
    let one = range(&base, 0..3).unwrap().film;
    assert!(one.to_image().mean().max_element() > 0.0);
    let two = range(
        &RenderSettings {
            threads: Some(2),
            ..base.clone()
        },
        0..3,
    )
    .unwrap()
    .film;
    assert_eq!(one, two);
    let err = range(&base, 1..3).unwrap_err().to_string();
    assert!(err.contains("radius and count"), "{err}");
    let bad = RenderSettings {
        photon: PhotonSettings {
            photons_per_iteration: None,
            radius: Some(0.0),
            ..Default::default()
        },
        ..base.clone()
    };
    assert!(range(&bad, 0..3).is_err());
}

/// pbrt's `Integrator "sppm"` with its parameters reaches the render hints.
#[test]
fn pbrt_sppm_parameters_are_honoured() {
    let text = r#"Integrator "sppm" "float radius" [0.25] "integer photonsperiteration" [5000] "integer maxdepth" [7]
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 20 "integer yresolution" 10
WorldBegin
LightSource "infinite" "rgb L" [0.5 0.5 0.5]
Shape "sphere" "float radius" 1
"#;
    let scene = trayecto::scene::pbrt::load_from_str(text, "t.pbrt").unwrap();
    assert_eq!(scene.hints.integrator.as_deref(), Some("sppm"));
    assert_eq!(scene.hints.photon_radius, Some(0.25));
    assert_eq!(scene.hints.photons_per_iteration, Some(5000));
    assert_eq!(scene.hints.max_depth, Some(7));
}

fn vcm(width: u32, height: u32, iterations: u32, max_depth: u32, merge: bool) -> RenderSettings {
    RenderSettings {
        integrator: IntegratorKind::Vcm,
        photon: PhotonSettings {
            no_merge: !merge,
            ..Default::default()
        },
        ..sppm(width, height, iterations, max_depth)
    }
}

/// Vertex connection and merging on the Cornell box converges to Mitsuba's reference: with
/// merges, the block error at 8 iterations is below 2/3 of the error at 2 (measured: 0.104 and
/// 0.055, the 1/√4 of noise) and below 0.08, and the means are within 2 %; without merges (bidirectional path tracing with one light subpath per camera
/// subpath, unbiased) the means are within 2 % too, and at depth 1 (the direct-only reference)
/// both are.
#[test]
fn vcm_converges_to_mitsuba_on_the_cornell_box() {
    let world = World::build(builtin::cornell(), &Default::default()).unwrap();
    let reference = read_exr(&repo_dir().join("tests/references/cornell_128.exr")).unwrap();
    let direct = read_exr(&repo_dir().join("tests/references/cornell_128_direct.exr")).unwrap();
    let low = render_world(&world, &vcm(128, 128, 2, 1024, true));
    let high = render_world(&world, &vcm(128, 128, 8, 1024, true));
    let (e_low, e_high) = (
        block_error(&low, &reference),
        block_error(&high, &reference),
    );
    eprintln!("vcm block error: {e_low} at 2 iterations, {e_high} at 8");
    assert_means_close(&high, &reference, 0.02, "vcm, 8 iterations");
    assert!(
        e_high < 0.08 && e_high < e_low * (2.0 / 3.0),
        "block error {e_low} at 2 iterations, {e_high} at 8"
    );
    let vc = render_world(&world, &vcm(128, 128, 4, 1024, false));
    eprintln!(
        "vcm without merges: block error {}",
        block_error(&vc, &reference)
    );
    assert_means_close(&vc, &reference, 0.02, "vcm without merges");
    for merge in [true, false] {
        let d = render_world(&world, &vcm(128, 128, 2, 1, merge));
        assert_means_close(&d, &direct, 0.02, &format!("vcm depth 1, merge {merge}"));
    }
}

/// VCM's film is the same for 1 and 2 threads, and a frame split into sample ranges (each
/// iteration's radius is a function of its index) adds up to the single run, bit for bit.
#[test]
fn vcm_film_is_a_function_of_seed_and_settings() {
    let world = World::build(builtin::cornell(), &Default::default()).unwrap();
    let base = RenderSettings {
        threads: Some(1),
        filter: trayecto::film::filter::Filter::new(trayecto::film::filter::FilterKind::Gaussian),
        ..vcm(24, 20, 5, 6, true)
    };
    let cancel = AtomicBool::new(false);
    let range = |s: &RenderSettings, samples: std::ops::Range<u32>| {
        render_range(
            &world,
            s,
            RangeStart {
                samples,
                resume: None,
            },
            &NoObserver,
            &cancel,
        )
        .unwrap()
        .film
    };
    let one = range(&base, 0..5);
    assert!(one.to_image().mean().max_element() > 0.0);
    let two = range(
        &RenderSettings {
            threads: Some(2),
            ..base.clone()
        },
        0..5,
    );
    assert_eq!(one, two);
    let mut split = range(&base, 0..2);
    split.add_film(&range(&base, 2..5)).unwrap();
    assert_eq!(one, split);
}

/// The photon and light-path integrators report their progress with a time left, as the tiled
/// renderer does (the CLI's bar showed "eta ?" throughout): every report has an estimate, the
/// work done reaches the whole, and nothing is left then.
#[test]
fn photon_and_light_path_renders_report_the_time_left() {
    use std::sync::Mutex;
    use trayecto::render::{Progress, RenderObserver};
    struct Record(Mutex<Vec<Progress>>);
    impl RenderObserver for Record {
        fn progress(&self, p: &Progress) {
            self.0.lock().unwrap().push(*p);
        }
    }
    let world = World::build(builtin::cornell(), &Default::default()).unwrap();
    let splatting = |integrator| RenderSettings {
        integrator,
        ..sppm(16, 16, 4, 4)
    };
    for settings in [
        sppm(16, 16, 4, 4),
        vcm(16, 16, 4, 4, true),
        splatting(IntegratorKind::LightTracer),
        splatting(IntegratorKind::Bdpt),
        splatting(IntegratorKind::Mlt),
    ] {
        let rec = Record(Mutex::new(Vec::new()));
        render_range(
            &world,
            &settings,
            RangeStart {
                samples: 0..4,
                resume: None,
            },
            &rec,
            &AtomicBool::new(false),
        )
        .unwrap();
        let reports = rec.0.into_inner().unwrap();
        let what = format!("{:?}", settings.integrator);
        assert!(!reports.is_empty(), "{what}: no progress reported");
        assert!(
            reports.iter().all(|p| p.remaining.is_some()),
            "{what}: a report without a time left"
        );
        // (Workers report as they finish, so reports need not come in order.)
        let last = reports.iter().max_by_key(|p| p.done).unwrap();
        assert_eq!(last.fraction(), 1.0, "{what}");
        assert_eq!(last.remaining, Some(std::time::Duration::ZERO), "{what}");
    }
}

/// Every point within the radius is found exactly once and no other, against a brute-force
/// scan, for radii below, at and above the cell size (so boxes of 1 to 5 cells a side, whose
/// cells collide in the small table).
#[test]
fn grid_finds_every_point_within_the_radius_once() {
    let mut rng = Pcg32::new(7, 1);
    let mut u = || rng.next_f32();
    let points: Vec<Vec3> = (0..3000)
        .map(|_| Vec3::new(u() * 4.0 - 2.0, u() * 4.0 - 2.0, u() * 0.5))
        .collect();
    for (cell, r) in [(0.2, 0.15), (0.2, 0.2), (0.1, 0.45), (0.5, 0.05)] {
        let grid = PointGrid::build(&points, cell);
        for _ in 0..200 {
            let p = Vec3::new(u() * 4.4 - 2.2, u() * 4.4 - 2.2, u() * 0.7 - 0.1);
            let mut seen = vec![0u32; points.len()];
            grid.for_each_within(&points, p, r, |i| seen[i] += 1);
            for (i, q) in points.iter().enumerate() {
                let want = u32::from((*q - p).length_squared() <= r * r);
                assert_eq!(seen[i], want, "point {i} at {q:?}, query {p:?} r {r}");
            }
        }
    }
    let empty = PointGrid::build(&[], 1.0);
    empty.for_each_within(&[], Vec3::ZERO, 1.0, |_| panic!("nothing to find"));
}

/// SPPM's update: the radius shrinks by √((N + αM)/(N + M)) and the flux with the disc's area.
#[test]
fn sppm_update_shrinks_the_radius_and_rescales_the_flux() {
    let mut p = PixelState::new(2.0);
    p.update(0, [1.0; 3], Vec3::ONE);
    assert_eq!(p.radius, 2.0);
    p.update(30, [3.0, 6.0, 0.0], Vec3::ONE);
    assert!((p.n - 20.0).abs() < 1e-12);
    let r = 2.0 * (20.0f64 / 30.0).sqrt();
    assert!((p.radius - r).abs() < 1e-12);
    assert!((p.tau[0] - 3.0 * (r / 2.0).powi(2)).abs() < 1e-12);
    assert!((p.tau[1] - 6.0 * (r / 2.0).powi(2)).abs() < 1e-12);
    p.update(20, [0.0; 3], Vec3::ONE);
    assert!((p.radius - r * ((20.0 + 40.0 / 3.0) / 40.0f64).sqrt()).abs() < 1e-12);
}

/// VCM's radius r_i = r_0 · i^((α−1)/2) (i from 1): r_0 first, then shrinking; a stored light
/// vertex takes at most 448 bytes.
#[test]
fn vcm_radius_shrinks_with_the_iteration_index() {
    assert_eq!(vcm_radius(0.5, 0), 0.5);
    let r = vcm_radius(0.5, 15);
    assert!((r - 0.5 * 16f32.powf(-0.125)).abs() < 1e-6, "{r}");
    assert!(vcm_radius(0.5, 16) < r);
    // The memory bound docs/DESIGN.md states for VCM's light vertex store (a vertex keeps its
    // shading: hit, BSDF, frame), so that growing it is a decision, not an accident.
    assert!(std::mem::size_of::<trayecto::integrator::vcm::LightVertex>() <= 448);
}

/// The time-to-equal-error comparison of BENCHMARKS.md ("Caustics seen through glass"): VCM,
/// BDPT and SPPM (Trayecto) and pbrt-v4's SPPM on scenes/pbrt/caustic-through-glass.pbrt at
/// 160 × 120, 2 threads, interleaved at 4, 16, 64 and 256 samples (iterations), each image's
/// relative RMS error against one reference (Trayecto's VCM at 1024 iterations; pbrt-v4 renders
/// the same file). A measurement, not a test: run by hand with
/// `cargo test --test photon caustic -- --ignored --nocapture`
/// (pbrt-v4 from ../shared/tools/pbrt-v4/pbrt, or $PBRT).
#[test]
#[ignore]
fn caustic_through_glass_time_to_equal_error() {
    use std::time::Instant;
    let file = repo_dir().join("scenes/pbrt/caustic-through-glass.pbrt");
    let scene = trayecto::scene::pbrt::load(&file).unwrap();
    let world = World::build(scene.clone(), &Default::default()).unwrap();
    let (w, h) = (160u32, 120u32);
    let settings = |kind: IntegratorKind, spp: u32| RenderSettings {
        width: w,
        height: h,
        spp,
        seed: 11,
        threads: Some(2),
        integrator: kind,
        path: PathSettings {
            max_depth: scene.hints.max_depth.unwrap_or(8),
            ..Default::default()
        },
        photon: PhotonSettings {
            radius: scene.hints.photon_radius,
            ..Default::default()
        },
        ..Default::default()
    };
    let run = |kind: IntegratorKind, spp: u32| {
        let out = trayecto::render::render(
            &world,
            &settings(kind, spp),
            &NoObserver,
            &AtomicBool::new(false),
        )
        .unwrap();
        (out.image, out.render_time.as_secs_f64())
    };
    let t = Instant::now();
    let (reference, _) = run(IntegratorKind::Vcm, 1024);
    eprintln!("reference: {:.1} s", t.elapsed().as_secs_f64());
    let m = reference.mean();
    let mean = ((m.x + m.y + m.z) / 3.0) as f64;
    let error = |img: &Image| {
        let s: f64 = img
            .data
            .iter()
            .zip(&reference.data)
            .map(|(a, b)| (*a - *b).as_dvec3().length_squared() / 3.0)
            .sum();
        (s / img.data.len() as f64).sqrt() / mean
    };
    let pbrt = std::env::var("PBRT").unwrap_or_else(|_| {
        repo_dir()
            .join("../shared/tools/pbrt-v4/pbrt")
            .to_string_lossy()
            .into_owned()
    });
    let tmp = std::env::temp_dir().join("trayecto-caustic-bench");
    std::fs::create_dir_all(&tmp).unwrap();
    let small = tmp.join("scene.pbrt");
    std::fs::write(
        &small,
        std::fs::read_to_string(&file).unwrap().replace(
            "\"integer xresolution\" [ 320 ] \"integer yresolution\" [ 240 ]",
            &format!("\"integer xresolution\" [ {w} ] \"integer yresolution\" [ {h} ]"),
        ),
    )
    .unwrap();
    let run_pbrt = |spp: u32| {
        let out = tmp.join(format!("pbrt-{spp}.exr"));
        let t = Instant::now();
        let st = std::process::Command::new(&pbrt)
            .args(["--quiet", "--nthreads", "2", "--seed", "11", "--spp"])
            .arg(spp.to_string())
            .arg("--outfile")
            .arg(&out)
            .arg(&small)
            .status()
            .expect("pbrt-v4 runs");
        assert!(st.success());
        // Wall time, scene parsing included (a fraction of a second for this scene).
        (read_exr(&out).unwrap(), t.elapsed().as_secs_f64())
    };
    let names = ["vcm", "bdpt", "sppm", "pbrt-v4 sppm"];
    let mut points: Vec<Vec<(f64, f64)>> = vec![Vec::new(); names.len()];
    for spp in [4u32, 16, 64, 256] {
        for (k, name) in names.iter().enumerate() {
            let (img, secs) = match k {
                0 => run(IntegratorKind::Vcm, spp),
                1 => run(IntegratorKind::Bdpt, spp),
                2 => run(IntegratorKind::Sppm, spp),
                _ => run_pbrt(spp),
            };
            let e = error(&img);
            eprintln!("{name:>13} {spp:>4} spp: {secs:8.2} s, rel. RMS error {e:.4}");
            points[k].push((secs, e));
        }
    }
    // Time to reach VCM's error at 64 iterations, interpolated log-log between ladder points.
    let target = points[0][2].1;
    println!("| method | error at 4 / 16 / 64 / 256 spp | time to error {target:.4} |");
    println!("| --- | --- | --- |");
    for (k, name) in names.iter().enumerate() {
        let p = &points[k];
        let mut reach = None;
        for i in 0..p.len() {
            if p[i].1 <= target {
                reach = Some(if i == 0 {
                    p[0].0
                } else {
                    let (t0, e0, t1, e1) = (p[i - 1].0, p[i - 1].1, p[i].0, p[i].1);
                    let f = (target.ln() - e0.ln()) / (e1.ln() - e0.ln());
                    (t0.ln() + f * (t1.ln() - t0.ln())).exp()
                });
                break;
            }
        }
        let errs: Vec<String> = p.iter().map(|(_, e)| format!("{e:.4}")).collect();
        let time = reach.map_or(format!("> {:.1} s", p[p.len() - 1].0), |t| {
            format!("{t:.1} s")
        });
        println!("| {name} | {} | {time} |", errs.join(" / "));
    }
}

/// SPPM and VCM against references beyond the Cornell box. A glossy scene
/// (scenes/pbrt/roughness.pbrt: rough conductor and dielectric, coated surfaces, point lights
/// and a uniform light at infinity), which SPPM passes through to its diffuse visible points as
/// pbrt-v4's SPPM does, against Trayecto's path tracer at 64 spp (itself held to pbrt-v4's
/// render of the file elsewhere); a thin-lens camera (screenwindow.pbrt) against pbrt-v4's
/// render; glass on a floor under an area light and a uniform sky (caustics), a uniform
/// environment and a distant light against Mitsuba 3's (scenes/mitsuba/).
/// Channel means within 3 % and 8 × 8 block error below a bound about 1.5 × the measured one.
#[test]
fn photon_methods_agree_with_references_on_glossy_lens_and_infinite_lights() {
    let cases: [(&str, &str, IntegratorKind, u32, f64); 8] = [
        (
            "scenes/mitsuba/glass.toml",
            "mitsuba_glass",
            IntegratorKind::Vcm,
            16,
            0.075,
        ),
        (
            "scenes/mitsuba/glass.toml",
            "mitsuba_glass",
            IntegratorKind::Sppm,
            16,
            0.075,
        ),
        (
            "scenes/pbrt/roughness.pbrt",
            "",
            IntegratorKind::Sppm,
            32,
            0.065,
        ),
        (
            "scenes/pbrt/roughness.pbrt",
            "",
            IntegratorKind::Vcm,
            16,
            0.075,
        ),
        (
            "scenes/pbrt/screenwindow.pbrt",
            "pbrt/screenwindow",
            IntegratorKind::Vcm,
            8,
            0.045,
        ),
        (
            "scenes/mitsuba/constant_env.toml",
            "mitsuba_constant_env",
            IntegratorKind::Vcm,
            8,
            0.022,
        ),
        (
            "scenes/mitsuba/directional.toml",
            "mitsuba_directional",
            IntegratorKind::Vcm,
            8,
            0.055,
        ),
        (
            "scenes/mitsuba/constant_env.toml",
            "mitsuba_constant_env",
            IntegratorKind::Sppm,
            16,
            0.09,
        ),
    ];
    let mut failed = Vec::new();
    for (file, reference, integrator, spp, bound) in cases {
        let scene = trayecto::scene::load(repo_dir().join(file).to_str().unwrap()).unwrap();
        let settings = |integrator, spp, width, height| RenderSettings {
            width,
            height,
            spp,
            seed: 5,
            integrator,
            filter: scene.hints.filter.unwrap_or_default(),
            path: PathSettings {
                max_depth: scene.hints.max_depth.unwrap_or(1024),
                ..Default::default()
            },
            ..Default::default()
        };
        let reference = if reference.is_empty() {
            let (w, h) = (scene.hints.width.unwrap(), scene.hints.height.unwrap());
            render_scene(&scene, &settings(IntegratorKind::Path, 64, w, h))
        } else {
            read_exr(&repo_dir().join(format!("tests/references/{reference}.exr"))).unwrap()
        };
        let img = render_scene(
            &scene,
            &settings(integrator, spp, reference.width, reference.height),
        );
        let what = format!("{file} {integrator:?}");
        let e = block_error(&img, &reference);
        let (m, r) = (img.mean(), reference.mean());
        let mean_off = ((m - r).abs() / r).max_element();
        eprintln!("{what}: block error {e:.4}, means off by {mean_off:.4}");
        if mean_off > 0.03 || e >= bound || e.is_nan() {
            failed.push(format!("{what}: means off by {mean_off}, block error {e}"));
        }
    }
    assert!(failed.is_empty(), "{failed:#?}");
}
