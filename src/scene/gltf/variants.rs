//! `KHR_materials_variants`: named sets of materials a viewer switches between (a shoe in three
//! colourways). The root lists the variant names; each primitive maps material indices to the
//! variants that use them. Every material is loaded anyway, so a variant only changes which
//! material an object points at: the scene keeps the mapping ([`crate::scene::ObjectVariants`])
//! and [`crate::scene::Scene::select_variant`] applies it (`--variant NAME`). Without a choice
//! the primitives' own `material` — the file's default — is rendered, as the extension says.

use super::*;
use crate::scene::{MediumInterface, ObjectVariants};

const EXT: &str = "KHR_materials_variants";

/// An object's variant mapping as read, before the media of volume materials exist.
pub(super) struct ObjectVariantsDraft {
    object: usize,
    default: MaterialId,
    by_variant: Vec<(usize, MaterialId)>,
}

impl Loader<'_> {
    /// The root's variant names. A malformed list is an error naming the extension.
    pub(super) fn read_variants(&mut self) -> Result<(), SceneError> {
        let Some(root) = self
            .doc
            .as_json()
            .extensions
            .as_ref()
            .and_then(|e| e.others.get(EXT))
        else {
            return Ok(());
        };
        let list = root
            .get("variants")
            .and_then(|v| v.as_array())
            .ok_or_else(|| self.err(format!("{EXT}: the root has no 'variants' array")))?;
        for (i, v) in list.iter().enumerate() {
            let name = v
                .get("name")
                .and_then(|n| n.as_str())
                .ok_or_else(|| self.err(format!("{EXT}: variant {i} has no 'name'")))?;
            if self.variants.iter().any(|n| n == name) {
                // Names select variants, so they must be unique to be selectable.
                return Err(self.err(format!("{EXT}: variant name '{name}' appears twice")));
            }
            self.variants.push(name.to_string());
        }
        self.scene.variants = self.variants.clone();
        Ok(())
    }

    /// Records `object`'s mapping from its primitive's extension object, checking every index.
    pub(super) fn primitive_variants(
        &mut self,
        prim: &gltf::Primitive,
        object: usize,
        default: MaterialId,
    ) -> Result<(), SceneError> {
        let Some(ext) = prim.extension_value(EXT) else {
            return Ok(());
        };
        let bad = |m: String| self.err(format!("{EXT}: {m}"));
        let mappings = ext
            .get("mappings")
            .and_then(|m| m.as_array())
            .ok_or_else(|| bad("a primitive has no 'mappings' array".into()))?;
        let mut by_variant = Vec::new();
        for m in mappings {
            let material = m
                .get("material")
                .and_then(|x| x.as_u64())
                .and_then(|x| usize::try_from(x).ok())
                .filter(|&x| x < self.doc.materials().count())
                .ok_or_else(|| bad("a mapping's 'material' names no material".into()))?;
            let variants = m
                .get("variants")
                .and_then(|v| v.as_array())
                .ok_or_else(|| bad("a mapping has no 'variants' array".into()))?;
            for v in variants {
                let v = v
                    .as_u64()
                    .and_then(|x| usize::try_from(x).ok())
                    .filter(|&x| x < self.variants.len())
                    .ok_or_else(|| {
                        bad(format!(
                            "a mapping names variant {v}, but the file lists {} variant(s)",
                            self.variants.len()
                        ))
                    })?;
                if by_variant.iter().any(|&(w, _)| w == v) {
                    return Err(bad(format!(
                        "a primitive maps variant '{}' twice",
                        self.variants[v]
                    )));
                }
                by_variant.push((v, material));
            }
        }
        if !by_variant.is_empty() {
            self.variant_sets.push(ObjectVariantsDraft {
                object,
                default,
                by_variant,
            });
        }
        Ok(())
    }
}

/// Attaches the mappings to the scene, each material with the medium its volume implies.
pub(super) fn finish(
    scene: &mut Scene,
    drafts: Vec<ObjectVariantsDraft>,
    medium_of: &[Option<usize>],
) {
    let medium = |m: MaterialId| {
        medium_of
            .get(m)
            .copied()
            .flatten()
            .map(|inside| MediumInterface {
                inside: Some(inside),
                outside: None,
            })
    };
    scene.variant_objects = drafts
        .into_iter()
        .map(|d| ObjectVariants {
            object: d.object,
            default: (d.default, medium(d.default)),
            by_variant: d
                .by_variant
                .into_iter()
                .map(|(v, m)| (v, m, medium(m)))
                .collect(),
        })
        .collect();
}
