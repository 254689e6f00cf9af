//! pbrt-v4 `mix` (`MixMaterial`): a material that only chooses one of two others per hit.

use crate::material::TextureRef;

/// At each hit `materials[1]` is chosen with probability amount = `amount` × texture R (≤ 0:
/// always `materials[0]`, ≥ 1: always `materials[1]`), by a hash of the hit, so the choice is
/// deterministic and the same for every query of that hit (see
/// [`crate::material::eval::resolve_mix`]). Indices are into the scene's materials. The mix's own
/// emission, alpha and double-sidedness still apply.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mix {
    pub materials: [u32; 2],
    pub amount: f32,
    pub amount_texture: Option<TextureRef>,
}

impl Mix {
    pub(super) fn validate(&self) -> Result<(), String> {
        if !self.amount.is_finite() {
            return Err("has a non-finite parameter".into());
        }
        Ok(())
    }
}
