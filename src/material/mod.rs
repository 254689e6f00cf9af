//! Materials and textures: the surface description loaders produce (glTF metallic-roughness
//! parameters plus the thesis's extra models). [`eval`] evaluates a material at a hit (textures,
//! opacity, emission, the [`Bsdf`]); [`bsdf`] dispatches to the scattering functions of [`bxdf`],
//! one file per variant; [`local_shading`] holds the thesis's direct-lighting BRDFs of the raycast
//! and Whitted modes.

pub mod bsdf;
pub mod bxdf;
pub mod clearcoat;
pub mod eval;
pub mod iridescence;
pub mod local_shading;
pub mod microfacet;
pub mod normal_map;
pub mod procedural;
pub mod sheen;
mod sheen_table;
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
    /// No surface at all: an index-matched boundary that only separates participating media
    /// (pbrt-v4's `interface` material, Mitsuba's `null` BSDF). The volumetric path tracer passes
    /// rays straight through it without counting a bounce; the other integrators see it as an
    /// index-matched (η = 1) smooth dielectric, which transmits every ray unchanged.
    Interface,
    /// glTF `KHR_materials_unlit`: the surface shows its base colour (factor × texture × vertex
    /// colour) as emitted radiance toward every ray and scatters nothing. It is not a light that
    /// next-event estimation samples (a viewer's unlit object lights nothing), so only paths that
    /// hit it by BSDF sampling or from the camera see it, each with MIS weight 1 — unbiased for
    /// that definition (docs/DESIGN.md §4).
    Unlit,
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
    /// Roughness given as float textures, evaluated per hit (pbrt-v4 evaluates `uroughness`,
    /// `vroughness` at the hit, then applies `remaproughness`): the conductor's (base of
    /// `coatedconductor`) and the interface's (coat of the coated models, the `dielectric`
    /// itself). An axis without a texture keeps its constant α above.
    pub conductor_roughness: RoughnessTextures,
    pub interface_roughness: RoughnessTextures,
    /// pbrt-v4 `displacement`: a float texture (R channel × `displacement_scale`) that bump-maps
    /// the shading normal (pbrt-v4 `BumpMap`, see [`eval::bump`]).
    pub displacement: Option<TextureRef>,
    pub displacement_scale: f32,
}

/// pbrt roughness along u and v as `factor` × texture R, per hit, remapped to GGX α with
/// [`microfacet::pbrt_roughness_to_alpha`] when `remap` (pbrt's `remaproughness`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughnessTextures {
    pub u: Option<TextureRef>,
    pub v: Option<TextureRef>,
    pub factor: Vec2,
    pub remap: bool,
}

impl Default for RoughnessTextures {
    fn default() -> Self {
        RoughnessTextures {
            u: None,
            v: None,
            factor: Vec2::ONE,
            remap: true,
        }
    }
}

impl RoughnessTextures {
    pub fn is_textured(&self) -> bool {
        self.u.is_some() || self.v.is_some()
    }
}

/// pbrt-v4 `mix` (`MixMaterial::ChooseMaterial`): at each hit `materials[1]` is chosen with
/// probability amount = `amount` × texture R (≤ 0: always `materials[0]`, ≥ 1: always
/// `materials[1]`), by a hash of the hit, so the choice is deterministic and the same for every
/// query of that hit (see [`eval::resolve_mix`]). Indices are into the scene's materials.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mix {
    pub materials: [u32; 2],
    pub amount: f32,
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
            conductor_roughness: RoughnessTextures::default(),
            interface_roughness: RoughnessTextures::default(),
            displacement: None,
            displacement_scale: 1.0,
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
            self.conductor_roughness.factor.x,
            self.conductor_roughness.factor.y,
            self.interface_roughness.factor.x,
            self.interface_roughness.factor.y,
            self.displacement_scale,
        ];
        if vecs.iter().any(|v| !v.is_finite()) || scalars.iter().any(|s| !s.is_finite()) {
            return Err("has a non-finite pbrt parameter".into());
        }
        if vecs.iter().any(|v| v.min_element() < 0.0)
            || self.conductor_alpha.min_element() < 0.0
            || self.interface_alpha.min_element() < 0.0
            || self.conductor_roughness.factor.min_element() < 0.0
            || self.interface_roughness.factor.min_element() < 0.0
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
    /// pbrt-v4 `mix`: this material only chooses one of two others per hit (its own emission,
    /// alpha and double-sidedness still apply; its scattering fields are unused).
    pub mix: Option<Mix>,
    pub mix_amount_texture: Option<TextureRef>,
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
            mix: None,
            mix_amount_texture: None,
        }
    }
}

/// Every texture slot of a [`Material`], listed once: validation, a TOML include's index shift
/// and `trayecto info` walk this list, so a new slot cannot be forgotten by one of them.
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
            $($borrow)+ $m.clearcoat_texture,
            $($borrow)+ $m.clearcoat_roughness_texture,
            $($borrow)+ $m.clearcoat_normal_texture,
            $($borrow)+ $m.sheen_color_texture,
            $($borrow)+ $m.sheen_roughness_texture,
            $($borrow)+ $m.anisotropy_texture,
            $($borrow)+ $m.iridescence_texture,
            $($borrow)+ $m.iridescence_thickness_texture,
            $($borrow)+ $m.diffuse_transmission_texture,
            $($borrow)+ $m.diffuse_transmission_color_texture,
            $($borrow)+ $m.mix_amount_texture,
            $($borrow)+ $m.pbrt.conductor_roughness.u,
            $($borrow)+ $m.pbrt.conductor_roughness.v,
            $($borrow)+ $m.pbrt.interface_roughness.u,
            $($borrow)+ $m.pbrt.interface_roughness.v,
            $($borrow)+ $m.pbrt.displacement,
        ]
    };
}

impl Material {
    /// The textures this material references (every slot that is set).
    pub fn texture_refs(&self) -> impl Iterator<Item = &TextureRef> {
        texture_slots!(self, &).into_iter().flatten()
    }

    /// [`Material::texture_refs`], mutable (e.g. to shift indices when scenes are merged).
    pub fn texture_refs_mut(&mut self) -> impl Iterator<Item = &mut TextureRef> {
        texture_slots!(self, &mut).into_iter().flatten()
    }

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
        let vecs = [
            self.base_color,
            self.emissive,
            self.specular_color,
            self.sheen_color,
            self.diffuse_transmission_color,
        ];
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
            self.sheen_roughness,
            self.anisotropy,
            self.anisotropy_rotation,
            self.iridescence,
            self.iridescence_ior,
            self.iridescence_thickness_min,
            self.iridescence_thickness_max,
            self.dispersion,
            self.diffuse_transmission,
            self.mix.map_or(0.0, |m| m.amount),
        ];
        if vecs.iter().any(|v| !v.is_finite()) || scalars.iter().any(|s| !s.is_finite()) {
            return Err("has a non-finite parameter".into());
        }
        if self.base_color.min_element() < 0.0 || self.emissive.min_element() < 0.0 {
            return Err("has a negative colour".into());
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
        self.pbrt.validate()?;
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
