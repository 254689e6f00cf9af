//! The `Shape` directive (pbrt-v4 file format, "Shapes"), with the `Attribute "shape"`
//! defaults applied; `shapes.rs` turns the shape into Trayecto's.

use crate::scene::SceneError;
use crate::scene::pbrt::{Cursor, Loader};

impl Loader {
    pub(super) fn shape_directives(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
    ) -> Result<bool, SceneError> {
        match name {
            "Shape" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "shape");
                self.shape(&ty, list, at)?;
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}
