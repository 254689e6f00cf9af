//! The directives of a pbrt-v4 file, one file per family (the sections of pbrt-v4's file format
//! reference, its `ParserTarget` methods): [`transform`], [`graphics_state`], [`options`],
//! [`materials`], [`lights`], [`shapes`], [`media`], [`instances`]. Each runs its directives
//! against the loader's graphics state; what they build (shapes, materials, lights, media)
//! is in the parent module's files.

mod graphics_state;
mod instances;
mod lights;
mod materials;
mod media;
mod options;
mod shapes;
mod transform;

use crate::scene::SceneError;
use crate::scene::pbrt::{Cursor, Loader, short};

impl Loader {
    /// Runs the directive `name`, whose arguments `p` reads, found at `at` in a file `depth`
    /// includes deep.
    pub(super) fn directive(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
        depth: usize,
    ) -> Result<(), SceneError> {
        // Each family runs the directives it knows and answers whether `name` was one of them.
        let handled = self.transform_directives(name, p, at)?
            || self.graphics_state_directives(name, p, at)?
            || self.option_directives(name, p, at)?
            || self.material_directives(name, p, at)?
            || self.light_directives(name, p, at)?
            || self.shape_directives(name, p, at)?
            || self.medium_directives(name, p, at)?
            || self.instance_directives(name, p, at)?;
        if handled {
            return Ok(());
        }
        match name {
            "Include" | "Import" => {
                let f = p.string(at)?;
                self.include(&f, at, depth)
            }
            other => Err(SceneError::invalid(
                at,
                format!("unknown directive '{}'", short(other)),
            )),
        }
    }
}
