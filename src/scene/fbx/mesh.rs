//! FBX `Geometry` (Mesh) objects to triangle meshes.
//!
//! A mesh is a list of control points (`Vertices`) and polygons (`PolygonVertexIndex`, where a
//! negative entry `-i-1` closes a polygon with vertex `i`). Normals, UVs, colours and material
//! slots live in layer elements, each with a mapping (per control point, per polygon vertex, per
//! polygon or for the whole mesh) and a reference mode (direct or through an index array).
//! Corners are split into render vertices by the attribute values they reference, polygons are
//! triangulated by ear clipping (so concave n-gons are right), and one sub-mesh is produced per
//! material slot.

use super::binary::Node;
use crate::scene::Mesh;
use glam::{DVec2, DVec3, Vec2, Vec4};
use std::collections::HashMap;

/// A triangulated geometry split by material slot.
pub struct Converted {
    /// (material slot, mesh); slot -1 when the geometry has no material layer.
    pub parts: Vec<(i64, Mesh)>,
    pub warnings: Vec<String>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Mapping {
    PolygonVertex,
    Vertex,
    Polygon,
    AllSame,
}

/// A layer element resolved to a per-corner lookup.
struct Layer {
    mapping: Mapping,
    index: Option<Vec<i64>>,
    /// Number of values in the direct array.
    len: usize,
    name: &'static str,
}

impl Layer {
    fn read(
        elem: &Node,
        index: &str,
        len_of_values: usize,
        name: &'static str,
        warnings: &mut Vec<String>,
        geom: &str,
    ) -> Option<Layer> {
        let mapping = match elem.child_str("MappingInformationType").unwrap_or("") {
            "ByPolygonVertex" => Mapping::PolygonVertex,
            "ByVertice" | "ByVertex" | "ByControlPoint" => Mapping::Vertex,
            "ByPolygon" => Mapping::Polygon,
            "AllSame" => Mapping::AllSame,
            other => {
                warnings.push(format!(
                    "mesh '{geom}': {name} mapped '{other}' is not supported and was ignored"
                ));
                return None;
            }
        };
        let reference = elem
            .child_str("ReferenceInformationType")
            .unwrap_or("Direct");
        let index = if reference == "IndexToDirect" || reference == "Index" {
            elem.child(index)
                .and_then(|n| n.prop(0))
                .and_then(|p| p.to_i64_vec())
        } else {
            None
        };
        Some(Layer {
            mapping,
            index,
            len: len_of_values,
            name,
        })
    }

    /// The value index for corner `pv` of polygon `poly` at control point `cp`.
    fn value_index(&self, pv: usize, poly: usize, cp: usize) -> Result<usize, String> {
        let m = match self.mapping {
            Mapping::PolygonVertex => pv,
            Mapping::Vertex => cp,
            Mapping::Polygon => poly,
            Mapping::AllSame => 0,
        };
        let v = match &self.index {
            Some(ix) => {
                let Some(&i) = ix.get(m) else {
                    return Err(format!(
                        "its {} index array has {} entries but entry {m} is needed",
                        self.name,
                        ix.len()
                    ));
                };
                if i < 0 {
                    return Err(format!("its {} index {m} is negative ({i})", self.name));
                }
                i as usize
            }
            None => m,
        };
        if v >= self.len {
            return Err(format!(
                "it references {} {v} but has only {}",
                self.name, self.len
            ));
        }
        Ok(v)
    }
}

fn f64_array(node: &Node, child: &str) -> Option<Vec<f64>> {
    node.child(child)?.prop(0)?.to_f64_vec()
}

/// Converts one `Geometry` node of class `Mesh`. `name` is for messages.
pub fn convert(geom: &Node, name: &str) -> Result<Converted, String> {
    let mut warnings = Vec::new();
    let verts = f64_array(geom, "Vertices").unwrap_or_default();
    if !verts.len().is_multiple_of(3) {
        return Err(format!(
            "mesh '{name}': its Vertices array has {} numbers, not a multiple of 3",
            verts.len()
        ));
    }
    let cps: Vec<DVec3> = verts
        .chunks_exact(3)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect();
    if let Some(i) = cps.iter().position(|p| !p.is_finite()) {
        return Err(format!("mesh '{name}': control point {i} is not finite"));
    }
    let pvi = geom
        .child("PolygonVertexIndex")
        .and_then(|n| n.prop(0))
        .and_then(|p| p.to_i64_vec())
        .unwrap_or_default();

    // Polygons as ranges of corners.
    let mut polys: Vec<(usize, usize)> = Vec::new();
    let mut start = 0;
    for (k, &raw) in pvi.iter().enumerate() {
        let cp = if raw < 0 { !raw } else { raw };
        if cp as usize >= cps.len() {
            return Err(format!(
                "mesh '{name}': polygon vertex {k} references control point {cp} but there are {}",
                cps.len()
            ));
        }
        if raw < 0 {
            polys.push((start, k + 1));
            start = k + 1;
        }
    }
    if start < pvi.len() {
        warnings.push(format!(
            "mesh '{name}': the last polygon is not closed (no negative index); it was closed"
        ));
        polys.push((start, pvi.len()));
    }
    let corner_cp = |k: usize| -> usize {
        let raw = pvi[k];
        (if raw < 0 { !raw } else { raw }) as usize
    };

    // Layer elements: the first normal and colour layers, the first two UV sets, the first
    // material layer.
    let first = |kind: &'static str| geom.children_named(kind).next();
    let normals = first("LayerElementNormal").and_then(|e| {
        let vals = f64_array(e, "Normals")?;
        let n: Vec<DVec3> = vals
            .chunks_exact(3)
            .map(|c| DVec3::new(c[0], c[1], c[2]))
            .collect();
        let layer = Layer::read(e, "NormalsIndex", n.len(), "normal", &mut warnings, name)?;
        Some((layer, n))
    });
    let mut uvs: Vec<(Layer, Vec<DVec2>)> = Vec::new();
    for e in geom.children_named("LayerElementUV") {
        if uvs.len() == 2 {
            warnings.push(format!(
                "mesh '{name}': UV sets beyond the second are ignored"
            ));
            break;
        }
        let Some(vals) = f64_array(e, "UV") else {
            continue;
        };
        let uv: Vec<DVec2> = vals
            .chunks_exact(2)
            .map(|c| DVec2::new(c[0], c[1]))
            .collect();
        if let Some(layer) = Layer::read(e, "UVIndex", uv.len(), "UV", &mut warnings, name) {
            uvs.push((layer, uv));
        }
    }
    let colors = first("LayerElementColor").and_then(|e| {
        let vals = f64_array(e, "Colors")?;
        let c: Vec<Vec4> = vals
            .chunks_exact(4)
            .map(|c| Vec4::new(c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32))
            .collect();
        let layer = Layer::read(e, "ColorIndex", c.len(), "colour", &mut warnings, name)?;
        Some((layer, c))
    });
    let materials = first("LayerElementMaterial").and_then(|e| {
        let slots = e.child("Materials")?.prop(0)?.to_i64_vec()?;
        let mapping = e.child_str("MappingInformationType").unwrap_or("AllSame");
        Some((mapping == "ByPolygon", slots))
    });
    // Tangent, binormal, smoothing and visibility layers are derived or editing-only data and are
    // not read: the renderer builds its shading frames from normals and UVs.

    // Per slot: the mesh being built and its corner-key → vertex map.
    struct Part {
        mesh: Mesh,
        map: HashMap<[u32; 5], u32>,
    }
    let mut parts: Vec<(i64, Part)> = Vec::new();
    let mut skipped = 0usize;
    let mut poly_pts: Vec<DVec3> = Vec::new();
    let mut tris: Vec<[usize; 3]> = Vec::new();
    let mut corner_vertex: Vec<u32> = Vec::new();
    for (poly, &(a, b)) in polys.iter().enumerate() {
        if b - a < 3 {
            skipped += 1;
            continue;
        }
        let slot = match &materials {
            Some((true, slots)) => slots.get(poly).copied().unwrap_or(0),
            Some((false, slots)) => slots.first().copied().unwrap_or(0),
            None => -1,
        };
        let part_index = match parts.iter().position(|(s, _)| *s == slot) {
            Some(i) => i,
            None => {
                let mesh = Mesh {
                    name: name.to_string(),
                    normals: normals.as_ref().map(|_| Vec::new()),
                    uv0: uvs.first().map(|_| Vec::new()),
                    uv1: uvs.get(1).map(|_| Vec::new()),
                    colors: colors.as_ref().map(|_| Vec::new()),
                    ..Default::default()
                };
                parts.push((
                    slot,
                    Part {
                        mesh,
                        map: HashMap::new(),
                    },
                ));
                parts.len() - 1
            }
        };
        let part = &mut parts[part_index].1;
        corner_vertex.clear();
        poly_pts.clear();
        for k in a..b {
            let cp = corner_cp(k);
            let err = |e: String| format!("mesh '{name}': {e}");
            let n_ix = match &normals {
                Some((l, _)) => l.value_index(k, poly, cp).map_err(err)? as u32,
                None => u32::MAX,
            };
            let mut uv_ix = [u32::MAX; 2];
            for (s, (l, _)) in uvs.iter().enumerate() {
                uv_ix[s] = l.value_index(k, poly, cp).map_err(err)? as u32;
            }
            let c_ix = match &colors {
                Some((l, _)) => l.value_index(k, poly, cp).map_err(err)? as u32,
                None => u32::MAX,
            };
            let key = [cp as u32, n_ix, uv_ix[0], uv_ix[1], c_ix];
            let next = part.mesh.positions.len() as u32;
            let v = *part.map.entry(key).or_insert(next);
            if v == next {
                let m = &mut part.mesh;
                m.positions.push(cps[cp].as_vec3());
                if let (Some(out), Some((_, vals))) = (m.normals.as_mut(), &normals) {
                    out.push(vals[n_ix as usize].as_vec3());
                }
                for (s, (_, vals)) in uvs.iter().enumerate() {
                    let out = if s == 0 {
                        m.uv0.as_mut()
                    } else {
                        m.uv1.as_mut()
                    };
                    if let Some(out) = out {
                        let uv = vals[uv_ix[s] as usize];
                        // FBX puts v = 0 at the bottom of the image; textures here are stored
                        // top row first with v pointing down (glTF), hence the flip.
                        out.push(Vec2::new(uv.x as f32, 1.0 - uv.y as f32));
                    }
                }
                if let (Some(out), Some((_, vals))) = (m.colors.as_mut(), &colors) {
                    out.push(vals[c_ix as usize]);
                }
            }
            corner_vertex.push(v);
            poly_pts.push(cps[cp]);
        }
        tris.clear();
        triangulate(&poly_pts, &mut tris);
        for t in &tris {
            part.mesh.indices.push([
                corner_vertex[t[0]],
                corner_vertex[t[1]],
                corner_vertex[t[2]],
            ]);
        }
    }
    if skipped > 0 {
        warnings.push(format!(
            "mesh '{name}': {skipped} polygon(s) with fewer than 3 vertices (points or lines) were skipped"
        ));
    }
    // Non-finite normals would poison shading; drop the normals of such a mesh.
    let mut out = Vec::with_capacity(parts.len());
    for (slot, mut part) in parts {
        if let Some(ns) = &mut part.mesh.normals
            && ns.iter().any(|n| !n.is_finite())
        {
            warnings.push(format!(
                "mesh '{name}': non-finite normals were dropped (geometric normals are used)"
            ));
            part.mesh.normals = None;
        }
        if let Some(uv) = &part.mesh.uv0
            && uv.iter().any(|t| !t.is_finite())
        {
            part.mesh.uv0 = None;
        }
        if let Some(uv) = &part.mesh.uv1
            && uv.iter().any(|t| !t.is_finite())
        {
            part.mesh.uv1 = None;
        }
        out.push((slot, part.mesh));
    }
    Ok(Converted {
        parts: out,
        warnings,
    })
}

/// Triangulates a planar (or nearly planar) polygon by ear clipping in the plane of its Newell
/// normal, keeping the polygon's winding. Falls back to a fan for degenerate input.
pub fn triangulate(pts: &[DVec3], out: &mut Vec<[usize; 3]>) {
    let n = pts.len();
    if n < 3 {
        return;
    }
    if n == 3 {
        out.push([0, 1, 2]);
        return;
    }
    let fan = |out: &mut Vec<[usize; 3]>, idx: &[usize]| {
        for i in 1..idx.len() - 1 {
            out.push([idx[0], idx[i], idx[i + 1]]);
        }
    };
    // Newell's method: a robust polygon normal for any simple polygon.
    let mut normal = DVec3::ZERO;
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        normal += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    let all: Vec<usize> = (0..n).collect();
    if !(normal.length_squared() > 0.0) {
        fan(out, &all);
        return;
    }
    // Project onto the plane of the two axes orthogonal to the normal's largest component, oriented
    // so that the polygon is counter-clockwise in 2D.
    let ax = normal.abs();
    let (u, v, sign) = if ax.x >= ax.y && ax.x >= ax.z {
        (1, 2, normal.x.signum())
    } else if ax.y >= ax.z {
        (2, 0, normal.y.signum())
    } else {
        (0, 1, normal.z.signum())
    };
    let p2: Vec<DVec2> = pts.iter().map(|p| DVec2::new(p[u], p[v] * sign)).collect();
    let cross = |a: DVec2, b: DVec2, c: DVec2| (b - a).perp_dot(c - a);
    let mut idx = all;
    let mut guard = 0usize;
    while idx.len() > 3 {
        guard += 1;
        if guard > n * n + 8 {
            break;
        }
        let m = idx.len();
        let mut clipped = false;
        for i in 0..m {
            let (ia, ib, ic) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
            let (a, b, c) = (p2[ia], p2[ib], p2[ic]);
            if !(cross(a, b, c) > 0.0) {
                continue; // reflex or degenerate corner
            }
            let inside = idx.iter().any(|&j| {
                j != ia
                    && j != ib
                    && j != ic
                    && cross(a, b, p2[j]) >= 0.0
                    && cross(b, c, p2[j]) >= 0.0
                    && cross(c, a, p2[j]) >= 0.0
            });
            if inside {
                continue;
            }
            out.push([ia, ib, ic]);
            idx.remove(i);
            clipped = true;
            break;
        }
        if !clipped {
            break;
        }
    }
    if idx.len() >= 3 {
        fan(out, &idx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area2(pts: &[DVec3], t: [usize; 3]) -> DVec3 {
        (pts[t[1]] - pts[t[0]]).cross(pts[t[2]] - pts[t[0]])
    }

    #[test]
    fn concave_polygon_is_covered_exactly_with_its_winding() {
        // An L shape (concave at vertex 3), counter-clockwise about +z: area 3.
        let pts: Vec<DVec3> = [
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]
        .iter()
        .map(|&(x, y)| DVec3::new(x, y, 0.0))
        .collect();
        let mut tris = Vec::new();
        triangulate(&pts, &mut tris);
        assert_eq!(tris.len(), 4);
        let mut total = 0.0;
        for &t in &tris {
            let a = area2(&pts, t);
            assert!(a.z > 0.0, "triangle {t:?} flipped");
            total += a.z * 0.5;
        }
        assert!((total - 3.0).abs() < 1e-12, "area {total}");
    }

    #[test]
    fn clockwise_polygon_keeps_its_winding() {
        let pts: Vec<DVec3> = [(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.0), (0.5, -0.5)]
            .iter()
            .map(|&(x, y)| DVec3::new(x, y, 3.0))
            .collect();
        let mut tris = Vec::new();
        triangulate(&pts, &mut tris);
        assert_eq!(tris.len(), 3);
        assert!(tris.iter().all(|&t| area2(&pts, t).z < 0.0));
    }
}
