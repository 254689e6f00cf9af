//! pbrt-v4 shapes as Trayecto geometry. Triangle and bilinear meshes, PLY files, spheres, disks
//! and cylinders (tessellated where Trayecto has no matching analytic shape), Loop subdivision
//! surfaces (subdivided), and curves (cubic Bézier curve primitives, [`crate::geometry::curve`]).
//!
//! Front faces follow pbrt-v4 (`Triangle::InteractionFromIntersection`, the quadrics): a mesh
//! with normals faces them, one without faces its counter-clockwise side; quadrics face outwards
//! (+z for disks); `ReverseOrientation` flips all of these. Trayecto's front face is the
//! counter-clockwise side (kept through mirroring transforms), so triangles are re-wound here.

use rayon::prelude::*;

use super::params::{ParamList, TexOr};
use super::{Loader, PlyJob};
use crate::geometry::curve::CurveType;
use crate::material::AlphaMode;
use crate::math::{Vec2, Vec3};
use crate::scene::{CurveShape, Mesh, SceneError, Shape};

/// Largest decompressed `.ply.gz` accepted, in bytes.
const MAX_GUNZIP: u64 = 4 << 30;
/// Largest expansion of a `.ply.gz` accepted: meshes compress a few times, a file of zeros
/// a thousand times (deflate's limit is 1032:1).
const MAX_GUNZIP_RATIO: u64 = 64;
/// Most Loop subdivision levels applied (each multiplies the triangle count by 4).
const MAX_LOOP_LEVELS: i64 = 6;
/// Memory per triangle of a subdivided mesh: 12 bytes of indices, 24 of position and normal
/// for its half vertex, and the previous level's copy while the next is made.
const LOOP_BYTES_PER_TRIANGLE: u64 = 48;
/// Grid resolution of tessellated quadrics (around × along).
const QUADRIC_STEPS: (usize, usize) = (96, 48);

/// Winds every triangle so its counter-clockwise side is pbrt's front: towards the vertex
/// normals when the mesh has them; then flips everything for `ReverseOrientation`.
pub fn orient(mesh: &mut Mesh, reverse: bool) {
    if let Some(n) = &mesh.normals {
        for t in &mut mesh.indices {
            let [a, b, c] = t.map(|i| i as usize);
            let (Some(pa), Some(pb), Some(pc)) = (
                mesh.positions.get(a),
                mesh.positions.get(b),
                mesh.positions.get(c),
            ) else {
                continue;
            };
            let ng = (*pb - *pa).cross(*pc - *pa);
            let ns = n.get(a).copied().unwrap_or(Vec3::ZERO)
                + n.get(b).copied().unwrap_or(Vec3::ZERO)
                + n.get(c).copied().unwrap_or(Vec3::ZERO);
            if ng.dot(ns) < 0.0 {
                t.swap(1, 2);
            }
        }
    }
    if reverse {
        for t in &mut mesh.indices {
            t.swap(1, 2);
        }
        if let Some(n) = &mut mesh.normals {
            for v in n.iter_mut() {
                *v = -*v;
            }
        }
    }
}

/// pbrt's (u, v), v up, stored the way Trayecto's meshes store texture coordinates (v down).
fn to_stored_uv(uv: Vec2) -> Vec2 {
    Vec2::new(uv.x, 1.0 - uv.y)
}

impl Loader {
    pub(super) fn shape(&mut self, ty: &str, list: ParamList, at: &str) -> Result<(), SceneError> {
        let name = format!("{ty} ({at})");
        let what = format!("Shape \"{ty}\"");
        // Parameters every shape may have.
        let alpha = list.float_tex("alpha");
        if self.current_object.is_some() && self.gs.area_light.is_some() {
            self.warn_once(
                &format!("instlight {at}"),
                format!("{at}: {what}: area lights inside ObjectBegin are not supported by pbrt-v4 either; the instances emit anyway"),
            );
        }
        let reverse = self.gs.reverse;
        self.light_area = None;
        let shape: Option<Shape> = match ty {
            "trianglemesh" => {
                let p = list.point3s("P");
                let Some(p) = p else {
                    return Err(SceneError::invalid(at, "trianglemesh without \"point3 P\""));
                };
                let indices = match list.ints("indices") {
                    Some(i) => i,
                    None if p.len() == 3 => vec![0, 1, 2],
                    None => {
                        return Err(SceneError::invalid(
                            at,
                            "trianglemesh without \"integer indices\" (only a 3-vertex mesh may omit them)",
                        ));
                    }
                };
                if indices.len() % 3 != 0 {
                    return Err(SceneError::invalid(
                        at,
                        format!(
                            "trianglemesh: {} indices is not a multiple of 3",
                            indices.len()
                        ),
                    ));
                }
                let mut mesh = Mesh {
                    name: name.clone(),
                    positions: p,
                    ..Default::default()
                };
                mesh.indices = checked_indices(&indices, 3, mesh.positions.len(), at)?
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect();
                self.mesh_attributes(&mut mesh, &list, at, &what)?;
                orient(&mut mesh, reverse);
                self.light_area = Some(super::LightArea::Triangles(1));
                Some(Shape::Mesh(self.scene.add_mesh(mesh)))
            }
            "bilinearmesh" => {
                let Some(p) = list.point3s("P") else {
                    return Err(SceneError::invalid(at, "bilinearmesh without \"point3 P\""));
                };
                let indices = match list.ints("indices") {
                    Some(i) => i,
                    None if p.len() == 4 => vec![0, 1, 2, 3],
                    None => {
                        return Err(SceneError::invalid(
                            at,
                            "bilinearmesh without \"integer indices\"",
                        ));
                    }
                };
                if indices.len() % 4 != 0 {
                    return Err(SceneError::invalid(
                        at,
                        format!(
                            "bilinearmesh: {} indices is not a multiple of 4",
                            indices.len()
                        ),
                    ));
                }
                let idx = checked_indices(&indices, 4, p.len(), at)?;
                let mut src = Mesh {
                    name: name.clone(),
                    positions: p,
                    ..Default::default()
                };
                self.mesh_attributes(&mut src, &list, at, &what)?;
                let mesh = bilinear_to_triangles(&src, &idx);
                let mut mesh = mesh;
                orient(&mut mesh, reverse);
                // Planar patches are two triangles each; curved ones are refined (no `power`).
                if mesh.indices.len() == idx.len() / 2 {
                    self.light_area = Some(super::LightArea::Triangles(2));
                }
                Some(Shape::Mesh(self.scene.add_mesh(mesh)))
            }
            "plymesh" => {
                let Some(file) = list.string("filename") else {
                    return Err(SceneError::invalid(
                        at,
                        "plymesh without \"string filename\"",
                    ));
                };
                if list.has("displacement") {
                    let _ = list.texture("displacement");
                    let _ = list.float("edgelength", 1.0);
                    self.warn(format!(
                        "{at}: {what} \"{file}\": displacement is not supported; the mesh is rendered undisplaced"
                    ));
                } else if list.has("edgelength") {
                    let _ = list.float("edgelength", 1.0);
                }
                if self.in_memory() {
                    self.warn(format!(
                        "{at}: {what} \"{file}\": files are not read when parsing text from memory"
                    ));
                    None
                } else {
                    let path = self.resolve(&file, at)?;
                    let mesh = self.scene.add_mesh(Mesh {
                        name: file.clone(),
                        ..Default::default()
                    });
                    self.ply_jobs.push(PlyJob {
                        mesh,
                        path,
                        name: file,
                        location: at.to_string(),
                        reverse,
                    });
                    Some(Shape::Mesh(mesh))
                }
            }
            "sphere" => {
                let r = list.float("radius", 1.0);
                // Clamped by |r|: a negative radius must reach the "empty sphere" warning below,
                // not make the clamp's bounds cross (a panic).
                let zmin = list.float("zmin", -r).clamp(-r.abs(), r.abs());
                let zmax = list.float("zmax", r).clamp(-r.abs(), r.abs());
                let phimax = list.float("phimax", 360.0).clamp(0.0, 360.0);
                if !(r > 0.0) || zmin >= zmax || phimax <= 0.0 {
                    self.warn(format!("{at}: {what}: empty sphere (radius {r}, z [{zmin}, {zmax}], phimax {phimax}) left out"));
                    None
                } else {
                    let full = zmin <= -r && zmax >= r && phimax >= 360.0;
                    // pbrt-v4 Sphere::Area: φmax · r · (zmax − zmin).
                    self.light_area = Some(super::LightArea::Quadric(
                        phimax.to_radians() * r * (zmax - zmin),
                    ));
                    // Trayecto's analytic sphere has its own (u, v) (around +y); pbrt's runs
                    // around +z in object space, so a textured sphere is tessellated.
                    let mat = self.current_material(at);
                    let textured = material_uses_uv(&self.scene.materials, mat);
                    if full && !reverse && !textured && is_similarity(&self.gs.ctm) {
                        Some(Shape::Sphere {
                            center: Vec3::ZERO,
                            radius: r,
                        })
                    } else {
                        // pbrt-v4 Sphere: u = φ/φmax, v = (θ − θ(zmin))/(θ(zmax) − θ(zmin)).
                        let theta0 = (zmin / r).clamp(-1.0, 1.0).acos();
                        let theta1 = (zmax / r).clamp(-1.0, 1.0).acos();
                        let mut m = tessellate(&name, QUADRIC_STEPS, |u, v| {
                            let phi = u * phimax.to_radians();
                            let z = r * (theta0 + (theta1 - theta0) * v).cos();
                            let rho = (r * r - z * z).max(0.0).sqrt();
                            let p = Vec3::new(rho * phi.cos(), rho * phi.sin(), z);
                            (p, p.normalize_or_zero())
                        });
                        orient(&mut m, reverse);
                        Some(Shape::Mesh(self.scene.add_mesh(m)))
                    }
                }
            }
            "cylinder" => {
                let r = list.float("radius", 1.0);
                let zmin = list.float("zmin", -1.0);
                let zmax = list.float("zmax", 1.0);
                let phimax = list.float("phimax", 360.0).clamp(0.0, 360.0);
                if !(r > 0.0) || zmin == zmax || phimax <= 0.0 {
                    self.warn(format!("{at}: {what}: empty cylinder left out"));
                    None
                } else {
                    // pbrt-v4 Cylinder::Area: (zmax − zmin) · r · φmax.
                    self.light_area = Some(super::LightArea::Quadric(
                        (zmax - zmin).abs() * r * phimax.to_radians(),
                    ));
                    let mut m = tessellate(&name, (QUADRIC_STEPS.0, 1), |u, v| {
                        let phi = u * phimax.to_radians();
                        let p = Vec3::new(r * phi.cos(), r * phi.sin(), zmin + (zmax - zmin) * v);
                        (p, Vec3::new(phi.cos(), phi.sin(), 0.0))
                    });
                    orient(&mut m, reverse);
                    Some(Shape::Mesh(self.scene.add_mesh(m)))
                }
            }
            "disk" => {
                let h = list.float("height", 0.0);
                let r = list.float("radius", 1.0);
                let ri = list.float("innerradius", 0.0).max(0.0);
                let phimax = list.float("phimax", 360.0).clamp(0.0, 360.0);
                if !(r > ri) || phimax <= 0.0 {
                    self.warn(format!("{at}: {what}: empty disk left out"));
                    None
                } else {
                    // pbrt-v4 Disk::Area: φmax · ½ (r² − rᵢ²).
                    self.light_area = Some(super::LightArea::Quadric(
                        phimax.to_radians() * 0.5 * (r * r - ri * ri),
                    ));
                    let mut m = tessellate(&name, (QUADRIC_STEPS.0, 1), |u, v| {
                        let phi = u * phimax.to_radians();
                        let rho = r + (ri - r) * v;
                        (Vec3::new(rho * phi.cos(), rho * phi.sin(), h), Vec3::Z)
                    });
                    orient(&mut m, reverse);
                    Some(Shape::Mesh(self.scene.add_mesh(m)))
                }
            }
            "loopsubdiv" => {
                let levels = list.int("levels", 3);
                let Some(p) = list.point3s("P") else {
                    return Err(SceneError::invalid(at, "loopsubdiv without \"point3 P\""));
                };
                let Some(indices) = list.ints("indices") else {
                    return Err(SceneError::invalid(
                        at,
                        "loopsubdiv without \"integer indices\"",
                    ));
                };
                if indices.len() % 3 != 0 {
                    return Err(SceneError::invalid(
                        at,
                        "loopsubdiv: indices is not a multiple of 3",
                    ));
                }
                let idx: Vec<[u32; 3]> = checked_indices(&indices, 3, p.len(), at)?
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect();
                let levels = if levels > MAX_LOOP_LEVELS {
                    self.warn(format!(
                        "{at}: {what}: {levels} levels capped at {MAX_LOOP_LEVELS}"
                    ));
                    MAX_LOOP_LEVELS
                } else {
                    levels.max(0)
                };
                // Each level makes 4 triangles of one: what the result will hold (indices,
                // positions and normals, about half a vertex a triangle) is charged to the
                // load's budget before subdividing.
                let final_tris = (idx.len() as u64).saturating_mul(1 << (2 * levels as u32));
                crate::limits::charge(final_tris.saturating_mul(LOOP_BYTES_PER_TRIANGLE), || {
                    format!("{at}: {what}: {levels} levels of subdivision ({final_tris} triangles)")
                })
                .map_err(|e| SceneError::invalid(at, e.to_string()))?;
                let (mut positions, mut tris) = (p, idx);
                for _ in 0..levels {
                    if tris.len() > 8_000_000 {
                        self.warn(format!(
                            "{at}: {what}: subdivision stopped at {} triangles",
                            tris.len()
                        ));
                        break;
                    }
                    (positions, tris) = super::shapes::loop_subdivide(&positions, &tris);
                }
                // pbrt-v4 ends on the limit surface, with its limit normals.
                let (positions, normals) = loop_limit(&positions, &tris);
                let mut mesh = Mesh {
                    name: name.clone(),
                    positions,
                    normals: Some(normals),
                    indices: tris,
                    ..Default::default()
                };
                orient(&mut mesh, reverse);
                Some(Shape::Mesh(self.scene.add_mesh(mesh)))
            }
            "curve" => self.curve(&list, &name, at, &what)?,
            other => {
                self.warn(format!(
                    "{at}: Shape \"{other}\" is not supported and was left out"
                ));
                for q in &list.params {
                    q.used.set(true);
                }
                None
            }
        };
        self.note_unused(&list, &what, at);
        let Some(shape) = shape else {
            return Ok(());
        };
        match alpha {
            Some(TexOr::Value(a)) if a >= 1.0 => self.place(shape, name, at),
            Some(TexOr::Value(a)) if a <= 0.0 => {
                // Fully transparent: pbrt-v4 skips such shapes too (it never hits them).
            }
            None => self.place(shape, name, at),
            Some(a) => {
                let node = match a {
                    TexOr::Value(v) => super::materials::TexNode::Const(Vec3::splat(v)),
                    TexOr::Texture(t) => self.alpha_node(&t, at),
                };
                self.place_with_alpha(shape, name, node, at);
            }
        }
        Ok(())
    }

    fn alpha_node(&mut self, t: &str, at: &str) -> super::materials::TexNode {
        match self.float_textures.get(t) {
            Some(n) => *n,
            None => {
                self.warn(format!(
                    "{at}: alpha texture \"{t}\" is not defined; the shape is opaque"
                ));
                super::materials::TexNode::Const(Vec3::ONE)
            }
        }
    }

    fn place_with_alpha(
        &mut self,
        shape: Shape,
        name: String,
        node: super::materials::TexNode,
        at: &str,
    ) {
        // A copy of the current material with the cut-out: pbrt-v4 keeps a hit with
        // probability alpha (a stochastic test), which is Trayecto's `Blend` mode.
        let before = self.scene.objects.len();
        let in_object = self.current_object.as_ref().map(|o| o.1.len());
        self.place(shape, name, at);
        let (factor, tex) = self.node_factor_pub(&node);
        let mat_id = if let Some((_, parts)) = &self.current_object {
            if Some(parts.len()) == in_object {
                return;
            }
            parts.last().map(|p| p.material)
        } else if self.scene.objects.len() > before {
            self.scene.objects.last().map(|o| o.material)
        } else {
            None
        };
        let Some(mat_id) = mat_id else { return };
        let mut m = self.scene.materials[mat_id].clone();
        m.alpha = factor.x;
        m.alpha_texture = tex;
        m.alpha_mode = AlphaMode::Blend;
        let id = self.scene.add_material(m);
        if let Some((_, parts)) = &mut self.current_object {
            if let Some(p) = parts.last_mut() {
                p.material = id;
            }
        } else if let Some(o) = self.scene.objects.last_mut() {
            o.material = id;
        }
    }

    /// Normals, uvs and tangents of a trianglemesh or bilinearmesh.
    fn mesh_attributes(
        &mut self,
        mesh: &mut Mesh,
        list: &ParamList,
        at: &str,
        what: &str,
    ) -> Result<(), SceneError> {
        let n = mesh.positions.len();
        if let Some(normals) = list.point3s("N") {
            if normals.len() != n {
                return Err(SceneError::invalid(
                    at,
                    format!("{what}: {} normals for {n} vertices", normals.len()),
                ));
            }
            mesh.normals = Some(normals);
        }
        let uv = list.point2s("uv").or_else(|| {
            // pbrt-v3 files write "float uv" (or "st") as a flat list.
            list.floats("uv")
                .or_else(|| list.floats("st"))
                .map(|f| f.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect())
        });
        if let Some(uv) = uv {
            if uv.len() != n {
                return Err(SceneError::invalid(
                    at,
                    format!("{what}: {} uvs for {n} vertices", uv.len()),
                ));
            }
            mesh.uv0 = Some(uv.into_iter().map(to_stored_uv).collect());
        }
        if list.has("S") {
            let _ = list.point3s("S");
            self.warn_once("tangentsS", format!("{at}: {what}: per-vertex tangents \"S\" are not used (Trayecto derives tangents from the uvs)"));
        }
        if list.has("faceIndices") {
            let _ = list.ints("faceIndices");
        }
        Ok(())
    }

    fn curve(
        &mut self,
        list: &ParamList,
        name: &str,
        at: &str,
        what: &str,
    ) -> Result<Option<Shape>, SceneError> {
        let Some(p) = list.point3s("P") else {
            return Err(SceneError::invalid(at, "curve without \"point3 P\""));
        };
        let basis = list.string("basis").unwrap_or_else(|| "bezier".into());
        let degree = list.int("degree", 3);
        let ty = list.string("type").unwrap_or_else(|| "flat".into());
        let w = list.float("width", 1.0);
        let w0 = list.float("width0", w);
        let w1 = list.float("width1", w);
        let split_depth = list.int("splitdepth", 3);
        let n = list.point3s("N");
        if !(degree == 2 || degree == 3) {
            return Err(SceneError::invalid(
                at,
                format!("curve: degree {degree} (2 or 3 expected)"),
            ));
        }
        let d = degree as usize;
        // Control points of each segment, as Bézier control points.
        let mut segments: Vec<Vec<Vec3>> = Vec::new();
        match basis.as_str() {
            "bezier" => {
                if p.len() < d + 1 || (p.len() - 1) % d != 0 {
                    return Err(SceneError::invalid(
                        at,
                        format!(
                            "curve: {} control points do not make degree-{d} Bézier segments",
                            p.len()
                        ),
                    ));
                }
                let mut i = 0;
                while i + d < p.len() {
                    segments.push(p[i..=i + d].to_vec());
                    i += d;
                }
            }
            "bspline" => {
                if p.len() < d + 1 {
                    return Err(SceneError::invalid(
                        at,
                        "curve: too few B-spline control points",
                    ));
                }
                // Uniform B-spline to Bézier (pbrt-v4 shapes.cpp: the blossoming of each span).
                for s in 0..p.len() - d {
                    let q = &p[s..=s + d];
                    if d == 3 {
                        let b0 = (q[0] + q[1] * 4.0 + q[2]) / 6.0;
                        let b1 = (q[1] * 2.0 + q[2]) / 3.0;
                        let b2 = (q[1] + q[2] * 2.0) / 3.0;
                        let b3 = (q[1] + q[2] * 4.0 + q[3]) / 6.0;
                        segments.push(vec![b0, b1, b2, b3]);
                    } else {
                        let b0 = (q[0] + q[1]) * 0.5;
                        let b2 = (q[1] + q[2]) * 0.5;
                        segments.push(vec![b0, q[1], b2]);
                    }
                }
            }
            other => {
                return Err(SceneError::invalid(
                    at,
                    format!("curve: unknown basis '{other}'"),
                ));
            }
        }
        let kind = match ty.as_str() {
            "flat" => CurveType::Flat,
            "cylinder" => CurveType::Cylinder,
            "ribbon" => CurveType::Ribbon,
            other => {
                self.warn(format!(
                    "{at}: {what}: curve type \"{other}\" is not known; \"flat\" is used"
                ));
                CurveType::Flat
            }
        };
        let nseg = segments.len();
        // pbrt-v4 needs one normal per segment end for ribbons (nSegments + 1).
        let normals = match (kind, &n) {
            (CurveType::Ribbon, Some(n)) if n.len() == nseg + 1 => {
                Some((0..nseg).map(|k| [n[k], n[k + 1]]).collect::<Vec<_>>())
            }
            (CurveType::Ribbon, _) => {
                self.warn(format!(
                    "{at}: {what}: a \"ribbon\" curve needs {} normals \"N\" (one per segment end); it is rendered as \"flat\"",
                    nseg + 1
                ));
                None
            }
            (_, Some(_)) => {
                self.warn_once(
                    "curveN",
                    format!("{at}: {what}: curve normals \"N\" are only used by \"ribbon\" curves (as in pbrt-v4)"),
                );
                None
            }
            _ => None,
        };
        let kind = if kind == CurveType::Ribbon && normals.is_none() {
            CurveType::Flat
        } else {
            kind
        };
        if !(0..=10).contains(&split_depth) {
            self.warn(format!(
                "{at}: {what}: \"splitdepth\" {split_depth} is outside 0..10; it is clamped"
            ));
        }
        // Quadratic segments are raised to cubic (the same curve).
        let cubic = |s: &[Vec3]| -> [Vec3; 4] {
            if s.len() == 3 {
                [
                    s[0],
                    s[0] + (s[1] - s[0]) * (2.0 / 3.0),
                    s[2] + (s[1] - s[2]) * (2.0 / 3.0),
                    s[2],
                ]
            } else {
                [s[0], s[1], s[2], s[3]]
            }
        };
        let width_at = |k: usize| w0 + (w1 - w0) * (k as f32 / nseg as f32);
        let shape = CurveShape {
            segments: segments.iter().map(|s| cubic(s)).collect(),
            widths: (0..nseg).map(|k| [width_at(k), width_at(k + 1)]).collect(),
            kind,
            normals,
            split_depth: split_depth.clamp(0, 10) as u32,
        };
        let _ = name;
        Ok(Some(Shape::Curves(Box::new(shape))))
    }

    /// Reads every `plymesh`, in parallel, into its reserved mesh slot.
    pub(super) fn load_plys(&mut self) -> Result<(), SceneError> {
        let jobs = std::mem::take(&mut self.ply_jobs);
        // The workers read under this load's budget and cancel flag (crate::limits).
        let ctx = crate::limits::current();
        let results: Vec<Result<(Mesh, Vec<String>), SceneError>> = jobs
            .par_iter()
            .map(|j| {
                let label = format!("{} (plymesh at {})", j.path.display(), j.location);
                let (bytes, _held) = crate::limits::scope(ctx.clone(), || read_maybe_gz(&j.path))
                    .map_err(|e| SceneError::invalid(&label, e))?;
                let mut warnings = Vec::new();
                let mut mesh = crate::scene::ply::parse_mesh(&bytes, &mut warnings)
                    .map_err(|m| SceneError::invalid(&label, format!("PLY: {m}")))?;
                mesh.name = j.name.clone();
                orient(&mut mesh, j.reverse);
                Ok((
                    mesh,
                    warnings
                        .into_iter()
                        .map(|w| format!("{label}: {w}"))
                        .collect(),
                ))
            })
            .collect();
        for (j, r) in jobs.iter().zip(results) {
            let (mesh, warnings) = r?;
            self.scene.meshes[j.mesh] = mesh;
            self.scene.warnings.extend(warnings);
        }
        Ok(())
    }

    pub(super) fn node_factor_pub(
        &mut self,
        node: &super::materials::TexNode,
    ) -> (Vec3, Option<crate::material::TextureRef>) {
        self.node_to_factor_public(node)
    }
}

/// A PLY file's bytes, gunzipped when they are gzip data, with the budget reservation holding
/// the decompressed bytes (bounded by [`MAX_GUNZIP_RATIO`] and the load's budget).
fn read_maybe_gz(
    path: &std::path::Path,
) -> Result<(Vec<u8>, Option<crate::limits::Reservation>), String> {
    let bytes = crate::limits::read_file(path).map_err(|e| format!("cannot read the mesh: {e}"))?;
    if bytes.starts_with(&[0x1f, 0x8b]) {
        let max = (bytes.len() as u64)
            .saturating_mul(MAX_GUNZIP_RATIO)
            .min(MAX_GUNZIP);
        let (out, held) = crate::limits::read_to_end_bounded(
            flate2::read::GzDecoder::new(&bytes[..]),
            max,
            "the gzip-compressed mesh",
        )?;
        return Ok((out, Some(held)));
    }
    Ok((bytes, None))
}

fn checked_indices(
    indices: &[i64],
    _arity: usize,
    n: usize,
    at: &str,
) -> Result<Vec<u32>, SceneError> {
    let mut out = Vec::with_capacity(indices.len());
    for (k, &i) in indices.iter().enumerate() {
        if i < 0 || i as usize >= n {
            return Err(SceneError::invalid(
                at,
                format!("index {k} is {i}, but the mesh has {n} vertices"),
            ));
        }
        out.push(i as u32);
    }
    Ok(out)
}

fn is_similarity(m: &crate::math::Mat4) -> bool {
    let lin = glam::Mat3::from_mat4(*m);
    let (sx, sy, sz) = (
        lin.x_axis.length(),
        lin.y_axis.length(),
        lin.z_axis.length(),
    );
    sx > 0.0
        && (sx - sy).abs() <= 1e-4 * sx
        && (sx - sz).abs() <= 1e-4 * sx
        && lin.x_axis.dot(lin.y_axis).abs() <= 1e-4 * sx * sy
        && lin.y_axis.dot(lin.z_axis).abs() <= 1e-4 * sy * sz
        && lin.x_axis.dot(lin.z_axis).abs() <= 1e-4 * sx * sz
}

/// A (steps.0 × steps.1) grid over (u, v) ∈ [0,1]², with normals from `f` (wound by `orient`).
/// Whether material `id` (or, for a `mix`, any material it can choose) reads texture
/// coordinates: any texture slot, bump map or mix amount texture.
pub(crate) fn material_uses_uv(materials: &[crate::material::Material], id: usize) -> bool {
    let mut stack = vec![(id, 0u32)];
    while let Some((i, depth)) = stack.pop() {
        let Some(m) = materials.get(i) else { continue };
        if m.texture_refs().next().is_some() {
            return true;
        }
        if let Some(mix) = m.mix()
            && depth < 16
        {
            stack.extend(mix.materials.iter().map(|&j| (j as usize, depth + 1)));
        }
    }
    false
}

/// pbrt-v4's `Triangle` gives a triangle of a mesh without uvs the coordinates (0, 0), (1, 0),
/// (1, 1) at its three corners. Trayecto's meshes share uvs between triangles, so such a mesh is
/// split into separate triangles carrying those uvs (stored with v down).
pub(crate) fn give_default_triangle_uvs(mesh: &mut Mesh) {
    if mesh.uv0.is_some() {
        return;
    }
    let corners: Vec<u32> = mesh.indices.iter().flatten().copied().collect();
    let pick3 = |v: &Vec<Vec3>| corners.iter().map(|&i| v[i as usize]).collect::<Vec<_>>();
    let pick4 =
        |v: &Vec<crate::math::Vec4>| corners.iter().map(|&i| v[i as usize]).collect::<Vec<_>>();
    mesh.positions = pick3(&mesh.positions);
    mesh.normals = mesh.normals.as_ref().map(pick3);
    mesh.tangents = mesh.tangents.as_ref().map(pick4);
    mesh.colors = mesh.colors.as_ref().map(pick4);
    mesh.uv1 = mesh
        .uv1
        .as_ref()
        .map(|v| corners.iter().map(|&i| v[i as usize]).collect());
    let tri_uv = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)].map(|(u, v)| to_stored_uv(Vec2::new(u, v)));
    mesh.uv0 = Some((0..mesh.indices.len()).flat_map(|_| tri_uv).collect());
    let n = mesh.indices.len() as u32;
    mesh.indices = (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
}

fn tessellate(name: &str, steps: (usize, usize), f: impl Fn(f32, f32) -> (Vec3, Vec3)) -> Mesh {
    let (nu, nv) = steps;
    let mut m = Mesh {
        name: name.to_string(),
        ..Default::default()
    };
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    for j in 0..=nv {
        for i in 0..=nu {
            let (u, v) = (i as f32 / nu as f32, j as f32 / nv as f32);
            let (p, n) = f(u, v);
            m.positions.push(p);
            normals.push(n);
            uvs.push(to_stored_uv(Vec2::new(u, v)));
        }
    }
    let row = (nu + 1) as u32;
    for j in 0..nv as u32 {
        for i in 0..nu as u32 {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            m.indices.push([a, b, d]);
            m.indices.push([a, d, c]);
        }
    }
    // Degenerate triangles at the poles and the disk's centre have zero area: harmless, but drop
    // them so light sampling never picks one.
    let pos = &m.positions;
    m.indices.retain(|t| {
        let [a, b, c] = t.map(|i| pos[i as usize]);
        (b - a).cross(c - a).length_squared() > 0.0
    });
    m.normals = Some(normals);
    m.uv0 = Some(uvs);
    m
}

fn bilinear_to_triangles(src: &Mesh, idx: &[u32]) -> Mesh {
    let mut m = Mesh {
        name: src.name.clone(),
        ..Default::default()
    };
    let mut normals = src.normals.as_ref().map(|_| Vec::new());
    let mut uvs = Vec::new();
    for q in idx.chunks_exact(4) {
        let [i00, i10, i01, i11] = [q[0], q[1], q[2], q[3]].map(|i| i as usize);
        let p = [
            src.positions[i00],
            src.positions[i10],
            src.positions[i01],
            src.positions[i11],
        ];
        // A planar patch is exactly two triangles; a curved one is refined.
        let planar = {
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            (p[3] - p[0]).dot(n).abs() <= 1e-6 * n.length() * (p[3] - p[0]).length().max(1e-30)
        };
        let steps = if planar { 1 } else { 8 };
        let uvq = src.uv0.as_ref().map(|u| [u[i00], u[i10], u[i01], u[i11]]);
        let nq = src
            .normals
            .as_ref()
            .map(|n| [n[i00], n[i10], n[i01], n[i11]]);
        let base = m.positions.len() as u32;
        for j in 0..=steps {
            for i in 0..=steps {
                let (u, v) = (i as f32 / steps as f32, j as f32 / steps as f32);
                let bl = |c: [Vec3; 4]| {
                    c[0] * (1.0 - u) * (1.0 - v)
                        + c[1] * u * (1.0 - v)
                        + c[2] * (1.0 - u) * v
                        + c[3] * u * v
                };
                m.positions.push(bl(p));
                if let (Some(ns), Some(nq)) = (&mut normals, nq) {
                    ns.push(bl(nq).normalize_or_zero());
                }
                uvs.push(match uvq {
                    Some(t) => {
                        t[0] * (1.0 - u) * (1.0 - v)
                            + t[1] * u * (1.0 - v)
                            + t[2] * (1.0 - u) * v
                            + t[3] * u * v
                    }
                    None => to_stored_uv(Vec2::new(u, v)),
                });
            }
        }
        let row = steps + 1;
        for j in 0..steps {
            for i in 0..steps {
                let a = base + j * row + i;
                let (b, c, d) = (a + 1, a + row, a + row + 1);
                // (p00, p10, p11) and (p00, p11, p01): counter-clockwise about ∂p/∂u × ∂p/∂v,
                // pbrt's bilinear patch normal.
                m.indices.push([a, b, d]);
                m.indices.push([a, d, c]);
            }
        }
    }
    m.normals = normals;
    m.uv0 = Some(uvs);
    m
}

/// One step of Loop subdivision (Loop 1987; the rules of PBRT 3rd ed. §3.8): every triangle
/// splits in four; new edge points are 3/8·(ends) + 1/8·(opposite vertices) inside, midpoints on
/// boundaries; old vertices move by the β rule inside and 1/8–3/4–1/8 on boundaries.
pub fn loop_subdivide(p: &[Vec3], tris: &[[u32; 3]]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    use std::collections::HashMap;
    let key = |a: u32, b: u32| if a < b { (a, b) } else { (b, a) };
    // Edge → opposite vertices.
    let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for t in tris {
        for e in 0..3 {
            let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
            edges.entry(key(a, b)).or_default().push(c);
        }
    }
    // Vertex neighbours and boundary flags.
    let mut nbrs: Vec<Vec<u32>> = vec![Vec::new(); p.len()];
    let mut boundary_nbrs: Vec<Vec<u32>> = vec![Vec::new(); p.len()];
    for (&(a, b), opp) in &edges {
        nbrs[a as usize].push(b);
        nbrs[b as usize].push(a);
        if opp.len() == 1 {
            boundary_nbrs[a as usize].push(b);
            boundary_nbrs[b as usize].push(a);
        }
    }
    let mut out: Vec<Vec3> = Vec::with_capacity(p.len() + edges.len());
    for (i, v) in p.iter().enumerate() {
        let bn = &boundary_nbrs[i];
        let moved = if bn.len() == 2 {
            *v * 0.75 + (p[bn[0] as usize] + p[bn[1] as usize]) * 0.125
        } else if !bn.is_empty() || nbrs[i].is_empty() {
            *v
        } else {
            let n = nbrs[i].len() as f32;
            let beta = if nbrs[i].len() == 3 {
                3.0 / 16.0
            } else {
                3.0 / (8.0 * n)
            };
            let sum: Vec3 = nbrs[i].iter().map(|&j| p[j as usize]).sum();
            *v * (1.0 - n * beta) + sum * beta
        };
        out.push(moved);
    }
    let mut edge_vertex: HashMap<(u32, u32), u32> = HashMap::new();
    let mut sorted: Vec<_> = edges.iter().collect();
    sorted.sort_by_key(|(k, _)| **k);
    for (&(a, b), opp) in sorted {
        let (pa, pb) = (p[a as usize], p[b as usize]);
        let e = if opp.len() == 2 {
            (pa + pb) * 0.375 + (p[opp[0] as usize] + p[opp[1] as usize]) * 0.125
        } else {
            (pa + pb) * 0.5
        };
        edge_vertex.insert((a, b), out.len() as u32);
        out.push(e);
    }
    let mut new_tris = Vec::with_capacity(tris.len() * 4);
    for t in tris {
        let m = |a: u32, b: u32| edge_vertex[&key(a, b)];
        let (ab, bc, ca) = (m(t[0], t[1]), m(t[1], t[2]), m(t[2], t[0]));
        new_tris.push([t[0], ab, ca]);
        new_tris.push([ab, t[1], bc]);
        new_tris.push([ca, bc, t[2]]);
        new_tris.push([ab, bc, ca]);
    }
    (out, new_tris)
}

/// The one-ring of vertex `v` in the order pbrt-v4's `SDVertex::oneRing` walks it, in `ring`,
/// from the faces `faces` around it: starting at a face's next vertex and crossing to the face
/// across the edge (v, next) — clockwise seen from the side the triangles wind counter-clockwise
/// towards; for a boundary vertex from the boundary neighbour at the end of that walk back to the
/// other one. Returns whether `v` is on a boundary, or `None` where the faces do not form one
/// fan (non-manifold or inconsistently wound), where the limit rules do not apply.
fn one_ring(v: u32, faces: &[u32], tris: &[[u32; 3]], ring: &mut Vec<u32>) -> Option<bool> {
    ring.clear();
    // (next, prev) of v in each face.
    let corner = |f: u32| -> (u32, u32) {
        let t = tris[f as usize];
        let k = t.iter().position(|&x| x == v).unwrap_or(0);
        (t[(k + 1) % 3], t[(k + 2) % 3])
    };
    // The single face whose `pick` corner is `x`, or None (none, or several: not a fan).
    let unique = |x: u32, pick: fn((u32, u32)) -> u32| -> Result<Option<u32>, ()> {
        let mut found = None;
        for &f in faces {
            if pick(corner(f)) == x {
                if found.is_some() {
                    return Err(());
                }
                found = Some(f);
            }
        }
        Ok(found)
    };
    let first = *faces.first()?;
    // Walk in pbrt's `nextFace` direction: the face across (v, next) has `prev` = next.
    let mut f = first;
    let mut steps = 0;
    let boundary = loop {
        let (next, _) = corner(f);
        match unique(next, |c| c.1).ok()? {
            Some(g) if g == first => break false,
            Some(g) => f = g,
            None => break true,
        }
        steps += 1;
        if steps > faces.len() {
            return None;
        }
    };
    if !boundary {
        f = first;
        loop {
            let (next, _) = corner(f);
            ring.push(next);
            f = unique(next, |c| c.1).ok()??;
            if f == first {
                break;
            }
            if ring.len() > faces.len() {
                return None;
            }
        }
        return (ring.len() == faces.len()).then_some(false);
    }
    // Boundary: `f` is the last face in the next direction; walk back with `prevFace`.
    ring.push(corner(f).0);
    loop {
        let (_, prev) = corner(f);
        ring.push(prev);
        match unique(prev, |c| c.0).ok()? {
            Some(g) => f = g,
            None => break,
        }
        if ring.len() > faces.len() + 1 {
            return None;
        }
    }
    (ring.len() == faces.len() + 1).then_some(true)
}

/// Loop's even-vertex weight β(n) for an interior vertex of valence n (Loop 1987; Warren's
/// simplification 3/(8n), 3/16 for n = 3, as PBRT §3.8 and pbrt-v4 use).
fn loop_beta(n: usize) -> f32 {
    if n == 3 {
        3.0 / 16.0
    } else {
        3.0 / (8.0 * n as f32)
    }
}

/// Moves the vertices of a Loop-subdivided mesh to the limit surface and gives each its limit
/// normal, the last step of pbrt-v4's `LoopSubdivide` (Loop 1987, §3.8 of PBRT 3rd ed.):
/// interior vertices go to (1 − nγ)·v + γ·Σ ring with γ = 1/(n + 3/(8β(n))); boundary vertices
/// to 3/5·v + 1/5·(their two boundary neighbours). The normal is S × T of the limit tangents,
/// from the limit positions of the ordered one-ring: interior S = Σ cos(2πj/n)·p_j,
/// T = Σ sin(2πj/n)·p_j; on a boundary S runs along it and T across it with the valence's
/// weights (Hoppe et al. 1994). The ring's order is pbrt-v4's, so the normals point where
/// pbrt-v4's do. A vertex whose faces do not form a fan keeps its position and gets the mean of
/// its faces' normals, turned the same way.
pub fn loop_limit(p: &[Vec3], tris: &[[u32; 3]]) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut faces_of: Vec<Vec<u32>> = vec![Vec::new(); p.len()];
    for (f, t) in tris.iter().enumerate() {
        for &v in t {
            if !faces_of[v as usize].contains(&(f as u32)) {
                faces_of[v as usize].push(f as u32);
            }
        }
    }
    let mut ring = Vec::new();
    let rings: Vec<Option<(bool, Vec<u32>)>> = (0..p.len())
        .map(|v| {
            let b = one_ring(v as u32, &faces_of[v], tris, &mut ring)?;
            Some((b, ring.clone()))
        })
        .collect();
    let limit: Vec<Vec3> = p
        .iter()
        .zip(&rings)
        .map(|(&v, r)| match r {
            Some((false, ring)) => {
                let n = ring.len() as f32;
                let gamma = 1.0 / (n + 3.0 / (8.0 * loop_beta(ring.len())));
                let sum: Vec3 = ring.iter().map(|&j| p[j as usize]).sum();
                v * (1.0 - n * gamma) + sum * gamma
            }
            Some((true, ring)) => {
                v * 0.6 + (p[ring[0] as usize] + p[ring[ring.len() - 1] as usize]) * 0.2
            }
            None => v,
        })
        .collect();
    let normals = rings
        .iter()
        .enumerate()
        .map(|(v, r)| {
            let q = |j: u32| limit[j as usize];
            let n = match r {
                Some((false, ring)) => {
                    let k = ring.len() as f32;
                    let (mut s, mut t) = (Vec3::ZERO, Vec3::ZERO);
                    for (j, &i) in ring.iter().enumerate() {
                        let a = std::f32::consts::TAU * j as f32 / k;
                        s += q(i) * a.cos();
                        t += q(i) * a.sin();
                    }
                    s.cross(t)
                }
                Some((true, ring)) => {
                    let k = ring.len();
                    let pv = limit[v];
                    let s = q(ring[k - 1]) - q(ring[0]);
                    let t = match k {
                        2 => q(ring[0]) + q(ring[1]) - pv * 2.0,
                        3 => q(ring[1]) - pv,
                        4 => {
                            -q(ring[0]) + q(ring[1]) * 2.0 + q(ring[2]) * 2.0
                                - q(ring[3])
                                - pv * 2.0
                        }
                        _ => {
                            let theta = std::f32::consts::PI / (k - 1) as f32;
                            let mut t = (q(ring[0]) + q(ring[k - 1])) * theta.sin();
                            for (j, &i) in ring.iter().enumerate().take(k - 1).skip(1) {
                                t += q(i) * ((2.0 * theta.cos() - 2.0) * (j as f32 * theta).sin());
                            }
                            -t
                        }
                    };
                    s.cross(t)
                }
                None => Vec3::ZERO,
            }
            .normalize_or_zero();
            if n != Vec3::ZERO && n.is_finite() {
                return n;
            }
            // The faces' normals, turned as pbrt-v4's ring order turns them (against the
            // counter-clockwise side).
            let sum: Vec3 = faces_of[v]
                .iter()
                .map(|&f| {
                    let [a, b, c] = tris[f as usize].map(|i| limit[i as usize]);
                    -(b - a).cross(c - a)
                })
                .sum();
            let n = sum.normalize_or_zero();
            if n == Vec3::ZERO { Vec3::Z } else { n }
        })
        .collect();
    (limit, normals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loop_subdivision_quadruples_and_shrinks_a_tetrahedron() {
        let p = vec![
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ];
        let t = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
        let (q, s) = loop_subdivide(&p, &t);
        assert_eq!(s.len(), 16);
        assert_eq!(q.len(), 4 + 6);
        // A closed surface's vertices move towards the centroid.
        assert!(q[0].length() < p[0].length());
    }

    /// An octahedron's limit surface: every vertex is on the limit sphere-like surface, the
    /// normals are unit and point inwards (pbrt-v4's ring order turns them against the
    /// counter-clockwise side, which faces out here), and a regular vertex of a flat patch stays
    /// in its plane with the plane's normal.
    #[test]
    fn loop_limit_positions_and_normals() {
        let p = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        // Counter-clockwise seen from outside.
        let t = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        let (mut q, mut s) = (p.clone(), t.clone());
        for _ in 0..2 {
            (q, s) = loop_subdivide(&q, &s);
        }
        let (l, n) = loop_limit(&q, &s);
        for (i, (x, m)) in l.iter().zip(&n).enumerate() {
            assert!((m.length() - 1.0).abs() < 1e-4, "{i}");
            assert!(m.dot(*x) < -0.8 * x.length(), "vertex {i}: {x} normal {m}");
        }
        // Symmetry: the six original vertices go to the same distance.
        let r = l[0].length();
        for v in &l[..6] {
            assert!((v.length() - r).abs() < 1e-5);
        }
        // A regular interior vertex of a flat hexagonal fan keeps its place; the limit normal is
        // the plane's (−z for counter-clockwise +z faces); boundary vertices stay in the plane.
        let mut fan = vec![Vec3::ZERO];
        for k in 0..6 {
            let a = std::f32::consts::TAU * k as f32 / 6.0;
            fan.push(Vec3::new(a.cos(), a.sin(), 0.0));
        }
        let tris: Vec<[u32; 3]> = (0..6).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
        let (l, n) = loop_limit(&fan, &tris);
        assert!(l[0].length() < 1e-6);
        for (v, m) in l.iter().zip(&n) {
            assert!(v.z.abs() < 1e-6);
            assert!((*m - -Vec3::Z).length() < 1e-5, "{m}");
        }
    }

    #[test]
    fn orientation_follows_normals_then_reverse() {
        let mut m = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            indices: vec![[0, 1, 2]],
            normals: Some(vec![-Vec3::Z; 3]),
            ..Default::default()
        };
        orient(&mut m, false);
        assert_eq!(m.indices[0], [0, 2, 1]);
        orient(&mut m, true);
        assert_eq!(m.indices[0], [0, 1, 2]);
        assert_eq!(m.normals.as_ref().unwrap()[0], Vec3::Z);
    }
}
