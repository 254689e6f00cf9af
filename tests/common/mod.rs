//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod stats;

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use trayecto::film::Image;
use trayecto::material::Material;
use trayecto::math::{Mat4, Vec3};
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene::{Scene, Shape};
use trayecto::world::{World, WorldOptions};

/// Adds a grey diffuse floor named "floor": the square of side `2·half` at y = 0 around the
/// origin, facing +y (e1 × e2 points up).
pub fn add_floor(s: &mut Scene, half: f32, albedo: f32) {
    let floor = s.add_material(Material::diffuse("floor", Vec3::splat(albedo)));
    s.add_object(
        "floor",
        Shape::Quad {
            corner: Vec3::new(-half, 0.0, half),
            e1: Vec3::new(2.0 * half, 0.0, 0.0),
            e2: Vec3::new(0.0, 0.0, -2.0 * half),
        },
        Mat4::IDENTITY,
        floor,
    );
}

/// A quad mesh of the four `corners` in order, as the two triangles (0, 1, 2) and (0, 2, 3) (its
/// front is (c1 − c0) × (c2 − c0)); no normals, tangents, uvs or colours.
pub fn quad_mesh(name: &str, corners: [Vec3; 4]) -> trayecto::scene::Mesh {
    trayecto::scene::Mesh {
        name: name.into(),
        positions: corners.to_vec(),
        indices: vec![[0, 1, 2], [0, 2, 3]],
        normals: None,
        tangents: None,
        uv0: None,
        uv1: None,
        colors: None,
    }
}

/// Adds the motion-blur tests' card to `s`: a 0.4 × 0.6 quad in the z = 0 plane centred on the
/// origin (two triangles, no normals or uvs) and a blue diffuse material; returns (mesh, material).
pub fn add_blue_card(s: &mut Scene) -> (trayecto::scene::MeshId, trayecto::scene::MaterialId) {
    let blue = s.add_material(Material::diffuse("blue", Vec3::new(0.1, 0.2, 0.9)));
    let card = s.add_mesh(quad_mesh(
        "card",
        [
            Vec3::new(-0.2, -0.3, 0.0),
            Vec3::new(0.2, -0.3, 0.0),
            Vec3::new(0.2, 0.3, 0.0),
            Vec3::new(-0.2, 0.3, 0.0),
        ],
    ));
    (card, blue)
}

/// Render settings as a pbrt file gives them: its film size, pixel filter and maximum depth, at
/// `spp` samples (RGB; the loader's spectral choice is left to the caller).
pub fn file_settings(scene: &Scene, spp: u32) -> RenderSettings {
    let mut s = RenderSettings {
        width: scene
            .hints
            .width
            .expect("the pbrt loader sets the film size"),
        height: scene
            .hints
            .height
            .expect("the pbrt loader sets the film size"),
        spp,
        filter: scene
            .hints
            .filter
            .expect("the pbrt loader always sets the filter"),
        ..Default::default()
    };
    s.path.max_depth = scene
        .hints
        .max_depth
        .expect("the pbrt loader sets maxdepth");
    s
}

/// Renders `scene` in-process and returns the linear image.
pub fn render_scene(scene: &Scene, settings: &RenderSettings) -> Image {
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            // The scene's own choice, else the uniform white sky these tests were written for.
            default_light: scene
                .default_light
                .or(Some(trayecto::scene::DefaultLight::Uniform)),
            ..WorldOptions::default()
        },
    )
    .expect("scene builds");
    render_world(&world, settings)
}

pub fn render_world(world: &World, settings: &RenderSettings) -> Image {
    render(world, settings, &NoObserver, &AtomicBool::new(false))
        .expect("render succeeds")
        .image
}

/// The repository's own test data.
pub fn repo_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The shared folder that holds `scenes/`: `$TRAYECTO_SHARED` if set, else the first ancestor of
/// the crate root with a `shared/scenes` inside (`/work/shared` beside `/work/main`; `../shared`
/// beside CI's clone). Panics (a test failure, never a skip) if it cannot be found.
pub fn shared_dir() -> PathBuf {
    if let Ok(dir) = std::env::var("TRAYECTO_SHARED") {
        let p = PathBuf::from(dir);
        assert!(
            p.join("scenes").is_dir(),
            "TRAYECTO_SHARED={} has no scenes/ folder",
            p.display()
        );
        return p;
    }
    let mut dir = repo_dir();
    loop {
        let candidate = dir.join("shared");
        if candidate.join("scenes").is_dir() {
            return candidate;
        }
        if !dir.pop() {
            panic!(
                "no shared/scenes folder above {} (set TRAYECTO_SHARED)",
                repo_dir().display()
            );
        }
    }
}

/// A file under `shared/scenes`, which must exist.
pub fn shared_scene(rel: &str) -> PathBuf {
    let p = shared_dir().join("scenes").join(rel);
    assert!(p.is_file(), "missing shared test scene {}", p.display());
    p
}

/// A file under `shared/scenes/`, which must exist (same as [`shared_scene`]).
pub fn scene_file(rel: &str) -> PathBuf {
    shared_scene(rel)
}

/// The float bits of every pixel of the EXR `out` (R, G, B in turn), to compare renders bit for
/// bit; a black image is refused, since two black images agreeing proves nothing (`what` names
/// the render in the message).
pub fn exr_bits(out: &std::path::Path, what: &str) -> Vec<u32> {
    let img = trayecto::film::output::read_exr(out).unwrap();
    assert!(
        img.data.iter().any(|p| p.max_element() > 0.0),
        "{what}: a black image proves nothing"
    );
    img.data
        .iter()
        .flat_map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
        .collect()
}

/// Root-mean-square difference over all channels.
pub fn rmse(a: &Image, b: &Image) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let mut s = 0.0f64;
    for (p, q) in a.data.iter().zip(&b.data) {
        let d = *p - *q;
        s += (d.x as f64).powi(2) + (d.y as f64).powi(2) + (d.z as f64).powi(2);
    }
    (s / (3 * a.data.len()) as f64).sqrt()
}

/// Asserts that each channel mean of `img` is within `rel` of `reference`'s.
pub fn assert_means_close(img: &Image, reference: &Image, rel: f32, what: &str) {
    let (m, r) = (img.mean(), reference.mean());
    for c in 0..3 {
        let err = (m[c] - r[c]).abs() / r[c].abs().max(1e-6);
        assert!(
            err <= rel,
            "{what}: channel {c} mean {} vs reference {} (relative error {err:.4} > {rel})",
            m[c],
            r[c]
        );
    }
}

/// Fraction of each pixel covered by geometry: the ray caster's depth view (0 where a ray misses)
/// at 4 × 4 sub-pixels, one ray each. `base` supplies the seed and sampler; its size, sample
/// count and integrator are replaced.
pub fn coverage(world: &World, width: u32, height: u32, base: &RenderSettings) -> Vec<f32> {
    use trayecto::integrator::{Aov, IntegratorKind, ShadingModel};
    const K: u32 = 4;
    let settings = RenderSettings {
        width: width * K,
        height: height * K,
        spp: 1,
        integrator: IntegratorKind::Raycast {
            aov: Aov::Depth,
            shading: ShadingModel::Pbr,
        },
        ..base.clone()
    };
    let depth = render_world(world, &settings);
    let mut hits = vec![0u32; (width * height) as usize];
    for y in 0..height * K {
        for x in 0..width * K {
            if depth.get(x, y).x > 0.0 {
                hits[((y / K) * width + x / K) as usize] += 1;
            }
        }
    }
    hits.into_iter()
        .map(|n| n as f32 / (K * K) as f32)
        .collect()
}

/// Mean of each block of an `n × n` grid of `img`, the mean of the three channels per pixel.
pub fn block_means(img: &Image, n: u32) -> Vec<f64> {
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

/// Per-channel means of the `b` × `b`-pixel blocks of `img`, row by row: a light path's
/// per-pixel noise is large at test sample counts, its blocks' is not, and a bias in any region
/// shows in its blocks.
pub fn block_rgb_means(img: &Image, b: u32) -> Vec<Vec3> {
    let mut out = Vec::new();
    for by in 0..img.height / b {
        for bx in 0..img.width / b {
            let mut s = Vec3::ZERO;
            for y in by * b..(by + 1) * b {
                for x in bx * b..(bx + 1) * b {
                    s += img.get(x, y);
                }
            }
            out.push(s / (b * b) as f32);
        }
    }
    out
}

/// Relative RMS difference of the 8 × 8-pixel block means of `img` and `reference` (over the
/// reference's mean luminance).
/// The pixel-wise mean of `images` (all of one size, at least one): the average of renders at
/// several moments of a shutter, which a motion-blurred render must converge to.
pub fn mean_image(images: impl IntoIterator<Item = Image>) -> Image {
    let mut n = 0u32;
    let mut sum: Option<Image> = None;
    for img in images {
        n += 1;
        match sum.as_mut() {
            None => sum = Some(img),
            Some(acc) => acc
                .data
                .iter_mut()
                .zip(&img.data)
                .for_each(|(x, y)| *x += *y),
        }
    }
    let mut mean = sum.expect("at least one image");
    mean.data.iter_mut().for_each(|p| *p /= n as f32);
    mean
}

/// `scene` compiled at `time` (an instant or a shutter), every other world option default.
pub fn posed_world(scene: &Scene, time: trayecto::world::motion::TimeOptions) -> World {
    World::build_posed(
        scene.clone(),
        &WorldOptions {
            time,
            ..Default::default()
        },
    )
    .unwrap()
}

pub fn block_error(img: &Image, reference: &Image) -> f64 {
    let (a, r) = (block_rgb_means(img, 8), block_rgb_means(reference, 8));
    let mut s = 0.0f64;
    for (p, q) in a.iter().zip(&r) {
        s += (*p - *q).as_dvec3().length_squared() / 3.0;
    }
    let m = reference.mean();
    (s / a.len() as f64).sqrt() / ((m.x + m.y + m.z) / 3.0) as f64
}

/// The Cornell box lit by a moving point light and a moving, turning spot light instead of its
/// ceiling emitter, animated as a glTF file's lights are (a rig of light nodes, linear channels
/// over [0, 1] s): the bulb crosses the box below the ceiling (x from −0.6 to 0.6) and the spot,
/// moving toward the back, turns from straight down to 30° toward the back wall. Motion blur
/// over [0, 1] keys both in the one world (`light::set::LightMotion`).
pub fn cornell_with_moving_lights() -> Scene {
    use glam::Quat;
    use std::sync::Arc;
    use trayecto::scene::LightDesc;
    use trayecto::scene::animation::{
        Animation, Channel, ChannelPath, Interpolation, Placed, Rig, RigNode,
    };
    let mut s = trayecto::scene::builtin::cornell();
    let light = s.objects.iter().find(|o| o.name == "light").unwrap();
    s.materials[light.material].emissive = Vec3::ZERO;
    let first = s.lights.len();
    s.lights.push(LightDesc::Point {
        name: "bulb".into(),
        position: Vec3::ZERO,
        intensity: Vec3::new(0.9, 0.8, 0.7),
    });
    s.lights.push(LightDesc::Spot {
        name: "spot".into(),
        position: Vec3::ZERO,
        direction: Vec3::NEG_Z,
        intensity: Vec3::new(2.0, 2.5, 3.0),
        inner_angle: 15f32.to_radians(),
        outer_angle: 25f32.to_radians(),
        falloff: trayecto::scene::SpotFalloff::default(),
    });
    let node = |translation: Vec3| RigNode {
        parent: None,
        matrix: None,
        translation,
        rotation: Quat::IDENTITY,
        scale: Vec3::ONE,
        weights: Vec::new(),
    };
    // A rotation of θ about x as glTF's (x, y, z, w): −90° turns the light's −z straight down,
    // −60° tilts it 30° toward −z.
    let about_x = |deg: f64| {
        let h = deg.to_radians() / 2.0;
        [h.sin(), 0.0, 0.0, h.cos()]
    };
    let (r0, r1) = (about_x(-90.0), about_x(-60.0));
    s.animation = Some(Arc::new(Animation {
        rig: Some(Rig {
            nodes: vec![node(Vec3::ZERO), node(Vec3::ZERO)],
            order: vec![0, 1],
            channels: vec![
                Channel {
                    node: 0,
                    path: ChannelPath::Translation,
                    interpolation: Interpolation::Linear,
                    times: vec![0.0, 1.0],
                    values: vec![-0.6, 0.8, 0.2, 0.6, 0.8, 0.2],
                },
                Channel {
                    node: 1,
                    path: ChannelPath::Translation,
                    interpolation: Interpolation::Linear,
                    times: vec![0.0, 1.0],
                    values: vec![0.3, 0.9, 0.4, 0.3, 0.9, -0.2],
                },
                Channel {
                    node: 1,
                    path: ChannelPath::Rotation,
                    interpolation: Interpolation::Linear,
                    times: vec![0.0, 1.0],
                    values: [r0, r1].concat(),
                },
            ],
            skins: Vec::new(),
            placed: vec![(0, Placed::Light(first)), (1, Placed::Light(first + 1))],
            deformed: Vec::new(),
        }),
        ..Default::default()
    }));
    s
}

/// The Cornell box lit by moving emitters: its ceiling light (a quad) at half its radiance
/// sliding from front to back (z from +0.3 to −0.3 of where it was), a square emissive panel (a
/// two-triangle mesh, one-sided, facing down) sliding across below the ceiling (x from −0.4 to
/// 0.4) while turning 40° about the vertical, and a small emissive sphere crossing the box from
/// back to front while its radius grows by half (so its area changes over the shutter).
/// Both move over [0, 1] s as a pbrt file's transform times move objects; motion blur over
/// [0, 1] keys them in the one world (`geometry::motion`), their area lights sampled where they
/// are at each sample's time.
pub fn cornell_with_moving_emitters() -> Scene {
    use std::sync::Arc;
    use trayecto::scene::animation::{Animation, MovingTransform, RigidMotion};
    let mut s = trayecto::scene::builtin::cornell();
    let light_object = s.objects.iter().position(|o| o.name == "light").unwrap();
    let light = &s.objects[light_object];
    s.materials[light.material].emissive *= 0.5;
    let mut panel_mat = Material::diffuse("panel", Vec3::splat(0.5));
    panel_mat.emissive = Vec3::new(24.0, 19.0, 10.0);
    let panel_mat = s.add_material(panel_mat);
    let mut ball_mat = Material::diffuse("ball", Vec3::splat(0.5));
    ball_mat.emissive = Vec3::new(5.0, 7.0, 9.0);
    let ball_mat = s.add_material(ball_mat);
    let a = 0.15;
    // Wound so that the front (e1 × e2) faces −y.
    let panel = s.add_mesh(quad_mesh(
        "panel",
        [
            Vec3::new(-a, 0.0, -a),
            Vec3::new(a, 0.0, -a),
            Vec3::new(a, 0.0, a),
            Vec3::new(-a, 0.0, a),
        ],
    ));
    let panel_object = s.objects.len();
    s.add_object("panel", Shape::Mesh(panel), Mat4::IDENTITY, panel_mat);
    let ball_object = s.objects.len();
    s.add_object(
        "ball",
        Shape::Sphere {
            center: Vec3::ZERO,
            radius: 0.06,
        },
        Mat4::IDENTITY,
        ball_mat,
    );
    s.animation = Some(Arc::new(Animation {
        rigid: vec![
            RigidMotion::Object {
                object: light_object,
                motion: MovingTransform {
                    times: [0.0, 1.0],
                    start: Mat4::from_translation(Vec3::new(0.0, 0.0, 0.3)),
                    end: Mat4::from_translation(Vec3::new(0.0, 0.0, -0.3)),
                },
            },
            RigidMotion::Object {
                object: panel_object,
                motion: MovingTransform {
                    times: [0.0, 1.0],
                    start: Mat4::from_translation(Vec3::new(-0.4, 0.95, 0.0)),
                    end: Mat4::from_translation(Vec3::new(0.4, 0.95, 0.0))
                        * Mat4::from_rotation_y(40f32.to_radians()),
                },
            },
            RigidMotion::Object {
                object: ball_object,
                motion: MovingTransform {
                    times: [0.0, 1.0],
                    start: Mat4::from_translation(Vec3::new(0.25, 0.35, -0.3)),
                    end: Mat4::from_translation(Vec3::new(0.25, 0.35, 0.3))
                        * Mat4::from_scale(Vec3::splat(1.5)),
                },
            },
        ],
        ..Default::default()
    }));
    s
}
