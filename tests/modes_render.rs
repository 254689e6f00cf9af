//! What each of the thesis's modes must show (issue 4): the ray caster's views, the Whitted
//! tracer's mirrors, refraction and hard shadows, and accelerators that never change the image.
//! Scenes are built in code so the tests do not depend on any loader.

use std::sync::atomic::AtomicBool;
use trayecto::accel::AccelKind;
use trayecto::camera::Camera;
use trayecto::film::Image;
use trayecto::geometry::Ray;
use trayecto::integrator::{Aov, IntegratorKind, RayStats, ShadingModel, whitted};
use trayecto::material::{Material, MaterialModel, Texture, TextureRef};
use trayecto::math::{Mat4, Vec2, Vec3, Vec4};
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::sampling::{SampleStream, SamplerKind};
use trayecto::scene::{CameraDesc, LightDesc, Scene, Shape, builtin, testscenes};
use trayecto::world::{World, WorldOptions};

fn world(scene: &Scene, accel: AccelKind) -> World {
    World::build(
        scene.clone(),
        &WorldOptions {
            accel,
            ..WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..Default::default()
            }
        },
    )
    .expect("scene compiles")
}

fn settings(w: u32, h: u32, spp: u32, integrator: IntegratorKind) -> RenderSettings {
    let mut s = RenderSettings {
        width: w,
        height: h,
        spp,
        integrator,
        threads: Some(2),
        ..Default::default()
    };
    s.path.max_depth = 8;
    s
}

fn run(world: &World, s: &RenderSettings) -> Image {
    render(world, s, &NoObserver, &AtomicBool::new(false))
        .expect("render")
        .image
}

fn raycast(aov: Aov) -> IntegratorKind {
    IntegratorKind::Raycast {
        aov,
        shading: ShadingModel::Pbr,
    }
}

fn whitted_mode() -> IntegratorKind {
    IntegratorKind::Whitted {
        shading: ShadingModel::Pbr,
    }
}

fn px(img: &Image, x: u32, y: u32) -> Vec3 {
    img.data[(y * img.width + x) as usize]
}

/// The four corners and the centre of pixel (x, y): a pixel is "clean" if all five agree.
fn footprint(x: u32, y: u32) -> [Vec2; 5] {
    let (x, y) = (x as f32, y as f32);
    [
        Vec2::new(x + 0.5, y + 0.5),
        Vec2::new(x, y),
        Vec2::new(x + 1.0, y),
        Vec2::new(x, y + 1.0),
        Vec2::new(x + 1.0, y + 1.0),
    ]
}

fn ray_sphere(r: &Ray, c: Vec3, radius: f32) -> Option<f32> {
    let d = r.d.normalize();
    let oc = r.o - c;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - radius * radius);
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > 0.0).then_some(t)
}

fn emitter(name: &str, radiance: Vec3) -> Material {
    let mut m = Material::diffuse(name, Vec3::ZERO);
    m.emissive = radiance;
    m
}

#[test]
fn raycast_normals_equal_the_analytic_sphere_normals() {
    let mut s = Scene::default();
    let m = s.add_material(Material::diffuse("grey", Vec3::splat(0.5)));
    s.add_object(
        "ball",
        Shape::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        },
        Mat4::IDENTITY,
        m,
    );
    let cam = CameraDesc::look_at("c", Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y, 40.0);
    s.cameras.push(cam.clone());
    let w = world(&s, AccelKind::Bvh);
    let img = run(&w, &settings(48, 48, 4, raycast(Aov::Normals)));
    let camera = Camera::new(&cam, 48, 48);
    let mut checked = 0;
    for y in 0..48 {
        for x in 0..48 {
            let normals: Vec<Option<Vec3>> = footprint(x, y)
                .iter()
                .map(|&f| {
                    let r = camera.generate_ray(f, Vec2::ZERO);
                    ray_sphere(&r, Vec3::ZERO, 1.0).map(|t| r.at(t).normalize())
                })
                .collect();
            let got = px(&img, x, y);
            if normals.iter().all(|n| n.is_none()) {
                assert_eq!(got, Vec3::ZERO, "background pixel ({x}, {y})");
                continue;
            }
            if normals.iter().any(|n| n.is_none()) {
                continue; // silhouette
            }
            let n = normals[0].unwrap();
            // Within the pixel the normal turns by at most the spread of its corners.
            let spread = normals
                .iter()
                .map(|m| (m.unwrap() - n).length())
                .fold(0.0f32, f32::max);
            let expect = (n + Vec3::ONE) * 0.5;
            assert!(
                (got - expect).length() <= 0.5 * spread + 1e-3,
                "pixel ({x}, {y}): {got} vs {expect}"
            );
            checked += 1;
        }
    }
    assert!(checked > 300, "{checked}");
}

#[test]
fn raycast_views_barycentric_depth_albedo_uv() {
    // One triangle facing the camera at distance 5.
    let mut s = Scene::default();
    // A 2×2 checker, nearest filtering so every pixel away from the cell edges has one exact
    // colour: texel (x, y) is red when x + y is odd, blue otherwise.
    let (red, blue) = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
    let mut checker = testscenes::checker("c", 2, 2, red, blue);
    checker.filter = trayecto::material::texture::FilterMode::Nearest;
    s.textures.push(checker);
    // A base colour factor that is not 1, so albedo = factor × texel is checked too.
    let factor = Vec3::new(0.9, 0.5, 0.7);
    let mut mat = Material::diffuse("t", factor);
    mat.base_color_texture = Some(TextureRef::new(0));
    let m = s.add_material(mat);
    let mesh = s.add_mesh(trayecto::scene::Mesh {
        name: "tri".into(),
        positions: vec![
            Vec3::new(-2.0, -2.0, 0.0),
            Vec3::new(2.0, -2.0, 0.0),
            Vec3::new(-2.0, 2.0, 0.0),
        ],
        indices: vec![[0, 1, 2]],
        uv0: Some(vec![
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 0.0),
        ]),
        ..Default::default()
    });
    s.add_object("tri", Shape::Mesh(mesh), Mat4::IDENTITY, m);
    let cam = CameraDesc::look_at("c", Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 60.0);
    s.cameras.push(cam.clone());
    let w = world(&s, AccelKind::Bvh);
    let camera = Camera::new(&cam, 32, 32);
    let views: Vec<(Aov, Image)> = [Aov::Barycentric, Aov::Depth, Aov::Uv, Aov::Albedo]
        .into_iter()
        .map(|a| (a, run(&w, &settings(32, 32, 16, raycast(a)))))
        .collect();
    let (mut checked, mut albedo_checked) = (0, 0);
    for y in 0..32 {
        for x in 0..32 {
            let inside = footprint(x, y).iter().all(|&f| {
                let r = camera.generate_ray(f, Vec2::ZERO);
                let p = r.at(5.0 / -r.d.z);
                p.x > -2.0 && p.y > -2.0 && p.x + p.y < 0.0
            });
            if !inside {
                continue;
            }
            let r = camera.generate_ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), Vec2::ZERO);
            let t = 5.0 / -r.d.z;
            let p = r.at(t);
            // Barycentrics of p: b1 weights vertex 1 (+x), b2 vertex 2 (+y).
            let b1 = (p.x + 2.0) / 4.0;
            let b2 = (p.y + 2.0) / 4.0;
            let bary = px(&views[0].1, x, y);
            assert!(
                (bary - Vec3::new(b1, b2, 1.0 - b1 - b2)).length() < 0.02,
                "({x},{y}) {bary}"
            );
            assert!((bary.x + bary.y + bary.z - 1.0).abs() < 1e-4);
            let depth = px(&views[1].1, x, y).x;
            assert!(
                (depth - t).abs() < 0.02 * t,
                "({x},{y}) depth {depth} vs {t}"
            );
            let uv = px(&views[2].1, x, y);
            assert!(
                (uv - Vec3::new(b1, 1.0 - b2, 0.0)).length() < 0.02,
                "uv {uv}"
            );
            // The albedo view is the base colour: factor × the checker cell at (u, v), for the
            // pixels whose footprint (±0.03 in u and v) stays inside one cell.
            let (u, v) = (b1, 1.0 - b2);
            if (u - 0.5).abs() > 0.06 && (v - 0.5).abs() > 0.06 {
                let odd = ((2.0 * u).floor() as i32 + (2.0 * v).floor() as i32) % 2 == 1;
                let expect = factor * if odd { red } else { blue };
                let albedo = px(&views[3].1, x, y);
                assert!(
                    (albedo - expect).abs().max_element() < 1e-4,
                    "({x},{y}) uv ({u:.3}, {v:.3}): albedo {albedo}, expected {expect}"
                );
                albedo_checked += 1;
            }
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked}");
    assert!(albedo_checked > 80, "{albedo_checked}");
}

/// Floor at y = 0, a sphere of radius 0.5 at (0, 1, 0) and a point light above: the raycast
/// image is black exactly where the segment to the light crosses the sphere, and elsewhere shows
/// the analytic irradiance `albedo/π · I cos θ / d²`.
#[test]
fn point_light_hard_shadow_is_where_geometry_says() {
    let albedo = 0.8;
    let intensity = 10.0;
    let light = Vec3::new(0.3, 3.0, 0.2);
    let (c, radius) = (Vec3::new(0.0, 1.0, 0.0), 0.5);
    let mut s = Scene::default();
    let m = s.add_material(Material::diffuse("white", Vec3::splat(albedo)));
    s.add_object(
        "floor",
        Shape::Quad {
            corner: Vec3::new(-10.0, 0.0, -10.0),
            e1: Vec3::new(0.0, 0.0, 20.0),
            e2: Vec3::new(20.0, 0.0, 0.0),
        },
        Mat4::IDENTITY,
        m,
    );
    s.add_object(
        "ball",
        Shape::Sphere { center: c, radius },
        Mat4::IDENTITY,
        m,
    );
    s.lights.push(LightDesc::Point {
        name: "p".into(),
        position: light,
        intensity: Vec3::splat(intensity),
    });
    let cam = CameraDesc::look_at("c", Vec3::new(0.0, 5.0, 3.0), Vec3::ZERO, Vec3::Y, 50.0);
    s.cameras.push(cam.clone());
    let camera = Camera::new(&cam, 64, 64);
    for (accel, shading) in [
        (AccelKind::Bvh, ShadingModel::Phong),
        (AccelKind::Grid, ShadingModel::BlinnPhong),
        (AccelKind::None, ShadingModel::Pbr),
    ] {
        let w = world(&s, accel);
        let img = run(
            &w,
            &settings(
                64,
                64,
                4,
                IntegratorKind::Raycast {
                    aov: Aov::Shaded,
                    shading,
                },
            ),
        );
        let (mut lit, mut dark) = (0, 0);
        for y in 0..64 {
            for x in 0..64 {
                // Classify the pixel's footprint: floor lit, floor shadowed, or other.
                let states: Vec<Option<(bool, f32)>> = footprint(x, y)
                    .iter()
                    .map(|&f| {
                        let r = camera.generate_ray(f, Vec2::ZERO);
                        let d = r.d.normalize();
                        if ray_sphere(&r, c, radius).is_some() || d.y >= 0.0 {
                            return None;
                        }
                        let p = r.o + d * (r.o.y / -d.y);
                        let to = light - p;
                        let shadow = Ray::new(p, to);
                        let blocked =
                            ray_sphere(&shadow, c, radius).is_some_and(|t| t < to.length());
                        let e = albedo / std::f32::consts::PI * intensity * to.normalize().y
                            / to.length_squared();
                        Some((blocked, e))
                    })
                    .collect();
                if states.iter().any(|s| s.is_none()) {
                    continue;
                }
                let blocked = states[0].unwrap().0;
                if states.iter().any(|s| s.unwrap().0 != blocked) {
                    continue; // the shadow's edge crosses the pixel
                }
                let got = px(&img, x, y);
                if blocked {
                    assert_eq!(got, Vec3::ZERO, "{accel:?} ({x},{y}) should be in shadow");
                    dark += 1;
                } else {
                    let e = states[0].unwrap().1;
                    assert!(
                        (got.x - e).abs() < 0.03 * e && got.x == got.y,
                        "{accel:?} ({x},{y}) {got} vs {e}"
                    );
                    lit += 1;
                }
            }
        }
        assert!(lit > 1000 && dark > 30, "lit {lit} dark {dark}");
    }
}

/// A horizontal mirror under a two-coloured emitting ceiling: every clean pixel shows the colour
/// found by reflecting its ray analytically.
#[test]
fn whitted_mirror_reflects_the_known_pattern() {
    let red = Vec3::new(1.0, 0.0, 0.0);
    let blue = Vec3::new(0.0, 0.2, 1.0);
    let mut s = Scene::default();
    let mut mirror = Material::diffuse("mirror", Vec3::ONE);
    mirror.model = MaterialModel::Mirror;
    let mirror = s.add_material(mirror);
    let mr = s.add_material(emitter("red", red));
    let mb = s.add_material(emitter("blue", blue));
    s.add_object(
        "mirror",
        Shape::Quad {
            corner: Vec3::new(-10.0, 0.0, -10.0),
            e1: Vec3::new(0.0, 0.0, 20.0),
            e2: Vec3::new(20.0, 0.0, 0.0),
        },
        Mat4::IDENTITY,
        mirror,
    );
    // Ceiling at y = 2 facing down: red for x < 0, blue for x > 0.
    for (x0, m) in [(-10.0, mr), (0.0, mb)] {
        s.add_object(
            "ceiling",
            Shape::Quad {
                corner: Vec3::new(x0, 2.0, -10.0),
                e1: Vec3::new(10.0, 0.0, 0.0),
                e2: Vec3::new(0.0, 0.0, 20.0),
            },
            Mat4::IDENTITY,
            m,
        );
    }
    let cam = CameraDesc::look_at(
        "c",
        Vec3::new(0.3, 1.0, 4.0),
        Vec3::new(-0.5, 0.0, 0.0),
        Vec3::Y,
        60.0,
    );
    s.cameras.push(cam.clone());
    let camera = Camera::new(&cam, 48, 48);
    let w = world(&s, AccelKind::Grid);
    let img = run(&w, &settings(48, 48, 4, whitted_mode()));
    let expected = |f: Vec2| -> Option<Vec3> {
        let r = camera.generate_ray(f, Vec2::ZERO);
        let mut d = r.d.normalize();
        let mut o = r.o;
        if d.y < 0.0 {
            o += d * (o.y / -d.y);
            d.y = -d.y; // reflection off y = 0
        }
        if d.y <= 1e-3 {
            return None;
        }
        let p = o + d * ((2.0 - o.y) / d.y);
        (p.x.abs() < 10.0 && p.z.abs() < 10.0).then_some(if p.x < 0.0 { red } else { blue })
    };
    let (mut mirrored, mut direct) = (0, 0);
    for y in 0..48 {
        for x in 0..48 {
            let e: Vec<Option<Vec3>> = footprint(x, y).iter().map(|&f| expected(f)).collect();
            if e.iter().any(|c| *c != e[0]) || e[0].is_none() {
                continue;
            }
            let got = px(&img, x, y);
            assert!(
                (got - e[0].unwrap()).length() < 1e-5,
                "({x},{y}) {got} vs {:?}",
                e[0]
            );
            let below = camera
                .generate_ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), Vec2::ZERO)
                .d
                .y
                < 0.0;
            if below { mirrored += 1 } else { direct += 1 }
        }
    }
    assert!(mirrored > 500 && direct > 100, "{mirrored} {direct}");
}

/// A glass slab of thickness 1 (IOR 1.5) in front of a red|green edge: the edge seen through the
/// slab along a ray at 30° moves by the Snell offset h·(tan θ − tan θ_t).
#[test]
fn refraction_through_a_slab_shifts_by_the_snell_offset() {
    let ior = 1.5f32;
    let mut s = Scene::default();
    let mut glass = Material::diffuse("glass", Vec3::ONE);
    glass.model = MaterialModel::dielectric();
    glass.ior = ior;
    let glass = s.add_material(glass);
    let mr = s.add_material(emitter("red", Vec3::new(1.0, 0.0, 0.0)));
    let mg = s.add_material(emitter("green", Vec3::new(0.0, 1.0, 0.0)));
    s.add_object(
        "slab",
        Shape::Cuboid {
            min: Vec3::new(-50.0, -50.0, -1.0),
            max: Vec3::new(50.0, 50.0, 0.0),
        },
        Mat4::IDENTITY,
        glass,
    );
    for (x0, m) in [(-50.0, mr), (0.0, mg)] {
        s.add_object(
            "backdrop",
            Shape::Quad {
                corner: Vec3::new(x0, -50.0, -3.0),
                e1: Vec3::new(50.0, 0.0, 0.0),
                e2: Vec3::new(0.0, 100.0, 0.0),
            },
            Mat4::IDENTITY,
            m,
        );
    }
    let theta = 30f32.to_radians();
    let d = Vec3::new(theta.sin(), 0.0, -theta.cos());
    let theta_t = (theta.sin() / ior).asin();
    for accel in [AccelKind::Bvh, AccelKind::Grid] {
        let w = world(&s, accel);
        let reds = |ox: f32| {
            let ray = Ray::new(Vec3::new(ox, 0.0, 5.0), d);
            let mut st = SampleStream::new(SamplerKind::Independent, 0, (0, 0), 0, 1);
            let mut stats = RayStats::default();
            let l = whitted::radiance(&w, &ray, &mut st, 8, ShadingModel::Pbr, &mut stats);
            assert!(
                l.max_element() > 0.5,
                "the edge must be visible through the slab: {l}"
            );
            l.x > l.y
        };
        // Bisect for the ray origin whose ray lands on the edge x = 0.
        let (mut lo, mut hi) = (-8.0f32, 0.0f32);
        assert!(reds(lo) && !reds(hi));
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if reds(mid) { lo = mid } else { hi = mid }
        }
        let found = 0.5 * (lo + hi);
        // Free flight: 5 to the slab, 2 from the slab to the backdrop, 1 inside at θ_t.
        let expect = -(7.0 * theta.tan() + theta_t.tan());
        let straight = -8.0 * theta.tan();
        assert!(
            (found - expect).abs() < 1e-3,
            "{accel:?}: {found} vs {expect}"
        );
        let offset = found - straight;
        assert!(
            (offset - (theta.tan() - theta_t.tan())).abs() < 1e-3,
            "Snell offset {offset}"
        );
    }
}

#[test]
fn ambient_light_and_occlusion_texture() {
    // A plane lit only by an ambient light: L = albedo · L_ambient · occlusion.
    let mut s = Scene::default();
    s.textures.push(Texture::constant("ao", Vec4::splat(0.25)));
    let mut m = Material::diffuse("m", Vec3::new(0.5, 0.4, 0.3));
    m.occlusion_texture = Some(TextureRef::new(0));
    m.occlusion_strength = 1.0;
    let m = s.add_material(m);
    s.add_object(
        "plane",
        Shape::Quad {
            corner: Vec3::new(-5.0, -5.0, 0.0),
            e1: Vec3::new(10.0, 0.0, 0.0),
            e2: Vec3::new(0.0, 10.0, 0.0),
        },
        Mat4::IDENTITY,
        m,
    );
    s.lights.push(LightDesc::Ambient {
        name: "ambient".into(),
        radiance: Vec3::splat(2.0),
    });
    s.cameras.push(CameraDesc::look_at(
        "c",
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::ZERO,
        Vec3::Y,
        30.0,
    ));
    let w = world(&s, AccelKind::Bvh);
    for model in [
        ShadingModel::Phong,
        ShadingModel::BlinnPhong,
        ShadingModel::Pbr,
    ] {
        let img = run(
            &w,
            &settings(
                8,
                8,
                1,
                IntegratorKind::Raycast {
                    aov: Aov::Shaded,
                    shading: model,
                },
            ),
        );
        for p in &img.data {
            assert!((*p - Vec3::new(0.25, 0.2, 0.15)).length() < 1e-5, "{p}");
        }
    }
}

#[test]
fn the_same_scene_renders_in_all_three_modes() {
    let s = builtin::cornell();
    let w = world(&s, AccelKind::Bvh);
    let shaded = run(&w, &settings(24, 24, 4, raycast(Aov::Shaded)));
    let whitted_img = run(&w, &settings(24, 24, 4, whitted_mode()));
    let path = run(&w, &settings(24, 24, 4, IntegratorKind::Path));
    for img in [&shaded, &whitted_img, &path] {
        assert!(
            img.data
                .iter()
                .all(|p| p.is_finite() && p.min_element() >= 0.0)
        );
        let mean: f32 =
            img.data.iter().map(|p| p.x + p.y + p.z).sum::<f32>() / img.data.len() as f32;
        assert!(mean > 0.05, "{mean}");
    }
    // The Cornell box is all diffuse: Whitted adds nothing to the ray caster's local shading.
    assert_eq!(shaded.data, whitted_img.data);
    // Global illumination brightens the box.
    let sum = |i: &Image| i.data.iter().map(|p| p.x + p.y + p.z).sum::<f32>();
    assert!(sum(&path) > sum(&shaded));
}

/// `--accel bvh|grid|none` must give bit-identical images.
#[test]
fn accelerators_give_identical_images() {
    let scenes = [
        (builtin::cornell(), IntegratorKind::Path),
        (testscenes::textured_spheres(3, 6), whitted_mode()),
        (testscenes::textured_spheres(2, 5), IntegratorKind::Path),
        (
            testscenes::textured_spheres(2, 4),
            raycast(Aov::Barycentric),
        ),
    ];
    for (scene, mode) in &scenes {
        let mut images = Vec::new();
        for accel in [AccelKind::Bvh, AccelKind::Grid, AccelKind::None] {
            let w = world(scene, accel);
            images.push(run(&w, &settings(32, 24, 2, *mode)).data);
        }
        assert!(
            images[0] == images[1],
            "{}: grid differs from bvh",
            scene.name
        );
        assert!(
            images[0] == images[2],
            "{}: none differs from bvh",
            scene.name
        );
    }
}

/// The command line: thesis output path (PPM P3, gamma 2.2) and the phase report.
#[test]
fn cli_prints_the_phase_report_and_writes_ppm() {
    let dir = std::env::temp_dir().join(format!("trayecto-modes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("thesis.ppm");
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_trayecto"))
        .args([
            "render",
            "cornell",
            "--integrator",
            "whitted",
            "--shading",
            "blinn-phong",
            "--accel",
            "grid",
            "--sampler",
            "poisson-disk",
            "--tonemap",
            "gamma2.2",
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    for needle in [
        "scene loaded",
        "acceleration structure built",
        "rendered (whitted)",
        "image written",
        "total",
        "grid ",
    ] {
        assert!(err.contains(needle), "missing '{needle}' in:\n{err}");
    }
    let ppm = std::fs::read_to_string(&out).unwrap();
    assert!(
        ppm.starts_with("P3\n8 8\n255\n"),
        "{}",
        &ppm[..20.min(ppm.len())]
    );
    std::fs::remove_dir_all(&dir).ok();
}
