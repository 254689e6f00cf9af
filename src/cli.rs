//! The `trayecto` command line (SPEC §2): `render`, `info`. Errors are reported with their context
//! and a non-zero exit code; nothing is rendered until every option has been checked.

use crate::accel::AccelKind;
use crate::film::output::{Format, write_image};
use crate::film::tonemap::Tonemap;
use crate::integrator::{Aov, IntegratorKind, PathSettings, ShadingModel};
use crate::render::{RenderObserver, RenderSettings};
use crate::sampling::SamplerKind;
use crate::world::{World, WorldOptions};
use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

#[derive(Parser, Debug)]
#[command(
    name = "trayecto",
    version,
    about = "Trayecto: a physically based path tracer. With no subcommand it renders (the built-in Cornell box by default).",
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    #[command(flatten)]
    pub render: RenderArgs,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a scene file or a built-in scene to an image.
    Render(RenderArgs),
    /// Show what a scene contains and every warning about it.
    Info(InfoArgs),
    /// Serve the web UI: render from the browser with a live preview.
    Serve(crate::server::ServeArgs),
    /// Merge partial films (.trp) of one frame into an image (or a longer partial film).
    Merge(MergeArgs),
}

#[derive(Args, Debug, Clone)]
pub struct MergeArgs {
    /// Partial films written by `render --samples A..B -o part.trp`, in any order.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// Output image (.exr, .hdr, .png, .ppm), or .trp for a merged partial film (which may then
    /// cover only part of the frame, without gaps).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Linear multiplier applied before tone mapping.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Tone mapping for .png/.ppm: clamp, gamma2.2, aces or agx.
    #[arg(long, default_value = "clamp")]
    pub tonemap: Tonemap,
}

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Scene file (.gltf, .glb, .obj, .ply, .fbx, .toml) or built-in name.
    #[arg(default_value = "cornell")]
    pub scene: String,
    /// Output image; the format follows the extension (.png, .ppm, .exr, .hdr).
    #[arg(short = 'o', long = "output", default_value = "render.png")]
    pub output: PathBuf,
    /// Image width in pixels [resolución].
    #[arg(long, default_value_t = 512)]
    pub width: u32,
    /// Image height in pixels [resolución].
    #[arg(long, default_value_t = 512)]
    pub height: u32,
    /// Camera samples per pixel [sobremuestreo].
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Continuation paths split at the first hit [rayos secundarios].
    #[arg(long, default_value_t = 1)]
    pub secondary: u32,
    /// Maximum number of bounces: 0 shows emitters only, 1 is direct lighting [profundidad máxima].
    #[arg(long, default_value_t = 64)]
    pub max_depth: u32,
    /// Linear multiplier applied before tone mapping [exposición].
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Rendering mode: path, raycast or whitted.
    #[arg(long, default_value = "path")]
    pub integrator: IntegratorKind,
    /// What the raycast mode shows: shaded, normals, barycentric, depth, albedo or uv.
    #[arg(long, default_value = "shaded")]
    pub aov: Aov,
    /// Direct-lighting model of the raycast and whitted modes: phong, blinn-phong or pbr.
    #[arg(long, default_value = "pbr")]
    pub shading: ShadingModel,
    /// Acceleration structure: bvh, grid or none.
    #[arg(long, default_value = "bvh")]
    pub accel: AccelKind,
    /// Camera sample generator: independent, stratified, sobol or poisson-disk.
    #[arg(long, default_value = "stratified")]
    pub sampler: SamplerKind,
    /// Disable next-event estimation (light sampling) for area and environment lights.
    #[arg(long)]
    pub no_nee: bool,
    /// Disable multiple importance sampling (light samples get full weight).
    #[arg(long)]
    pub no_mis: bool,
    /// Bounces before Russian roulette starts.
    #[arg(long, default_value_t = 3)]
    pub rr_depth: u32,
    /// Russian roulette keeps a path with probability min(1, scale × throughput); 1 is PBRT's rule.
    #[arg(long, default_value_t = 3.0)]
    pub rr_scale: f32,
    /// Random seed; the image is a pure function of the seed and the settings.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Worker threads (default: all cores). Does not change the image.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Tone mapping for .png/.ppm: clamp, gamma2.2, aces or agx.
    #[arg(long, default_value = "clamp")]
    pub tonemap: Tonemap,
    /// Camera to render, by name or index (default: the first).
    #[arg(long)]
    pub camera: Option<String>,
    /// Render a scene without lights unlit instead of adding a white environment.
    #[arg(long)]
    pub no_default_light: bool,
    /// Light the scene with an equirectangular environment map (.hdr or .exr).
    #[arg(long, value_name = "FILE")]
    pub env: Option<std::path::PathBuf>,
    /// Render only sample indices A..B of the --spp frame (write a partial film: -o part.trp).
    #[arg(long, value_name = "A..B")]
    pub samples: Option<String>,
    /// Save the film to FILE (a partial film) during the render and on Ctrl-C, to --resume later.
    #[arg(long, value_name = "FILE")]
    pub checkpoint: Option<PathBuf>,
    /// Seconds between checkpoints (at the end of a pass; 0: after every pass).
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0)]
    pub checkpoint_interval: f64,
    /// Continue the render saved in FILE by --checkpoint (same scene and settings); the result is
    /// identical to an uninterrupted render. Checkpoints go on to FILE unless --checkpoint says.
    #[arg(long, value_name = "FILE")]
    pub resume: Option<PathBuf>,
    /// Print only errors.
    #[arg(short, long)]
    pub quiet: bool,
}

#[derive(Args, Debug, Clone)]
pub struct InfoArgs {
    /// Scene file or built-in name.
    pub scene: String,
}

impl RenderArgs {
    /// The render settings these options describe, checked for absurd values.
    pub fn settings(&self) -> Result<RenderSettings> {
        let s = RenderSettings {
            width: self.width,
            height: self.height,
            spp: self.spp,
            seed: self.seed,
            threads: self.threads,
            sampler: self.sampler,
            integrator: self.integrator.with_options(self.aov, self.shading),
            path: PathSettings {
                max_depth: self.max_depth,
                rr_depth: self.rr_depth,
                rr_scale: self.rr_scale,
                nee: !self.no_nee,
                mis: !self.no_mis,
                secondary: self.secondary,
            },
        };
        s.validate()?;
        if !(self.exposure.is_finite() && self.exposure > 0.0) {
            bail!(
                "invalid setting: exposure must be a positive number (got {})",
                self.exposure
            );
        }
        Ok(s)
    }

    pub fn world_options(&self) -> WorldOptions {
        WorldOptions {
            accel: self.accel,
            camera: self.camera.clone(),
            no_default_light: self.no_default_light,
            env: self.env.clone(),
        }
    }
}

/// Terminal progress bar (only when stderr is a terminal).
struct Progress {
    bar: Option<indicatif::ProgressBar>,
}

impl RenderObserver for Progress {
    fn tile_done(&self, done: u64, total: u64) {
        if let Some(b) = &self.bar {
            b.set_length(total);
            b.set_position(done);
        }
    }
}

/// Set by Ctrl-C: the render stops after the pass in flight and saves a checkpoint.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

fn is_partial_output(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("trp"))
}

/// The exit code of a render stopped by Ctrl-C (128 + SIGINT, as shells report it).
pub const EXIT_INTERRUPTED: u8 = 130;

#[derive(Debug, thiserror::Error)]
#[error("interrupted{}", .0.as_ref().map(|p| format!("; the render so far is saved in {} (continue it with --resume {})", p.display(), p.display())).unwrap_or_else(|| "; nothing saved (use --checkpoint FILE to be able to resume)".into()))]
pub struct Interrupted(pub Option<PathBuf>);

pub fn run_render(args: &RenderArgs) -> Result<()> {
    let settings = args.settings()?;
    let partial_output = is_partial_output(&args.output);
    if !partial_output {
        Format::from_path(&args.output)?;
    }
    let samples = args
        .samples
        .as_deref()
        .map(crate::split::parse_range)
        .transpose()
        .map_err(|e| anyhow::anyhow!("invalid setting: --samples: {e}"))?;
    if let Some(r) = &samples {
        if r.end > settings.spp {
            bail!(
                "invalid setting: --samples {}..{} goes past the frame's {} samples per pixel (--spp)",
                r.start,
                r.end,
                settings.spp
            );
        }
        if !partial_output {
            bail!(
                "{}: a partial render (--samples) writes a partial film: use -o FILE.trp, then `trayecto merge`",
                args.output.display()
            );
        }
    }
    if !(args.checkpoint_interval >= 0.0 && args.checkpoint_interval <= 1e9) {
        bail!(
            "invalid setting: --checkpoint-interval must be 0 or more seconds (got {})",
            args.checkpoint_interval
        );
    }
    for p in [Some(&args.output), args.checkpoint.as_ref()]
        .into_iter()
        .flatten()
    {
        if let Some(parent) = p.parent()
            && !parent.as_os_str().is_empty()
            && !parent.is_dir()
        {
            bail!("{}: the folder does not exist", p.display());
        }
    }
    if let Some(r) = &args.resume
        && !r.is_file()
    {
        bail!("{}: no such checkpoint file", r.display());
    }
    if let Some(parent) = args.output.parent()
        && !parent.as_os_str().is_empty()
        && !parent.is_dir()
    {
        bail!(
            "{}: the output folder does not exist",
            args.output.display()
        );
    }
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };

    let t0 = Instant::now();
    let scene = crate::scene::load(&args.scene)?;
    let load_time = t0.elapsed();
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }

    let t1 = Instant::now();
    let world = World::build(&scene, &args.world_options())?;
    let build_time = t1.elapsed();
    for w in &world.warnings {
        eprintln!("warning: {w}");
    }
    say(format!(
        "scene '{}': {} triangles, {} primitives, {} materials, {} lights ({} area), {} cameras",
        scene.name,
        world.triangle_count(),
        world.primitive_count(),
        world.materials.len(),
        world.lights.lights.len(),
        world.area_light_count(),
        scene.cameras.len()
    ));
    say(format!(
        "rendering {}x{} at {} spp, max depth {}, {} integrator, {} threads",
        settings.width,
        settings.height,
        settings.spp,
        settings.path.max_depth,
        settings.integrator.name(),
        settings.threads.unwrap_or_else(rayon::current_num_threads)
    ));

    let bar = if std::io::stderr().is_terminal() && !args.quiet {
        let b = indicatif::ProgressBar::new(1);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40.cyan/blue} {percent:>3}% {elapsed_precise} (eta {eta})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Some(b)
    } else {
        None
    };
    let progress = Progress { bar };
    let digest = crate::scene::digest::digest(&args.scene, &scene, args.env.as_deref())?;
    let frame = crate::split::FrameId {
        scene: args.scene.clone(),
        digest,
        settings: settings.clone(),
        world: args.world_options(),
    };
    let opts = crate::split::SplitOptions {
        samples,
        checkpoint: args.checkpoint.clone().or_else(|| args.resume.clone()),
        checkpoint_interval: std::time::Duration::from_secs_f64(args.checkpoint_interval),
        resume: args.resume.clone(),
    };
    // Ctrl-C stops after the pass in flight and saves; a second Ctrl-C exits at once. Only one
    // handler per process: a second render in the same process keeps the first.
    let _ = ctrlc::set_handler(|| {
        if INTERRUPTED.swap(true, std::sync::atomic::Ordering::SeqCst) {
            std::process::exit(EXIT_INTERRUPTED as i32);
        }
    });
    let split = crate::split::render_split(&world, &frame, &opts, &progress, &INTERRUPTED)?;
    if let Some(b) = &progress.bar {
        b.finish_and_clear();
    }
    if split.render.cancelled {
        return Err(Interrupted(split.checkpoint_written).into());
    }
    let discarded = split.render.film.discarded;
    let out = crate::render::RenderOutput {
        image: split.render.film.to_image(),
        stats: split.render.stats,
        discarded_samples: discarded,
        render_time: split.render.render_time,
    };

    let t3 = Instant::now();
    if partial_output {
        crate::film::partial::Part {
            header: split.header,
            film: split.render.film,
        }
        .write(&args.output)?;
    } else {
        write_image(&out.image, &args.output, args.exposure, args.tonemap)?;
    }
    let write_time = t3.elapsed();
    if out.discarded_samples > 0 {
        eprintln!(
            "warning: {} samples were NaN, infinite or beyond {:e} and were discarded",
            out.discarded_samples,
            crate::film::SAMPLE_LIMIT
        );
    }
    // The thesis's console log (Fig. 5.44–5.46): phase durations and the time at which each ended.
    let mut report = crate::phases::PhaseReport::new();
    report.phase("scene loaded", load_time);
    report.phase(
        "world compiled",
        build_time.saturating_sub(world.accel_build_time),
    );
    report.phase("acceleration structure built", world.accel_build_time);
    report.phase(
        format!("rendered ({})", settings.integrator.name()),
        out.render_time,
    );
    report.phase("image written", write_time);
    report.note(format!("acceleration    {}", world.accel.describe()));
    report.note(format!(
        "rays            {} ({} camera/bounce/reflection/refraction, {} shadow), {:.2} Mrays/s",
        out.stats.rays + out.stats.shadow_rays,
        out.stats.rays,
        out.stats.shadow_rays,
        out.rays_per_second() / 1e6
    ));
    for line in report.lines() {
        say(line);
    }
    say(format!("wrote {}", args.output.display()));
    Ok(())
}

pub fn run_merge(args: &MergeArgs) -> Result<()> {
    use crate::film::partial::{Part, merge};
    let partial_output = is_partial_output(&args.output);
    if !partial_output {
        Format::from_path(&args.output)?;
    }
    if !(args.exposure.is_finite() && args.exposure > 0.0) {
        bail!(
            "invalid setting: exposure must be a positive number (got {})",
            args.exposure
        );
    }
    let mut parts = Vec::with_capacity(args.parts.len());
    for p in &args.parts {
        parts.push((p.clone(), Part::read(p)?));
    }
    let merged = merge(parts, !partial_output).context("cannot merge")?;
    if partial_output {
        merged.write(&args.output)?;
    } else {
        write_image(
            &merged.film.to_image(),
            &args.output,
            args.exposure,
            args.tonemap,
        )?;
    }
    eprintln!(
        "merged {} parts (samples {}..{} of {} spp) into {}",
        args.parts.len(),
        merged.header.samples[0],
        merged.header.samples[1],
        merged.header.spp,
        args.output.display()
    );
    Ok(())
}

pub fn run_info(args: &InfoArgs) -> Result<()> {
    let scene = crate::scene::load(&args.scene)?;
    let world = World::build(&scene, &WorldOptions::default())
        .with_context(|| format!("compiling {}", args.scene))?;
    let b = world.bounds;
    println!("scene       {}", scene.name);
    println!("meshes      {}", scene.meshes.len());
    println!("objects     {}", scene.objects.len());
    println!("triangles   {}", world.triangle_count());
    println!("primitives  {}", world.primitive_count());
    println!(
        "bounds      [{:.4}, {:.4}, {:.4}] – [{:.4}, {:.4}, {:.4}]",
        b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
    );
    println!("materials   {}", scene.materials.len());
    for (i, m) in scene.materials.iter().enumerate() {
        let textures = [
            m.base_color_texture,
            m.metallic_roughness_texture,
            m.normal_texture,
            m.occlusion_texture,
            m.emissive_texture,
            m.transmission_texture,
        ]
        .iter()
        .flatten()
        .count();
        println!(
            "  {i}: '{}' {:?} base colour {}{}{}",
            m.name,
            m.model,
            m.base_color,
            if textures > 0 {
                format!(", {textures} texture(s)")
            } else {
                String::new()
            },
            if m.is_emissive() { " (emissive)" } else { "" }
        );
    }
    println!("textures    {}", scene.textures.len());
    println!(
        "lights      {} ({} area)",
        world.lights.lights.len(),
        world.area_light_count()
    );
    for l in &scene.lights {
        use crate::scene::LightDesc as L;
        let what = match l {
            L::Point {
                position: p,
                intensity: i,
                ..
            } => format!("point at {p}, {i} W/sr"),
            L::Spot {
                position: p,
                intensity: i,
                ..
            } => format!("spot at {p}, {i} W/sr"),
            L::Directional {
                direction: d,
                irradiance: e,
                ..
            } => {
                format!("directional towards {d}, {e} W/m²")
            }
            L::Ambient { radiance: r, .. } => format!("ambient, radiance {r}"),
            L::Environment { path, .. } => format!("environment map {}", path.display()),
        };
        println!("  '{}' {what}", l.name());
    }
    println!("cameras     {}", scene.cameras.len());
    for (i, c) in scene.cameras.iter().enumerate() {
        println!(
            "  {i}: '{}' at {} vfov {:.2}°",
            c.name,
            c.camera_to_world.w_axis.truncate(),
            c.vfov_deg
        );
    }
    let warnings: Vec<&String> = scene.warnings.iter().chain(world.warnings.iter()).collect();
    println!("warnings    {}", warnings.len());
    for w in warnings {
        println!("  {w}");
    }
    Ok(())
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Some(Command::Render(a)) => run_render(a),
        Some(Command::Info(a)) => run_info(a),
        Some(Command::Serve(a)) => crate::server::run(a),
        Some(Command::Merge(a)) => run_merge(a),
        None => run_render(&cli.render),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<Interrupted>() => {
            eprintln!("{e}");
            ExitCode::from(EXIT_INTERRUPTED)
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
