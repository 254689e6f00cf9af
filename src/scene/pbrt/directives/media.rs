//! Participating media: `MakeNamedMedium` and `MediumInterface` (pbrt-v4 file format, "Media").

use crate::scene::SceneError;
use crate::scene::pbrt::{Cursor, Loader};

impl Loader {
    pub(super) fn medium_directives(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
    ) -> Result<bool, SceneError> {
        match name {
            "MakeNamedMedium" => {
                let n = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "medium");
                self.make_named_medium(&n, &list, at)?;
            }
            "MediumInterface" => {
                let inside = p.string(at)?;
                // The second name is optional (one name sets both sides).
                let outside = p.optional_string().unwrap_or_else(|| inside.clone());
                self.gs.medium_inside = inside;
                self.gs.medium_outside = outside;
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}
