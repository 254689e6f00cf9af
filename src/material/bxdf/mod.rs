//! The scattering functions, one file per [`Bsdf`](super::Bsdf) variant (PBRT-v4's `bxdfs.h`
//! shape): each variant is a plain struct with `eval` (f, without the cosine), `pdf` (solid angle)
//! and `sample`, all in the local shading frame where the shading normal is +z. They must agree:
//! the chi-square tests in `tests/bsdf_chi2.rs` check every sampler against its pdf.
//!
//! To add a variant: write `bxdf/NAME.rs` with a `Copy` struct and those three methods, add a
//! tuple variant `Bsdf::Name(Name)` in `bsdf.rs` and one arm to each of its dispatch `match`es
//! (`eval`, `pdf`, `sample`, `is_specular`, `has_one_lobe`, `is_transmissive`, `albedo`), build
//! it in `eval::Bsdf::from_material`, and add its chi-square test.

pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod diffuse_transmission;
pub mod gltf_transmission;
pub mod layered;
pub mod metallic_roughness;
pub mod mirror;
pub mod thin_dielectric;

pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use diffuse_transmission::DiffuseTransmission;
pub use gltf_transmission::GltfTransmission;
pub use layered::Layered;
pub use metallic_roughness::MetallicRoughness;
pub use mirror::Mirror;
pub use thin_dielectric::ThinDielectric;

use crate::math::Vec3;

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
    /// Relative IOR crossed (1 for reflection); radiance was scaled by 1/eta².
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
