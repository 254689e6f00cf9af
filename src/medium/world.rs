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

/// The order [`assign`] gives the scene's objects, as indices into `scene.objects`: those whose
/// material only separates media (`interface`) after all the others, each group in its own
/// order; `None` when there are none (the order is kept). Motion blur's keys follow it, as the
/// compiled world's meshes, spheres, quads and instances do.
pub fn object_order(scene: &Scene) -> Option<Vec<usize>> {
    let pass =
        |i: &usize| scene.materials[scene.objects[*i].material].model == MaterialModel::Interface;
    let n = scene.objects.len();
    if !(0..n).any(|i| pass(&i)) {
        return None;
    }
    Some(
        (0..n)
            .filter(|i| !pass(i))
            .chain((0..n).filter(|i| pass(i)))
            .collect(),
    )
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
    // Interface surfaces go after every other object, so their primitives have the higher
    // indices of their kind. A fog volume resting on a floor has its bottom face in the floor's
    // plane: a ray reaches both at the same `t` (bit for bit on a shared plane), and the
    // accelerators break such ties by the lower primitive (`Bvh::intersect_impl`). Found
    // first, the interface would be crossed and its continuation ray, offset past the plane,
    // would miss the floor (a dark patch under the volume) or reach it in the wrong medium;
    // found second, the floor is hit in the medium the ray is in, as when the volume reaches
    // a little into the floor. The order ([`object_order`], which motion blur's keys follow too)
    // keeps every other object's (lights and all); scenes without interface surfaces keep theirs.
    if let Some(order) = object_order(scene) {
        let mut objects: Vec<_> = std::mem::take(&mut scene.objects)
            .into_iter()
            .map(Some)
            .collect();
        scene.objects = order
            .into_iter()
            .map(|i| objects[i].take().expect("an order names each object once"))
            .collect();
    }
    Ok(WorldMedia {
        media,
        interfaces,
        passthrough,
        camera_medium: scene.camera_medium,
        active,
    })
}
