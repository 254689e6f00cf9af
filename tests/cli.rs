//! The `trayecto` binary: renders with its defaults, writes every output format, and refuses bad
//! input with a one-line cause and a non-zero exit code before doing any work.

use std::path::PathBuf;
use std::process::{Command, Output};

fn trayecto(args: &[&str], dir: &std::path::Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_trayecto"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("binary runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn no_arguments_renders_the_cornell_box_to_render_png() {
    // The defaults (512×512, 64 spp) take a few seconds; check the no-argument path with the
    // default scene and output name but a smaller size through the `render` subcommand too.
    let dir = temp_dir("default");
    let o = trayecto(&["--width", "32", "--height", "24", "--spp", "2"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(dir.join("render.png")).expect("render.png written");
    assert_eq!((img.width(), img.height()), (32, 24));
    let log = stderr(&o);
    for phase in [
        "scene loaded",
        "acceleration structure built",
        "render",
        "written",
        "Mrays/s",
        "cornell",
    ] {
        assert!(log.contains(phase), "log lacks '{phase}':\n{log}");
    }
}

#[test]
fn every_output_format_is_written() {
    let dir = temp_dir("formats");
    for ext in ["png", "ppm", "exr", "hdr"] {
        let out = format!("out.{ext}");
        let o = trayecto(
            &[
                "render", "cornell", "-o", &out, "--width", "16", "--height", "16", "--spp", "1",
                "-q",
            ],
            &dir,
        );
        assert!(o.status.success(), "{ext}: {}", stderr(&o));
        assert!(dir.join(&out).metadata().unwrap().len() > 0);
    }
    let ppm = std::fs::read_to_string(dir.join("out.ppm")).unwrap();
    assert!(ppm.starts_with("P3\n16 16\n255\n"));
    let exr = trayecto::film::output::read_exr(&dir.join("out.exr")).unwrap();
    assert_eq!((exr.width, exr.height), (16, 16));
}

#[test]
fn bad_options_fail_cleanly_before_rendering() {
    let dir = temp_dir("bad");
    let cases: &[(&[&str], &str)] = &[
        (&["--width", "0"], "resolution"),
        (&["--height", "1000000"], "resolution"),
        (&["--spp", "0"], "samples per pixel"),
        (&["--exposure", "-1"], "exposure"),
        (&["--exposure", "NaN"], "exposure"),
        (&["--secondary", "0"], "secondary"),
        (&["--rr-scale", "0"], "Russian roulette scale"),
        (&["--rr-scale", "NaN"], "Russian roulette scale"),
        (&["-o", "image.bmp"], "unsupported output format"),
        (&["-o", "no/such/dir/x.png"], "output folder does not exist"),
        (&["render", "no-such-scene"], "unknown built-in scene"),
        (&["render", "missing.gltf"], "missing.gltf"),
        (&["--camera", "7"], "no camera '7'"),
        (&["--integrator", "bogus"], "bogus"),
    ];
    for (args, expect) in cases {
        let o = trayecto(args, &dir);
        assert!(!o.status.success(), "{args:?} should fail");
        let e = stderr(&o);
        assert!(e.contains(expect), "{args:?}: expected '{expect}' in: {e}");
        assert!(!e.contains("panicked"), "{args:?} panicked: {e}");
    }
    assert!(
        !dir.join("render.png").exists(),
        "nothing may be written on error"
    );
}

#[test]
fn info_describes_the_scene() {
    let dir = temp_dir("info");
    let o = trayecto(&["info", "cornell"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("primitives  8"), "{out}");
    assert!(out.contains("lights      1 (1 area)"), "{out}");
    assert!(out.contains("'light'"), "{out}");
}

fn render_to(dir: &std::path::Path, out: &str, extra: &[&str]) {
    let mut args = vec![
        "render", "cornell", "-o", out, "--width", "16", "--height", "12", "--spp", "2", "--seed",
        "5", "-q",
    ];
    args.extend_from_slice(extra);
    let o = trayecto(&args, dir);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
}

/// `--exposure` and `--tonemap` reach the 8-bit outputs, and only them: the same render (same
/// seed) written as EXR is the raw radiance L; the PNG and PPM must decode to
/// round(255 · tonemap(exposure · L)) in every pixel and channel (±1), the HDR to L itself.
#[test]
fn exposure_and_tonemap_shape_png_and_ppm_but_not_exr_and_hdr() {
    use trayecto::film::tonemap::Tonemap;
    let dir = temp_dir("exposure");
    render_to(&dir, "raw.exr", &[]);
    let raw = trayecto::film::output::read_exr(&dir.join("raw.exr")).unwrap();
    assert_eq!((raw.width, raw.height), (16, 12));
    let cases: &[(&str, f32, Tonemap)] = &[
        ("clamp", 1.0, Tonemap::Clamp),
        ("aces", 2.5, Tonemap::Aces),
        ("agx", 0.6, Tonemap::Agx),
        ("gamma2.2", 4.0, Tonemap::Gamma22),
    ];
    let mut pngs = Vec::new();
    for &(name, exposure, tonemap) in cases {
        let e = exposure.to_string();
        let flags = ["--exposure", e.as_str(), "--tonemap", name];
        for ext in ["png", "ppm", "exr", "hdr"] {
            render_to(&dir, &format!("{name}.{ext}"), &flags);
        }
        // EXR: bit-identical to the default render; HDR: the same within RGBE precision.
        let exr = trayecto::film::output::read_exr(&dir.join(format!("{name}.exr"))).unwrap();
        assert_eq!(exr, raw, "{name}: EXR changed with exposure/tone mapping");
        let hdr = image::open(dir.join(format!("{name}.hdr")))
            .unwrap()
            .to_rgb32f();
        let png = image::open(dir.join(format!("{name}.png")))
            .unwrap()
            .to_rgb8();
        let ppm: Vec<i32> = std::fs::read_to_string(dir.join(format!("{name}.ppm")))
            .unwrap()
            .split_whitespace()
            .skip(4)
            .map(|v| v.parse().unwrap())
            .collect();
        for y in 0..raw.height {
            for x in 0..raw.width {
                let l = raw.data[(y * raw.width + x) as usize];
                let want = tonemap.apply(l * exposure);
                for c in 0..3 {
                    let want = (want[c] * 255.0).round() as i32;
                    let got_png = png.get_pixel(x, y)[c] as i32;
                    let got_ppm = ppm[((y * raw.width + x) * 3) as usize + c];
                    assert!(
                        (got_png - want).abs() <= 1 && (got_ppm - want).abs() <= 1,
                        "{name} x{exposure} pixel ({x}, {y}) channel {c}: PNG {got_png}, PPM {got_ppm}, expected {want}"
                    );
                    let h = hdr.get_pixel(x, y)[c];
                    assert!(
                        (h - l[c]).abs() <= l.max_element() / 128.0,
                        "{name}: HDR pixel ({x}, {y}) {h} vs radiance {}",
                        l[c]
                    );
                }
            }
        }
        pngs.push(png);
    }
    // And the options visibly change the PNG: no two of these settings give the same image.
    for i in 0..pngs.len() {
        for j in i + 1..pngs.len() {
            assert_ne!(
                pngs[i], pngs[j],
                "{} and {} gave the same PNG",
                cases[i].0, cases[j].0
            );
        }
    }
}

/// `--env FILE` lights the scene with the map: a TOML scene without lights (which would get the
/// default white environment of radiance 1) shows a constant map of radiance (0.25, 0.5, 1) in its
/// background, and its white diffuse sphere (albedo 0.8, convex) reflects 0.8 × that.
#[test]
fn env_option_lights_the_scene_with_the_map() {
    let dir = temp_dir("env");
    // A 16×8 constant equirectangular map, written as Radiance HDR (exact in RGBE).
    let px = vec![image::Rgb([0.25f32, 0.5, 1.0]); 16 * 8];
    let f = std::fs::File::create(dir.join("sky.hdr")).unwrap();
    image::codecs::hdr::HdrEncoder::new(std::io::BufWriter::new(f))
        .encode(&px, 16, 8)
        .unwrap();
    std::fs::write(
        dir.join("ball.toml"),
        r#"
[[camera]]
eye = [0.0, 0.0, 5.0]
target = [0.0, 0.0, 0.0]
fov = 40.0

[[material]]
name = "white"
base_color = [0.8, 0.8, 0.8]

[[object]]
name = "ball"
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "white"
"#,
    )
    .unwrap();
    let render = |out: &str, extra: &[&str]| {
        let mut args = vec![
            "render",
            "ball.toml",
            "-o",
            out,
            "--width",
            "24",
            "--height",
            "24",
            "--spp",
            "64",
            "-q",
        ];
        args.extend_from_slice(extra);
        let o = trayecto(&args, &dir);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        trayecto::film::output::read_exr(&dir.join(out)).unwrap()
    };
    let lit = render("lit.exr", &["--env", "sky.hdr"]);
    let plain = render("plain.exr", &["--default-light", "uniform"]);
    let sky = trayecto::math::Vec3::new(0.25, 0.5, 1.0);
    let close = |a: trayecto::math::Vec3, b: trayecto::math::Vec3, tol: f32| {
        ((a - b) / b).abs().max_element() < tol
    };
    // Corner: the background.
    assert!(
        close(lit.get(0, 0), sky, 1e-3),
        "background {}",
        lit.get(0, 0)
    );
    assert!(
        close(plain.get(0, 0), trayecto::math::Vec3::ONE, 1e-3),
        "default background {}",
        plain.get(0, 0)
    );
    // Centre 4×4: the sphere, 0.8 × the environment (to 3 %: noise of 64 spp × 16 pixels).
    let mut centre = trayecto::math::Vec3::ZERO;
    for y in 10..14 {
        for x in 10..14 {
            centre += lit.get(x, y) / 16.0;
        }
    }
    assert!(close(centre, sky * 0.8, 0.03), "sphere {centre}");
}

/// pbrt files render spectrally by default, as pbrt-v4 renders every file, and the plan's log
/// line says so and why; `--rgb` opts out, other formats stay RGB, and an integrator without a
/// spectral path falls back to RGB with a line saying so, where an explicit `--spectral` is
/// refused. The default is `--spectral`'s image byte for byte, and `--rgb` another image.
#[test]
fn pbrt_files_render_spectrally_by_default_and_the_log_says_why() {
    let dir = temp_dir("colour-mode");
    let metals = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pbrt/metals.pbrt");
    let run = |scene: &str, out: &str, extra: &[&str]| {
        let mut args = vec![
            "render", scene, "-o", out, "--width", "16", "--height", "4", "--spp", "2",
        ];
        args.extend_from_slice(extra);
        trayecto(&args, &dir)
    };
    let ok = |o: Output| {
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o) + &String::from_utf8_lossy(&o.stdout)
    };
    let log = ok(run(metals, "default.exr", &[]));
    assert!(
        log.contains("spectral (3 wavelengths per sample; pbrt file; --rgb for RGB)"),
        "{log}"
    );
    ok(run(metals, "spectral.exr", &["--spectral"]));
    let log = ok(run(metals, "rgb.exr", &["--rgb"]));
    assert!(log.contains(", RGB (--rgb)"), "{log}");
    let read = |f: &str| std::fs::read(dir.join(f)).unwrap();
    assert_eq!(read("default.exr"), read("spectral.exr"));
    assert_ne!(read("default.exr"), read("rgb.exr"));
    let log = ok(run(metals, "whitted.exr", &["--integrator", "whitted"]));
    assert!(
        log.contains("the whitted has no spectral path yet: rendering RGB"),
        "{log}"
    );
    let o = run(metals, "x.exr", &["--spectral", "--integrator", "whitted"]);
    assert!(
        !o.status.success() && stderr(&o).contains("--spectral"),
        "{}",
        stderr(&o)
    );
    let o = run(metals, "x.exr", &["--spectral", "--rgb"]);
    assert!(!o.status.success(), "{}", stderr(&o));
    let log = ok(run("cornell", "cornell.exr", &[]));
    assert!(log.contains("threads, RGB\n"), "{log}");
}

/// A TOML scene's `[render] guiding = true` guides the command line's render as `--guiding`
/// does (the same image, byte for byte), `--no-guiding` turns it off (the unguided image), and
/// `--guiding --no-guiding` is refused.
#[test]
fn a_toml_scene_can_turn_guiding_on() {
    let dir = temp_dir("toml-guiding");
    let room = "[[camera]]\neye = [0.0, 1.0, 3.0]\ntarget = [0.0, 0.5, 0.0]\n\
        [[material]]\nname = \"grey\"\nbase_color = [0.7, 0.7, 0.7]\n\
        [[object]]\ntype = \"box\"\nmin = [-1.0, 0.0, -1.0]\nmax = [1.0, 0.2, 1.0]\nmaterial = \"grey\"\n\
        [[object]]\ntype = \"sphere\"\ncenter = [0.0, 0.6, 0.0]\nradius = 0.4\nmaterial = \"grey\"\n";
    std::fs::write(dir.join("plain.toml"), room).unwrap();
    std::fs::write(
        dir.join("guided.toml"),
        format!("{room}[render]\nguiding = true\n"),
    )
    .unwrap();
    let render = |scene: &str, out: &str, extra: &[&str]| {
        let mut args = vec![
            "render", scene, "--width", "24", "--height", "16", "--spp", "16", "--quiet", "-o", out,
        ];
        args.extend_from_slice(extra);
        let o = trayecto(&args, &dir);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(dir.join(out)).unwrap()
    };
    let by_file = render("guided.toml", "by-file.exr", &[]);
    let by_flag = render("plain.toml", "by-flag.exr", &["--guiding"]);
    let plain = render("plain.toml", "plain.exr", &[]);
    let turned_off = render("guided.toml", "off.exr", &["--no-guiding"]);
    assert!(by_file == by_flag, "the file's guiding is not --guiding");
    assert!(
        turned_off == plain,
        "--no-guiding did not turn the file's guiding off"
    );
    assert!(by_file != plain, "guiding changed nothing");
    let o = trayecto(
        &[
            "render",
            "plain.toml",
            "--guiding",
            "--no-guiding",
            "-o",
            "x.exr",
        ],
        &dir,
    );
    assert!(!o.status.success());
}
