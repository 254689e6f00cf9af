//! Filtered texture lookups (`--texture-filter trilinear`): the MIP level chosen from a hit's
//! pixel footprint, and the error of a 1-spp render of a receding checkerboard against the
//! supersampled pixel integral of the unfiltered texture, with filtering on and off.

use std::sync::atomic::AtomicBool;

use trayecto::camera::Camera;
use trayecto::material::texture::TextureFilter;
use trayecto::material::{Material, MaterialModel, TextureRef};
use trayecto::math::{Mat4, Vec2, Vec3};
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene::testscenes::{checker, grid_plane};
use trayecto::scene::{CameraDesc, Scene, Shape};
use trayecto::world::{World, WorldOptions};

/// An unlit (KHR_materials_unlit) square of half-size `half` carrying a `size`² checker of
/// `cells`² squares, placed by `transform` (the square lies in y = 0, normal +y, uv over it).
fn scene(size: u32, cells: u32, half: f32, transform: Mat4, camera: CameraDesc) -> Scene {
    let mut s = Scene::default();
    s.textures.push(checker(
        "checker",
        size,
        cells,
        Vec3::splat(0.9),
        Vec3::splat(0.05),
    ));
    let mut m = Material::diffuse("board", Vec3::ONE);
    m.model = MaterialModel::Unlit;
    m.double_sided = true;
    m.base_color_texture = Some(TextureRef::new(0));
    let m = s.add_material(m);
    let plane = s.add_mesh(grid_plane("board", 1));
    s.add_object(
        "board",
        Shape::Mesh(plane),
        transform * Mat4::from_scale(Vec3::new(half, 1.0, half)),
        m,
    );
    s.cameras.push(camera);
    s
}

fn build(s: Scene, filter: TextureFilter) -> World {
    World::build(
        s,
        &WorldOptions {
            texture_filter: filter,
            ..WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..Default::default()
            }
        },
    )
    .unwrap()
}

/// A 256² texture over a 2 × 2 square facing a camera 4 units away whose 64 pixels span
/// tan(φ/2) = 0.5: a pixel is 2·4·0.5/64 = 1/16 units, 8 texels, so level log2(8) = 3; at 2
/// units, level 2. Fails if the footprint is off by a factor (say the 2× pbrt-v4 applies),
/// or the derivatives are taken in the wrong uv set or space.
#[test]
fn mip_level_of_a_plane_at_a_known_distance() {
    let vfov = 2.0 * 0.5f32.atan().to_degrees();
    for (dist, want) in [(4.0f32, 3.0f32), (2.0, 2.0), (8.0, 4.0)] {
        let cam = CameraDesc::look_at("c", Vec3::new(0.0, 0.0, dist), Vec3::ZERO, Vec3::Y, vfov);
        // Stand the square up to face +z.
        let face_z = Mat4::from_rotation_x(std::f32::consts::FRAC_PI_2);
        let world = build(scene(256, 8, 1.0, face_z, cam), TextureFilter::Trilinear);
        assert!(!world.textures[0].mips.is_empty(), "no pyramid was built");
        let camera = Camera::new(&world.camera, 64, 64);
        let fp = camera.footprint();
        for film in [Vec2::new(32.0, 32.0), Vec2::new(28.5, 35.5)] {
            let ray = camera.generate_ray(film, Vec2::ZERO);
            let hit = world
                .intersect_filtered(&ray, &fp)
                .expect("the square is in view");
            let level = world.textures[0].mip_level(hit.duv[0]);
            // Off-centre pixels see the square slightly obliquely: a little finer.
            assert!(
                (level - want).abs() < 0.05,
                "distance {dist}, film {film}: level {level}, want {want}"
            );
            // Screen x moves along u, screen y along v, each by 8 texels per pixel at 4 units.
            let texels = 256.0 / 2.0 * (2.0 * dist * 0.5 / 64.0);
            assert!((hit.duv[0].x.abs() * 256.0 - texels).abs() < 0.05 * texels);
            assert!((hit.duv[0].w.abs() * 256.0 - texels).abs() < 0.05 * texels);
        }
        // Filtering off: no footprint, no pyramid.
        let cam = world.camera.clone();
        let off = build(scene(256, 8, 1.0, face_z, cam), TextureFilter::None);
        assert!(off.textures[0].mips.is_empty());
        let ray = camera.generate_ray(Vec2::new(32.0, 32.0), Vec2::ZERO);
        let hit = off
            .intersect_filtered(&ray, &Default::default())
            .expect("in view");
        assert_eq!(hit.duv, [trayecto::math::Vec4::ZERO; 2]);
    }
}

fn receding_board() -> Scene {
    // A 40 × 40 floor with 128² checker squares of 8 texels, seen at a grazing angle: far
    // away many squares fall in one pixel.
    let cam = CameraDesc::look_at(
        "c",
        Vec3::new(0.0, 1.0, 19.0),
        Vec3::new(0.0, 0.0, 5.0),
        Vec3::Y,
        40.0,
    );
    scene(1024, 128, 20.0, Mat4::IDENTITY, cam)
}

fn render_board(filter: TextureFilter, spp: u32, seed: u64) -> Vec<Vec3> {
    let world = build(receding_board(), filter);
    let settings = RenderSettings {
        width: 64,
        height: 48,
        spp,
        seed,
        path: trayecto::integrator::path::PathSettings {
            max_depth: 0,
            ..Default::default()
        },
        ..Default::default()
    };
    render(&world, &settings, &NoObserver, &AtomicBool::new(false))
        .unwrap()
        .image
        .data
}

fn rmse(a: &[Vec3], b: &[Vec3]) -> f32 {
    let s: f32 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum();
    (s / a.len() as f32).sqrt()
}

/// At 1 spp the unfiltered board aliases (each pixel reads one random texel of the many it
/// covers); the trilinear one reads their average. Against the box-filtered pixel integral of
/// the unfiltered texture (256 spp), the filtered error must be well under half the unfiltered
/// one, averaged over seeds. Measured: see BENCHMARKS.md ("Other measurements"). Fails with the
/// footprint disabled (ratio ≈ 1) and with a 16× too small footprint.
#[test]
fn receding_checkerboard_at_one_spp_has_much_lower_error_filtered() {
    let reference = render_board(TextureFilter::None, 256, 99);
    let (mut on, mut off) = (0.0, 0.0);
    for seed in 1..=3 {
        on += rmse(&render_board(TextureFilter::Trilinear, 1, seed), &reference);
        off += rmse(&render_board(TextureFilter::None, 1, seed), &reference);
    }
    eprintln!(
        "1-spp RMSE vs the 256-spp pixel integral: trilinear {on:.4}, none {off:.4} (sum of 3 seeds)"
    );
    assert!(on < 0.5 * off, "trilinear {on} vs none {off}");
}
