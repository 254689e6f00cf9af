//! The thesis's naming conventions (Annex B; docs/DESIGN.md §3), honoured by every loader:
//!
//! * a material whose name contains `emissive` and has no emission of its own emits its diffuse
//!   colour × 5 (the thesis's loader);
//! * a material whose name contains `refractive` is a dielectric with IOR 1.4;
//! * a light whose name contains `ambient` is an ambient light of that light's colour.
//!
//! Names are matched case-insensitively.

use super::{LightDesc, Scene};
use crate::material::{Material, MaterialModel};
use crate::math::Vec3;

/// Emission multiplier of the `emissive` convention.
pub const EMISSIVE_SCALE: f32 = 5.0;
/// Index of refraction of the `refractive` convention.
pub const REFRACTIVE_IOR: f32 = 1.4;

fn name_has(name: &str, word: &str) -> bool {
    name.to_ascii_lowercase().contains(word)
}

/// True if a light of this name is to be treated as ambient.
pub fn is_ambient_light_name(name: &str) -> bool {
    name_has(name, "ambient")
}

/// The ambient light a light named `*ambient*` becomes.
pub fn ambient_light(name: &str, color: Vec3) -> LightDesc {
    LightDesc::Ambient {
        name: name.to_string(),
        radiance: color,
    }
}

/// Applies the material conventions to one material; returns a note describing what changed.
pub fn apply_to_material(m: &mut Material) -> Option<String> {
    let mut notes = Vec::new();
    if name_has(&m.name, "emissive") && !m.is_emissive() {
        m.emissive = m.base_color * EMISSIVE_SCALE;
        if m.base_color_texture.is_some() {
            m.emissive_texture = m.base_color_texture;
        }
        notes.push(format!(
            "material '{}' emits its diffuse colour × {EMISSIVE_SCALE} (name contains 'emissive')",
            m.name
        ));
    }
    if name_has(&m.name, "refractive") {
        m.model = MaterialModel::dielectric();
        m.ior = REFRACTIVE_IOR;
        m.transmission = 1.0;
        m.roughness = 0.0;
        m.metallic = 0.0;
        notes.push(format!(
            "material '{}' is a dielectric with IOR {REFRACTIVE_IOR} (name contains 'refractive')",
            m.name
        ));
    }
    (!notes.is_empty()).then(|| notes.join("; "))
}

/// Applies the material conventions to every material of a scene. Loaders call this once the
/// materials are read; the changes are listed as notes in `scene.warnings` so `trayecto info`
/// shows them.
pub fn apply_material_conventions(scene: &mut Scene) {
    for m in &mut scene.materials {
        if let Some(note) = apply_to_material(m) {
            scene.warnings.push(format!("convention: {note}"));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emissive_and_refractive_by_name() {
        let mut m = Material::diffuse("Light_EMISSIVE.001", Vec3::new(1.0, 0.5, 0.25));
        assert!(apply_to_material(&mut m).is_some());
        assert_eq!(m.emissive, Vec3::new(5.0, 2.5, 1.25));

        // Already emissive: left alone.
        let mut m = Material::diffuse("emissive", Vec3::ONE);
        m.emissive = Vec3::splat(2.0);
        apply_to_material(&mut m);
        assert_eq!(m.emissive, Vec3::splat(2.0));

        let mut g = Material::diffuse("Refractive ball", Vec3::ONE);
        apply_to_material(&mut g);
        assert!(g.model.is_dielectric());
        assert_eq!(g.ior, 1.4);

        let mut plain = Material::diffuse("wall", Vec3::ONE);
        assert!(apply_to_material(&mut plain).is_none());
        assert!(is_ambient_light_name("Ambient_Light"));
        assert!(!is_ambient_light_name("Point"));
    }
}
