//! Environment rotation (`--env-rotation`, TOML `rotation`, the server's `env_rotation`) and the
//! camera override (`--camera-from`, the viewport's `camera`).
//!
//! A map turned by θ about +y, seen from a camera, is the unturned map seen from that camera
//! turned by −θ about +y (the scene, a sphere on the axis, is unchanged by the turn): the light
//! that arrives along world direction ω comes from map direction R⁻¹ω in both.

mod common;

use trayecto::camera::CameraSpec;
use trayecto::film::Image;
use trayecto::math::{Mat3, Vec3};
use trayecto::render::RenderSettings;
use trayecto::scene::Scene;
use trayecto::world::{World, WorldOptions};

fn sphere_scene() -> Scene {
    let dir = std::env::temp_dir().join(format!("trayecto-envrot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("sphere.toml");
    std::fs::write(
        &path,
        r#"
default_light = "off"
[[material]]
name = "grey"
model = "diffuse"
base_color = [0.6, 0.6, 0.6]
[[object]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "grey"
"#,
    )
    .unwrap();
    let scene = trayecto::scene::load_file(&path).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    scene
}

fn render(rotation: f32, eye: Vec3) -> Image {
    let options = WorldOptions {
        env: Some(common::shared_scene("hdr/studio_small_03_1k.hdr")),
        env_rotation: rotation,
        camera_override: Some(CameraSpec {
            eye,
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov: 60.0,
        }),
        ..WorldOptions::default()
    };
    let world = World::build(sphere_scene(), &options).unwrap();
    let settings = RenderSettings {
        width: 48,
        height: 32,
        spp: 16,
        threads: None,
        ..RenderSettings::default()
    };
    common::render_world(&world, &settings)
}

/// Mean absolute difference over the mean value.
fn rel_diff(a: &Image, b: &Image) -> f64 {
    let (mut d, mut m) = (0.0f64, 0.0f64);
    for (p, q) in a.data.iter().zip(&b.data) {
        d += (*p - *q).abs().element_sum() as f64;
        m += p.element_sum() as f64;
    }
    d / m
}

#[test]
fn a_turned_map_equals_the_turned_back_camera() {
    let eye = Vec3::new(0.0, 0.8, 4.0);
    for degrees in [90.0f32, -37.5] {
        let turned = render(degrees, eye);
        let back = Mat3::from_rotation_y(-degrees.to_radians()) * eye;
        let equivalent = render(0.0, back);
        let unturned = render(0.0, eye);
        let same = rel_diff(&turned, &equivalent);
        let different = rel_diff(&turned, &unturned);
        eprintln!("{degrees}°: turned vs camera turned back {same:.4}, vs unturned {different:.4}");
        // Only rounding in the ray directions separates the two (the same samples are drawn).
        assert!(same < 0.01, "{degrees}°: {same}");
        assert!(
            different > 0.1,
            "{degrees}°: the rotation changed little ({different})"
        );
    }
}

/// A TOML scene's own camera given back through `--camera-from` renders the same image,
/// bit for bit (the same look-at numbers build the same matrix).
#[test]
fn camera_from_a_toml_scene_gives_its_camera() {
    let dir = std::env::temp_dir().join(format!("trayecto-camfrom-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("s.toml");
    std::fs::write(
        &path,
        r#"
[[camera]]
eye = [0.5, 1.5, 3.0]
target = [0.0, 0.25, 0.0]
fov = 45.0
[[material]]
name = "grey"
model = "diffuse"
base_color = [0.6, 0.6, 0.6]
[[object]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "grey"
[[object]]
type = "box"
min = [0.8, -1.0, -0.5]
max = [1.6, 0.2, 0.5]
material = "grey"
"#,
    )
    .unwrap();
    let spec = trayecto::pipeline::camera_from_file(&path).unwrap();
    assert_eq!(spec.eye, Vec3::new(0.5, 1.5, 3.0));
    assert_eq!(spec.fov, 45.0);
    let settings = RenderSettings {
        width: 24,
        height: 16,
        spp: 2,
        ..RenderSettings::default()
    };
    let scene = trayecto::scene::load_file(&path).unwrap();
    let own = common::render_scene(&scene, &settings);
    let build = |c: CameraSpec| {
        let o = WorldOptions {
            camera_override: Some(c),
            ..WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..WorldOptions::default()
            }
        };
        common::render_world(&World::build(scene.clone(), &o).unwrap(), &settings)
    };
    assert_eq!(build(spec).data, own.data);
    let moved = CameraSpec {
        eye: Vec3::new(-2.0, 1.0, 2.0),
        ..spec
    };
    assert_ne!(build(moved).data, own.data);
    // A scene file without a camera, and a broken camera, are clear errors naming the file.
    std::fs::write(dir.join("none.toml"), "name = \"x\"\n").unwrap();
    let e = trayecto::pipeline::camera_from_file(&dir.join("none.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("none.toml") && e.contains("camera"), "{e}");
    // An invalid override is refused when the world is built, not rendered as NaN.
    let o = WorldOptions {
        camera_override: Some(CameraSpec {
            fov: f32::NAN,
            ..spec
        }),
        ..WorldOptions::default()
    };
    assert!(World::build(scene.clone(), &o).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}
