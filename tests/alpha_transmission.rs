//! Alpha modes (glTF MASK and BLEND) and partial KHR_materials_transmission, measured on a sheet
//! in front of a uniform emitter.
//!
//! The camera looks head-on at a sheet (z = 0) that fills the frame; behind it a larger emissive
//! quad of radiance 1 faces the camera; there is no other light. Whatever reaches the camera came
//! through the sheet, so the image mean is the sheet's expected transmittance:
//! * a black BLEND sheet of opacity a lets 1 − a through (stochastic transparency);
//! * a MASK sheet is fully open below the cutoff and fully closed above it;
//! * a thin-walled transmissive sheet (IOR 1.5) with factor t transmits t·T where T is the thin
//!   slab's transmittance, so images for different t are in the ratio of the factors.

use trayecto::material::texture::FilterMode;
use trayecto::material::{AlphaMode, Material, MaterialModel, Texture, TextureRef};
use trayecto::math::{Mat4, Vec3, Vec4};
use trayecto::render::RenderSettings;
use trayecto::render::{NoObserver, render};
use trayecto::scene::{CameraDesc, LightDesc, Object, Scene, Shape};
use trayecto::world::{World, WorldOptions};

const SIZE: u32 = 32;

fn quad(name: &str, z: f32, half: f32, material: usize) -> Object {
    Object {
        name: name.into(),
        shape: Shape::Quad {
            corner: Vec3::new(-half, -half, z),
            e1: Vec3::new(2.0 * half, 0.0, 0.0),
            e2: Vec3::new(0.0, 2.0 * half, 0.0),
        },
        transform: Mat4::IDENTITY,
        material,
        medium: None,
    }
}

/// The sheet (material 0, plus `textures`) in front of the emitter; returns the linear image.
fn render_sheet(sheet: Material, textures: Vec<Texture>, spp: u32, max_depth: u32) -> Vec<Vec3> {
    let emitter = Material {
        name: "emitter".into(),
        base_color: Vec3::ZERO,
        emissive: Vec3::ONE,
        ..Default::default()
    };
    let scene = Scene {
        name: "sheet".into(),
        objects: vec![quad("sheet", 0.0, 1.0, 0), quad("emitter", -1.0, 4.0, 1)],
        materials: vec![sheet, emitter],
        textures,
        lights: vec![],
        cameras: vec![CameraDesc::look_at(
            "cam",
            Vec3::new(0.0, 0.0, 40.0),
            Vec3::ZERO,
            Vec3::Y,
            // Slightly narrower than the sheet, so every pixel looks through it.
            2.0 * (0.9f32 / 40.0).atan().to_degrees(),
        )],
        ..Default::default()
    };
    let options = WorldOptions {
        default_light: Some(trayecto::light::default_light::DefaultLight::Off),
        ..Default::default()
    };
    let world = World::build(scene.clone(), &options).unwrap();
    let mut settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        spp,
        ..Default::default()
    };
    settings.path.max_depth = max_depth;
    let out = render(
        &world,
        &settings,
        &NoObserver,
        &std::sync::atomic::AtomicBool::new(false),
    )
    .unwrap();
    out.image.data
}

fn mean(px: &[Vec3]) -> f64 {
    px.iter()
        .map(|p| p.dot(Vec3::splat(1.0 / 3.0)) as f64)
        .sum::<f64>()
        / px.len() as f64
}

fn black_sheet(alpha: f32, mode: AlphaMode) -> Material {
    Material {
        name: "sheet".into(),
        base_color: Vec3::ZERO,
        alpha,
        alpha_mode: mode,
        ..Default::default()
    }
}

#[test]
fn blend_lets_one_minus_alpha_through() {
    let spp = 16;
    for alpha in [0.25f32, 0.5, 0.9] {
        let m = mean(&render_sheet(
            black_sheet(alpha, AlphaMode::Blend),
            vec![],
            spp,
            4,
        ));
        let expected = 1.0 - alpha as f64;
        // Each camera sample is a Bernoulli(1 − a) coin: four standard errors of the mean.
        let n = (SIZE * SIZE * spp) as f64;
        let sigma = (expected * (1.0 - expected) / n).sqrt();
        assert!(
            (m - expected).abs() < 4.0 * sigma + 1e-4,
            "alpha {alpha}: mean {m:.4}, expected {expected:.4} ± {:.4}",
            4.0 * sigma
        );
    }
}

#[test]
fn blend_opacity_one_is_opaque_and_opaque_mode_ignores_alpha() {
    let m = mean(&render_sheet(
        black_sheet(1.0, AlphaMode::Blend),
        vec![],
        4,
        4,
    ));
    assert_eq!(m, 0.0, "a BLEND sheet of opacity 1 must block everything");
    let m = mean(&render_sheet(
        black_sheet(0.2, AlphaMode::Opaque),
        vec![],
        4,
        4,
    ));
    assert_eq!(m, 0.0, "OPAQUE mode ignores alpha (glTF 2.0 §3.9.4)");
}

#[test]
fn mask_is_all_or_nothing_at_the_cutoff() {
    let open = mean(&render_sheet(
        black_sheet(0.4, AlphaMode::Mask),
        vec![],
        4,
        4,
    ));
    assert!(
        (open - 1.0).abs() < 1e-4,
        "alpha 0.4 < cutoff 0.5: open, got {open}"
    );
    let closed = mean(&render_sheet(
        black_sheet(0.6, AlphaMode::Mask),
        vec![],
        4,
        4,
    ));
    assert_eq!(closed, 0.0, "alpha 0.6 ≥ cutoff 0.5: closed");
}

#[test]
fn mask_follows_the_base_colour_texture_alpha() {
    // 2×1 texture: the left texel is transparent, the right one opaque (nearest filtering).
    let texture = Texture {
        name: "half".into(),
        width: 2,
        height: 1,
        texels: vec![Vec4::new(0.0, 0.0, 0.0, 0.0), Vec4::new(0.0, 0.0, 0.0, 1.0)].into(),
        wrap_s: Default::default(),
        wrap_t: Default::default(),
        filter: FilterMode::Nearest,
        mipmap: true,
        mips: Vec::new(),
        procedural: None,
        layout: Default::default(),
    };
    let sheet = Material {
        base_color_texture: Some(TextureRef::new(0)),
        ..black_sheet(1.0, AlphaMode::Mask)
    };
    let img = render_sheet(sheet, vec![texture], 4, 4);
    let half = SIZE as usize / 2;
    let (mut left, mut right) = (Vec::new(), Vec::new());
    for (i, p) in img.iter().enumerate() {
        let x = i % SIZE as usize;
        // Skip the column pair at the seam, where a pixel's samples straddle both texels.
        if x + 1 < half {
            left.push(*p);
        } else if x > half {
            right.push(*p);
        }
    }
    let (l, r) = (mean(&left), mean(&right));
    assert!((l - 1.0).abs() < 1e-4, "left half is a hole, got {l}");
    assert_eq!(r, 0.0, "right half is solid");
}

/// A white floor lit by a directional light through a black BLEND sheet, seen through the same
/// sheet: the camera ray and the shadow ray each pass with probability 1 − a, so direct
/// lighting scales with (1 − a)².
#[test]
fn shadow_rays_see_through_blend_holes() {
    let render_floor = |alpha: f32| {
        let floor = Material::diffuse("floor", Vec3::ONE);
        let scene = Scene {
            name: "shadow".into(),
            objects: vec![quad("sheet", 1.0, 2.0, 0), quad("floor", 0.0, 4.0, 1)],
            materials: vec![black_sheet(alpha, AlphaMode::Blend), floor],
            lights: vec![LightDesc::Directional {
                name: "sun".into(),
                direction: Vec3::new(0.0, 0.0, -1.0),
                irradiance: Vec3::splat(3.0),
            }],
            cameras: vec![CameraDesc::look_at(
                "cam",
                Vec3::new(0.0, 0.0, 40.0),
                Vec3::ZERO,
                Vec3::Y,
                2.0 * (0.9f32 / 40.0).atan().to_degrees(),
            )],
            ..Default::default()
        };
        let world = World::build(
            scene.clone(),
            &WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..WorldOptions::default()
            },
        )
        .unwrap();
        let mut settings = RenderSettings {
            width: SIZE,
            height: SIZE,
            spp: 64,
            ..Default::default()
        };
        settings.path.max_depth = 1;
        let out = render(
            &world,
            &settings,
            &NoObserver,
            &std::sync::atomic::AtomicBool::new(false),
        )
        .unwrap();
        mean(&out.image.data)
    };
    let clear = render_floor(0.0);
    assert!(
        (clear - 3.0 / std::f64::consts::PI).abs() < 1e-3,
        "unshadowed floor radiance E/π, got {clear}"
    );
    let half = render_floor(0.5);
    let ratio = half / clear;
    assert!(
        (ratio - 0.25).abs() < 0.01,
        "opacity 0.5 on both rays: ratio {ratio:.4}, expected 0.25"
    );
}

fn transmissive_sheet(transmission: f32, metallic: f32) -> Material {
    Material {
        name: "glass".into(),
        model: MaterialModel::metallic_roughness(),
        base_color: Vec3::ONE,
        metallic,
        // Smooth: the camera sees the background straight through (a rough thin sheet blurs it
        // over a wide lobe, see `Bsdf::ThinDielectric`).
        roughness: 0.0,
        transmission,
        thin_walled: true,
        ..Default::default()
    }
}

#[test]
fn partial_transmission_scales_the_transmitted_light() {
    let spp = 32;
    let full = mean(&render_sheet(transmissive_sheet(1.0, 0.0), vec![], spp, 8));
    // A thin slab of IOR 1.5 seen head-on transmits (1 − R)/(1 + R) with R = 0.04.
    let slab = (1.0 - 0.04) / (1.0 + 0.04);
    assert!(
        (full - slab).abs() < 0.01,
        "full transmission: {full:.4}, thin slab {slab:.4}"
    );
    for (t, metallic, expected) in [(0.5f32, 0.0f32, 0.5f64), (0.25, 0.0, 0.25), (1.0, 0.5, 0.5)] {
        let m = mean(&render_sheet(
            transmissive_sheet(t, metallic),
            vec![],
            spp,
            8,
        ));
        // Per sample the sheet transmits with probability p = (1 − metallic)·t.
        let n = (SIZE * SIZE * spp) as f64;
        let sigma = full * (expected * (1.0 - expected) / n).sqrt();
        assert!(
            (m - expected * full).abs() < 4.0 * sigma + 1e-3,
            "transmission {t}, metallic {metallic}: {m:.4}, expected {:.4}",
            expected * full
        );
    }
}
