//! What the world keeps about media: the compiled media, which medium each material's surface
//! separates (objects with a medium interface get their own copy of their material, so a hit's
//! material index also names its interface and the geometry needs no new field), and the camera's
//! medium.

use super::{GridError, Medium};
use crate::material::{Material, MaterialModel};
use crate::math::Vec3;
use crate::scene::{MediumInterface, Scene};

#[derive(Clone, Debug, Default)]
pub struct WorldMedia {
    pub media: Vec<Medium>,
    /// Per material index: the media on its two sides, or `None` (no transition).
    pub interfaces: Vec<Option<MediumInterface>>,
    /// Per material index: true for `MaterialModel::Interface` (no surface).
    pub passthrough: Vec<bool>,
    pub camera_medium: Option<usize>,
    /// True if the volumetric path tracer must run: the scene has media or interface surfaces.
    pub active: bool,
}

impl WorldMedia {
    /// The medium a ray leaving a surface of `material` in direction `d` travels in, given the
    /// surface's outward geometric normal `ng` and the medium `current` the ray was in.
    #[inline]
    pub fn after_crossing(
        &self,
        material: u32,
        d: Vec3,
        ng: Vec3,
        current: Option<usize>,
    ) -> Option<usize> {
        match self.interfaces.get(material as usize).copied().flatten() {
            None => current,
            Some(mi) => {
                if d.dot(ng) > 0.0 {
                    mi.outside
                } else {
                    mi.inside
                }
            }
        }
    }

    #[inline]
    pub fn is_passthrough(&self, material: u32) -> bool {
        self.passthrough[material as usize]
    }
}

/// Gives every object with a medium interface its own material index (a copy of its material,
/// appended to `scene.materials`; the object is pointed at it) and compiles the media. Scenes
/// without interfaces are not changed.
pub fn assign(scene: &mut Scene) -> Result<WorldMedia, GridError> {
    let mut interfaces: Vec<Option<MediumInterface>> = vec![None; scene.materials.len()];
    // Objects sharing a material and an interface share the copy.
    let mut copies: std::collections::HashMap<(usize, MediumInterface), usize> =
        std::collections::HashMap::new();
    for i in 0..scene.objects.len() {
        let Some(mi) = scene.objects[i].medium else {
            continue;
        };
        let material = scene.objects[i].material;
        let idx = match copies.get(&(material, mi)) {
            Some(&idx) => idx,
            None => {
                let copy: Material = scene.materials[material].clone();
                scene.materials.push(copy);
                interfaces.push(Some(mi));
                let idx = scene.materials.len() - 1;
                copies.insert((material, mi), idx);
                idx
            }
        };
        scene.objects[i].material = idx;
    }
    let media = scene
        .media
        .iter()
        .map(Medium::from_desc)
        .collect::<Result<Vec<_>, _>>()?;
    let passthrough: Vec<bool> = scene
        .materials
        .iter()
        .map(|m| m.model == MaterialModel::Interface)
        .collect();
    let active = !media.is_empty() || passthrough.iter().any(|&p| p);
    Ok(WorldMedia {
        media,
        interfaces,
        passthrough,
        camera_medium: scene.camera_medium,
        active,
    })
}
