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
//! - moving objects, lights and deforming meshes are posed and compiled at the middle of each
//!   of [`TimeOptions::steps`] equal parts of the shutter, each world with its own exact BVH,
//!   and a sample traces the world of the part holding its time: a stratified estimate of the
//!   shutter's average that converges to it as the steps grow. A scene whose only motion is
//!   its camera's is compiled once.
use super::{World, WorldOptions};
use crate::math::{Mat3, Mat4, Vec3};
use crate::scene::animation::{Animation, decompose};
use crate::scene::{Scene, SceneError};
use glam::Quat;

/// Frames per second when neither `--fps` nor the file gives one (film's rate, and Blender's
/// default).
pub const DEFAULT_FPS: f64 = 24.0;
/// Worlds a shutter is cut into unless `--shutter-steps` says.
pub const DEFAULT_SHUTTER_STEPS: u32 = 16;
/// The most `--shutter-steps` accepts (each step is a whole world in memory).
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
    /// `--shutter-steps`: worlds the shutter is cut into for moving objects, and the intervals
    /// between the camera's poses (0: [`DEFAULT_SHUTTER_STEPS`]).
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
    /// scene posed at the moment, or one world per shutter step (the first is this world, the
    /// others in [`World::motion`]). A scene in which nothing moves is built once, as a still
    /// (a warning says a shutter was ignored).
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
        let steps = if close > open && objects_move {
            opts.steps()
        } else {
            1
        };
        let mut first = scene.clone();
        first.pose(Some(step_time(open, close, 0, steps)));
        let mut w = World::build(first, options)?;
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

    /// True for a still: no step worlds and no moving camera.
    pub fn is_still(&self) -> bool {
        self.motion.is_empty() && self.camera_motion.is_none()
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
/// times, decomposed into translation, rotation and scale, interpolated piecewise (pbrt-v4
/// `AnimatedTransform::Interpolate`: translation and scale linearly, the rotation by slerp).
#[derive(Clone, Debug)]
pub struct CameraMotion {
    keys: Vec<(Vec3, Quat, Mat3)>,
}

impl CameraMotion {
    /// From the transforms at the shutter's opening, `keys.len() − 2` times between and its
    /// closing (at least two).
    pub fn new(keys: &[Mat4]) -> CameraMotion {
        assert!(keys.len() >= 2, "a camera motion needs two poses");
        let mut out: Vec<(Vec3, Quat, Mat3)> = Vec::with_capacity(keys.len());
        for &m in keys {
            let (s, mut r, t) = decompose(m);
            // q and −q are one rotation: keep each key on the previous one's side, so every
            // interval turns the short way.
            if let Some(prev) = out.last()
                && prev.1.dot(r) < 0.0
            {
                r = -r;
            }
            out.push((t, r, s));
        }
        CameraMotion { keys: out }
    }

    /// The world-from-camera transform at fraction `u` in [0, 1] of the shutter.
    #[inline]
    pub fn at(&self, u: f32) -> Mat4 {
        let n = self.keys.len() - 1;
        let x = u.clamp(0.0, 1.0) * n as f32;
        let i = (x as usize).min(n - 1);
        let f = x - i as f32;
        let (t0, r0, s0) = self.keys[i];
        let (t1, r1, s1) = self.keys[i + 1];
        let r = if f == 0.0 {
            r0
        } else {
            r0.slerp(r1, f).normalize()
        };
        let s = s0 * (1.0 - f) + s1 * f;
        Mat4::from_translation(t0.lerp(t1, f)) * Mat4::from_quat(r) * Mat4::from_mat3(s)
    }
}
