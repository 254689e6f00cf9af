//! Light directives: `LightSource` and `AreaLightSource` (pbrt-v4 file format, "Lights",
//! "Area lights"), with the `Attribute "light"` defaults applied.

use crate::scene::SceneError;
use crate::scene::pbrt::{Cursor, Loader};

impl Loader {
    pub(super) fn light_directives(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
    ) -> Result<bool, SceneError> {
        match name {
            "LightSource" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "light");
                if self.gs.ctm != self.gs.ctm_end {
                    // pbrt-v4 warns the same and uses the start transform.
                    self.warn_once(
                        "animated light",
                        format!("{at}: LightSource \"{ty}\" under an animated transform is placed at its start time (pbrt-v4 does not animate lights either)"),
                    );
                }
                self.light_source(&ty, list, at)?;
            }
            "AreaLightSource" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "light");
                self.area_light_source(&ty, list, at);
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}
