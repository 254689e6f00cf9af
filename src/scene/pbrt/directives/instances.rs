//! Object instancing: `ObjectBegin`, `ObjectEnd`, `ObjectInstance` (pbrt-v4 file format,
//! "Object instancing").

use crate::scene::SceneError;
use crate::scene::pbrt::{Cursor, Frame, Loader, MAX_ATTRIBUTE_DEPTH};

impl Loader {
    pub(super) fn instance_directives(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
    ) -> Result<bool, SceneError> {
        match name {
            "ObjectBegin" => {
                let n = p.string(at)?;
                if self.current_object.is_some() {
                    return Err(SceneError::invalid(
                        at,
                        "ObjectBegin inside another ObjectBegin",
                    ));
                }
                if self.stack.len() >= MAX_ATTRIBUTE_DEPTH {
                    return Err(SceneError::invalid(at, "ObjectBegin: nested too deeply"));
                }
                // ObjectBegin implies AttributeBegin (pbrt-v4 scene.cpp).
                self.stack
                    .push((self.gs.clone(), Frame::Attribute, at.to_string()));
                self.current_object = Some((n, Vec::new()));
            }
            "ObjectEnd" => {
                let Some((n, parts)) = self.current_object.take() else {
                    return Err(SceneError::invalid(at, "ObjectEnd without ObjectBegin"));
                };
                if self.instances.contains_key(&n) {
                    self.warn(format!("{at}: ObjectBegin \"{n}\" redefines the object"));
                }
                self.instances.insert(n, parts);
                match self.stack.pop() {
                    Some((saved, Frame::Attribute, _)) => self.gs = saved,
                    _ => {
                        return Err(SceneError::invalid(
                            at,
                            "ObjectEnd does not match the ObjectBegin's attribute block",
                        ));
                    }
                }
            }
            "ObjectInstance" => {
                let n = p.string(at)?;
                if self.current_object.is_some() {
                    return Err(SceneError::invalid(at, "ObjectInstance inside ObjectBegin"));
                }
                let Some(parts) = self.instances.get(&n) else {
                    return Err(SceneError::invalid(
                        at,
                        format!("ObjectInstance: no object named '{n}'"),
                    ));
                };
                let ctm = self.gs.ctm;
                // pbrt-v4 animates an instance whose transform differs between the two
                // TransformTimes (an `AnimatedTransform` of render-from-instance).
                let moving = self.gs.ctm != self.gs.ctm_end;
                let parts = parts.clone();
                for part in parts {
                    self.scene.add_object(
                        &part.name,
                        part.shape,
                        ctm * part.transform,
                        part.material,
                    );
                    if let Some(o) = self.scene.objects.last_mut() {
                        o.medium = part.medium;
                    }
                    if moving {
                        self.motion
                            .push(crate::scene::animation::RigidMotion::Instance {
                                object: self.scene.objects.len() - 1,
                                motion: crate::scene::animation::MovingTransform {
                                    times: self.transform_times,
                                    start: ctm,
                                    end: self.gs.ctm_end,
                                },
                                part: part.transform,
                            });
                    }
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}
