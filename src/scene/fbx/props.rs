//! `Properties70` tables and the `Definitions` templates that supply their defaults.
//!
//! An object's property is looked up in its own `Properties70` first, then in the
//! `PropertyTemplate` of its class from the `Definitions` section, then falls back to the FBX SDK
//! default the caller passes.

use super::binary::{Document, Node, Property};
use glam::DVec3;
use std::collections::HashMap;

/// One `P` entry: its values (the properties after name, type, label, flags).
#[derive(Clone, Debug, Default)]
pub struct PropValue {
    pub values: Vec<Property>,
}

#[derive(Clone, Debug, Default)]
pub struct PropertyTable {
    pub entries: HashMap<String, PropValue>,
}

impl PropertyTable {
    /// Reads the `Properties70` child of `node` (or the older `Properties60`).
    pub fn from_node(node: &Node) -> PropertyTable {
        let mut t = PropertyTable::default();
        let Some(p70) = node
            .child("Properties70")
            .or_else(|| node.child("Properties60"))
        else {
            return t;
        };
        for p in p70
            .children
            .iter()
            .filter(|c| c.name == "P" || c.name == "Property")
        {
            let Some(name) = p.prop(0).and_then(|v| v.as_str()) else {
                continue;
            };
            // Properties70 entries carry name, type, label, flags; Properties60 only name, type, flags.
            let skip = if p.name == "P" { 4 } else { 3 };
            t.entries.insert(
                name.to_string(),
                PropValue {
                    values: p.props.iter().skip(skip).cloned().collect(),
                },
            );
        }
        t
    }

    pub fn contains(&self, name: &str) -> bool {
        self.entries.contains_key(name)
    }

    fn number_raw(&self, name: &str) -> Option<f64> {
        self.entries.get(name)?.values.first()?.as_f64()
    }

    fn vec3_raw(&self, name: &str) -> Option<DVec3> {
        let v = &self.entries.get(name)?.values;
        Some(DVec3::new(
            v.first()?.as_f64()?,
            v.get(1)?.as_f64()?,
            v.get(2)?.as_f64()?,
        ))
    }
}

/// An object's properties with its class template behind them.
#[derive(Clone, Copy)]
pub struct Props<'a> {
    pub own: &'a PropertyTable,
    pub template: Option<&'a PropertyTable>,
}

impl<'a> Props<'a> {
    /// True if the object itself sets the property (not only its template).
    pub fn has_own(&self, name: &str) -> bool {
        self.own.contains(name)
    }

    pub fn number(&self, name: &str, default: f64) -> f64 {
        self.own
            .number_raw(name)
            .or_else(|| self.template.and_then(|t| t.number_raw(name)))
            .filter(|v| v.is_finite())
            .unwrap_or(default)
    }

    pub fn opt_number(&self, name: &str) -> Option<f64> {
        self.own
            .number_raw(name)
            .or_else(|| self.template.and_then(|t| t.number_raw(name)))
            .filter(|v| v.is_finite())
    }

    pub fn int(&self, name: &str, default: i64) -> i64 {
        let v = self.number(name, default as f64);
        if v.fract() == 0.0 && v.abs() < 1e15 {
            v as i64
        } else {
            default
        }
    }

    pub fn vec3(&self, name: &str, default: DVec3) -> DVec3 {
        self.own
            .vec3_raw(name)
            .or_else(|| self.template.and_then(|t| t.vec3_raw(name)))
            .filter(|v| v.is_finite())
            .unwrap_or(default)
    }

    pub fn opt_vec3(&self, name: &str) -> Option<DVec3> {
        self.own
            .vec3_raw(name)
            .or_else(|| self.template.and_then(|t| t.vec3_raw(name)))
            .filter(|v| v.is_finite())
    }
}

/// The `Definitions` section: property templates by (object type, class), e.g.
/// (`Model`, `FbxNode`), (`NodeAttribute`, `FbxLight`), (`Material`, `FbxSurfacePhong`).
#[derive(Clone, Debug, Default)]
pub struct Templates {
    map: HashMap<(String, String), PropertyTable>,
}

impl Templates {
    pub fn from_document(doc: &Document) -> Templates {
        let mut map = HashMap::new();
        let Some(defs) = doc.node("Definitions") else {
            return Templates { map };
        };
        for ot in defs.children_named("ObjectType") {
            let Some(ty) = ot.prop(0).and_then(|p| p.as_str()) else {
                continue;
            };
            for pt in ot.children_named("PropertyTemplate") {
                let Some(class) = pt.prop(0).and_then(|p| p.as_str()) else {
                    continue;
                };
                let table = PropertyTable::from_node(pt);
                // Blender's exporter writes one template per object type; when lights and cameras
                // share `NodeAttribute` it has been seen to write the camera's properties under
                // the `FbxLight` name (and vice versa). A template whose properties belong to the
                // other class would hand wrong defaults (e.g. a camera's 0.8 grey `Color` to every
                // light), so such a template is dropped and the FBX SDK defaults are used instead.
                let mislabelled = (class == "FbxLight" && table.contains("FieldOfView"))
                    || (class == "FbxCamera" && table.contains("LightType"));
                if !mislabelled {
                    map.insert((ty.to_string(), class.to_string()), table);
                }
            }
        }
        Templates { map }
    }

    pub fn get(&self, object_type: &str, class: &str) -> Option<&PropertyTable> {
        self.map.get(&(object_type.to_string(), class.to_string()))
    }
}
