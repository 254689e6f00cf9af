//! pbrt-v4 materials and textures mapped onto Trayecto's.
//!
//! Textures become nodes of an arena ([`TexNode`], [`TexExpr`]) as the file defines them; a
//! texture can only name textures defined before it, so children always precede parents and the
//! graph has no cycle. Constants fold while the graph is built. Where a material uses a texture,
//! a constant becomes the material's factor; an `imagemap` with `uv` mapping (optionally scaled
//! by a constant) becomes an image texture reference with its `uscale/vscale/udelta/vdelta` as a
//! UV transform (the plain image path); anything else (`checkerboard` in 2D or 3D, `mix`,
//! `directionmix`, `bilerp`, `scale` of two textures, `invert`, other mappings) becomes a
//! procedural texture evaluated at each hit ([`crate::material::procedural`]), exactly as
//! pbrt-v4 evaluates it. Graphs nested deeper than [`procedural::MAX_DEPTH`] or costing more
//! than [`procedural::MAX_COST`] node evaluations per lookup are errors.
//!
//! Material mapping: `diffuse` → Lambertian; `dielectric` → dielectric (rough through
//! `roughness`); `thindielectric` → thin-walled transmission; `conductor` → the pbrt-v4 conductor
//! (complex Fresnel of RGB η, k or pbrt's `reflectance`, anisotropic GGX); `coateddiffuse` and
//! `coatedconductor` → pbrt-v4's layered BSDF (coat roughness/η, thickness, albedo, g, maxdepth,
//! nsamples); `diffusetransmission` → Lambertian reflection and transmission; `mix` → a material
//! that chooses one of the two per hit with probability `amount` (textured or not), as pbrt-v4's
//! `MixMaterial` does (`eval::resolve_mix`); `interface` → an index-matched boundary.
//! `roughness`/`uroughness`/`vroughness` textures are evaluated per hit (with `remaproughness`);
//! `displacement` bump-maps the shading normal per hit (`eval::bump`); a conductor's η and k
//! textures are evaluated per hit. A dielectric's textured η, layer albedo and transmittance use
//! their mean (warned).

use std::collections::HashMap;
use std::path::PathBuf;

use rayon::prelude::*;

use super::Loader;
use super::params::{ParamList, SpectrumValue, TexOr};
use crate::material::microfacet::pbrt_roughness_to_alpha;
use crate::material::models::{
    Coat, CoatedConductor, CoatedDiffuse, Conductor, Dielectric, DiffuseTransmission, Hair,
    HairAbsorption, Mix, Slab,
};
use crate::material::procedural::{self, Mapping2D, Procedural, TexCtx, TexExpr};
use crate::material::texture::{FilterMode, TextureRef, UvTransform};
use crate::material::{Material, MaterialModel, RoughnessTextures, Texture, WrapMode};
use crate::math::{Vec2, Vec3, Vec4};
use crate::scene::SceneError;

/// A material as the file defines it.
#[derive(Clone, Debug)]
pub struct MatSpec {
    pub name: String,
    pub ty: String,
    pub params: ParamList,
    pub at: String,
}

/// A texture value: a constant, or a node of the loader's texture arena.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TexNode {
    Const(Vec3),
    Node(u32),
}

/// The loader's texture graph: every node of every named texture, children before parents, with
/// each node's nesting depth and evaluation cost (shared children counted each time).
#[derive(Default)]
pub struct TexArena {
    nodes: Vec<TexExpr>,
    depth: Vec<u32>,
    cost: Vec<u64>,
    /// Scene texture (and material factor) made for a node, so materials naming the same
    /// texture share one procedural texture.
    made: HashMap<u32, (Vec3, TextureRef)>,
    /// Procedural textures whose fallback texel (their mean) is computed after images decode.
    procedural: Vec<usize>,
}

impl TexArena {
    fn index(&mut self, n: TexNode) -> u32 {
        match n {
            TexNode::Node(i) => i,
            TexNode::Const(c) => self.push(TexExpr::Const(c)),
        }
    }

    fn push(&mut self, e: TexExpr) -> u32 {
        let (mut d, mut c) = (1u32, 1u64);
        let (ch, k) = e.children();
        for &i in &ch[..k] {
            d = d.max(self.depth[i as usize].saturating_add(1));
            c = c.saturating_add(self.cost[i as usize]);
        }
        self.nodes.push(e);
        self.depth.push(d);
        self.cost.push(c);
        (self.nodes.len() - 1) as u32
    }

    fn get(&self, n: TexNode) -> Option<&TexExpr> {
        match n {
            TexNode::Node(i) => self.nodes.get(i as usize),
            TexNode::Const(_) => None,
        }
    }

    /// The nodes `root` reaches, in arena order (so still children first), re-indexed, the root
    /// last.
    fn extract(&self, root: u32) -> Procedural {
        let mut keep = vec![false; root as usize + 1];
        let mut stack = vec![root];
        while let Some(i) = stack.pop() {
            if std::mem::replace(&mut keep[i as usize], true) {
                continue;
            }
            let (ch, k) = self.nodes[i as usize].children();
            stack.extend_from_slice(&ch[..k]);
        }
        let mut new_index = vec![u32::MAX; keep.len()];
        let mut nodes = Vec::new();
        for (i, _) in keep.iter().enumerate().filter(|(_, k)| **k) {
            new_index[i] = nodes.len() as u32;
            let r = |j: u32| new_index[j as usize];
            nodes.push(match self.nodes[i] {
                TexExpr::Checkerboard { tex, map } => TexExpr::Checkerboard {
                    tex: tex.map(r),
                    map,
                },
                TexExpr::Checkerboard3D {
                    tex,
                    texture_from_world,
                } => TexExpr::Checkerboard3D {
                    tex: tex.map(r),
                    texture_from_world,
                },
                TexExpr::Scale { tex, scale } => TexExpr::Scale {
                    tex: r(tex),
                    scale: r(scale),
                },
                TexExpr::Mix { tex, amount } => TexExpr::Mix {
                    tex: tex.map(r),
                    amount: r(amount),
                },
                TexExpr::DirectionMix { tex, dir } => TexExpr::DirectionMix {
                    tex: tex.map(r),
                    dir,
                },
                leaf => leaf,
            });
        }
        Procedural { nodes }
    }
}

/// An image to decode after parsing.
pub struct ImageJob {
    pub texture: usize,
    pub path: PathBuf,
    pub name: String,
    pub srgb: bool,
    pub gamma: Option<f32>,
    pub filter: FilterMode,
    pub wrap: WrapMode,
    pub at: String,
}

/// What makes two image textures the same texture: the file (canonical path, so every
/// spelling of one file is one key) and how it is decoded and looked up.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct ImageKey {
    path: PathBuf,
    srgb: bool,
    gamma: Option<u32>,
    /// The lookup's filter and wrap modes (as their discriminants).
    filter: u8,
    wrap: u8,
    /// Normal maps keep a flat normal, not magenta, when the file cannot be decoded.
    normal: bool,
}

impl ImageKey {
    fn of(
        path: &std::path::Path,
        srgb: bool,
        gamma: Option<f32>,
        f: FilterMode,
        w: WrapMode,
    ) -> Self {
        ImageKey {
            path: path.canonicalize().unwrap_or_else(|_| path.to_path_buf()),
            normal: false,
            srgb,
            gamma: gamma.map(f32::to_bits),
            filter: f as u8,
            wrap: w as u8,
        }
    }
}

/// Resolution of the grid over [0, 1]² whose mean stands for a procedural texture where a
/// single value is needed (light-power estimates, the raycast modes' roughness).
const MEAN_GRID: u32 = 32;

impl Loader {
    /// pbrt-v4's 2D texture mapping of a `Texture` directive (`TextureMapping2D::Create`):
    /// `uv` with `uscale/vscale/udelta/vdelta`; `spherical`, `cylindrical` and `planar` (with
    /// `v1`, `v2`, `udelta`, `vdelta`) of the point in the texture's space, the inverse of the
    /// transform current at the directive.
    fn mapping_2d(&mut self, list: &ParamList, what: &str, at: &str) -> Mapping2D {
        let uv = |list: &ParamList| Mapping2D::Uv {
            su: list.float("uscale", 1.0),
            sv: list.float("vscale", 1.0),
            du: list.float("udelta", 0.0),
            dv: list.float("vdelta", 0.0),
        };
        let m = list.string("mapping").unwrap_or_else(|| "uv".into());
        if m == "uv" {
            return uv(list);
        }
        let Some(texture_from_world) = super::invert(&self.gs.ctm) else {
            self.warn(format!(
                "{at}: {what}: mapping \"{m}\" under a singular transform; uv mapping is used"
            ));
            return uv(list);
        };
        match m.as_str() {
            "spherical" => Mapping2D::Spherical { texture_from_world },
            "cylindrical" => Mapping2D::Cylindrical { texture_from_world },
            "planar" => Mapping2D::Planar {
                texture_from_world,
                vs: list.point3("v1", Vec3::X),
                vt: list.point3("v2", Vec3::Y),
                ds: list.float("udelta", 0.0),
                dt: list.float("vdelta", 0.0),
            },
            other => {
                // pbrt-v4 reports an unknown mapping and uses uv.
                self.warn(format!(
                    "{at}: {what}: mapping \"{other}\" is unknown; uv mapping is used"
                ));
                uv(list)
            }
        }
    }

    pub(super) fn texture_directive(
        &mut self,
        name: String,
        ty: &str,
        class: &str,
        list: ParamList,
        at: &str,
    ) -> Result<(), SceneError> {
        let is_float = match ty {
            "float" => true,
            "spectrum" | "color" | "rgb" => false,
            other => {
                return Err(SceneError::invalid(
                    at,
                    format!(
                        "Texture \"{name}\": unknown texture type '{other}' (float or spectrum)"
                    ),
                ));
            }
        };
        let what = format!("Texture \"{name}\"");
        let node = match class {
            "constant" => self.tex_param(&list, "value", is_float, Vec3::ONE, at),
            "scale" => {
                let t = self.tex_param(&list, "tex", is_float, Vec3::ONE, at);
                let s = self.tex_param(&list, "scale", true, Vec3::ONE, at);
                match (t, s) {
                    (TexNode::Const(t), TexNode::Const(s)) => TexNode::Const(t * s.x),
                    _ => {
                        let (tex, scale) = (self.tex.index(t), self.tex.index(s));
                        TexNode::Node(self.tex.push(TexExpr::Scale { tex, scale }))
                    }
                }
            }
            "mix" => {
                let a = self.tex_param(&list, "tex1", is_float, Vec3::ZERO, at);
                let b = self.tex_param(&list, "tex2", is_float, Vec3::ONE, at);
                let amount = self.tex_param(&list, "amount", true, Vec3::splat(0.5), at);
                match (a, b, amount) {
                    (TexNode::Const(a), TexNode::Const(b), TexNode::Const(t)) => {
                        TexNode::Const(a * (1.0 - t.x) + b * t.x)
                    }
                    _ => {
                        let tex = [self.tex.index(a), self.tex.index(b)];
                        let amount = self.tex.index(amount);
                        TexNode::Node(self.tex.push(TexExpr::Mix { tex, amount }))
                    }
                }
            }
            "directionmix" => {
                let a = self.tex_param(&list, "tex1", is_float, Vec3::ZERO, at);
                let b = self.tex_param(&list, "tex2", is_float, Vec3::ONE, at);
                // pbrt-v4: `dir` in the texture's space, taken to render space and normalised.
                let dir = self
                    .gs
                    .ctm
                    .transform_vector3(list.point3("dir", Vec3::Y))
                    .normalize_or_zero();
                if let (TexNode::Const(a), TexNode::Const(b)) = (a, b)
                    && a == b
                {
                    TexNode::Const(a)
                } else if !dir.is_finite() || dir == Vec3::ZERO {
                    return Err(SceneError::invalid(
                        at,
                        format!("{what}: \"dir\" is not a direction"),
                    ));
                } else {
                    let tex = [self.tex.index(a), self.tex.index(b)];
                    TexNode::Node(self.tex.push(TexExpr::DirectionMix { tex, dir }))
                }
            }
            "checkerboard" => {
                let a = self.tex_param(&list, "tex1", is_float, Vec3::ONE, at);
                let b = self.tex_param(&list, "tex2", is_float, Vec3::ZERO, at);
                let dim = list.int("dimension", 2);
                let e = match dim {
                    2 => {
                        let map = self.mapping_2d(&list, &what, at);
                        TexExpr::Checkerboard { tex: [0, 0], map }
                    }
                    3 => {
                        // pbrt-v4 `TextureMapping3D`: the point in the texture's space.
                        let Some(texture_from_world) = super::invert(&self.gs.ctm) else {
                            return Err(SceneError::invalid(
                                at,
                                format!("{what}: a 3D checkerboard under a singular transform"),
                            ));
                        };
                        TexExpr::Checkerboard3D {
                            tex: [0, 0],
                            texture_from_world,
                        }
                    }
                    d => {
                        return Err(SceneError::invalid(
                            at,
                            format!("{what}: {d}-dimensional checkerboards do not exist (2 or 3)"),
                        ));
                    }
                };
                if let (TexNode::Const(a), TexNode::Const(b)) = (a, b)
                    && a == b
                {
                    TexNode::Const(a)
                } else {
                    let tex = [self.tex.index(a), self.tex.index(b)];
                    TexNode::Node(self.tex.push(match e {
                        TexExpr::Checkerboard { map, .. } => TexExpr::Checkerboard { tex, map },
                        TexExpr::Checkerboard3D {
                            texture_from_world, ..
                        } => TexExpr::Checkerboard3D {
                            tex,
                            texture_from_world,
                        },
                        other => other,
                    }))
                }
            }
            "bilerp" => {
                // pbrt-v4 `BilerpTexture`: four constant corner values (not textures).
                let g = |l: &mut Loader, k: &str, d: f32| -> Vec3 {
                    match l.tex_param(&list, k, is_float, Vec3::splat(d), at) {
                        TexNode::Const(c) => c,
                        TexNode::Node(_) => {
                            l.warn(format!(
                                "{at}: {what}: \"{k}\" must be a value, not a texture; {d} is used"
                            ));
                            Vec3::splat(d)
                        }
                    }
                };
                let v = [
                    g(self, "v00", 0.0),
                    g(self, "v10", 0.0),
                    g(self, "v01", 1.0),
                    g(self, "v11", 1.0),
                ];
                let map = self.mapping_2d(&list, &what, at);
                TexNode::Node(self.tex.push(TexExpr::Bilerp { v, map }))
            }
            "imagemap" => self.imagemap(&name, &list, is_float, at)?,
            other => {
                self.warn(format!(
                    "{at}: {what} \"{other}\" is not supported; a constant 0.5 is used"
                ));
                // Its own parameters are covered by this warning.
                for q in &list.params {
                    q.used.set(true);
                }
                TexNode::Const(Vec3::splat(0.5))
            }
        };
        if let TexNode::Node(i) = node {
            let (d, c) = (self.tex.depth[i as usize], self.tex.cost[i as usize]);
            if d > procedural::MAX_DEPTH || c > procedural::MAX_COST {
                return Err(SceneError::invalid(
                    at,
                    format!(
                        "{what}: the texture graph is nested {d} deep and costs {c} evaluations \
                         per lookup (limits {} and {})",
                        procedural::MAX_DEPTH,
                        procedural::MAX_COST
                    ),
                ));
            }
        }
        self.note_unused(&list, &format!("{what} \"{class}\""), at);
        let table = if is_float {
            &mut self.float_textures
        } else {
            &mut self.spectrum_textures
        };
        table.insert(name, node);
        Ok(())
    }

    fn imagemap(
        &mut self,
        name: &str,
        list: &ParamList,
        is_float: bool,
        at: &str,
    ) -> Result<TexNode, SceneError> {
        let Some(file) = list.string("filename") else {
            return Err(SceneError::invalid(
                at,
                format!("Texture \"{name}\": imagemap without \"filename\""),
            ));
        };
        let map = self.mapping_2d(list, &format!("Texture \"{name}\""), at);
        let scale = list.float("scale", 1.0);
        let invert = list.bool("invert", false);
        // pbrt-v4 filters every one of these through its MIP pyramid; Trayecto does when
        // `--texture-filter trilinear` builds pyramids, and then "point" and "bilinear" read
        // the levels bilinearly and blended (trilinear) too. EWA is approximated by trilinear.
        let filter = match list.string("filter").as_deref() {
            Some("point") => FilterMode::Nearest,
            None | Some("bilinear" | "trilinear") => FilterMode::Bilinear,
            Some(f) => {
                self.warn(format!(
                    "{at}: Texture \"{name}\": filter \"{f}\" is not supported; bilinear \
                     (trilinear with --texture-filter trilinear) is used"
                ));
                FilterMode::Bilinear
            }
        };
        let wrap = match list.string("wrap").as_deref() {
            None | Some("repeat") => WrapMode::Repeat,
            Some("clamp") => WrapMode::ClampToEdge,
            Some(w) => {
                self.warn(format!(
                    "{at}: Texture \"{name}\": wrap \"{w}\" is not supported; clamp is used"
                ));
                WrapMode::ClampToEdge
            }
        };
        let lower = file.to_ascii_lowercase();
        let float_format = [".exr", ".pfm", ".hdr"].iter().any(|e| lower.ends_with(e));
        let (srgb, gamma) = match list.string("encoding").as_deref() {
            None => (!float_format, None),
            Some("sRGB") => (!float_format, None),
            Some("linear") => (false, None),
            // pbrt-v4 applies an encoding only to 8-bit images; float images are linear.
            Some(g) if g.starts_with("gamma ") && float_format => (false, None),
            Some(g) if g.starts_with("gamma ") => match g[6..].trim().parse::<f32>() {
                Ok(v) if v.is_finite() && v > 0.0 => (false, Some(v)),
                _ => {
                    return Err(SceneError::invalid(
                        at,
                        format!("Texture \"{name}\": bad encoding '{g}'"),
                    ));
                }
            },
            Some(other) => {
                return Err(SceneError::invalid(
                    at,
                    format!("Texture \"{name}\": unknown encoding '{other}'"),
                ));
            }
        };
        let _ = is_float;
        let path = match self.resolve(&file, at) {
            Ok(p) => p,
            Err(e) if self.in_memory() => {
                self.warn(e.to_string());
                return Ok(TexNode::Const(Vec3::splat(0.5)));
            }
            Err(e) => return Err(e),
        };
        let key = ImageKey::of(&path, srgb, gamma, filter, wrap);
        let index = match self.images_made.get(&key) {
            Some(&i) => i,
            None => {
                let index = self.scene.textures.len();
                self.scene
                    .textures
                    .push(crate::scene::image_io::missing_texture(&file));
                self.images_made.insert(key, index);
                self.image_jobs.push(ImageJob {
                    texture: index,
                    path,
                    name: file,
                    srgb,
                    gamma,
                    filter,
                    wrap,
                    at: at.to_string(),
                });
                index
            }
        };
        Ok(TexNode::Node(self.tex.push(TexExpr::Image {
            texture: index as u32,
            scale,
            invert,
            map,
        })))
    }

    pub(super) fn in_memory(&self) -> bool {
        self.root_dir.is_none()
    }

    /// A texture-or-value parameter as a node. Float values are splatted.
    fn tex_param(
        &mut self,
        list: &ParamList,
        key: &str,
        is_float: bool,
        default: Vec3,
        at: &str,
    ) -> TexNode {
        if is_float {
            match list.float_tex(key) {
                Some(TexOr::Value(v)) => TexNode::Const(Vec3::splat(v)),
                Some(TexOr::Texture(t)) => self.lookup_texture(&t, true, at),
                None => TexNode::Const(default),
            }
        } else {
            match list.spectrum_tex(key) {
                Some(TexOr::Value(s)) => TexNode::Const(self.reflectance_rgb(&s, at, key)),
                Some(TexOr::Texture(t)) => self.lookup_texture(&t, false, at),
                None => {
                    // A float given where a spectrum is expected (e.g. "float tex1") is allowed.
                    match list.floats(key) {
                        Some(v) if !v.is_empty() => TexNode::Const(Vec3::splat(v[0])),
                        _ => TexNode::Const(default),
                    }
                }
            }
        }
    }

    fn lookup_texture(&mut self, name: &str, is_float: bool, at: &str) -> TexNode {
        let (first, second) = if is_float {
            (&self.float_textures, &self.spectrum_textures)
        } else {
            (&self.spectrum_textures, &self.float_textures)
        };
        if let Some(n) = first.get(name).or_else(|| second.get(name)) {
            return *n;
        }
        self.warn(format!(
            "{at}: texture \"{name}\" is not defined; a constant 0.5 is used"
        ));
        TexNode::Const(Vec3::splat(0.5))
    }

    /// RGB of an unbounded spectrum (medium coefficients): as a reflectance-like one.
    pub(super) fn spectrum_as_rgb(&mut self, s: &SpectrumValue, at: &str, key: &str) -> Vec3 {
        self.reflectance_rgb(s, at, key)
    }

    /// RGB of a reflectance-like spectrum (albedos, η, k).
    fn reflectance_rgb(&mut self, s: &SpectrumValue, at: &str, key: &str) -> Vec3 {
        match s {
            SpectrumValue::Rgb(c) => *c,
            SpectrumValue::Named(n) => {
                if let Some(e) = super::spectra::named_glass_eta(n) {
                    return Vec3::splat(e);
                }
                if let Some((eta, k)) = super::spectra::named_metal(n) {
                    return if n.ends_with("-eta") { eta } else { k };
                }
                if let Some(v) = self.spectrum_file(n, at)
                    && let Some(c) = super::spectra::sampled_rgb(&v)
                {
                    return c;
                }
                self.warn(format!(
                    "{at}: \"{key}\": named spectrum \"{n}\" is not known; 0.5 is used"
                ));
                Vec3::splat(0.5)
            }
            SpectrumValue::Sampled(v) => super::spectra::sampled_rgb(v).unwrap_or_else(|| {
                self.warn(format!(
                    "{at}: \"{key}\": bad sampled spectrum; 0.5 is used"
                ));
                Vec3::splat(0.5)
            }),
            SpectrumValue::Blackbody(_) => {
                self.warn(format!(
                    "{at}: \"{key}\": a blackbody is not a reflectance; 0.5 is used"
                ));
                Vec3::splat(0.5)
            }
        }
    }

    /// A node as a material factor plus an optional texture reference: a constant is a factor;
    /// a `uv`-mapped, non-inverted image (or such an image scaled by a constant) is the plain
    /// image path with pbrt's mapping as a UV transform; anything else is a procedural texture
    /// evaluated per hit, made once per node.
    fn node_to_factor(&mut self, node: &TexNode) -> (Vec3, Option<TextureRef>) {
        let i = match *node {
            TexNode::Const(c) => return (c, None),
            TexNode::Node(i) => i,
        };
        let image = |e: Option<&TexExpr>| match e {
            Some(&TexExpr::Image {
                texture,
                scale,
                invert: false,
                map: Mapping2D::Uv { su, sv, du, dv },
            }) => Some((texture, scale, (su, sv, du, dv))),
            _ => None,
        };
        let mut plain = image(self.tex.get(*node)).map(|(t, s, m)| (t, s, 1.0, m));
        if let Some(&TexExpr::Scale { tex, scale }) = self.tex.get(*node)
            && let Some(&TexExpr::Const(c)) = self.tex.nodes.get(scale as usize)
            && let Some((t, s, m)) = image(self.tex.nodes.get(tex as usize))
        {
            // pbrt-v4 folds a constant `scale` texture into the image's scale too.
            plain = Some((t, s, c.x, m));
        }
        if let Some((texture, scale, k, (su, sv, du, dv))) = plain {
            // Trayecto's v runs down the image (mesh uvs are stored as (u, 1 − v)); pbrt's
            // lookup of (su·u + du, sv·v + dv) with v up is, in stored coordinates,
            // (su·u' + du, sv·v' + 1 − sv − dv).
            let mut r = TextureRef::new(texture as usize);
            if (su, sv, du, dv) != (1.0, 1.0, 0.0, 0.0) {
                r.transform = Some(UvTransform {
                    offset: Vec2::new(du, 1.0 - sv - dv),
                    rotation: 0.0,
                    scale: Vec2::new(su, sv),
                });
            }
            return (Vec3::splat(scale * k), Some(r));
        }
        if let Some((c, r)) = self.tex.made.get(&i) {
            return (*c, Some(*r));
        }
        let index = self.scene.textures.len();
        let mut t = Texture::constant("pbrt procedural texture", Vec4::ONE);
        t.procedural = Some(Box::new(self.tex.extract(i)));
        self.scene.textures.push(t);
        self.tex.procedural.push(index);
        let r = TextureRef::new(index);
        self.tex.made.insert(i, (Vec3::ONE, r));
        (Vec3::ONE, Some(r))
    }

    pub(super) fn node_to_factor_public(&mut self, node: &TexNode) -> (Vec3, Option<TextureRef>) {
        self.node_to_factor(node)
    }

    /// Decodes every image texture, in parallel.
    pub(super) fn run_image_jobs(&mut self) {
        let jobs = std::mem::take(&mut self.image_jobs);
        // The workers charge the same budget and see the same cancel flag (crate::limits).
        let ctx = crate::limits::current();
        let results: Vec<(usize, Result<Texture, String>)> = jobs
            .par_iter()
            .map(|j| {
                let r = crate::limits::scope(ctx.clone(), || decode_image(j));
                (j.texture, r)
            })
            .collect();
        for ((index, r), j) in results.into_iter().zip(&jobs) {
            match r {
                Ok(t) => self.scene.textures[index] = t,
                Err(e) => self.warn(format!(
                    "{}: texture \"{}\" could not be read ({e}): using a magenta fallback",
                    j.at, j.name
                )),
            }
        }
        self.image_jobs = jobs;
    }

    /// Sets each procedural texture's single texel to its mean over [0, 1]² of pbrt's (u, v)
    /// (after images are decoded): what a plain lookup and light-power estimates see.
    pub(super) fn run_procedural_means(&mut self) {
        let list = std::mem::take(&mut self.tex.procedural);
        let textures = &self.scene.textures;
        let means: Vec<(usize, Vec3)> = list
            .par_iter()
            .filter_map(|&i| {
                let p = textures[i].procedural.as_ref()?;
                Some((i, grid_mean(|ctx| p.eval(textures, ctx))))
            })
            .collect();
        for (i, m) in means {
            let t = &mut self.scene.textures[i];
            t.texels = crate::material::texture::Texels::F32(vec![m.extend(1.0)]);
        }
    }

    /// GGX α along u and v (pbrt's `uroughness`/`vroughness`, falling back to `roughness`),
    /// remapped as pbrt-v4's `TrowbridgeReitzDistribution::RoughnessToAlpha` when
    /// `remaproughness` is true (its default). A roughness given as a float texture is evaluated
    /// per hit (the returned [`RoughnessTextures`]); its α slot holds the α of its mean over
    /// [0,1]², which only the raycast/Whitted local shading uses.
    fn alpha_pair(&mut self, p: &ParamList, prefix: &str, at: &str) -> (Vec2, RoughnessTextures) {
        // (roughness or texture factor, texture, mean roughness over [0,1]²); a texture named
        // twice (e.g. the same for u and v) is converted once.
        type Axis = (f32, Option<TextureRef>, f32);
        let mut seen: Vec<(String, Axis)> = Vec::new();
        let mut get = |l: &mut Loader, k: &str| -> Option<Axis> {
            match p.float_tex(&format!("{prefix}{k}")) {
                Some(TexOr::Value(v)) => Some((v, None, v)),
                Some(TexOr::Texture(t)) => {
                    if let Some((_, a)) = seen.iter().find(|(n, _)| *n == t) {
                        return Some(*a);
                    }
                    let n = l.lookup_texture(&t, true, at);
                    let mean = l.mean_over_unit_square(&n).x;
                    let (c, r) = l.node_to_factor(&n);
                    seen.push((t, (c.x, r, mean)));
                    Some((c.x, r, mean))
                }
                None => None,
            }
        };
        let r = get(self, "roughness");
        let u = get(self, "uroughness");
        let v = get(self, "vroughness");
        let zero = (0.0, None, 0.0);
        let (u, v) = match (u, v, r) {
            (Some(u), Some(v), _) => (u, v),
            (Some(u), None, r) => (u, r.unwrap_or(zero)),
            (None, Some(v), r) => (r.unwrap_or(zero), v),
            (None, None, r) => (r.unwrap_or(zero), r.unwrap_or(zero)),
        };
        let remap = p.bool("remaproughness", true);
        let fix = |x: f32| if x.is_finite() { x.max(0.0) } else { 0.0 };
        let alpha = Vec2::new(
            pbrt_roughness_to_alpha(fix(u.2), remap),
            pbrt_roughness_to_alpha(fix(v.2), remap),
        );
        let textures = RoughnessTextures {
            u: u.1,
            v: v.1,
            factor: Vec2::new(fix(u.0), fix(v.0)),
            remap,
        };
        (alpha, textures)
    }

    /// glTF perceptual roughness (α = roughness²) for the models that are isotropic
    /// (dielectric): anisotropy is warned and rendered with α = √(αu·αv). Roughness textures
    /// go to the returned [`Dielectric`] (evaluated per hit, [`crate::material::eval`]).
    fn roughness(&mut self, p: &ParamList, at: &str, what: &str) -> (f32, Dielectric) {
        let mut dielectric = Dielectric::default();
        let (a, tex) = self.alpha_pair(p, "", at);
        if tex.is_textured() {
            if tex.u != tex.v || tex.factor.x != tex.factor.y {
                self.warn(format!(
                    "{at}: {what}: anisotropic roughness textures are rendered isotropic with α = √(αu·αv) per hit"
                ));
            }
            dielectric.alpha = a;
            dielectric.roughness = tex;
        }
        let (au, av) = (a.x, a.y);
        if !tex.is_textured() && (au - av).abs() > 1e-6 * au.max(av) {
            self.warn(format!(
                "{at}: {what}: anisotropic roughness (α {au} × {av}) is rendered isotropic with α = √(αu·αv)"
            ));
        }
        let alpha = (au * av).sqrt();
        (alpha.sqrt().clamp(0.0, 1.0), dielectric)
    }

    /// A node's mean over [0, 1]² of pbrt's (u, v) (images read as far as they are decoded).
    fn mean_over_unit_square(&self, n: &TexNode) -> Vec3 {
        match *n {
            TexNode::Const(c) => c,
            TexNode::Node(i) => grid_mean(|ctx| {
                procedural::eval_node(&self.tex.nodes, i, &self.scene.textures, ctx)
            }),
        }
    }

    /// A node's value at pbrt's (u, v) = (0.5, 0.5).
    fn value_at_centre(&self, n: &TexNode) -> Vec3 {
        match *n {
            TexNode::Const(c) => c,
            TexNode::Node(i) => {
                let ctx = TexCtx {
                    uv: Vec2::splat(0.5),
                    n: Vec3::Z,
                    ..Default::default()
                };
                procedural::eval_node(&self.tex.nodes, i, &self.scene.textures, &ctx)
            }
        }
    }

    /// A spectrum parameter the pbrt-v4 models take as a constant (layer albedo, diffuse
    /// transmittance): a texture is warned and replaced by its mean.
    fn constant_spectrum(
        &mut self,
        p: &ParamList,
        key: &str,
        default: Vec3,
        at: &str,
        what: &str,
    ) -> Vec3 {
        let n = self.tex_param(p, key, false, default, at);
        match n {
            TexNode::Const(c) => c,
            TexNode::Node(_) => {
                self.warn(format!(
                    "{at}: {what}: a textured \"{key}\" is not supported; its mean over [0,1]² is used"
                ));
                self.mean_over_unit_square(&n)
            }
        }
    }

    /// A float parameter the model takes as a constant (the hair's roughnesses, angle, η and
    /// melanin): a texture is warned and `default` used.
    fn constant_float(
        &mut self,
        p: &ParamList,
        key: &str,
        default: f32,
        at: &str,
        what: &str,
    ) -> f32 {
        match p.float_tex(key) {
            Some(TexOr::Value(v)) if v.is_finite() => v,
            Some(TexOr::Value(v)) => {
                self.warn(format!(
                    "{at}: {what}: \"{key}\" {v} is not a number; {default} is used"
                ));
                default
            }
            Some(TexOr::Texture(t)) => {
                self.warn(format!(
                    "{at}: {what}: a textured \"{key}\" (\"{t}\") is not supported; {default} is used"
                ));
                default
            }
            None => default,
        }
    }

    /// The coat's slab (pbrt-v4 `LayeredBxDF`): thickness, albedo, g, maxdepth, nsamples, put in
    /// the ranges the BSDF accepts (out-of-range values are warned, not errors: pbrt-v4 takes
    /// them without checking).
    fn layer_params(&mut self, p: &ParamList, at: &str, what: &str) -> Slab {
        let thickness = p.float("thickness", 0.01);
        let albedo = self.constant_spectrum(p, "albedo", Vec3::ZERO, at, what);
        let g = p.float("g", 0.0);
        let max_depth = p.int("maxdepth", 10);
        let n_samples = p.int("nsamples", 1);
        let thickness = if thickness.is_finite() && thickness > 0.0 {
            thickness
        } else {
            self.warn(format!(
                "{at}: {what}: thickness {thickness} is not positive; 0.01 is used"
            ));
            0.01
        };
        let a = if albedo.is_finite() {
            albedo.clamp(Vec3::ZERO, Vec3::ONE)
        } else {
            Vec3::ZERO
        };
        if a != albedo {
            self.warn(format!(
                "{at}: {what}: albedo {albedo:?} is clamped to [0, 1]"
            ));
        }
        let g = if g.is_finite() && g.abs() < 1.0 {
            g
        } else {
            self.warn(format!("{at}: {what}: g {g} is outside (-1, 1); 0 is used"));
            0.0
        };
        let clamp_count = |l: &mut Loader, v: i64, name: &str, d: u32| -> u32 {
            if (1..=1000).contains(&v) {
                v as u32
            } else {
                l.warn(format!(
                    "{at}: {what}: {name} {v} is outside 1..=1000; {d} is used"
                ));
                d
            }
        };
        Slab {
            thickness,
            albedo: a,
            g,
            max_depth: clamp_count(self, max_depth, "maxdepth", 10),
            n_samples: clamp_count(self, n_samples, "nsamples", 1),
        }
    }

    /// Conductor η and k (pbrt `eta`/`k`, or `reflectance`) with prefix `pre` for the η/k keys.
    fn conductor_params(
        &mut self,
        p: &ParamList,
        pre: &str,
        m: &mut Material,
        at: &str,
        what: &str,
    ) -> Conductor {
        let mut c = Conductor::default();
        (c.alpha, c.roughness) = self.alpha_pair(p, pre, at);
        let has_eta_k = p.has(&format!("{pre}eta")) || p.has(&format!("{pre}k"));
        if let Some(r) = p.spectrum_tex("reflectance") {
            if has_eta_k {
                self.warn(format!("{at}: {what}: both \"reflectance\" and \"{pre}eta\"/\"{pre}k\" are given (pbrt-v4 refuses this); the reflectance is used"));
                let _ = (
                    p.spectrum_tex(&format!("{pre}eta")),
                    p.spectrum_tex(&format!("{pre}k")),
                );
            }
            let node = match r {
                TexOr::Value(s) => TexNode::Const(self.reflectance_rgb(&s, at, "reflectance")),
                TexOr::Texture(t) => self.lookup_texture(&t, false, at),
            };
            let (color, t) = self.node_to_factor(&node);
            m.base_color = color;
            m.base_color_texture = t;
            c.reflectance = true;
        } else {
            (c.eta, c.eta_texture) =
                self.conductor_spectrum(p, &format!("{pre}eta"), "metal-Cu-eta", at);
            (c.k, c.k_texture) = self.conductor_spectrum(p, &format!("{pre}k"), "metal-Cu-k", at);
            c.reflectance = false;
            // η and k given as spectra (named metals, pbrt-v4's copper default, sampled lists,
            // spectrum files) stay spectra for spectral rendering; one given as RGB is
            // upsampled there from its value.
            let eta = self.bsdf_spectrum(p, &format!("{pre}eta"), Some("metal-Cu-eta"));
            let k = self.bsdf_spectrum(p, &format!("{pre}k"), Some("metal-Cu-k"));
            c.spectra =
                (eta.is_some() || k.is_some()).then_some(crate::spectrum::ConductorSpectra {
                    eta,
                    k,
                    outside_ior: 1.0,
                });
            let e = c.eta;
            let k = c.k;
            if !(e.is_finite() && k.is_finite()) || e.min_element() < 0.0 || k.min_element() < 0.0 {
                self.warn(format!("{at}: {what}: eta {e:?} / k {k:?} are not finite and non-negative; metal-Cu is used"));
                let d = Conductor::default();
                c.eta = d.eta;
                c.k = d.k;
                c.spectra = crate::spectrum::ConductorSpectra::named("metal-Cu-eta", "metal-Cu-k");
            }
        }
        c
    }

    /// The id in [`crate::spectrum::BsdfSpectra`] of the spectrum parameter `key` when it is
    /// given as a spectrum spectral rendering can follow: a named metal or glass, a sampled
    /// `[λ v …]` list or a spectrum file (kept in [`crate::scene::Scene::bsdf_spectra`]);
    /// `default`'s when the parameter is absent. `None` for RGB, a texture or a bad spectrum
    /// (whose RGB value, already warned about, is then upsampled).
    fn bsdf_spectrum(&mut self, p: &ParamList, key: &str, default: Option<&str>) -> Option<u16> {
        let samples = match p.spectrum_tex(key) {
            Some(TexOr::Value(SpectrumValue::Named(n))) => {
                if let Some(id) =
                    crate::spectrum::tabulated_id(&n).or_else(|| crate::spectrum::glass_id(&n))
                {
                    return Some(id);
                }
                self.spectrum_file_quiet(&n)?
            }
            Some(TexOr::Value(SpectrumValue::Sampled(v))) => v,
            None if !p.has(key) => {
                return default.and_then(|d| {
                    crate::spectrum::tabulated_id(d).or_else(|| crate::spectrum::glass_id(d))
                });
            }
            _ => return None,
        };
        let table = crate::spectrum::SpectrumTable::sampled(&samples)?;
        self.scene.add_bsdf_spectrum(table)
    }

    /// η or k of a conductor: named spectra through [`crate::spectrum`] (the conversion measured
    /// against pbrt-v4 in `scripts/references/pbrt_metal_patches.py`), RGB as given, a texture
    /// as its factor and texture, evaluated per hit ([`Conductor::eta_k`]).
    fn conductor_spectrum(
        &mut self,
        p: &ParamList,
        key: &str,
        default: &str,
        at: &str,
    ) -> (Vec3, Option<TextureRef>) {
        match p.spectrum_tex(key) {
            Some(TexOr::Value(SpectrumValue::Named(n))) => {
                if let Some(c) = crate::spectrum::named_spectrum_rgb(&n) {
                    return (c, None);
                }
            }
            Some(TexOr::Texture(t)) => {
                let n = self.lookup_texture(&t, false, at);
                return self.node_to_factor(&n);
            }
            _ => {}
        }
        if !p.has(key)
            && let Some(c) = crate::spectrum::named_spectrum_rgb(default)
        {
            return (c, None);
        }
        (self.spectrum_const(p, key, default, at), None)
    }

    fn spectrum_factor(
        &mut self,
        p: &ParamList,
        key: &str,
        default: Vec3,
        at: &str,
    ) -> (Vec3, Option<TextureRef>) {
        let node = self.tex_param(p, key, false, default, at);
        self.node_to_factor(&node)
    }

    /// Converts a material. `depth` guards `mix` recursion.
    pub(super) fn convert_material(&mut self, spec: &MatSpec, depth: u32) -> Material {
        let p = &spec.params;
        let at = spec.at.as_str();
        let what = format!("material \"{}\" ({})", spec.name, spec.ty);
        let mut m = Material {
            name: spec.name.clone(),
            ..Default::default()
        };
        // Parameters every material may have.
        let _ = p.string("type");
        // pbrt-v4 `displacement`: bump mapping of the shading normal per hit (eval::bump); a
        // constant displaces nothing.
        if let Some(d) = p.float_tex("displacement") {
            if let TexOr::Texture(t) = d {
                let n = self.lookup_texture(&t, true, at);
                let (c, r) = self.node_to_factor(&n);
                if r.is_some() && c.x != 0.0 && c.x.is_finite() {
                    m.displacement = r;
                    m.displacement_scale = c.x;
                }
            }
            if p.has("normalmap") {
                self.warn(format!(
                    "{at}: {what}: both \"displacement\" and \"normalmap\" are given; the normal map is used (as pbrt-v4 does)"
                ));
            }
        }
        if let Some(n) = p.string("normalmap") {
            self.normal_map(&mut m, &n, at, &what);
        }
        match spec.ty.as_str() {
            "diffuse" => {
                let (c, t) = self.spectrum_factor(p, "reflectance", Vec3::splat(0.5), at);
                m.model = MaterialModel::Diffuse;
                m.base_color = c;
                m.base_color_texture = t;
            }
            "coateddiffuse" => {
                // pbrt-v4 CoatedDiffuseMaterial: a dielectric interface over a Lambertian base
                // with a homogeneous slab between them (LayeredBxDF, stochastic evaluation).
                let (c, t) = self.spectrum_factor(p, "reflectance", Vec3::splat(0.5), at);
                m.base_color = c;
                m.base_color_texture = t;
                let mut coat = Coat::default();
                (coat.alpha, coat.roughness) = self.alpha_pair(p, "", at);
                coat.eta = self.eta(p, at, &what);
                coat.eta_spectrum = self.dispersive_eta(p, "eta");
                let slab = self.layer_params(p, at, &what);
                m.model = MaterialModel::CoatedDiffuse(CoatedDiffuse { coat, slab });
            }
            "conductor" => {
                let c = self.conductor_params(p, "", &mut m, at, &what);
                m.model = MaterialModel::Conductor(c);
            }
            "coatedconductor" => {
                // pbrt-v4 CoatedConductorMaterial: `interface.*` for the coat, `conductor.*` for
                // the base, an unprefixed `reflectance` instead of conductor.eta/k.
                let conductor = self.conductor_params(p, "conductor.", &mut m, at, &what);
                let mut coat = Coat::default();
                (coat.alpha, coat.roughness) = self.alpha_pair(p, "interface.", at);
                coat.eta = self.prefixed_eta(p, "interface.", at, &what);
                coat.eta_spectrum = self.dispersive_eta(p, "interface.eta");
                let slab = self.layer_params(p, at, &what);
                m.model = MaterialModel::CoatedConductor(CoatedConductor {
                    coat,
                    conductor,
                    slab,
                });
            }
            "dielectric" | "thindielectric" => {
                let eta = self.eta(p, at, &what);
                let (rough, mut dielectric) = if spec.ty == "dielectric" {
                    self.roughness(p, at, &what)
                } else {
                    (0.0, Dielectric::default())
                };
                // An η spectrum varying with λ (a named glass, a sampled η) disperses in spectral
                // rendering (pbrt-v4 follows η(λ)); a constant one is the IOR.
                let eta_spectrum = self.dispersive_eta(p, "eta");
                dielectric.eta_spectrum = eta_spectrum;
                m.ior = eta;
                m.base_color = Vec3::ONE;
                m.roughness = rough;
                if spec.ty == "dielectric" {
                    m.model = MaterialModel::Dielectric(dielectric);
                } else {
                    m.model = MaterialModel::metallic_roughness();
                    if let Some(x) = m.metallic_roughness_mut() {
                        x.eta_spectrum = eta_spectrum;
                    }
                    m.metallic = 0.0;
                    m.transmission = 1.0;
                    m.thin_walled = true;
                }
            }
            "diffusetransmission" => {
                // pbrt-v4 DiffuseTransmissionMaterial: Lambertian reflection and transmission,
                // both multiplied by `scale`.
                let scale = p.float("scale", 1.0);
                let scale = if scale.is_finite() && scale >= 0.0 {
                    scale
                } else {
                    self.warn(format!(
                        "{at}: {what}: scale {scale} is not a non-negative number; 1 is used"
                    ));
                    1.0
                };
                let (c, t) = self.spectrum_factor(p, "reflectance", Vec3::splat(0.25), at);
                let tr = self.constant_spectrum(p, "transmittance", Vec3::splat(0.25), at, &what);
                m.base_color = c * scale;
                m.base_color_texture = t;
                m.model = MaterialModel::DiffuseTransmission(DiffuseTransmission {
                    transmittance: if tr.is_finite() {
                        tr.max(Vec3::ZERO) * scale
                    } else {
                        Vec3::splat(0.25)
                    },
                });
            }
            "mix" => {
                // pbrt-v4 MixMaterial: one of the two materials is chosen per hit with
                // probability `amount` for materials[1] (eval::resolve_mix). This material only
                // holds the choice (and, from the graphics state, emission and alpha).
                let names = p.strings("materials").unwrap_or_default();
                let (mut amount, texture) = match p.float_tex("amount") {
                    Some(TexOr::Value(v)) => (v, None),
                    Some(TexOr::Texture(t)) => {
                        let n = self.lookup_texture(&t, true, at);
                        let (c, r) = self.node_to_factor(&n);
                        (c.x, r)
                    }
                    None => (0.5, None),
                };
                if !amount.is_finite() {
                    self.warn(format!(
                        "{at}: {what}: amount {amount} is not a number; 0.5 is used"
                    ));
                    amount = 0.5;
                }
                if names.len() != 2 {
                    self.warn(format!("{at}: {what}: \"materials\" must name two materials; the default material is used"));
                    return Material::diffuse(&spec.name, Vec3::splat(0.5));
                }
                if depth > 16 {
                    self.warn(format!(
                        "{at}: {what}: mix materials nested too deeply (a mix that contains itself?); the default material is used"
                    ));
                    return Material::diffuse(&spec.name, Vec3::splat(0.5));
                }
                let a = self.mix_component(&names[0], at, depth);
                let b = self.mix_component(&names[1], at, depth);
                m.model = MaterialModel::Mix(Mix {
                    materials: [a as u32, b as u32],
                    amount,
                    amount_texture: texture,
                });
            }
            "hair" => {
                // pbrt-v4 HairMaterial: σ_a given, else `reflectance` (or `color`) inverted, else
                // melanin concentrations; brown hair (eumelanin 1.3) when none is given.
                let mut h = Hair {
                    beta_m: self.constant_float(p, "beta_m", 0.3, at, &what),
                    beta_n: self.constant_float(p, "beta_n", 0.3, at, &what),
                    alpha: self.constant_float(p, "alpha", 2.0, at, &what),
                    eta: self.constant_float(p, "eta", 1.55, at, &what),
                    ..Hair::default()
                };
                let colour_key = if p.has("reflectance") {
                    Some("reflectance")
                } else if p.has("color") {
                    Some("color")
                } else {
                    None
                };
                let melanin = p.has("eumelanin") || p.has("pheomelanin");
                let ignored = |names: &[&str]| -> Vec<String> {
                    names
                        .iter()
                        .filter(|n| p.has(n))
                        .map(|n| format!("\"{n}\""))
                        .collect()
                };
                let (absorption, unused) = if p.has("sigma_a") {
                    let s = self.constant_spectrum(p, "sigma_a", Vec3::ZERO, at, &what);
                    (
                        HairAbsorption::SigmaA(s),
                        ignored(&["reflectance", "color", "eumelanin", "pheomelanin"]),
                    )
                } else if let Some(key) = colour_key {
                    let (c, t) = self.spectrum_factor(p, key, Vec3::splat(0.5), at);
                    m.base_color = c;
                    m.base_color_texture = t;
                    (
                        HairAbsorption::Reflectance,
                        ignored(&["eumelanin", "pheomelanin"]),
                    )
                } else if melanin {
                    let eumelanin = self.constant_float(p, "eumelanin", 0.0, at, &what);
                    let pheomelanin = self.constant_float(p, "pheomelanin", 0.0, at, &what);
                    (
                        HairAbsorption::Melanin {
                            eumelanin,
                            pheomelanin,
                        },
                        Vec::new(),
                    )
                } else {
                    (h.absorption, Vec::new())
                };
                if !unused.is_empty() {
                    self.warn(format!(
                        "{at}: {what}: {} ignored: the absorption is taken from the first of \"sigma_a\", \"reflectance\", the melanin concentrations (as pbrt-v4 does)",
                        unused.join(", ")
                    ));
                    for n in ["reflectance", "color", "eumelanin", "pheomelanin"] {
                        if p.has(n) {
                            let _ = p.spectrum_tex(n);
                            let _ = p.float_tex(n);
                        }
                    }
                }
                h.absorption = absorption;
                m.model = MaterialModel::Hair(h);
            }
            "interface" => {
                // A boundary that only separates media (pbrt-v4 `interface`): no surface.
                m.model = MaterialModel::Interface;
                m.ior = 1.0;
                m.roughness = 0.0;
            }
            other => {
                let (c, t) = self.spectrum_factor(p, "reflectance", Vec3::splat(0.5), at);
                m.model = MaterialModel::Diffuse;
                m.base_color = c;
                m.base_color_texture = t;
                self.warn(format!(
                    "{at}: {what}: material type \"{other}\" is not supported; a diffuse material{} is used",
                    if p.has("reflectance") { " with its reflectance" } else { "" }
                ));
                // Its own parameters are covered by this warning.
                for q in &p.params {
                    q.used.set(true);
                }
            }
        }
        self.note_unused(p, &what, at);
        m
    }

    /// A component of a `mix`: the named material (without an area light) as a scene material,
    /// shared with the shapes that name it. A name defined later is filled in at the end, as
    /// pbrt-v4 creates named materials at the end of the world block.
    fn mix_component(&mut self, n: &str, at: &str, depth: u32) -> crate::scene::MaterialId {
        // The keys `current_material` uses for the same name without an area light.
        let key = format!("named {n}|None");
        let pending_key = format!("pending {n}|None");
        if let Some(id) = self
            .material_cache
            .get(&key)
            .or_else(|| self.material_cache.get(&pending_key))
        {
            return *id;
        }
        let Some(spec) = self.named_materials.get(n).cloned() else {
            let id = self
                .scene
                .add_material(Material::diffuse("pbrt default", Vec3::splat(0.5)));
            self.material_cache.insert(pending_key, id);
            self.pending_materials
                .push((id, n.to_string(), None, at.to_string()));
            return id;
        };
        let m = self.convert_material(&spec, depth + 1);
        let id = self.scene.add_material(m);
        self.material_cache.insert(key, id);
        id
    }

    fn eta(&mut self, p: &ParamList, at: &str, what: &str) -> f32 {
        self.prefixed_eta(p, "", at, what)
    }

    fn prefixed_eta(&mut self, p: &ParamList, pre: &str, at: &str, what: &str) -> f32 {
        let key = format!("{pre}eta");
        let e = match p.float_tex(&key) {
            Some(TexOr::Value(v)) => v,
            Some(TexOr::Texture(t)) => {
                self.warn(format!(
                    "{at}: {what}: a textured eta (\"{t}\") is not supported; 1.5 is used"
                ));
                1.5
            }
            None => match p.spectrum(&key) {
                Some(SpectrumValue::Named(n)) => match super::spectra::named_glass_eta(&n) {
                    Some(e) => {
                        self.warn_once(
                            &format!("disp {n}"),
                            format!("{at}: {what}: spectrally varying eta \"{n}\" is rendered with its index at 587.6 nm ({e}) in RGB; --spectral disperses it"),
                        );
                        e
                    }
                    None => match self.spectrum_file(&n, at) {
                        Some(v) => self.sampled_eta(&v, &key, at, what),
                        None => {
                            self.warn(format!(
                                "{at}: {what}: eta spectrum \"{n}\" is not known; 1.5 is used"
                            ));
                            1.5
                        }
                    },
                },
                Some(SpectrumValue::Rgb(c)) => (c.x + c.y + c.z) / 3.0,
                Some(SpectrumValue::Sampled(v)) => self.sampled_eta(&v, &key, at, what),
                Some(other) => {
                    self.warn(format!(
                        "{at}: {what}: eta {other:?} is not supported; 1.5 is used"
                    ));
                    1.5
                }
                None => 1.5,
            },
        };
        if !(e.is_finite() && e > 0.0) {
            self.warn(format!(
                "{at}: {what}: eta {e} is not positive; 1.5 is used"
            ));
            return 1.5;
        }
        e
    }

    /// The IOR RGB rendering gives a sampled η(λ) (a list or a spectrum file): its value at the
    /// helium d line, 587.56 nm, as for a named glass (pbrt-v4 follows η(λ), and so does
    /// spectral rendering where the material disperses: [`Self::bsdf_spectrum`]).
    fn sampled_eta(&mut self, v: &[(f32, f32)], key: &str, at: &str, what: &str) -> f32 {
        let Some(t) = crate::spectrum::SpectrumTable::sampled(v) else {
            self.warn(format!(
                "{at}: {what}: \"{key}\": bad sampled spectrum; 1.5 is used"
            ));
            return 1.5;
        };
        let e = t.value(587.56);
        if v.iter().any(|s| s.1 != v[0].1) {
            self.warn_once(
                &format!("disp sampled {key}"),
                format!("{at}: {what}: spectrally varying \"{key}\" is rendered with its index at 587.6 nm ({e}) in RGB; --spectral disperses it"),
            );
        }
        e
    }

    /// The [`crate::spectrum::BsdfSpectra`] id of the η parameter `key` when it is a spectrum
    /// that varies over 360–830 nm (a named glass, a sampled list or file): spectral rendering
    /// disperses it at the hero wavelength, as pbrt-v4's dielectric, thin dielectric and coated
    /// materials do (they terminate the secondary wavelengths for any non-constant η). `None`
    /// for a float, RGB or constant η.
    fn dispersive_eta(&mut self, p: &ParamList, key: &str) -> Option<u16> {
        self.bsdf_spectrum(p, key, None)
            .filter(|&id| !self.constant_eta(id))
    }

    /// True if the η spectrum `id` is one value wherever spectral rendering samples it
    /// (360–830 nm, 0 beyond a sampled η's wavelengths counting as 1, as pbrt-v4's dielectric
    /// takes it): such a dielectric does not disperse.
    fn constant_eta(&self, id: u16) -> bool {
        let spectra = crate::spectrum::BsdfSpectra {
            tables: self.scene.bsdf_spectra.clone().into(),
        };
        let eta = |l: u32| {
            let e = spectra.value(id, l as f32);
            if e == 0.0 { 1.0 } else { e }
        };
        let first = eta(360);
        (361..=830).all(|l| eta(l) == first)
    }

    /// A constant spectrum parameter with a named default (η and k of conductors).
    fn spectrum_const(&mut self, p: &ParamList, key: &str, default: &str, at: &str) -> Vec3 {
        match p.spectrum_tex(key) {
            Some(TexOr::Value(s)) => self.reflectance_rgb(&s, at, key),
            Some(TexOr::Texture(t)) => {
                let n = self.lookup_texture(&t, false, at);
                self.warn(format!("{at}: \"{key}\": a textured value (\"{t}\") is not supported; its value at the centre is used"));
                self.value_at_centre(&n)
            }
            None => self.reflectance_rgb(&SpectrumValue::Named(default.into()), at, key),
        }
    }
}

impl Loader {
    /// pbrt-v4's `normalmap`: an image read with linear encoding whose texel (bilinear, repeat)
    /// is a tangent-space normal 2c − 1 in the frame (∂p/∂u, n × ∂p/∂u, n) (pbrt-v4
    /// `NormalMap`, `Frame::FromXZ`). Trayecto's tangent-space normal mapping uses the same frame
    /// for meshes whose uv parameterisation is not mirrored (its bitangent follows ∂p/∂v, which
    /// n × ∂p/∂u then equals). A missing image is a warning and the surface stays unmapped.
    fn normal_map(&mut self, m: &mut Material, file: &str, at: &str, what: &str) {
        let path = match self.resolve(file, at) {
            Ok(p) if p.is_file() => p,
            Ok(_) => {
                self.warn(format!(
                    "{at}: {what}: normal map \"{file}\" does not exist; the surface is not normal-mapped"
                ));
                return;
            }
            Err(e) => {
                self.warn(format!("{e}; the surface is not normal-mapped"));
                return;
            }
        };
        let key = ImageKey {
            normal: true,
            ..ImageKey::of(&path, false, None, FilterMode::Bilinear, WrapMode::Repeat)
        };
        if let Some(&index) = self.images_made.get(&key) {
            m.normal_texture = Some(crate::material::texture::TextureRef::new(index));
            m.normal_scale = 1.0;
            return;
        }
        let index = self.scene.textures.len();
        self.images_made.insert(key, index);
        // A flat normal until the image is decoded (and if it cannot be).
        self.scene.textures.push(Texture::image(
            file,
            1,
            1,
            vec![Vec4::new(0.5, 0.5, 1.0, 1.0)],
        ));
        self.image_jobs.push(ImageJob {
            texture: index,
            path,
            name: file.to_string(),
            srgb: false,
            gamma: None,
            filter: FilterMode::Bilinear,
            wrap: WrapMode::Repeat,
            at: at.to_string(),
        });
        m.normal_texture = Some(crate::material::texture::TextureRef::new(index));
        m.normal_scale = 1.0;
    }
}

/// The mean of `f` over a [`MEAN_GRID`]² grid of cell centres of pbrt's (u, v) ∈ [0, 1]² (at
/// the origin, normal +z, no footprint).
fn grid_mean(f: impl Fn(&TexCtx) -> Vec3) -> Vec3 {
    let n = MEAN_GRID;
    let mut s = Vec3::ZERO;
    for i in 0..n {
        for j in 0..n {
            let ctx = TexCtx {
                uv: Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32),
                n: Vec3::Z,
                ..Default::default()
            };
            s += f(&ctx);
        }
    }
    s / (n * n) as f32
}

/// Reads and decodes one image (PNG, JPEG, TGA, HDR via the `image` crate; EXR via the loader
/// shared with the environment maps; PFM by hand).
pub(crate) fn decode_image(j: &ImageJob) -> Result<Texture, String> {
    let lower = j.name.to_ascii_lowercase();
    let mut t = if lower.ends_with(".exr") {
        decode_exr(&j.name, &j.path)?
    } else {
        let bytes = crate::limits::read_file(&j.path).map_err(|e| e.to_string())?;
        if lower.ends_with(".pfm") {
            crate::scene::image_io::decode_pfm(&j.name, &bytes)?
        } else {
            crate::scene::image_io::decode_texture(&j.name, &bytes, j.srgb)?
        }
    };
    if let Some(g) = j.gamma {
        t.map_texels(|c| {
            Vec4::new(
                c.x.max(0.0).powf(g),
                c.y.max(0.0).powf(g),
                c.z.max(0.0).powf(g),
                c.w,
            )
        });
    }
    t.filter = j.filter;
    t.wrap_s = j.wrap;
    t.wrap_t = j.wrap;
    Ok(t)
}

fn decode_exr(name: &str, path: &std::path::Path) -> Result<Texture, String> {
    let img = crate::film::output::read_exr(path).map_err(|e| e.to_string())?;
    let (w, h) = (img.width, img.height);
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("image size {w}×{h} is not supported"));
    }
    crate::limits::charge(u64::from(w) * u64::from(h) * 16, || {
        format!("the {w}×{h} texture '{name}'")
    })?;
    Ok(Texture::image(
        name,
        w,
        h,
        img.data.iter().map(|c| c.extend(1.0)).collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::image_io::decode_pfm;

    #[test]
    fn pfm_rows_are_flipped_and_truncation_is_an_error() {
        let mut f = b"PF\n2 1\n-1.0\n".to_vec();
        for v in [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0] {
            f.extend_from_slice(&v.to_le_bytes());
        }
        let t = decode_pfm("x", &f).unwrap();
        assert_eq!(t.texels.get(1), Vec4::new(4.0, 5.0, 6.0, 1.0));
        assert!(decode_pfm("x", &f[..f.len() - 1]).is_err());
        assert!(decode_pfm("x", b"PF\n999999 999999\n-1\n").is_err());
    }
}
