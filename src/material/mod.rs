//! Materials and textures: the surface description loaders produce (glTF metallic-roughness
//! parameters plus the thesis's extra models). [`eval`] evaluates a material at a hit (textures,
//! opacity, emission, the [`Bsdf`]); [`bsdf`] dispatches to the scattering functions of [`bxdf`],
//! one file per variant; [`local_shading`] holds the thesis's direct-lighting BRDFs of the raycast
//! and Whitted modes.

pub mod bsdf;
pub mod bxdf;
pub mod clearcoat;
pub mod eval;
pub mod local_shading;
pub mod microfacet;
pub mod normal_map;
pub mod texture;

pub use bsdf::Bsdf;
pub use texture::{Texture, TextureRef, WrapMode};

use crate::math::{Vec2, Vec3};

/// How the path tracer scatters light at the surface.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum MaterialModel {
    /// Lambertian reflection of the base colour.
    #[default]
    Diffuse,
    /// glTF 2.0 metallic-roughness (with transmission when `transmission > 0`).
    MetallicRoughness,
    /// Smooth or rough dielectric (glass); the thesis's `refractive` material.
    Dielectric,
    /// Perfect mirror.
    Mirror,
    /// pbrt-v4 `conductor`: exact Fresnel of η + i k per channel ([`PbrtParams::conductor_eta`],
    /// `conductor_k`, or the base colour as `reflectance` when `conductor_reflectance`), smooth or
    /// anisotropic GGX with α = [`PbrtParams::conductor_alpha`].
    Conductor,
    /// pbrt-v4 `coateddiffuse`: a dielectric coat over a Lambertian base of the base colour.
    CoatedDiffuse,
    /// pbrt-v4 `coatedconductor`: a dielectric coat over the conductor of `Conductor`.
    CoatedConductor,
    /// pbrt-v4 `diffusetransmission`: Lambertian reflection of the base colour and Lambertian
    /// transmission of [`PbrtParams::transmittance`].
    DiffuseTransmission,
}

/// Parameters of the pbrt-v4 models ([`MaterialModel::Conductor`], `CoatedDiffuse`,
/// `CoatedConductor`, `DiffuseTransmission`). Roughnesses are GGX α already (apply
/// [`microfacet::pbrt_roughness_to_alpha`] for pbrt's `remaproughness`); x is along the tangent
/// (pbrt's `uroughness`), y along the bitangent (`vroughness`). Defaults are pbrt-v4's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PbrtParams {
    /// Conductor η and k per linear-sRGB channel (default: pbrt's `metal-Cu-eta`/`metal-Cu-k`
    /// converted by [`crate::spectrum`]).
    pub conductor_eta: Vec3,
    pub conductor_k: Vec3,
    /// Use the base colour (× texture) as pbrt's `reflectance` instead of η/k.
    pub conductor_reflectance: bool,
    pub conductor_alpha: Vec2,
    /// The coat: relative IOR and GGX α (pbrt `interface.eta`/`interface.roughness` for
    /// `coatedconductor`, `eta`/`roughness` for `coateddiffuse`).
    pub interface_eta: f32,
    pub interface_alpha: Vec2,
    /// Slab between coat and base: thickness (σt = 1), medium albedo and HG asymmetry g.
    pub thickness: f32,
    pub albedo: Vec3,
    pub g: f32,
    /// Random-walk length and walks per evaluation of the layered BSDF.
    pub max_depth: u32,
    pub n_samples: u32,
    /// Lambertian transmittance of `diffusetransmission`.
    pub transmittance: Vec3,
}

impl Default for PbrtParams {
    fn default() -> Self {
        let (eta, k) =
            crate::spectrum::named_conductor_rgb("metal-Cu").unwrap_or((Vec3::ONE, Vec3::ZERO));
        PbrtParams {
            conductor_eta: eta,
            conductor_k: k,
            conductor_reflectance: false,
            conductor_alpha: Vec2::ZERO,
            interface_eta: 1.5,
            interface_alpha: Vec2::ZERO,
            thickness: 0.01,
            albedo: Vec3::ZERO,
            g: 0.0,
            max_depth: 10,
            n_samples: 1,
            transmittance: Vec3::splat(0.25),
        }
    }
}

impl PbrtParams {
    fn validate(&self) -> Result<(), String> {
        let vecs = [
            self.conductor_eta,
            self.conductor_k,
            self.albedo,
            self.transmittance,
        ];
        let scalars = [
            self.conductor_alpha.x,
            self.conductor_alpha.y,
            self.interface_alpha.x,
            self.interface_alpha.y,
            self.interface_eta,
            self.thickness,
            self.g,
        ];
        if vecs.iter().any(|v| !v.is_finite()) || scalars.iter().any(|s| !s.is_finite()) {
            return Err("has a non-finite pbrt parameter".into());
        }
        if vecs.iter().any(|v| v.min_element() < 0.0)
            || self.conductor_alpha.min_element() < 0.0
            || self.interface_alpha.min_element() < 0.0
        {
            return Err("has a negative eta, k, albedo, transmittance or roughness".into());
        }
        if self.interface_eta <= 0.0 {
            return Err(format!(
                "coat eta must be positive (got {})",
                self.interface_eta
            ));
        }
        if self.thickness <= 0.0 {
            return Err(format!(
                "layer thickness must be positive (got {})",
                self.thickness
            ));
        }
        if !(-1.0 < self.g && self.g < 1.0) {
            return Err(format!("layer g must be in (-1, 1) (got {})", self.g));
        }
        if self.albedo.max_element() > 1.0 {
            return Err("layer albedo must be at most 1".into());
        }
        if self.max_depth == 0
            || self.max_depth > 1000
            || self.n_samples == 0
            || self.n_samples > 1000
        {
            return Err(format!(
                "layer maxdepth and nsamples must be in 1..=1000 (got {}, {})",
                self.max_depth, self.n_samples
            ));
        }
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AlphaMode {
    #[default]
    Opaque,
    Mask,
    Blend,
}

/// Parameters for the Phong / Blinn-Phong models of the raycast and Whitted modes (thesis §5.1.10).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhongParams {
    pub specular: Vec3,
    pub shininess: f32,
}

/// A material, in the glTF metallic-roughness vocabulary (docs/DESIGN.md §3–4). Colour factors are linear RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub model: MaterialModel,
    pub base_color: Vec3,
    pub base_color_texture: Option<TextureRef>,
    /// Opacity (glTF base colour alpha, OBJ `d`).
    pub alpha: f32,
    pub alpha_mode: AlphaMode,
    pub alpha_cutoff: f32,
    pub metallic: f32,
    pub roughness: f32,
    /// Roughness in G, metalness in B (glTF).
    pub metallic_roughness_texture: Option<TextureRef>,
    pub normal_texture: Option<TextureRef>,
    pub normal_scale: f32,
    pub occlusion_texture: Option<TextureRef>,
    pub occlusion_strength: f32,
    /// Emitted radiance factor (already multiplied by any emissive strength).
    pub emissive: Vec3,
    pub emissive_texture: Option<TextureRef>,
    pub transmission: f32,
    pub transmission_texture: Option<TextureRef>,
    pub ior: f32,
    /// glTF transmission without KHR_materials_volume: an infinitely thin sheet.
    pub thin_walled: bool,
    /// KHR_materials_specular.
    pub specular: f32,
    pub specular_color: Vec3,
    pub double_sided: bool,
    /// Phong parameters for the raycast/Whitted modes, when the file gives them.
    pub phong: Option<PhongParams>,
    // Inputs the importers fill that the first BSDFs do not use yet (issue 8).
    /// KHR_materials_specular: strength in A, colour (sRGB) in RGB.
    pub specular_texture: Option<TextureRef>,
    pub specular_color_texture: Option<TextureRef>,
    /// KHR_materials_volume: thickness (object space; 0 = thin walled), Beer-Lambert attenuation
    /// colour and distance (infinite = no absorption).
    pub thickness: f32,
    pub attenuation_color: Vec3,
    pub attenuation_distance: f32,
    /// Opacity map (OBJ `map_d`), first channel.
    pub alpha_texture: Option<TextureRef>,
    /// Parameters of the pbrt-v4 models (unused by the others).
    pub pbrt: PbrtParams,
    /// KHR_materials_clearcoat: layer weight (× texture R), roughness (× texture G) and the
    /// coat's own normal map (without one, the coat follows the unmapped vertex normal).
    pub clearcoat: f32,
    pub clearcoat_texture: Option<TextureRef>,
    pub clearcoat_roughness: f32,
    pub clearcoat_roughness_texture: Option<TextureRef>,
    pub clearcoat_normal_texture: Option<TextureRef>,
    pub clearcoat_normal_scale: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            name: String::new(),
            model: MaterialModel::Diffuse,
            base_color: Vec3::splat(0.8),
            base_color_texture: None,
            alpha: 1.0,
            alpha_mode: AlphaMode::Opaque,
            alpha_cutoff: 0.5,
            metallic: 0.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            occlusion_texture: None,
            occlusion_strength: 1.0,
            emissive: Vec3::ZERO,
            emissive_texture: None,
            transmission: 0.0,
            transmission_texture: None,
            ior: 1.5,
            thin_walled: false,
            specular: 1.0,
            specular_color: Vec3::ONE,
            double_sided: false,
            phong: None,
            specular_texture: None,
            specular_color_texture: None,
            thickness: 0.0,
            attenuation_color: Vec3::ONE,
            attenuation_distance: f32::INFINITY,
            alpha_texture: None,
            pbrt: PbrtParams::default(),
            clearcoat: 0.0,
            clearcoat_texture: None,
            clearcoat_roughness: 0.0,
            clearcoat_roughness_texture: None,
            clearcoat_normal_texture: None,
            clearcoat_normal_scale: 1.0,
        }
    }
}

impl Material {
    pub fn diffuse(name: &str, color: Vec3) -> Material {
        Material {
            name: name.to_string(),
            base_color: color,
            ..Default::default()
        }
    }

    pub fn is_emissive(&self) -> bool {
        self.emissive.max_element() > 0.0
    }

    /// Rejects parameters that would produce NaNs or reference missing textures.
    pub fn validate(&self, texture_count: usize) -> Result<(), String> {
        let vecs = [self.base_color, self.emissive, self.specular_color];
        let scalars = [
            self.alpha,
            self.alpha_cutoff,
            self.metallic,
            self.roughness,
            self.normal_scale,
            self.occlusion_strength,
            self.transmission,
            self.ior,
            self.specular,
            self.clearcoat,
            self.clearcoat_roughness,
            self.clearcoat_normal_scale,
        ];
        if vecs.iter().any(|v| !v.is_finite()) || scalars.iter().any(|s| !s.is_finite()) {
            return Err("has a non-finite parameter".into());
        }
        if self.base_color.min_element() < 0.0 || self.emissive.min_element() < 0.0 {
            return Err("has a negative colour".into());
        }
        self.pbrt.validate()?;
        if self.ior <= 0.0 {
            return Err(format!(
                "index of refraction must be positive (got {})",
                self.ior
            ));
        }
        let texs = [
            &self.base_color_texture,
            &self.metallic_roughness_texture,
            &self.normal_texture,
            &self.occlusion_texture,
            &self.emissive_texture,
            &self.transmission_texture,
            &self.specular_texture,
            &self.specular_color_texture,
            &self.alpha_texture,
            &self.clearcoat_texture,
            &self.clearcoat_roughness_texture,
            &self.clearcoat_normal_texture,
        ];
        for t in texs.into_iter().flatten() {
            if t.texture >= texture_count {
                return Err(format!("references missing texture {}", t.texture));
            }
        }
        Ok(())
    }
}
