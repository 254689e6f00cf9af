//! Materials and textures: the surface description loaders produce, a [`Material`] holding one
//! of the models of [`models`] (glTF metallic-roughness, pbrt-v4's, the thesis's) with its own
//! parameters. [`eval`] evaluates a material at a hit (textures, opacity, emission, the [`Bsdf`]
//! each model builds); [`bsdf`] dispatches to the scattering functions of [`bxdf`],
//! one file per variant; [`local_shading`] holds the thesis's direct-lighting BRDFs of the raycast
//! and Whitted modes.

pub mod bsdf;
pub mod bxdf;
pub mod clearcoat;
pub mod eval;
pub mod iridescence;
pub mod local_shading;
pub mod microfacet;
pub mod models;
pub mod normal_map;
pub mod procedural;
pub mod sheen;
mod sheen_table;
pub mod texture;

pub use bsdf::Bsdf;
pub use models::{MaterialModel, MetallicRoughness, Mix, RoughnessTextures};
pub use texture::{Texture, TextureRef, WrapMode};

use crate::math::Vec3;

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

/// A material (docs/DESIGN.md §3–4): its scattering model with that model's own parameters
/// ([`MaterialModel`], one file per model in [`models`]), and what is shared by every model or read
/// for every model — name, emission, opacity, normal and bump maps, double-sidedness, ambient
/// occlusion, and the glTF core (base colour, metallic, roughness, IOR, transmission, volume,
/// specular) that the raycast/Whitted local shading, the albedo AOV and the medium set-up read
/// whatever the model. Colour factors are linear RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub model: MaterialModel,
    /// Base colour factor: the albedo of the diffuse models, the reflectance of a conductor given
    /// as `reflectance`, the tint of glTF transmission, an unlit surface's radiance.
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
    /// pbrt-v4 `displacement`: a float texture (R channel × `displacement_scale`) that bump-maps
    /// the shading normal of any model (pbrt-v4 `BumpMap`, see [`eval::bump`]).
    pub displacement: Option<TextureRef>,
    pub displacement_scale: f32,
    /// The spectrum of `emissive` when the scene gave one (a pbrt-v4 `blackbody`, named or
    /// sampled `L`), which spectral rendering evaluates per wavelength; `emissive` is its RGB
    /// projection, what RGB mode uses. `None`: an RGB emission, upsampled in spectral mode.
    pub emission_spectrum: Option<crate::spectrum::Illuminant>,
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
            displacement: None,
            displacement_scale: 1.0,
            emission_spectrum: None,
        }
    }
}

/// Every texture slot of a [`Material`] outside its model's parameters, listed once (the model's
/// own are [`MaterialModel::texture_slots`]): validation, a TOML include's index shift and
/// `trayecto info` walk this list, so a new slot cannot be forgotten by one of them.
macro_rules! texture_slots {
    ($m:expr, $($borrow:tt)+) => {
        [
            $($borrow)+ $m.base_color_texture,
            $($borrow)+ $m.metallic_roughness_texture,
            $($borrow)+ $m.normal_texture,
            $($borrow)+ $m.occlusion_texture,
            $($borrow)+ $m.emissive_texture,
            $($borrow)+ $m.transmission_texture,
            $($borrow)+ $m.specular_texture,
            $($borrow)+ $m.specular_color_texture,
            $($borrow)+ $m.alpha_texture,
            $($borrow)+ $m.displacement,
        ]
    };
}

impl Material {
    /// The textures this material references (every slot that is set).
    pub fn texture_refs(&self) -> impl Iterator<Item = &TextureRef> {
        texture_slots!(self, &)
            .into_iter()
            .chain(self.model.texture_slots())
            .flatten()
    }

    /// [`Material::texture_refs`], mutable (e.g. to shift indices when scenes are merged).
    pub fn texture_refs_mut(&mut self) -> impl Iterator<Item = &mut TextureRef> {
        texture_slots!(self, &mut)
            .into_iter()
            .chain(self.model.texture_slots_mut())
            .flatten()
    }

    pub fn diffuse(name: &str, color: Vec3) -> Material {
        Material {
            name: name.to_string(),
            base_color: color,
            ..Default::default()
        }
    }

    /// The glTF extensions of a metallic-roughness material ([`MaterialModel::MetallicRoughness`]);
    /// none ([`MetallicRoughness::NONE`]) for every other model.
    #[inline]
    pub fn metallic_roughness(&self) -> &MetallicRoughness {
        match &self.model {
            MaterialModel::MetallicRoughness(x) => x,
            _ => &MetallicRoughness::NONE,
        }
    }

    /// [`Material::metallic_roughness`], mutable; `None` for another model.
    #[inline]
    pub fn metallic_roughness_mut(&mut self) -> Option<&mut MetallicRoughness> {
        match &mut self.model {
            MaterialModel::MetallicRoughness(x) => Some(x),
            _ => None,
        }
    }

    /// The choice of a pbrt-v4 `mix` ([`MaterialModel::Mix`]), `None` for every other model.
    #[inline]
    pub fn mix(&self) -> Option<Mix> {
        match self.model {
            MaterialModel::Mix(mix) => Some(mix),
            _ => None,
        }
    }

    /// KHR_materials_unlit: the surface shows its base colour and scatters nothing.
    #[inline]
    pub fn is_unlit(&self) -> bool {
        // A discriminant test: the derived `PartialEq` of the whole model is an out-of-line call
        // comparing every field, and this runs at every hit (`World::emitted`).
        matches!(self.model, MaterialModel::Unlit)
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
            self.displacement_scale,
        ];
        if vecs.iter().any(|v| !v.is_finite()) || scalars.iter().any(|s| !s.is_finite()) {
            return Err("has a non-finite parameter".into());
        }
        if self.base_color.min_element() < 0.0 || self.emissive.min_element() < 0.0 {
            return Err("has a negative colour".into());
        }
        self.model.validate()?;
        if self.ior <= 0.0 {
            return Err(format!(
                "index of refraction must be positive (got {})",
                self.ior
            ));
        }
        for t in self.texture_refs() {
            if t.texture >= texture_count {
                return Err(format!("references missing texture {}", t.texture));
            }
        }
        Ok(())
    }
}
