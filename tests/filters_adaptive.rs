//! Issue #19 (part 2): reconstruction filters, adaptive sampling, the time limit and crop
//! windows, at the level of rendered images. The filters' samplers have their own unit tests
//! (weights integrate to one, chi-square against |f|) in `src/film/filter.rs`.

mod common;

use std::process::Command;
use std::sync::atomic::AtomicBool;
use trayecto::film::filter::{Filter, FilterKind};
use trayecto::math::{Mat4, Vec3};
use trayecto::pipeline::{CropSpec, GivenSettings, OutputSpec, RenderJob, Silent};
use trayecto::render::{Crop, NoObserver, RenderSettings, render_range};
use trayecto::scene::{CameraDesc, LightDesc, Object, Scene, Shape};
use trayecto::world::{World, WorldOptions};

const ALL: [FilterKind; 5] = [
    FilterKind::Box,
    FilterKind::Tent,
    FilterKind::Gaussian,
    FilterKind::Mitchell,
    FilterKind::BlackmanHarris,
];

/// Every camera ray sees the same radiance: a uniform environment and one small sphere behind
/// the camera (so the world has geometry).
fn constant_scene(radiance: Vec3) -> Scene {
    Scene {
        name: "constant".into(),
        objects: vec![Object {
            name: "behind".into(),
            shape: Shape::Sphere {
                center: Vec3::new(0.0, 0.0, 50.0),
                radius: 0.1,
            },
            transform: Mat4::IDENTITY,
            material: 0,
            medium: None,
        }],
        materials: vec![Default::default()],
        lights: vec![LightDesc::Ambient {
            name: "env".into(),
            radiance,
        }],
        cameras: vec![CameraDesc::look_at(
            "cam",
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::Y,
            40.0,
        )],
        ..Default::default()
    }
}

fn settings(w: u32, h: u32, spp: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        spp,
        ..RenderSettings::default()
    }
}

/// A constant scene stays constant under every filter. Box and tent weigh every sample 1, so
/// every pixel is exactly the constant. The tabulated filters' weights f/pdf vary with the
/// table's piecewise-constant fit (|w − 1| is bounded by the fit, checked per pixel below);
/// Mitchell's weights are ±K (its negative lobes), so its pixels are constant in expectation:
/// the image mean is checked against 4 standard errors of the signed weights' spread.
#[test]
fn constant_scene_stays_constant_under_every_filter() {
    let c = Vec3::new(0.5, 0.25, 1.0);
    let world = World::build(
        constant_scene(c),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    for kind in ALL {
        let s = RenderSettings {
            filter: Filter::new(kind),
            ..settings(24, 24, 64)
        };
        let img = common::render_world(&world, &s);
        let ratios: Vec<f64> = img.data.iter().map(|p| (p.z / c.z) as f64).collect();
        for p in &img.data {
            // The channels keep their proportions whatever the weight.
            assert!((p.x / p.z - 0.5).abs() < 1e-5 && (p.y / p.z - 0.25).abs() < 1e-5);
        }
        let n = ratios.len() as f64;
        let mean = ratios.iter().sum::<f64>() / n;
        let sd = (ratios.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n).sqrt();
        match kind {
            FilterKind::Box | FilterKind::Tent => {
                assert!(ratios.iter().all(|&r| r == 1.0), "{kind:?}: {ratios:?}");
            }
            FilterKind::Gaussian | FilterKind::BlackmanHarris => {
                let worst = ratios.iter().map(|r| (r - 1.0).abs()).fold(0.0, f64::max);
                assert!(worst < 0.01, "{kind:?}: a pixel is off by {worst}");
                assert!((mean - 1.0).abs() < 1e-3, "{kind:?}: mean {mean}");
            }
            FilterKind::Mitchell => {
                // Per-pixel spread sd; the mean of n pixels is within 4 sd/√n of 1.
                assert!(sd > 0.0 && sd < 0.15, "{kind:?}: per-pixel spread {sd}");
                assert!(
                    (mean - 1.0).abs() < 4.0 * sd / n.sqrt(),
                    "{kind:?}: mean {mean}, spread {sd}"
                );
            }
        }
    }
}

/// FNV-1a over the bits of every channel of every pixel, in row order.
fn image_hash(img: &trayecto::film::Image) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for p in &img.data {
        for v in p.to_array() {
            for b in v.to_bits().to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    h
}

/// The default filter keeps the image Trayecto rendered before it had filters: the Cornell box at
/// 16 × 16 px and 4 spp hashes to the value recorded when the filters came in (bits of the
/// unfiltered render, one sample per pixel position), so a default that is not the box of
/// radius 0.5, or a box that moves its samples, changes the hash. A renderer change that alters
/// this image on purpose updates the constant (the message prints the new one).
#[test]
fn default_box_is_unchanged() {
    const PRE_FILTER_HASH: u64 = 0x6de6_e141_41f5_f8ff;
    let scene = trayecto::scene::load("cornell").unwrap();
    let world = World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let a = common::render_world(&world, &settings(16, 16, 4));
    let h = image_hash(&a);
    assert_eq!(h, PRE_FILTER_HASH, "default-filter image hash {h:#018x}");
    let b = common::render_world(
        &world,
        &RenderSettings {
            filter: Filter::new(FilterKind::Box),
            ..settings(16, 16, 4)
        },
    );
    assert_eq!(a, b, "Filter::default() is not the box of radius 0.5");
}

/// A vertical edge between a white sky (left half of the view) and a black quad (right half),
/// seen through box filters of radius r: a pixel's value is the fraction of its filter's
/// footprint [x + ½ − r, x + ½ + r] left of the edge (at x = 8 of 16), so radius 1.5 spreads the
/// step over pixels 7 and 8 as 2/3 and 1/3 and radius 0.5 keeps it a step (a radius taken as a
/// diameter, 3, would give 0.58 and 0.42). Measured noise floor of a pixel's value (64 stratified
/// spp: 8 × 8 strata, the edge crossing some of them): at most 0.0104 over seeds 0–5 (NOISE);
/// the tolerance is 3× that.
#[test]
fn box_radius_blurs_an_edge_as_predicted() {
    let mut scene = Scene {
        name: "edge".into(),
        ..Default::default()
    };
    let black = scene.add_material(trayecto::material::Material::diffuse("black", Vec3::ZERO));
    scene.add_object(
        "right half",
        Shape::Quad {
            corner: Vec3::new(0.0, -100.0, -1.0),
            e1: Vec3::new(100.0, 0.0, 0.0),
            e2: Vec3::new(0.0, 200.0, 0.0),
        },
        Mat4::IDENTITY,
        black,
    );
    scene.lights.push(LightDesc::Ambient {
        name: "sky".into(),
        radiance: Vec3::ONE,
    });
    scene.cameras.push(CameraDesc::look_at(
        "cam",
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::Y,
        40.0,
    ));
    let world = World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    const NOISE: f32 = 0.0104;
    let mut worst = 0.0f32;
    for (radius, profile) in [
        (0.5, [1.0, 1.0, 1.0, 0.0, 0.0, 0.0]),
        (1.5, [1.0, 1.0, 2.0 / 3.0, 1.0 / 3.0, 0.0, 0.0]),
    ] {
        let img = common::render_world(
            &world,
            &RenderSettings {
                filter: Filter {
                    radius: [radius, radius],
                    ..Filter::new(FilterKind::Box)
                },
                ..settings(16, 4, 64)
            },
        );
        for y in 0..4 {
            for (i, want) in profile.iter().enumerate() {
                let x = 5 + i as u32;
                let got = img.get(x, y);
                worst = worst.max((got.x - want).abs());
                assert!(
                    (got - Vec3::splat(*want)).abs().max_element() < 3.0 * NOISE,
                    "radius {radius}: pixel ({x}, {y}) is {got}, the box predicts {want}"
                );
            }
        }
    }
    eprintln!("edge profile: worst deviation {worst}");
}

/// A crop renders exactly the same pixels as the same window of the full render, for the default
/// filter and for a wide filter (whose samples reach outside the window). Adaptive sampling is
/// not covered here: its mask's dilation stops at the crop's edge, so an adaptive crop is not a
/// window of the adaptive full render.
#[test]
fn crop_equals_the_window_of_the_full_image() {
    let scene = trayecto::scene::load("cornell").unwrap();
    let world = World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let crop = Crop {
        x0: 5,
        x1: 19,
        y0: 3,
        y1: 12,
    };
    for filter in [Filter::default(), Filter::new(FilterKind::Mitchell)] {
        let full_s = RenderSettings {
            filter,
            ..settings(24, 16, 8)
        };
        let full = common::render_world(&world, &full_s);
        let part = common::render_world(
            &world,
            &RenderSettings {
                crop: Some(crop),
                ..full_s.clone()
            },
        );
        assert_eq!((part.width, part.height), (14, 9));
        for y in 0..9 {
            for x in 0..14 {
                assert_eq!(
                    part.get(x, y).to_array().map(f32::to_bits),
                    full.get(x + 5, y + 3).to_array().map(f32::to_bits),
                    "{filter:?} pixel ({x}, {y})"
                );
            }
        }
    }
    // pbrt's cropwindow rule: pixels ceil(24·0.25)..ceil(24·0.6) = 6..15, ceil(16·0.1).. = 2..8.
    assert_eq!(
        Crop::from_fractions([0.25, 0.6, 0.1, 0.5], 24, 16),
        Crop {
            x0: 6,
            x1: 15,
            y0: 2,
            y1: 8
        }
    );
}

/// A noise threshold that some pixels of the Cornell box (24×24, 128-spp frame) meet after their
/// first 16 samples and some do not: the 90th percentile of the relative errors of those samples
/// (read from a film with variance tracking), so the test does not depend on guessing the
/// scene's noise level.
fn cornell_threshold(world: &World) -> f32 {
    let film = first_16_samples(world);
    let mut e: Vec<f64> = (0..film.counts().len())
        .map(|i| film.relative_error(i))
        .collect();
    e.sort_by(f64::total_cmp);
    e[e.len() * 9 / 10] as f32
}

/// The film of the Cornell box's first 16 samples (24 × 24 px, variance tracked).
fn first_16_samples(world: &World) -> trayecto::film::Film {
    let s = RenderSettings {
        noise_threshold: Some(100.0),
        ..settings(24, 24, 128)
    };
    let start = trayecto::render::RangeStart {
        samples: 0..16,
        resume: None,
    };
    render_range(world, &s, start, &NoObserver, &AtomicBool::new(false))
        .unwrap()
        .film
}

fn adaptive_settings(threads: usize, threshold: f32) -> RenderSettings {
    RenderSettings {
        noise_threshold: Some(threshold),
        threads: Some(threads),
        ..settings(24, 24, 128)
    }
}

/// Adaptive sampling is a pure function of seed and settings: one thread and three threads give
/// the same bits, and the per-pixel sample counts differ between pixels (some stopped early).
#[test]
fn adaptive_is_bit_identical_across_thread_counts_and_stops_clean_pixels() {
    let scene = trayecto::scene::load("cornell").unwrap();
    let world = World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let t = cornell_threshold(&world);
    let run = |threads| {
        let s = adaptive_settings(threads, t);
        let start = trayecto::render::RangeStart {
            samples: 0..s.spp,
            resume: None,
        };
        render_range(&world, &s, start, &NoObserver, &AtomicBool::new(false)).unwrap()
    };
    let one = run(1);
    let three = run(3);
    assert_eq!(one.film, three.film);
    let counts = one.film.counts();
    let min = *counts.iter().min().unwrap();
    let max = *counts.iter().max().unwrap();
    assert!(min >= trayecto::render::ADAPTIVE_MIN_SAMPLES, "min {min}");
    assert!(min < max, "every pixel got {min} samples: nothing adapted");
    // A pixel stopped below the cap took no sample after the pass that stopped it, so the
    // final film holds exactly the samples it was judged on: its relative error meets the
    // threshold. (An inverted rule stops the noisy pixels instead.)
    let mut stopped = 0;
    for (i, &n) in counts.iter().enumerate() {
        if n < 128 {
            stopped += 1;
            let e = one.film.relative_error(i);
            assert!(
                e <= t as f64,
                "pixel {i} stopped at {n} samples with relative error {e} > threshold {t}"
            );
        }
    }
    assert!(stopped > 0, "no pixel stopped early");
    // The rule spends samples where one sample is noisy: the per-sample relative deviation
    // (relative error × √n, which does not shrink with n) of the pixels that ran to the cap is
    // larger than that of the pixels that stopped. An inverted rule (stop where the error is
    // above the threshold) stops the noisy pixels and keeps the clean ones, and fails here.
    let per_sample = |i: usize| one.film.relative_error(i) * (counts[i] as f64).sqrt();
    let mean_of = |capped: bool| {
        let v: Vec<f64> = (0..counts.len())
            .filter(|&i| (counts[i] >= 128) == capped)
            .map(per_sample)
            .filter(|x| x.is_finite())
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    // Measured on this render: 2.82 against 0.96 (a ratio of 2.9); an inverted rule gives
    // a ratio below 1.
    let (capped, early) = (mean_of(true), mean_of(false));
    assert!(
        capped > 1.5 * early,
        "pixels run to the cap deviate {capped:.3} per sample, pixels stopped early {early:.3}: \
         the samples did not go to the noisy pixels"
    );
}

/// Absurd values are refused before rendering, with a message naming the option.
#[test]
fn absurd_values_are_refused() {
    let base = settings(8, 8, 4);
    for s in [
        RenderSettings {
            noise_threshold: Some(-0.1),
            ..base.clone()
        },
        RenderSettings {
            noise_threshold: Some(f32::NAN),
            ..base.clone()
        },
        RenderSettings {
            noise_threshold: Some(0.0),
            ..base.clone()
        },
        RenderSettings {
            time_limit: Some(-1.0),
            ..base.clone()
        },
        RenderSettings {
            time_limit: Some(f64::NAN),
            ..base.clone()
        },
        RenderSettings {
            time_limit: Some(f64::INFINITY),
            ..base.clone()
        },
        RenderSettings {
            crop: Some(Crop {
                x0: 4,
                x1: 4,
                y0: 0,
                y1: 8,
            }),
            ..base.clone()
        },
        RenderSettings {
            crop: Some(Crop {
                x0: 0,
                x1: 9,
                y0: 0,
                y1: 8,
            }),
            ..base.clone()
        },
        RenderSettings {
            filter: Filter {
                radius: [f32::NAN, 1.0],
                ..Filter::default()
            },
            ..base.clone()
        },
    ] {
        assert!(s.validate().is_err(), "{s:?}");
    }
    assert!(CropSpec::parse("0.5,0.2,0,1", false).is_err());
    assert!(CropSpec::parse("0,1.5,0,1", false).is_err());
    assert!(CropSpec::parse("NaN,1,0,1", false).is_err());
    assert!(CropSpec::parse("0,1,0", false).is_err());
    assert!(CropSpec::parse("-1,4,0,4", true).is_err());

    let bin = env!("CARGO_BIN_EXE_trayecto");
    let dir = std::env::temp_dir().join(format!("trayecto-refuse-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let trp = dir.join("x.trp").to_string_lossy().to_string();
    let png = dir.join("x.png").to_string_lossy().to_string();
    // (options, what the message must say); every case also names a writable output.
    let cases: [(&[&str], &str); 12] = [
        (&["--noise-threshold", "-1"], "noise threshold"),
        (&["--noise-threshold", "nan"], "noise threshold"),
        (&["--time-limit", "-5"], "time limit"),
        (&["--time-limit", "nan"], "time limit"),
        (&["--crop", "0.5,0.2,0,1"], "--crop"),
        (&["--pixel-bounds", "0,10,5,2"], "--pixel-bounds"),
        (&["--pixel-bounds", "0,10,0,9"], "crop window"),
        (&["--filter", "lanczos"], "lanczos"),
        (&["--filter", "gaussian", "--filter-radius", "0"], "radius"),
        (&["--filter-sigma", "0.5"], "--filter"),
        (
            &["--noise-threshold", "0.01", "--samples", "0..8", "-o", &trp],
            "cannot be combined",
        ),
        (
            &["--time-limit", "5", "--checkpoint", &trp, "-o", &png],
            "cannot be combined",
        ),
    ];
    for (args, want) in cases {
        let mut cmd = Command::new(bin);
        cmd.args(["cornell", "--width", "8", "--height", "8", "--spp", "2"])
            .args(args);
        if !args.contains(&"-o") {
            cmd.args(["-o", &png]);
        }
        let out = cmd.output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} was accepted");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: expected '{want}' in: {err}");
    }
    assert!(!dir.join("x.png").exists() && !dir.join("x.trp").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A time limit ends the render at a pass boundary: the result is the film of the complete
/// passes, identical to a render of exactly that many samples per pixel.
#[test]
fn time_limited_render_equals_the_render_of_its_passes() {
    let scene = trayecto::scene::load("cornell").unwrap();
    let world = World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let s = RenderSettings {
        time_limit: Some(0.3),
        ..settings(16, 16, 1 << 16)
    };
    let start = trayecto::render::RangeStart {
        samples: 0..s.spp,
        resume: None,
    };
    let r = render_range(&world, &s, start, &NoObserver, &AtomicBool::new(false)).unwrap();
    assert!(
        r.stopped_early && r.done >= 1 && r.done < s.spp,
        "done {}",
        r.done
    );
    // The same frame rendered up to `done` without a time limit.
    let plain = RenderSettings {
        time_limit: None,
        ..s.clone()
    };
    let start = trayecto::render::RangeStart {
        samples: 0..r.done,
        resume: None,
    };
    let p = render_range(&world, &plain, start, &NoObserver, &AtomicBool::new(false)).unwrap();
    assert_eq!(r.film, p.film);
}

/// pbrt's PixelFilter and cropwindow reach the render through the scene's hints (and the
/// command line's --filter wins); without a PixelFilter a pbrt file gets pbrt's Gaussian.
#[test]
fn pbrt_filter_and_crop_are_applied() {
    let text = |extra: &str| {
        format!(
            r#"LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 20 "integer yresolution" 10 {extra}
Sampler "independent" "integer pixelsamples" 2
WorldBegin
LightSource "infinite" "rgb L" [0.5 0.5 0.5]
Shape "sphere" "float radius" 1
"#
        )
    };
    let plain = trayecto::scene::pbrt::load_from_str(&text(""), "t.pbrt").unwrap();
    assert_eq!(plain.hints.filter, Some(Filter::new(FilterKind::Gaussian)));
    let with = trayecto::scene::pbrt::load_from_str(
        &(text("\"float cropwindow\" [0.2 0.7 0 0.5]").replace(
            "WorldBegin",
            "PixelFilter \"mitchell\" \"float xradius\" 1.5 \"float B\" 0.5\nWorldBegin",
        )),
        "t.pbrt",
    )
    .unwrap();
    let f = with.hints.filter.unwrap();
    assert_eq!(f.kind, FilterKind::Mitchell);
    assert_eq!((f.radius, f.b, f.c), ([1.5, 2.0], 0.5, 1.0 / 3.0));
    assert!(
        !with.warnings.iter().any(|w| w.contains("PixelFilter")),
        "{:?}",
        with.warnings
    );
    let job = RenderJob {
        scene: "t.pbrt".into(),
        world: WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        settings: RenderSettings::default(),
        given: GivenSettings {
            width: false,
            height: false,
            spp: false,
            max_depth: false,
            filter: false,
            integrator: false,
            spectral: false,
            guiding: false,
        },
        outputs: vec![],
        split: Default::default(),
        crop: None,
        aovs: vec![],
        denoise: None,
    };
    let s = job.settings_for(&with);
    assert_eq!(s.filter, f);
    // pbrt files render spectrally unless the job says (`--rgb`), as pbrt-v4 does.
    assert!(s.path.spectral);
    assert_eq!(
        s.crop,
        Some(Crop {
            x0: 4,
            x1: 14,
            y0: 0,
            y1: 5
        })
    );
    // The command line wins over the file.
    let cli = RenderJob {
        given: GivenSettings {
            filter: true,
            spectral: true,
            ..job.given
        },
        crop: Some(CropSpec::Pixels([0, 20, 0, 10])),
        ..job.clone()
    };
    let s = cli.settings_for(&with);
    assert_eq!(s.filter, Filter::default());
    assert!(
        !s.path.spectral,
        "an explicit RGB wins over the file's spectral default"
    );
    assert_eq!(s.crop, None, "a crop of the whole image is no crop");
    // An unsupported filter is a warning naming it.
    let sinc = trayecto::scene::pbrt::load_from_str(
        &text("").replace("WorldBegin", "PixelFilter \"sinc\"\nWorldBegin"),
        "t.pbrt",
    )
    .unwrap();
    assert!(
        sinc.warnings
            .iter()
            .any(|w| w.contains("PixelFilter \"sinc\""))
    );
    // A bad parameter is an error naming the directive.
    let bad = trayecto::scene::pbrt::load_from_str(
        &text("").replace(
            "WorldBegin",
            "PixelFilter \"gaussian\" \"float sigma\" -1\nWorldBegin",
        ),
        "t.pbrt",
    );
    assert!(format!("{:?}", bad.err()).contains("PixelFilter"));
}

/// The whole pipeline writes a crop-sized image, and the CLI's crop options work end to end.
#[test]
fn pipeline_writes_only_the_window() {
    let dir = std::env::temp_dir().join(format!("trayecto-crop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("crop.exr");
    let job = RenderJob {
        scene: "cornell".into(),
        world: WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        settings: settings(32, 32, 2),
        given: GivenSettings::ALL,
        outputs: vec![OutputSpec {
            path: out.clone(),
            exposure: 1.0,
            tonemap: Default::default(),
        }],
        split: Default::default(),
        crop: Some(CropSpec::Fractions([0.5, 1.0, 0.25, 0.5])),
        aovs: vec![],
        denoise: None,
    };
    let report = job.run(&Silent, &AtomicBool::new(false)).unwrap();
    assert_eq!(report.settings.crop.unwrap().width(), 16);
    let img = trayecto::film::output::read_exr(&out).expect("the written crop reads back");
    // The same window of the full render, through the same pipeline.
    let full_out = dir.join("full.exr");
    let full = RenderJob {
        outputs: vec![OutputSpec {
            path: full_out.clone(),
            exposure: 1.0,
            tonemap: Default::default(),
        }],
        crop: None,
        ..job.clone()
    };
    full.run(&Silent, &AtomicBool::new(false)).unwrap();
    let full = trayecto::film::output::read_exr(&full_out).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!((img.width, img.height), (16, 8));
    for y in 0..8 {
        for x in 0..16 {
            assert_eq!(img.get(x, y), full.get(x + 16, y + 8));
        }
    }
}

/// An adaptive render writes its per-pixel sample counts and variances as the `samples` and
/// `variance` layers of its EXR (channels `samples.Y`, `variance.Y`), beside the beauty R, G, B;
/// the counts are those of the film (between 16 and the cap, not all equal).
#[test]
fn adaptive_render_writes_sample_and_variance_layers() {
    let dir = std::env::temp_dir().join(format!("trayecto-adaptive-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("a.exr");
    let job = RenderJob {
        scene: "cornell".into(),
        world: WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        settings: adaptive_settings(
            2,
            cornell_threshold(
                &World::build(
                    trayecto::scene::load("cornell").unwrap(),
                    &WorldOptions {
                        default_light: Some(trayecto::scene::DefaultLight::Uniform),
                        ..WorldOptions::default()
                    },
                )
                .unwrap(),
            ),
        ),
        given: GivenSettings::ALL,
        outputs: vec![OutputSpec {
            path: out.clone(),
            exposure: 1.0,
            tonemap: Default::default(),
        }],
        split: Default::default(),
        crop: None,
        aovs: vec![],
        denoise: None,
    };
    let report = job.run(&Silent, &AtomicBool::new(false)).unwrap();
    let (w, h, channels) = trayecto::film::output::read_exr_channels(&out).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!((w, h), (24, 24));
    let get = |name: &str| {
        channels
            .iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no channel {name}"))
            .1
            .clone()
    };
    let counts = get("samples.Y");
    let variance = get("variance.Y");
    let min = counts.iter().cloned().fold(f32::INFINITY, f32::min);
    let max = counts.iter().cloned().fold(0.0, f32::max);
    assert!(min >= 16.0 && max <= 128.0 && min < max, "{min}..{max}");
    let mean = counts.iter().sum::<f32>() as f64 / counts.len() as f64;
    assert!((mean - report.mean_samples).abs() < 1e-3);
    assert!(variance.iter().any(|v| *v > 0.0));
    // Pixel for pixel, the layers hold the film of the same render redone in memory: its
    // counts and its per-pixel variance (a transposed layer or another variance formula fails).
    let world = World::build(
        trayecto::scene::load("cornell").unwrap(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let r = render_range(
        &world,
        &job.settings,
        trayecto::render::RangeStart {
            samples: 0..job.settings.spp,
            resume: None,
        },
        &NoObserver,
        &AtomicBool::new(false),
    )
    .unwrap();
    for i in 0..counts.len() {
        assert_eq!(
            counts[i],
            r.film.counts()[i] as f32,
            "samples.Y of pixel {i}"
        );
        assert_eq!(
            variance[i].to_bits(),
            (r.film.variance(i) as f32).to_bits(),
            "variance.Y of pixel {i}"
        );
    }
}

/// **Benchmark, not a test** (ignored; it asserts nothing and takes minutes): adaptive vs uniform
/// sampling, samples needed for a set relative error on a scene with easy and hard regions.
/// Prints the table summarised in BENCHMARKS.md ("Tried, did not pay"):
///
///   ADAPTIVE_BENCH="scenes/mitsuba/glass.toml 48 1024" \
///     cargo test --test filters_adaptive -- --ignored --nocapture adaptive_benchmark
///
/// (scene, image size, reference spp, largest spp of the uniform ladder and adaptive cap). The error of an image is measured against an independent
/// reference (another seed) per pixel as |Y − Y_ref| / max(Y_ref, 0.01) (Y: luminance),
/// summarised by its mean and 95th percentile.
#[test]
#[ignore]
fn adaptive_benchmark() {
    use trayecto::film::{Image, luminance};
    let args = std::env::var("ADAPTIVE_BENCH")
        .unwrap_or_else(|_| "scenes/mitsuba/glass.toml 48 4096 1024".into());
    let a: Vec<&str> = args.split_whitespace().collect();
    let (scene_name, size, ref_spp) = (
        a[0].to_string(),
        a.get(1).and_then(|v| v.parse().ok()).unwrap_or(48u32),
        a.get(2).and_then(|v| v.parse().ok()).unwrap_or(4096u32),
    );
    let cap: u32 = a.get(3).and_then(|v| v.parse().ok()).unwrap_or(1024);
    let errors = |img: &Image, reference: &Image| {
        let mut e: Vec<f64> = img
            .data
            .iter()
            .zip(&reference.data)
            .map(|(p, r)| {
                let (yp, yr) = (luminance(*p) as f64, luminance(*r) as f64);
                (yp - yr).abs() / yr.abs().max(0.01)
            })
            .collect();
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        e.sort_by(f64::total_cmp);
        (mean, e[(e.len() as f64 * 0.95) as usize])
    };
    let scene = trayecto::scene::load(&scene_name).expect("scene loads");
    let world = World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .expect("world builds");
    let run = |s: &RenderSettings| {
        let t = std::time::Instant::now();
        let start = trayecto::render::RangeStart {
            samples: 0..s.spp,
            resume: None,
        };
        let r = render_range(&world, s, start, &NoObserver, &AtomicBool::new(false)).unwrap();
        let c = r.film.counts();
        let mean = c.iter().map(|&n| n as f64).sum::<f64>() / c.len() as f64;
        (r.film.to_image(), mean, t.elapsed().as_secs_f64())
    };
    let base = settings(size, size, 1);
    let (reference, _, t_ref) = run(&RenderSettings {
        spp: ref_spp,
        seed: 12345,
        ..base.clone()
    });
    println!(
        "scene {scene_name}, {size}x{size}, reference {ref_spp} spp (seed 12345, {t_ref:.1} s)"
    );
    println!("| mode | mean spp | mean rel. error | 95th pct rel. error | time (s) |");
    println!("|---|---|---|---|---|");
    for spp in (4..=cap.ilog2()).map(|k| 1u32 << k) {
        let (img, m_spp, t) = run(&RenderSettings {
            spp,
            ..base.clone()
        });
        let (m, p95) = errors(&img, &reference);
        println!("| uniform {spp} spp | {m_spp:.1} | {m:.4} | {p95:.4} | {t:.2} |");
    }
    for threshold in [0.1f32, 0.05, 0.03, 0.02] {
        let (img, m_spp, t) = run(&RenderSettings {
            spp: cap,
            noise_threshold: Some(threshold),
            ..base.clone()
        });
        let (m, p95) = errors(&img, &reference);
        println!("| adaptive {threshold} (cap {cap}) | {m_spp:.1} | {m:.4} | {p95:.4} | {t:.2} |");
    }
}
