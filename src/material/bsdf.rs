//! Scattering functions, evaluated in the local shading frame where the shading normal is +z.
//! Each BSDF provides `eval` (f, without the cosine), `pdf` (solid angle) and `sample`, which must
//! agree: the chi-square tests in `tests/sampling_chi2.rs` check every sampler against its pdf.
//!
//! Two-sided shading (SPEC §4): for opaque materials the integrator builds the frame around the
//! normal flipped to the side the ray arrived from, so `wo.z > 0` always and no `abs()` is taken.

use super::{Material, MaterialModel, Texture};
use crate::geometry::SurfaceHit;
use crate::math::{INV_PI, Vec2, Vec3};
use crate::sampling::warp;

#[derive(Clone, Copy, Debug)]
pub enum Bsdf {
    /// Lambertian reflection with the given albedo.
    Diffuse { albedo: Vec3 },
}

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
}

#[inline]
fn same_hemisphere(a: Vec3, b: Vec3) -> bool {
    a.z * b.z > 0.0
}

impl Bsdf {
    /// Builds the BSDF of `material` at `hit`, reading its textures.
    pub fn from_material(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Bsdf {
        let base = base_color(material, textures, hit);
        match material.model {
            MaterialModel::Diffuse
            | MaterialModel::MetallicRoughness
            | MaterialModel::Dielectric
            | MaterialModel::Mirror => Bsdf::Diffuse { albedo: base },
        }
    }

    /// True if every lobe is a Dirac delta (light sampling is pointless).
    #[inline]
    pub fn is_specular(&self) -> bool {
        match self {
            Bsdf::Diffuse { .. } => false,
        }
    }

    /// True if the BSDF transmits: its frame must keep the geometric orientation.
    #[inline]
    pub fn is_transmissive(&self) -> bool {
        false
    }

    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self {
            Bsdf::Diffuse { albedo } => {
                if same_hemisphere(wo, wi) && wo.z > 0.0 {
                    *albedo * INV_PI
                } else {
                    Vec3::ZERO
                }
            }
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Bsdf::Diffuse { .. } => {
                if same_hemisphere(wo, wi) && wo.z > 0.0 {
                    warp::cosine_hemisphere_pdf(wi.z)
                } else {
                    0.0
                }
            }
        }
    }

    /// Samples an incident direction. `u_lobe` chooses among lobes, `u` the direction.
    #[inline]
    pub fn sample(&self, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        match self {
            Bsdf::Diffuse { albedo } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let wi = warp::cosine_hemisphere(u);
                let pdf = warp::cosine_hemisphere_pdf(wi.z);
                if pdf <= 0.0 {
                    return None;
                }
                Some(BsdfSample {
                    wi,
                    f: *albedo * INV_PI,
                    pdf,
                    specular: false,
                })
            }
        }
    }

    /// Hemispherical albedo estimate used by the raycast `albedo` view and RR heuristics.
    pub fn albedo(&self) -> Vec3 {
        match self {
            Bsdf::Diffuse { albedo } => *albedo,
        }
    }
}

/// Base colour at a hit: factor × texture (sRGB-decoded) × vertex colour.
pub fn base_color(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Vec3 {
    let mut c = material.base_color * hit.color.truncate();
    if let Some(t) = &material.base_color_texture {
        c *= sample_texture(textures, t, hit).truncate();
    }
    c
}

/// Reads a texture reference at a hit, applying its UV set and transform.
#[inline]
pub fn sample_texture(
    textures: &[Texture],
    t: &super::TextureRef,
    hit: &SurfaceHit,
) -> crate::math::Vec4 {
    let mut uv = hit.uv[(t.texcoord as usize).min(1)];
    if let Some(tr) = &t.transform {
        uv = tr.apply(uv);
    }
    textures[t.texture].lookup(uv)
}

/// Emitted radiance of `material` at `hit` (front face only unless double-sided), toward `wo`.
#[inline]
pub fn emitted(material: &Material, textures: &[Texture], hit: &SurfaceHit, wo: Vec3) -> Vec3 {
    if !material.is_emissive() {
        return Vec3::ZERO;
    }
    if !material.double_sided && hit.ng.dot(wo) <= 0.0 {
        return Vec3::ZERO;
    }
    let mut e = material.emissive;
    if let Some(t) = &material.emissive_texture {
        e *= sample_texture(textures, t, hit).truncate();
    }
    e
}
