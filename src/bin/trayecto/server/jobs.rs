//! Render jobs: each runs on its own thread through the library's pipeline (`pipeline::RenderJob`), with an
//! observer that keeps the latest film snapshot for the preview and the tile counters for the
//! progress bar. Cancelling sets the driver's flag; when the thread ends the world, the film and
//! the preview are dropped, so a cancelled job holds no image memory.

use super::request::{Defaults, RenderRequest};
use serde_json::{Value, json};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use trayecto::denoise::DenoiseOptions;
use trayecto::film::aov::side_path;
use trayecto::film::output::to_rgb8;
use trayecto::film::{Film, Image};
use trayecto::limits::{Budget, LoadContext};
use trayecto::pipeline::{
    GivenSettings, LogLine, OutputSpec, PipelineError, PipelineObserver, RenderJob, Stage,
    frame_path,
};
use trayecto::render::RenderObserver;
use trayecto::world::WorldOptions;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobState {
    /// Waiting for a free slot (`--max-jobs` renders already run).
    Queued,
    Loading,
    Building,
    Rendering,
    Denoising,
    Writing,
    Done,
    Failed,
    Cancelled,
}

impl JobState {
    pub fn name(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Loading => "loading",
            JobState::Building => "building",
            JobState::Rendering => "rendering",
            JobState::Denoising => "denoising",
            JobState::Writing => "writing",
            JobState::Done => "done",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }

    pub fn is_active(self) -> bool {
        !matches!(
            self,
            JobState::Done | JobState::Failed | JobState::Cancelled
        )
    }
}

/// The mutable part of a job, behind one mutex (touched once per pass, not per sample).
pub struct JobStatus {
    pub state: JobState,
    pub samples_done: u32,
    /// The film after the latest pass, and how many snapshots have been taken so far.
    pub preview: Option<Arc<Image>>,
    pub preview_version: u64,
    /// PNG of the preview, cached for the version it was encoded from.
    pub preview_png: Option<(u64, Arc<Vec<u8>>)>,
    pub render_started: Option<Instant>,
    /// The renderer's latest estimate of the time left and when it was made
    /// (`RenderObserver::progress`); the API reports it less the time since.
    pub eta: Option<(Duration, Instant)>,
    pub finished: Option<Instant>,
    pub timings: Vec<(&'static str, f64)>,
    pub log: Vec<String>,
    pub error: Option<String>,
    pub png: Option<PathBuf>,
    pub exr: Option<PathBuf>,
    /// The denoised images (`<output>.denoised.png`/`.exr`), when the request asked for them.
    pub denoised: Option<(PathBuf, PathBuf)>,
    /// A sequence (`frames`): the frame in flight and when its build started, and each frame
    /// written.
    pub frame: Option<(u32, Instant)>,
    pub frames_done: Vec<FrameDone>,
}

/// A frame of a sequence, written.
pub struct FrameDone {
    pub frame: u32,
    /// From its build to its files.
    pub seconds: f64,
    pub png: PathBuf,
    pub exr: PathBuf,
}

pub struct Job {
    pub id: u64,
    pub request: RenderRequest,
    pub cancel: AtomicBool,
    pub created: Instant,
    pub created_unix: u64,
    pub tiles_done: AtomicU64,
    pub tiles_total: AtomicU64,
    status: Mutex<JobStatus>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding the lock leaves plain data that is still readable.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Job {
    pub fn status(&self) -> MutexGuard<'_, JobStatus> {
        lock(&self.status)
    }

    /// The preview as PNG (encoded on demand, once per pass), if there is one.
    pub fn preview_png(&self) -> Option<Arc<Vec<u8>>> {
        let (version, image) = {
            let st = self.status();
            if let Some((v, png)) = &st.preview_png
                && *v == st.preview_version
            {
                return Some(png.clone());
            }
            (st.preview_version, st.preview.clone()?)
        };
        let rgb = to_rgb8(&image, self.request.exposure, self.request.tonemap);
        let png = Arc::new(encode_png(&rgb, image.width, image.height)?);
        let mut st = self.status();
        if st.preview_version == version {
            st.preview_png = Some((version, png.clone()));
        }
        Some(png)
    }

    /// The job as the API reports it; `queue_position` (1 = next to start) while it waits.
    pub fn to_json(&self, queue_position: Option<usize>) -> Value {
        let st = self.status();
        let r = &self.request;
        let now = st.finished.unwrap_or_else(Instant::now);
        let elapsed = now.duration_since(self.created).as_secs_f64();
        let total = self.tiles_total.load(Ordering::Relaxed);
        let done = self.tiles_done.load(Ordering::Relaxed).min(total);
        let mut progress = match st.state {
            JobState::Done => 1.0,
            _ if total > 0 => done as f64 / total as f64,
            _ => 0.0,
        };
        // A sequence: the frames written and the fraction of the one in flight.
        let frame_count = r.frames.map(|(a, b)| f64::from(b - a) + 1.0);
        if let Some(n) = frame_count
            && st.state.is_active()
        {
            let in_flight = if st.frame.is_some() { progress } else { 0.0 };
            progress = ((st.frames_done.len() as f64 + in_flight) / n).min(1.0);
        }
        // Remaining time: the renderer's estimate (`render::remaining_time`, the CLI's too) less
        // the time since it was made; unknown until the first tile is done.
        // (Renderers that report tiles only, the light-path ones, get the work fraction's.)
        let remaining = match (st.state, st.eta, st.render_started) {
            (JobState::Rendering, Some((left, at)), _) => Some(
                left.saturating_sub(now.saturating_duration_since(at))
                    .as_secs_f64(),
            ),
            (JobState::Rendering, None, Some(t0)) if done > 0 => {
                let spent = now.duration_since(t0).as_secs_f64();
                Some(spent * (total - done) as f64 / done as f64)
            }
            (s, _, _) if !s.is_active() => Some(0.0),
            _ => None,
        };
        // A sequence: the frame in flight's time left, and the frames after it at the mean time
        // of those written (or, before one is, at this one's time so far plus its time left).
        let remaining = match (frame_count, st.frame, remaining) {
            (Some(n), Some((_, started)), Some(left)) if st.state.is_active() => {
                let after = (n - st.frames_done.len() as f64 - 1.0).max(0.0);
                let per_frame = if st.frames_done.is_empty() {
                    now.saturating_duration_since(started).as_secs_f64() + left
                } else {
                    st.frames_done.iter().map(|f| f.seconds).sum::<f64>()
                        / st.frames_done.len() as f64
                };
                Some(left + after * per_frame)
            }
            _ => remaining,
        };
        let base = format!("/api/renders/{}", self.id);
        // A sequence: its range, the frame in flight and each frame's files as written.
        let frames = r.frames.map(|(first, last)| {
            let done: Vec<Value> = st
                .frames_done
                .iter()
                .map(|d| {
                    let f = d.frame;
                    json!({
                        "frame": f,
                        "png": format!("{base}/frame-{f:04}.png"),
                        "exr": format!("{base}/frame-{f:04}.exr"),
                    })
                })
                .collect();
            json!({
                "first": first,
                "last": last,
                "current": st.frame.map(|f| f.0),
                "done": done,
            })
        });
        json!({
            "id": self.id,
            "scene": r.scene,
            "output": r.output,
            "width": r.settings.width,
            "height": r.settings.height,
            "spp": r.settings.spp,
            "secondary": r.settings.path.secondary,
            "max_depth": r.settings.path.max_depth,
            "exposure": r.exposure,
            "environment": r.environment.as_ref().map(|(n, _)| n),
            "env_rotation": r.env_rotation,
            "camera": r.camera.map(|c| super::request::camera_json(&c)),
            // glTF KHR_materials_variants choice; null: the file's default materials.
            "variant": r.variant,
            "aovs": r.aovs.iter().map(|k| k.name()).collect::<Vec<_>>(),
            "transparent": r.settings.path.transparent,
            "linear": st.exr.as_ref().map(|_| format!("{base}/linear")),
            "state": st.state.name(),
            "active": st.state.is_active(),
            "queue_position": queue_position,
            "samples_done": st.samples_done,
            "progress": progress,
            "elapsed_s": elapsed,
            "remaining_s": remaining,
            "preview_version": st.preview_version,
            "preview": if st.preview.is_some() { Some(format!("{base}/preview.png")) } else { None },
            "timings": st.timings.iter().map(|(k, v)| json!({"phase": k, "seconds": v})).collect::<Vec<_>>(),
            "log": st.log,
            "error": st.error,
            "png": st.png.as_ref().map(|_| format!("{base}/image.png")),
            "exr": st.exr.as_ref().map(|_| format!("{base}/image.exr")),
            "denoise": r.denoise,
            "denoised_png": st.denoised.as_ref().map(|_| format!("{base}/denoised.png")),
            "denoised_exr": st.denoised.as_ref().map(|_| format!("{base}/denoised.exr")),
            "time": r.time.time,
            "frame": r.time.frame,
            "fps": r.time.fps,
            "shutter": r.time.shutter,
            "frames": frames,
            "created_unix": self.created_unix,
        })
    }
}

fn encode_png(rgb: &[u8], w: u32, h: u32) -> Option<Vec<u8>> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    )
    .write_image(rgb, w, h, image::ExtendedColorType::Rgb8)
    .ok()?;
    Some(out)
}

/// Feeds the driver's progress into the job.
/// The job's observer; `out_dir` is the server's output folder, which log lines show as bare file
/// names (the page and the API never reveal the server's folders).
struct Observer<'a> {
    job: &'a Job,
    out_dir: String,
}

impl RenderObserver for Observer<'_> {
    fn pass_done(&self, film: &Film, samples_done: u32, _spp: u32) {
        // The copy is made outside the lock; the lock is held only to swap it in.
        let image = Arc::new(film.to_image());
        let mut st = self.job.status();
        st.preview = Some(image);
        st.preview_version += 1;
        st.samples_done = samples_done;
    }

    fn tile_done(&self, done: u64, total: u64) {
        self.job.tiles_total.store(total, Ordering::Relaxed);
        self.job.tiles_done.fetch_max(done, Ordering::Relaxed);
    }

    fn progress(&self, progress: &trayecto::render::Progress) {
        if let Some(left) = progress.remaining {
            self.job.status().eta = Some((left, Instant::now()));
        }
    }
}

impl PipelineObserver for Observer<'_> {
    fn stage_started(&self, stage: Stage) {
        let mut st = self.job.status();
        // A sequence builds each frame's world after the one load: a new frame starts.
        if let (Stage::Build, Some((first, _))) = (stage, self.job.request.frames) {
            st.frame = Some((first + st.frames_done.len() as u32, Instant::now()));
            self.job.tiles_done.store(0, Ordering::Relaxed);
            self.job.tiles_total.store(0, Ordering::Relaxed);
            st.eta = None;
        }
        st.state = match stage {
            Stage::Load => JobState::Loading,
            Stage::Build => JobState::Building,
            Stage::Render => {
                st.render_started = Some(Instant::now());
                JobState::Rendering
            }
            Stage::Denoise => JobState::Denoising,
            Stage::Write => JobState::Writing,
        };
    }

    fn stage_finished(&self, stage: Stage, took: Duration) {
        let name = match stage {
            Stage::Load => "load",
            Stage::Build => "build (accel)",
            Stage::Render => "render",
            Stage::Denoise => "denoise",
            Stage::Write => "write",
        };
        let mut st = self.job.status();
        st.timings.push((name, took.as_secs_f64()));
        if stage == Stage::Write
            && let Some((frame, started)) = st.frame.take()
        {
            let out = |ext: &str| {
                let file = format!("{}{}.{ext}", self.out_dir, self.job.request.output);
                frame_path(std::path::Path::new(&file), frame)
            };
            st.frames_done.push(FrameDone {
                frame,
                seconds: started.elapsed().as_secs_f64(),
                png: out("png"),
                exr: out("exr"),
            });
        }
    }

    fn log(&self, line: LogLine) {
        let line = self
            .job
            .request
            .relative_paths(&line.to_string().replace(&self.out_dir, ""));
        self.job.status().log.push(line);
    }
}

/// Why a job could not be accepted.
#[derive(Debug, PartialEq)]
pub enum SubmitError {
    /// `max_jobs` renders run and `max_queued` more already wait.
    Busy { running: usize, queued: usize },
    /// A running or queued job writes the same output name.
    NameInUse(String),
    /// The output folder already holds files of that name (an earlier render's).
    NameTaken(String),
}

/// Every job the server knows: the queued, the running and the last few finished ones, in the
/// order they were submitted. Cloning shares the list (the render threads hold a clone to start
/// the next queued job when they end).
#[derive(Clone)]
pub struct Jobs {
    inner: Arc<Inner>,
}

struct Inner {
    list: Mutex<Vec<Arc<Job>>>,
    next_id: AtomicU64,
    max_active: usize,
    max_queued: usize,
    history: usize,
    output_dir: PathBuf,
    /// What all loads together may take, and one load ([`trayecto::limits`]).
    memory: Arc<Budget>,
    per_job: u64,
    /// Scene loads outside render jobs (scene views) holding a slot, and those waiting for one.
    loads_running: AtomicUsize,
    loads_waiting: AtomicUsize,
    /// Signalled (with the list's lock) whenever a slot frees.
    slot_freed: Condvar,
}

/// A render slot held by a scene load outside the jobs (`GET /api/scene-view`): counted with
/// the running jobs against `--max-jobs`, freed when dropped.
pub struct LoadSlot {
    jobs: Jobs,
    ctx: Arc<LoadContext>,
}

impl LoadSlot {
    /// Runs a load in this slot, under a job's memory budget.
    pub fn run<R>(&self, f: impl FnOnce() -> R) -> R {
        trayecto::limits::scope(self.ctx.clone(), f)
    }
}

impl Drop for LoadSlot {
    fn drop(&mut self) {
        self.jobs.inner.loads_running.fetch_sub(1, Ordering::SeqCst);
        self.jobs.dispatch();
    }
}

impl Jobs {
    /// `max_active` renders run at once; up to `max_queued` more wait for a slot, first come
    /// first served.
    pub fn new(max_active: usize, max_queued: usize, history: usize, output_dir: PathBuf) -> Jobs {
        Jobs {
            inner: Arc::new(Inner {
                list: Mutex::new(Vec::new()),
                next_id: AtomicU64::new(1),
                max_active,
                max_queued,
                history,
                output_dir,
                memory: Budget::new(trayecto::limits::default_limit()),
                per_job: trayecto::limits::default_limit(),
                loads_running: AtomicUsize::new(0),
                loads_waiting: AtomicUsize::new(0),
                slot_freed: Condvar::new(),
            }),
        }
    }

    /// Sets the memory all loads together may take and one load (before the list is shared).
    pub fn with_memory(mut self, total: u64, per_job: u64) -> Jobs {
        if let Some(inner) = Arc::get_mut(&mut self.inner) {
            inner.memory = Budget::new(total);
            inner.per_job = per_job.min(total);
        }
        self
    }

    /// A load's context: a budget of its own inside the total, and its cancel flag.
    fn load_context(&self, cancel: Option<trayecto::limits::CancelCheck>) -> Arc<LoadContext> {
        LoadContext::new(
            Budget::child(&self.inner.memory, self.inner.per_job),
            cancel,
        )
    }

    /// Running jobs plus loads holding a slot (the list's lock held).
    fn busy_slots(&self, list: &[Arc<Job>]) -> usize {
        let jobs = list
            .iter()
            .filter(|j| {
                let s = j.status().state;
                s.is_active() && s != JobState::Queued
            })
            .count();
        jobs + self.inner.loads_running.load(Ordering::SeqCst)
    }

    /// [`Jobs::load_slot_in`] under a fresh job budget.
    #[cfg(test)]
    pub fn load_slot(&self) -> Result<LoadSlot, String> {
        self.load_slot_in(self.load_context(None))
    }

    /// Waits for a render slot for a scene load outside the jobs (the load then runs under
    /// `ctx`); queued renders go first. Refused (as a full queue refuses a render) when
    /// `max_queued` loads already wait.
    fn load_slot_in(&self, ctx: Arc<LoadContext>) -> Result<LoadSlot, String> {
        let inner = &self.inner;
        let mut list = lock(&inner.list);
        if inner.loads_waiting.load(Ordering::SeqCst) >= inner.max_queued.max(1) {
            return Err("the server is busy: too many scene loads wait; try again later".into());
        }
        inner.loads_waiting.fetch_add(1, Ordering::SeqCst);
        loop {
            let queued = list.iter().any(|j| j.status().state == JobState::Queued);
            if !queued && self.busy_slots(&list) < inner.max_active {
                break;
            }
            list = inner
                .slot_freed
                .wait_timeout(list, Duration::from_millis(500))
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        inner.loads_waiting.fetch_sub(1, Ordering::SeqCst);
        inner.loads_running.fetch_add(1, Ordering::SeqCst);
        drop(list);
        Ok(LoadSlot {
            jobs: self.clone(),
            ctx,
        })
    }

    /// Runs a scene load outside the jobs (the page's scene view and defaults) under the job
    /// memory budget: a file waits for a render slot ([`Jobs::load_slot`]); a built-in scene is
    /// made from code, small and bounded, and does not wait (else a page opened while renders
    /// queue would wait for every one of them before it could show the queue).
    pub fn run_load<R>(
        &self,
        builtin: bool,
        f: impl FnOnce() -> Result<R, String>,
    ) -> Result<R, String> {
        self.run_load_in(builtin, self.load_context(None), f)
    }

    /// A job's memory budget and `cancel` flag for a load whose result outlives it (a viewport
    /// session's world): the caller keeps the context as long as the world, so what the load
    /// charged stays counted against the server's total until the world is dropped.
    pub fn view_context(&self, cancel: trayecto::limits::CancelCheck) -> Arc<LoadContext> {
        self.load_context(Some(cancel))
    }

    /// [`Jobs::run_load`] under the context `ctx`.
    pub fn run_load_in<R>(
        &self,
        builtin: bool,
        ctx: Arc<LoadContext>,
        f: impl FnOnce() -> Result<R, String>,
    ) -> Result<R, String> {
        if builtin {
            trayecto::limits::scope(ctx, f)
        } else {
            self.load_slot_in(ctx)?.run(f)
        }
    }

    pub fn get(&self, id: u64) -> Option<Arc<Job>> {
        lock(&self.inner.list).iter().find(|j| j.id == id).cloned()
    }

    /// Newest first.
    pub fn all(&self) -> Vec<Arc<Job>> {
        lock(&self.inner.list).iter().rev().cloned().collect()
    }

    /// Jobs queued or running.
    pub fn active_count(&self) -> usize {
        lock(&self.inner.list)
            .iter()
            .filter(|j| j.status().state.is_active())
            .count()
    }

    /// 1 for the queued job that starts next, 2 for the one after, …; `None` unless queued.
    pub fn queue_position(&self, id: u64) -> Option<usize> {
        lock(&self.inner.list)
            .iter()
            .filter(|j| j.status().state == JobState::Queued)
            .position(|j| j.id == id)
            .map(|p| p + 1)
    }

    /// The job as the API reports it, with its place in the queue.
    pub fn json(&self, job: &Job) -> Value {
        job.to_json(self.queue_position(job.id))
    }

    /// Cancels a job: a queued one ends at once (it never starts), a running one stops at the
    /// end of its current tile.
    pub fn cancel(&self, job: &Job) {
        job.cancel.store(true, Ordering::Relaxed);
        let mut st = job.status();
        if st.state == JobState::Queued {
            st.state = JobState::Cancelled;
            st.log.push("cancelled before it started".into());
            st.finished = Some(Instant::now());
        }
    }

    /// Accepts a job: it starts at once if fewer than `max_active` run, else it waits in the
    /// queue; refused when the queue is full too.
    pub fn submit(&self, mut request: RenderRequest) -> Result<Arc<Job>, SubmitError> {
        let inner = &self.inner;
        let job = {
            let mut list = lock(&inner.list);
            let states: Vec<JobState> = list.iter().map(|j| j.status().state).collect();
            let queued = states.iter().filter(|s| **s == JobState::Queued).count();
            let running = states.iter().filter(|s| s.is_active()).count() - queued;
            if running >= inner.max_active && queued >= inner.max_queued {
                return Err(SubmitError::Busy { running, queued });
            }
            let in_use = |name: &str| {
                list.iter()
                    .zip(&states)
                    .any(|(j, s)| s.is_active() && j.request.output == name)
            };
            // Files are never overwritten: a name an earlier render wrote (in this run of the
            // server or before it) is refused rather than silently replaced.
            let frames = request.frames;
            // A sequence writes `<name>_NNNN.png` (and `<name>_NNNN.denoised.png`) per frame.
            let written = |name: &str| {
                let frame_files = |f: Option<u32>| {
                    ["png", "exr"].iter().any(|ext| {
                        let mut file = inner.output_dir.join(format!("{name}.{ext}"));
                        if let Some(f) = f {
                            file = frame_path(&file, f);
                        }
                        file.exists() || side_path(&file, "denoised").exists()
                    })
                };
                match frames {
                    None => frame_files(None),
                    Some((a, b)) => (a..=b).any(|f| frame_files(Some(f))),
                }
            };
            // Ids are handed out under this lock, so this is the new job's.
            let id = inner.next_id.load(Ordering::Relaxed);
            if !request.output_given {
                // A request without a name gets `render-ID`; ids start again at 1 when the
                // server restarts, so a name an earlier run wrote gets `render-ID-2`, ...
                request.output = (1..=1000)
                    .map(|k| match k {
                        1 => format!("{}-{id}", Defaults::OUTPUT),
                        k => format!("{}-{id}-{k}", Defaults::OUTPUT),
                    })
                    .find(|n| !in_use(n.as_str()) && !written(n.as_str()))
                    .ok_or_else(|| SubmitError::NameTaken(format!("{}-{id}", Defaults::OUTPUT)))?;
            }
            if in_use(&request.output) {
                return Err(SubmitError::NameInUse(request.output));
            }
            if written(&request.output) {
                return Err(SubmitError::NameTaken(request.output));
            }
            inner.next_id.store(id + 1, Ordering::Relaxed);
            let job = Arc::new(Job {
                id,
                request,
                cancel: AtomicBool::new(false),
                created: Instant::now(),
                created_unix: SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .map(|d| d.as_secs())
                    .unwrap_or(0),
                tiles_done: AtomicU64::new(0),
                tiles_total: AtomicU64::new(0),
                status: Mutex::new(JobStatus {
                    state: JobState::Queued,
                    samples_done: 0,
                    preview: None,
                    preview_version: 0,
                    preview_png: None,
                    render_started: None,
                    eta: None,
                    finished: None,
                    timings: Vec::new(),
                    log: Vec::new(),
                    error: None,
                    png: None,
                    exr: None,
                    denoised: None,
                    frame: None,
                    frames_done: Vec::new(),
                }),
            });
            list.push(job.clone());
            // Forget the oldest finished jobs beyond the history length.
            let mut finished = list
                .iter()
                .filter(|j| !j.status().state.is_active())
                .count();
            list.retain(|j| {
                if finished > inner.history && !j.status().state.is_active() {
                    finished -= 1;
                    false
                } else {
                    true
                }
            });
            job
        };
        self.dispatch();
        Ok(job)
    }

    /// Starts queued jobs, oldest first, while fewer than `max_active` run. Called after a
    /// submission and whenever a job ends.
    fn dispatch(&self) {
        let list = lock(&self.inner.list);
        let mut running = self.busy_slots(&list);
        for job in list.iter() {
            if running >= self.inner.max_active {
                break;
            }
            {
                // Checked and changed under the job's lock, as `cancel` does: a job is either
                // cancelled while queued or started, never both.
                let mut st = job.status();
                if st.state != JobState::Queued {
                    continue;
                }
                st.state = JobState::Loading;
            }
            running += 1;
            self.spawn(job.clone());
        }
        // Scene loads waiting for a slot look again.
        self.inner.slot_freed.notify_all();
    }

    fn spawn(&self, job: Arc<Job>) {
        let worker = job.clone();
        let jobs = self.clone();
        let spawned = std::thread::Builder::new()
            .name(format!("render-{}", job.id))
            .spawn(move || {
                let j = worker.clone();
                let out_dir = jobs.inner.output_dir.clone();
                // The job's loads run under its own budget inside the server's total, and stop
                // when it is cancelled (checked at each file read and in long loops).
                let flag = worker.clone();
                let load =
                    jobs.load_context(Some(Arc::new(move || flag.cancel.load(Ordering::Relaxed))));
                // A panic in the renderer must not leave the job counted as running forever.
                let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    trayecto::limits::scope(load, || run_job(&j, &out_dir))
                }));
                {
                    let mut st = worker.status();
                    match r {
                        Ok(Ok(())) => st.state = JobState::Done,
                        Ok(Err(JobEnd::Cancelled)) => {
                            st.state = JobState::Cancelled;
                            st.log.push("cancelled".into());
                        }
                        Ok(Err(JobEnd::Failed(m))) => {
                            st.log.push(format!("error: {m}"));
                            st.error = Some(m);
                            st.state = JobState::Failed;
                        }
                        Err(_) => {
                            st.error = Some("internal error: the renderer panicked".into());
                            st.state = JobState::Failed;
                        }
                    }
                    // Free the image memory: the result is on disk, and a cancelled or failed
                    // job keeps nothing.
                    st.preview = None;
                    st.preview_png = None;
                    st.finished = Some(Instant::now());
                }
                jobs.dispatch();
            });
        if let Err(e) = spawned {
            {
                let mut st = job.status();
                st.state = JobState::Failed;
                st.error = Some(format!("could not start a render thread: {e}"));
                st.finished = Some(Instant::now());
            }
            // Not `dispatch` again from here (it holds the list lock): the next job starts when
            // another one ends or is submitted.
        }
    }
}

enum JobEnd {
    Cancelled,
    Failed(String),
}

/// Runs the library's render pipeline for the job: the same stages, log and report as the CLI.
fn run_job(job: &Job, out_dir: &std::path::Path) -> Result<(), JobEnd> {
    let r = &job.request;
    // Test seam, compiled into unit-test builds only: a renderer panic, to check that the job
    // fails cleanly (`a_renderer_panic_becomes_a_failed_job`).
    #[cfg(test)]
    if r.output == "panic-in-renderer" {
        panic!("deliberate panic in the renderer (test)");
    }
    let png = out_dir.join(format!("{}.png", r.output));
    let exr = out_dir.join(format!("{}.exr", r.output));
    let output = |path: &PathBuf| OutputSpec {
        path: path.clone(),
        exposure: r.exposure,
        tonemap: r.tonemap,
    };
    let render = RenderJob {
        scene: r.source.load_spec(),
        world: WorldOptions {
            default_light: r.default_light,
            variant: r.variant.clone(),
            env: r.environment.as_ref().map(|(_, p)| p.clone()),
            env_rotation: r.env_rotation,
            camera_override: r.camera,
            time: r.time.clone(),
            ..WorldOptions::default()
        },
        settings: r.settings.clone(),
        // The web UI always sends its size, samples and depth; the filter only when asked
        // (else the scene file's, e.g. a pbrt PixelFilter).
        // Spectral or RGB when asked, else the file's default (pbrt files spectral).
        given: GivenSettings {
            filter: r.filter_given,
            spectral: r.spectral_given,
            guiding: r.guiding_given,
            ..GivenSettings::ALL
        },
        outputs: vec![output(&png), output(&exr)],
        split: Default::default(),
        crop: r.crop,
        aovs: r.aovs.clone(),
        // Open Image Denoise as the CLI finds it; without it the job fails before rendering,
        // with the install command in its error.
        denoise: r.denoise.then(DenoiseOptions::default),
    };
    let observer = Observer {
        job,
        out_dir: format!("{}{}", out_dir.display(), std::path::MAIN_SEPARATOR),
    };
    let ran = match r.frames {
        Some((first, last)) => render
            .run_frames(first..=last, &observer, &job.cancel)
            .map(|_| ()),
        None => render.run(&observer, &job.cancel).map(|_| ()),
    };
    match ran {
        Ok(()) => {}
        Err(PipelineError::Cancelled) => return Err(JobEnd::Cancelled),
        Err(PipelineError::Write { path, error }) => {
            // Report the name only, not the server's folder layout (the error names the path).
            let why = match error {
                trayecto::film::output::OutputError::Write { message, .. }
                | trayecto::film::output::OutputError::Read { message, .. } => message,
                e @ trayecto::film::output::OutputError::UnknownFormat { .. } => e.to_string(),
            };
            return Err(JobEnd::Failed(format!(
                "could not write {}: {why}",
                path.file_name()
                    .map(|f| f.to_string_lossy())
                    .unwrap_or_default()
            )));
        }
        // Scene errors name the file by its canonical path; show the name the page used.
        Err(e) => {
            return Err(JobEnd::Failed(
                r.relative_paths(&e.to_string().replace(&observer.out_dir, "")),
            ));
        }
    }
    let mut st = job.status();
    st.timings
        .push(("total", job.created.elapsed().as_secs_f64()));
    // A sequence shows (and serves as `image.png`/`.exr`) its last frame.
    let (png, exr) = match r.frames {
        Some((_, last)) => (frame_path(&png, last), frame_path(&exr, last)),
        None => (png, exr),
    };
    if r.denoise {
        st.denoised = Some((side_path(&png, "denoised"), side_path(&exr, "denoised")));
    }
    st.png = Some(png);
    st.exr = Some(exr);
    st.samples_done = r.settings.spp;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::server::request::SceneSource;

    fn request(output: &str, size: u32, spp: u32) -> RenderRequest {
        RenderRequest {
            scene: "cornell".into(),
            source: SceneSource::Builtin("cornell".into()),
            output: output.into(),
            output_given: true,
            settings: trayecto::render::RenderSettings {
                width: size,
                height: size,
                spp,
                threads: Some(1),
                ..Default::default()
            },
            exposure: 1.0,
            tonemap: Default::default(),
            default_light: None,
            denoise: false,
            filter_given: false,
            spectral_given: false,
            guiding_given: false,
            crop: None,
            variant: None,
            environment: None,
            env_rotation: 0.0,
            camera: None,
            aovs: Vec::new(),
            scenes_dir: None,
            time: Default::default(),
            frames: None,
        }
    }

    fn wait(job: &Arc<Job>) {
        let t0 = Instant::now();
        while job.status().state.is_active() {
            assert!(t0.elapsed() < Duration::from_secs(60), "job still running");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// With one slot, later jobs wait in order with their positions, a queued job cancelled
    /// never starts, a full queue refuses, and the rest complete in submission order.
    #[test]
    fn jobs_beyond_the_slots_queue_and_run_in_order() {
        let dir = std::env::temp_dir().join(format!("trayecto-jobs-queue-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let jobs = Jobs::new(1, 3, 10, dir.clone());
        // The first is long enough to still run while the others are submitted.
        let first = jobs.submit(request("q1", 64, 4096)).unwrap();
        let second = jobs.submit(request("q2", 8, 1)).unwrap();
        // A queued job's name is in use.
        assert!(matches!(
            jobs.submit(request("q2", 8, 1)),
            Err(SubmitError::NameInUse(_))
        ));
        let third = jobs.submit(request("q3", 8, 1)).unwrap();
        let fourth = jobs.submit(request("q4", 8, 1)).unwrap();
        assert_ne!(first.status().state, JobState::Queued);
        assert_eq!(second.status().state, JobState::Queued);
        assert_eq!(jobs.queue_position(first.id), None);
        assert_eq!(jobs.queue_position(second.id), Some(1));
        assert_eq!(jobs.queue_position(third.id), Some(2));
        assert_eq!(jobs.json(&fourth)["queue_position"], 3);
        // The queue (3) is full: refused, naming what runs and waits.
        assert_eq!(
            jobs.submit(request("q5", 8, 1)).err(),
            Some(SubmitError::Busy {
                running: 1,
                queued: 3
            })
        );
        jobs.cancel(&third);
        assert_eq!(third.status().state, JobState::Cancelled);
        assert_eq!(jobs.queue_position(fourth.id), Some(2));
        jobs.cancel(&first);
        for j in [&first, &second, &third, &fourth] {
            wait(j);
        }
        assert_eq!(first.status().state, JobState::Cancelled);
        assert_eq!(second.status().state, JobState::Done);
        assert_eq!(fourth.status().state, JobState::Done);
        // The cancelled queued job never rendered; the others ran one after the other.
        assert!(third.status().render_started.is_none());
        let (s2, s4) = (second.status(), fourth.status());
        assert!(s2.finished.unwrap() <= s4.render_started.unwrap());
        drop((s2, s4));
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A panic in the renderer becomes a failed job with an error, the job stops counting as
    /// running, and its slot takes the next job (max_active = 1).
    #[test]
    fn a_renderer_panic_becomes_a_failed_job() {
        let dir = std::env::temp_dir().join(format!("trayecto-jobs-panic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let jobs = Jobs::new(1, 4, 10, dir.clone());
        let request = |output: &str| super::tests::request(output, 8, 1);
        let job = jobs.submit(request("panic-in-renderer")).unwrap();
        wait(&job);
        {
            let st = job.status();
            assert_eq!(st.state, JobState::Failed);
            let e = st.error.as_deref().unwrap_or("");
            assert!(e.contains("panicked"), "error: {e:?}");
            assert!(st.png.is_none() && st.exr.is_none());
        }
        assert_eq!(jobs.active_count(), 0);
        let next = jobs.submit(request("after-the-panic")).unwrap();
        wait(&next);
        assert_eq!(next.status().state, JobState::Done);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A cancel while the scene loads ends the job: the load checks the job's flag at each
    /// file read. The scene includes files in a fan-out that reads 20000 of them before its
    /// include bound stops it, so a job that ignored Cancel would end "failed", not "cancelled".
    #[test]
    fn a_cancel_during_loading_ends_the_job() {
        let dir = std::env::temp_dir().join(format!("trayecto-jobs-load-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for i in 0..26 {
            let body = if i < 25 {
                format!("Include \"f{}.pbrt\"\nInclude \"f{}.pbrt\"\n", i + 1, i + 1)
            } else {
                String::new()
            };
            std::fs::write(dir.join(format!("f{i}.pbrt")), body).unwrap();
        }
        let scene = dir.join("fan.pbrt");
        std::fs::write(&scene, "WorldBegin\nInclude \"f0.pbrt\"\n").unwrap();
        let jobs = Jobs::new(1, 4, 10, dir.clone());
        let mut r = request("fan", 8, 1);
        r.source = SceneSource::File(scene);
        let job = jobs.submit(r).unwrap();
        assert_eq!(job.status().state, JobState::Loading);
        std::thread::sleep(Duration::from_millis(20));
        let t = Instant::now();
        jobs.cancel(&job);
        wait(&job);
        assert_eq!(
            job.status().state,
            JobState::Cancelled,
            "{:?}",
            job.status().error
        );
        assert!(
            t.elapsed() < Duration::from_millis(500),
            "{:?}",
            t.elapsed()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Scene loads outside jobs (scene views) take a render slot: with one slot, a job waits
    /// while a view holds it, and a view waits while a job runs.
    #[test]
    fn scene_views_wait_in_the_render_slots() {
        let dir = std::env::temp_dir().join(format!("trayecto-jobs-views-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let jobs = Jobs::new(1, 4, 10, dir.clone()).with_memory(1 << 30, 1 << 29);
        let slot = jobs.load_slot().unwrap();
        let job = jobs.submit(request("after-view", 8, 1)).unwrap();
        assert_eq!(job.status().state, JobState::Queued);
        // The view's load runs under a job's budget inside the total.
        let used = slot.run(|| {
            trayecto::limits::charge(1 << 20, || "x".into()).unwrap();
            trayecto::limits::current().budget.limit()
        });
        assert_eq!(used, 1 << 29);
        drop(slot);
        wait(&job);
        assert_eq!(job.status().state, JobState::Done);
        // A long job holds the slot; a view asked for meanwhile gets it only when it ends.
        let long = jobs.submit(request("long", 64, 4096)).unwrap();
        let j = jobs.clone();
        let view = std::thread::spawn(move || {
            let _slot = j.load_slot().unwrap();
            Instant::now()
        });
        std::thread::sleep(Duration::from_millis(100));
        jobs.cancel(&long);
        wait(&long);
        let ended = long.status().finished.unwrap();
        assert!(view.join().unwrap() >= ended);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
