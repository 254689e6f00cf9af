//! Animations, skins and morph targets read into a [`Rig`] (posed by `scene::animation`).

use super::*;
use crate::scene::animation::{
    Animation, Channel, ChannelPath, Deformed, Interpolation, Placed, RigNode, Skin,
};

impl Loader<'_> {
    /// Records that the node hierarchy reached `node` from `parent` (parents come first).
    pub(super) fn rig_visit(&mut self, node: &gltf::Node, parent: Option<usize>) {
        if self.rig.nodes.is_empty() {
            self.rig.nodes = self
                .doc
                .nodes()
                .map(|n| {
                    let (t, r, s) = n.transform().decomposed();
                    let matrix = match n.transform() {
                        gltf::scene::Transform::Matrix { matrix } => {
                            Some(Mat4::from_cols_array_2d(&matrix))
                        }
                        _ => None,
                    };
                    let weights = n
                        .weights()
                        .or_else(|| n.mesh().and_then(|m| m.weights()))
                        .map(|w| w.iter().map(|&x| x as f64).collect())
                        .unwrap_or_default();
                    RigNode {
                        parent: None,
                        matrix,
                        translation: Vec3::from(t),
                        rotation: glam::Quat::from_array(r),
                        scale: Vec3::from(s),
                        weights,
                    }
                })
                .collect();
        }
        self.rig.nodes[node.index()].parent = parent;
        self.rig.order.push(node.index());
    }

    pub(super) fn rig_place(&mut self, node: &gltf::Node, placed: Placed) {
        self.rig.placed.push((node.index(), placed));
    }

    /// A primitive of a skinned node or with morph targets: a mesh of its own, with what posing
    /// it needs (the rest vertices, the targets' displacements, the skin's influences).
    pub(super) fn deformed_primitive(
        &mut self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
    ) -> Result<Option<(MeshId, MaterialId)>, SceneError> {
        let mesh_name = mesh
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("mesh {}", mesh.index()));
        let Some((id, material)) = self.build_primitive(&mesh_name, prim)? else {
            return Ok(None);
        };
        let base = &self.scene.meshes[id];
        let n = base.positions.len();
        let mut d = Deformed {
            mesh: id,
            node: node.index(),
            skin: node.skin().map(|s| s.index()),
            positions: base.positions.clone(),
            normals: base.normals.clone(),
            tangents: base.tangents.clone(),
            target_positions: Vec::new(),
            target_normals: Vec::new(),
            influences: 0,
            joints: Vec::new(),
            weights: Vec::new(),
        };
        let vec3s = |v: Vec<[f64; 4]>| -> Vec<Vec3> {
            v.iter()
                .map(|e| Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32))
                .collect()
        };
        let draco = prim.extension_value("KHR_draco_mesh_compression").is_some();
        if draco && prim.morph_targets().next().is_some() {
            self.warn_once(
                "draco morph",
                format!(
                    "mesh '{mesh_name}': morph targets of Draco-compressed primitives are not \
                     supported: the base shape is rendered"
                ),
            );
        } else {
            for (k, target) in prim.morph_targets().enumerate() {
                let what = format!("mesh '{mesh_name}' morph target {k}");
                let positions = match target.positions() {
                    Some(acc) => vec3s(self.read_accessor(&acc, &format!("{what} POSITION"))?.0),
                    None => vec![Vec3::ZERO; n],
                };
                let normals = match target.normals() {
                    Some(acc) => Some(vec3s(
                        self.read_accessor(&acc, &format!("{what} NORMAL"))?.0,
                    )),
                    None => None,
                };
                if positions.len() != n || normals.as_ref().is_some_and(|v| v.len() != n) {
                    return Err(self.err(format!(
                        "{what}: its attributes do not have the mesh's {n} vertices"
                    )));
                }
                if target.tangents().is_some() {
                    self.warn_once(
                        "morph tangents",
                        "morph target TANGENT displacements are ignored (the base tangents are kept)"
                            .into(),
                    );
                }
                d.target_positions.push(positions);
                d.target_normals.push(normals);
            }
        }
        if d.skin.is_some() {
            // Every JOINTS_n/WEIGHTS_n pair: four influences each (glTF 2.0 §3.7.3.1).
            let mut sets = Vec::new();
            for k in 0.. {
                let (Some(j), Some(w)) = (
                    prim.get(&gltf::Semantic::Joints(k)),
                    prim.get(&gltf::Semantic::Weights(k)),
                ) else {
                    break;
                };
                let j = self
                    .read_accessor(&j, &format!("mesh '{mesh_name}' JOINTS_{k}"))?
                    .0;
                let w = self
                    .read_accessor(&w, &format!("mesh '{mesh_name}' WEIGHTS_{k}"))?
                    .0;
                if j.len() != n || w.len() != n {
                    return Err(self.err(format!(
                        "mesh '{mesh_name}': JOINTS_{k}/WEIGHTS_{k} do not have the mesh's {n} vertices"
                    )));
                }
                sets.push((j, w));
            }
            if sets.is_empty() || draco {
                self.scene.warnings.push(format!(
                    "mesh '{mesh_name}' is skinned but has no JOINTS_0/WEIGHTS_0{}: it is rendered \
                     in its bind pose",
                    if draco {
                        " outside its Draco stream"
                    } else {
                        ""
                    }
                ));
                d.skin = None;
            } else {
                d.influences = 4 * sets.len();
                d.joints.reserve(n * d.influences);
                d.weights.reserve(n * d.influences);
                for v in 0..n {
                    for (j, w) in &sets {
                        for c in 0..4 {
                            d.joints.push(j[v][c].max(0.0) as u32);
                            d.weights.push(w[v][c] as f32);
                        }
                    }
                }
            }
        }
        self.rig.deformed.push(d);
        Ok(Some((id, material)))
    }

    /// After the nodes: the animation channels and skins; the scene gets its [`Animation`] and
    /// its rest pose (skins and default morph weights applied) when anything in it deforms or
    /// moves.
    pub(super) fn finish_animation(&mut self) -> Result<(), SceneError> {
        let doc = self.doc;
        let mut channels = Vec::new();
        for anim in doc.animations() {
            for ch in anim.channels() {
                let node = ch.target().node();
                if node.index() >= self.rig.nodes.len() {
                    // A node outside the rendered scene: nothing of it is drawn.
                    continue;
                }
                let sampler = ch.sampler();
                let interpolation = match sampler.interpolation() {
                    gltf::animation::Interpolation::Step => Interpolation::Step,
                    gltf::animation::Interpolation::Linear => Interpolation::Linear,
                    gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
                };
                let what = format!("animation {} channel", anim.index());
                let times: Vec<f64> = self
                    .read_accessor(&sampler.input(), &format!("{what} input"))?
                    .0
                    .iter()
                    .map(|e| e[0])
                    .collect();
                let (out, ncomp) =
                    self.read_accessor(&sampler.output(), &format!("{what} output"))?;
                let groups = if interpolation == Interpolation::CubicSpline {
                    3
                } else {
                    1
                };
                use gltf::animation::Property;
                let path = match ch.target().property() {
                    Property::Translation => ChannelPath::Translation,
                    Property::Rotation => ChannelPath::Rotation,
                    Property::Scale => ChannelPath::Scale,
                    Property::MorphTargetWeights => {
                        let per_key = out.len() / (times.len() * groups).max(1);
                        ChannelPath::Weights(per_key)
                    }
                };
                let values: Vec<f64> = if matches!(path, ChannelPath::Weights(_)) {
                    out.iter().map(|e| e[0]).collect()
                } else {
                    out.iter().flat_map(|e| e[..ncomp].to_vec()).collect()
                };
                let need = times.len() * groups * path.width();
                if times.is_empty()
                    || values.len() != need
                    || times.windows(2).any(|w| w[0] >= w[1])
                    || times.iter().any(|t| !t.is_finite())
                {
                    self.scene.warnings.push(format!(
                        "{what} {}: its keyframes are malformed (times not increasing, or \
                         {} values where {need} were expected); it is ignored",
                        ch.index(),
                        values.len()
                    ));
                    continue;
                }
                if self
                    .rig
                    .nodes
                    .get(node.index())
                    .is_some_and(|n| n.matrix.is_some())
                    && !matches!(path, ChannelPath::Weights(_))
                {
                    self.warn_once(
                        "matrix animated",
                        "an animation targets a node given by a matrix (invalid glTF); its TRS \
                         decomposition is animated"
                            .into(),
                    );
                }
                channels.push(Channel {
                    node: node.index(),
                    path,
                    interpolation,
                    times,
                    values,
                });
            }
        }
        let mut skins = Vec::new();
        for skin in doc.skins() {
            let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
            let inverse_bind = match skin.inverse_bind_matrices() {
                Some(acc) => self.read_matrices(&acc, &format!("skin {}", skin.index()))?,
                None => vec![Mat4::IDENTITY; joints.len()],
            };
            if inverse_bind.len() < joints.len() {
                return Err(self.err(format!(
                    "skin {}: {} inverse bind matrices for {} joints",
                    skin.index(),
                    inverse_bind.len(),
                    joints.len()
                )));
            }
            skins.push(Skin {
                joints,
                inverse_bind,
            });
        }
        if channels.is_empty() && self.rig.deformed.is_empty() {
            return Ok(());
        }
        let mut rig = std::mem::take(&mut self.rig);
        rig.channels = channels;
        rig.skins = skins;
        self.scene.animation = Some(std::sync::Arc::new(Animation {
            rig: Some(rig),
            clips: doc.animations().count(),
            ..Default::default()
        }));
        self.scene.pose(None);
        Ok(())
    }

    /// A `MAT4` float accessor (inverse bind matrices), column-major.
    fn read_matrices(&self, acc: &gltf::Accessor, what: &str) -> Result<Vec<Mat4>, SceneError> {
        if acc.dimensions() != Dimensions::Mat4 || acc.data_type() != DataType::F32 {
            return Err(self.err(format!(
                "{what}: inverse bind matrices must be float MAT4 (accessor {})",
                acc.index()
            )));
        }
        let count = acc.count();
        if count > MAX_ACCESSOR_COUNT / 4 {
            return Err(self.err(format!("{what}: absurd matrix count ({count})")));
        }
        let Some(view) = acc.view() else {
            return Ok(vec![Mat4::ZERO; count]);
        };
        if view.stride().is_some_and(|s| s != 64) {
            return Err(self.err(format!(
                "{what}: inverse bind matrices must be tightly packed"
            )));
        }
        let mut cols = Vec::new();
        // Four columns of four floats per matrix, tightly packed (a view used by matrices has
        // no byte stride, glTF 2.0 §3.6.2.4).
        self.read_elements_packed(&view, acc.offset(), count * 4, &mut cols, what)?;
        Ok(cols
            .chunks_exact(4)
            .map(|c| {
                let f = |i: usize| c[i].map(|x| x as f32);
                Mat4::from_cols_array_2d(&[f(0), f(1), f(2), f(3)])
            })
            .collect())
    }

    fn read_elements_packed(
        &self,
        view: &gltf::buffer::View,
        offset: usize,
        count: usize,
        out: &mut Vec<[f64; 4]>,
        what: &str,
    ) -> Result<(), SceneError> {
        let data = self.view_bytes(view)?;
        let needed = count.checked_mul(16).and_then(|n| n.checked_add(offset));
        if needed.is_none_or(|n| n > data.len()) {
            return Err(self.err(format!(
                "{what}: {} matrices at offset {offset} do not fit in buffer view {}",
                count / 4,
                view.index()
            )));
        }
        out.reserve(count);
        for i in 0..count {
            let b = offset + i * 16;
            let mut e = [0.0f64; 4];
            for (c, v) in e.iter_mut().enumerate() {
                let p = b + 4 * c;
                *v = f32::from_le_bytes([data[p], data[p + 1], data[p + 2], data[p + 3]]) as f64;
            }
            out.push(e);
        }
        Ok(())
    }
}
