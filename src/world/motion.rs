//! Time: the moment of an animated scene a render shows, and motion blur (docs/DESIGN.md §5,
//! "Motion blur").
//!
//! The scene is posed ([`Scene::pose`]) at `--time` seconds, or at `--frame` N of `--fps`
//! (the file's frame rate where it has one, else [`DEFAULT_FPS`]). With a shutter the shutter
//! interval is cut into [`TimeOptions::steps`] equal parts and the scene is posed and compiled at
//! the middle of each: every camera sample draws a time in [0, 1) after its film and lens
//! numbers (one more dimension of the sample's stream, so the image is a pure function of the
//! seed and splits and resumes stay exact), and traces the world of the part holding it — a
//! stratified estimate of the shutter's average in which moving cameras, rigid objects, skinned
//! and morphing meshes all move, each world with its own exact BVH. Without a shutter nothing
//! is drawn and stills are unchanged.

use super::{World, WorldOptions};
use crate::scene::animation::Animation;
use crate::scene::{Scene, SceneError};

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
    /// `--shutter-steps`: worlds the shutter is cut into (0: [`DEFAULT_SHUTTER_STEPS`]).
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
        let steps = if close > open { opts.steps() } else { 1 };
        let mut first = scene.clone();
        first.pose(Some(step_time(open, close, 0, steps)));
        let mut w = World::build(first, options)?;
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

    /// Worlds a camera sample chooses from by its time: 1 for a still.
    pub fn time_steps(&self) -> usize {
        1 + self.motion.len()
    }

    /// The world of shutter step `k` ([`World::build_posed`]).
    #[inline]
    pub fn at_step(&self, k: usize) -> &World {
        if k == 0 { self } else { &self.motion[k - 1] }
    }
}
