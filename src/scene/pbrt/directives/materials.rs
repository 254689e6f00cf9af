//! Materials and textures: `MakeNamedMaterial`, `Material`, `NamedMaterial`, `Texture` (pbrt-v4
//! file format, "Materials", "Textures"). They are recorded here and built by `materials.rs`.

use crate::scene::SceneError;
use crate::scene::pbrt::materials::MatSpec;
use crate::scene::pbrt::{Cursor, Loader, MatRef};

impl Loader {
    pub(super) fn material_directives(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
    ) -> Result<bool, SceneError> {
        match name {
            "MakeNamedMaterial" => {
                let n = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "material");
                let ty = list.string("type").unwrap_or_default();
                if ty.is_empty() {
                    return Err(SceneError::invalid(
                        at,
                        format!("MakeNamedMaterial \"{n}\": no \"string type\""),
                    ));
                }
                if self.named_materials.contains_key(&n) {
                    self.warn(format!(
                        "{at}: MakeNamedMaterial \"{n}\" redefines the material"
                    ));
                }
                self.named_materials.insert(
                    n.clone(),
                    MatSpec {
                        name: n,
                        ty,
                        params: list,
                        at: at.to_string(),
                    },
                );
            }
            "Material" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "material");
                self.anonymous_materials.push(MatSpec {
                    name: format!("{ty} ({at})"),
                    ty,
                    params: list,
                    at: at.to_string(),
                });
                self.gs.material = MatRef::Anonymous(self.anonymous_materials.len() - 1);
            }
            "NamedMaterial" => {
                let n = p.string(at)?;
                self.gs.material = MatRef::Named(n);
            }
            "Texture" => {
                let n = p.string(at)?;
                let ty = p.string(at)?;
                let class = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "texture");
                self.texture_directive(n, &ty, &class, list, at)?;
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}
