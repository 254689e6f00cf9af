//! Time: the moment of an animated scene a render shows, and motion blur (docs/DESIGN.md §5,
//! "Motion blur").
//!
//! The scene is posed ([`Scene::pose`]) at `--time` seconds, or at `--frame` N of `--fps`
//! (the file's frame rate where it has one, else [`DEFAULT_FPS`]). With a shutter every camera
//! sample draws a time in [0, 1) after its film and lens numbers (one more dimension of the
//! sample's stream, so the image is a pure function of the seed and splits and resumes stay
//! exact; a still draws nothing and is unchanged), the fraction of the shutter it sees:
//! - the camera moves continuously: its world-from-camera transform at the sample's time is
//!   interpolated ([`CameraMotion`]) between poses at [`TimeOptions::steps`] + 1 times across the
//!   shutter, decomposed into translation, rotation and scale (pbrt-v4 `AnimatedTransform`),
//!   the rotation by slerp. A pbrt camera's two-key motion is reproduced exactly (its path
//!   between keys is itself such an interpolation); a glTF camera node's is followed between
//!   the poses.
//! - moving meshes (rigid, skinned, morphing), spheres and quads move continuously too: the world is
//!   compiled once, posed at the shutter's middle, and keeps the moving primitives' vertices at
//!   [`TimeOptions::steps`] + 1 times ([`motion_keys`], `geometry::motion`); the camera ray
//!   carries the sample's time ([`crate::geometry::Ray::time`]), every ray spawned along its
//!   path inherits it, and a moving primitive is intersected where it is at that time, in a BVH
//!   of its own bounded over the shutter (`accel::Accel`).
//! - moving point, spot and directional lights too: the world's light set keeps their
//!   positions and directions at the same keys (`light::set::LightMotion`) and places each at
//!   the time of the ray that samples it or of the light path it starts.
//! - emitters on moving meshes and spheres too: their area lights sample, and take densities
//!   on, the primitive where it is at the sample's time (`light::AreaLight::at`).
//! - moving instances of a shared mesh too: each keeps its world-from-object transform at the
//!   same keys, decomposed (`geometry::motion::KeyedTransform`), and a ray meets it placed by
//!   the interpolation at the ray's time, boxed per key segment in the instances' top-level BVH
//!   (`accel::instance`).
//! - a moving medium boundary is a moving surface like any other: a ray crossing it at its time
//!   changes medium there (the media themselves do not move, in either scheme, as in pbrt-v4).
//! - moving boxes too, placed by their transform interpolated as an instance's (an emissive
//!   one falls back).
//! - motion that is not interpolated so (a light whose power, colour or cone changes,
//!   a moving curve or emissive box) falls back to posing and compiling the scene at the middle of each of
//!   [`TimeOptions::steps`] equal parts of the shutter, each world with its own exact BVH, a
//!   sample tracing the world of the part holding its time: a stratified estimate of the
//!   shutter's average that converges to it as the steps grow. A scene whose only motion is
//!   its camera's is compiled once.
use super::{World, WorldOptions};
use crate::geometry::motion::{MotionStore, MovingMesh, STILL};
use crate::geometry::sphere::Sphere;
use crate::math::{Mat3, Mat4, Vec3, Vec4, transform_normal};
use crate::scene::animation::Animation;
use crate::scene::{Scene, SceneError};

/// Frames per second when neither `--fps` nor the file gives one (film's rate, and Blender's
/// default).
pub const DEFAULT_FPS: f64 = 24.0;
/// Key intervals over the shutter (worlds, for the fallback) unless `--shutter-steps` says.
pub const DEFAULT_SHUTTER_STEPS: u32 = 16;
/// The most `--shutter-steps` accepts (with the fallback each step is a whole world in memory).
pub const MAX_SHUTTER_STEPS: u32 = 256;

#[derive(Clone, Debug, Default, PartialEq)]
pub struct TimeOptions {
    /// `--time`: scene time in seconds.
    pub time: Option<f64>,
    /// `--frame N` (or a frame of `--frames`): time N / fps.
    pub frame: Option<u32>,
    /// `--fps`: overrides the file's frame rate.
    pub fps: Option<f64>,
    /// `--shutter OPEN,CLOSE` in seconds: relative to the moment when `time` or `frame` is
    /// given, else scene time.
    pub shutter: Option<[f64; 2]>,
    /// `--shutter-steps`: the intervals between the keys of moving primitives and of the
    /// camera, or the worlds the shutter is cut into where motion falls back to them
    /// (0: [`DEFAULT_SHUTTER_STEPS`]).
    pub steps: u32,
}

impl TimeOptions {
    /// Refuses values no render can use.
    pub fn validate(&self) -> Result<(), String> {
        if let Some(t) = self.time
            && !t.is_finite()
        {
            return Err(format!(
                "--time must be a finite number of seconds (got {t})"
            ));
        }
        if let Some(f) = self.fps
            && !(f.is_finite() && f > 0.0)
        {
            return Err(format!("--fps must be a positive number (got {f})"));
        }
        if self.time.is_some() && self.frame.is_some() {
            return Err("--time and --frame both give the moment: use one".into());
        }
        if let Some([o, c]) = self.shutter
            && !(o.is_finite() && c.is_finite() && o <= c)
        {
            return Err(format!(
                "--shutter OPEN,CLOSE needs finite times with OPEN <= CLOSE (got {o},{c})"
            ));
        }
        if self.steps > MAX_SHUTTER_STEPS {
            return Err(format!(
                "--shutter-steps must be at most {MAX_SHUTTER_STEPS} (got {})",
                self.steps
            ));
        }
        Ok(())
    }

    /// The frame rate `--frame` uses: `--fps`, else the file's, else [`DEFAULT_FPS`].
    pub fn fps(&self, anim: Option<&Animation>) -> f64 {
        self.fps.or(anim.and_then(|a| a.fps)).unwrap_or(DEFAULT_FPS)
    }

    /// The moment to render, if one was asked for.
    pub fn moment(&self, anim: Option<&Animation>) -> Option<f64> {
        self.time
            .or_else(|| self.frame.map(|f| f as f64 / self.fps(anim)))
    }

    /// The shutter interval in scene time: `--shutter` (after the moment, if any), else, with
    /// no moment asked for, the file's own (pbrt's camera `shutteropen`/`shutterclose`) when
    /// something in it moves.
    pub fn shutter_interval(&self, anim: Option<&Animation>) -> Option<(f64, f64)> {
        match self.shutter {
            Some([o, c]) => {
                let m = self.moment(anim).unwrap_or(0.0);
                Some((m + o, m + c))
            }
            // The file's shutter is scene time; a moment asked for is a still.
            None if self.moment(anim).is_some() => None,
            None => anim.filter(|a| a.moves())?.shutter,
        }
    }

    pub fn steps(&self) -> u32 {
        if self.steps == 0 {
            DEFAULT_SHUTTER_STEPS
        } else {
            self.steps
        }
    }
}

/// The middle of step `k` of `steps` over [open, close].
pub fn step_time(open: f64, close: f64, k: u32, steps: u32) -> f64 {
    open + (close - open) * (k as f64 + 0.5) / steps as f64
}

/// The shutter step of a time number `u` in [0, 1).
#[inline]
pub fn step_of(u: f32, steps: usize) -> usize {
    ((u * steps as f32) as usize).min(steps - 1)
}

impl World {
    /// [`World::build`] at the moment and with the motion blur `options.time` asks for: the
    /// scene posed at the moment, or posed at the shutter's middle with its moving primitives'
    /// keys ([`motion_keys`]), or, for motion the keys do not cover, one world per shutter step
    /// (the first is this world, the others in [`World::motion`]). A scene in which nothing
    /// moves is built once, as a still (a warning says a shutter was ignored).
    pub fn build_posed(mut scene: Scene, options: &WorldOptions) -> Result<World, SceneError> {
        let label = scene
            .source
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| scene.name.clone());
        let opts = &options.time;
        opts.validate()
            .map_err(|m| SceneError::invalid(&label, m))?;
        let anim = scene.animation.clone();
        let moment = opts.moment(anim.as_deref());
        let moves = anim.as_ref().is_some_and(|a| a.moves());
        let interval = opts.shutter_interval(anim.as_deref());
        let Some((open, close)) = interval.filter(|_| moves) else {
            if moment.is_some() {
                scene.pose(moment);
            }
            let mut w = World::build(scene, options)?;
            if opts.shutter.is_some() {
                w.warnings.push(
                    "--shutter: nothing in the scene moves, so there is no motion blur".into(),
                );
            }
            return Ok(w);
        };
        // The camera the world will show, when it is one of the scene's: it may move.
        let camera_index = if options.camera_override.is_some() {
            None
        } else {
            match options.camera.as_deref() {
                Some(sel) => scene
                    .camera_by(Some(sel))
                    .and_then(|c| scene.cameras.iter().position(|d| std::ptr::eq(c, d))),
                None => (!scene.cameras.is_empty()).then_some(0),
            }
        };
        let mut discrete_reason: Option<String> = None;
        let camera_keys = camera_index
            .zip(anim.as_deref())
            .filter(|_| close > open)
            .and_then(|(i, a)| {
                let n = opts.steps();
                let keys: Option<Vec<Mat4>> = (0..=n)
                    .map(|k| a.camera_at(i, open + (close - open) * k as f64 / n as f64))
                    .collect();
                keys.filter(|k| k.iter().any(|m| *m != k[0]))
            });
        let objects_move = anim.as_ref().is_some_and(|a| a.moves_beyond_cameras());
        if close > open && objects_move {
            match motion_keys(&mut scene, options, open, close, opts.steps() as usize + 1) {
                Ok((mid, store, light_motion)) => {
                    // Keys only for what moves within the shutter.
                    let moving =
                        store.prims_move() || store.instance_motion.iter().any(Option::is_some);
                    let mut w = World::build_with_motion(
                        mid,
                        options,
                        moving.then_some(store),
                        light_motion,
                    )?;
                    w.camera_motion = camera_keys.map(|k| CameraMotion::new(&k));
                    if w.is_still() {
                        w.warnings.push(
                            "motion blur: nothing the render shows moves during the shutter".into(),
                        );
                    }
                    return Ok(w);
                }
                Err(reason) => {
                    // The discrete scheme below covers it, a world per step.
                    discrete_reason = Some(reason);
                }
            }
        }
        let steps = if close > open && objects_move {
            opts.steps()
        } else {
            1
        };
        let mut first = scene.clone();
        first.pose(Some(step_time(open, close, 0, steps)));
        let mut w = World::build(first, options)?;
        if let Some(reason) = discrete_reason {
            w.warnings.push(format!(
                "motion blur: {reason}, so the shutter is cut into {steps} steps (a world each, \
                 --shutter-steps) instead of moving continuously"
            ));
        }
        w.camera_motion = camera_keys.map(|k| CameraMotion::new(&k));
        if steps == 1 {
            if w.camera_motion.is_none() && close > open {
                w.warnings
                    .push("motion blur: nothing the render shows moves during the shutter".into());
            }
            return Ok(w);
        }
        // A scene without a camera is framed once, at the shutter's opening: the automatic
        // camera must not follow the moving objects' bounds from step to step.
        let fixed;
        let auto_camera = scene.cameras.is_empty() && options.camera_override.is_none();
        let step_options = if auto_camera {
            fixed = WorldOptions {
                camera_override: Some(crate::camera::CameraSpec::from_desc(&w.camera)),
                ..options.clone()
            };
            &fixed
        } else {
            options
        };
        let mut rest = Vec::with_capacity(steps as usize - 1);
        for k in 1..steps {
            let mut s = if k + 1 == steps {
                std::mem::take(&mut scene)
            } else {
                scene.clone()
            };
            s.pose(Some(step_time(open, close, k, steps)));
            let mut sw = World::build(s, step_options)?;
            if auto_camera {
                sw.camera = w.camera.clone();
            }
            rest.push(sw);
        }
        w.motion = rest;
        Ok(w)
    }

    /// True for a still: no moving primitives, step worlds or moving camera.
    pub fn is_still(&self) -> bool {
        self.motion.is_empty()
            && self.camera_motion.is_none()
            && self.geometry.motion.is_none()
            && self.geometry.instances.motion.is_empty()
            && !self.lights.moves()
    }

    /// Worlds a camera sample chooses from by its time: 1 for a still.
    pub fn time_steps(&self) -> usize {
        1 + self.motion.len()
    }

    /// The world of shutter step `k` ([`World::build_posed`]); the camera at that moment is the
    /// one [`World::camera_motion`] gives (the step worlds' own cameras are not used).
    #[inline]
    pub fn at_step(&self, k: usize) -> &World {
        if k == 0 { self } else { &self.motion[k - 1] }
    }
}

/// A camera's motion over the shutter: its world-from-camera transform at `n + 1` evenly spaced
/// times, decomposed and interpolated piecewise (pbrt-v4 `AnimatedTransform::Interpolate`).
pub use crate::geometry::motion::KeyedTransform as CameraMotion;

/// The keys of continuous motion blur: the scene posed at `keys` evenly spaced times over
/// [open, close], the objects that move between them found, and their flattened meshes'
/// vertices (positions, normals, tangents, transformed as `compile_geometry` transforms them),
/// spheres and quads kept per key (an emissive one too: its area light is sampled where it is at each
/// sample's time, `light::AreaLight::at`). Returns the scene posed at the shutter's middle (the
/// world's pose for everything that does not read a time) and the keys; `Err` names what
/// continuous motion does not cover (the caller falls back to a world per step): a light that
/// changes more than its position and direction
/// ([`light_keys`]), a moving shape other than a mesh, sphere, box or quad, an emissive moving
/// box, an instanced mesh that deforms, or a transform that mirrors part of the time (or, for
/// an instance, is singular part of it). Moving instances get their world-from-object
/// transform per key (`MotionStore::instance_motion`). Also returns the moving lights' keys.
/// The scene's moving lights: index in `Scene::lights`, (position, direction) per key.
type LightKeys = Vec<(usize, Vec<(Vec3, Vec3)>)>;

fn motion_keys(
    scene: &mut Scene,
    options: &WorldOptions,
    open: f64,
    close: f64,
    keys: usize,
) -> Result<(Scene, MotionStore, LightKeys), String> {
    use crate::scene::Shape;
    // The textures do not move: leave them out of the posed copies.
    let textures = std::mem::take(&mut scene.textures);
    let time = |k: usize| open + (close - open) * k as f64 / (keys - 1) as f64;
    // Per key: every object's transform, and the meshes a pose deformed (skins, morphs).
    let mut transforms: Vec<Vec<Mat4>> = Vec::with_capacity(keys);
    let mut deformed: Vec<Vec<Option<crate::scene::Mesh>>> = Vec::with_capacity(keys);
    // Per key: the scene's lights, posed.
    let mut key_lights: Vec<Vec<crate::scene::LightDesc>> = Vec::with_capacity(keys);
    for k in 0..keys {
        let mut s = scene.clone();
        s.pose(Some(time(k)));
        transforms.push(s.objects.iter().map(|o| o.transform).collect());
        deformed.push(
            s.meshes
                .into_iter()
                .zip(&scene.meshes)
                .map(|(posed, rest)| {
                    let same = posed.positions == rest.positions
                        && posed.normals == rest.normals
                        && posed.tangents == rest.tangents;
                    (!same).then_some(posed)
                })
                .collect(),
        );
        key_lights.push(s.lights);
    }
    let mut mid = scene.clone();
    scene.textures = textures;
    mid.textures = scene.textures.clone();
    mid.pose(Some(0.5 * (open + close)));
    let light_motion = light_keys(&key_lights)?;
    let instanced = super::instanced_objects(&mid, options.instancing);
    let mut store = MotionStore {
        keys,
        ..Default::default()
    };
    // The world compiles the objects in the order media give them (interface surfaces last,
    // `medium::world::assign`): the slots follow it.
    let order = crate::medium::world::object_order(scene)
        .unwrap_or_else(|| (0..scene.objects.len()).collect());
    for o in order {
        let obj = &scene.objects[o];
        let mesh_id = match obj.shape {
            Shape::Mesh(id) => Some(id),
            _ => None,
        };
        let turns = (1..keys).any(|k| transforms[k][o] != transforms[0][o]);
        let deforms = mesh_id.is_some_and(|id| {
            (1..keys).any(|k| {
                let (a, b) = (&deformed[k][id], &deformed[0][id]);
                match (a, b) {
                    (Some(a), Some(b)) => {
                        a.positions != b.positions
                            || a.normals != b.normals
                            || a.tangents != b.tangents
                    }
                    (None, None) => false,
                    _ => true,
                }
            })
        });
        let moves = turns || deforms;
        let slot = if moves {
            store.meshes.len() as u32
        } else {
            STILL
        };
        match (&obj.shape, instanced[o]) {
            (Shape::Mesh(_), true) if moves => {
                // A moving instance keeps its world-from-object transform per key, placed at a
                // ray's time by their decomposed interpolation (`geometry::instance`).
                if deforms {
                    return Err(format!(
                        "the mesh of the instanced object '{}' deforms",
                        obj.name
                    ));
                }
                let keyed = keyed_transform(&transforms, o, "instanced object", &obj.name)?;
                store.instance_motion.push(Some(keyed));
                continue;
            }
            (Shape::Mesh(_), true) => {
                store.instance_motion.push(None);
                continue;
            }
            (Shape::Mesh(_), false) => store.mesh_slot.push(slot),
            (Shape::Sphere { .. }, _) => store.sphere_slot.push(if moves {
                (store.spheres.len() / keys) as u32
            } else {
                STILL
            }),
            (Shape::Quad { .. }, _) => store.quad_slot.push(if moves {
                (store.quads.len() / keys) as u32
            } else {
                STILL
            }),
            (Shape::Cuboid { .. }, _) => {
                // As compile_geometry: a box singular at the middle pose is left out.
                if Mat3::from_mat4(mid.objects[o].transform).determinant() == 0.0 {
                    continue;
                }
                if !moves {
                    store.cuboid_slot.push(STILL);
                    continue;
                }
                // A moving box keeps its object-to-world transform per key, placed at a ray's
                // time by their decomposed interpolation (`MotionStore::cuboid`).
                if scene.materials[obj.material].is_emissive() {
                    return Err(format!("the emissive box '{}' moves", obj.name));
                }
                let keyed = keyed_transform(&transforms, o, "box", &obj.name)?;
                store.cuboid_slot.push(store.cuboids.len() as u32);
                store.cuboids.push(keyed);
                continue;
            }
            _ if moves => {
                return Err(format!(
                    "the object '{}' moves and is not a mesh, a sphere, a box or a quad",
                    obj.name
                ));
            }
            _ => continue,
        }
        if !moves {
            continue;
        }
        let flip = |m: &Mat4| Mat3::from_mat4(*m).determinant() < 0.0;
        if (1..keys).any(|k| flip(&transforms[k][o]) != flip(&transforms[0][o])) {
            return Err(format!(
                "the object '{}' is mirrored part of the time",
                obj.name
            ));
        }
        match obj.shape {
            Shape::Mesh(id) => {
                let rest = &scene.meshes[id];
                let mut mm = MovingMesh {
                    verts: rest.positions.len(),
                    positions: Vec::with_capacity(rest.positions.len() * keys),
                    normals: rest.normals.as_ref().map(|_| Vec::new()),
                    tangents: rest.tangents.as_ref().map(|_| Vec::new()),
                };
                for k in 0..keys {
                    let m = transforms[k][o];
                    let mesh = deformed[k][id].as_ref().unwrap_or(rest);
                    // As compile_geometry flattens a mesh.
                    let inv = m.inverse();
                    let mirrored = flip(&m);
                    mm.positions
                        .extend(mesh.positions.iter().map(|&p| m.transform_point3(p)));
                    if let (Some(out), Some(ns)) = (mm.normals.as_mut(), mesh.normals.as_ref()) {
                        out.extend(
                            ns.iter()
                                .map(|&n| transform_normal(&inv, n).normalize_or_zero()),
                        );
                    }
                    if let (Some(out), Some(ts)) = (mm.tangents.as_mut(), mesh.tangents.as_ref()) {
                        out.extend(ts.iter().map(|t| {
                            let v = m.transform_vector3(t.truncate()).normalize_or_zero();
                            Vec4::new(v.x, v.y, v.z, if mirrored { -t.w } else { t.w })
                        }));
                    }
                }
                let n = mm.verts * keys;
                if mm.positions.len() != n
                    || mm.normals.as_ref().is_some_and(|v| v.len() != n)
                    || mm.tangents.as_ref().is_some_and(|v| v.len() != n)
                {
                    return Err(format!("the mesh of '{}' changes its size", obj.name));
                }
                store.meshes.push(mm);
            }
            Shape::Sphere { center, radius } => {
                for key in &transforms {
                    let m = key[o];
                    store.spheres.push(Sphere {
                        center: m.transform_point3(center),
                        radius: radius * Mat3::from_mat4(m).x_axis.length(),
                    });
                }
            }
            Shape::Quad { corner, e1, e2 } => {
                // As compile_geometry places a quad (its edges swapped under a mirroring
                // transform, which holds at every key or at none).
                for key in &transforms {
                    let m = key[o];
                    let c = m.transform_point3(corner);
                    let (mut a, mut b) = (m.transform_vector3(e1), m.transform_vector3(e2));
                    if flip(&m) {
                        std::mem::swap(&mut a, &mut b);
                    }
                    store.quads.push(crate::geometry::quad::Quad::new(c, a, b));
                }
            }
            _ => unreachable!("only meshes, spheres and quads get here"),
        }
    }
    Ok((mid, store, light_motion))
}

/// Object `o`'s world-from-object transforms at the keys (`transforms[k][o]`) as a transform
/// placed at a ray's time by their decomposed interpolation, for a moving instance or box
/// (`what` names the kind in the messages). Refused: a transform singular at some key (it has
/// no decomposition) and one whose handedness changes over the shutter (a mirror part of the
/// time, which the decomposition into a rotation cannot follow).
fn keyed_transform(
    transforms: &[Vec<Mat4>],
    o: usize,
    what: &str,
    name: &str,
) -> Result<crate::geometry::motion::KeyedTransform, String> {
    let keyed: Vec<Mat4> = transforms.iter().map(|k| k[o]).collect();
    let det = |m: &Mat4| Mat3::from_mat4(*m).determinant();
    if !keyed.iter().all(|m| det(m).is_normal()) {
        return Err(format!(
            "the {what} '{name}' has a singular transform part of the time"
        ));
    }
    if keyed
        .iter()
        .any(|m| (det(m) < 0.0) != (det(&keyed[0]) < 0.0))
    {
        return Err(format!("the object '{name}' is mirrored part of the time"));
    }
    Ok(crate::geometry::motion::KeyedTransform::new(&keyed))
}

/// The scene's lights that move over the keys `key_lights` (the scene's lights posed at each
/// key): per moving light its index and its (position, unit direction) at every key. Points,
/// spots and directional lights may move and turn; `Err` names a light that changes in any
/// other way (its power, colour or cone), or a light of another kind that moves.
fn light_keys(key_lights: &[Vec<crate::scene::LightDesc>]) -> Result<LightKeys, String> {
    use crate::scene::LightDesc;
    // A light's pose, and the light with its pose taken out (what must not change).
    fn pose(l: &LightDesc) -> Option<((Vec3, Vec3), LightDesc)> {
        let mut still = l.clone();
        let pose = match &mut still {
            LightDesc::Point { position, .. } => (std::mem::take(position), Vec3::ZERO),
            LightDesc::Spot {
                position,
                direction,
                ..
            } => (std::mem::take(position), std::mem::take(direction)),
            LightDesc::Directional { direction, .. } => (Vec3::ZERO, std::mem::take(direction)),
            _ => return None,
        };
        Some(((pose.0, pose.1.normalize_or_zero()), still))
    }
    let Some(first) = key_lights.first() else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for (i, l0) in first.iter().enumerate() {
        let same = |k: &Vec<LightDesc>| format!("{:?}", k[i]) == format!("{l0:?}");
        if key_lights.iter().all(same) {
            continue;
        }
        let Some((_, still0)) = pose(l0) else {
            return Err(format!("the light '{}' moves", l0.name()));
        };
        let mut poses = Vec::with_capacity(key_lights.len());
        for k in key_lights {
            match pose(&k[i]) {
                Some((p, still)) if format!("{still:?}") == format!("{still0:?}") => poses.push(p),
                _ => {
                    return Err(format!(
                        "the light '{}' changes more than its position and direction",
                        l0.name()
                    ));
                }
            }
        }
        out.push((i, poses));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LightDesc;

    fn point(x: f32, intensity: f32) -> LightDesc {
        LightDesc::Point {
            name: "bulb".into(),
            position: Vec3::new(x, 1.0, 0.0),
            intensity: Vec3::splat(intensity),
        }
    }

    /// A light that only moves is keyed (its position at every key); one whose power changes,
    /// or a moving light of a kind that has no pose, is named for the fallback.
    #[test]
    fn light_keys_take_poses_and_name_other_changes() {
        let still = LightDesc::Ambient {
            name: "sky".into(),
            radiance: Vec3::ONE,
        };
        let keys: Vec<Vec<LightDesc>> = (0..3)
            .map(|k| vec![still.clone(), point(k as f32, 1.0)])
            .collect();
        let got = light_keys(&keys).unwrap();
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].0, 1);
        let xs: Vec<f32> = got[0].1.iter().map(|(p, _)| p.x).collect();
        assert_eq!(xs, [0.0, 1.0, 2.0]);
        let brighter: Vec<Vec<LightDesc>> =
            (0..3).map(|k| vec![point(k as f32, k as f32)]).collect();
        let e = light_keys(&brighter).unwrap_err();
        assert!(
            e.contains("'bulb'") && e.contains("more than its position"),
            "{e}"
        );
        let sky: Vec<Vec<LightDesc>> = (0..2)
            .map(|k| {
                vec![LightDesc::Ambient {
                    name: "sky".into(),
                    radiance: Vec3::splat(k as f32),
                }]
            })
            .collect();
        assert!(light_keys(&sky).unwrap_err().contains("'sky'"));
    }
}
