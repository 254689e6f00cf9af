//! Issue #22: the image follows the scene camera's shape, and messages say their cause once.
//! Library-level checks (no rendering) plus the CLI's exact error text; each takes milliseconds.

use std::process::Command;
use trayecto::math::Vec3;
use trayecto::pipeline::{GivenSettings, RenderJob};
use trayecto::render::RenderSettings;
use trayecto::scene::{CameraDesc, Scene};
use trayecto::world::WorldOptions;

fn job(width: Option<u32>, height: Option<u32>) -> RenderJob {
    RenderJob {
        scene: "unused".into(),
        world: WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        settings: RenderSettings {
            width: width.unwrap_or(512),
            height: height.unwrap_or(512),
            ..RenderSettings::default()
        },
        given: GivenSettings {
            width: width.is_some(),
            height: height.is_some(),
            spp: false,
            max_depth: false,
            filter: false,
            integrator: false,
            spectral: false,
            guiding: false,
        },
        split: Default::default(),
        aovs: Vec::new(),
        denoise: None,
        outputs: vec![],
        crop: None,
    }
}

fn scene_with_aspect(aspect: Option<f32>) -> Scene {
    let mut c = CameraDesc::look_at("cam", Vec3::Z, Vec3::ZERO, Vec3::Y, 40.0);
    c.aspect = aspect;
    Scene {
        cameras: vec![c],
        ..Scene::default()
    }
}

fn size(j: &RenderJob, s: &Scene) -> (u32, u32, Option<String>) {
    let (st, note) = j.resolve(s);
    (st.width, st.height, note)
}

#[test]
fn size_follows_the_camera_aspect() {
    let s = scene_with_aspect(Some(2.0));
    // Nothing given: 512 high, width from the aspect, and a line saying so.
    let (w, h, note) = size(&job(None, None), &s);
    assert_eq!((w, h), (1024, 512));
    assert_eq!(
        note.as_deref(),
        Some(
            "image size 1024x512 from the camera's aspect ratio (give --width/--height to change it)"
        )
    );
    // One side given derives the other.
    assert_eq!(size(&job(Some(300), None), &s).0, 300);
    assert_eq!(size(&job(Some(300), None), &s).1, 150);
    assert_eq!(size(&job(None, Some(100)), &s).0, 200);
    // Both given and agreeing: no note.
    assert_eq!(size(&job(Some(400), Some(200)), &s).2, None);
    // Both given and disagreeing: the fit is explained.
    let (w, h, note) = size(&job(Some(512), Some(512)), &s);
    assert_eq!((w, h), (512, 512));
    assert_eq!(
        note.as_deref(),
        Some(
            "camera 'cam' has aspect ratio 2.000 but the image is 512x512 (1.000): the view is \
             fitted as Blender does (sensor fit auto), the camera's wider field of view spans \
             the image's width"
        )
    );
    // A camera without an aspect ratio: the square default, silently.
    let (w, h, note) = size(&job(None, None), &scene_with_aspect(None));
    assert_eq!((w, h, note), (512, 512, None));
}

#[test]
fn file_resolution_wins_over_camera_aspect() {
    let mut s = scene_with_aspect(Some(2.0));
    s.hints.width = Some(640);
    s.hints.height = Some(480);
    assert_eq!(size(&job(None, None), &s).0, 640);
    assert_eq!(size(&job(None, None), &s).1, 480);
    // --width alone keeps the file's 4:3.
    assert_eq!(size(&job(Some(320), None), &s).1, 240);
    assert_eq!(size(&job(None, Some(240)), &s).0, 320);
}

#[test]
fn toml_render_table_gives_the_resolution() {
    let toml = b"[render]\nwidth = 300\nheight = 200\nspp = 7\n";
    let s = trayecto::scene::toml_scene::load_from_bytes(toml, std::path::Path::new("."), "t.toml")
        .unwrap();
    assert_eq!(
        (s.hints.width, s.hints.height, s.hints.spp),
        (Some(300), Some(200), Some(7))
    );
    let e = trayecto::scene::toml_scene::load_from_bytes(
        b"[render]\nwidth = 0\n",
        std::path::Path::new("."),
        "t.toml",
    )
    .unwrap_err();
    assert_eq!(e.to_string(), "t.toml: [render] width must be at least 1");
}

/// A TOML scene's `[render] guiding` turns path guiding on for its renders unless the job says
/// otherwise (`--guiding`/`--no-guiding`, the web request's and the Python options' `guiding`).
#[test]
fn toml_render_table_turns_guiding_on_unless_the_job_says() {
    let load = |toml: &[u8]| {
        trayecto::scene::toml_scene::load_from_bytes(toml, std::path::Path::new("."), "t.toml")
            .unwrap()
    };
    let on = load(b"[render]\nguiding = true\n");
    let off = load(b"[render]\nguiding = false\n");
    let silent = load(b"[render]\nspp = 4\n");
    assert_eq!(
        (on.hints.guiding, off.hints.guiding, silent.hints.guiding),
        (Some(true), Some(false), None)
    );
    let mut j = job(None, None);
    assert!(j.settings_for(&on).guiding);
    assert!(!j.settings_for(&off).guiding);
    assert!(!j.settings_for(&silent).guiding);
    // Given by the job (`--no-guiding`; `--guiding` sets it true), the job's wins.
    j.given.guiding = true;
    assert!(!j.settings_for(&on).guiding);
    j.settings.guiding = true;
    assert!(j.settings_for(&off).guiding);
    assert!(j.settings_for(&silent).guiding);
    let e = trayecto::scene::toml_scene::load_from_bytes(
        b"[render]\nguiding = 1\n",
        std::path::Path::new("."),
        "t.toml",
    )
    .unwrap_err();
    assert!(e.to_string().contains("guiding"), "{e}");
}

#[test]
fn blender_sensor_fit() {
    let mut c = CameraDesc::look_at("c", Vec3::Z, Vec3::ZERO, Vec3::Y, 90.0);
    // tan(45°) = 1 vertically; with aspect 2 the horizontal half-width is 2.
    c.aspect = Some(2.0);
    let same = c.fitted_tan_half_v(2.0);
    assert!((same - 1.0).abs() < 1e-6, "{same}");
    // A square image: the horizontal 2 spans its width (the larger side, tie), so vertically 2.
    assert!((c.fitted_tan_half_v(1.0) - 2.0).abs() < 1e-6);
    // A 4:1 image: horizontal still 2, vertical 0.5.
    assert!((c.fitted_tan_half_v(4.0) - 0.5).abs() < 1e-6);
    // A tall camera (aspect 0.5): its larger side is vertical (tan 1); a 2:1 image puts it across.
    c.aspect = Some(0.5);
    assert!((c.fitted_tan_half_v(2.0) - 0.5).abs() < 1e-6);
    assert!((c.fitted_tan_half_v(0.5) - 1.0).abs() < 1e-6);
}

/// pbrt-v4's `fov` spans the shorter side of whatever film it renders: a pbrt file rendered at
/// another aspect ratio than its `Film` frames what pbrt-v4 would with a `Film` of that size
/// (`PerspectiveCamera`'s screen window), not Blender's fit.
#[test]
fn pbrt_fov_spans_the_shorter_side_at_any_resolution() {
    let text = |extra: &str| {
        format!(
            "Film \"rgb\" \"integer xresolution\" [ 160 ] \"integer yresolution\" [ 90 ]\n\
             Camera \"perspective\" \"float fov\" [ 40 ] {extra}\n\
             WorldBegin\n\
             Shape \"sphere\" \"float radius\" [ 1 ]\n"
        )
    };
    let s = trayecto::scene::pbrt::load_from_str(&text(""), "t.pbrt").unwrap();
    let c = &s.cameras[0];
    assert_eq!(c.fit, trayecto::scene::SensorFit::Shorter);
    let t = 20f32.to_radians().tan();
    for (aspect, want) in [
        (16.0 / 9.0, t),
        (4.0 / 3.0, t),
        (1.0, t),
        (0.75, t / 0.75),
        (0.5, t / 0.5),
    ] {
        let got = c.fitted_tan_half_v(aspect);
        assert!(
            (got - want).abs() < 1e-5 * want,
            "aspect {aspect}: {got} against {want}"
        );
    }
    // The console says which fit it used.
    let note = size(&job(Some(96), Some(72)), &s).2.unwrap();
    assert!(
        note.ends_with("as in pbrt-v4, the field of view spans the image's shorter side (height)"),
        "{note}"
    );
    // An explicit screen window is tied to the file's film: fitted as any camera.
    let s = trayecto::scene::pbrt::load_from_str(
        &text("\"float screenwindow\" [ -1 1 -0.5 0.5 ]"),
        "t.pbrt",
    )
    .unwrap();
    assert_eq!(s.cameras[0].fit, trayecto::scene::SensorFit::Auto);
}

fn trayecto(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_trayecto"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn missing_scene_says_it_once() {
    let (ok, err) = trayecto(&["render", "nonexist.gltf", "-q"]);
    assert!(!ok);
    assert_eq!(
        err,
        format!(
            "error: nonexist.gltf: no such file (scene files: {}; built-in scenes: {})\n",
            trayecto::scene::extension_list(false),
            trayecto::scene::builtin::NAMES.join(", ")
        )
    );
    let (ok, err) = trayecto(&["info", "nonexist.gltf"]);
    assert!(!ok);
    assert_eq!(err.matches("no such file").count(), 1, "{err}");
}

#[test]
fn unreadable_scene_and_output_say_it_once() {
    let dir = std::env::temp_dir().join(format!("trayecto-papercuts-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A folder named like a scene.
    let folder = dir.join("folder.gltf");
    std::fs::create_dir_all(&folder).unwrap();
    let (ok, err) = trayecto(&["render", folder.to_str().unwrap(), "-q"]);
    assert!(!ok);
    assert!(
        err.starts_with(&format!(
            "error: {}: is a folder; give a scene file inside it",
            folder.display()
        )),
        "{err}"
    );
    // An output folder that does not exist.
    let out = dir.join("nope/out.png");
    let (ok, err) = trayecto(&["render", "-o", out.to_str().unwrap(), "-q"]);
    assert!(!ok);
    assert_eq!(
        err,
        format!(
            "error: {}: the output folder does not exist\n",
            out.display()
        )
    );
    let _ = std::fs::remove_dir_all(&dir);
}
