//! PLY mesh loader (ASCII, binary little- and big-endian), docs/DESIGN.md §3.
//!
//! Written by hand: the available crates preallocate from the header's element counts, which a
//! hostile file can set to billions. Here nothing is reserved beyond what the data can hold, every
//! read is bounds-checked, and any inconsistency is an error naming the file.
//!
//! Read: `vertex` (x, y, z; nx, ny, nz; u/v, s/t or texture_u/texture_v; red, green, blue, alpha)
//! and `face` (`vertex_indices` or `vertex_index` lists, fan-triangulated). Other elements and
//! properties are skipped with a warning.

use super::conventions::apply_material_conventions;
use super::{Mesh, Scene, SceneError, Shape};
use crate::material::Material;
use crate::math::{Mat4, Vec2, Vec3, Vec4};

/// Largest header accepted, in bytes.
const MAX_HEADER: usize = 1 << 20;
/// Largest polygon accepted (vertices per face).
const MAX_FACE: usize = 1 << 16;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    /// Maximum of an unsigned/normalised colour channel of this type.
    fn colour_max(self) -> f64 {
        match self {
            Ty::U8 | Ty::I8 => 255.0,
            Ty::U16 | Ty::I16 => 65535.0,
            _ => 1.0,
        }
    }
}

#[derive(Clone, Debug)]
struct Prop {
    name: String,
    ty: Ty,
    /// For list properties: the type of the count.
    list: Option<Ty>,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

enum Body<'a> {
    Ascii {
        data: &'a [u8],
        pos: usize,
    },
    Binary {
        data: &'a [u8],
        pos: usize,
        big: bool,
    },
}

impl Body<'_> {
    fn read(&mut self, ty: Ty) -> Result<f64, String> {
        match self {
            Body::Ascii { data, pos } => {
                while *pos < data.len() && data[*pos].is_ascii_whitespace() {
                    *pos += 1;
                }
                let start = *pos;
                while *pos < data.len() && !data[*pos].is_ascii_whitespace() {
                    *pos += 1;
                }
                if start == *pos {
                    return Err("the file ends before all elements were read".into());
                }
                let tok = std::str::from_utf8(&data[start..*pos])
                    .map_err(|_| "non-text bytes in an ASCII PLY body".to_string())?;
                tok.parse::<f64>().map_err(|_| {
                    format!(
                        "'{}' is not a number",
                        tok.chars().take(20).collect::<String>()
                    )
                })
            }
            Body::Binary { data, pos, big } => {
                let n = ty.size();
                let bytes = data
                    .get(*pos..*pos + n)
                    .ok_or_else(|| "the file ends before all elements were read".to_string())?;
                *pos += n;
                let mut b = [0u8; 8];
                b[..n].copy_from_slice(bytes);
                if *big {
                    b[..n].reverse();
                }
                Ok(match ty {
                    Ty::I8 => b[0] as i8 as f64,
                    Ty::U8 => b[0] as f64,
                    Ty::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
                    Ty::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
                    Ty::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    Ty::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    Ty::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    Ty::F64 => f64::from_le_bytes(b),
                })
            }
        }
    }

    /// An upper bound on how many more values the body can hold (for safe reservations).
    fn remaining_values(&self) -> usize {
        match self {
            Body::Ascii { data, pos } => (data.len().saturating_sub(*pos)).div_ceil(2),
            Body::Binary { data, pos, .. } => data.len().saturating_sub(*pos),
        }
    }
}

/// Parses PLY bytes. `label` names the file in messages. (Also the fuzzing entry point.)
pub fn load_from_bytes(bytes: &[u8], label: &str) -> Result<Scene, SceneError> {
    let err = |m: String| SceneError::invalid(label, m);
    let mut scene = Scene {
        name: label.to_string(),
        source: Some(label.into()),
        ..Default::default()
    };
    let mesh = parse(bytes, &mut scene.warnings).map_err(|m| err(format!("PLY: {m}")))?;
    let material = scene.add_material(Material::diffuse("PLY default", Vec3::splat(0.8)));
    let name = mesh.name.clone();
    let id = scene.add_mesh(mesh);
    scene.add_object(&name, Shape::Mesh(id), Mat4::IDENTITY, material);
    apply_material_conventions(&mut scene);
    Ok(scene)
}

fn parse_header(bytes: &[u8]) -> Result<(Format, Vec<Element>, usize), String> {
    if !bytes.starts_with(b"ply") {
        return Err("not a PLY file (it does not start with 'ply')".into());
    }
    let limit = bytes.len().min(MAX_HEADER);
    let mut pos = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let rest = &bytes[pos..limit];
        let Some(nl) = rest.iter().position(|&b| b == b'\n') else {
            return Err("the header has no 'end_header' line".into());
        };
        let line = std::str::from_utf8(&rest[..nl])
            .map_err(|_| "the header is not text".to_string())?
            .trim_end_matches('\r')
            .trim();
        pos += nl + 1;
        let mut w = line.split_whitespace();
        match w.next() {
            Some("ply") | Some("comment") | Some("obj_info") | None => {}
            Some("format") => {
                format = Some(match w.next() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Little,
                    Some("binary_big_endian") => Format::Big,
                    other => return Err(format!("unknown format {other:?}")),
                });
            }
            Some("element") => {
                let (Some(name), Some(count)) = (w.next(), w.next()) else {
                    return Err(format!("malformed line '{line}'"));
                };
                let count = count
                    .parse::<usize>()
                    .map_err(|_| format!("bad element count in '{line}'"))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| "a property comes before any element".to_string())?;
                let words: Vec<&str> = w.collect();
                let prop = match words.as_slice() {
                    ["list", ct, it, name] => Prop {
                        name: name.to_string(),
                        ty: Ty::parse(it).ok_or_else(|| format!("unknown type '{it}'"))?,
                        list: Some(Ty::parse(ct).ok_or_else(|| format!("unknown type '{ct}'"))?),
                    },
                    [t, name] => Prop {
                        name: name.to_string(),
                        ty: Ty::parse(t).ok_or_else(|| format!("unknown type '{t}'"))?,
                        list: None,
                    },
                    _ => return Err(format!("malformed line '{line}'")),
                };
                el.props.push(prop);
            }
            Some("end_header") => break,
            Some(other) => return Err(format!("unknown header keyword '{other}'")),
        }
    }
    let format = format.ok_or("the header has no 'format' line")?;
    Ok((format, elements, pos))
}

/// Parses PLY bytes into one mesh (also used by the pbrt importer's `plymesh`).
pub(crate) fn parse_mesh(bytes: &[u8], warnings: &mut Vec<String>) -> Result<Mesh, String> {
    parse(bytes, warnings)
}

fn parse(bytes: &[u8], warnings: &mut Vec<String>) -> Result<Mesh, String> {
    let (format, elements, start) = parse_header(bytes)?;
    let data = &bytes[start..];
    let mut body = match format {
        Format::Ascii => Body::Ascii { data, pos: 0 },
        Format::Little | Format::Big => Body::Binary {
            data,
            pos: 0,
            big: format == Format::Big,
        },
    };
    let mut mesh = Mesh {
        name: "ply".into(),
        ..Default::default()
    };
    let mut have_vertices = false;
    for el in &elements {
        let idx = |names: &[&str]| {
            el.props
                .iter()
                .position(|p| names.contains(&p.name.as_str()))
        };
        match el.name.as_str() {
            "vertex" => {
                if have_vertices {
                    return Err("more than one 'vertex' element".into());
                }
                have_vertices = true;
                let (Some(x), Some(y), Some(z)) = (idx(&["x"]), idx(&["y"]), idx(&["z"])) else {
                    return Err("the vertex element lacks x, y or z".into());
                };
                let normal = (idx(&["nx"]), idx(&["ny"]), idx(&["nz"]));
                let uv = (
                    idx(&["u", "s", "texture_u", "texture_s"]),
                    idx(&["v", "t", "texture_v", "texture_t"]),
                );
                let rgb = (idx(&["red"]), idx(&["green"]), idx(&["blue"]));
                let alpha = idx(&["alpha"]);
                let used: Vec<Option<usize>> = vec![
                    Some(x),
                    Some(y),
                    Some(z),
                    normal.0,
                    normal.1,
                    normal.2,
                    uv.0,
                    uv.1,
                    rgb.0,
                    rgb.1,
                    rgb.2,
                    alpha,
                ];
                for (i, p) in el.props.iter().enumerate() {
                    if !used.contains(&Some(i)) {
                        warnings.push(format!("PLY vertex property '{}' is ignored", p.name));
                    }
                }
                let cap = el
                    .count
                    .min(body.remaining_values() / el.props.len().max(1));
                let mut pos = Vec::with_capacity(cap);
                let mut nor = Vec::new();
                let mut tex = Vec::new();
                let mut col = Vec::new();
                let mut row = vec![0.0f64; el.props.len()];
                for _ in 0..el.count {
                    for (i, p) in el.props.iter().enumerate() {
                        row[i] = match p.list {
                            None => body.read(p.ty)?,
                            Some(ct) => {
                                // A list in a vertex: skip it.
                                let n = list_len(&mut body, ct)?;
                                for _ in 0..n {
                                    body.read(p.ty)?;
                                }
                                0.0
                            }
                        };
                    }
                    pos.push(Vec3::new(row[x] as f32, row[y] as f32, row[z] as f32));
                    if let (Some(a), Some(b), Some(c)) = normal {
                        nor.push(Vec3::new(row[a] as f32, row[b] as f32, row[c] as f32));
                    }
                    if let (Some(a), Some(b)) = uv {
                        // PLY's v runs up the image; textures have v = 0 at the top (glTF).
                        tex.push(Vec2::new(row[a] as f32, 1.0 - row[b] as f32));
                    }
                    if let (Some(r), Some(g), Some(b)) = rgb {
                        let m = |i: usize| (row[i] / el.props[i].ty.colour_max()) as f32;
                        let a = alpha.map_or(1.0, m);
                        col.push(Vec4::new(m(r), m(g), m(b), a));
                    }
                }
                mesh.positions = pos;
                mesh.normals = (!nor.is_empty()).then_some(nor);
                mesh.uv0 = (!tex.is_empty()).then_some(tex);
                mesh.colors = (!col.is_empty()).then_some(col);
            }
            "face" => {
                let Some(vi) = idx(&["vertex_indices", "vertex_index"]) else {
                    return Err("the face element has no vertex_indices list".into());
                };
                if el.props[vi].list.is_none() {
                    return Err("vertex_indices is not a list".into());
                }
                for (i, p) in el.props.iter().enumerate() {
                    if i != vi {
                        warnings.push(format!("PLY face property '{}' is ignored", p.name));
                    }
                }
                let mut poly = Vec::new();
                for _ in 0..el.count {
                    for (i, p) in el.props.iter().enumerate() {
                        match p.list {
                            None => {
                                body.read(p.ty)?;
                            }
                            Some(ct) => {
                                let n = list_len(&mut body, ct)?;
                                poly.clear();
                                for _ in 0..n {
                                    let v = body.read(p.ty)?;
                                    if i == vi {
                                        if !(v >= 0.0 && v < u32::MAX as f64 && v.fract() == 0.0) {
                                            return Err(format!("bad vertex index {v}"));
                                        }
                                        poly.push(v as u32);
                                    }
                                }
                                if i == vi {
                                    for k in 1..poly.len().saturating_sub(1) {
                                        mesh.indices.push([poly[0], poly[k], poly[k + 1]]);
                                    }
                                }
                            }
                        }
                    }
                }
            }
            other => {
                warnings.push(format!(
                    "PLY element '{other}' ({} entries) is ignored",
                    el.count
                ));
                for _ in 0..el.count {
                    for p in &el.props {
                        match p.list {
                            None => {
                                body.read(p.ty)?;
                            }
                            Some(ct) => {
                                let n = list_len(&mut body, ct)?;
                                for _ in 0..n {
                                    body.read(p.ty)?;
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    if !have_vertices {
        return Err("the file has no vertex element".into());
    }
    Ok(mesh)
}

fn list_len(body: &mut Body, ty: Ty) -> Result<usize, String> {
    let n = body.read(ty)?;
    if !(n >= 0.0 && n.fract() == 0.0 && n <= MAX_FACE as f64) {
        return Err(format!("bad list length {n}"));
    }
    Ok(n as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
        property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0 255 0 0\n1 0 0 255 0 0\n1 1 0 255 0 0\n0 1 0 255 0 0\n4 0 1 2 3\n";

    #[test]
    fn ascii_quad_is_two_triangles_with_colours() {
        let s = load_from_bytes(ASCII.as_bytes(), "t.ply").unwrap();
        assert_eq!(s.meshes[0].indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(
            s.meshes[0].colors.as_ref().unwrap()[0],
            Vec4::new(1.0, 0.0, 0.0, 1.0)
        );
    }

    #[test]
    fn binary_big_and_little_endian_agree() {
        for big in [false, true] {
            let mut b = format!(
                "ply\nformat binary_{}_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n",
                if big { "big" } else { "little" }
            )
            .into_bytes();
            let f = |v: f32| {
                if big {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                }
            };
            let u = |v: u32| {
                if big {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                }
            };
            for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0f32]] {
                for c in p {
                    b.extend(f(c));
                }
            }
            b.push(3);
            for i in [0, 1, 2] {
                b.extend(u(i));
            }
            let s = load_from_bytes(&b, "b.ply").unwrap();
            assert_eq!(s.meshes[0].positions[2], Vec3::new(0.0, 2.0, 0.0));
            assert_eq!(s.meshes[0].indices, vec![[0, 1, 2]]);
        }
    }

    /// Parsed and validated, as `scene::load_file` does with a file on disk.
    fn load_validated(bytes: &[u8], label: &str) -> Result<Scene, SceneError> {
        crate::scene::load_bytes(bytes, std::path::Path::new("."), label)
    }

    #[test]
    fn hostile_headers_are_errors() {
        let huge = ASCII.replace("element vertex 4", "element vertex 99999999999");
        assert!(load_validated(huge.as_bytes(), "h.ply").is_err());
        let bad_index = ASCII.replace("4 0 1 2 3", "4 0 1 2 7");
        let e = load_validated(bad_index.as_bytes(), "h.ply")
            .unwrap_err()
            .to_string();
        assert!(e.contains("h.ply"), "{e}");
        // A vertex that is not finite cannot be bounded: the triangles using it are dropped with
        // a warning (docs/DESIGN.md §7), and the rest of the file loads.
        let nan = ASCII.replace("1 1 0 255", "nan 1 0 255");
        let s = load_validated(nan.as_bytes(), "h.ply").unwrap();
        assert!(
            s.meshes
                .iter()
                .all(|m| m.indices.iter().all(|t| !t.contains(&2)))
        );
        assert!(
            s.warnings.iter().any(|w| w.contains("finite")),
            "{:?}",
            s.warnings
        );
        assert!(load_validated(b"ply\nformat ascii 1.0\n", "h.ply").is_err());
        assert!(load_validated(b"", "h.ply").is_err());
    }
}
