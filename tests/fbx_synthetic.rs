//! The FBX loader on small files written here, for what the shared scenes do not exercise: a Z-up
//! file in metres, a model hierarchy with pivots, per-polygon material slots, n-gons, a spot
//! light, zlib-compressed arrays, 64-bit (7.5) record headers and texture paths.

use glam::Vec3;
use std::io::Write;
use trayecto::scene::{LightDesc, Shape, fbx};

/// A property of the test writer.
enum P {
    I(i32),
    L(i64),
    D(f64),
    S(String),
    Di(Vec<f64>, bool),
    Ii(Vec<i32>, bool),
}

fn s(v: &str) -> P {
    P::S(v.to_string())
}

struct N {
    name: &'static str,
    props: Vec<P>,
    children: Vec<N>,
}

fn n(name: &'static str, props: Vec<P>, children: Vec<N>) -> N {
    N {
        name,
        props,
        children,
    }
}

/// A `P` entry of a Properties70 block.
fn p(name: &str, ty: &str, vals: Vec<P>) -> N {
    let mut props = vec![s(name), s(ty), s(""), s("A")];
    props.extend(vals);
    n("P", props, vec![])
}

fn p3(name: &str, v: [f64; 3]) -> N {
    p(name, "Vector3D", v.iter().map(|&x| P::D(x)).collect())
}

fn write_array(out: &mut Vec<u8>, code: u8, count: usize, raw: Vec<u8>, compress: bool) {
    out.push(code);
    out.extend((count as u32).to_le_bytes());
    if compress {
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(&raw).unwrap();
        let z = e.finish().unwrap();
        out.extend(1u32.to_le_bytes());
        out.extend((z.len() as u32).to_le_bytes());
        out.extend(z);
    } else {
        out.extend(0u32.to_le_bytes());
        out.extend((raw.len() as u32).to_le_bytes());
        out.extend(raw);
    }
}

fn write_node(out: &mut Vec<u8>, node: &N, wide: bool) {
    let field = |out: &mut Vec<u8>, v: u64| {
        if wide {
            out.extend(v.to_le_bytes())
        } else {
            out.extend((v as u32).to_le_bytes())
        }
    };
    let start = out.len();
    let mut props = Vec::new();
    for pr in &node.props {
        match pr {
            P::I(v) => {
                props.push(b'I');
                props.extend(v.to_le_bytes());
            }
            P::L(v) => {
                props.push(b'L');
                props.extend(v.to_le_bytes());
            }
            P::D(v) => {
                props.push(b'D');
                props.extend(v.to_le_bytes());
            }
            P::S(v) => {
                props.push(b'S');
                props.extend((v.len() as u32).to_le_bytes());
                props.extend(v.as_bytes());
            }
            P::Di(v, c) => write_array(
                &mut props,
                b'd',
                v.len(),
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
                *c,
            ),
            P::Ii(v, c) => write_array(
                &mut props,
                b'i',
                v.len(),
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
                *c,
            ),
        }
    }
    field(out, 0); // end offset, patched below
    field(out, node.props.len() as u64);
    field(out, props.len() as u64);
    out.push(node.name.len() as u8);
    out.extend(node.name.as_bytes());
    out.extend(props);
    for c in &node.children {
        write_node(out, c, wide);
    }
    if !node.children.is_empty() {
        out.extend(std::iter::repeat_n(0u8, if wide { 25 } else { 13 }));
    }
    let end = out.len() as u64;
    if wide {
        out[start..start + 8].copy_from_slice(&end.to_le_bytes());
    } else {
        out[start..start + 4].copy_from_slice(&(end as u32).to_le_bytes());
    }
}

fn write_fbx(nodes: &[N], version: u32) -> Vec<u8> {
    let wide = version >= 7500;
    let mut out = b"Kaydara FBX Binary  \0\x1a\0".to_vec();
    out.extend(version.to_le_bytes());
    for node in nodes {
        write_node(&mut out, node, wide);
    }
    out.extend(std::iter::repeat_n(0u8, if wide { 25 } else { 13 }));
    out
}

fn obj(kind: &'static str, id: i64, name: &str, class: &str, children: Vec<N>) -> N {
    n(
        kind,
        vec![P::L(id), s(&format!("{name}\u{0}\u{1}{kind}")), s(class)],
        children,
    )
}

fn props70(entries: Vec<N>) -> N {
    n("Properties70", vec![], entries)
}

fn c(kind: &str, child: i64, parent: i64, prop: Option<&str>) -> N {
    let mut props = vec![s(kind), P::L(child), P::L(parent)];
    if let Some(pr) = prop {
        props.push(s(pr));
    }
    n("C", props, vec![])
}

/// A Z-up file in metres: a parent rotated about its pivot holding a mesh with a quad (slot 0)
/// and a concave pentagon (slot 1); a spot light; a texture that points outside the folder.
/// The control points of the test mesh (file units): a quad (0–3) and a concave pentagon (4–8),
/// each polygon corner a different control point.
const VERTICES: [[f64; 3]; 9] = [
    [0., 0., 0.],
    [1., 0., 0.],
    [1., 1., 0.],
    [0., 1., 0.],
    [2., 0., 0.],
    [4., 0., 0.],
    [4., 2., 0.],
    [3., 1., 0.],
    [2., 2., 0.],
];
const NORMALS: [[f64; 3]; 3] = [[0., 0., 1.], [0.6, 0., 0.8], [0., -0.8, 0.6]];
/// Corner k (= control point k) → its normal in `NORMALS` (not k mod 3, so an index ignored in
/// favour of the control point number is caught).
const NORMALS_INDEX: [i32; 9] = [2, 0, 1, 1, 2, 0, 0, 2, 1];
/// UV of control point i (ByVertice, Direct): (0.1 i, 0.1 i + 0.05), with v = 0 at the bottom.
fn file_uv(i: usize) -> [f64; 2] {
    [0.1 * i as f64, 0.1 * i as f64 + 0.05]
}

fn scene(compress: bool) -> Vec<N> {
    let int = |name: &str, v: i32| p(name, "int", vec![P::I(v)]);
    let global = n(
        "GlobalSettings",
        vec![],
        vec![props70(vec![
            int("UpAxis", 2),
            int("UpAxisSign", 1),
            int("FrontAxis", 1),
            int("FrontAxisSign", -1),
            int("CoordAxis", 0),
            int("CoordAxisSign", 1),
            p("UnitScaleFactor", "double", vec![P::D(100.0)]),
        ])],
    );
    let geom = obj(
        "Geometry",
        10,
        "shape",
        "Mesh",
        vec![
            n("Vertices", vec![P::Di(VERTICES.concat(), compress)], vec![]),
            n(
                "PolygonVertexIndex",
                vec![P::Ii(vec![0, 1, 2, -4, 4, 5, 6, 7, -9], compress)],
                vec![],
            ),
            n(
                "LayerElementMaterial",
                vec![P::I(0)],
                vec![
                    n("MappingInformationType", vec![s("ByPolygon")], vec![]),
                    n("ReferenceInformationType", vec![s("IndexToDirect")], vec![]),
                    n("Materials", vec![P::Ii(vec![0, 1], compress)], vec![]),
                ],
            ),
            n(
                // Three distinct unit normals, one per polygon corner through an index, so the
                // test can tell which value each vertex got.
                "LayerElementNormal",
                vec![P::I(0)],
                vec![
                    n("MappingInformationType", vec![s("ByPolygonVertex")], vec![]),
                    n("ReferenceInformationType", vec![s("IndexToDirect")], vec![]),
                    n("Normals", vec![P::Di(NORMALS.concat(), compress)], vec![]),
                    n(
                        "NormalsIndex",
                        vec![P::Ii(NORMALS_INDEX.to_vec(), compress)],
                        vec![],
                    ),
                ],
            ),
            n(
                "LayerElementUV",
                vec![P::I(0)],
                vec![
                    n("MappingInformationType", vec![s("ByVertice")], vec![]),
                    n("ReferenceInformationType", vec![s("Direct")], vec![]),
                    n(
                        "UV",
                        vec![P::Di((0..9).flat_map(file_uv).collect(), compress)],
                        vec![],
                    ),
                ],
            ),
        ],
    );
    let parent = obj(
        "Model",
        1,
        "parent",
        "Null",
        vec![props70(vec![
            // 90° about file Z around the pivot (1, 0, 0), then up 1 m along file Z.
            p3("Lcl Translation", [0.0, 0.0, 1.0]),
            p3("Lcl Rotation", [0.0, 0.0, 90.0]),
            p3("RotationPivot", [1.0, 0.0, 0.0]),
        ])],
    );
    let child = obj(
        "Model",
        2,
        "shape",
        "Mesh",
        vec![props70(vec![p3("Lcl Scaling", [2.0, 2.0, 2.0])])],
    );
    let red = obj(
        "Material",
        20,
        "red",
        "",
        vec![
            n("ShadingModel", vec![s("lambert")], vec![]),
            props70(vec![p(
                "DiffuseColor",
                "Color",
                vec![P::D(1.0), P::D(0.0), P::D(0.0)],
            )]),
        ],
    );
    let blue = obj(
        "Material",
        21,
        "blue",
        "",
        vec![props70(vec![p(
            "DiffuseColor",
            "Color",
            vec![P::D(0.0), P::D(0.0), P::D(1.0)],
        )])],
    );
    let tex = obj(
        "Texture",
        30,
        "stolen",
        "",
        vec![
            n("FileName", vec![s("/etc/passwd")], vec![]),
            n("RelativeFilename", vec![s("../../../etc/passwd")], vec![]),
        ],
    );
    let spot_attr = obj(
        "NodeAttribute",
        40,
        "spot",
        "Light",
        vec![props70(vec![
            int("LightType", 2),
            p("Intensity", "Number", vec![P::D(400.0)]),
            p("InnerAngle", "Number", vec![P::D(30.0)]),
            p("OuterAngle", "Number", vec![P::D(60.0)]),
        ])],
    );
    let spot = obj(
        "Model",
        41,
        "spot",
        "Light",
        vec![props70(vec![p3("Lcl Translation", [0.0, 0.0, 3.0])])],
    );
    vec![
        n(
            "FBXHeaderExtension",
            vec![],
            vec![n("FBXVersion", vec![P::I(7400)], vec![])],
        ),
        global,
        n(
            "Objects",
            vec![],
            vec![geom, parent, child, red, blue, tex, spot_attr, spot],
        ),
        n(
            "Connections",
            vec![],
            vec![
                c("OO", 1, 0, None),
                c("OO", 2, 1, None),
                c("OO", 10, 2, None),
                c("OO", 20, 2, None),
                c("OO", 21, 2, None),
                c("OP", 30, 20, Some("DiffuseColor")),
                c("OO", 41, 0, None),
                c("OO", 40, 41, None),
            ],
        ),
    ]
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

#[test]
fn hierarchy_pivots_axes_units_slots_and_spot_light() {
    for (version, compress) in [(7400, false), (7400, true), (7500, true)] {
        let bytes = write_fbx(&scene(compress), version);
        let dir = std::env::temp_dir().join(format!("trayecto_fbx_syn_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let s =
            fbx::load_bytes(&bytes, "synthetic.fbx", Some(&dir)).unwrap_or_else(|e| panic!("{e}"));
        // Two sub-meshes (one per material slot): a quad (2 triangles), a concave pentagon (3).
        assert_eq!(s.objects.len(), 2, "{version} {compress}");
        let tri_counts: Vec<usize> = s
            .objects
            .iter()
            .map(|o| match o.shape {
                Shape::Mesh(m) => s.meshes[m].indices.len(),
                _ => 0,
            })
            .collect();
        assert_eq!(tri_counts, vec![2, 3]);
        let red = &s.materials[s.objects[0].material];
        let blue = &s.materials[s.objects[1].material];
        assert_eq!((red.name.as_str(), blue.name.as_str()), ("red", "blue"));
        // File point p (Z up, metres) → child scale 2 → parent: rotate 90° about Z around the
        // pivot (1,0,0), translate +1 along Z → Y-up: (x, y, z) ↦ (x, z, −y).
        let o = &s.objects[0];
        let Shape::Mesh(m) = o.shape else { panic!() };
        let world: Vec<Vec3> = s.meshes[m]
            .positions
            .iter()
            .map(|&p| o.transform.transform_point3(p))
            .collect();
        let expect = |p: Vec3| {
            let q = p * 2.0 - Vec3::X; // scaled, relative to the pivot
            let r = Vec3::new(-q.y, q.x, q.z) + Vec3::X + Vec3::Z; // rotated back, moved up
            Vec3::new(r.x, r.z, -r.y)
        };
        assert!(
            world
                .iter()
                .any(|&w| close(w, expect(Vec3::new(1.0, 1.0, 0.0)))),
            "{world:?}"
        );
        assert!(
            world.iter().any(|&w| close(w, expect(Vec3::ZERO))),
            "{world:?}"
        );
        // Winding survives triangulation: the quad faces file +Z, i.e. world +Y.
        let t = s.meshes[m].indices[0];
        let n = (world[t[1] as usize] - world[t[0] as usize])
            .cross(world[t[2] as usize] - world[t[0] as usize]);
        assert!(n.normalize().dot(Vec3::Y) > 0.999, "{n}");
        // Every vertex of both sub-meshes carries its control point's exact values: the file's
        // normal (through NormalsIndex) and UV with v flipped to v-down (glTF's convention),
        // u unchanged. Vertices are matched to control points by their (local) position.
        let mut seen = [false; 9];
        for o in &s.objects {
            let Shape::Mesh(m) = o.shape else { panic!() };
            let mesh = &s.meshes[m];
            let (normals, uv) = (mesh.normals.as_ref(), mesh.uv0.as_ref());
            let (normals, uv) = (normals.expect("normals read"), uv.expect("UVs read"));
            for (k, p) in mesh.positions.iter().enumerate() {
                let i = VERTICES
                    .iter()
                    .position(|v| (p.as_dvec3() - glam::DVec3::from(*v)).length() < 1e-6)
                    .unwrap_or_else(|| panic!("vertex {p} is no control point"));
                seen[i] = true;
                let [u, v] = file_uv(i);
                let want_uv = glam::Vec2::new(u as f32, (1.0 - v) as f32);
                assert!(
                    (uv[k] - want_uv).abs().max_element() < 1e-6,
                    "control point {i}: uv {} expected {want_uv} (file ({u}, {v}))",
                    uv[k]
                );
                let want_n = Vec3::from(NORMALS[NORMALS_INDEX[i] as usize].map(|x| x as f32));
                assert!(
                    (normals[k] - want_n).abs().max_element() < 1e-6,
                    "control point {i}: normal {} expected {want_n}",
                    normals[k]
                );
            }
        }
        assert!(seen.iter().all(|&b| b), "{seen:?}");
        // The texture path escaping the folder is refused: a warning and the magenta fallback.
        let all = s.warnings.join("\n");
        assert!(all.contains("'stolen'") && all.contains("refused"), "{all}");
        let t = red.base_color_texture.expect("fallback texture");
        assert_eq!(
            s.textures[t.texture].texels.get(0).truncate(),
            Vec3::new(1.0, 0.0, 1.0)
        );
        // The spot light: 3 m up (file Z) is world +Y; FBX lights shine down local −Y, which is
        // file −Y = world +Z; cone angles are full angles in degrees; 400/100 W over 4π sr.
        let spot = s.lights.iter().find(|l| l.name() == "spot").unwrap();
        let LightDesc::Spot {
            position,
            direction,
            intensity,
            inner_angle,
            outer_angle,
            ..
        } = spot
        else {
            panic!("{spot:?}")
        };
        assert!(close(*position, Vec3::new(0.0, 3.0, 0.0)), "{position}");
        assert!(close(*direction, Vec3::Z), "{direction}");
        assert!(close(
            *intensity,
            Vec3::splat(4.0 / (4.0 * std::f32::consts::PI))
        ));
        assert!((inner_angle.to_degrees() - 15.0).abs() < 1e-4);
        assert!((outer_angle.to_degrees() - 30.0).abs() < 1e-4);
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn hostile_counts_and_cycles_are_errors() {
    // A compressed array claiming far more elements than its bytes could inflate to.
    let mut nodes = scene(true);
    let bytes = write_fbx(&nodes, 7400);
    let needle = 9u32.to_le_bytes(); // PolygonVertexIndex count
    let pos = bytes
        .windows(5)
        .position(|w| w[0] == b'i' && w[1..5] == needle)
        .unwrap();
    let mut bad = bytes.clone();
    bad[pos + 1..pos + 5].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = fbx::load_bytes(&bad, "huge.fbx", None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("huge.fbx") && e.contains("compressed array"),
        "{e}"
    );
    // A model that is its own grandparent.
    if let Some(conns) = nodes.iter_mut().find(|n| n.name == "Connections") {
        conns.children.push(c("OO", 1, 2, None));
    }
    let e = fbx::load_bytes(&write_fbx(&nodes, 7400), "cycle.fbx", None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cycle"), "{e}");
}

/// A zlib array within the allowed inflation ratio can still ask for more memory than there
/// is (2.4 MB of zeros claim 2.4 GB): it is charged to the load's budget before inflating.
#[test]
fn a_compressed_array_within_the_ratio_is_charged_to_the_budget() {
    use trayecto::limits::{self, Budget, LoadContext};
    let mut nodes = scene(true);
    nodes.push(n("Junk", vec![P::Di(vec![0.0; 4 << 20], true)], vec![]));
    let bytes = write_fbx(&nodes, 7400);
    assert!(bytes.len() < 1 << 20, "{} bytes", bytes.len());
    let small = LoadContext::new(Budget::new(32 << 20), None);
    let e = limits::scope(small, || fbx::load_bytes(&bytes, "zeros.fbx", None))
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("zeros.fbx") && e.contains("compressed array") && e.contains("budget"),
        "{e}"
    );
    let enough = LoadContext::new(Budget::new(256 << 20), None);
    assert!(limits::scope(enough, || fbx::load_bytes(&bytes, "zeros.fbx", None)).is_ok());
}
