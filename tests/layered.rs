//! pbrt-v4's layered BSDF (`coateddiffuse`, `coatedconductor`). Its `eval` and `pdf` are
//! stochastic estimates, so a chi-square test of `sample` against `pdf` would not be meaningful;
//! instead:
//! * the sampled estimator of the directional albedo, mean of f cos / pdf over `sample`, must equal
//!   the albedo from quadrature of `eval` (the two share no code path beyond the interfaces);
//! * with an index-matched coat (η = 1) the layered BSDF must be exactly its Lambertian base;
//! * with a smooth coat over a Lambertian base and a thin clear layer, the random walk must
//!   converge to the closed form of the infinite series of internal reflections
//!   (1 − F(θo))(1 − F(θi)) R / (π η² (1 − R F̄ᵢₙₜ)) (Weidlich & Wilkie 2007; Mitsuba's `plastic`);
//! * white furnace: a lossless configuration (white base, clear layer, smooth coat) reflects all
//!   the light, and nothing reflects more;
//! * reciprocity f(wo, wi) = f(wi, wo), in expectation.

use trayecto::material::Bsdf;
use trayecto::material::bxdf::Conductor;
use trayecto::material::bxdf::layered::{Base, Coat, Layered};
use trayecto::material::microfacet::{Ggx, fresnel_dielectric};
use trayecto::math::{PI, Vec2, Vec3};
use trayecto::sampling::rng::Pcg32;

fn coated_diffuse(r: f32, eta: f32, alpha: f32, thickness: f32, albedo: f32) -> Layered {
    Layered {
        coat: Coat {
            eta,
            dist: Ggx::anisotropic(alpha, alpha),
            eta_spectrum: None,
        },
        base: Base::Diffuse {
            reflectance: Vec3::splat(r),
        },
        thickness,
        albedo: Vec3::splat(albedo),
        g: 0.3,
        max_depth: 100,
        n_samples: 1,
    }
}

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// ∫ eval(wo, wi) cos θi dωi by midpoint quadrature in (cos θi, φi) over the upper hemisphere.
fn albedo_quadrature(l: &Layered, wo: Vec3, nc: usize, np: usize) -> Vec3 {
    let mut e = Vec3::ZERO;
    for a in 0..nc {
        let c = (a as f32 + 0.5) / nc as f32;
        let s = (1.0 - c * c).sqrt();
        for b in 0..np {
            let phi = 2.0 * PI * (b as f32 + 0.5) / np as f32;
            let wi = Vec3::new(s * phi.cos(), s * phi.sin(), c);
            e += l.eval(wo, wi) * c;
        }
    }
    e * (2.0 * PI / (nc * np) as f32)
}

/// Mean of f cos / pdf over `n` samples (the non-specular part if `specular` is false, else only
/// the Dirac part).
fn albedo_sampled(l: &Layered, wo: Vec3, n: usize, specular: bool) -> Vec3 {
    let mut rng = Pcg32::new(7, 11);
    let mut e = Vec3::ZERO;
    for _ in 0..n {
        let uc = rng.next_f32();
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        if let Some(s) = l.sample(wo, uc, u)
            && s.specular == specular
        {
            e += s.f * s.wi.z.abs() / s.pdf;
        }
    }
    e / n as f32
}

#[test]
fn sampling_agrees_with_quadrature_of_eval() {
    let conductor = Base::Conductor(Conductor::new(
        Vec3::new(0.2, 0.9, 1.1),
        Vec3::new(3.9, 2.4, 2.2),
        0.2,
        0.2,
    ));
    let cases = [
        (
            "rough coat / diffuse",
            coated_diffuse(0.8, 1.5, 0.3, 0.01, 0.0),
        ),
        (
            "rough coat / diffuse, scattering layer",
            coated_diffuse(0.6, 1.5, 0.3, 0.1, 0.8),
        ),
        (
            "rough coat / rough conductor",
            Layered {
                base: conductor,
                ..coated_diffuse(0.0, 1.5, 0.25, 0.01, 0.0)
            },
        ),
    ];
    for (name, l) in cases {
        for wo in [dir(10.0, 0.0), dir(60.0, 30.0)] {
            let quad = albedo_quadrature(&l, wo, 128, 128);
            let sampled = albedo_sampled(&l, wo, 400_000, false);
            println!("{name} wo {wo:?}: quadrature {quad:?}, sampled {sampled:?}");
            let err = (quad - sampled).abs().max_element();
            assert!(
                err < 0.02 * quad.max_element() + 2e-3,
                "{name} at {wo:?}: quadrature of eval {quad:?} vs sampled {sampled:?}"
            );
            assert!(quad.max_element() < 1.0, "{name}: albedo {quad:?} above 1");
        }
    }
}

#[test]
fn index_matched_coat_is_its_base() {
    let l = coated_diffuse(0.7, 1.0, 0.0, 1e-6, 0.0);
    for (wo, wi) in [
        (dir(0.0, 0.0), dir(40.0, 10.0)),
        (dir(70.0, 0.0), dir(20.0, 200.0)),
    ] {
        let f = l.eval(wo, wi);
        assert!(
            (f - Vec3::splat(0.7 / PI)).abs().max_element() < 1e-5,
            "{f:?}"
        );
    }
}

/// Hemispherical cosine-weighted average of the Fresnel reflectance seen from inside the coat.
fn internal_diffuse_fresnel(eta: f32) -> f32 {
    let n = 20_000;
    let mut s = 0.0;
    for i in 0..n {
        let c = (i as f32 + 0.5) / n as f32;
        // From inside: cos measured against the inward normal, i.e. a negative cosine.
        s += fresnel_dielectric(-c, eta) * 2.0 * c / n as f32;
    }
    s
}

#[test]
fn smooth_coat_converges_to_the_closed_form() {
    let (r, eta) = (0.8f32, 1.5f32);
    let mut l = coated_diffuse(r, eta, 0.0, 1e-6, 0.0);
    // Total internal reflection makes single walks very noisy (F is 1 or ~0.05): average many.
    l.n_samples = 16384;
    let fdr = internal_diffuse_fresnel(eta);
    for (wo, wi) in [
        (dir(0.0, 0.0), dir(30.0, 0.0)),
        (dir(45.0, 0.0), dir(60.0, 120.0)),
        (dir(75.0, 0.0), dir(10.0, 300.0)),
    ] {
        let expected =
            (1.0 - fresnel_dielectric(wo.z, eta)) * (1.0 - fresnel_dielectric(wi.z, eta)) * r
                / (PI * eta * eta * (1.0 - r * fdr));
        let got = l.eval(wo, wi).x;
        println!("smooth coat {wo:?} {wi:?}: walk {got}, closed form {expected}");
        assert!(
            (got - expected).abs() < 0.02 * expected,
            "walk {got} vs closed form {expected}"
        );
    }
}

#[test]
fn lossless_layer_reflects_everything_and_no_more() {
    // White base, clear thin layer, smooth coat: light leaves eventually (the walk's max depth is
    // large), so Dirac reflection at the coat plus the diffuse part is 1.
    let mut l = coated_diffuse(1.0, 1.5, 0.0, 1e-6, 0.0);
    l.max_depth = 1000;
    for wo in [dir(0.0, 0.0), dir(50.0, 0.0), dir(80.0, 0.0)] {
        let spec = fresnel_dielectric(wo.z, 1.5);
        let diffuse = albedo_quadrature(&l, wo, 64, 32).x;
        let sampled =
            albedo_sampled(&l, wo, 200_000, false).x + albedo_sampled(&l, wo, 200_000, true).x;
        println!(
            "lossless {wo:?}: F {spec} + diffuse {diffuse} = {}, sampled {sampled}",
            spec + diffuse
        );
        assert!((spec + diffuse - 1.0).abs() < 0.02, "{}", spec + diffuse);
        assert!((sampled - 1.0).abs() < 0.01, "{sampled}");
    }
    // A rough coat loses energy (single-scattering microfacets) but never creates it.
    let mut rough = coated_diffuse(1.0, 1.5, 0.5, 1e-6, 0.0);
    rough.max_depth = 1000;
    for wo in [dir(0.0, 0.0), dir(60.0, 0.0)] {
        // (About 0.56 at α = 0.5: light trapped by total internal reflection meets the rough
        // interface many times, and each meeting loses the single-scattering deficit.)
        let e = albedo_quadrature(&rough, wo, 64, 64).x;
        println!("rough lossless coat {wo:?}: albedo {e}");
        assert!(e <= 1.0 && e > 0.45, "rough lossless coat albedo {e}");
    }
}

#[test]
fn layered_is_reciprocal_in_expectation() {
    let mut l = coated_diffuse(0.6, 1.5, 0.3, 0.05, 0.5);
    l.n_samples = 32768;
    for (a, b) in [
        (dir(20.0, 0.0), dir(60.0, 100.0)),
        (dir(70.0, 10.0), dir(5.0, 250.0)),
    ] {
        let (fab, fba) = (l.eval(a, b).x, l.eval(b, a).x);
        println!("reciprocity: f(a,b) {fab} f(b,a) {fba}");
        assert!(
            (fab - fba).abs() < 0.02 * fab.max(fba),
            "f(a,b) {fab} vs f(b,a) {fba}"
        );
    }
}

#[test]
fn layered_is_dispatched_and_deterministic() {
    let l = coated_diffuse(0.6, 1.5, 0.3, 0.05, 0.5);
    let b = Bsdf::Layered(l);
    let (wo, wi) = (dir(30.0, 0.0), dir(45.0, 90.0));
    assert_eq!(b.eval(wo, wi), b.eval(wo, wi));
    assert_eq!(b.pdf(wo, wi), l.pdf(wo, wi));
    assert!(!b.is_specular() && !b.is_transmissive());
    // The two-sided coat: seen from below it is the same material.
    assert_eq!(b.eval(-wo, -wi), b.eval(wo, wi));
}
