//! glTF `KHR_materials_volume` absorption as a participating medium.
//!
//! The extension makes a transmissive material's mesh the boundary of a homogeneous volume
//! (`thicknessFactor > 0`; 0 means thin-walled). Light travelling a distance x inside it keeps the
//! fraction `attenuationColor^(x / attenuationDistance)` (Beer–Lambert, extension text), i.e. an
//! absorption coefficient σa = −ln(attenuationColor) / attenuationDistance per channel, in world
//! units (the distance is given in world space). A path tracer follows the real path length
//! through the real geometry, so `thicknessFactor` and `thicknessTexture` — the rasteriser's
//! estimate of that length — are not needed and are correctly unused.

use super::{MediumDesc, MediumInterface, Scene};
use crate::math::Vec3;

/// Adds one absorbing medium per volume material and makes every object using that material its
/// boundary (inside: the medium, outside: vacuum). Objects that already have an interface keep it.
///
/// Returns, per material, the medium made for it (glTF material variants switch objects between
/// materials, and their media with them).
pub fn apply_volume_absorption(scene: &mut Scene) -> Vec<Option<usize>> {
    let mut medium_of = vec![None; scene.materials.len()];
    for (i, m) in scene.materials.iter().enumerate() {
        if !has_absorbing_volume(m) {
            continue;
        }
        let c = m.attenuation_color.clamp(Vec3::splat(1e-6), Vec3::ONE);
        let sigma_a = -Vec3::new(c.x.ln(), c.y.ln(), c.z.ln()) / m.attenuation_distance;
        scene.media.push(MediumDesc::homogeneous(
            &format!("{} (KHR_materials_volume)", m.name),
            sigma_a.max(Vec3::ZERO),
            Vec3::ZERO,
            1.0,
            0.0,
        ));
        medium_of[i] = Some(scene.media.len() - 1);
    }
    for o in &mut scene.objects {
        if o.medium.is_none()
            && let Some(m) = medium_of.get(o.material).copied().flatten()
        {
            o.medium = Some(MediumInterface {
                inside: Some(m),
                outside: None,
            });
        }
    }
    medium_of
}

/// True for a material whose volume absorbs: not thin-walled, transmissive, a finite positive
/// attenuation distance and an attenuation colour below 1 in some channel.
pub fn has_absorbing_volume(m: &crate::material::Material) -> bool {
    !m.thin_walled
        && m.thickness > 0.0
        && m.transmission > 0.0
        && m.attenuation_distance.is_finite()
        && m.attenuation_distance > 0.0
        && m.attenuation_color.is_finite()
        && m.attenuation_color.min_element() < 1.0
}
