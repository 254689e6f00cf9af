//! White-furnace tests: a sphere inside a uniform environment of radiance 1.
//!
//! Seen from far away (nearly orthographic) the sphere covers a disc of π r² out of the frame's
//! area A, and a convex object scatters every camera ray exactly once (or, for glass, until it
//! leaves), so the image mean is 1 − (π r² / A)(1 − Ē) with Ē the cosine-weighted mean of the
//! directional albedo E(μ) over the disc (the disc's pixels are distributed in μ = cos θ with
//! density 2μ). For non-absorbing BSDFs without energy loss (albedo-1 Lambertian, smooth metal with
//! F0 = 1, smooth glass) Ē = 1 and the image is uniformly 1. Rough GGX microfacets are single-
//! scattering models and lose the energy of the light that would bounce between microfacets
//! (Heitz et al. 2016, "Multiple-Scattering Microfacet BSDFs with the Smith Model"); that loss is
//! computed here from `eval` by deterministic quadrature, independently of the sampling code,
//! and the render must match it.

use std::sync::atomic::AtomicBool;
use trayecto::material::bxdf::MetallicRoughness;
use trayecto::material::{Bsdf, Material, MaterialModel, PbrtParams};
use trayecto::math::{Mat4, PI, Vec3};
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene::{CameraDesc, LightDesc, Object, Scene, Shape};
use trayecto::world::{World, WorldOptions};

const HALF_FRAME: f32 = 1.5;
const DIST: f32 = 200.0;

fn furnace_mean(material: Material, spp: u32) -> f32 {
    let vfov = 2.0 * (HALF_FRAME / DIST).atan().to_degrees();
    let scene = Scene {
        name: "furnace".into(),
        objects: vec![Object {
            name: "sphere".into(),
            shape: Shape::Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            },
            transform: Mat4::IDENTITY,
            material: 0,
            medium: None,
        }],
        materials: vec![material],
        lights: vec![LightDesc::Ambient {
            name: "env".into(),
            radiance: Vec3::ONE,
        }],
        cameras: vec![CameraDesc::look_at(
            "cam",
            Vec3::new(0.0, 0.0, DIST),
            Vec3::ZERO,
            Vec3::Y,
            vfov,
        )],
        ..Default::default()
    };
    let world = World::build(scene.clone(), &WorldOptions::default()).unwrap();
    let settings = RenderSettings {
        width: 32,
        height: 32,
        spp,
        ..Default::default()
    };
    let out = render(&world, &settings, &NoObserver, &AtomicBool::new(false)).unwrap();
    let sum: Vec3 = out.image.data.iter().copied().sum();
    (sum / out.image.data.len() as f32).dot(Vec3::splat(1.0 / 3.0))
}

/// Ē = 2 ∫ E(μ) μ dμ, with E(μ) = ∫ f cos θi dωi by midpoint quadrature in (cos θi, φi).
fn mean_albedo(bsdf: &Bsdf) -> f64 {
    let (n_mu, n_c, n_p) = (48, 384, 192);
    let mut total = 0.0;
    for i in 0..n_mu {
        let mu = (i as f64 + 0.5) / n_mu as f64;
        let wo = Vec3::new((1.0 - mu * mu).sqrt() as f32, 0.0, mu as f32);
        let mut e = 0.0;
        for a in 0..n_c {
            let c = (a as f64 + 0.5) / n_c as f64;
            let s = (1.0 - c * c).sqrt();
            for b in 0..n_p {
                // f is symmetric in φ about the plane of wo: integrate over [0, π] and double.
                let phi = PI as f64 * (b as f64 + 0.5) / n_p as f64;
                let wi = Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, c as f32);
                e += bsdf.eval(wo, wi).x as f64 * c;
            }
        }
        e *= (1.0 / n_c as f64) * (2.0 * std::f64::consts::PI / n_p as f64);
        total += 2.0 * e * mu / n_mu as f64;
    }
    total
}

fn expected_mean(e_avg: f64) -> f32 {
    let coverage = PI as f64 / (4.0 * (HALF_FRAME as f64).powi(2));
    (1.0 - coverage * (1.0 - e_avg)) as f32
}

fn metal(roughness: f32) -> Material {
    Material {
        model: MaterialModel::MetallicRoughness,
        base_color: Vec3::ONE,
        metallic: 1.0,
        roughness,
        ..Default::default()
    }
}

#[test]
fn albedo_one_diffuse_returns_the_environment() {
    let m = furnace_mean(Material::diffuse("white", Vec3::ONE), 32);
    assert!((m - 1.0).abs() < 0.005, "diffuse furnace mean {m}");
}

#[test]
fn smooth_dielectric_sphere_returns_the_environment() {
    // Every path ends by leaving the sphere: the 1/η² scalings in and out cancel, and Russian
    // roulette (on the η-corrected throughput) never kills a path of weight 1.
    let m = Material {
        model: MaterialModel::Dielectric,
        ior: 1.5,
        roughness: 0.0,
        ..Default::default()
    };
    let v = furnace_mean(m, 32);
    assert!((v - 1.0).abs() < 0.005, "glass furnace mean {v}");
}

#[test]
fn metals_lose_exactly_their_single_scattering_deficit() {
    let hit_material = |r: f32| {
        let m = metal(r);
        // Evaluate the BSDF the renderer builds (no textures, so the hit does not matter).
        Bsdf::MetallicRoughness(MetallicRoughness {
            base: Vec3::ONE,
            metallic: 1.0,
            ggx: trayecto::material::microfacet::Ggx::new(r * r),
            f0_dielectric: Vec3::splat(0.04),
            specular: m.specular,
        })
    };
    for (roughness, spp) in [(0.0f32, 16u32), (0.5, 32), (1.0, 32)] {
        let e_avg = if roughness == 0.0 {
            1.0 // α = 10⁻³: a mirror up to a loss far below the tolerance
        } else {
            mean_albedo(&hit_material(roughness))
        };
        let expected = expected_mean(e_avg);
        let got = furnace_mean(metal(roughness), spp);
        println!(
            "metal roughness {roughness}: Ē = {e_avg:.4}, image mean {got:.4} (expected {expected:.4})"
        );
        assert!(
            (got - expected).abs() < 0.006,
            "metal roughness {roughness}: image mean {got}, expected {expected} (Ē {e_avg})"
        );
        if roughness == 1.0 {
            // The size of the single-scattering loss at α = 1: about 60 % of the energy (Kulla &
            // Conty 2017, "Revisiting Physically Based Shading at Imageworks", fig. 4).
            assert!(e_avg > 0.35 && e_avg < 0.5, "Ē at roughness 1 = {e_avg}");
        }
    }
}

#[test]
fn rough_dielectric_sphere_loses_a_bounded_fraction() {
    let m = Material {
        model: MaterialModel::Dielectric,
        ior: 1.5,
        roughness: 0.5,
        ..Default::default()
    };
    let v = furnace_mean(m, 32);
    println!("rough glass (roughness 0.5) furnace mean {v}");
    assert!(v <= 1.005 && v > 0.9, "rough glass furnace mean {v}");
}

fn pbrt_material(model: MaterialModel, base: Vec3, f: impl Fn(&mut PbrtParams)) -> Material {
    let mut m = Material {
        model,
        base_color: base,
        ..Default::default()
    };
    f(&mut m.pbrt);
    m
}

#[test]
fn lossless_pbrt_materials_return_the_environment() {
    // A conductor of reflectance ~1 (pbrt's `reflectance` parameterisation, F0 = 0.9999) is a
    // perfect mirror at every angle; a diffuse-transmission sphere with R + T = 1 keeps every
    // path alive until it leaves.
    let mirror = pbrt_material(MaterialModel::Conductor, Vec3::ONE, |p| {
        p.conductor_reflectance = true;
    });
    let v = furnace_mean(mirror, 16);
    assert!((v - 1.0).abs() < 0.005, "smooth conductor furnace mean {v}");
    let sheet = pbrt_material(MaterialModel::DiffuseTransmission, Vec3::splat(0.4), |p| {
        p.transmittance = Vec3::splat(0.6);
    });
    let v = furnace_mean(sheet, 32);
    assert!(
        (v - 1.0).abs() < 0.01,
        "diffuse transmission furnace mean {v}"
    );
}

#[test]
fn rough_conductor_loses_its_single_scattering_deficit() {
    use trayecto::material::bxdf::Conductor;
    let m = pbrt_material(MaterialModel::Conductor, Vec3::ONE, |p| {
        p.conductor_reflectance = true;
        p.conductor_alpha = trayecto::math::Vec2::new(0.2, 0.6);
    });
    let (eta, k) = trayecto::material::microfacet::conductor_from_reflectance(Vec3::ONE);
    let e_avg = mean_albedo_aniso(&Bsdf::Conductor(Conductor::new(eta, k, 0.2, 0.6)));
    let expected = expected_mean(e_avg);
    let got = furnace_mean(m, 32);
    println!("anisotropic conductor: Ē = {e_avg:.4}, image mean {got:.4} (expected {expected:.4})");
    assert!(
        (got - expected).abs() < 0.008,
        "image mean {got}, expected {expected}"
    );
    // Anisotropy lies between its two isotropic bounds.
    let e_of = |a: f32| mean_albedo_aniso(&Bsdf::Conductor(Conductor::new(eta, k, a, a)));
    let (e_lo, e_hi) = (e_of(0.6), e_of(0.2));
    println!("isotropic 0.6: {e_lo:.4}, isotropic 0.2: {e_hi:.4}");
    assert!(
        e_lo < e_avg && e_avg < e_hi && e_hi < 1.0,
        "{e_lo} < {e_avg} < {e_hi}"
    );
}

#[test]
fn coated_diffuse_furnace_is_bounded() {
    // White base under a smooth coat and a clear thin layer: lossless up to the walk's depth.
    let m = pbrt_material(MaterialModel::CoatedDiffuse, Vec3::ONE, |p| {
        p.thickness = 1e-5;
        p.max_depth = 200;
    });
    let v = furnace_mean(m, 32);
    assert!(
        v <= 1.01 && v > 0.98,
        "lossless coated diffuse furnace mean {v}"
    );
    // pbrt's defaults (thickness 0.01, maxdepth 10) lose a little, never gain.
    let m = pbrt_material(MaterialModel::CoatedDiffuse, Vec3::ONE, |p| {
        p.interface_alpha = trayecto::math::Vec2::splat(0.3);
    });
    let v = furnace_mean(m, 32);
    println!("coated diffuse (pbrt defaults, rough coat) furnace mean {v}");
    assert!(v <= 1.005 && v > 0.85, "coated diffuse furnace mean {v}");
}

/// Ē for an anisotropic BSDF: like [`mean_albedo`] but over the full circle of φ and of wo's
/// azimuth.
fn mean_albedo_aniso(bsdf: &Bsdf) -> f64 {
    let (n_mu, n_az, n_c, n_p) = (24, 4, 128, 128);
    let mut total = 0.0;
    for i in 0..n_mu {
        let mu = (i as f64 + 0.5) / n_mu as f64;
        for j in 0..n_az {
            let az = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / n_az as f64;
            let s = (1.0 - mu * mu).sqrt();
            let wo = Vec3::new((s * az.cos()) as f32, (s * az.sin()) as f32, mu as f32);
            let mut e = 0.0;
            for a in 0..n_c {
                let c = (a as f64 + 0.5) / n_c as f64;
                let st = (1.0 - c * c).sqrt();
                for b in 0..n_p {
                    let phi = 2.0 * std::f64::consts::PI * (b as f64 + 0.5) / n_p as f64;
                    let wi = Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, c as f32);
                    e += bsdf.eval(wo, wi).x as f64 * c;
                }
            }
            e *= 2.0 * std::f64::consts::PI / (n_c * n_p) as f64;
            total += 2.0 * e * mu / (n_mu * n_az) as f64;
        }
    }
    total
}
