//! A material evaluated at a hit: texture lookups (with their UV set and transform), base
//! colour, opacity for the alpha modes, emitted radiance, and the [`Bsdf`] the path tracer
//! scatters with (`Bsdf::from_material`).

use super::bxdf::layered::{Base, Coat};
use super::bxdf::{Conductor, Diffuse, DiffuseTransmission, Layered, MetallicRoughness, Mirror};
use super::clearcoat::Clearcoat;
use super::microfacet::{AnisoGgx, Ggx, conductor_from_reflectance};
use super::{Bsdf, Material, MaterialModel, Texture, TextureRef};
use crate::geometry::SurfaceHit;
use crate::math::{Vec3, Vec4};

impl Bsdf {
    /// Builds the BSDF of `material` at `hit`, reading its textures.
    pub fn from_material(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Bsdf {
        let base = base_color(material, textures, hit);
        let (roughness, mut metallic) = roughness_metallic(material, textures, hit);
        let eta = if material.ior > 0.0 {
            material.ior
        } else {
            1.5
        };
        let p = &material.pbrt;
        let conductor = || {
            let (eta, k) = if p.conductor_reflectance {
                conductor_from_reflectance(base)
            } else {
                (p.conductor_eta, p.conductor_k)
            };
            Conductor::new(eta, k, p.conductor_alpha.x, p.conductor_alpha.y)
        };
        let layered = |base: Base| {
            Bsdf::Layered(Layered {
                coat: Coat {
                    eta: p.interface_eta,
                    dist: AnisoGgx::new(p.interface_alpha.x, p.interface_alpha.y),
                },
                base,
                thickness: p.thickness,
                albedo: p.albedo,
                g: p.g,
                max_depth: p.max_depth,
                n_samples: p.n_samples,
            })
        };
        match material.model {
            MaterialModel::Conductor => Bsdf::Conductor(conductor()),
            MaterialModel::CoatedDiffuse => layered(Base::Diffuse { reflectance: base }),
            MaterialModel::CoatedConductor => layered(Base::Conductor(conductor())),
            MaterialModel::DiffuseTransmission => Bsdf::DiffuseTransmission(DiffuseTransmission {
                reflectance: base,
                transmittance: p.transmittance,
            }),
            MaterialModel::Diffuse => Bsdf::Diffuse(Diffuse { albedo: base }),
            MaterialModel::Mirror => Bsdf::Mirror(Mirror { color: base }),
            MaterialModel::Dielectric => Bsdf::dielectric(eta, roughness, Vec3::ONE),
            MaterialModel::MetallicRoughness => {
                let mut transmission = material.transmission;
                if transmission > 0.0
                    && let Some(t) = &material.transmission_texture
                {
                    // KHR_materials_transmission: the factor is multiplied by the R channel.
                    transmission *= sample_texture(textures, t, hit).x;
                }
                // KHR_materials_transmission replaces the diffuse lobe of the dielectric part:
                //   mix(mix(dielectric(diffuse), transmissive, t), metal, metallic).
                // The transmissive component (a dielectric interface tinted by the base colour,
                // thin-walled without KHR_materials_volume) is chosen stochastically with
                // probability (1 − metallic)·t, an unbiased one-sample estimate of the mixture
                // (the coin is a hash of the hit, so NEE and BSDF sampling at this vertex see the
                // same component). The rest is the metallic-roughness BRDF with the metallic
                // weight renormalised: metallic' = metallic / (1 − (1 − metallic)·t).
                let p_transmit = transmission.clamp(0.0, 1.0) * (1.0 - metallic);
                if p_transmit > 0.0 {
                    if p_transmit >= 1.0 || hit_coin(hit) < p_transmit {
                        if material.thin_walled {
                            return Bsdf::thin_dielectric(eta, roughness, base);
                        }
                        return Bsdf::dielectric(eta, roughness, base);
                    }
                    metallic = (metallic / (1.0 - p_transmit)).min(1.0);
                }
                let r0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
                let f0_dielectric = (material.specular_color * r0).min(Vec3::ONE);
                let specular = material.specular.clamp(0.0, 1.0);
                let coat = clearcoat(material, textures, hit);
                if metallic == 0.0
                    && (specular == 0.0 || f0_dielectric == Vec3::ZERO)
                    && coat.is_none()
                {
                    // No specular lobe at all (Blender's "Specular IOR Level" 0, exported as
                    // KHR_materials_specular 0): the mixture is exactly Lambertian, with the same
                    // value, pdf and samples, so skip the GGX terms.
                    return Bsdf::Diffuse(Diffuse { albedo: base });
                }
                Bsdf::MetallicRoughness(MetallicRoughness {
                    base,
                    metallic,
                    ggx: Ggx::new(roughness * roughness),
                    f0_dielectric,
                    specular,
                    coat,
                })
            }
        }
    }
}

/// The material's clearcoat at `hit` (KHR_materials_clearcoat: factor × texture R, roughness ×
/// texture G), `None` when its weight is zero. Its normal is +z (the shading normal) until the
/// integrator calls [`Bsdf::set_coat_normal`] with [`clearcoat_normal`].
fn clearcoat(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Option<Clearcoat> {
    if !(material.clearcoat > 0.0) {
        return None;
    }
    let mut weight = material.clearcoat;
    if let Some(t) = &material.clearcoat_texture {
        weight *= sample_texture(textures, t, hit).x;
    }
    let mut roughness = material.clearcoat_roughness;
    if let Some(t) = &material.clearcoat_roughness_texture {
        roughness *= sample_texture(textures, t, hit).y;
    }
    (weight > 0.0).then(|| Clearcoat::new(weight, roughness, Vec3::Z))
}

/// The clearcoat's world-space normal at `hit`, which must be taken **before** the base's normal
/// map is applied: the coat's own normal map (`clearcoatNormalTexture`, tangent space, with its
/// scale) on the interpolated vertex normal, or that normal itself — the base's normal map does
/// not apply to the coat (KHR_materials_clearcoat).
pub fn clearcoat_normal(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Vec3 {
    let n = hit.ns;
    let Some(t) = &material.clearcoat_normal_texture else {
        return n;
    };
    let c = sample_texture(textures, t, hit).truncate() * 2.0 - Vec3::ONE;
    let s = material.clearcoat_normal_scale;
    let tangent = (hit.tangent - n * n.dot(hit.tangent)).normalize_or_zero();
    if tangent == Vec3::ZERO {
        return n;
    }
    let sign = if hit.bitangent_sign < 0.0 { -1.0 } else { 1.0 };
    let bitangent = n.cross(tangent) * sign;
    let p = (tangent * (c.x * s) + bitangent * (c.y * s) + n * c.z).normalize_or_zero();
    if p == Vec3::ZERO || !p.is_finite() || p.dot(hit.ng) <= 0.0 {
        return n;
    }
    p
}

/// Roughness and metalness at a hit, factors × texture (glTF: roughness in G, metalness in B,
/// linear), each clamped to [0, 1].
#[inline]
pub fn roughness_metallic(
    material: &Material,
    textures: &[Texture],
    hit: &SurfaceHit,
) -> (f32, f32) {
    let (mut roughness, mut metallic) = (material.roughness, material.metallic);
    if let Some(t) = &material.metallic_roughness_texture {
        let v = sample_texture(textures, t, hit);
        roughness *= v.y;
        metallic *= v.z;
    }
    (roughness.clamp(0.0, 1.0), metallic.clamp(0.0, 1.0))
}

/// Base colour at a hit: factor × texture (sRGB-decoded) × vertex colour.
pub fn base_color(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Vec3 {
    let mut c = material.base_color * hit.color.truncate();
    if let Some(t) = &material.base_color_texture {
        c *= sample_texture(textures, t, hit).truncate();
    }
    c
}

/// A uniform number in [0, 1) that is a pure function of the hit (its position and ray
/// distance): the coin that picks one component of a stochastic material mixture.
#[inline]
fn hit_coin(hit: &SurfaceHit) -> f32 {
    crate::sampling::rng::hash_floats_to_unit(&[hit.p.x, hit.p.y, hit.p.z, hit.t])
}

/// Opacity at a hit (glTF: base colour factor alpha × texture alpha × vertex colour alpha; OBJ
/// `d` × `map_d`), used by the alpha MASK and BLEND modes.
#[inline]
pub fn opacity(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> f32 {
    let mut a = material.alpha * hit.color.w;
    if let Some(t) = &material.base_color_texture {
        a *= sample_texture(textures, t, hit).w;
    }
    if let Some(t) = &material.alpha_texture {
        a *= sample_texture(textures, t, hit).x;
    }
    a
}

/// Reads a texture reference at a hit, applying its UV set and transform.
#[inline]
pub fn sample_texture(textures: &[Texture], t: &TextureRef, hit: &SurfaceHit) -> Vec4 {
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
