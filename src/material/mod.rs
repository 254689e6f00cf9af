//! Materials and textures: the surface description loaders produce (glTF metallic-roughness
//! parameters plus the thesis's extra models). [`eval`] evaluates a material at a hit (textures,
//! opacity, emission, the [`Bsdf`]); [`bsdf`] dispatches to the scattering functions of [`bxdf`],
//! one file per variant; [`local_shading`] holds the thesis's direct-lighting BRDFs of the raycast
//! and Whitted modes.

pub mod bsdf;
pub mod bxdf;
pub mod eval;
pub mod local_shading;
pub mod microfacet;
pub mod normal_map;
pub mod texture;

pub use bsdf::Bsdf;
pub use texture::{Texture, TextureRef, WrapMode};

use crate::math::Vec3;

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
    /// No surface at all: an index-matched boundary that only separates participating media
    /// (pbrt-v4's `interface` material, Mitsuba's `null` BSDF). The volumetric path tracer passes
    /// rays straight through it without counting a bounce; the other integrators see it as an
    /// index-matched (η = 1) smooth dielectric, which transmits every ray unchanged.
    Interface,
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
        ];
        if vecs.iter().any(|v| !v.is_finite()) || scalars.iter().any(|s| !s.is_finite()) {
            return Err("has a non-finite parameter".into());
        }
        if self.base_color.min_element() < 0.0 || self.emissive.min_element() < 0.0 {
            return Err("has a negative colour".into());
        }
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
        ];
        for t in texs.into_iter().flatten() {
            if t.texture >= texture_count {
                return Err(format!("references missing texture {}", t.texture));
            }
        }
        Ok(())
    }
}
