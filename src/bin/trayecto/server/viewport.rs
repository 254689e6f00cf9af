//! The interactive viewport: a progressive preview that follows the page's camera.
//!
//! Each page opens one *session* (an id it makes up). A session owns a worker thread that keeps
//! the compiled [`World`] of its scene, so a camera move only swaps the camera: no reload, no
//! rebuild. Every request bumps the session's generation and raises its cancel flag, which the
//! render driver polls per tile, so a stale preview stops at once and previews never pile up.
//! The worker then renders the new view at a quarter of the size with 1 sample per pixel, and
//! then at full size pass after pass (1, 1, 2, 4, … samples) up to the request's `spp`, publishing
//! the linear film after each pass for the page to tone-map itself.
//!
//! Previews do not enter the render queue: rendering a view takes no slot of `--max-jobs` and
//! never delays or refuses a final render (it shares the CPU with running renders). Loading and
//! building a scene file's world is a load like a render's: it waits for a slot
//! ([`super::jobs::Jobs::run_load_in`]) and runs under a job's memory budget and the session's
//! cancel flag, whose charges stay counted as long as the session keeps the world. At most [`MAX_SESSIONS`]
//! sessions live; a new one closes the least recently used, and a session idle for
//! [`IDLE_CLOSE`] closes itself, freeing its world.

use super::jobs::Jobs;
use super::request::{RenderRequest, SceneSource, camera_json};
use serde_json::{Value, json};
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};
use trayecto::camera::CameraSpec;
use trayecto::film::{Film, Image};
use trayecto::render::{RenderObserver, RenderSettings};
use trayecto::scene::{CameraDesc, Projection, SphericalMapping};
use trayecto::world::{World, WorldOptions};

/// Viewport sessions alive at once (each may hold a compiled scene in memory).
pub const MAX_SESSIONS: usize = 4;
/// A session without requests for this long frees its world and ends.
pub const IDLE_CLOSE: Duration = Duration::from_secs(300);
/// Longest session id a page may choose.
pub const MAX_SESSION_ID: usize = 64;

/// The view the page orbits around: the camera the scene would render with (its first, or the
/// framing camera for a model without one) with its target moved to where the view ray passes
/// the centre of the scene's bounds, and the bounds themselves.
pub fn view_json(world: &World) -> Value {
    let projection = projection_name(&world.camera.projection);
    let mut cam = CameraSpec::from_desc(&world.camera);
    let b = world.bounds;
    let finite = b.min.is_finite() && b.max.is_finite() && b.min.cmple(b.max).all();
    if finite {
        let centre = (b.min + b.max) * 0.5;
        let dir = (cam.target - cam.eye).normalize_or_zero();
        let t = (centre - cam.eye).dot(dir);
        if t > 1e-6 * (1.0 + cam.eye.length()) {
            cam.target = cam.eye + dir * t;
        }
    }
    json!({
        "camera": camera_json(&cam),
        "projection": projection,
        "bounds": if finite { json!({"min": b.min.to_array(), "max": b.max.to_array()}) } else { Value::Null },
    })
}

/// The name the page shows for a scene camera's projection. The orbit's `camera` is a
/// perspective eye/target/up/fov: only a request without a camera renders the scene's own
/// orthographic or spherical projection (and its off-centre screen window, kept in its matrix).
pub fn projection_name(p: &Projection) -> &'static str {
    match p {
        Projection::Perspective => "perspective",
        Projection::Orthographic { .. } => "orthographic",
        Projection::Spherical(SphericalMapping::EqualArea) => "spherical (equal-area)",
        Projection::Spherical(SphericalMapping::Equirectangular) => "spherical (equirectangular)",
    }
}

/// What must match for the worker to reuse its world.
#[derive(Clone, Debug, PartialEq)]
struct WorldKey {
    scene: String,
    default_light: Option<trayecto::light::default_light::DefaultLight>,
    variant: Option<String>,
    env: Option<std::path::PathBuf>,
    env_rotation: f32,
    /// The moment of an animated scene (a sequence's first frame); the viewport shows that
    /// pose without motion blur.
    time: trayecto::world::motion::TimeOptions,
}

impl WorldKey {
    fn of(r: &RenderRequest) -> WorldKey {
        WorldKey {
            scene: r.source.load_spec(),
            default_light: r.default_light,
            variant: r.variant.clone(),
            env: r.environment.as_ref().map(|(_, p)| p.clone()),
            env_rotation: r.env_rotation,
            time: trayecto::world::motion::TimeOptions {
                time: r.time.time,
                frame: r.time.frame.or(r.frames.map(|f| f.0)),
                fps: r.time.fps,
                shutter: None,
                steps: 0,
            },
        }
    }
}

/// A session's built scene: the world, what it was built from, and what the scene itself asks
/// for that a request may not override.
struct Built {
    key: WorldKey,
    world: World,
    /// The scene's own camera (`world.camera` is replaced per view).
    own_camera: CameraDesc,
    /// The file's pixel filter (pbrt `PixelFilter`), used unless the request names one.
    filter: Option<trayecto::film::filter::Filter>,
    /// The file renders spectrally by default (pbrt), used unless the request says.
    prefers_spectral: bool,
    /// The memory budget the world was loaded under: what it charged stays counted against the
    /// server's total while the world lives.
    _budget: Arc<trayecto::limits::LoadContext>,
}

/// What the page reads back.
#[derive(Default)]
struct ViewStatus {
    /// The request generation the image and state belong to.
    generation: u64,
    /// Bumped at each published image.
    version: u64,
    state: &'static str,
    image: Option<Arc<Image>>,
    samples: u32,
    spp: u32,
    error: Option<String>,
    /// The scene's own view and bounds (for the orbit), once the world is built.
    view: Option<Value>,
    /// Milliseconds from the request to its first image, and to its first full-size pass.
    first_ms: Option<f64>,
    full_ms: Option<f64>,
    build_ms: Option<f64>,
}

struct Pending {
    generation: u64,
    request: Option<(RenderRequest, Instant)>,
    closed: bool,
}

pub struct Session {
    pending: Mutex<Pending>,
    wake: Condvar,
    cancel: AtomicBool,
    status: Mutex<ViewStatus>,
    last_used: Mutex<Instant>,
    jobs: Jobs,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Session {
    fn close(&self) {
        lock(&self.pending).closed = true;
        self.cancel.store(true, Ordering::Relaxed);
        self.wake.notify_all();
    }

    pub fn json(&self) -> Value {
        let st = lock(&self.status);
        json!({
            "generation": st.generation,
            "version": st.version,
            "state": st.state,
            "samples": st.samples,
            "spp": st.spp,
            "width": st.image.as_ref().map(|i| i.width),
            "height": st.image.as_ref().map(|i| i.height),
            "error": st.error,
            "view": st.view,
            "first_ms": st.first_ms,
            "full_ms": st.full_ms,
            "build_ms": st.build_ms,
        })
    }

    /// The image on show with its version and samples.
    pub fn image(&self) -> Option<(Arc<Image>, u64, u32)> {
        let st = lock(&self.status);
        st.image.clone().map(|i| (i, st.version, st.samples))
    }
}

#[derive(Clone, Default)]
pub struct Viewports {
    sessions: Arc<Mutex<HashMap<String, Arc<Session>>>>,
}

impl Viewports {
    pub fn get(&self, id: &str) -> Option<Arc<Session>> {
        lock(&self.sessions).get(id).cloned()
    }

    /// Hands the session `id` a new view (opening the session if needed) and cancels the view
    /// it was rendering. Returns the request's generation.
    pub fn submit(&self, id: &str, request: RenderRequest, jobs: &Jobs) -> Result<u64, String> {
        let session = {
            let mut map = lock(&self.sessions);
            match map.get(id) {
                // A session that closed itself (idle) but is not yet forgotten is replaced.
                Some(s) if !lock(&s.pending).closed => s.clone(),
                _ => {
                    map.remove(id);
                    if map.len() >= MAX_SESSIONS {
                        let oldest = map
                            .iter()
                            .min_by_key(|(_, s)| *lock(&s.last_used))
                            .map(|(k, _)| k.clone());
                        if let Some(k) = oldest
                            && let Some(s) = map.remove(&k)
                        {
                            s.close();
                        }
                    }
                    let s = Arc::new(Session {
                        pending: Mutex::new(Pending {
                            generation: 0,
                            request: None,
                            closed: false,
                        }),
                        wake: Condvar::new(),
                        cancel: AtomicBool::new(false),
                        status: Mutex::new(ViewStatus {
                            state: "idle",
                            ..Default::default()
                        }),
                        last_used: Mutex::new(Instant::now()),
                        jobs: jobs.clone(),
                    });
                    let worker = s.clone();
                    let all = self.clone();
                    let key = id.to_string();
                    std::thread::Builder::new()
                        .name("viewport".into())
                        .spawn(move || {
                            run(&worker);
                            // Forget the session if it is still the one registered under its id.
                            let mut map = lock(&all.sessions);
                            if map.get(&key).is_some_and(|s| Arc::ptr_eq(s, &worker)) {
                                map.remove(&key);
                            }
                        })
                        .map_err(|e| format!("could not start the viewport thread: {e}"))?;
                    map.insert(id.to_string(), s.clone());
                    s
                }
            }
        };
        *lock(&session.last_used) = Instant::now();
        let mut p = lock(&session.pending);
        p.generation += 1;
        p.request = Some((request, Instant::now()));
        // Under the same lock the worker takes requests with, so it cannot miss the flag.
        session.cancel.store(true, Ordering::Relaxed);
        session.wake.notify_all();
        Ok(p.generation)
    }
}

/// Publishes each finished pass of the current generation.
struct Publish<'a> {
    session: &'a Session,
    generation: u64,
    since: Instant,
    full_size: bool,
}

impl Publish<'_> {
    fn show(&self, image: Image, samples: u32, spp: u32) {
        if self.session.cancel.load(Ordering::Relaxed) {
            return;
        }
        let ms = self.since.elapsed().as_secs_f64() * 1e3;
        let mut st = lock(&self.session.status);
        if st.generation != self.generation {
            return;
        }
        st.image = Some(Arc::new(image));
        st.version += 1;
        st.samples = samples;
        st.spp = spp;
        st.first_ms.get_or_insert(ms);
        if self.full_size {
            st.full_ms.get_or_insert(ms);
            st.state = if samples >= spp { "done" } else { "refining" };
        } else {
            st.state = "preview";
        }
    }
}

impl RenderObserver for Publish<'_> {
    fn pass_done(&self, film: &Film, samples_done: u32, spp: u32) {
        self.show(film.to_image(), samples_done, spp);
    }
}

/// The session's worker: waits for the newest request, renders it, and ends when the session
/// is closed or idle.
fn run(session: &Arc<Session>) {
    let mut world: Option<Built> = None;
    let mut seen = 0;
    loop {
        let (generation, request, since) = {
            let mut p = lock(&session.pending);
            loop {
                if p.closed {
                    return;
                }
                if p.generation > seen
                    && let Some((r, t)) = p.request.take()
                {
                    session.cancel.store(false, Ordering::Relaxed);
                    break (p.generation, r, t);
                }
                let (guard, timeout) = session
                    .wake
                    .wait_timeout(p, IDLE_CLOSE)
                    .unwrap_or_else(|e| e.into_inner());
                p = guard;
                if timeout.timed_out() && lock(&session.last_used).elapsed() >= IDLE_CLOSE {
                    p.closed = true;
                }
            }
        };
        seen = generation;
        {
            let mut st = lock(&session.status);
            st.generation = generation;
            st.state = "loading";
            st.error = None;
            st.first_ms = None;
            st.full_ms = None;
        }
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            render_view(session, &mut world, generation, &request, since)
        }));
        let failed = match r {
            Ok(Ok(())) => None,
            Ok(Err(m)) => Some(m),
            Err(_) => {
                world = None;
                Some("internal error: the renderer panicked".to_string())
            }
        };
        if let Some(m) = failed {
            let mut st = lock(&session.status);
            if st.generation == generation {
                st.state = "failed";
                st.error = Some(m);
            }
        }
    }
}

fn render_view(
    session: &Arc<Session>,
    cache: &mut Option<Built>,
    generation: u64,
    r: &RenderRequest,
    since: Instant,
) -> Result<(), String> {
    let key = WorldKey::of(r);
    let stale = || session.cancel.load(Ordering::Relaxed);
    if cache.as_ref().is_none_or(|b| b.key != key) {
        *cache = None;
        // The old world's view must not be read as the new scene's (the page takes the first
        // view it sees after choosing a scene as that scene's home view).
        lock(&session.status).view = None;
        let t = Instant::now();
        let name_it = |m: String| match &r.source {
            SceneSource::File(p) => m.replace(&*p.to_string_lossy(), &r.scene),
            SceneSource::Builtin(_) => m,
        };
        let flag = session.clone();
        let ctx = session
            .jobs
            .view_context(Arc::new(move || flag.cancel.load(Ordering::Relaxed)));
        let builtin = matches!(r.source, SceneSource::Builtin(_));
        let loaded = session.jobs.run_load_in(builtin, ctx.clone(), || {
            let mut scene =
                trayecto::scene::load(&key.scene).map_err(|e| name_it(e.to_string()))?;
            if let Some(v) = &r.variant {
                scene
                    .select_variant(v)
                    .map_err(|e| name_it(e.to_string()))?;
            }
            if stale() {
                return Ok(None);
            }
            let filter = scene.hints.filter;
            let prefers_spectral = scene.hints.spectral;
            let options = WorldOptions {
                default_light: r.default_light,
                variant: r.variant.clone(),
                env: key.env.clone(),
                env_rotation: key.env_rotation,
                time: key.time.clone(),
                ..WorldOptions::default()
            };
            let w = World::build_posed(scene, &options).map_err(|e| name_it(e.to_string()))?;
            Ok(Some((w, filter, prefers_spectral)))
        });
        let (w, filter, prefers_spectral) = match loaded {
            Ok(Some(built)) => built,
            // A newer request replaced this one while it loaded (its load was cancelled).
            Ok(None) => return Ok(()),
            Err(_) if stale() => return Ok(()),
            Err(e) => return Err(e),
        };
        let view = view_json(&w);
        let mut st = lock(&session.status);
        st.view = Some(view);
        st.build_ms = Some(t.elapsed().as_secs_f64() * 1e3);
        drop(st);
        *cache = Some(Built {
            key,
            own_camera: w.camera.clone(),
            world: w,
            filter,
            prefers_spectral,
            _budget: ctx,
        });
    }
    let Built {
        world,
        own_camera,
        filter,
        prefers_spectral,
        ..
    } = cache.as_mut().expect("built above");
    // Without a camera the scene's own camera is rendered as the command line renders it: its
    // projection, lens and screen window, not the perspective eye/target/fov `view` reports
    // for the orbit. A camera from the page is a perspective view.
    world.camera = match r.camera {
        Some(c) => c.to_desc("viewport"),
        None => own_camera.clone(),
    };
    if stale() {
        return Ok(());
    }
    lock(&session.status).state = "rendering";
    // The scene file's pixel filter unless the request names one, as the final render's
    // `RenderJob::resolve` does, so the viewport refines to the final render's image.
    let mut full = RenderSettings {
        time_limit: None,
        filter: match filter {
            Some(f) if !r.filter_given => *f,
            _ => r.settings.filter,
        },
        ..r.settings.clone()
    };
    // Spectral or RGB as the final render resolves it: the request's, else the file's default,
    // RGB where the integrator has no spectral path.
    let given = trayecto::pipeline::GivenSettings {
        spectral: r.spectral_given,
        ..trayecto::pipeline::GivenSettings::ALL
    };
    if !r.spectral_given {
        full.path.spectral = *prefers_spectral;
    }
    let _ = trayecto::pipeline::rgb_fallback(&given, world, &mut full, &[]);
    // The quick first look: a quarter of the size, one sample per pixel.
    let quick = RenderSettings {
        width: full.width.div_ceil(4).max(1),
        height: full.height.div_ceil(4).max(1),
        spp: 1,
        noise_threshold: None,
        time_limit: None,
        ..full.clone()
    };
    let small = Publish {
        session,
        generation,
        since,
        full_size: false,
    };
    let cancelled =
        |e: &trayecto::render::RenderError| matches!(e, trayecto::render::RenderError::Cancelled);
    match trayecto::render::render(
        world,
        &quick,
        &trayecto::render::NoObserver,
        &session.cancel,
    ) {
        Ok(out) => small.show(out.image, 0, full.spp),
        Err(e) if cancelled(&e) => return Ok(()),
        Err(e) => return Err(e.to_string()),
    }
    let big = Publish {
        full_size: true,
        ..small
    };
    match trayecto::render::render(world, &full, &big, &session.cancel) {
        Ok(_) => Ok(()),
        Err(e) if cancelled(&e) => Ok(()),
        Err(e) => Err(e.to_string()),
    }
}
