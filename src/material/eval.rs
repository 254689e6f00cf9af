//! A material evaluated at a hit: texture lookups (with their UV set and transform), base
//! colour, opacity for the alpha modes, emitted radiance, and the [`Bsdf`] the path tracer
//! scatters with (`Bsdf::from_material` in [`super::models`], where each model builds its own
//! from these lookups).

use super::texture::SharedFootprint;
use super::{Material, Texture, TextureRef};
use crate::geometry::{ShadingDerivatives, SurfaceHit};
use crate::math::{Vec2, Vec3, Vec4};
use std::cell::Cell;

/// Deepest chain of `mix` materials followed at one hit (the pbrt loader refuses cycles; this
/// only bounds the work for scenes built in code).
const MAX_MIX_DEPTH: u32 = 16;

/// The material that scatters at `hit` when the primitive's material is `index`: itself, or for a
/// pbrt-v4 `mix` the component chosen as `MixMaterial::ChooseMaterial` does — amount ≤ 0 gives
/// `materials[0]`, ≥ 1 `materials[1]`, otherwise `materials[1]` when amount ≥ u, where u is a
/// hash of the hit (position and ray distance, standing in for pbrt's p and ωo) and the two
/// indices. Every query of one hit (NEE, BSDF sampling, AOVs) therefore sees the same material,
/// and the expected BSDF is (1 − amount)·f₀ + amount·f₁. Nested mixes are followed.
pub fn resolve_mix<'a>(
    materials: &'a [Material],
    textures: &[Texture],
    index: u32,
    hit: &SurfaceHit,
) -> &'a Material {
    let mut m = &materials[index as usize];
    for _ in 0..MAX_MIX_DEPTH {
        let Some(mix) = m.mix() else {
            return m;
        };
        let mut amount = mix.amount;
        if let Some(t) = &mix.amount_texture {
            amount *= sample_texture(textures, t, hit).x;
        }
        let pick = if amount <= 0.0 {
            0
        } else if amount >= 1.0 {
            1
        } else {
            let [a, b] = mix.materials;
            let u = crate::sampling::rng::hash_floats_to_unit(&[
                hit.p.x,
                hit.p.y,
                hit.p.z,
                hit.t,
                f32::from_bits(a),
                f32::from_bits(b),
            ]);
            usize::from(amount >= u)
        };
        match materials.get(mix.materials[pick] as usize) {
            Some(next) => m = next,
            None => return m,
        }
    }
    m
}

/// pbrt-v4's scale of its ray differentials at 64 samples per pixel and more
/// (`max(1/8, 1/√spp)`, applied to camera rays and to `Camera::Approximate_dp_dxy`): the bump
/// map's steps and lookups use the footprint shrunk by it. The fixed 1/8 keeps the image
/// independent of the sample count (pbrt-v4's bump steps grow below 64 spp).
pub const PBRT_DIFFERENTIAL_SCALE: f32 = 0.125;

/// pbrt-v4 `BumpMap` (pbrt-v4 materials.h; Blinn 1978; PBRT §10.5.1, eq. 10.12): the surface
/// displaced along its normal, p' = p + d·n with d = scale × displacement texture R, has
/// ∂p'/∂u ≈ ∂p/∂u + (d(u + Δu, v) − d(u, v))/Δu · n + d · ∂n/∂u and likewise for v, and the
/// shading normal becomes ∂p'/∂u × ∂p'/∂v turned to the geometric normal's side. `sd` holds the
/// shading ∂p/∂u, ∂p/∂v, ∂n/∂u, ∂n/∂v in pbrt's convention (v growing up the image; see
/// [`crate::geometry::GeometryStore::pbrt_shading_derivatives`]). The d·∂n/∂u term is zero on
/// flat-shaded meshes; on a curved one it changes the bump's tilt by O(d/r), which is not small
/// where a displacement texture with values near 1 and no scale lies on a surface of radius ~1
/// (the tub's foam in Bitterli's bathroom). Leaves the hit unchanged without a displacement
/// texture or when the result is degenerate.
///
/// The steps are pbrt-v4's: with the pixel footprint (`hit.duv`, which renders of scenes with a
/// bump map always have, `World::has_bump`), Δu = ½(|∂u/∂x| + |∂u/∂y|) and Δv likewise, of the
/// footprint shrunk as pbrt-v4 shrinks its ray differentials ([`PBRT_DIFFERENTIAL_SCALE`]), and
/// the three lookups read the texture's pyramid at that footprint; without one (hits not seen
/// through a perspective camera) Δ = 0.0005, pbrt-v4's fallback. The step matters: the finite
/// difference of an image with sharp edges (tiles and their grout) grows as 1/Δ where an edge
/// falls inside it, and Bitterli's bathroom floor (a colour image of tiles read as height) is
/// 10–30 % darker with the fallback step than with pbrt-v4's.
pub fn bump(
    material: &Material,
    textures: &[Texture],
    hit: &mut SurfaceHit,
    sd: &ShadingDerivatives,
) {
    let Some(t) = &material.displacement else {
        return;
    };
    const DELTA: f32 = 0.0005;
    let scale = material.displacement_scale;
    let fp = hit.duv[t.texcoord as usize & 1] * PBRT_DIFFERENTIAL_SCALE;
    let step = |s: f32| if s > 0.0 && s.is_finite() { s } else { DELTA };
    let du = step(0.5 * (fp.x.abs() + fp.z.abs()));
    let dv = step(0.5 * (fp.y.abs() + fp.w.abs()));
    // pbrt-v4's MIP filter width is twice the largest derivative where Trayecto's lookup takes
    // one pixel's footprint (`Texture::mip_level`): the lookups get the shrunk footprint doubled.
    let mut probe = *hit;
    probe.duv = [
        hit.duv[0] * (2.0 * PBRT_DIFFERENTIAL_SCALE),
        hit.duv[1] * (2.0 * PBRT_DIFFERENTIAL_SCALE),
    ];
    // Stored uvs have v growing down the image (glTF), so pbrt's v + Δ is stored v − Δ.
    let mut d = |shift: Vec2| {
        probe.uv = [hit.uv[0] + shift, hit.uv[1] + shift];
        scale * sample_texture(textures, t, &probe).x
    };
    let d0 = d(Vec2::ZERO);
    let d_u = d(Vec2::new(du, 0.0));
    let d_v = d(Vec2::new(0.0, -dv));
    let n = hit.ns;
    let pu = sd.dpdu + n * ((d_u - d0) / du) + sd.dndu * d0;
    let pv = sd.dpdv + n * ((d_v - d0) / dv) + sd.dndv * d0;
    let mut ns = pu.cross(pv).normalize_or_zero();
    if ns == Vec3::ZERO || !ns.is_finite() {
        return;
    }
    if ns.dot(hit.ng) < 0.0 {
        ns = -ns;
    }
    hit.ns = ns;
    let tangent = (pu - ns * ns.dot(pu)).normalize_or_zero();
    if tangent != Vec3::ZERO && tangent.is_finite() {
        hit.tangent = tangent;
    }
}

/// The clearcoat's world-space normal at `hit`, which must be taken **before** the base's normal
/// map is applied: the coat's own normal map (`clearcoatNormalTexture`, tangent space, with its
/// scale) on the interpolated vertex normal, or that normal itself — the base's normal map does
/// not apply to the coat (KHR_materials_clearcoat).
pub fn clearcoat_normal(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Vec3 {
    let n = hit.ns;
    let coat = material.metallic_roughness();
    let Some(t) = &coat.clearcoat_normal_texture else {
        return n;
    };
    let c = sample_texture(textures, t, hit).truncate() * 2.0 - Vec3::ONE;
    let s = coat.clearcoat_normal_scale;
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
/// linear), each clamped to [0, 1]. Always inlined: with the procedural-texture branch in
/// [`sample_texture`] LLVM stopped inlining it (and [`base_color`]) into `Bsdf::from_material`,
/// which cost 0.9 % more instructions on the untextured Cornell box (callgrind).
#[inline(always)]
pub fn roughness_metallic(
    material: &Material,
    textures: &[Texture],
    hit: &SurfaceHit,
) -> (f32, f32) {
    roughness_metallic_in(material, &HitTextures::new(textures, hit, None))
}

/// [`roughness_metallic`] through a hit's shared lookups.
#[inline(always)]
pub(super) fn roughness_metallic_in(material: &Material, tx: &HitTextures) -> (f32, f32) {
    let (mut roughness, mut metallic) = (material.roughness, material.metallic);
    if let Some(t) = &material.metallic_roughness_texture {
        let v = tx.sample(t);
        roughness *= v.y;
        metallic *= v.z;
    }
    (roughness.clamp(0.0, 1.0), metallic.clamp(0.0, 1.0))
}

/// Base colour at a hit: factor × texture (sRGB-decoded) × vertex colour. Always inlined (see
/// [`roughness_metallic`]).
#[inline(always)]
pub fn base_color(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Vec3 {
    base_color_in(material, &HitTextures::new(textures, hit, None))
}

/// [`base_color`] through a hit's shared lookups.
#[inline(always)]
pub(super) fn base_color_in(material: &Material, tx: &HitTextures) -> Vec3 {
    let mut c = material.base_color * tx.hit.color.truncate();
    if let Some(t) = &material.base_color_texture {
        c *= tx.sample(t).truncate();
    }
    c
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

/// Reads a texture reference at a hit, applying its UV set and transform. A procedural texture
/// ([`super::procedural`]) is evaluated at the hit instead (alpha 1; its mapping replaces the
/// reference's transform).
#[inline]
pub fn sample_texture(textures: &[Texture], t: &TextureRef, hit: &SurfaceHit) -> Vec4 {
    HitTextures::new(textures, hit, None).sample(t)
}

/// The uv and its pixel derivatives at which `t` reads its image at `hit`: uv set `set`
/// through the reference's transform.
#[inline(always)]
fn texture_uv(t: &TextureRef, hit: &SurfaceHit, set: usize) -> (Vec2, Vec4) {
    let mut uv = hit.uv[set];
    let mut duv = hit.duv[set];
    if let Some(tr) = &t.transform {
        uv = tr.apply(uv);
        if duv != Vec4::ZERO {
            // The transform is affine: its linear part maps the derivatives.
            let o = tr.apply(Vec2::ZERO);
            let dx = tr.apply(Vec2::new(duv.x, duv.y)) - o;
            let dy = tr.apply(Vec2::new(duv.z, duv.w)) - o;
            duv = Vec4::new(dx.x, dx.y, dy.x, dy.y);
        }
    }
    (uv, duv)
}

/// The texture lookups of one hit, sharing their bilinear addressing: a lookup at the same uv
/// of a texture with the same size, wrap modes and layout as the previous one reuses its texel
/// addresses and weights ([`Texture::lookup_shared`]; the results are [`sample_texture`]'s bit
/// for bit). ToyCar's body reads its normal map, base colour, metallic-roughness and clearcoat
/// textures (1024², repeating, uv set 0, no transform) at every hit.
pub struct HitTextures<'a> {
    pub textures: &'a [Texture],
    pub hit: &'a SurfaceHit,
    /// The previous lookup's addressing ([`SharedFootprint::NONE`] before the hit's first);
    /// `None`: every lookup is the plain [`Texture::lookup_filtered`].
    pub shared: Option<&'a Cell<SharedFootprint>>,
}

impl<'a> HitTextures<'a> {
    #[inline(always)]
    pub fn new(
        textures: &'a [Texture],
        hit: &'a SurfaceHit,
        shared: Option<&'a Cell<SharedFootprint>>,
    ) -> HitTextures<'a> {
        HitTextures {
            textures,
            hit,
            shared,
        }
    }

    /// [`sample_texture`] of `t` at this hit.
    #[inline]
    pub fn sample(&self, t: &TextureRef) -> Vec4 {
        let set = (t.texcoord as usize).min(1);
        let tex = &self.textures[t.texture];
        if let Some(p) = &tex.procedural {
            return procedural_lookup(p, self.textures, self.hit, set);
        }
        let (uv, duv) = texture_uv(t, self.hit, set);
        match self.shared {
            Some(shared) => tex.lookup_shared(uv, duv, shared),
            None => tex.lookup_filtered(uv, duv),
        }
    }
}

/// A procedural texture at `hit`, in pbrt's (u, v) convention: stored uvs have v growing down
/// the image, so pbrt's v is 1 − v and its derivatives change sign. Kept out of line so the
/// image lookup above stays as small as it was.
#[inline(never)]
#[cold]
fn procedural_lookup(
    p: &super::procedural::Procedural,
    textures: &[Texture],
    hit: &SurfaceHit,
    set: usize,
) -> Vec4 {
    let (uv, d) = (hit.uv[set], hit.duv[set]);
    let ctx = super::procedural::TexCtx {
        uv: Vec2::new(uv.x, 1.0 - uv.y),
        duv: Vec4::new(d.x, -d.y, d.z, -d.w),
        p: hit.p,
        n: hit.ng,
    };
    p.eval(textures, &ctx).extend(1.0)
}

/// Emitted radiance of `material` at `hit` (front face only unless double-sided), toward `wo`.
#[inline]
pub fn emitted(material: &Material, textures: &[Texture], hit: &SurfaceHit, wo: Vec3) -> Vec3 {
    let unlit = material.is_unlit();
    if !material.is_emissive() && !unlit {
        return Vec3::ZERO;
    }
    if !material.double_sided && hit.ng.dot(wo) <= 0.0 {
        return Vec3::ZERO;
    }
    if unlit {
        // KHR_materials_unlit: the base colour (factor × texture × vertex colour) is the
        // radiance the surface shows.
        return base_color(material, textures, hit);
    }
    let mut e = material.emissive;
    if let Some(t) = &material.emissive_texture {
        e *= sample_texture(textures, t, hit).truncate();
    }
    e
}
