//! The material models, one file per model, each with its own parameters and its own
//! construction of the [`Bsdf`] at a hit (mirroring [`crate::material::bxdf`], one file per BSDF
//! variant); `Bsdf::from_model` below dispatches on the model. [`crate::material::eval`] holds
//! what every model shares at a hit (texture lookups, base colour, opacity, emission). What is
//! read for every model — the base colour, and the glTF metallic, roughness, IOR, transmission and
//! specular that the raycast/Whitted local shading reads whatever the model — stays in
//! [`Material`] (docs/DESIGN.md §1).

pub mod coated;
pub mod conductor;
pub mod dielectric;
pub mod diffuse_transmission;
pub mod hair;
pub mod metallic_roughness;
pub mod mix;

pub use coated::{Coat, CoatedConductor, CoatedDiffuse, Slab};
pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse_transmission::DiffuseTransmission;
pub use hair::{Hair, HairAbsorption};
pub use metallic_roughness::MetallicRoughness;
pub use mix::Mix;

use super::eval::{HitTextures, base_color_in, roughness_metallic_in};
use super::microfacet::pbrt_roughness_to_alpha;
use super::texture::SharedFootprint;
use super::{Bsdf, Material, Texture, TextureRef, bxdf};
use crate::geometry::SurfaceHit;
use crate::math::{Vec2, Vec3};
use std::cell::Cell;

/// How the path tracer scatters light at the surface, with the parameters only that model reads.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum MaterialModel {
    /// Lambertian reflection of the base colour.
    #[default]
    Diffuse,
    /// glTF 2.0 metallic-roughness with its KHR extensions
    /// ([`metallic_roughness`]; transmission when the material's `transmission > 0`).
    MetallicRoughness(MetallicRoughness),
    /// Smooth or rough dielectric (glass); the thesis's `refractive` material.
    Dielectric(Dielectric),
    /// Perfect mirror of the base colour.
    Mirror,
    /// pbrt-v4 `conductor`.
    Conductor(Conductor),
    /// pbrt-v4 `coateddiffuse`: a dielectric coat over a Lambertian base of the base colour.
    CoatedDiffuse(CoatedDiffuse),
    /// pbrt-v4 `coatedconductor`: a dielectric coat over a conductor.
    CoatedConductor(CoatedConductor),
    /// pbrt-v4 `diffusetransmission`: Lambertian reflection of the base colour and Lambertian
    /// transmission.
    DiffuseTransmission(DiffuseTransmission),
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
    /// pbrt-v4 `mix`: chooses one of two other materials per hit
    /// ([`crate::material::eval::resolve_mix`]); it scatters nothing itself.
    Mix(Mix),
    /// pbrt-v4 `hair`: Chiang et al. 2016's fibre scattering ([`hair`]).
    Hair(Hair),
}

impl MaterialModel {
    /// The model's name, as `trayecto info` prints it.
    pub fn name(&self) -> &'static str {
        match self {
            MaterialModel::Diffuse => "Diffuse",
            MaterialModel::MetallicRoughness(_) => "MetallicRoughness",
            MaterialModel::Dielectric(_) => "Dielectric",
            MaterialModel::Mirror => "Mirror",
            MaterialModel::Conductor(_) => "Conductor",
            MaterialModel::CoatedDiffuse(_) => "CoatedDiffuse",
            MaterialModel::CoatedConductor(_) => "CoatedConductor",
            MaterialModel::DiffuseTransmission(_) => "DiffuseTransmission",
            MaterialModel::Interface => "Interface",
            MaterialModel::Unlit => "Unlit",
            MaterialModel::Mix(_) => "Mix",
            MaterialModel::Hair(_) => "Hair",
        }
    }

    /// A smooth dielectric without roughness textures (its roughness is the material's).
    pub fn dielectric() -> MaterialModel {
        MaterialModel::Dielectric(Dielectric::default())
    }

    /// glTF metallic-roughness without extensions.
    pub fn metallic_roughness() -> MaterialModel {
        MaterialModel::MetallicRoughness(MetallicRoughness::NONE)
    }

    pub fn is_metallic_roughness(&self) -> bool {
        matches!(self, MaterialModel::MetallicRoughness(_))
    }

    pub fn is_dielectric(&self) -> bool {
        matches!(self, MaterialModel::Dielectric(_))
    }

    /// The texture slots of the model's own parameters (each set or not).
    pub fn texture_slots(&self) -> impl Iterator<Item = &Option<TextureRef>> {
        let (x, r1, r2, c) = match self {
            MaterialModel::MetallicRoughness(x) => (Some(x), None, None, None),
            MaterialModel::Conductor(c) => (None, Some(&c.roughness), None, Some(c)),
            MaterialModel::Dielectric(d) => (None, Some(&d.roughness), None, None),
            MaterialModel::CoatedDiffuse(c) => (None, Some(&c.coat.roughness), None, None),
            MaterialModel::CoatedConductor(c) => (
                None,
                Some(&c.conductor.roughness),
                Some(&c.coat.roughness),
                Some(&c.conductor),
            ),
            _ => (None, None, None, None),
        };
        let mix = match self {
            MaterialModel::Mix(m) => Some(&m.amount_texture),
            _ => None,
        };
        x.into_iter()
            .flat_map(MetallicRoughness::texture_slots)
            .chain(r1.into_iter().chain(r2).flat_map(|r| [&r.u, &r.v]))
            .chain(mix)
            .chain(c.into_iter().flat_map(|c| [&c.eta_texture, &c.k_texture]))
    }

    /// [`MaterialModel::texture_slots`], mutable.
    pub fn texture_slots_mut(&mut self) -> impl Iterator<Item = &mut Option<TextureRef>> {
        let (x, r1, r2, mix, c) = match self {
            MaterialModel::MetallicRoughness(x) => (Some(x), None, None, None, None),
            MaterialModel::Conductor(c) => {
                let Conductor {
                    roughness,
                    eta_texture,
                    k_texture,
                    ..
                } = c;
                (
                    None,
                    Some(roughness),
                    None,
                    None,
                    Some([eta_texture, k_texture]),
                )
            }
            MaterialModel::Dielectric(d) => (None, Some(&mut d.roughness), None, None, None),
            MaterialModel::CoatedDiffuse(c) => {
                (None, Some(&mut c.coat.roughness), None, None, None)
            }
            MaterialModel::CoatedConductor(c) => {
                let Conductor {
                    roughness,
                    eta_texture,
                    k_texture,
                    ..
                } = &mut c.conductor;
                (
                    None,
                    Some(roughness),
                    Some(&mut c.coat.roughness),
                    None,
                    Some([eta_texture, k_texture]),
                )
            }
            MaterialModel::Mix(m) => (None, None, None, Some(&mut m.amount_texture), None),
            _ => (None, None, None, None, None),
        };
        x.into_iter()
            .flat_map(MetallicRoughness::texture_slots_mut)
            .chain(r1.into_iter().chain(r2).flat_map(|r| [&mut r.u, &mut r.v]))
            .chain(mix)
            .chain(c.into_iter().flatten())
    }

    /// Rejects model parameters that would produce NaNs or that the BSDF does not accept.
    pub fn validate(&self) -> Result<(), String> {
        match self {
            MaterialModel::Dielectric(d) => d.validate(),
            MaterialModel::Conductor(c) => c.validate(),
            MaterialModel::CoatedDiffuse(c) => c.validate(),
            MaterialModel::CoatedConductor(c) => c.validate(),
            MaterialModel::DiffuseTransmission(d) => d.validate(),
            MaterialModel::Mix(m) => m.validate(),
            MaterialModel::Hair(h) => h.validate(),
            MaterialModel::MetallicRoughness(x) => x.validate(),
            MaterialModel::Diffuse
            | MaterialModel::Mirror
            | MaterialModel::Interface
            | MaterialModel::Unlit => Ok(()),
        }
    }
}

impl Bsdf {
    /// The BSDF of `material` at the hit of `tx`: each model builds its own. Each reads only the
    /// inputs it uses (a Lambertian surface needs its base colour alone; computing every model's
    /// inputs first was ~40 % of a Cornell box vertex's `from_material` instructions,
    /// callgrind). All are pure functions of the hit.
    #[inline]
    pub(super) fn from_model(material: &Material, tx: &HitTextures) -> Bsdf {
        let base = || base_color_in(material, tx);
        let eta = if material.ior > 0.0 {
            material.ior
        } else {
            1.5
        };
        match &material.model {
            MaterialModel::Conductor(c) => Bsdf::Conductor(c.lobe(tx, 1.0, base)),
            MaterialModel::CoatedDiffuse(c) => c.bsdf(tx, base),
            MaterialModel::CoatedConductor(c) => c.bsdf(tx, base),
            MaterialModel::DiffuseTransmission(d) => d.bsdf(base()),
            // A mix is resolved to one of its materials before scattering
            // (`World::surface_material`); left unresolved it is Lambertian of its base colour.
            MaterialModel::Diffuse | MaterialModel::Mix(_) => {
                Bsdf::Diffuse(bxdf::Diffuse { albedo: base() })
            }
            MaterialModel::Mirror => Bsdf::Mirror(bxdf::Mirror { color: base() }),
            MaterialModel::Dielectric(d) => {
                d.bsdf(tx, eta, || roughness_metallic_in(material, tx).0)
            }
            MaterialModel::Interface => Bsdf::dielectric(1.0, 0.0, Vec3::ONE),
            // KHR_materials_unlit: the base colour is emitted (`eval::emitted`), nothing scatters.
            MaterialModel::Unlit => Bsdf::Diffuse(bxdf::Diffuse { albedo: Vec3::ZERO }),
            MaterialModel::MetallicRoughness(x) => metallic_roughness::bsdf(material, x, tx, eta),
            MaterialModel::Hair(h) => h.bsdf(material, tx),
        }
    }
}

/// pbrt roughness along u and v as `factor` × texture R, per hit, remapped to GGX α with
/// [`pbrt_roughness_to_alpha`] when `remap` (pbrt's `remaproughness`).
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

    /// GGX α along (u, v) at the hit of `tx`: `alpha` for an axis without a roughness texture,
    /// else pbrt's roughness factor × texture R remapped as `remaproughness` asks (pbrt-v4
    /// evaluates the roughness textures at the hit, then `RoughnessToAlpha`).
    #[inline]
    pub fn alpha(&self, alpha: Vec2, tx: &HitTextures) -> Vec2 {
        if !self.is_textured() {
            return alpha;
        }
        let axis = |t: &Option<TextureRef>, factor: f32, constant: f32| match t {
            Some(t) => {
                let x = factor * tx.sample(t).x;
                pbrt_roughness_to_alpha(if x.is_finite() { x } else { 0.0 }, self.remap)
            }
            None => constant,
        };
        Vec2::new(
            axis(&self.u, self.factor.x, alpha.x),
            axis(&self.v, self.factor.y, alpha.y),
        )
    }
}

impl Bsdf {
    /// Builds the BSDF of `material` at `hit`, reading its textures.
    #[inline]
    pub fn from_material(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Bsdf {
        Bsdf::from_material_shared(material, textures, hit, None)
    }

    /// [`Bsdf::from_material`], with `Some(shared)` its image lookups sharing their bilinear
    /// addressing with each other and with the hit's earlier lookups (the normal map's,
    /// [`crate::material::normal_map::apply_normal_map_shared`]), where it is provably the same
    /// ([`HitTextures`]); with `None` every lookup is the plain one.
    pub fn from_material_shared(
        material: &Material,
        textures: &[Texture],
        hit: &SurfaceHit,
        shared: Option<&Cell<SharedFootprint>>,
    ) -> Bsdf {
        let tx = &HitTextures::new(textures, hit, shared);
        Bsdf::from_model(material, tx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{PrimRef, PrimitiveKind};
    use crate::material::normal_map::{apply_normal_map, apply_normal_map_shared};
    use crate::math::Vec4;

    /// ToyCar's body in small: a clearcoated metallic-roughness material whose normal map, base
    /// colour, metallic-roughness and clearcoat textures share a size (and a sampler), plus a
    /// coat-roughness texture of another height. Normal map then BSDF through one kept
    /// footprint ([`World::shade_surface`]'s order) give the shading normal and the BSDF (every
    /// field, by its `Debug` form) of the separate calls at every uv, and the footprint is used.
    ///
    /// [`World::shade_surface`]: crate::world::World::shade_surface
    #[test]
    fn shared_footprint_gives_the_same_shading() {
        let image = |w: u32, h: u32, k: f32| {
            let texels = (0..w * h)
                .map(|i| {
                    let f = |c: f32| ((i as f32 * c * k).sin() * 0.5 + 0.5).clamp(0.0, 1.0);
                    Vec4::new(f(0.37), f(1.3), f(0.71), 1.0)
                })
                .collect();
            let mut t = Texture::image("t", w, h, texels);
            t.tile();
            t
        };
        let textures = vec![
            image(16, 8, 1.0),
            image(16, 8, 2.0),
            image(16, 8, 3.0),
            image(16, 8, 4.0),
            // Same width (so the same tile-row stride), another height.
            image(16, 12, 5.0),
        ];
        let material = Material {
            model: MaterialModel::MetallicRoughness(crate::material::MetallicRoughness {
                clearcoat: 1.0,
                clearcoat_texture: Some(TextureRef::new(3)),
                clearcoat_roughness: 0.6,
                clearcoat_roughness_texture: Some(TextureRef::new(4)),
                ..Default::default()
            }),
            normal_texture: Some(TextureRef::new(0)),
            base_color_texture: Some(TextureRef::new(1)),
            metallic_roughness_texture: Some(TextureRef::new(2)),
            metallic: 0.5,
            ..Default::default()
        };
        for i in 0..400 {
            let uv = Vec2::new(i as f32 * 0.0731 - 3.0, i as f32 * 0.0419 - 2.0);
            let hit = SurfaceHit {
                t: 1.0,
                prim: PrimRef::new(PrimitiveKind::Sphere, 0),
                uv: [uv; 2],
                ..SurfaceHit::EMPTY
            };
            let mut plain = hit;
            apply_normal_map(&material, &textures, &mut plain);
            let want = Bsdf::from_material(&material, &textures, &plain);
            let mut kept = hit;
            let shared = Cell::new(SharedFootprint::NONE);
            apply_normal_map_shared(&material, &textures, &mut kept, Some(&shared));
            assert_ne!(shared.get(), SharedFootprint::NONE, "uv {uv:?}");
            let got = Bsdf::from_material_shared(&material, &textures, &kept, Some(&shared));
            assert_eq!(
                kept.ns.to_array().map(f32::to_bits),
                plain.ns.to_array().map(f32::to_bits)
            );
            assert_eq!(format!("{got:?}"), format!("{want:?}"), "uv {uv:?}");
        }
    }
}
