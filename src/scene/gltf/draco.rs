//! `KHR_draco_mesh_compression`: a primitive whose triangles and some (usually all) vertex
//! attributes are one Draco stream in a buffer view. The extension object names the view and maps
//! each glTF attribute (`POSITION`, `NORMAL`, `TEXCOORD_0`, …) to a Draco attribute *unique id*;
//! the primitive's accessors keep their type, component type and `normalized` flag but have no
//! data (extension text, "Conformance").
//!
//! Decoding uses `draco-core`, a pure-Rust port of the reference decoder. It returns
//! [`draco_core::DracoError`] for malformed streams and takes ceilings on what one decode may
//! produce ([`draco_core::decode_limits::DecodeLimits`]), set here to the loader's accessor limit
//! so a forged header cannot exhaust memory. Draco dequantizes positions, texture coordinates and
//! octahedral normals itself; integer attributes (colours, quantized data) come out as the
//! integers they were, and are normalised here when the accessor says `normalized` (glTF 2.0
//! §3.11), as for any other accessor.
//!
//! Attributes the extension does not list are read from their accessors as usual; their counts
//! must then agree with the decoded point count, which `Scene::validate` checks.

use draco_core::decode_limits::DecodeLimits;
use draco_core::decoder_buffer::DecoderBuffer;
use draco_core::mesh_decoder::MeshDecoder;

use super::*;

pub(super) const EXT: &str = "KHR_draco_mesh_compression";

/// Total decoded attribute bytes accepted for one primitive (far above real models).
const MAX_DECODED_BYTES: u64 = 1 << 31;

/// A decoded Draco primitive: attributes by glTF semantic name, and the triangle list.
pub(super) struct DracoPrimitive {
    /// Semantic (`"POSITION"`) → up to four components per point, and how many are meaningful.
    pub attributes: HashMap<String, (Vec<[f64; 4]>, usize)>,
    /// Flat triangle list (three point indices per triangle), each index checked in range.
    pub indices: Vec<u32>,
}

impl Loader<'_> {
    /// Decodes the primitive's Draco stream, or `None` if it does not use the extension.
    pub(super) fn decode_draco(
        &self,
        mesh_name: &str,
        prim: &gltf::Primitive,
    ) -> Result<Option<DracoPrimitive>, SceneError> {
        let Some(ext) = prim.extension_value(EXT) else {
            return Ok(None);
        };
        let bad = |why: String| self.err(format!("mesh '{mesh_name}': {EXT}: {why}"));
        let view_index = ext
            .get("bufferView")
            .and_then(|v| v.as_u64())
            .and_then(|v| usize::try_from(v).ok())
            .ok_or_else(|| bad("'bufferView' is missing or not an index".into()))?;
        let view = self
            .doc
            .views()
            .nth(view_index)
            .ok_or_else(|| bad(format!("buffer view {view_index} does not exist")))?;
        let ids = ext
            .get("attributes")
            .and_then(|a| a.as_object())
            .ok_or_else(|| bad("'attributes' is missing or not an object".into()))?;
        let bytes = self.view_bytes(&view)?;

        let limits = DecodeLimits::default()
            .with_max_points(MAX_ACCESSOR_COUNT as u64)
            .with_max_faces(MAX_ACCESSOR_COUNT as u64)
            .with_max_decoded_bytes(MAX_DECODED_BYTES);
        let mut buffer = DecoderBuffer::new(bytes).with_limits(limits);
        let mut mesh = draco_core::Mesh::new();
        MeshDecoder::new()
            .decode(&mut buffer, &mut mesh)
            .map_err(|e| {
                bad(format!(
                    "the Draco stream in buffer view {view_index} cannot be decoded ({e})"
                ))
            })?;
        let points = mesh.num_points();
        if mesh.num_faces() == 0 {
            return Err(bad(format!(
                "the Draco stream in buffer view {view_index} holds no triangles ({points} points)"
            )));
        }
        let mut indices = Vec::with_capacity(mesh.num_faces() * 3);
        for face in mesh.faces() {
            for p in face {
                if p.0 as usize >= points {
                    return Err(bad(format!(
                        "a triangle references point {} of {points}",
                        p.0
                    )));
                }
                indices.push(p.0);
            }
        }

        let mut attributes = HashMap::new();
        for (name, id) in ids {
            let id = id
                .as_u64()
                .and_then(|v| u32::try_from(v).ok())
                .ok_or_else(|| bad(format!("attribute '{name}' has no Draco attribute id")))?;
            let att = mesh.attribute_by_unique_id(id).ok_or_else(|| {
                bad(format!(
                    "attribute '{name}' refers to Draco attribute {id}, which the stream does not have"
                ))
            })?;
            let ncomp = usize::from(att.num_components());
            // What the glTF accessor says the data is; Draco must provide at least that many
            // components (a TANGENT without its handedness would be silently wrong).
            let accessor = prim
                .attributes()
                .find(|(s, _)| s.to_string() == *name)
                .map(|(_, a)| a);
            let wanted = match accessor.as_ref().map(|a| a.dimensions()) {
                Some(Dimensions::Scalar) => 1,
                Some(Dimensions::Vec2) => 2,
                Some(Dimensions::Vec3) => 3,
                Some(Dimensions::Vec4) => 4,
                Some(other) => {
                    return Err(bad(format!(
                        "attribute '{name}' has accessor type {other:?}, expected a scalar or vector"
                    )));
                }
                // Listed by the extension but not by the primitive: not used.
                None => continue,
            };
            if ncomp < wanted || ncomp > 4 {
                return Err(bad(format!(
                    "attribute '{name}' decodes to {ncomp} components, but its accessor has {wanted}"
                )));
            }
            let normalize = accessor.as_ref().is_some_and(|a| a.normalized()) || att.normalized();
            let max = match att.data_type() {
                draco_core::DataType::Int8 => i8::MAX as f64,
                draco_core::DataType::Uint8 => u8::MAX as f64,
                draco_core::DataType::Int16 => i16::MAX as f64,
                draco_core::DataType::Uint16 => u16::MAX as f64,
                draco_core::DataType::Int32 => i32::MAX as f64,
                draco_core::DataType::Uint32 => u32::MAX as f64,
                draco_core::DataType::Float32 | draco_core::DataType::Float64 => 1.0,
                other => {
                    return Err(bad(format!(
                        "attribute '{name}' has Draco data type {other:?}, which glTF cannot hold"
                    )));
                }
            };
            let scale = if normalize && max > 1.0 {
                Some(max)
            } else {
                None
            };
            let flat = att.read_f32s(points, wanted);
            let values: Vec<[f64; 4]> = flat
                .chunks_exact(wanted)
                .map(|c| {
                    let mut e = [0.0f64; 4];
                    for (o, &v) in e.iter_mut().zip(c) {
                        // glTF 2.0 §3.11: signed normalised integers clamp at −1.
                        *o = match scale {
                            Some(m) => (v as f64 / m).max(-1.0),
                            None => v as f64,
                        };
                    }
                    e
                })
                .collect();
            attributes.insert(name.clone(), (values, wanted));
        }
        if !attributes.contains_key("POSITION") && prim.get(&gltf::Semantic::Positions).is_some() {
            // POSITION is then read from its accessor; without data it would be all zeros.
            let acc = prim.get(&gltf::Semantic::Positions).expect("checked above");
            if acc.view().is_none() && acc.sparse().is_none() {
                return Err(bad(
                    "POSITION is neither in the Draco stream nor in its accessor".into(),
                ));
            }
        }
        Ok(Some(DracoPrimitive {
            attributes,
            indices,
        }))
    }
}
