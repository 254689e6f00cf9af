//! glTF 2.0 metallic-roughness with its KHR extensions (transmission, volume, specular,
//! clearcoat, sheen, anisotropy, iridescence, dispersion, diffuse transmission): the glTF
//! specification's layered mixture as a [`Bsdf`] at a hit.

use crate::geometry::SurfaceHit;
use crate::material::bxdf::dielectric::dispersive_iors;
use crate::material::bxdf::metallic_roughness::{Anisotropy, Extensions};
use crate::material::bxdf::{self, Dielectric, Diffuse, GltfTransmission, ThinDielectric};
use crate::material::clearcoat::Clearcoat;
use crate::material::eval::{HitTextures, base_color_in, roughness_metallic_in};
use crate::material::iridescence::Iridescence;
use crate::material::microfacet::{Ggx, MIN_ALPHA};
use crate::material::sheen::Sheen;
use crate::material::{Bsdf, Material, TextureRef};
use crate::math::{Vec2, Vec3};

/// The parameters only the metallic-roughness model reads: the glTF extensions that add lobes to
/// its BSDF. The core parameters (base colour, metallic, roughness, IOR, transmission, volume,
/// specular) stay in [`Material`]: the raycast/Whitted local shading and the medium set-up read
/// them for every model. Defaults are the extensions' (all off).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetallicRoughness {
    /// KHR_materials_clearcoat: layer weight (× texture R), roughness (× texture G) and the
    /// coat's own normal map (without one, the coat follows the unmapped vertex normal).
    pub clearcoat: f32,
    pub clearcoat_texture: Option<TextureRef>,
    pub clearcoat_roughness: f32,
    pub clearcoat_roughness_texture: Option<TextureRef>,
    pub clearcoat_normal_texture: Option<TextureRef>,
    pub clearcoat_normal_scale: f32,
    /// KHR_materials_sheen: colour (linear; × sRGB texture RGB) and roughness (× texture A).
    /// Zero colour = no sheen.
    pub sheen_color: Vec3,
    pub sheen_color_texture: Option<TextureRef>,
    pub sheen_roughness: f32,
    pub sheen_roughness_texture: Option<TextureRef>,
    /// KHR_materials_anisotropy: strength in [0, 1] (× texture B), rotation (radians, from the
    /// tangent toward the bitangent) and the direction texture (RG in [−1, 1], rotated).
    pub anisotropy: f32,
    pub anisotropy_rotation: f32,
    pub anisotropy_texture: Option<TextureRef>,
    /// KHR_materials_iridescence: factor (× texture R), thin-film IOR and thickness range in nm
    /// (the thickness texture's G picks between min and max; without it the maximum is used).
    pub iridescence: f32,
    pub iridescence_texture: Option<TextureRef>,
    pub iridescence_ior: f32,
    pub iridescence_thickness_min: f32,
    pub iridescence_thickness_max: f32,
    pub iridescence_thickness_texture: Option<TextureRef>,
    /// KHR_materials_dispersion: 20 / Abbe number (0 = none).
    pub dispersion: f32,
    /// KHR_materials_diffuse_transmission: factor (× texture A) and colour (× sRGB texture RGB).
    pub diffuse_transmission: f32,
    pub diffuse_transmission_texture: Option<TextureRef>,
    pub diffuse_transmission_color: Vec3,
    pub diffuse_transmission_color_texture: Option<TextureRef>,
    /// The η spectrum (a [`crate::spectrum::BsdfSpectra`] id) of a thin-walled transmissive
    /// sheet whose η varies with λ (pbrt's `thindielectric` with a named glass or a sampled η):
    /// spectral rendering follows it ([`crate::material::bxdf::ThinDielectric::eta_spectrum`]);
    /// RGB rendering takes the material's IOR.
    pub eta_spectrum: Option<u16>,
}

impl MetallicRoughness {
    /// No extension: what a model other than metallic-roughness has
    /// ([`Material::metallic_roughness`]).
    pub const NONE: MetallicRoughness = MetallicRoughness {
        clearcoat: 0.0,
        clearcoat_texture: None,
        clearcoat_roughness: 0.0,
        clearcoat_roughness_texture: None,
        clearcoat_normal_texture: None,
        clearcoat_normal_scale: 1.0,
        sheen_color: Vec3::ZERO,
        sheen_color_texture: None,
        sheen_roughness: 0.0,
        sheen_roughness_texture: None,
        anisotropy: 0.0,
        anisotropy_rotation: 0.0,
        anisotropy_texture: None,
        iridescence: 0.0,
        iridescence_texture: None,
        iridescence_ior: 1.3,
        iridescence_thickness_min: 100.0,
        iridescence_thickness_max: 400.0,
        iridescence_thickness_texture: None,
        dispersion: 0.0,
        diffuse_transmission: 0.0,
        diffuse_transmission_texture: None,
        diffuse_transmission_color: Vec3::ONE,
        diffuse_transmission_color_texture: None,
        eta_spectrum: None,
    };

    /// The extensions' texture slots (set or not).
    pub fn texture_slots(&self) -> [&Option<TextureRef>; 10] {
        [
            &self.clearcoat_texture,
            &self.clearcoat_roughness_texture,
            &self.clearcoat_normal_texture,
            &self.sheen_color_texture,
            &self.sheen_roughness_texture,
            &self.anisotropy_texture,
            &self.iridescence_texture,
            &self.iridescence_thickness_texture,
            &self.diffuse_transmission_texture,
            &self.diffuse_transmission_color_texture,
        ]
    }

    /// [`MetallicRoughness::texture_slots`], mutable.
    pub fn texture_slots_mut(&mut self) -> [&mut Option<TextureRef>; 10] {
        [
            &mut self.clearcoat_texture,
            &mut self.clearcoat_roughness_texture,
            &mut self.clearcoat_normal_texture,
            &mut self.sheen_color_texture,
            &mut self.sheen_roughness_texture,
            &mut self.anisotropy_texture,
            &mut self.iridescence_texture,
            &mut self.iridescence_thickness_texture,
            &mut self.diffuse_transmission_texture,
            &mut self.diffuse_transmission_color_texture,
        ]
    }

    pub(super) fn validate(&self) -> Result<(), String> {
        let vecs = [self.sheen_color, self.diffuse_transmission_color];
        let scalars = [
            self.clearcoat,
            self.clearcoat_roughness,
            self.clearcoat_normal_scale,
            self.sheen_roughness,
            self.anisotropy,
            self.anisotropy_rotation,
            self.iridescence,
            self.iridescence_ior,
            self.iridescence_thickness_min,
            self.iridescence_thickness_max,
            self.dispersion,
            self.diffuse_transmission,
        ];
        if vecs.iter().any(|v| !v.is_finite()) || scalars.iter().any(|s| !s.is_finite()) {
            return Err("has a non-finite parameter".into());
        }
        if self.sheen_color.min_element() < 0.0
            || self.diffuse_transmission_color.min_element() < 0.0
        {
            return Err("has a negative sheen or diffuse-transmission colour".into());
        }
        if self.iridescence_ior <= 0.0
            || self.iridescence_thickness_min < 0.0
            || self.iridescence_thickness_max < 0.0
            || self.dispersion < 0.0
        {
            return Err(
                "has a non-positive iridescence IOR or a negative thin-film thickness or dispersion"
                    .into(),
            );
        }
        Ok(())
    }
}

impl Default for MetallicRoughness {
    fn default() -> Self {
        MetallicRoughness::NONE
    }
}

/// The metallic-roughness BSDF of `material` (whose extensions are `x`) at the hit of `tx`;
/// `eta` is its IOR (1.5 when not positive).
#[inline]
pub(super) fn bsdf(material: &Material, x: &MetallicRoughness, tx: &HitTextures, eta: f32) -> Bsdf {
    let hit = tx.hit;
    let base = base_color_in(material, tx);
    let (roughness, mut metallic) = roughness_metallic_in(material, tx);
    let mut transmission = material.transmission;
    if transmission > 0.0
        && let Some(t) = &material.transmission_texture
    {
        // KHR_materials_transmission: the factor is multiplied by the R channel.
        transmission *= tx.sample(t).x;
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
            if let Some(b) = layered_transmission(material, x, tx, eta, roughness, base) {
                return Bsdf::GltfTransmission(b);
            }
            if material.thin_walled {
                // KHR_materials_dispersion: no effect on thin-walled materials.
                let mut sheet = ThinDielectric::new(eta, roughness, base);
                sheet.eta_spectrum = x.eta_spectrum;
                return Bsdf::ThinDielectric(sheet);
            }
            if x.dispersion > 0.0 {
                let iors = dispersive_iors(eta, x.dispersion);
                return Bsdf::Dielectric(
                    Dielectric::new(eta, roughness, base).with_dispersion(iors),
                );
            }
            return Bsdf::dielectric(eta, roughness, base);
        }
        metallic = (metallic / (1.0 - p_transmit)).min(1.0);
    }
    let r0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
    // KHR_materials_specular: colour × texture RGB (sRGB), strength × texture A.
    let mut specular_color = material.specular_color;
    if let Some(t) = &material.specular_color_texture {
        specular_color *= tx.sample(t).truncate();
    }
    let f0_dielectric = (specular_color * r0).min(Vec3::ONE);
    let mut specular = material.specular;
    if let Some(t) = &material.specular_texture {
        specular *= tx.sample(t).w;
    }
    let specular = specular.clamp(0.0, 1.0);
    let coat = clearcoat(x, tx);
    let ext = extensions(x, tx, roughness);
    if metallic == 0.0
        && (specular == 0.0 || f0_dielectric == Vec3::ZERO)
        && coat.is_none()
        && ext == Extensions::default()
    {
        // No specular lobe at all (Blender's "Specular IOR Level" 0, exported as
        // KHR_materials_specular 0): the mixture is exactly Lambertian, with the same
        // value, pdf and samples, so skip the GGX terms.
        return Bsdf::Diffuse(Diffuse { albedo: base });
    }
    Bsdf::MetallicRoughness(bxdf::MetallicRoughness {
        base,
        metallic,
        ggx: Ggx::new(roughness * roughness),
        f0_dielectric,
        specular,
        coat,
        ext,
        wo_terms: None,
    })
}

/// The transmissive component under the BRDF extensions the glTF specification layers over the
/// whole material (clearcoat, sheen, anisotropy, iridescence), or `None` when it has none of
/// them (then it is a plain [`Dielectric`] or thin sheet, as before).
fn layered_transmission(
    material: &Material,
    x: &MetallicRoughness,
    tx: &HitTextures,
    eta: f32,
    roughness: f32,
    tint: Vec3,
) -> Option<GltfTransmission> {
    let coat = clearcoat(x, tx);
    let ext = extensions(x, tx, roughness);
    if coat.is_none()
        && ext.sheen.is_none()
        && ext.anisotropy.is_none()
        && ext.iridescence.is_none()
    {
        return None;
    }
    let thin = material.thin_walled;
    let mut b = GltfTransmission::new(eta, roughness, tint, thin);
    if let Some(a) = ext.anisotropy {
        b.rough = (a.dist.alpha_x.max(a.dist.alpha_y) >= MIN_ALPHA).then_some(a);
    }
    if !thin && x.dispersion > 0.0 {
        // KHR_materials_dispersion: no effect on thin-walled materials.
        b.dispersion = Some(dispersive_iors(eta, x.dispersion));
    }
    b.iridescence = ext.iridescence;
    b.coat = coat;
    b.sheen = ext.sheen;
    Some(b)
}

/// The material's clearcoat at `hit` (KHR_materials_clearcoat: factor × texture R, roughness ×
/// texture G), `None` when its weight is zero. Its normal is +z (the shading normal) until the
/// integrator calls [`Bsdf::set_coat_normal`] with [`crate::material::eval::clearcoat_normal`].
fn clearcoat(material: &MetallicRoughness, tx: &HitTextures) -> Option<Clearcoat> {
    if !(material.clearcoat > 0.0) {
        return None;
    }
    let mut weight = material.clearcoat;
    if let Some(t) = &material.clearcoat_texture {
        weight *= tx.sample(t).x;
    }
    let mut roughness = material.clearcoat_roughness;
    if let Some(t) = &material.clearcoat_roughness_texture {
        roughness *= tx.sample(t).y;
    }
    (weight > 0.0).then(|| Clearcoat::new(weight, roughness, Vec3::Z))
}

/// The KHR extensions of the metallic-roughness lobes at `hit` (sheen, anisotropy, iridescence,
/// diffuse transmission), each off when its weight is zero. `roughness` is the base's (factor ×
/// texture), which anisotropy stretches.
fn extensions(material: &MetallicRoughness, tx: &HitTextures, roughness: f32) -> Extensions {
    let hit = tx.hit;
    let mut ext = Extensions::default();
    // KHR_materials_sheen: colour × texture RGB (sRGB), roughness × texture A.
    if material.sheen_color.max_element() > 0.0 {
        let mut color = material.sheen_color;
        if let Some(t) = &material.sheen_color_texture {
            color *= tx.sample(t).truncate();
        }
        let mut rough = material.sheen_roughness;
        if let Some(t) = &material.sheen_roughness_texture {
            rough *= tx.sample(t).w;
        }
        ext.sheen = Sheen::new(color, rough);
    }
    // KHR_materials_anisotropy: the texture's RG is a direction in [−1, 1]² (tangent space),
    // rotated by the rotation; B scales the strength. Without a texture the direction is the
    // tangent, rotated. The direction is placed in the unflipped local frame (x = tangent,
    // y = normal × tangent = bitangent × its sign); the integrator mirrors y when it flips the
    // normal (`Bsdf::flip_bitangent`).
    if material.anisotropy > 0.0 {
        let mut strength = material.anisotropy;
        let mut d = Vec2::X;
        if let Some(t) = &material.anisotropy_texture {
            let v = tx.sample(t);
            d = Vec2::new(v.x * 2.0 - 1.0, v.y * 2.0 - 1.0);
            strength *= v.z;
        }
        let (s, c) = material.anisotropy_rotation.sin_cos();
        let d = Vec2::new(c * d.x - s * d.y, s * d.x + c * d.y);
        let sign = if hit.bitangent_sign < 0.0 { -1.0 } else { 1.0 };
        if strength > 0.0 {
            ext.anisotropy = Some(Anisotropy::new(
                roughness,
                strength,
                Vec2::new(d.x, d.y * sign),
            ));
        }
    }
    // KHR_materials_iridescence: factor × texture R; thickness = mix(min, max, texture G), the
    // maximum without a texture.
    if material.iridescence > 0.0 {
        let mut factor = material.iridescence;
        if let Some(t) = &material.iridescence_texture {
            factor *= tx.sample(t).x;
        }
        let (lo, hi) = (
            material.iridescence_thickness_min,
            material.iridescence_thickness_max,
        );
        let thickness = match &material.iridescence_thickness_texture {
            Some(t) => lo + (hi - lo) * tx.sample(t).y,
            None => hi,
        };
        if factor > 0.0 {
            ext.iridescence = Some(Iridescence {
                factor: factor.clamp(0.0, 1.0),
                ior: material.iridescence_ior,
                thickness: thickness.max(0.0),
                wavelengths: None,
            });
        }
    }
    // KHR_materials_diffuse_transmission: factor × texture A, colour × texture RGB (sRGB).
    if material.diffuse_transmission > 0.0 {
        let mut factor = material.diffuse_transmission;
        if let Some(t) = &material.diffuse_transmission_texture {
            factor *= tx.sample(t).w;
        }
        let mut color = material.diffuse_transmission_color;
        if let Some(t) = &material.diffuse_transmission_color_texture {
            color *= tx.sample(t).truncate();
        }
        if factor > 0.0 {
            ext.diffuse_transmission = factor.clamp(0.0, 1.0);
            ext.diffuse_transmission_color = color.clamp(Vec3::ZERO, Vec3::ONE);
        }
    }
    ext
}

/// A uniform number in [0, 1) that is a pure function of the hit (its position and ray
/// distance): the coin that picks one component of a stochastic material mixture.
#[inline]
fn hit_coin(hit: &SurfaceHit) -> f32 {
    crate::sampling::rng::hash_floats_to_unit(&[hit.p.x, hit.p.y, hit.p.z, hit.t])
}
