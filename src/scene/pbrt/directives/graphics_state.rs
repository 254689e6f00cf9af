//! The graphics state's blocks and flags: `AttributeBegin`/`End` (the whole state),
//! pbrt-v3's `TransformBegin`/`End` (the transform only), `Attribute` defaults and
//! `ReverseOrientation` (pbrt-v4 file format, "Attributes").

use crate::scene::SceneError;
use crate::scene::pbrt::{Cursor, Frame, Loader, MAX_ATTRIBUTE_DEPTH};

impl Loader {
    pub(super) fn graphics_state_directives(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
    ) -> Result<bool, SceneError> {
        match name {
            "ReverseOrientation" => self.gs.reverse = !self.gs.reverse,
            "AttributeBegin" | "TransformBegin" => {
                if self.stack.len() >= MAX_ATTRIBUTE_DEPTH {
                    return Err(SceneError::invalid(
                        at,
                        format!("{name}: nested too deeply"),
                    ));
                }
                let frame = if name == "AttributeBegin" {
                    Frame::Attribute
                } else {
                    if !self.warned_once.contains("TransformBegin") {
                        self.warn_once(
                            "TransformBegin",
                            format!("{at}: TransformBegin is deprecated in pbrt-v4 (read as in pbrt-v3: it saves only the transform)"),
                        );
                    }
                    Frame::Transform
                };
                self.stack.push((self.gs.clone(), frame, at.to_string()));
            }
            "AttributeEnd" | "TransformEnd" => {
                let want = if name == "AttributeEnd" {
                    Frame::Attribute
                } else {
                    Frame::Transform
                };
                let Some((saved, frame, opened)) = self.stack.pop() else {
                    return Err(SceneError::invalid(
                        at,
                        format!("{name} without a matching begin"),
                    ));
                };
                if frame != want {
                    return Err(SceneError::invalid(
                        at,
                        format!(
                            "{name} closes the block opened at {opened}, which is of the other kind"
                        ),
                    ));
                }
                if frame == Frame::Attribute {
                    self.gs = saved;
                } else {
                    self.gs.ctm = saved.ctm;
                    self.gs.ctm_end = saved.ctm_end;
                    self.gs.active = saved.active;
                }
            }
            "Attribute" => {
                let target = p.string(at)?;
                let list = p.params(at)?;
                if !["shape", "light", "material", "medium", "texture"].contains(&target.as_str()) {
                    return Err(SceneError::invalid(
                        at,
                        format!("Attribute: unknown target '{target}'"),
                    ));
                }
                let entry = self.gs.attributes.entry(target).or_default();
                for prm in list.params {
                    entry.retain(|q| q.name != prm.name);
                    entry.push(prm);
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}
