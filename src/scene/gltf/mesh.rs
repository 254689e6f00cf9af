//! Mesh primitives: positions, normals, tangents, texture coordinates and colours into [`Mesh`].

use super::*;

impl Loader<'_> {
    pub(super) fn primitive(
        &mut self,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
    ) -> Result<Option<(MeshId, MaterialId)>, SceneError> {
        let key = (mesh.index(), prim.index());
        if let Some(r) = self.meshes.get(&key) {
            return Ok(*r);
        }
        let mesh_name = mesh
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("mesh {}", mesh.index()));
        let r = self.build_primitive(&mesh_name, prim)?;
        self.meshes.insert(key, r);
        Ok(r)
    }

    pub(super) fn build_primitive(
        &mut self,
        mesh_name: &str,
        prim: &gltf::Primitive,
    ) -> Result<Option<(MeshId, MaterialId)>, SceneError> {
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.warn_once(
                &format!("mode {mode:?}"),
                format!("primitives of mode {mode:?} are not supported and are skipped"),
            );
            return Ok(None);
        }
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
            self.scene.warnings.push(format!(
                "mesh '{mesh_name}': a primitive without POSITION is skipped"
            ));
            return Ok(None);
        };
        // KHR_draco_mesh_compression: the listed attributes and the triangles come from the
        // Draco stream (draco.rs); the accessors only describe them.
        let mut draco = self.decode_draco(mesh_name, prim)?;
        let mut take = |this: &Self,
                        acc: &gltf::Accessor,
                        sem: &gltf::Semantic,
                        what: &str|
         -> Result<(Vec<[f64; 4]>, usize), SceneError> {
            if let Some(v) = draco
                .as_mut()
                .and_then(|d| d.attributes.remove(&sem.to_string()))
            {
                return Ok(v);
            }
            this.read_accessor(acc, what)
        };
        let vec3 = |v: Vec<[f64; 4]>| -> Vec<Vec3> {
            v.iter()
                .map(|e| Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32))
                .collect()
        };
        let what = format!("mesh '{mesh_name}' POSITION");
        let positions = vec3(take(self, &pos_acc, &gltf::Semantic::Positions, &what)?.0);
        let n = positions.len();
        let mut m = Mesh {
            name: mesh_name.to_string(),
            positions,
            ..Default::default()
        };
        for (sem, acc) in prim.attributes() {
            use gltf::Semantic as S;
            match sem {
                S::Positions => {}
                S::Normals => m.normals = Some(vec3(take(self, &acc, &sem, "NORMAL")?.0)),
                S::Tangents => {
                    let (v, _) = take(self, &acc, &sem, "TANGENT")?;
                    m.tangents = Some(
                        v.iter()
                            .map(|e| Vec4::new(e[0] as f32, e[1] as f32, e[2] as f32, e[3] as f32))
                            .collect(),
                    );
                }
                S::TexCoords(k @ (0 | 1)) => {
                    let (v, _) = take(self, &acc, &sem, &format!("TEXCOORD_{k}"))?;
                    let uv = Some(
                        v.iter()
                            .map(|e| Vec2::new(e[0] as f32, e[1] as f32))
                            .collect(),
                    );
                    if k == 0 {
                        m.uv0 = uv;
                    } else {
                        m.uv1 = uv;
                    }
                }
                S::Colors(0) => {
                    let (v, nc) = take(self, &acc, &sem, "COLOR_0")?;
                    m.colors = Some(
                        v.iter()
                            .map(|e| {
                                let a = if nc == 4 { e[3] as f32 } else { 1.0 };
                                Vec4::new(e[0] as f32, e[1] as f32, e[2] as f32, a)
                            })
                            .collect(),
                    );
                }
                S::Joints(_) | S::Weights(_) => {}
                other => {
                    self.warn_once(
                        &format!("attr {other:?}"),
                        format!("vertex attribute {other:?} is not supported and is ignored"),
                    );
                }
            }
        }
        let idx: Vec<u32> = match (draco.map(|d| d.indices), prim.indices()) {
            // Draco streams hold triangles whatever the primitive's mode says.
            (Some(tris), _) => {
                m.indices = tris.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
                return Ok(Some((
                    self.scene.add_mesh(m),
                    self.primitive_material(mesh_name, prim)?,
                )));
            }
            (None, Some(acc)) => self.read_indices(&acc)?,
            (None, None) => (0..n as u32).collect(),
        };
        let tri = |a: u32, b: u32, c: u32| [a, b, c];
        m.indices = match mode {
            Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
                .map(|i| {
                    // glTF §3.7.2.1: p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}} keeps the winding.
                    tri(idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2])
                })
                .collect(),
            Mode::TriangleFan => (0..idx.len().saturating_sub(2))
                .map(|i| tri(idx[i + 1], idx[i + 2], idx[0]))
                .collect(),
            _ => {
                if !idx.len().is_multiple_of(3) {
                    self.scene.warnings.push(format!(
                        "mesh '{mesh_name}': {} indices is not a multiple of 3; the extra ones are ignored",
                        idx.len()
                    ));
                }
                idx.chunks_exact(3).map(|c| tri(c[0], c[1], c[2])).collect()
            }
        };
        let material = self.primitive_material(mesh_name, prim)?;
        let id = self.scene.add_mesh(m);
        Ok(Some((id, material)))
    }

    fn primitive_material(
        &mut self,
        mesh_name: &str,
        prim: &gltf::Primitive,
    ) -> Result<MaterialId, SceneError> {
        Ok(match prim.material().index() {
            Some(i) if i < self.scene.materials.len() => i,
            Some(i) => {
                return Err(self.err(format!(
                    "mesh '{mesh_name}' references material {i}, which does not exist"
                )));
            }
            None => self.default_material(),
        })
    }

    // ---------------------------------------------------------------- node hierarchy
}
