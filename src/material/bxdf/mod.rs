//! The scattering functions, one file per [`Bsdf`](super::Bsdf) variant (PBRT-v4's `bxdfs.h`
//! shape): each variant is a plain struct with `eval` (f, without the cosine), `pdf` (solid angle)
//! and `sample`, all in the local shading frame where the shading normal is +z. They must agree:
//! the chi-square tests in `tests/bsdf_chi2.rs` check every sampler against its pdf.
//!
//! To add a variant: write `bxdf/NAME.rs` with a `Copy` struct and those three methods, add a
//! tuple variant `Bsdf::Name(Name)` in `bsdf.rs` and one arm to each of its dispatch `match`es
//! (`eval`, `pdf`, `sample`, `is_specular`, `has_one_lobe`, `is_transmissive`, `eta_crossed`,
//! `albedo`), build it in `eval::Bsdf::from_material`, and add its chi-square test (and, if it is
//! reciprocal, a case of the adjoint test in `bsdf.rs`).

pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod diffuse_transmission;
pub mod gltf_transmission;
pub mod hair;
pub mod layered;
pub mod metallic_roughness;
pub mod mirror;
pub mod thin_dielectric;

pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use diffuse_transmission::DiffuseTransmission;
pub use gltf_transmission::GltfTransmission;
pub use hair::Hair;
pub use layered::Layered;
pub use metallic_roughness::MetallicRoughness;
pub use mirror::Mirror;
pub use thin_dielectric::ThinDielectric;

use crate::math::Vec3;

/// What a path carries (pbrt-v4 `TransportMode`; Veach 1997 §3.7.6, §5.2–5.3): radiance, on paths
/// traced from the camera, or importance, on paths traced from the lights. The BSDFs of this
/// module compute f for radiance; [`super::Bsdf::eval_mode`] and [`super::Bsdf::sample_mode`] give
/// the adjoint f*(wo, wi) = f(wi, wo) for importance, which differs from f(wo, wi) only by the
/// η² of refraction: radiance crossing into a medium of relative IOR η' is scaled by 1/η'²,
/// importance is not.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TransportMode {
    #[default]
    Radiance,
    Importance,
}

impl TransportMode {
    /// Veach's correction for shading normals (Veach 1997 §5.3, eq. 5.20; pbrt-v4
    /// `CorrectShadingNormal`): a BSDF evaluated against a shading normal `ns` that is not the
    /// geometric normal `ng` (interpolated normals, normal and bump maps) is not symmetric, and
    /// a path carrying importance must multiply f·|wi·ns| by
    /// |wo·ns| |wi·ng| / (|wo·ng| |wi·ns|) to transport the adjoint. 1 for radiance. All four
    /// vectors in one frame (world, or the local shading frame with `ns` = +z).
    #[inline]
    pub fn shading_normal_correction(self, wo: Vec3, wi: Vec3, ns: Vec3, ng: Vec3) -> f32 {
        match self {
            TransportMode::Radiance => 1.0,
            TransportMode::Importance => {
                let num = wo.dot(ns).abs() * wi.dot(ng).abs();
                let denom = wo.dot(ng).abs() * wi.dot(ns).abs();
                if denom == 0.0 { 0.0 } else { num / denom }
            }
        }
    }
}

/// Per channel, the relative IOR crossed from `wo` to `wi` through a refracting interface of
/// per-channel IOR `etas` (inside / outside): 1 for reflection, `etas` entering, 1/`etas`
/// leaving (the η' whose 1/η'² scales transmitted radiance).
#[inline]
pub(crate) fn eta_crossed(etas: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    if same_hemisphere(wo, wi) {
        Vec3::ONE
    } else if wo.z > 0.0 {
        etas
    } else {
        Vec3::ONE / etas
    }
}

/// A sampled incident direction with its BSDF value and pdf. It lives here, below both the
/// variants that produce it and [`super::bsdf`], which re-exports it, so that the two modules
/// import one way only.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Incident direction in the local frame.
    pub wi: Vec3,
    /// BSDF value f(wo, wi) (no cosine).
    pub f: Vec3,
    /// Solid-angle pdf; for a specular (Dirac) lobe the discrete probability of the lobe.
    pub pdf: f32,
    /// True if `wi` was chosen from a Dirac delta lobe: light sampling cannot produce it.
    pub specular: bool,
    /// Relative IOR crossed (1 for reflection); radiance was scaled by 1/eta² (importance is
    /// not: [`TransportMode`]).
    pub eta: f32,
}

impl BsdfSample {
    /// A sample from a non-Dirac lobe, or `None` when its pdf is not positive (then the
    /// direction cannot be weighted). `f` is evaluated only for a usable sample.
    #[inline]
    pub fn glossy(wi: Vec3, pdf: f32, eta: f32, f: impl FnOnce() -> Vec3) -> Option<BsdfSample> {
        if !(pdf > 0.0) {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: f(),
            pdf,
            specular: false,
            eta,
        })
    }
}

#[inline]
pub(crate) fn same_hemisphere(a: Vec3, b: Vec3) -> bool {
    a.z * b.z > 0.0
}

/// The Dirac reflection lobe of a smooth interface with reflectance `r`, chosen with
/// probability `pdf` (shared by the thick and the thin-walled dielectric).
#[inline]
pub(crate) fn fresnel_reflection_sample(wo: Vec3, r: f32, pdf: f32) -> BsdfSample {
    let wi = Vec3::new(-wo.x, -wo.y, wo.z);
    BsdfSample {
        wi,
        f: Vec3::splat(r / wi.z.abs()),
        pdf,
        specular: true,
        eta: 1.0,
    }
}
