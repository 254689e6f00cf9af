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
        (&["--threads", "0"], "threads"),
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
