//! Tangent-space normal mapping (glTF `normalTexture`; thesis §5.3.3): the shading frame at a hit
//! is rebuilt from the texel, n' = normalize(T·x·s + B·y·s + N·z) with (x, y, z) = 2·texel − 1,
//! s the normal scale, T the mesh tangent (or ∂p/∂u when the mesh has none) and
//! B = (N × T)·w the bitangent with the tangent's handedness w.
//!
//! A shading normal that is not the geometric one makes the BSDF asymmetric: paths carrying
//! importance (from the lights) correct for it with
//! [`TransportMode::shading_normal_correction`](super::bxdf::TransportMode::shading_normal_correction)
//! (Veach 1997 §5.3).

use std::cell::Cell;

use super::Material;
use super::Texture;
use super::eval::HitTextures;
use super::texture::SharedFootprint;
use crate::geometry::SurfaceHit;
use crate::math::Vec3;

/// Replaces `hit.ns` and `hit.tangent` by the normal-mapped shading frame. Leaves the hit
/// unchanged when the material has no normal map or the result would be degenerate or face away
/// from the geometric normal (which would let light leak through the surface).
#[inline]
pub fn apply_normal_map(material: &Material, textures: &[Texture], hit: &mut SurfaceHit) {
    apply_normal_map_shared(material, textures, hit, None);
}

/// [`apply_normal_map`], its lookup leaving its bilinear addressing in `shared` for the hit's
/// later lookups ([`HitTextures`]; the map does not move the uv, so the material's textures of
/// the same size read the same texel positions).
#[inline]
pub fn apply_normal_map_shared(
    material: &Material,
    textures: &[Texture],
    hit: &mut SurfaceHit,
    shared: Option<&Cell<SharedFootprint>>,
) {
    let Some(t) = &material.normal_texture else {
        return;
    };
    let c = HitTextures::new(textures, hit, shared).sample(t).truncate() * 2.0 - Vec3::ONE;
    let c = Vec3::new(
        c.x * material.normal_scale,
        c.y * material.normal_scale,
        c.z,
    );
    let n = hit.ns;
    let tangent = (hit.tangent - n * n.dot(hit.tangent)).normalize_or_zero();
    if tangent == Vec3::ZERO {
        return;
    }
    let sign = if hit.bitangent_sign < 0.0 { -1.0 } else { 1.0 };
    let bitangent = n.cross(tangent) * sign;
    let p = (tangent * c.x + bitangent * c.y + n * c.z).normalize_or_zero();
    if p == Vec3::ZERO || !p.is_finite() || p.dot(hit.ng) <= 0.0 {
        return;
    }
    hit.ns = p;
    hit.tangent = (tangent - p * p.dot(tangent)).normalize_or_zero();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{PrimRef, PrimitiveKind};
    use crate::material::TextureRef;
    use crate::math::Vec4;

    fn hit() -> SurfaceHit {
        SurfaceHit {
            t: 1.0,
            prim: PrimRef::new(PrimitiveKind::Sphere, 0),
            ..SurfaceHit::EMPTY
        }
    }

    fn material(texel: Vec4) -> (Material, Vec<Texture>) {
        let m = Material {
            normal_texture: Some(TextureRef::new(0)),
            ..Default::default()
        };
        (m, vec![Texture::constant("n", texel)])
    }

    #[test]
    fn flat_normal_map_is_identity() {
        let (m, t) = material(Vec4::new(0.5, 0.5, 1.0, 1.0));
        let mut h = hit();
        apply_normal_map(&m, &t, &mut h);
        assert!((h.ns - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn tilted_texel_tilts_along_tangent_and_bitangent() {
        // (x, y, z) = (0.6, 0, 0.8): tilted toward +T.
        let (m, t) = material(Vec4::new(0.8, 0.5, 0.9, 1.0));
        let mut h = hit();
        apply_normal_map(&m, &t, &mut h);
        assert!(
            (h.ns - Vec3::new(0.6, 0.0, 0.8)).length() < 1e-5,
            "{:?}",
            h.ns
        );
        assert!(h.tangent.dot(h.ns).abs() < 1e-5);
        // Negative handedness mirrors the bitangent.
        let (m, t) = material(Vec4::new(0.5, 0.8, 0.9, 1.0));
        let mut h = hit();
        h.bitangent_sign = -1.0;
        apply_normal_map(&m, &t, &mut h);
        assert!(
            (h.ns - Vec3::new(0.0, -0.6, 0.8)).length() < 1e-5,
            "{:?}",
            h.ns
        );
    }
}
