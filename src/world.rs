//! The render-time world: the scene description compiled into world-space primitives, an
//! accelerator, materials, textures, lights and the chosen camera.

use crate::accel::{Accel, AccelKind};
use crate::geometry::cuboid::Cuboid;
use crate::geometry::instance::{Instance, SharedMesh};
use crate::geometry::primitive::{
    AnalyticPrim, Intersection, MeshAttributes, NO_LIGHT, SurfaceHit,
};
use crate::geometry::quad::Quad;
use crate::geometry::sphere::Sphere;
use crate::geometry::triangle::TriangleVerts;
use crate::geometry::{Bounds3, GeometryStore, PrimRef, PrimitiveKind, Ray};
use crate::light::default_light::{self, DefaultLight};
use crate::light::{
    AreaLight, DirectionalLight, EnvMap, EnvironmentLight, Light, LightSet, PointLight, SpotLight,
    UniformLight,
};
use crate::material::{AlphaMode, Material, Texture};
use crate::math::{Mat3, Vec2, Vec3, Vec4, transform_normal};
use crate::scene::{CameraDesc, LightDesc, Scene, SceneError, Shape};
use std::sync::Arc;

/// Options that shape the world but are not part of the scene file.
#[derive(Clone, Debug, Default)]
pub struct WorldOptions {
    pub accel: AccelKind,
    /// `--camera NAME|INDEX`.
    pub camera: Option<String>,
    /// `--default-light auto|on|off`; `None` defers to the scene file (TOML `default_light`),
    /// then to `auto`. The rule is in [`crate::light::default_light`].
    pub default_light: Option<DefaultLight>,
    /// `--env FILE`: an equirectangular environment map lighting the scene.
    pub env: Option<std::path::PathBuf>,
    /// `--env-rotation DEGREES`: the `--env` map turned about the up axis (+y), counter-clockwise
    /// seen from above, as TOML `[background] rotation` does.
    pub env_rotation: f32,
    /// `--camera-from FILE`, the web viewport's `camera`: render from this view instead of the
    /// scene's cameras (not with `camera`).
    pub camera_override: Option<crate::camera::CameraSpec>,
    /// `--variant NAME`: the glTF material variant to render (`KHR_materials_variants`), applied
    /// to the loaded scene by [`crate::scene::Scene::select_variant`]; `None` is the file's
    /// default materials.
    pub variant: Option<String>,
    /// `--light-sampler auto|power|bvh`: how next-event estimation chooses a light.
    pub light_sampler: crate::light::LightSamplerKind,
    /// `--texture-filter none|trilinear`: `trilinear` builds MIP pyramids of the image
    /// textures and reads them over each hit's pixel footprint; `none` (the default) keeps
    /// the textures' own unfiltered lookups.
    pub texture_filter: crate::material::texture::TextureFilter,
    /// When objects sharing a mesh become instances of one copy (a two-level BVH) instead of
    /// being flattened into world-space triangles each.
    pub instancing: Instancing,
    /// `--time`, `--frame`, `--fps`, `--shutter`: the moment of an animated scene to render and
    /// the motion blur interval ([`motion`]).
    pub time: motion::TimeOptions,
}

/// When objects that share a mesh are instanced (docs/DESIGN.md §5): the images are the same
/// either way; instancing saves the memory of the copies at some traversal cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Instancing {
    /// Instance a mesh when several objects use it and their copies would hold at least
    /// [`AUTO_INSTANCE_TRIANGLES`] triangles; ordinary scenes stay flat.
    #[default]
    Auto,
    /// Instance every mesh object that can be (for tests and measurements).
    Always,
    /// Flatten everything.
    Never,
}

/// Copies of one mesh, in triangles, from which [`Instancing::Auto`] instances it: about
/// 150 MB of flattened triangles, attributes and BVH (~150 bytes a triangle).
pub const AUTO_INSTANCE_TRIANGLES: usize = 1 << 20;

pub struct World {
    pub geometry: GeometryStore,
    pub accel: Accel,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub lights: LightSet,
    pub camera: CameraDesc,
    pub bounds: Bounds3,
    /// Warnings produced while compiling (in addition to the scene's own).
    pub warnings: Vec<String>,
    /// Time spent building the acceleration structure (for the phase report).
    pub accel_build_time: std::time::Duration,
    /// Participating media and the medium interfaces of surfaces.
    pub media: crate::medium::world::WorldMedia,
    /// The spectra BSDFs name by id for spectral rendering (sampled η and k; the named metals and
    /// glasses are built in): [`crate::material::Bsdf::make_spectral`].
    pub bsdf_spectra: crate::spectrum::BsdfSpectra,
    /// Per material: true if its alpha mode is MASK or BLEND, so a hit on it may be a hole.
    cutout: Vec<bool>,
    /// True if any material is a cutout; opaque scenes skip the alpha test entirely.
    has_cutouts: bool,
    /// `WorldOptions::texture_filter`: with `Trilinear` the textures carry MIP pyramids and
    /// renders give the path tracers the camera's [`crate::camera::Footprint`].
    pub texture_filter: crate::material::texture::TextureFilter,
    /// True if a material bump-maps (pbrt-v4 `displacement`): its finite differences are taken
    /// over the pixel footprint, so renders give the path tracers the camera's footprint even
    /// without `--texture-filter trilinear` (`eval::bump`).
    pub has_bump: bool,
    /// Motion blur that moving primitives' keys do not cover (`GeometryStore::motion` does the
    /// rest): the scene posed at the shutter's time steps, one world each; a camera sample
    /// draws its time and traces the world of its step ([`motion`]). Empty for a still and
    /// for continuous motion.
    pub motion: Vec<World>,
    /// Motion blur of a moving camera: its transform at a sample's time ([`motion`]). `None`
    /// when the camera does not move.
    pub camera_motion: Option<motion::CameraMotion>,
}

/// Rays pass through at most this many cut-out surfaces; beyond it the next surface counts as
/// opaque, so a pathological stack of holes cannot loop for ever.
const MAX_CUTOUT_LAYERS: u32 = 256;

impl World {
    /// Whether hits need the camera's pixel footprint: filtered (trilinear) texture lookups and
    /// bump maps take their differences over it, so the drivers hand it to the integrators.
    #[inline]
    pub fn needs_footprint(&self) -> bool {
        self.texture_filter == crate::material::texture::TextureFilter::Trilinear || self.has_bump
    }

    /// Compiles `scene` for rendering. The scene is consumed: its materials and textures move
    /// into the world instead of being copied. The scene must be valid: `scene::load` validated
    /// it (the one place, docs/DESIGN.md §3; `Scene::select_variant` keeps it valid), and a scene
    /// built in code is checked with `Scene::validate` before it comes here. Debug builds check
    /// again, so a test that builds an invalid scene by hand fails here rather than deeper.
    pub fn build(scene: Scene, options: &WorldOptions) -> Result<World, SceneError> {
        Self::build_with_motion(scene, options, None, Vec::new())
    }

    /// [`World::build`] with the keys of the primitives that move during the shutter
    /// ([`motion`]): its mesh and sphere slots follow the order [`compile_geometry`] gives the
    /// flattened meshes and spheres; the moving primitives go to their own BVH. `light_motion`
    /// holds the scene's moving lights (index in `Scene::lights`, position and direction per key,
    /// [`crate::light::set::LightMotion`]).
    fn build_with_motion(
        mut scene: Scene,
        options: &WorldOptions,
        motion: Option<crate::geometry::motion::MotionStore>,
        light_motion: Vec<(usize, Vec<(Vec3, Vec3)>)>,
    ) -> Result<World, SceneError> {
        debug_assert!(
            scene.validate().is_ok(),
            "World::build got an invalid scene: {:?}",
            scene.validate()
        );
        let label = scene
            .source
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| scene.name.clone());
        let mut warnings = Vec::new();
        // Objects that bound media get their own material index (see medium::world); scenes
        // without medium interfaces are left exactly as they are.
        let media = crate::medium::world::assign(&mut scene)
            .map_err(|e| SceneError::invalid(&label, format!("medium grid: {e}")))?;
        let mut g = compile_geometry(&scene, &label, options.instancing, &mut warnings)?;
        // Moving instances keep their transform's keys with the instances (the two-level
        // hierarchy places each at a ray's time, `accel::instance`); the per-segment BVHs are
        // for moving meshes, spheres and quads.
        let motion = motion
            .map(|mut m| {
                let keys = std::mem::take(&mut m.instance_motion);
                if keys.iter().any(Option::is_some) {
                    debug_assert_eq!(keys.len(), g.instances.instances.len());
                    let store = &mut g.instances;
                    for (inst, keys) in store.instances.iter_mut().zip(keys) {
                        if let Some(keys) = keys {
                            inst.motion = store.motion.len() as u32;
                            store.motion.push(keys);
                        }
                    }
                }
                m
            })
            .filter(|m| m.prims_move());
        if let Some(m) = motion {
            debug_assert_eq!(m.mesh_slot.len(), g.meshes.len());
            debug_assert_eq!(m.sphere_slot.len(), g.spheres.len());
            debug_assert_eq!(m.quad_slot.len(), g.quads.len());
            debug_assert_eq!(m.cuboid_slot.len(), g.cuboids.len());
            g.moving_prims = (0..g.triangles.len())
                .filter(|&i| m.mesh(g.tri_mesh[i].0).is_some())
                .map(|i| PrimRef::new(PrimitiveKind::Triangle, i as u32))
                .chain(
                    (0..g.spheres.len())
                        .filter(|&i| m.sphere_slot[i] != crate::geometry::motion::STILL)
                        .map(|i| PrimRef::new(PrimitiveKind::Sphere, i as u32)),
                )
                .chain(
                    (0..g.cuboids.len())
                        .filter(|&i| m.cuboid_slot[i] != crate::geometry::motion::STILL)
                        .map(|i| PrimRef::new(PrimitiveKind::Cuboid, i as u32)),
                )
                // In `PrimRef` order (spheres, boxes, quads): `static_prims` needs it.
                .chain(
                    (0..g.quads.len())
                        .filter(|&i| m.quad_slot[i] != crate::geometry::motion::STILL)
                        .map(|i| PrimRef::new(PrimitiveKind::Quad, i as u32)),
                )
                .collect();
            g.motion = Some(Box::new(m));
        }
        let (mut lights, footprint_means) = area_lights(&mut g, &scene.materials, &scene.textures);
        // Each light's emission spectrum, when it was given one: area lights their material's,
        // the scene's lights theirs (`Scene::light_spectra`), the lights added below none.
        let mut spectra: Vec<Option<crate::spectrum::Illuminant>> = lights
            .iter()
            .map(|l| match l {
                Light::Area(a) => scene.materials[a.material as usize]
                    .emission_spectrum
                    .clone(),
                _ => None,
            })
            .collect();
        let first_scene_light = spectra.len();
        spectra.resize(first_scene_light + scene.lights.len(), None);
        for (i, s) in &scene.light_spectra {
            if let Some(slot) = spectra.get_mut(first_scene_light + i) {
                *slot = Some(s.clone());
            }
        }
        lights.extend(scene_lights(&scene, &label)?);
        let studio = add_option_lights(&mut lights, &scene, &g, options, &mut warnings)?;
        let bounds = g.scene_bounds();
        let accel_start = std::time::Instant::now();
        let accel = Accel::build(options.accel, &g);
        let accel_build_time = accel_start.elapsed();
        let camera = choose_camera(&scene, options, bounds, &accel, &g, &label)?;
        if studio {
            // Turned to the view (light::studio), so it waits for the camera.
            let map = crate::light::studio::studio_environment(&camera.camera_to_world);
            lights.push(Light::Environment(EnvironmentLight { map: Arc::new(map) }));
        }
        let Scene {
            materials,
            mut textures,
            ..
        } = scene;
        // MIP pyramids (they read level 0 row-major), then every level stored in cache-line
        // tiles (`TexelLayout`), in one parallel pass over the textures. Lookups from here on
        // read them tiled; the light estimates below see the same values (lookups return the same
        // bits in either layout, `Texture::average` sums row by row in both).
        {
            use rayon::prelude::*;
            let mips = options.texture_filter == crate::material::texture::TextureFilter::Trilinear;
            // pbrt-v4 reads a bump map's displacement texture through its MIP pyramid at the
            // pixel footprint (`BumpMap` evaluates it at three footprint-sized shifts), so those
            // textures get pyramids whatever the option says.
            let mut bump = vec![false; textures.len()];
            for m in &materials {
                if let Some(t) = &m.displacement {
                    bump[t.texture] = true;
                }
            }
            textures.par_iter_mut().zip(bump).for_each(|(t, bump)| {
                if mips || bump {
                    t.build_mips();
                }
                t.tile();
            });
        }
        let mut lights = LightSet::new(
            lights,
            &g,
            &materials,
            &textures,
            bounds,
            &footprint_means,
            options.light_sampler,
        );
        lights.set_spectra(&spectra);
        if let Some(keys) = light_motion.first().map(|(_, k)| k.len()) {
            // The scene's lights follow the area lights (`first_scene_light`) in the set.
            let mut m = crate::light::set::LightMotion {
                keys,
                slot: vec![u32::MAX; lights.lights.len()],
                poses: Vec::with_capacity(keys * light_motion.len()),
            };
            for (i, poses) in &light_motion {
                debug_assert_eq!(poses.len(), keys);
                m.slot[first_scene_light + i] = (m.poses.len() / keys) as u32;
                m.poses.extend_from_slice(poses);
            }
            lights.set_motion(m, &g, &materials);
        }
        let cutout: Vec<bool> = materials
            .iter()
            .map(|m| m.alpha_mode != AlphaMode::Opaque)
            .collect();
        let has_cutouts = cutout.iter().any(|&c| c);
        let has_bump = materials.iter().any(|m| m.displacement.is_some());
        Ok(World {
            geometry: g,
            accel,
            materials,
            textures,
            lights,
            media,
            bsdf_spectra: crate::spectrum::BsdfSpectra {
                tables: scene.bsdf_spectra.clone().into(),
            },
            camera,
            bounds,
            warnings,
            accel_build_time,
            cutout,
            has_cutouts,
            texture_filter: options.texture_filter,
            has_bump,
            motion: Vec::new(),
            camera_motion: None,
        })
    }

    /// Changes the scene's light `index` (in `Scene::lights` order) to `desc` in place, the
    /// geometry and its BVH kept: a front end that changes a light's power or colour renders
    /// the world [`World::build`] would make of the changed scene without building it again.
    /// Only the light selection (over lights, not triangles) is redone. Returns `false`, the
    /// world unchanged, when the light cannot be changed this way: an environment map (its
    /// sampling densities come from the texels and the scale), a change of kind, or a light
    /// that moves during the shutter (its keys were posed from the animation, not from `desc`).
    pub fn set_scene_light(&mut self, index: usize, desc: &LightDesc) -> bool {
        if matches!(desc, LightDesc::Environment { .. }) {
            return false;
        }
        // The compiled lights are the area lights, then the scene's in order (`build`).
        let area = self
            .lights
            .lights
            .iter()
            .take_while(|l| matches!(l, Light::Area(_)))
            .count();
        let Ok(light) = scene_light(desc, "") else {
            return false;
        };
        if self.lights.light_moves(area + index) {
            return false;
        }
        let same_kind = self
            .lights
            .lights
            .get(area + index)
            .is_some_and(|old| std::mem::discriminant(old) == std::mem::discriminant(&light));
        if !same_kind
            || !self
                .motion
                .iter_mut()
                .all(|w| w.set_scene_light(index, desc))
        {
            return false;
        }
        self.lights
            .replace(area + index, light, &self.geometry, &self.materials);
        true
    }

    /// The first surface along `ray`, with its shading attributes. Cut-out (alpha) holes are
    /// skipped, see [`World::intersect_raw`].
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        let isect = self.candidate(ray)?;
        let mut hit = SurfaceHit::EMPTY;
        self.complete_into(ray, isect, &mut hit).then_some(hit)
    }

    /// The accelerator's closest hit along `ray`, cut-out holes not yet skipped: `None` means
    /// the ray leaves the scene. [`World::complete_into`] finishes it. A caller that would
    /// have to set up storage for the hit first can ask this before (a missed camera ray then
    /// costs no set-up).
    #[inline]
    pub fn candidate(&self, ray: &Ray) -> Option<Intersection> {
        self.accel.intersect(&self.geometry, ray)
    }

    /// Finishes the [`World::candidate`] `isect` of `ray` into `hit` (every field): skips cut-out
    /// holes, then expands the hit; `false` (and `hit` unspecified) when only holes were found.
    /// Written in place so the path tracer keeps one hit's storage along a path instead of
    /// moving 144-byte hits (each move a `memcpy` call).
    #[inline]
    pub fn complete_into(&self, ray: &Ray, isect: Intersection, hit: &mut SurfaceHit) -> bool {
        if !self.has_cutouts {
            self.geometry.surface_hit_into(ray, &isect, hit);
            return true;
        }
        let Some((isect, alpha_tested)) = self.skip_cutouts(ray, isect) else {
            return false;
        };
        // A cut-out surface that turned out to be there was already expanded for its alpha test.
        match alpha_tested {
            Some(tested) => {
                *hit = tested;
                hit.t = isect.t;
            }
            None => self.geometry.surface_hit_into(ray, &isect, hit),
        }
        true
    }

    /// [`World::intersect`], with the hit's uv derivatives ([`SurfaceHit::duv`]) set from the
    /// camera `footprint` when it is on, for filtered texture lookups.
    #[inline]
    pub fn intersect_filtered(
        &self,
        ray: &Ray,
        footprint: &crate::camera::Footprint,
    ) -> Option<SurfaceHit> {
        let mut hit = SurfaceHit::EMPTY;
        self.intersect_filtered_into(ray, footprint, &mut hit)
            .then_some(hit)
    }

    /// [`World::intersect_filtered`] written into `hit`, as [`World::complete_into`] writes it.
    #[inline]
    pub fn intersect_filtered_into(
        &self,
        ray: &Ray,
        footprint: &crate::camera::Footprint,
        hit: &mut SurfaceHit,
    ) -> bool {
        match self.candidate(ray) {
            Some(isect) => self.complete_filtered_into(ray, isect, footprint, hit),
            None => false,
        }
    }

    /// [`World::intersect_filtered_into`] from the [`World::candidate`] `isect` of `ray`.
    #[inline]
    pub fn complete_filtered_into(
        &self,
        ray: &Ray,
        isect: Intersection,
        footprint: &crate::camera::Footprint,
        hit: &mut SurfaceHit,
    ) -> bool {
        if !self.complete_into(ray, isect, hit) {
            return false;
        }
        if let Some((dpdx, dpdy)) = footprint.dp_dxy(hit.p, hit.ng) {
            hit.duv = self.geometry.uv_derivatives(hit, dpdx, dpdy);
        }
        true
    }

    /// The first surface along `ray` that is not a hole of an alpha-masked or alpha-blended
    /// material. `t` is in the parameter of `ray` even when holes were passed through.
    #[inline]
    pub fn intersect_raw(&self, ray: &Ray) -> Option<Intersection> {
        let isect = self.accel.intersect(&self.geometry, ray)?;
        if !self.has_cutouts {
            return Some(isect);
        }
        self.skip_cutouts(ray, isect).map(|(isect, _)| isect)
    }

    /// True if something opaque lies on `ray` before `ray.t_max`.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        if !self.has_cutouts {
            return self.accel.occluded(&self.geometry, ray);
        }
        // Any-hit traversal cannot evaluate textures, so walk the hits in order instead.
        self.intersect_raw(ray).is_some()
    }

    /// Continues `ray` through cut-out holes until it meets a surface that is there.
    ///
    /// glTF alpha modes (glTF 2.0 §3.9.4): MASK keeps the surface where alpha ≥ alphaCutoff;
    /// BLEND is rendered as stochastic transparency (Enderton et al. 2010): the surface is present
    /// with probability alpha, decided by a hash of the ray and the hit so that the expected
    /// radiance, and the expected shadow-ray transmittance 1 − alpha, are exact without keeping
    /// per-ray sampler state here.
    ///
    /// Returns the hit with `t` in `ray`'s parameter and, when that surface is itself a cut-out
    /// material, the shading attributes its alpha test computed (with `t` still along the last
    /// continuation ray), so the caller need not compute them again.
    fn skip_cutouts(
        &self,
        ray: &Ray,
        mut isect: Intersection,
    ) -> Option<(Intersection, Option<SurfaceHit>)> {
        let mut current = *ray;
        // Parameter of `current`'s origin along the original ray.
        let mut t_offset = 0.0f32;
        let d2 = ray.d.length_squared();
        for _ in 0..MAX_CUTOUT_LAYERS {
            let material = self.geometry.material(isect.prim) as usize;
            if !self.cutout[material] {
                isect.t += t_offset;
                return Some((isect, None));
            }
            let hit = self.geometry.surface_hit(&current, &isect);
            let m = &self.materials[material];
            let alpha = crate::material::eval::opacity(m, &self.textures, &hit);
            let present = match m.alpha_mode {
                AlphaMode::Mask => alpha >= m.alpha_cutoff,
                _ => alpha >= 1.0 || cutout_hash(&current, isect.t) < alpha,
            };
            if present {
                isect.t += t_offset;
                return Some((isect, Some(hit)));
            }
            // Step through the hole: respawn on the far side with the remaining extent.
            let mut next = Ray::spawn(hit.p, hit.p_error, hit.ng, ray.d).with_time(ray.time);
            t_offset = (next.o - ray.o).dot(ray.d) / d2;
            if ray.t_max.is_finite() {
                next.t_max = ray.t_max - t_offset;
                if !(next.t_max > 0.0) {
                    return None;
                }
            }
            current = next;
            isect = self.accel.intersect(&self.geometry, &current)?;
        }
        isect.t += t_offset;
        Some((isect, None))
    }

    /// Triangles in the world, an instanced mesh's counted once per instance.
    pub fn triangle_count(&self) -> usize {
        self.geometry.triangles.len() + self.geometry.instances.triangle_count()
    }

    pub fn primitive_count(&self) -> usize {
        self.geometry.len()
    }

    pub fn area_light_count(&self) -> usize {
        self.lights
            .lights
            .iter()
            .filter(|l| l.as_area().is_some())
            .count()
    }

    /// Count of area lights that are triangles (for reports).
    pub fn emissive_triangle_count(&self) -> usize {
        self.lights
            .lights
            .iter()
            .filter(|l| matches!(l.as_area(), Some(a) if a.prim.kind() == PrimitiveKind::Triangle))
            .count()
    }

    pub fn prim_ref(kind: PrimitiveKind, index: u32) -> PrimRef {
        PrimRef::new(kind, index)
    }
}

/// Step 1: every object's shape in world space (meshes transformed and flattened, analytic
/// shapes placed), each tagged with its material.
fn compile_geometry(
    scene: &Scene,
    label: &str,
    instancing: Instancing,
    warnings: &mut Vec<String>,
) -> Result<GeometryStore, SceneError> {
    let mut g = GeometryStore::default();
    let instanced = instanced_objects(scene, instancing);
    charge_world_memory(scene, &instanced, label)?;
    // Shared meshes of the instances, by scene mesh.
    let mut shared: std::collections::HashMap<usize, u32> = Default::default();
    for (obj, &instance) in scene.objects.iter().zip(&instanced) {
        let m = obj.transform;
        let material = obj.material as u32;
        match &obj.shape {
            Shape::Mesh(mesh_id) if instance => {
                let store = &mut g.instances;
                let index = *shared.entry(*mesh_id).or_insert_with(|| {
                    let mesh = &scene.meshes[*mesh_id];
                    store.meshes.push(SharedMesh::new(
                        mesh.positions.clone(),
                        MeshAttributes {
                            indices: mesh.indices.clone(),
                            normals: mesh.normals.clone(),
                            tangents: mesh.tangents.clone(),
                            uv0: mesh.uv0.clone(),
                            uv1: mesh.uv1.clone(),
                            colors: mesh.colors.clone(),
                            material: 0,
                        },
                    ));
                    store.meshes.len() as u32 - 1
                });
                let shared_mesh = &store.meshes[index as usize];
                store
                    .instances
                    .push(Instance::new(shared_mesh, index, m, material));
            }
            Shape::Mesh(mesh_id) => {
                let mesh = &scene.meshes[*mesh_id];
                let inv = m.inverse();
                let flip = Mat3::from_mat4(m).determinant() < 0.0;
                let positions: Vec<Vec3> = mesh
                    .positions
                    .iter()
                    .map(|&p| m.transform_point3(p))
                    .collect();
                let mut attrs = MeshAttributes {
                    indices: Vec::with_capacity(mesh.indices.len()),
                    normals: mesh.normals.as_ref().map(|ns| {
                        ns.iter()
                            .map(|&n| transform_normal(&inv, n).normalize_or_zero())
                            .collect()
                    }),
                    tangents: mesh.tangents.as_ref().map(|ts| {
                        ts.iter()
                            .map(|t| {
                                let v = m.transform_vector3(t.truncate()).normalize_or_zero();
                                // Mirroring flips the bitangent's handedness.
                                Vec4::new(v.x, v.y, v.z, if flip { -t.w } else { t.w })
                            })
                            .collect()
                    }),
                    uv0: mesh.uv0.clone(),
                    uv1: mesh.uv1.clone(),
                    colors: mesh.colors.clone(),
                    material,
                };
                let mesh_index = g.meshes.len() as u32;
                let mut dropped = 0usize;
                for tri in &mesh.indices {
                    // A negative-determinant transform mirrors the mesh: swap two vertices so the
                    // counter-clockwise (front) winding is preserved.
                    let tri = if flip { [tri[0], tri[2], tri[1]] } else { *tri };
                    let verts = TriangleVerts {
                        p0: positions[tri[0] as usize],
                        p1: positions[tri[1] as usize],
                        p2: positions[tri[2] as usize],
                    };
                    // Finite object-space vertices can overflow under the transform; such a
                    // triangle cannot be bounded, so the BVH could never find it: drop it here,
                    // where the object can be named.
                    if !(verts.p0.is_finite() && verts.p1.is_finite() && verts.p2.is_finite()) {
                        dropped += 1;
                        continue;
                    }
                    g.tri_mesh.push((mesh_index, attrs.indices.len() as u32));
                    g.tri_light.push(NO_LIGHT);
                    g.triangles.push(verts);
                    attrs.indices.push(tri);
                }
                if dropped > 0 {
                    warnings.push(format!(
                        "object '{}': {dropped} triangle(s) of mesh '{}' have vertices beyond the \
                         range of 32-bit floats after the object's transform and were dropped",
                        obj.name, mesh.name
                    ));
                }
                g.meshes.push(attrs);
            }
            Shape::Sphere { center, radius } => {
                let lin = Mat3::from_mat4(m);
                let sx = lin.x_axis.length();
                let (sy, sz) = (lin.y_axis.length(), lin.z_axis.length());
                let similar = (sx - sy).abs() <= 1e-4 * sx && (sx - sz).abs() <= 1e-4 * sx;
                let orthogonal = lin.x_axis.dot(lin.y_axis).abs() <= 1e-4 * sx * sy
                    && lin.y_axis.dot(lin.z_axis).abs() <= 1e-4 * sy * sz
                    && lin.x_axis.dot(lin.z_axis).abs() <= 1e-4 * sx * sz;
                if !(similar && orthogonal) {
                    return Err(SceneError::invalid(
                        label,
                        format!(
                            "sphere '{}' has a non-uniform scale or shear, which is not supported",
                            obj.name
                        ),
                    ));
                }
                g.spheres.push(AnalyticPrim {
                    shape: Sphere {
                        center: m.transform_point3(*center),
                        radius: radius * sx,
                    },
                    material,
                    light: NO_LIGHT,
                });
            }
            Shape::Cuboid { min, max } => {
                if Mat3::from_mat4(m).determinant() == 0.0 {
                    warnings.push(format!(
                        "box '{}' has a singular transform and was skipped",
                        obj.name
                    ));
                    continue;
                }
                g.cuboids.push(AnalyticPrim {
                    shape: Cuboid::new(Bounds3::new(*min, *max), m),
                    material,
                    light: NO_LIGHT,
                });
            }
            Shape::Quad { corner, e1, e2 } => {
                let c = m.transform_point3(*corner);
                let (mut a, mut b) = (m.transform_vector3(*e1), m.transform_vector3(*e2));
                if Mat3::from_mat4(m).determinant() < 0.0 {
                    std::mem::swap(&mut a, &mut b);
                }
                g.quads.push(AnalyticPrim {
                    shape: Quad::new(c, a, b),
                    material,
                    light: NO_LIGHT,
                });
            }
            Shape::Curves(c) => push_curves(&mut g, c, m, material),
        }
    }
    if !g.instances.is_empty() {
        let flat = g.triangles.len() as u32;
        g.instances.finish(flat);
    }
    Ok(g)
}

/// Which objects become instances of a shared mesh ([`Instancing`]). Only meshes whose
/// triangles could all be bounded under the object's transform qualify, under an invertible
/// transform, with a material that does not emit: area lights are single triangles in world
/// space (the light BVH and the samplers index them), so an emissive object stays flat.
/// World memory per flattened triangle, beyond the scene mesh it comes from: its transformed
/// vertices and indices (`TriangleVerts`, `tri_mesh`, `tri_light`, the mesh's attribute copy) and
/// the BVH build's references, bounds and nodes at their peak. Measured as the growth of the
/// peak resident set with the triangle count (2.46 M subdivided triangles: 145 bytes each beyond
/// the 48 the scene mesh was charged), rounded up.
const WORLD_BYTES_PER_TRIANGLE: u64 = 160;
/// Per analytic primitive (sphere, box, quad, curve segment) and per instance placement: its
/// record and its share of the BVH.
const WORLD_BYTES_PER_PRIMITIVE: u64 = 256;

/// Charges the load's memory budget (crate::limits) for the world about to be compiled from
/// `scene`, before any of it is allocated: a scene of a few kilobytes can expand into tens of
/// millions of triangles (subdivision, instancing flattened), and the geometry copy and the BVH
/// over them would otherwise exhaust memory where only a clear error is acceptable.
fn charge_world_memory(scene: &Scene, instanced: &[bool], label: &str) -> Result<(), SceneError> {
    let mut triangles: u64 = 0;
    let mut primitives: u64 = 0;
    let mut shared = vec![false; scene.meshes.len()];
    for (obj, &instance) in scene.objects.iter().zip(instanced) {
        match &obj.shape {
            Shape::Mesh(id) if instance => {
                primitives += 1;
                if !std::mem::replace(&mut shared[*id], true) {
                    triangles += scene.meshes[*id].indices.len() as u64;
                }
            }
            Shape::Mesh(id) => triangles += scene.meshes[*id].indices.len() as u64,
            Shape::Curves(c) => primitives += c.segments.len() as u64,
            _ => primitives += 1,
        }
    }
    let bytes = triangles
        .saturating_mul(WORLD_BYTES_PER_TRIANGLE)
        .saturating_add(primitives.saturating_mul(WORLD_BYTES_PER_PRIMITIVE));
    crate::limits::charge(bytes, || {
        format!("the world of {triangles} triangles and {primitives} other primitives")
    })
    .map_err(|e| SceneError::invalid(label, e.to_string()))
}

fn instanced_objects(scene: &Scene, instancing: Instancing) -> Vec<bool> {
    let candidate = |o: &crate::scene::Object| match o.shape {
        Shape::Mesh(id) => {
            !scene.meshes[id].indices.is_empty()
                && !scene.materials[o.material].is_emissive()
                && Mat3::from_mat4(o.transform).determinant().is_normal()
        }
        _ => false,
    };
    let mut uses = vec![0usize; scene.meshes.len()];
    for o in &scene.objects {
        if let Shape::Mesh(id) = o.shape
            && candidate(o)
        {
            uses[id] += 1;
        }
    }
    scene
        .objects
        .iter()
        .map(|o| {
            let Shape::Mesh(id) = o.shape else {
                return false;
            };
            let wanted = match instancing {
                Instancing::Never => false,
                Instancing::Always => true,
                Instancing::Auto => {
                    uses[id] >= 2
                        && uses[id].saturating_mul(scene.meshes[id].indices.len())
                            >= AUTO_INSTANCE_TRIANGLES
                }
            };
            wanted && candidate(o) && {
                // Every vertex must stay finite under the transform (else it is flattened, and
                // the flattening drops what overflows with a warning).
                let m = o.transform;
                scene.meshes[id]
                    .positions
                    .iter()
                    .all(|&p| m.transform_point3(p).is_finite())
            }
        })
        .collect()
}

/// Places `curves`' segments in the world with transform `m`, each split into 2^split_depth
/// pieces (pbrt-v4 `Curve::Create`). Widths are object-space lengths: they are scaled by the
/// transform's mean linear scale (exact for the similarity transforms hair files use).
fn push_curves(
    g: &mut GeometryStore,
    curves: &crate::scene::CurveShape,
    m: crate::math::Mat4,
    material: u32,
) {
    use crate::geometry::curve::{Curve, bezier_part};
    let scale = Mat3::from_mat4(m).determinant().abs().cbrt();
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    let pieces = 1u32 << curves.split_depth.min(10);
    for (k, seg) in curves.segments.iter().enumerate() {
        let world = seg.map(|p| m.transform_point3(p));
        let [w0, w1] = curves.widths[k].map(|w| w * scale);
        let normals = curves.normals.as_ref().map_or([Vec3::Z; 2], |n| {
            n[k].map(|v| m.transform_vector3(v).normalize_or_zero())
        });
        for i in 0..pieces {
            let u0 = i as f32 / pieces as f32;
            let u1 = (i + 1) as f32 / pieces as f32;
            let lerp = |t: f32| w0 + (w1 - w0) * t;
            let slerp_end = |t: f32| {
                let [n0, n1] = normals;
                let angle = n0.dot(n1).clamp(-1.0, 1.0).acos();
                if angle.sin().abs() < 1e-5 {
                    n0
                } else {
                    (n0 * ((1.0 - t) * angle).sin() + n1 * (t * angle).sin()) / angle.sin()
                }
            };
            g.curves.push(AnalyticPrim {
                shape: Curve {
                    cp: bezier_part(&world, u0, u1),
                    u_range: [u0, u1],
                    width: [lerp(u0), lerp(u1)],
                    kind: curves.kind,
                    normals: [slerp_end(u0), slerp_end(u1)],
                },
                material,
                light: NO_LIGHT,
            });
        }
    }
}

/// Step 2: an area light for every primitive with an emissive material, non-zero area and, for
/// triangles with an emissive texture, a texture footprint that is not black
/// ([`crate::light::emission`]). Returns the lights and, per light, the mean of its texture
/// footprint when it was read (for its power).
fn area_lights(
    g: &mut GeometryStore,
    materials: &[Material],
    textures: &[Texture],
) -> (Vec<Light>, Vec<Option<Vec3>>) {
    use rayon::prelude::*;
    // Triangles' texture footprints, read in parallel (ToyCar: 88 837 triangles).
    let footprints: Vec<Option<Vec3>> = (0..g.triangles.len())
        .into_par_iter()
        .map(|i| {
            let prim = PrimRef::new(PrimitiveKind::Triangle, i as u32);
            let m = &materials[g.material(prim) as usize];
            let t = m.emissive_texture.as_ref()?;
            if !m.is_emissive() {
                return None;
            }
            let texture = textures.get(t.texture)?;
            let (mesh_i, local) = g.tri_mesh[i];
            let mesh = &g.meshes[mesh_i as usize];
            let idx = mesh.indices[local as usize].map(|x| x as usize);
            let set = if t.texcoord >= 1 && mesh.uv1.is_some() {
                &mesh.uv1
            } else {
                &mesh.uv0
            };
            // Without texture coordinates every lookup is at (0, 0).
            let uvs = match set {
                Some(uv) => idx.map(|k| uv[k]),
                None => [Vec2::ZERO; 3],
            };
            crate::light::emission::footprint_mean(texture, t, uvs)
        })
        .collect();
    let mut lights = Vec::new();
    let mut means = Vec::new();
    for prim in g.all_prims() {
        let material = g.material(prim);
        // An area that overflowed (a triangle spanning more than ~1e19) cannot be sampled:
        // its pdf would be 0 and its power infinite. Curves are not emitters: pbrt-v4 cannot
        // sample points on them either.
        let area = g.area(prim);
        if prim.kind() == PrimitiveKind::Curve
            || !(materials[material as usize].is_emissive() && area > 0.0 && area.is_finite())
        {
            continue;
        }
        let mean = match prim.kind() {
            PrimitiveKind::Triangle => footprints[prim.index()],
            _ => None,
        };
        if mean == Some(Vec3::ZERO) {
            continue;
        }
        g.set_light(prim, lights.len() as u32);
        lights.push(Light::Area(AreaLight::new(prim, material)));
        means.push(mean);
    }
    (lights, means)
}

/// Step 3: the scene's own lights (point, spot, directional, ambient, environment maps, whose
/// relative paths are relative to the scene file).
fn scene_lights(scene: &Scene, label: &str) -> Result<Vec<Light>, SceneError> {
    scene.lights.iter().map(|l| scene_light(l, label)).collect()
}

/// One of the scene's lights, compiled.
fn scene_light(l: &LightDesc, label: &str) -> Result<Light, SceneError> {
    Ok(match l {
        LightDesc::Point {
            position,
            intensity,
            ..
        } => Light::Point(PointLight {
            position: *position,
            intensity: *intensity,
        }),
        LightDesc::Spot {
            position,
            direction,
            intensity,
            inner_angle,
            outer_angle,
            falloff,
            ..
        } => Light::Spot(SpotLight {
            position: *position,
            direction: direction.normalize(),
            intensity: *intensity,
            cos_inner: inner_angle.cos(),
            cos_outer: outer_angle.cos(),
            falloff: *falloff,
        }),
        LightDesc::Directional {
            direction,
            irradiance,
            ..
        } => Light::Directional(DirectionalLight {
            direction: direction.normalize(),
            irradiance: *irradiance,
        }),
        LightDesc::Ambient { radiance, .. } => Light::Uniform(UniformLight {
            radiance: *radiance,
        }),
        LightDesc::Environment {
            name,
            path,
            scale,
            mapping,
            transform,
        } => {
            // The loaders resolve the file against the scene's folder (`resolve_in_dir`), so
            // the path is used as given; joining the folder again read `dir/dir/map.hdr`.
            let map = EnvMap::load_mapped(path, *scale, Mat3::from_mat4(*transform), *mapping)
                .map_err(|e| {
                    SceneError::invalid(
                        label,
                        format!("environment light '{name}' ({}): {e}", path.display()),
                    )
                })?;
            Light::Environment(EnvironmentLight { map: Arc::new(map) })
        }
    })
}

/// Step 4: the lights the options add: `--env`, and the default environment when the
/// default-light rule ([`default_light`]) calls for it: the uniform one is added here; `true`
/// asks for the studio environment, which is added once the camera is known.
fn add_option_lights(
    lights: &mut Vec<Light>,
    scene: &Scene,
    g: &GeometryStore,
    options: &WorldOptions,
    warnings: &mut Vec<String>,
) -> Result<bool, SceneError> {
    if let Some(path) = &options.env {
        if !options.env_rotation.is_finite() {
            return Err(SceneError::invalid(
                path.display(),
                format!(
                    "environment rotation must be a number of degrees (got {})",
                    options.env_rotation
                ),
            ));
        }
        let rotation = Mat3::from_rotation_y(options.env_rotation.to_radians());
        let map = EnvMap::load(path, Vec3::ONE, rotation)
            .map_err(|e| SceneError::invalid(path.display(), e))?;
        lights.push(Light::Environment(EnvironmentLight { map: Arc::new(map) }));
    }
    let mode = options
        .default_light
        .or(scene.default_light)
        .unwrap_or_default();
    let area_of = |i: usize| match &lights[i] {
        Light::Area(a) => g.area(a.prim),
        _ => 0.0,
    };
    let emitters = default_light::emitter_stats(
        lights,
        &scene.materials,
        &scene.textures,
        area_of,
        g.scene_bounds().bounding_sphere().1,
    );
    // An emissive medium is the author's lighting too: a scene lit only by glowing gas must not
    // get the white environment that `auto` gives an unlit scene.
    let medium_glows = scene.media.iter().any(|m| {
        let grid_glows = matches!(
            &m.kind,
            crate::scene::MediumKind::Grid {
                emission: Some(_),
                ..
            }
        );
        (m.le.max_element() > 0.0 || grid_glows) && (m.sigma_a * m.scale).max_element() > 0.0
    });
    let decision = if medium_glows && matches!(mode, DefaultLight::Auto | DefaultLight::Uniform) {
        default_light::Decision {
            add: false,
            reason: String::new(),
        }
    } else {
        default_light::decide(mode, lights, &emitters)
    };
    if !decision.reason.is_empty() {
        warnings.push(decision.reason);
    }
    if decision.add && mode == DefaultLight::Uniform {
        lights.push(Light::Uniform(UniformLight {
            radiance: Vec3::ONE,
        }));
        return Ok(false);
    }
    Ok(decision.add)
}

/// Step 6 (after the accelerator): the camera `--camera` names, or the scene's first, or one
/// framing the scene's bounds from the front.
fn choose_camera(
    scene: &Scene,
    options: &WorldOptions,
    bounds: Bounds3,
    accel: &Accel,
    g: &GeometryStore,
    label: &str,
) -> Result<CameraDesc, SceneError> {
    if let Some(spec) = &options.camera_override {
        spec.validate().map_err(|e| SceneError::invalid(label, e))?;
        return Ok(spec.to_desc("view"));
    }
    let mut camera = select_camera(scene, options, bounds, label)?;
    if scene.cameras.is_empty() && options.camera.is_none() {
        camera = face_the_front(camera, bounds, accel, g);
    }
    Ok(camera)
}

/// The camera named by `--camera` (name or index), else the scene's first, else one that frames
/// the scene's bounds from the front (+z), looking down −z.
fn select_camera(
    scene: &Scene,
    options: &WorldOptions,
    bounds: Bounds3,
    label: &str,
) -> Result<CameraDesc, SceneError> {
    if let Some(sel) = &options.camera {
        return scene.camera_by(Some(sel)).cloned().ok_or_else(|| {
            let names: Vec<String> = scene
                .cameras
                .iter()
                .enumerate()
                .map(|(i, c)| format!("{i}: '{}'", c.name))
                .collect();
            SceneError::invalid(
                label,
                format!(
                    "no camera '{sel}' (the scene has {})",
                    if names.is_empty() {
                        "no cameras".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            )
        });
    }
    if let Some(c) = scene.cameras.first() {
        return Ok(c.clone());
    }
    Ok(auto_camera(bounds))
}

/// The automatic camera sees the model from +z. Most models face +z (glTF's front), but a room
/// modelled to be seen from −z, such as the original Cornell box data (camera at z = −800 mm,
/// open side at z = 0), would show only the back of its back wall. So 9 × 9 rays of the automatic
/// view are traced: if most of what they hit are back faces, the camera moves to the opposite side.
fn face_the_front(
    camera: CameraDesc,
    bounds: Bounds3,
    accel: &Accel,
    g: &GeometryStore,
) -> CameraDesc {
    const N: usize = 9;
    let count_back = |cam: &CameraDesc| {
        let eye = cam.camera_to_world.transform_point3(Vec3::ZERO);
        let (c, r) = bounds.bounding_sphere();
        let right = cam
            .camera_to_world
            .transform_vector3(Vec3::X)
            .normalize_or_zero();
        let up = cam
            .camera_to_world
            .transform_vector3(Vec3::Y)
            .normalize_or_zero();
        let (mut back, mut hits) = (0, 0);
        for i in 0..N {
            for j in 0..N {
                let s = (i as f32 + 0.5) / N as f32 * 2.0 - 1.0;
                let t = (j as f32 + 0.5) / N as f32 * 2.0 - 1.0;
                let target = c + (right * s + up * t) * (0.7 * r);
                let ray = Ray::new(eye, target - eye);
                if let Some(i) = accel.intersect(g, &ray) {
                    let hit = g.surface_hit(&ray, &i);
                    hits += 1;
                    back += usize::from(hit.ng.dot(ray.d) > 0.0);
                }
            }
        }
        (back, hits)
    };
    if bounds.is_empty() {
        return camera;
    }
    let (back, hits) = count_back(&camera);
    if hits == 0 || back * 2 <= hits {
        return camera;
    }
    let behind = orbit_camera(bounds, 180.0, 0.0);
    let (back2, hits2) = count_back(&behind);
    // Only if the other side is better: a closed model seen from anywhere shows front faces.
    if back2 * hits < back * hits2 {
        behind
    } else {
        camera
    }
}

/// The automatic camera, as model viewers frame a model (the Khronos sample viewer, Blender's
/// glTF preview): it looks down −z at the centre of the bounds from the distance where the bounding
/// sphere fits the vertical field of view of 39.6°. A model that is flat in y (a ground sheet such
/// as TwoSidedPlane, extent in y under 1 % of its largest extent) would be seen edge-on from there,
/// i.e. not at all, so it is seen from 30° above instead.
pub fn auto_camera(bounds: Bounds3) -> CameraDesc {
    let flat_in_y = !bounds.is_empty() && {
        let e = bounds.max - bounds.min;
        e.y <= 0.01 * e.max_element()
    };
    orbit_camera(bounds, 0.0, if flat_in_y { 30.0 } else { 0.0 })
}

/// A camera on the bounding sphere's fitting distance around the bounds' centre, `yaw_deg` about
/// +y from +z (positive towards +x) and `pitch_deg` above the horizon, looking at the centre with
/// +y up and a 39.6° vertical field of view. `orbit_camera(b, 0, 0)` looks down −z.
pub fn orbit_camera(bounds: Bounds3, yaw_deg: f32, pitch_deg: f32) -> CameraDesc {
    let (center, radius) = if bounds.is_empty() {
        (Vec3::ZERO, 1.0)
    } else {
        let (c, r) = bounds.bounding_sphere();
        (c, r.max(1e-4))
    };
    let vfov: f32 = 39.6;
    // The sphere of radius r is tangent to the view cone at distance r / sin(fov/2); 5 % margin.
    let dist = radius / (vfov.to_radians() * 0.5).sin() * 1.05;
    let (yaw, pitch) = (
        yaw_deg.to_radians(),
        pitch_deg.clamp(-89.0, 89.0).to_radians(),
    );
    let dir = Vec3::new(
        yaw.sin() * pitch.cos(),
        pitch.sin(),
        yaw.cos() * pitch.cos(),
    );
    let eye = center + dir * dist;
    let mut cam = CameraDesc::look_at("auto", eye, center, Vec3::Y, vfov);
    cam.focus_distance = dist;
    cam
}

/// A uniform number in [0, 1) that is a pure function of the ray and the hit distance: the
/// coin of stochastic transparency. Different samples have different rays, so the coins are
/// independent across samples while the same ray always gets the same answer.
#[inline]
fn cutout_hash(ray: &Ray, t: f32) -> f32 {
    let (o, d) = (ray.o, ray.d);
    crate::sampling::rng::hash_floats_to_unit(&[o.x, o.y, o.z, d.x, d.y, d.z, t])
}

/// The queries integrators ask of the world (lights, BSDFs, emission), in their own file.
mod media;
pub mod motion;
mod queries;
