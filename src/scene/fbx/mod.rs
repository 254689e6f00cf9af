//! Binary FBX 7.x scenes (the thesis's own format, §5.1.9 and Annex B), read natively: the node
//! format by hand ([`binary`]), then the object graph (`Objects` linked by `Connections`) turned
//! into a [`Scene`]: meshes per material slot, the model hierarchy with FBX's full local
//! transform and the file's axis/unit system, Phong/Lambert materials, textures, cameras and
//! point/spot/directional lights.
//!
//! Units: Trayecto's scene units are metres with +Y up (as glTF). FBX lengths are in
//! `UnitScaleFactor` centimetres per unit, so they are scaled by `UnitScaleFactor / 100`, and the
//! `GlobalSettings` axes are rotated to +Y up.
//!
//! Light intensities follow Blender's FBX convention (the exporter writes `Intensity` = watts ×
//! 100): a point or spot light of `Intensity` I and `Color` c radiates `c · (I/100) / (4π)` W/sr
//! (Blender's point light of P watts has radiant intensity P/4π); a directional light gives an
//! irradiance of `c · I/100` W/m². (glTF's candela are divided by 683 lm/W instead, docs/DESIGN.md §4; the
//! two agree for files exported from the same Blender scene.)
//!
//! Materials follow Blender's FBX importer: `DiffuseColor·DiffuseFactor` is the base colour,
//! `EmissiveColor·EmissiveFactor` the emitted radiance, `Opacity` the alpha; Phong materials are
//! metallic-roughness with roughness `1 − √shininess / 10`, metallic `ReflectionFactor` and
//! specular `4·SpecularFactor` (Blender writes half its specular level, whose 0.5 is glTF's 1);
//! Lambert materials are purely diffuse. Surfaces are double-sided (docs/DESIGN.md §3).

pub mod binary;
mod mesh;
mod props;
pub mod texture;
mod transform;

use std::collections::HashMap;
use std::path::Path;

use binary::{Document, Node};
use glam::{DMat4, DVec3};
use props::{PropertyTable, Props, Templates};

use super::conventions;
use super::{CameraDesc, LightDesc, MaterialId, Scene, SceneError, Shape, SpotFalloff};
use crate::material::texture::TextureRef;
use crate::material::{AlphaMode, Material, MaterialModel, PhongParams};
use crate::math::Vec3;

/// Reads an FBX file from memory. `label` names it in messages; textures are read from
/// `scene_dir` (none when `None`).
pub fn load_bytes(data: &[u8], label: &str, scene_dir: Option<&Path>) -> Result<Scene, SceneError> {
    let doc = binary::parse(data)
        .map_err(|e| SceneError::invalid(label, format!("not a readable binary FBX file: {e}")))?;
    let mut scene = Converter::new(&doc, label, scene_dir)?.run()?;
    // So that messages name the file when this entry point is used directly.
    scene.source = Some(std::path::PathBuf::from(label));
    scene.name = Path::new(label)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(scene)
}

/// An entry of `Objects`.
struct Obj<'a> {
    node: &'a Node,
    /// The object's name without the `\0\x01Class` suffix.
    name: String,
    /// The third property: `Mesh`, `Light`, `Camera`, `Null`, …
    class: String,
    props: PropertyTable,
}

impl Obj<'_> {
    fn kind(&self) -> &str {
        &self.node.name
    }
}

struct Converter<'a> {
    label: String,
    scene_dir: Option<&'a Path>,
    templates: Templates,
    objects: HashMap<i64, Obj<'a>>,
    /// Object ids in file order.
    order: Vec<i64>,
    /// parent → (child, property) in connection order.
    children: HashMap<i64, Vec<(i64, Option<String>)>>,
    /// child → parent, object-object connections only.
    parents: HashMap<i64, Vec<i64>>,
    axis: DMat4,
    unit_scale_cm: f64,
    scene: Scene,
    materials: HashMap<i64, MaterialId>,
    textures: HashMap<(i64, bool), Option<usize>>,
    default_material: Option<MaterialId>,
}

/// Splits FBX's `Name\0\x01Class` object names.
fn object_name(s: &str) -> String {
    match s.find("\u{0}\u{1}") {
        Some(i) => s[..i].to_string(),
        None => match s.find("::") {
            // ASCII-style "Class::Name" names seen in some binary writers.
            Some(i) if s.starts_with("Model::") || s.starts_with("Material::") => {
                s[i + 2..].to_string()
            }
            _ => s.to_string(),
        },
    }
}

fn v3(v: DVec3) -> Vec3 {
    v.as_vec3()
}

impl<'a> Converter<'a> {
    fn new(
        doc: &'a Document,
        label: &str,
        scene_dir: Option<&'a Path>,
    ) -> Result<Self, SceneError> {
        let err = |m: String| SceneError::invalid(label, m);
        let objects_node = doc
            .node("Objects")
            .ok_or_else(|| err("the file has no 'Objects' section".into()))?;
        let mut objects = HashMap::new();
        let mut order = Vec::new();
        for n in &objects_node.children {
            let Some(id) = n.prop(0).and_then(|p| p.as_i64()) else {
                continue;
            };
            let name = object_name(n.prop(1).and_then(|p| p.as_str()).unwrap_or(""));
            let class = n.prop(2).and_then(|p| p.as_str()).unwrap_or("").to_string();
            if objects
                .insert(
                    id,
                    Obj {
                        node: n,
                        name,
                        class,
                        props: PropertyTable::from_node(n),
                    },
                )
                .is_some()
            {
                return Err(err(format!("two objects share the id {id}")));
            }
            order.push(id);
        }
        let mut children: HashMap<i64, Vec<(i64, Option<String>)>> = HashMap::new();
        let mut parents: HashMap<i64, Vec<i64>> = HashMap::new();
        if let Some(conns) = doc.node("Connections") {
            for c in conns.children_named("C") {
                let kind = c.prop(0).and_then(|p| p.as_str()).unwrap_or("");
                let (Some(child), Some(parent)) = (
                    c.prop(1).and_then(|p| p.as_i64()),
                    c.prop(2).and_then(|p| p.as_i64()),
                ) else {
                    continue;
                };
                let prop = c.prop(3).and_then(|p| p.as_str()).map(str::to_string);
                match kind {
                    "OO" => {
                        children.entry(parent).or_default().push((child, None));
                        parents.entry(child).or_default().push(parent);
                    }
                    "OP" => children.entry(parent).or_default().push((child, prop)),
                    _ => {}
                }
            }
        }
        let empty = PropertyTable::default();
        let gs = doc
            .node("GlobalSettings")
            .map(PropertyTable::from_node)
            .unwrap_or(empty);
        let axis = transform::axis_system(&Props {
            own: &gs,
            template: None,
        });
        let mut scene = Scene::default();
        scene.warnings.extend(axis.notes);
        let ambient = Props {
            own: &gs,
            template: None,
        }
        .vec3("AmbientColor", DVec3::ZERO);
        if ambient.max_element() > 0.0 {
            scene.warnings.push(format!(
                "GlobalSettings AmbientColor ({:.3}, {:.3}, {:.3}) is ignored (use a light named 'ambient')",
                ambient.x, ambient.y, ambient.z
            ));
        }
        Ok(Converter {
            label: label.to_string(),
            scene_dir,
            templates: Templates::from_document(doc),
            objects,
            order,
            children,
            parents,
            axis: axis.matrix,
            unit_scale_cm: axis.unit_scale_cm,
            scene,
            materials: HashMap::new(),
            textures: HashMap::new(),
            default_material: None,
        })
    }

    fn err(&self, m: String) -> SceneError {
        SceneError::invalid(&self.label, m)
    }

    fn warn(&mut self, m: String) {
        self.scene.warnings.push(m);
    }

    /// Children of `id` of the given object kind (`Geometry`, `Material`, …), in connection order.
    fn children_of(&self, id: i64, kind: &str) -> Vec<i64> {
        self.children
            .get(&id)
            .map(|v| {
                v.iter()
                    .filter(|(c, p)| {
                        p.is_none() && self.objects.get(c).is_some_and(|o| o.kind() == kind)
                    })
                    .map(|(c, _)| *c)
                    .collect()
            })
            .unwrap_or_default()
    }

    fn model_parent(&self, id: i64) -> Option<i64> {
        self.parents
            .get(&id)?
            .iter()
            .copied()
            .find(|p| self.objects.get(p).is_some_and(|o| o.kind() == "Model"))
    }

    fn run(mut self) -> Result<Scene, SceneError> {
        self.report_unsupported();
        let globals = self.global_transforms()?;
        let model_ids: Vec<i64> = self
            .order
            .iter()
            .copied()
            .filter(|id| self.objects[id].kind() == "Model")
            .collect();
        let mut geometry_cache: HashMap<i64, Vec<(i64, usize)>> = HashMap::new();
        for id in model_ids {
            let Some((global, geometric, visible)) = globals.get(&id).copied() else {
                continue;
            };
            let (name, class) = {
                let o = &self.objects[&id];
                (o.name.clone(), o.class.clone())
            };
            if !visible {
                self.warn(format!(
                    "model '{name}' is hidden (Visibility 0) and was skipped"
                ));
                continue;
            }
            let world = self.axis * global;
            match class.as_str() {
                "Light" => self.light(id, &name, world),
                "Camera" => self.camera(id, &name, world),
                _ => {}
            }
            let geoms = self.children_of(id, "Geometry");
            if geoms.is_empty() {
                continue;
            }
            let mats: Vec<i64> = self.children_of(id, "Material");
            let transform = (world * geometric).as_mat4();
            for g in geoms {
                let parts = match geometry_cache.get(&g) {
                    Some(p) => p.clone(),
                    None => {
                        let p = self.geometry(g)?;
                        geometry_cache.insert(g, p.clone());
                        p
                    }
                };
                for (slot, mesh) in parts {
                    let material = if slot < 0 {
                        match mats.first() {
                            Some(&m) => self.material(m),
                            None => self.default_material(),
                        }
                    } else {
                        match mats.get(slot as usize) {
                            Some(&m) => self.material(m),
                            None => {
                                self.warn(format!(
                                    "model '{name}' uses material slot {slot} but has {} material(s); a default grey is used",
                                    mats.len()
                                ));
                                self.default_material()
                            }
                        }
                    };
                    self.scene
                        .add_object(&name, Shape::Mesh(mesh), transform, material);
                }
            }
        }
        conventions::apply_material_conventions(&mut self.scene);
        Ok(self.scene)
    }

    /// Warns, by name, about everything in the file that is not rendered.
    fn report_unsupported(&mut self) {
        let mut counts: Vec<(String, usize)> = Vec::new();
        let mut bump = |k: String| match counts.iter_mut().find(|(n, _)| *n == k) {
            Some((_, c)) => *c += 1,
            None => counts.push((k, 1)),
        };
        let mut named = Vec::new();
        for id in &self.order {
            let o = &self.objects[id];
            match o.kind() {
                "Model" => match o.class.as_str() {
                    "Mesh" | "Null" | "Light" | "Camera" | "" => {}
                    "LimbNode" | "Root" | "Limb" => bump("skeleton joint (Model LimbNode)".into()),
                    other => named.push(format!("model '{}' of type '{other}'", o.name)),
                },
                "Geometry" => {
                    if o.class != "Mesh" {
                        named.push(format!("geometry '{}' of type '{}'", o.name, o.class));
                    }
                }
                "NodeAttribute"
                | "Material"
                | "Texture"
                | "Video"
                | "Pose"
                | "Implementation"
                | "BindingTable"
                | "DisplayLayer"
                | "SelectionSet"
                | "Collection"
                | "CollectionExclusive" => {}
                k if k.starts_with("Animation") => bump(format!("{k} (animation)")),
                "Deformer" | "SubDeformer" => bump(format!(
                    "{} {} (skinning or blend shapes: meshes are rendered in their rest pose)",
                    o.kind(),
                    o.class
                )),
                other => bump(format!("{other} object")),
            }
        }
        for (k, c) in counts {
            self.warn(format!("unsupported FBX content ignored: {c} × {k}"));
        }
        for n in named {
            self.warn(format!("unsupported FBX content ignored: {n}"));
        }
    }

    /// (global transform, geometric transform, visible) of every model, parents first.
    #[allow(clippy::type_complexity)]
    fn global_transforms(&mut self) -> Result<HashMap<i64, (DMat4, DMat4, bool)>, SceneError> {
        let template = self.templates.get("Model", "FbxNode").cloned();
        let mut locals = HashMap::new();
        let mut notes = Vec::new();
        let mut rrss = Vec::new();
        for id in &self.order {
            let o = &self.objects[id];
            if o.kind() != "Model" {
                continue;
            }
            let p = Props {
                own: &o.props,
                template: template.as_ref(),
            };
            let l = transform::local_transform(&p);
            for n in &l.notes {
                notes.push(format!("model '{}' {n}", o.name));
            }
            if l.inherit == transform::Inherit::RrSs {
                rrss.push(o.name.clone());
            }
            let visible = p.number("Visibility", 1.0) > 0.0 && p.number("Show", 1.0) > 0.0;
            locals.insert(*id, (l, visible));
        }
        for n in notes {
            self.warn(n);
        }
        if !rrss.is_empty() {
            self.warn(format!(
                "models {} inherit scale the 'RrSs' way, approximated as the usual parent × child",
                rrss.join(", ")
            ));
        }
        let mut out = HashMap::new();
        for (&id, _) in locals.iter() {
            // The chain from this model up to the root.
            let mut chain = vec![id];
            let mut cur = id;
            while let Some(p) = self.model_parent(cur) {
                if chain.len() > locals.len() {
                    return Err(self.err(format!(
                        "the model hierarchy has a cycle through '{}'",
                        self.objects[&id].name
                    )));
                }
                chain.push(p);
                cur = p;
            }
            let mut g = DMat4::IDENTITY;
            let mut parent_scaling = DVec3::ONE;
            let mut visible = true;
            for m in chain.iter().rev() {
                let Some((l, vis)) = locals.get(m) else {
                    continue;
                };
                g = transform::compose(g, parent_scaling, l);
                parent_scaling = l.scaling;
                visible &= *vis;
            }
            let geometric = locals[&id].0.geometric;
            out.insert(id, (g, geometric, visible));
        }
        Ok(out)
    }

    fn default_material(&mut self) -> MaterialId {
        if let Some(m) = self.default_material {
            return m;
        }
        let mut m = Material::diffuse("fbx_default", Vec3::splat(0.8));
        m.double_sided = true;
        let id = self.scene.add_material(m);
        self.default_material = Some(id);
        id
    }

    /// Converts one geometry into meshes, one per material slot.
    fn geometry(&mut self, id: i64) -> Result<Vec<(i64, usize)>, SceneError> {
        let (node, name, class) = {
            let o = &self.objects[&id];
            (o.node, o.name.clone(), o.class.clone())
        };
        if class != "Mesh" {
            return Ok(Vec::new());
        }
        let c = mesh::convert(node, &name).map_err(|e| self.err(e))?;
        self.scene.warnings.extend(c.warnings);
        let mut out = Vec::new();
        for (slot, m) in c.parts {
            if m.indices.is_empty() {
                continue;
            }
            out.push((slot, self.scene.add_mesh(m)));
        }
        Ok(out)
    }

    fn material(&mut self, id: i64) -> MaterialId {
        if let Some(&m) = self.materials.get(&id) {
            return m;
        }
        let o = &self.objects[&id];
        let shading = o
            .node
            .child_str("ShadingModel")
            .unwrap_or("phong")
            .to_ascii_lowercase();
        let lambert = shading == "lambert";
        let template = self.templates.get(
            "Material",
            if lambert {
                "FbxSurfaceLambert"
            } else {
                "FbxSurfacePhong"
            },
        );
        let p = Props {
            own: &o.props,
            template,
        };
        let name = o.name.clone();
        let color = |main: &str, legacy: &str, default: DVec3| {
            p.opt_vec3(main)
                .or_else(|| p.opt_vec3(legacy))
                .unwrap_or(default)
        };
        let diffuse = color("DiffuseColor", "Diffuse", DVec3::splat(0.8));
        let diffuse_factor = p.number("DiffuseFactor", 1.0);
        let emissive = color("EmissiveColor", "Emissive", DVec3::ZERO);
        let emissive_factor = p.number("EmissiveFactor", 1.0);
        let specular = color("SpecularColor", "Specular", DVec3::splat(0.2));
        let specular_factor = p.number("SpecularFactor", 1.0);
        let shininess = p
            .opt_number("ShininessExponent")
            .or_else(|| p.opt_number("Shininess"))
            .unwrap_or(20.0);
        let alpha = if p.has_own("Opacity") {
            p.number("Opacity", 1.0)
        } else if p.has_own("TransparencyFactor") {
            1.0 - p.number("TransparencyFactor", 0.0)
        } else {
            1.0
        }
        .clamp(0.0, 1.0);
        let mut m = Material {
            name: name.clone(),
            model: if lambert {
                MaterialModel::Diffuse
            } else {
                MaterialModel::metallic_roughness()
            },
            base_color: v3((diffuse * diffuse_factor).max(DVec3::ZERO)),
            emissive: v3((emissive * emissive_factor).max(DVec3::ZERO)),
            alpha: alpha as f32,
            alpha_mode: if alpha < 1.0 {
                AlphaMode::Blend
            } else {
                AlphaMode::Opaque
            },
            double_sided: true,
            ..Default::default()
        };
        if !lambert {
            // Blender's importer: roughness = 1 − √shininess / 10 (its exporter writes
            // shininess = (10·(1 − roughness))²), metallic = ReflectionFactor, and its specular
            // level = 2·SpecularFactor, whose default 0.5 is glTF's specular 1.
            m.roughness = (1.0 - shininess.clamp(0.0, 100.0).sqrt() / 10.0) as f32;
            m.metallic = p.number("ReflectionFactor", 0.0).clamp(0.0, 1.0) as f32;
            m.specular = (4.0 * specular_factor).clamp(0.0, 1.0) as f32;
            m.phong = Some(PhongParams {
                specular: v3((specular * specular_factor).max(DVec3::ZERO)),
                shininess: shininess.max(0.0) as f32,
            });
        }
        // Textures connected to the material's properties.
        let links: Vec<(i64, String)> = self
            .children
            .get(&id)
            .map(|v| {
                v.iter()
                    .filter_map(|(c, p)| Some((*c, p.clone()?)))
                    .filter(|(c, _)| {
                        self.objects
                            .get(c)
                            .is_some_and(|o| o.kind() == "Texture" || o.kind() == "LayeredTexture")
                    })
                    .collect()
            })
            .unwrap_or_default();
        for (tex, prop) in links {
            match prop.as_str() {
                "DiffuseColor" | "Diffuse" => {
                    if let Some(t) = self.texture(tex, true, &name, &prop) {
                        // A texture replaces the colour it is connected to (FBX SDK).
                        m.base_color = Vec3::splat(diffuse_factor.max(0.0) as f32);
                        m.base_color_texture = Some(TextureRef::new(t));
                    }
                }
                "EmissiveColor" | "Emissive" => {
                    if let Some(t) = self.texture(tex, true, &name, &prop) {
                        m.emissive = Vec3::splat(emissive_factor.max(0.0) as f32);
                        m.emissive_texture = Some(TextureRef::new(t));
                    }
                }
                "NormalMap" => {
                    if let Some(t) = self.texture(tex, false, &name, &prop) {
                        m.normal_texture = Some(TextureRef::new(t));
                    }
                }
                other => {
                    let tname = self.objects[&tex].name.clone();
                    self.warn(format!(
                        "material '{name}': texture '{tname}' on '{other}' is not supported and was ignored"
                    ));
                }
            }
        }
        let mid = self.scene.add_material(m);
        self.materials.insert(id, mid);
        mid
    }

    /// Loads (once) the image of a Texture object; warnings and fallbacks for missing files.
    fn texture(&mut self, id: i64, srgb: bool, material: &str, prop: &str) -> Option<usize> {
        if let Some(&t) = self.textures.get(&(id, srgb)) {
            return t;
        }
        let o = &self.objects[&id];
        let tname = o.name.clone();
        if o.kind() == "LayeredTexture" {
            self.warn(format!(
                "material '{material}': layered texture '{tname}' on '{prop}' is not supported"
            ));
            self.textures.insert((id, srgb), None);
            return None;
        }
        let relative = o.node.child_str("RelativeFilename").map(str::to_string);
        let absolute = o
            .node
            .child_str("FileName")
            .or_else(|| o.node.child_str("Filename"))
            .map(str::to_string);
        let wrap_u = o
            .props
            .entries
            .get("WrapModeU")
            .and_then(|v| v.values.first()?.as_i64());
        let wrap_v = o
            .props
            .entries
            .get("WrapModeV")
            .and_then(|v| v.values.first()?.as_i64());
        // An embedded image: a Video object connected to the texture, with its bytes in Content.
        let embedded = self.children_of(id, "Video").into_iter().find_map(|v| {
            match self.objects[&v].node.child("Content")?.prop(0)? {
                binary::Property::Raw(b) if !b.is_empty() => Some(b.clone()),
                _ => None,
            }
        });
        let result = match (&embedded, self.scene_dir) {
            (Some(bytes), _) => texture::decode(&tname, bytes, srgb),
            (None, Some(dir)) => {
                texture::load(dir, &tname, relative.as_deref(), absolute.as_deref(), srgb)
            }
            (None, None) => Err("no scene folder to read it from".to_string()),
        };
        let index = match result {
            Ok(mut t) => {
                use crate::material::WrapMode;
                let mode = |w: Option<i64>| match w {
                    Some(1) => WrapMode::ClampToEdge,
                    _ => WrapMode::Repeat,
                };
                t.wrap_s = mode(wrap_u);
                t.wrap_t = mode(wrap_v);
                self.scene.textures.push(t);
                Some(self.scene.textures.len() - 1)
            }
            Err(e) => {
                if srgb {
                    self.warn(format!(
                        "material '{material}': texture '{tname}' on '{prop}' could not be loaded ({e}); shown in magenta"
                    ));
                    self.scene
                        .textures
                        .push(crate::scene::image_io::missing_texture(&tname));
                    Some(self.scene.textures.len() - 1)
                } else {
                    self.warn(format!(
                        "material '{material}': texture '{tname}' on '{prop}' could not be loaded ({e}); ignored"
                    ));
                    None
                }
            }
        };
        self.textures.insert((id, srgb), index);
        index
    }

    /// The node attribute of a light or camera model.
    fn attribute(&self, model: i64) -> Option<&Obj<'a>> {
        self.children_of(model, "NodeAttribute")
            .first()
            .and_then(|a| self.objects.get(a))
    }

    fn light(&mut self, id: i64, name: &str, world: DMat4) {
        let Some(attr) = self.attribute(id) else {
            self.warn(format!(
                "light '{name}' has no light attribute and was skipped"
            ));
            return;
        };
        let p = Props {
            own: &attr.props,
            template: self.templates.get("NodeAttribute", "FbxLight"),
        };
        // FBX SDK defaults: a white point light of intensity 100.
        let kind = p.int("LightType", 0);
        let color = v3(p.vec3("Color", DVec3::ONE).max(DVec3::ZERO));
        let watts = (p.number("Intensity", 100.0) / 100.0).max(0.0) as f32;
        let cast = p.number("CastLight", 1.0) > 0.0;
        let decay = p.has_own("DecayType").then(|| p.int("DecayType", 2));
        let inner = p.number("InnerAngle", 0.0);
        let outer = p.number("OuterAngle", 45.0);
        if !cast {
            self.warn(format!("light '{name}' has CastLight off and was skipped"));
            return;
        }
        if conventions::is_ambient_light_name(name) {
            self.scene
                .lights
                .push(conventions::ambient_light(name, color));
            self.warn(format!(
                "convention: light '{name}' is an ambient light of its colour (name contains 'ambient')"
            ));
            return;
        }
        if let Some(d) = decay
            && d != 2
        {
            self.warn(format!(
                "light '{name}' has decay type {d}; it is rendered with the physical inverse-square falloff"
            ));
        }
        let position = v3(world.transform_point3(DVec3::ZERO));
        // FBX lights shine down their local −Y axis.
        let direction = v3(world.transform_vector3(DVec3::NEG_Y).normalize_or_zero());
        let intensity = color * watts / (4.0 * std::f32::consts::PI);
        match kind {
            0 => self.scene.lights.push(LightDesc::Point {
                name: name.to_string(),
                position,
                intensity,
            }),
            1 | 2 if direction.length_squared() == 0.0 => {
                self.warn(format!("light '{name}' has a degenerate direction and was skipped"));
            }
            1 => self.scene.lights.push(LightDesc::Directional {
                name: name.to_string(),
                direction,
                irradiance: color * watts,
            }),
            2 => {
                // InnerAngle and OuterAngle are full cone angles in degrees.
                let outer = (outer.clamp(0.0, 179.9) * 0.5).to_radians() as f32;
                let inner = ((inner.clamp(0.0, 179.9) * 0.5).to_radians() as f32).min(outer);
                self.scene.lights.push(LightDesc::Spot {
                    name: name.to_string(),
                    position,
                    direction,
                    intensity,
                    inner_angle: inner,
                    outer_angle: outer,
                    falloff: SpotFalloff::SquaredRamp,
                });
            }
            3 => self.warn(format!(
                "light '{name}' is an FBX area light, which is not supported: model it as a mesh with an 'emissive' material"
            )),
            other => self.warn(format!(
                "light '{name}' has unsupported type {other} and was skipped"
            )),
        }
    }

    fn camera(&mut self, id: i64, name: &str, world: DMat4) {
        let Some(attr) = self.attribute(id) else {
            self.warn(format!(
                "camera '{name}' has no camera attribute and was skipped"
            ));
            return;
        };
        let mut notes = Vec::new();
        let p = Props {
            own: &attr.props,
            template: self.templates.get("NodeAttribute", "FbxCamera"),
        };
        let mp = Props {
            own: &self.objects[&id].props,
            template: None,
        };
        if p.int("CameraProjectionType", 0) == 1 {
            notes.push(format!(
                "camera '{name}' is orthographic, which is not supported: rendered as perspective"
            ));
        }
        let aspect = {
            let (w, h) = (p.number("AspectWidth", 0.0), p.number("AspectHeight", 0.0));
            let (mw, mh) = (mp.number("AspectW", 0.0), mp.number("AspectH", 0.0));
            if w > 0.0 && h > 0.0 {
                Some(w / h)
            } else if mw > 0.0 && mh > 0.0 {
                Some(mw / mh)
            } else {
                p.opt_number("FilmAspectRatio").filter(|a| *a > 0.0)
            }
        };
        // The vertical field of view from the aperture mode (FBX SDK EApertureMode).
        let fov_y = p.opt_number("FieldOfViewY");
        let fov = p.opt_number("FieldOfView");
        let half_tan = |deg: f64| (deg.to_radians() * 0.5).tan();
        let vfov = match p.int("ApertureMode", 2) {
            0 => fov_y.or(fov),
            1 => fov.map(|h| {
                let a = aspect.unwrap_or(1.0);
                2.0 * (half_tan(h) / a).atan().to_degrees()
            }),
            3 => {
                let focal = p.number("FocalLength", 0.0);
                let film_h = p.number("FilmHeight", 0.0) * 25.4; // inches to mm
                if focal > 0.0 && film_h > 0.0 {
                    Some(2.0 * (film_h * 0.5 / focal).atan().to_degrees())
                } else {
                    fov_y
                }
            }
            _ => fov.or(fov_y),
        };
        let vfov = match vfov.filter(|v| *v > 0.0 && *v < 180.0) {
            Some(v) => v as f32,
            None => {
                notes.push(format!(
                    "camera '{name}' has no usable field of view; 40° is used"
                ));
                40.0
            }
        };
        let eye = world.transform_point3(DVec3::ZERO);
        // FBX cameras look down their local +X with +Y up.
        let fwd = world.transform_vector3(DVec3::X).normalize_or_zero();
        let mut up = world.transform_vector3(DVec3::Y).normalize_or_zero();
        if fwd == DVec3::ZERO || !eye.is_finite() {
            notes.push(format!(
                "camera '{name}' has a degenerate transform and was skipped"
            ));
            self.scene.warnings.extend(notes);
            return;
        }
        if up.cross(fwd).length_squared() < 1e-12 {
            up = if fwd.y.abs() < 0.9 {
                DVec3::Y
            } else {
                DVec3::Z
            };
        }
        let mut cam = CameraDesc::look_at(name, v3(eye), v3(eye + fwd), v3(up), vfov);
        cam.aspect = aspect.map(|a| a as f32);
        let focus = p.number("FocusDistance", 0.0) * self.unit_scale_cm / 100.0;
        cam.focus_distance = if focus > 0.0 && focus.is_finite() {
            focus as f32
        } else {
            1.0
        };
        if p.number("UseDepthOfField", 0.0) > 0.0 {
            notes.push(format!(
                "camera '{name}': depth of field is not read from FBX; rendered as a pinhole"
            ));
        }
        self.scene.cameras.push(cam);
        self.scene.warnings.extend(notes);
    }
}
