//! The node hierarchy flattened with world transforms, perspective cameras and
//! `KHR_lights_punctual` lights.

use super::*;
use crate::scene::animation::Placed;

impl Loader<'_> {
    pub(super) fn nodes(&mut self) -> Result<(), SceneError> {
        let doc = self.doc;
        let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
            Some(s) => s.nodes().collect(),
            None => {
                // No scene: render every node that is nobody's child.
                let children: HashSet<usize> = doc
                    .nodes()
                    .flat_map(|n| n.children().map(|c| c.index()).collect::<Vec<_>>())
                    .collect();
                doc.nodes()
                    .filter(|n| !children.contains(&n.index()))
                    .collect()
            }
        };
        if doc.scenes().count() > 1 {
            self.scene.warnings.push(format!(
                "the file has {} scenes; only the default one is rendered",
                doc.scenes().count()
            ));
        }
        let mut visited = HashSet::new();
        let mut stack: Vec<(gltf::Node, Mat4, Option<usize>)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, Mat4::IDENTITY, None))
            .collect();
        while let Some((node, parent, parent_index)) = stack.pop() {
            if !visited.insert(node.index()) {
                // A node reached twice is a cycle or a shared child, both invalid glTF.
                self.warn_once(
                    "revisit",
                    format!(
                        "node {} is reached more than once (invalid hierarchy); later visits are ignored",
                        node.index()
                    ),
                );
                continue;
            }
            let local = Mat4::from_cols_array_2d(&node.transform().matrix());
            let world = parent * local;
            let node_name = node
                .name()
                .map(str::to_string)
                .unwrap_or_else(|| format!("node {}", node.index()));
            self.rig_visit(&node, parent_index);
            if let Some(mesh) = node.mesh() {
                // Instance placements relative to the node, so posing can move the node.
                let locals = self.gpu_instances(&node)?;
                // Skinned meshes and meshes with morph targets get a copy per node: each node
                // poses its own vertices (animation.rs).
                let deforms = node.skin().is_some()
                    || mesh
                        .primitives()
                        .any(|p| p.morph_targets().next().is_some());
                for prim in mesh.primitives() {
                    let built = if deforms {
                        self.deformed_primitive(&node, &mesh, &prim)?
                    } else {
                        self.primitive(&mesh, &prim)?
                    };
                    if let Some((mesh_id, material)) = built {
                        for &local in &locals {
                            self.scene.add_object(
                                &node_name,
                                Shape::Mesh(mesh_id),
                                if local == Mat4::IDENTITY {
                                    world
                                } else {
                                    world * local
                                },
                                material,
                            );
                            let object = self.scene.objects.len() - 1;
                            self.rig_place(&node, Placed::Object { object, local });
                            self.primitive_variants(&prim, object, material)?;
                        }
                    }
                }
            }
            if let Some(cam) = node.camera() {
                let before = self.scene.cameras.len();
                self.camera(&cam, &node_name, world);
                if self.scene.cameras.len() > before {
                    self.rig_place(&node, Placed::Camera(before));
                }
            }
            if let Some(light) = node.light() {
                let before = self.scene.lights.len();
                self.light(&light, &node_name, world);
                if self.scene.lights.len() > before {
                    self.rig_place(&node, Placed::Light(before));
                }
            }
            for c in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((c, world, Some(node.index())));
            }
        }
        Ok(())
    }

    /// Where a node's mesh is placed relative to the node: once, or with
    /// `EXT_mesh_gpu_instancing` once per instance at the instance's translation,
    /// rotation and scale (the extension's TRS, composed as a node's). The objects share the
    /// mesh, so the world can instance them (docs/DESIGN.md §6).
    fn gpu_instances(&mut self, node: &gltf::Node) -> Result<Vec<Mat4>, SceneError> {
        const EXT: &str = "EXT_mesh_gpu_instancing";
        let Some(ext) = node.extension_value(EXT) else {
            return Ok(vec![Mat4::IDENTITY]);
        };
        let attributes = ext.get("attributes").and_then(|a| a.as_object());
        let read = |name: &str| -> Result<Option<Vec<[f64; 4]>>, SceneError> {
            let Some(index) = attributes
                .and_then(|a| a.get(name))
                .and_then(|v| v.as_u64())
            else {
                return Ok(None);
            };
            let Some(acc) = self.doc.accessors().nth(index as usize) else {
                return Err(self.err(format!("{EXT} {name}: there is no accessor {index}")));
            };
            Ok(Some(self.read_accessor(&acc, &format!("{EXT} {name}"))?.0))
        };
        let (t, r, s) = (read("TRANSLATION")?, read("ROTATION")?, read("SCALE")?);
        let counts: Vec<usize> = [&t, &r, &s]
            .iter()
            .filter_map(|v| v.as_ref())
            .map(Vec::len)
            .collect();
        let Some(&n) = counts.first() else {
            self.scene.warnings.push(format!(
                "node {}: {EXT} has no TRANSLATION, ROTATION or SCALE; the mesh is placed once",
                node.index()
            ));
            return Ok(vec![Mat4::IDENTITY]);
        };
        if counts.iter().any(|&c| c != n) {
            return Err(self.err(format!(
                "node {}: {EXT} attributes have different counts ({counts:?})",
                node.index()
            )));
        }
        let v3 = |v: &Option<Vec<[f64; 4]>>, i: usize, default: Vec3| {
            v.as_ref().map_or(default, |v| {
                Vec3::new(v[i][0] as f32, v[i][1] as f32, v[i][2] as f32)
            })
        };
        let mut bad_rotation = false;
        let placements = (0..n)
            .map(|i| {
                let q = r.as_ref().map_or(glam::Quat::IDENTITY, |r| {
                    let [x, y, z, w] = r[i].map(|c| c as f32);
                    let q = glam::Quat::from_xyzw(x, y, z, w);
                    let len = q.length();
                    if len > 0.0 && len.is_finite() {
                        q / len
                    } else {
                        bad_rotation = true;
                        glam::Quat::IDENTITY
                    }
                });
                Mat4::from_scale_rotation_translation(
                    v3(&s, i, Vec3::ONE),
                    q,
                    v3(&t, i, Vec3::ZERO),
                )
            })
            .collect();
        if bad_rotation {
            self.scene.warnings.push(format!(
                "node {}: {EXT} has rotations that are not quaternions (zero or not finite); \
                 those instances are not rotated",
                node.index()
            ));
        }
        Ok(placements)
    }

    pub(super) fn camera(&mut self, cam: &gltf::Camera, node_name: &str, world: Mat4) {
        let name = cam.name().unwrap_or(node_name).to_string();
        // Cameras ignore scale: keep the rotation and the position only.
        let rigid = crate::scene::animation::rigid;
        match cam.projection() {
            gltf::camera::Projection::Perspective(p) => {
                self.scene.cameras.push(CameraDesc {
                    name,
                    camera_to_world: rigid(world),
                    vfov_deg: p.yfov().to_degrees(),
                    aspect: p.aspect_ratio(),
                    fit: crate::scene::SensorFit::Auto,
                    aperture_radius: 0.0,
                    focus_distance: 1.0,
                    projection: crate::scene::Projection::Perspective,
                });
            }
            gltf::camera::Projection::Orthographic(o) => {
                // glTF: `xmag`/`ymag` are half the view's width and height in scene units (the
                // spec forbids zero; their sign carries no meaning, so it is dropped).
                let (xmag, ymag) = (o.xmag().abs(), o.ymag().abs());
                if !(xmag > 0.0 && ymag > 0.0 && xmag.is_finite() && ymag.is_finite()) {
                    self.scene.warnings.push(format!(
                        "camera '{name}' is orthographic with xmag {} and ymag {}, which cannot \
                         frame a view; it is skipped",
                        o.xmag(),
                        o.ymag()
                    ));
                    return;
                }
                self.scene.cameras.push(CameraDesc {
                    name,
                    camera_to_world: rigid(world),
                    // Not used by the projection; the angle that frames the same height at unit
                    // distance, for front ends that show a perspective view of it.
                    vfov_deg: (2.0 * ymag.atan().to_degrees()).clamp(1.0, 170.0),
                    aspect: Some(xmag / ymag),
                    fit: crate::scene::SensorFit::Auto,
                    aperture_radius: 0.0,
                    focus_distance: 1.0,
                    projection: crate::scene::Projection::Orthographic { half_height: ymag },
                });
            }
        }
    }

    pub(super) fn light(
        &mut self,
        light: &gltf::khr_lights_punctual::Light,
        node_name: &str,
        world: Mat4,
    ) {
        use gltf::khr_lights_punctual::Kind;
        let name = light.name().unwrap_or(node_name).to_string();
        let color = Vec3::from(light.color());
        if is_ambient_light_name(&name) || is_ambient_light_name(node_name) {
            // The thesis's convention (Annex B): an ambient light of that light's colour.
            self.scene.lights.push(ambient_light(&name, color));
            self.scene.warnings.push(format!(
                "convention: light '{name}' is an ambient light of its colour (name contains 'ambient')"
            ));
            return;
        }
        if light.range().is_some() {
            self.warn_once(
                "range",
                "KHR_lights_punctual 'range' is ignored: lights fall off with the inverse square of distance"
                    .into(),
            );
        }
        // docs/DESIGN.md §4: candela (lm/sr) and lux (lm/m²) / 683 lm/W → W/sr and W/m².
        let power = color * (light.intensity() / LUMENS_PER_WATT);
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let desc = match light.kind() {
            Kind::Point => LightDesc::Point {
                name,
                position,
                intensity: power,
            },
            Kind::Directional => LightDesc::Directional {
                name,
                direction,
                irradiance: power,
            },
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => LightDesc::Spot {
                name,
                position,
                direction,
                intensity: power,
                inner_angle: inner_cone_angle,
                outer_angle: outer_cone_angle,
                falloff: SpotFalloff::SquaredRamp,
            },
        };
        self.scene.lights.push(desc);
    }
}
