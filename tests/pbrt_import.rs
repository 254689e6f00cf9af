//! The pbrt-v4 importer: the Bitterli scenes load, small feature scenes agree with pbrt-v4's own
//! renders (committed in tests/references/pbrt/, made by scripts/pbrt_references.sh), a pbrt
//! scene and its TOML twin render alike, the camera convention puts the red wall where pbrt-v4
//! does, and hostile input is a clean error.

mod common;

use std::path::{Path, PathBuf};

use trayecto::film::Image;
use trayecto::render::RenderSettings;
use trayecto::scene::{self, Scene};

fn repo(rel: &str) -> PathBuf {
    common::repo_dir().join(rel)
}

fn load(p: &Path) -> Scene {
    scene::load(p.to_str().unwrap()).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Renders at the file's own resolution, maximum depth and `spp` samples.
fn render(scene: &Scene, spp: u32) -> Image {
    let mut s = RenderSettings {
        width: scene.hints.width.unwrap(),
        height: scene.hints.height.unwrap(),
        spp,
        ..Default::default()
    };
    s.path.max_depth = scene.hints.max_depth.unwrap();
    common::render_scene(scene, &s)
}

fn read_exr(p: &Path) -> Image {
    trayecto::film::output::read_exr(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Mean of each block of a `n × n` grid (luminance-weighted RGB sum).
fn block_means(img: &Image, n: u32) -> Vec<f64> {
    let mut out = Vec::new();
    for by in 0..n {
        for bx in 0..n {
            let (x0, x1) = (bx * img.width / n, (bx + 1) * img.width / n);
            let (y0, y1) = (by * img.height / n, (by + 1) * img.height / n);
            let mut s = 0.0f64;
            for y in y0..y1 {
                for x in x0..x1 {
                    let p = img.data[(y * img.width + x) as usize];
                    s += (p.x + p.y + p.z) as f64;
                }
            }
            out.push(s / ((x1 - x0) * (y1 - y0)) as f64 / 3.0);
        }
    }
    out
}

/// (relative error of the image mean, largest relative block error on a 4 × 4 grid, with blocks
/// darker than 2 % of the mean compared in absolute terms against the mean).
fn compare(img: &Image, reference: &Image) -> (f64, f64) {
    assert_eq!((img.width, img.height), (reference.width, reference.height));
    let (a, b) = (block_means(img, 4), block_means(reference, 4));
    let ma: f64 = a.iter().sum::<f64>() / a.len() as f64;
    let mb: f64 = b.iter().sum::<f64>() / b.len() as f64;
    let mean_err = (ma - mb).abs() / mb;
    let block_err = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs() / y.max(0.02 * mb))
        .fold(0.0, f64::max);
    (mean_err, block_err)
}

#[test]
fn bitterli_scenes_load_with_their_settings() {
    // (scene, triangles at least, the file's resolution and samples)
    let cases: [(&str, usize, (u32, u32)); 5] = [
        ("cornell-box", 10, (64, 64)),
        ("veach-mis", 10, (1280, 720)),
        ("coffee", 1000, (800, 1000)),
        ("dining-room", 10_000, (960, 540)),
        ("volumetric-caustic", 10, (512, 512)),
    ];
    for (name, min_tris, (w, h)) in cases {
        let p = common::shared_scene(&format!("pbrt/{name}/scene-v4.pbrt"));
        let s = load(&p);
        assert!(
            s.triangle_count() >= min_tris,
            "{name}: {} triangles",
            s.triangle_count()
        );
        assert_eq!(
            (s.hints.width, s.hints.height),
            (Some(w), Some(h)),
            "{name}"
        );
        assert!(
            s.hints.spp.is_some() && s.hints.max_depth.is_some(),
            "{name}"
        );
        assert_eq!(s.cameras.len(), 1, "{name}");
        assert!(s.has_light(), "{name} has no light");
        // Every warning names a file and line (or the Film/Camera it concerns).
        for w in &s.warnings {
            assert!(
                w.contains(".pbrt") || w.contains(".ply"),
                "{name}: warning without a location: {w}"
            );
        }
    }
}

#[test]
fn camera_convention_puts_the_red_wall_where_pbrt_does() {
    let scene = load(&repo("scenes/pbrt/camera-convention.pbrt"));
    let img = render(&scene, 16);
    let reference = read_exr(&repo("tests/references/pbrt/camera-convention.exr"));
    // Red minus green in the left and right thirds of the image (the walls are there).
    let redness = |im: &Image, left: bool| {
        let mut s = 0.0f64;
        for y in 0..im.height {
            for x in 0..im.width / 3 {
                let x = if left { x } else { im.width - 1 - x };
                let p = im.data[(y * im.width + x) as usize];
                s += (p.x - p.y) as f64;
            }
        }
        s
    };
    // pbrt-v4's left-handed camera: world +x (the red wall) is on the image's right.
    assert!(redness(&reference, false) > 0.0 && redness(&reference, true) < 0.0);
    assert!(
        redness(&img, false) > 0.0 && redness(&img, true) < 0.0,
        "the red wall is not on the right"
    );
    // fov spans the shorter (vertical) axis of this 2:1 film, and the image matches pbrt's.
    let (mean_err, block_err) = compare(&img, &reference);
    eprintln!("camera-convention: mean {mean_err:.4}, worst 4x4 block {block_err:.4}");
    assert!(
        mean_err < 0.05 && block_err < 0.15,
        "mean {mean_err}, block {block_err}"
    );
}

#[test]
fn feature_scene_matches_pbrt_v4() {
    let scene = load(&repo("scenes/pbrt/features.pbrt"));
    let img = render(&scene, 64);
    let reference = read_exr(&repo("tests/references/pbrt/features.exr"));
    let (mean_err, block_err) = compare(&img, &reference);
    eprintln!("features: mean {mean_err:.4}, worst 4x4 block {block_err:.4}");
    assert!(
        mean_err < 0.05 && block_err < 0.15,
        "mean {mean_err}, block {block_err}"
    );
}

#[test]
fn cornell_box_agrees_with_its_tungsten_reference() {
    let scene = load(&common::shared_scene("pbrt/cornell-box/scene-v4.pbrt"));
    let mut s = RenderSettings {
        width: 64,
        height: 64,
        spp: 64,
        ..Default::default()
    };
    s.path.max_depth = scene.hints.max_depth.unwrap();
    let img = common::render_scene(&scene, &s);
    let full = read_exr(&common::shared_scene("pbrt/cornell-box/TungstenRender.exr"));
    // Box-filter the 1024² reference down to 64².
    let k = full.width / 64;
    let mut data = Vec::new();
    for y in 0..64 {
        for x in 0..64 {
            let mut acc = trayecto::math::Vec3::ZERO;
            for j in 0..k {
                for i in 0..k {
                    acc += full.data[((y * k + j) * full.width + x * k + i) as usize];
                }
            }
            data.push(acc / (k * k) as f32);
        }
    }
    let reference = Image {
        width: 64,
        height: 64,
        data,
    };
    let (mean_err, block_err) = compare(&img, &reference);
    eprintln!("cornell-box vs Tungsten: mean {mean_err:.4}, worst 4x4 block {block_err:.4}");
    // The file limits paths to 4 bounces (Tungsten's render used more), which costs ~3 % of the
    // mean; the rest is noise at 64 spp.
    assert!(
        mean_err < 0.06 && block_err < 0.15,
        "mean {mean_err}, block {block_err}"
    );
}

#[test]
fn pbrt_scene_and_its_toml_twin_render_alike() {
    let a = load(&repo("scenes/pbrt/twin/box.pbrt"));
    let b = load(&repo("scenes/pbrt/twin/box.toml"));
    let ia = render(&a, 32);
    let mut s = RenderSettings {
        width: ia.width,
        height: ia.height,
        spp: 32,
        ..Default::default()
    };
    s.path.max_depth = 5;
    let ib = common::render_scene(&b, &s);
    // Not a pair of black images: lit, with the red wall on the left (Trayecto's right-handed
    // view, which the pbrt twin reproduces with `Scale -1 1 1`).
    assert!(ia.mean().x > 0.05, "{}", ia.mean());
    let left_red: f32 = (0..ia.height)
        .flat_map(|y| (0..ia.width / 3).map(move |x| (x, y)))
        .map(|(x, y)| {
            let p = ia.data[(y * ia.width + x) as usize];
            p.x - p.y
        })
        .sum();
    assert!(left_red > 0.0);
    let (mean_err, block_err) = compare(&ia, &ib);
    eprintln!("twin: mean {mean_err:.4}, worst 4x4 block {block_err:.4}");
    assert!(
        mean_err < 0.02 && block_err < 0.06,
        "mean {mean_err}, block {block_err}"
    );
}

fn err_of(text: &str) -> String {
    match scene::pbrt::load_from_str(text, "hostile.pbrt") {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn hostile_text_is_a_clean_error_naming_file_and_line() {
    let e = err_of("WorldBegin\nShape \"sphere\" \"float radius\" [ 1 ");
    assert!(
        e.contains("hostile.pbrt:2") && e.contains("unterminated"),
        "{e}"
    );
    let e = err_of("WorldBegin\n\nShape \"sphere");
    assert!(
        e.contains("hostile.pbrt:3") && e.contains("unterminated string"),
        "{e}"
    );
    let e = err_of("WorldBegin\nShape \"sphere\" \"float radius\" [ nan ]");
    assert!(e.contains("hostile.pbrt:2"), "{e}");
    let e = err_of(
        "WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 1000000000]",
    );
    assert!(
        e.contains("1000000000") && e.contains("hostile.pbrt:2"),
        "{e}"
    );
    let e = err_of("Translate 1 2");
    assert!(e.contains("hostile.pbrt:1"), "{e}");
    let e = err_of("Frobnicate 1");
    assert!(e.contains("unknown directive"), "{e}");
    let e = err_of("AttributeEnd");
    assert!(e.contains("without a matching"), "{e}");
    let e = err_of("Shape \"sphere\" \"float radius\" [ 1e999 ]");
    assert!(e.contains("hostile.pbrt:1"), "{e}");
    // 10⁹ subdivision levels are capped, not attempted.
    let s = scene::pbrt::load_from_str(
        "WorldBegin\nShape \"loopsubdiv\" \"integer levels\" 1000000000 \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]",
        "levels.pbrt",
    )
    .unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("capped")));
}

#[test]
fn includes_are_confined_and_cycles_detected() {
    let dir = std::env::temp_dir().join(format!("trayecto-pbrt-include-{}", std::process::id()));
    let sub = dir.join("scene");
    std::fs::create_dir_all(&sub).unwrap();
    std::fs::write(dir.join("secret.pbrt"), "WorldBegin\n").unwrap();
    std::fs::write(sub.join("a.pbrt"), "WorldBegin\nInclude \"b.pbrt\"\n").unwrap();
    std::fs::write(sub.join("b.pbrt"), "Include \"a.pbrt\"\n").unwrap();
    std::fs::write(sub.join("up.pbrt"), "Include \"../secret.pbrt\"\n").unwrap();
    std::fs::write(
        sub.join("abs.pbrt"),
        format!("Include \"{}\"\n", dir.join("secret.pbrt").display()),
    )
    .unwrap();
    std::fs::write(sub.join("missing.pbrt"), "Include \"nope.pbrt\"\n").unwrap();
    let e = scene::load(sub.join("a.pbrt").to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("cycle") && e.contains("b.pbrt:1"), "{e}");
    let e = scene::load(sub.join("up.pbrt").to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("..") && e.contains("up.pbrt:1"), "{e}");
    let e = scene::load(sub.join("abs.pbrt").to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("absolute"), "{e}");
    let e = scene::load(sub.join("missing.pbrt").to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("nope.pbrt"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn unsupported_features_are_warnings_with_locations() {
    let s = scene::pbrt::load_from_str(
        "Film \"rgb\" \"float iso\" 100\nCamera \"perspective\"\nWorldBegin\nMaterial \"hair\"\nLightSource \"goniometric\"\nShape \"sphere\" \"float bogus\" 1\n",
        "w.pbrt",
    )
    .unwrap();
    let has = |needle: &str| s.warnings.iter().any(|w| w.contains(needle));
    assert!(has("w.pbrt:1") && has("\"float iso\""), "{:?}", s.warnings);
    assert!(has("w.pbrt:4") && has("hair"), "{:?}", s.warnings);
    assert!(has("w.pbrt:5") && has("goniometric"), "{:?}", s.warnings);
    assert!(
        has("w.pbrt:6") && has("\"float bogus\""),
        "{:?}",
        s.warnings
    );
}
