//! Scene animation: what a file says moves, and the scene posed at a moment (docs/DESIGN.md §3,
//! "Animation").
//!
//! A loader that finds motion attaches an [`Animation`] to the [`Scene`]: the node hierarchy of a
//! glTF file with its animation channels, skins and morph targets ([`Rig`]), or pbrt's
//! transforms at two times ([`RigidMotion`]). [`Scene::pose`] rewrites the object transforms,
//! cameras, lights and deformed vertex positions for a time, from data kept since the load, so a
//! sequence of frames reads the file once.
//!
//! Sampling follows the glTF 2.0 specification (§3.11 "Animations" and Appendix C
//! "Interpolation"): times before the first keyframe take the first value and after the last the
//! last; `STEP` holds a keyframe's value until the next, `LINEAR` interpolates (rotations by
//! spherical linear interpolation along the shorter arc), `CUBICSPLINE` is the Hermite spline of
//! the keyframes' in- and out-tangents scaled by the keyframe interval, rotations normalised.
//! Every channel of every animation in the file plays at once.

use std::sync::Arc;

use glam::Quat;

use crate::math::{Mat3, Mat4, Vec3, Vec4};

use super::{LightDesc, MeshId, Scene};

/// How a sampler interpolates between keyframes (glTF `animation.sampler.interpolation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

/// What a channel animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelPath {
    Translation,
    Rotation,
    Scale,
    /// Morph target weights; the count of targets.
    Weights(usize),
}

impl ChannelPath {
    /// Components of one output value.
    pub fn width(self) -> usize {
        match self {
            ChannelPath::Translation | ChannelPath::Scale => 3,
            ChannelPath::Rotation => 4,
            ChannelPath::Weights(n) => n,
        }
    }
}

/// One animation channel: a node's property sampled from keyframes.
#[derive(Clone, Debug)]
pub struct Channel {
    pub node: usize,
    pub path: ChannelPath,
    pub interpolation: Interpolation,
    /// Keyframe times in seconds, increasing.
    pub times: Vec<f64>,
    /// `width` components per keyframe (three groups of them for `CUBICSPLINE`: in-tangent,
    /// value, out-tangent).
    pub values: Vec<f64>,
}

impl Channel {
    /// The channel's value at time `t` (glTF 2.0 Appendix C), `width` components into `out`.
    pub fn sample(&self, t: f64, out: &mut [f64]) {
        let w = self.path.width();
        debug_assert_eq!(out.len(), w);
        let n = self.times.len();
        if n == 0 {
            return;
        }
        let cubic = self.interpolation == Interpolation::CubicSpline;
        // The value of keyframe k (the middle group for cubic splines).
        let value = |k: usize| -> &[f64] {
            let s = if cubic { (3 * k + 1) * w } else { k * w };
            &self.values[s..s + w]
        };
        if t <= self.times[0] || n == 1 {
            out.copy_from_slice(value(0));
            return;
        }
        if t >= self.times[n - 1] {
            out.copy_from_slice(value(n - 1));
            return;
        }
        // The keyframe interval holding t: times[k] <= t < times[k + 1].
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let td = t1 - t0;
        let s = if td > 0.0 { (t - t0) / td } else { 0.0 };
        match self.interpolation {
            Interpolation::Step => out.copy_from_slice(value(k)),
            Interpolation::Linear => {
                let (a, b) = (value(k), value(k + 1));
                if self.path == ChannelPath::Rotation {
                    slerp(a, b, s, out);
                } else {
                    for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
                        *o = a * (1.0 - s) + b * s;
                    }
                }
            }
            Interpolation::CubicSpline => {
                // Appendix C: p(s) = (2s³−3s²+1)v_k + td(s³−2s²+s)b_k + (−2s³+3s²)v_{k+1}
                // + td(s³−s²)a_{k+1}, with b_k the out-tangent of k and a_{k+1} the in-tangent
                // of k + 1.
                let group = |k: usize, g: usize| &self.values[(3 * k + g) * w..(3 * k + g + 1) * w];
                let (v0, b0) = (group(k, 1), group(k, 2));
                let (a1, v1) = (group(k + 1, 0), group(k + 1, 1));
                let (s2, s3) = (s * s, s * s * s);
                let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h10 = td * (s3 - 2.0 * s2 + s);
                let h01 = -2.0 * s3 + 3.0 * s2;
                let h11 = td * (s3 - s2);
                for (i, o) in out.iter_mut().enumerate() {
                    *o = h00 * v0[i] + h10 * b0[i] + h01 * v1[i] + h11 * a1[i];
                }
                if self.path == ChannelPath::Rotation {
                    normalize(out);
                }
            }
        }
    }
}

fn normalize(q: &mut [f64]) {
    let len = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    if len > 0.0 && len.is_finite() {
        q.iter_mut().for_each(|c| *c /= len);
    }
}

/// Spherical linear interpolation of unit quaternions along the shorter arc (glTF 2.0
/// Appendix C's `slerp`), falling back to normalised linear interpolation when they are almost
/// parallel (the sine would vanish).
fn slerp(a: &[f64], b: &[f64], s: f64, out: &mut [f64]) {
    let mut d: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    // q and −q are the same rotation: take the nearer one.
    let sign = if d < 0.0 { -1.0 } else { 1.0 };
    d *= sign;
    let (wa, wb) = if d > 0.9995 {
        (1.0 - s, s)
    } else {
        let theta = d.clamp(-1.0, 1.0).acos();
        let sin = theta.sin();
        (((1.0 - s) * theta).sin() / sin, (s * theta).sin() / sin)
    };
    for ((o, a), b) in out.iter_mut().zip(a).zip(b) {
        *o = wa * a + wb * sign * b;
    }
    normalize(out);
}

/// A node of the hierarchy: its parent and rest transform.
#[derive(Clone, Debug)]
pub struct RigNode {
    pub parent: Option<usize>,
    /// The node's `matrix` (never animated, glTF 2.0 §3.11), or its TRS.
    pub matrix: Option<Mat4>,
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
    /// Default morph weights (the node's `weights`, else its mesh's).
    pub weights: Vec<f64>,
}

/// A skin: joint nodes and their inverse bind matrices.
#[derive(Clone, Debug)]
pub struct Skin {
    pub joints: Vec<usize>,
    pub inverse_bind: Vec<Mat4>,
}

/// What a node places in the scene: a scene object (at the node's world transform times
/// `local`), a camera or a light.
#[derive(Clone, Copy, Debug)]
pub enum Placed {
    Object { object: usize, local: Mat4 },
    Camera(usize),
    Light(usize),
}

/// A mesh whose vertices move: morph targets blended by the node's weights, then skinned.
#[derive(Clone, Debug)]
pub struct Deformed {
    pub mesh: MeshId,
    pub node: usize,
    pub skin: Option<usize>,
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub tangents: Option<Vec<Vec4>>,
    /// Per morph target: position and normal displacements.
    pub target_positions: Vec<Vec<Vec3>>,
    pub target_normals: Vec<Option<Vec<Vec3>>>,
    /// Skin influences: `influences` (joint, weight) pairs per vertex, from every
    /// `JOINTS_n`/`WEIGHTS_n` set (a zero weight pads).
    pub influences: usize,
    pub joints: Vec<u32>,
    pub weights: Vec<f32>,
}

/// A glTF node hierarchy with its animation channels, skins and deformed meshes.
#[derive(Clone, Debug, Default)]
pub struct Rig {
    pub nodes: Vec<RigNode>,
    /// Nodes in an order that puts every parent before its children.
    pub order: Vec<usize>,
    pub channels: Vec<Channel>,
    pub skins: Vec<Skin>,
    /// (node, what it places).
    pub placed: Vec<(usize, Placed)>,
    pub deformed: Vec<Deformed>,
}

/// A transform that moves between two times (pbrt-v4's `AnimatedTransform`: the start and end
/// matrices decomposed into translation, rotation and scale, interpolated linearly, the rotation
/// by slerp; constant outside the interval).
#[derive(Clone, Copy, Debug)]
pub struct MovingTransform {
    pub times: [f64; 2],
    pub start: Mat4,
    pub end: Mat4,
}

impl MovingTransform {
    pub fn at(&self, t: f64) -> Mat4 {
        let [t0, t1] = self.times;
        let s = if t1 > t0 {
            ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        if s == 0.0 {
            return self.start;
        }
        if s == 1.0 {
            return self.end;
        }
        let (s0, r0, t0) = decompose(self.start);
        let (s1, r1, t1) = decompose(self.end);
        let q0 = [r0.x as f64, r0.y as f64, r0.z as f64, r0.w as f64];
        let q1 = [r1.x as f64, r1.y as f64, r1.z as f64, r1.w as f64];
        let mut q = [0.0; 4];
        slerp(&q0, &q1, s, &mut q);
        let sf = s as f32;
        let rot = Quat::from_xyzw(q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32);
        Mat4::from_translation(t0.lerp(t1, sf))
            * Mat4::from_quat(rot)
            * Mat4::from_mat3(Mat3::from_cols_array(&[
                s0.x_axis.x + (s1.x_axis.x - s0.x_axis.x) * sf,
                s0.x_axis.y + (s1.x_axis.y - s0.x_axis.y) * sf,
                s0.x_axis.z + (s1.x_axis.z - s0.x_axis.z) * sf,
                s0.y_axis.x + (s1.y_axis.x - s0.y_axis.x) * sf,
                s0.y_axis.y + (s1.y_axis.y - s0.y_axis.y) * sf,
                s0.y_axis.z + (s1.y_axis.z - s0.y_axis.z) * sf,
                s0.z_axis.x + (s1.z_axis.x - s0.z_axis.x) * sf,
                s0.z_axis.y + (s1.z_axis.y - s0.z_axis.y) * sf,
                s0.z_axis.z + (s1.z_axis.z - s0.z_axis.z) * sf,
            ]))
    }
}

pub(crate) use crate::math::decompose;

/// Rigid motion from a pbrt file: an object's or the camera's transform at two times.
#[derive(Clone, Copy, Debug)]
pub enum RigidMotion {
    Object {
        object: usize,
        motion: MovingTransform,
    },
    Camera {
        camera: usize,
        motion: MovingTransform,
    },
    /// A shape of a pbrt `ObjectInstance` under a moving transform: the object's transform is
    /// the instance's, interpolated, times `part`, the shape's transform inside `ObjectBegin`
    /// (pbrt-v4 interpolates the instance's transform and applies the definition's after it).
    Instance {
        object: usize,
        motion: MovingTransform,
        part: Mat4,
    },
}

/// Everything in a scene that moves, kept with the scene so it can be posed at any time.
#[derive(Clone, Debug, Default)]
pub struct Animation {
    pub rig: Option<Rig>,
    pub rigid: Vec<RigidMotion>,
    /// The file's frame rate, when it says (`--frame` uses it unless `--fps` is given).
    pub fps: Option<f64>,
    /// The file's camera shutter (pbrt `shutteropen`/`shutterclose`), when it has one.
    pub shutter: Option<(f64, f64)>,
    /// Number of animations in the file (glTF), for messages.
    pub clips: usize,
}

impl Animation {
    /// The interval the keyframes span (glTF), or the motion's times (pbrt).
    pub fn time_range(&self) -> Option<(f64, f64)> {
        let mut range: Option<(f64, f64)> = None;
        let mut add = |a: f64, b: f64| {
            range = Some(match range {
                Some((x, y)) => (x.min(a), y.max(b)),
                None => (a, b),
            })
        };
        if let Some(rig) = &self.rig {
            for c in &rig.channels {
                if let (Some(&a), Some(&b)) = (c.times.first(), c.times.last()) {
                    add(a, b);
                }
            }
        }
        for m in &self.rigid {
            let (RigidMotion::Object { motion, .. }
            | RigidMotion::Camera { motion, .. }
            | RigidMotion::Instance { motion, .. }) = m;
            add(motion.times[0], motion.times[1]);
        }
        range
    }

    /// Whether anything changes with time (a rig may only have static skins).
    pub fn moves(&self) -> bool {
        !self.rigid.is_empty() || self.rig.as_ref().is_some_and(|r| !r.channels.is_empty())
    }

    /// Whether anything but cameras changes with time: objects, lights or deformed meshes.
    /// A scene whose only motion is its camera's is blurred with one world
    /// (crate::world::motion).
    pub fn moves_beyond_cameras(&self) -> bool {
        if self
            .rigid
            .iter()
            .any(|m| matches!(m, RigidMotion::Object { .. } | RigidMotion::Instance { .. }))
        {
            return true;
        }
        let Some(rig) = &self.rig else {
            return false;
        };
        // A node moves when a channel animates it or an ancestor (parents come first in
        // `order`).
        let mut moving = vec![false; rig.nodes.len()];
        for c in &rig.channels {
            if let Some(m) = moving.get_mut(c.node) {
                *m = true;
            }
        }
        for &i in &rig.order {
            if let Some(p) = rig.nodes[i].parent {
                moving[i] |= moving[p];
            }
        }
        let placed_moves = rig
            .placed
            .iter()
            .any(|&(node, p)| moving[node] && !matches!(p, Placed::Camera(_)));
        let deformed_moves = rig.deformed.iter().any(|d| {
            moving[d.node]
                || d.skin
                    .is_some_and(|s| rig.skins[s].joints.iter().any(|&j| moving[j]))
        });
        placed_moves || deformed_moves
    }

    /// The world-from-camera transform of scene camera `camera` at time `t`, as
    /// [`Scene::pose`] would set it, if the animation moves that camera; the rest of the scene
    /// is not posed.
    pub fn camera_at(&self, camera: usize, t: f64) -> Option<Mat4> {
        for m in &self.rigid {
            if let RigidMotion::Camera { camera: c, motion } = m
                && *c == camera
            {
                return Some(motion.at(t));
            }
        }
        let rig = self.rig.as_ref().filter(|r| !r.channels.is_empty())?;
        let &(node, _) = rig
            .placed
            .iter()
            .find(|(_, p)| matches!(p, Placed::Camera(c) if *c == camera))?;
        let (world, _) = rig.node_pose(Some(t));
        Some(rigid(world[node]))
    }
}

/// Cameras ignore scale: the rotation and the position only.
pub fn rigid(world: Mat4) -> Mat4 {
    Mat4::from_cols(
        world.x_axis.truncate().normalize_or_zero().extend(0.0),
        world.y_axis.truncate().normalize_or_zero().extend(0.0),
        world.z_axis.truncate().normalize_or_zero().extend(0.0),
        world.w_axis,
    )
}

impl Rig {
    /// World matrices and morph weights of every node at time `t` (`None`: the rest pose, no
    /// channel applied).
    pub fn node_pose(&self, t: Option<f64>) -> (Vec<Mat4>, Vec<Vec<f64>>) {
        let n = self.nodes.len();
        let mut trs: Vec<(Vec3, Quat, Vec3)> = self
            .nodes
            .iter()
            .map(|nd| (nd.translation, nd.rotation, nd.scale))
            .collect();
        let mut animated = vec![false; n];
        let mut weights: Vec<Vec<f64>> = self.nodes.iter().map(|nd| nd.weights.clone()).collect();
        if let Some(t) = t {
            let mut buf = Vec::new();
            for c in &self.channels {
                buf.clear();
                buf.resize(c.path.width(), 0.0);
                c.sample(t, &mut buf);
                let v3 = |b: &[f64]| Vec3::new(b[0] as f32, b[1] as f32, b[2] as f32);
                let e = &mut trs[c.node];
                match c.path {
                    ChannelPath::Translation => e.0 = v3(&buf),
                    ChannelPath::Scale => e.2 = v3(&buf),
                    ChannelPath::Rotation => {
                        e.1 = Quat::from_xyzw(
                            buf[0] as f32,
                            buf[1] as f32,
                            buf[2] as f32,
                            buf[3] as f32,
                        )
                    }
                    ChannelPath::Weights(_) => {
                        weights[c.node] = buf.clone();
                        continue;
                    }
                }
                animated[c.node] = true;
            }
        }
        let mut world = vec![Mat4::IDENTITY; n];
        for &i in &self.order {
            let nd = &self.nodes[i];
            let local = match nd.matrix {
                Some(m) if !animated[i] => m,
                _ => {
                    let (t, r, s) = trs[i];
                    Mat4::from_scale_rotation_translation(s, r, t)
                }
            };
            world[i] = match nd.parent {
                Some(p) => world[p] * local,
                None => local,
            };
        }
        (world, weights)
    }
}

impl Scene {
    /// Poses the scene at time `t` in seconds (`None`: the rest pose of the file, skins and
    /// default morph weights applied, no animation channel). Objects, cameras, lights and the
    /// vertices of deformed meshes are rewritten from the [`Animation`] kept since the load;
    /// a scene without one is left as it is.
    pub fn pose(&mut self, t: Option<f64>) {
        let Some(anim) = self.animation.clone() else {
            return;
        };
        if let Some(rig) = &anim.rig {
            self.pose_rig(rig, t);
        }
        let time = t.unwrap_or(0.0);
        for m in &anim.rigid {
            match *m {
                RigidMotion::Object { object, motion } => {
                    if let Some(o) = self.objects.get_mut(object) {
                        o.transform = motion.at(time);
                    }
                }
                RigidMotion::Camera { camera, motion } => {
                    if let Some(c) = self.cameras.get_mut(camera) {
                        c.camera_to_world = motion.at(time);
                    }
                }
                RigidMotion::Instance {
                    object,
                    motion,
                    part,
                } => {
                    if let Some(o) = self.objects.get_mut(object) {
                        o.transform = motion.at(time) * part;
                    }
                }
            }
        }
    }

    fn pose_rig(&mut self, rig: &Rig, t: Option<f64>) {
        let (world, weights) = rig.node_pose(t);
        let skinned: std::collections::HashSet<usize> = rig
            .deformed
            .iter()
            .filter(|d| d.skin.is_some())
            .map(|d| d.mesh)
            .collect();
        for &(node, placed) in &rig.placed {
            let w = world[node];
            match placed {
                Placed::Object { object, local } => {
                    if let Some(o) = self.objects.get_mut(object) {
                        // glTF 2.0 §3.7.3.3: a skinned mesh ignores its node's transform; the
                        // joints place it.
                        let is_skinned =
                            matches!(o.shape, super::Shape::Mesh(m) if skinned.contains(&m));
                        o.transform = if is_skinned {
                            Mat4::IDENTITY
                        } else {
                            w * local
                        };
                    }
                }
                Placed::Camera(c) => {
                    if let Some(c) = self.cameras.get_mut(c) {
                        c.camera_to_world = rigid(w);
                    }
                }
                Placed::Light(l) => {
                    let position = w.transform_point3(Vec3::ZERO);
                    let dir = w.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
                    match self.lights.get_mut(l) {
                        Some(LightDesc::Point { position: p, .. }) => *p = position,
                        Some(LightDesc::Spot {
                            position: p,
                            direction: d,
                            ..
                        }) => {
                            *p = position;
                            *d = dir;
                        }
                        Some(LightDesc::Directional { direction: d, .. }) => *d = dir,
                        _ => {}
                    }
                }
            }
        }
        for d in &rig.deformed {
            let Some(mesh) = self.meshes.get_mut(d.mesh) else {
                continue;
            };
            let (p, n, tg) = deform(d, &weights[d.node], d.skin.map(|s| (&rig.skins[s], &world)));
            mesh.positions = p;
            mesh.normals = n;
            mesh.tangents = tg;
        }
    }
}

/// A deformed mesh's vertices: morph targets blended with `weights` (glTF 2.0 §3.7.2.2), then
/// linear blend skinning by the joints' world matrices times their inverse bind matrices
/// (§3.7.3). Normals go through the inverse transpose of each vertex's blended matrix.
#[allow(clippy::type_complexity)]
pub fn deform(
    d: &Deformed,
    weights: &[f64],
    skin: Option<(&Skin, &Vec<Mat4>)>,
) -> (Vec<Vec3>, Option<Vec<Vec3>>, Option<Vec<Vec4>>) {
    let mut p = d.positions.clone();
    let mut n = d.normals.clone();
    let mut tg = d.tangents.clone();
    for (k, w) in weights.iter().enumerate() {
        let w = *w as f32;
        if w == 0.0 {
            continue;
        }
        if let Some(dp) = d.target_positions.get(k) {
            p.iter_mut().zip(dp).for_each(|(p, dp)| *p += w * *dp);
        }
        if let (Some(n), Some(Some(dn))) = (n.as_mut(), d.target_normals.get(k)) {
            n.iter_mut().zip(dn).for_each(|(n, dn)| *n += w * *dn);
        }
    }
    if let Some((skin, world)) = skin {
        let joint_mats: Vec<Mat4> = skin
            .joints
            .iter()
            .zip(&skin.inverse_bind)
            .map(|(&j, ibm)| world.get(j).copied().unwrap_or(Mat4::IDENTITY) * *ibm)
            .collect();
        let k = d.influences;
        for (v, pv) in p.iter_mut().enumerate() {
            let mut m = Mat4::ZERO;
            for i in 0..k {
                let w = d.weights.get(v * k + i).copied().unwrap_or(0.0);
                if w != 0.0 {
                    let j = d.joints[v * k + i] as usize;
                    m += joint_mats.get(j).copied().unwrap_or(Mat4::IDENTITY) * w;
                }
            }
            *pv = m.transform_point3(*pv);
            let lin = Mat3::from_mat4(m);
            if let Some(n) = n.as_mut() {
                n[v] = lin.inverse().transpose() * n[v];
            }
            if let Some(tg) = tg.as_mut() {
                let x = (lin * tg[v].truncate()).normalize_or_zero();
                tg[v] = x.extend(tg[v].w);
            }
        }
    }
    if let Some(n) = n.as_mut() {
        n.iter_mut().for_each(|n| *n = n.normalize_or_zero());
    }
    (p, n, tg)
}

/// Shared handle kept in [`Scene::animation`].
pub type AnimationRef = Arc<Animation>;

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(path: ChannelPath, interp: Interpolation, times: &[f64], values: &[f64]) -> Channel {
        Channel {
            node: 0,
            path,
            interpolation: interp,
            times: times.to_vec(),
            values: values.to_vec(),
        }
    }

    #[test]
    fn step_linear_and_clamping() {
        let c = channel(
            ChannelPath::Translation,
            Interpolation::Step,
            &[1.0, 2.0],
            &[0.0, 0.0, 0.0, 4.0, 8.0, 2.0],
        );
        let mut o = [0.0; 3];
        c.sample(1.5, &mut o);
        assert_eq!(o, [0.0; 3]);
        c.sample(2.0, &mut o);
        assert_eq!(o, [4.0, 8.0, 2.0]);
        let l = Channel {
            interpolation: Interpolation::Linear,
            ..c.clone()
        };
        l.sample(1.25, &mut o);
        assert_eq!(o, [1.0, 2.0, 0.5]);
        l.sample(-3.0, &mut o);
        assert_eq!(o, [0.0; 3]);
        l.sample(9.0, &mut o);
        assert_eq!(o, [4.0, 8.0, 2.0]);
    }

    #[test]
    fn slerp_takes_the_shorter_arc() {
        // 0° and 350° about z: the quaternions' dot product is negative, so the nearer copy
        // of the second (−10°) is taken and halfway is −5°, not 175°.
        let h = |deg: f64| deg.to_radians() / 2.0;
        let a = [0.0, 0.0, 0.0, 1.0];
        let b = [0.0, 0.0, h(350.0).sin(), h(350.0).cos()];
        let c = channel(
            ChannelPath::Rotation,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[a, b].concat(),
        );
        let mut o = [0.0; 4];
        c.sample(0.5, &mut o);
        let angle = 2.0 * o[2].atan2(o[3]);
        assert!(
            (angle.to_degrees() + 5.0).abs() < 1e-9,
            "{}",
            angle.to_degrees()
        );
    }

    #[test]
    fn cubic_spline_hermite() {
        // One component, v0 = 0, b0 = 1, a1 = 1, v1 = 1 over [0, 2]: a line of slope 1/2 in s
        // scaled by td = 2 → p(s) = 2·(s³−2s²+s)·1 + (−2s³+3s²)·1 + 2·(s³−s²)·1 = s … at s = ½,
        // 2·(1/8 − 1/2 + 1/2) + (−1/4 + 3/4) + 2·(1/8 − 1/4) = 1/4 + 1/2 − 1/4 = 1/2.
        let c = channel(
            ChannelPath::Weights(1),
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            &[9.0, 0.0, 1.0, 1.0, 1.0, 9.0],
        );
        let mut o = [0.0; 1];
        c.sample(1.0, &mut o);
        assert!((o[0] - 0.5).abs() < 1e-12, "{o:?}");
        c.sample(2.0, &mut o);
        assert_eq!(o[0], 1.0);
    }

    #[test]
    fn moving_transform_interpolates_trs() {
        let a = Mat4::from_translation(Vec3::new(0.0, 0.0, 0.0));
        let b = Mat4::from_translation(Vec3::new(2.0, 0.0, 0.0))
            * Mat4::from_rotation_z(std::f32::consts::FRAC_PI_2)
            * Mat4::from_scale(Vec3::splat(3.0));
        let m = MovingTransform {
            times: [0.0, 1.0],
            start: a,
            end: b,
        };
        let h = m.at(0.5);
        let p = h.transform_point3(Vec3::X);
        // Halfway: translated by 1, turned 45°, scaled by 2.
        let r = std::f32::consts::FRAC_1_SQRT_2 * 2.0;
        assert!((p - Vec3::new(1.0 + r, r, 0.0)).length() < 1e-4, "{p}");
        assert_eq!(m.at(-1.0), a);
        assert_eq!(m.at(2.0), b);
    }
}
