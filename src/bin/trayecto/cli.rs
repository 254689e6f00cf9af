//! The `trayecto` command line (docs/DESIGN.md §2): `render`, `info`. Errors are reported with their context
//! and a non-zero exit code; nothing is rendered until every option has been checked.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use trayecto::accel::AccelKind;
use trayecto::denoise::DenoiseOptions;
use trayecto::film::aov::AovKind;
use trayecto::film::filter::{Filter, FilterKind};
use trayecto::film::output::Format;
use trayecto::film::tonemap::Tonemap;
use trayecto::integrator::{Aov, IntegratorKind, PathSettings, ShadingModel};
use trayecto::light::LightSamplerKind;
use trayecto::light::default_light::DefaultLight;
use trayecto::pipeline::{
    CropSpec, GivenSettings, LogLine, OutputSpec, PipelineError, PipelineObserver, RenderJob,
    Stage, is_partial_film,
};
use trayecto::render::{RenderObserver, RenderSettings};
use trayecto::sampling::SamplerKind;
use trayecto::split::SplitOptions;
use trayecto::world::{World, WorldOptions};

/// What `trayecto --help` leads with; the README shows the same lines (a test checks both).
pub const HELP_START: &str = "\
Start here (in a checkout):
  cargo run --release                     # renders the built-in Cornell box to render.png
  ./scripts/test.sh                       # runs the whole test suite (what CI runs)
One example per front end:
  trayecto render scene.gltf -o out.png   # render a scene file; its camera sets the image's shape
  trayecto info scene.gltf                # what a scene contains and every warning about it
  trayecto serve --scenes DIR             # the web UI on http://127.0.0.1:8080";

/// `render`'s option groups, in the order `-h` and `--help` show them. `-h` lists the options
/// a first render needs; `--help` is the full reference (every option, the thesis's names).
const HEADING_OUTPUT: &str = "Image";
const HEADING_SAMPLING: &str = "Quality and noise";
const HEADING_SCENE: &str = "Scene, camera and lighting";
const HEADING_RUN: &str = "Running";
const HEADING_FARM: &str = "Parts, resuming and cropping";
const HEADING_EXPERT: &str = "Integrator (expert)";

#[derive(Parser, Debug)]
#[command(
    name = "trayecto",
    version,
    about = "Trayecto: a physically based path tracer. With no subcommand it renders (the built-in Cornell box by default).",
    before_help = HELP_START,
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
    Render(Box<RenderArgs>),
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
    /// View transform for .png/.ppm: pbr-neutral, agx, clamp, gamma2.2 or aces.
    ///
    /// pbr-neutral (Khronos PBR Neutral) shows base colours as authored and rolls highlights
    /// off to white; agx (Blender's default) compresses a wider range with a filmic look; clamp
    /// is the thesis's sRGB clip. .exr and .hdr hold the radiance itself.
    #[arg(long, default_value = "pbr-neutral")]
    pub tonemap: Tonemap,
    /// Print only errors.
    #[arg(short, long)]
    pub quiet: bool,
}

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Scene file (.gltf, .glb, .obj, .ply, .fbx, .pbrt, .xml, .toml) or built-in name.
    #[arg(default_value = "cornell")]
    pub scene: String,
    /// Output image; the format follows the extension (.png, .ppm, .exr, .hdr).
    #[arg(short = 'o', long = "output", default_value = "render.png", help_heading = HEADING_OUTPUT)]
    pub output: PathBuf,
    /// Image width in pixels [resolución].
    ///
    /// Default: the scene file's resolution (pbrt Film, TOML
    /// [render]), else from the height and the camera's aspect ratio, else 512.
    #[arg(long, help_heading = HEADING_OUTPUT)]
    pub width: Option<u32>,
    /// Image height in pixels [resolución].
    ///
    /// Default: the scene file's resolution, else from the
    /// width and the camera's aspect ratio, else 512.
    #[arg(long, help_heading = HEADING_OUTPUT)]
    pub height: Option<u32>,
    /// Camera samples per pixel [sobremuestreo].
    ///
    /// (Default: the scene file's own setting, e.g. a pbrt Film or Sampler, else 64.)
    #[arg(long, help_heading = HEADING_SAMPLING)]
    pub spp: Option<u32>,
    /// Continuation paths split at the first hit [rayos secundarios].
    #[arg(long, default_value_t = 1, help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub secondary: u32,
    /// Maximum number of bounces: 0 shows emitters only, 1 is direct lighting [profundidad máxima].
    ///
    /// Scattering events in participating media count as bounces; crossing a medium boundary
    /// (an interface surface) does not.
    /// (Default: the scene file's own setting, e.g. a pbrt Film or Sampler, else 64.)
    #[arg(long, help_heading = HEADING_SAMPLING)]
    pub max_depth: Option<u32>,
    /// Linear multiplier applied before tone mapping [exposición].
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true, help_heading = HEADING_OUTPUT)]
    pub exposure: f32,
    /// Rendering mode: path (the default), raycast, whitted, lighttracer (paths from the
    /// lights, splatted onto the film), bdpt (bidirectional path tracing), sppm (stochastic
    /// progressive photon mapping: --spp iterations), vcm (vertex connection and merging:
    /// --spp iterations) or mlt (Metropolis light transport over BDPT: --spp mutations per
    /// pixel). A pbrt file's `Integrator "lighttracer"`, `"bdpt"`, `"sppm"` or `"mlt"` is
    /// honoured unless this is given.
    #[arg(long, help_heading = HEADING_SAMPLING)]
    pub integrator: Option<IntegratorKind>,
    /// SPPM: photon paths per iteration (Default: the scene file's `photonsperiteration`, else
    /// one per pixel).
    #[arg(long, help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub photons_per_iteration: Option<u64>,
    /// SPPM and VCM: the initial photon search (merge) radius, in scene units; it shrinks as
    /// the iterations go on (Default: the scene file's `radius`, else 1/200 of the scene's
    /// bounding-box diagonal).
    #[arg(long, help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub photon_radius: Option<f32>,
    /// VCM: connections only, no merges (bidirectional path tracing with one light subpath per
    /// camera subpath, unbiased).
    #[arg(long, help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub vcm_no_merge: bool,
    /// MLT: bootstrap paths per depth, to estimate the image's brightness and start the chains
    /// (Default: the scene file's `bootstrapsamples`, else 100000).
    #[arg(long, help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub mlt_bootstrap_samples: Option<u32>,
    /// MLT: independent Markov chains (Default: the scene file's `chains`, else 1000).
    #[arg(long, help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub mlt_chains: Option<u32>,
    /// MLT: probability of a large step, a fresh path (Default: the scene file's
    /// `largestepprobability`, else 0.3).
    #[arg(long, help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub mlt_large_step_probability: Option<f32>,
    /// MLT: deviation of a small step in primary sample space (Default: the scene file's
    /// `sigma`, else 0.01).
    #[arg(long, help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub mlt_sigma: Option<f32>,
    /// AOV layers to write with the image, comma-separated: albedo, normal (both at the first
    /// non-specular hit: the denoiser's guides), depth, position, shading_normal, material_id,
    /// object_id, samples (samples each pixel took), variance (the variance of one sample's
    /// luminance in each pixel; the mean's is variance/samples), or all. An .exr output gets
    /// them as channels of one multi-layer file (albedo.R, normal.X, Z, P.X, N.X, IndexMA.X,
    /// IndexOB.X, samples.Y, variance.Y); other formats get side files (out.albedo.png, ...).
    /// With --integrator raycast, a single view name (shaded, normals, barycentric, depth,
    /// albedo, uv) instead picks what the image shows. With --integrator bdpt, bdpt-sS-tT is
    /// strategy (s, t) weighted as it adds to the image, bdpt-sS-tT-unweighted the strategy
    /// alone, bdpt-depthD[-unweighted] every strategy of depth D (a pass of their own).
    #[arg(long, value_name = "LIST", help_heading = HEADING_OUTPUT, hide_short_help = true)]
    pub aov: Option<String>,
    /// Also write the image denoised by Intel Open Image Denoise beside the raw one: out.denoised.png.
    ///
    /// The RT filter, HDR, with prefiltered albedo and normal guides. OIDN is loaded at run time:
    /// install it with ./scripts/install-oidn.sh, or point --oidn / TRAYECTO_OIDN at the library.
    #[arg(long, help_heading = HEADING_OUTPUT)]
    pub denoise: bool,
    /// The Open Image Denoise library to load (libOpenImageDenoise.so) for --denoise. Default:
    /// $TRAYECTO_OIDN, else the copy ./scripts/install-oidn.sh puts under target/, else a pyoidn
    /// wheel in Python's site-packages, else a system install.
    #[arg(long, value_name = "PATH", requires = "denoise", help_heading = HEADING_OUTPUT, hide_short_help = true)]
    pub oidn: Option<PathBuf>,
    /// Direct-lighting model of the raycast and whitted modes: phong, blinn-phong or pbr.
    #[arg(long, default_value = "pbr", help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub shading: ShadingModel,
    /// Acceleration structure: bvh, grid or none.
    #[arg(long, default_value = "bvh", help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub accel: AccelKind,
    /// Camera sample generator: independent, stratified, padded, sobol, zsobol or poisson-disk.
    #[arg(long, default_value = "stratified", help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub sampler: SamplerKind,
    /// Disable next-event estimation (light sampling) for area and environment lights.
    #[arg(long, help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub no_nee: bool,
    /// Disable multiple importance sampling (light samples get full weight).
    #[arg(long, help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub no_mis: bool,
    /// Bounces before Russian roulette starts.
    #[arg(long, default_value_t = 3, help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub rr_depth: u32,
    /// Russian roulette keeps a path with probability min(1, scale × throughput); 1 is PBRT's rule.
    #[arg(long, default_value_t = 3.0, help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub rr_scale: f32,
    /// Random seed; the image is a pure function of the seed and the settings.
    #[arg(long, default_value_t = 0, help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub seed: u64,
    /// Worker threads (default, and 0: all cores). Does not change the image.
    #[arg(long, help_heading = HEADING_RUN)]
    pub threads: Option<usize>,
    /// View transform for .png/.ppm: pbr-neutral, agx, clamp, gamma2.2 or aces.
    ///
    /// pbr-neutral (Khronos PBR Neutral, the default) shows base colours as authored and rolls
    /// highlights off to white; agx (Blender's default) compresses a wider range with a filmic
    /// look; clamp is the thesis's sRGB clip. .exr and .hdr hold the radiance itself, whatever
    /// this says.
    #[arg(long, default_value = "pbr-neutral", help_heading = HEADING_OUTPUT)]
    pub tonemap: Tonemap,
    /// Camera to render, by name or index (default: the first).
    #[arg(long, help_heading = HEADING_SCENE)]
    pub camera: Option<String>,
    /// When to add the default studio environment: auto, on, off or uniform.
    ///
    /// auto: when the scene has no lights, or only self-lit emissive surfaces such as decals and
    /// labels with radiance <= 1; on: unless the scene has an environment; off: never; uniform:
    /// as auto, with a uniform white environment of radiance 1 instead of the studio (a soft key
    /// light above the viewer, a fill, a rim and a darker floor, turned to the camera). Default:
    /// the scene file's `default_light`, else auto.
    #[arg(long, value_name = "MODE", help_heading = HEADING_SCENE)]
    pub default_light: Option<DefaultLight>,
    /// Same as `--default-light off` (kept for older scripts).
    #[arg(long, conflicts_with = "default_light", help_heading = HEADING_SCENE, hide_short_help = true)]
    pub no_default_light: bool,
    /// Light the scene with an equirectangular environment map (.hdr or .exr).
    #[arg(long, value_name = "FILE", help_heading = HEADING_SCENE)]
    pub env: Option<std::path::PathBuf>,
    /// Turn the --env map about the up axis (+y) by DEGREES, counter-clockwise seen from above
    /// (TOML scenes: `rotation` of the environment).
    #[arg(
        help_heading = HEADING_SCENE, hide_short_help = true,
        long,
        value_name = "DEGREES",
        requires = "env",
        allow_negative_numbers = true
    )]
    pub env_rotation: Option<f32>,
    /// Render from the camera in FILE: a TOML file with a `[camera]` table (eye, target, up, fov;
    /// the web viewport's "Save camera" writes one) or any scene file, whose first camera is used.
    #[arg(long, value_name = "FILE", conflicts_with = "camera", help_heading = HEADING_SCENE, hide_short_help = true)]
    pub camera_from: Option<PathBuf>,
    /// glTF material variant to render (KHR_materials_variants; `trayecto info` lists them).
    /// Default: the file's default materials.
    #[arg(long, value_name = "NAME", help_heading = HEADING_SCENE, hide_short_help = true)]
    pub variant: Option<String>,
    /// Render an animated scene (glTF animations, skins, morph targets; pbrt motion) at this
    /// time in seconds. Default: the file's rest pose.
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub time: Option<f64>,
    /// Render frame N of the animation: time N / --fps.
    #[arg(long, value_name = "N", conflicts_with_all = ["time", "frames"])]
    pub frame: Option<u32>,
    /// Render frames A..B (inclusive) of the animation, loading the scene once; each output is
    /// numbered (-o out.exr writes out_0001.exr, out_0002.exr and so on).
    #[arg(long, value_name = "A..B", conflicts_with = "time")]
    pub frames: Option<String>,
    /// Frames per second for --frame/--frames. Default: the file's, else 24.
    #[arg(long, value_name = "FPS", hide_short_help = true)]
    pub fps: Option<f64>,
    /// Motion blur: the shutter is open from OPEN to CLOSE seconds (after --time or the frame's
    /// time when given, else scene time). Default: none (pbrt files: their camera's shutter).
    #[arg(long, value_name = "OPEN,CLOSE", allow_hyphen_values = true)]
    pub shutter: Option<String>,
    /// Motion blur: moving meshes, spheres, quads, boxes and instances (rigid, skinned, morphing;
    /// emitters and medium boundaries too), moving lights and a moving camera are keyed at this
    /// many + 1 times across the shutter and interpolated between them at each sample's time.
    /// Motion that is not (a moving curve or emissive box) is posed at this many times instead,
    /// a compiled world each. Default 16.
    #[arg(long, value_name = "N", hide_short_help = true)]
    pub shutter_steps: Option<u32>,
    /// How next-event estimation chooses a light: auto (bvh8 above 16 emitters, points and
    /// spots, else power), power (in proportion to power), bvh (the light BVH: by importance
    /// from the shading point, four children per tree node) or bvh8 (the same with eight
    /// children per tree node).
    #[arg(long, value_name = "SAMPLER", default_value = "auto", help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub light_sampler: LightSamplerKind,
    /// Texture filtering: none (each texture's own bilinear or nearest lookup at the hit) or
    /// trilinear (MIP pyramids built at load, read over each hit's pixel footprint from
    /// pbrt-v4-style ray differentials; path tracers and perspective cameras only). See docs/DESIGN.md.
    #[arg(long, value_name = "FILTER", default_value = "none", help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub texture_filter: trayecto::material::texture::TextureFilter,
    /// Render only sample indices A..B of the --spp frame (write a partial film: -o part.trp).
    #[arg(long, value_name = "A..B", help_heading = HEADING_FARM, hide_short_help = true)]
    pub samples: Option<String>,
    /// Save the film to FILE (a partial film) during the render and on Ctrl-C (or SIGTERM,
    /// SIGHUP), to --resume later. Without it, Ctrl-C writes the image of the completed passes.
    /// With --frames each frame saves to its own FILE_NNNN.
    #[arg(long, value_name = "FILE", help_heading = HEADING_FARM, hide_short_help = true)]
    pub checkpoint: Option<PathBuf>,
    /// Seconds between checkpoints (at the end of a pass; 0: after every pass).
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0, help_heading = HEADING_FARM, hide_short_help = true)]
    pub checkpoint_interval: f64,
    /// Continue the render saved in FILE by --checkpoint (same scene and settings); the result is
    /// identical to an uninterrupted render. Checkpoints go on to FILE unless --checkpoint says.
    /// With --frames: the sequence goes on where it stopped (finished frames are skipped).
    #[arg(long, value_name = "FILE", help_heading = HEADING_FARM, hide_short_help = true)]
    pub resume: Option<PathBuf>,
    /// Pixel reconstruction filter: box, tent, gaussian, mitchell or blackman-harris, by filter
    /// importance sampling. Default: the scene file's (a pbrt PixelFilter, else pbrt's Gaussian
    /// for .pbrt files), else box (one pixel, as glTF/TOML/OBJ/FBX scenes have always rendered).
    #[arg(long, value_name = "NAME", help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub filter: Option<FilterKind>,
    /// Filter radius in pixels (pbrt's xradius/yradius). Default per filter as in pbrt-v4: box
    /// 0.5, tent 2, gaussian 1.5, mitchell 2; blackman-harris 1.5 (Cycles' filter width).
    #[arg(long, value_name = "PIXELS", help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub filter_radius: Option<f32>,
    /// Standard deviation of the gaussian filter in pixels (pbrt default 0.5).
    #[arg(long, value_name = "PIXELS", help_heading = HEADING_SAMPLING, hide_short_help = true)]
    pub filter_sigma: Option<f32>,
    /// Adaptive sampling: stop a pixel once the relative standard error of its mean luminance is
    /// below X (e.g. 0.01).
    ///
    /// Judged after every pass from the passes before it; --spp is the most
    /// any pixel gets. The image is still a pure function of the seed and the settings. An .exr
    /// output holds the samples each pixel took and the variance as layers; beside other formats
    /// they are written only when asked for (`--aov samples,variance`).
    #[arg(long, value_name = "X", allow_negative_numbers = true, help_heading = HEADING_SAMPLING)]
    pub noise_threshold: Option<f32>,
    /// Progressive rendering: stop after the last pass that ends within SECONDS.
    ///
    /// The first pass always completes; a pass in flight when time runs out is dropped. Without --spp the frame
    /// is planned at 65536 spp. How many passes finish depends on the machine; the image after
    /// a given number of passes does not.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true, help_heading = HEADING_SAMPLING)]
    pub time_limit: Option<f64>,
    /// Render and write only this window, as fractions of the image: x0,x1,y0,y1 in 0..1 (pbrt's
    /// cropwindow: columns ceil(width*x0)..ceil(width*x1), likewise rows). The pixels are the same
    /// as in the full render. Default: the scene file's cropwindow/pixelbounds, else the whole image.
    #[arg(long, value_name = "X0,X1,Y0,Y1", conflicts_with = "pixel_bounds", help_heading = HEADING_FARM, hide_short_help = true)]
    pub crop: Option<String>,
    /// Render and write only columns x0..x1 and rows y0..y1 (pixels, ends excluded; pbrt's
    /// pixelbounds).
    #[arg(long, value_name = "X0,X1,Y0,Y1", help_heading = HEADING_FARM, hide_short_help = true)]
    pub pixel_bounds: Option<String>,
    /// Most memory loading the scene may take (e.g. 4G, 512M); a file that asks for more is
    /// an error naming it. Default: half the physical memory (or of `ulimit -v`).
    #[arg(long, value_name = "SIZE", value_parser = trayecto::limits::parse_size, help_heading = HEADING_RUN, hide_short_help = true)]
    pub memory_limit: Option<u64>,
    /// Print only errors.
    #[arg(short, long, help_heading = HEADING_RUN)]
    pub quiet: bool,
    /// A Mitsuba scene parameter, NAME=VALUE (overrides the file's <default>; repeatable).
    #[arg(short = 'D', long = "define", help_heading = HEADING_SCENE, value_name = "NAME=VALUE", value_parser = trayecto::scene::mitsuba::parse_define)]
    pub define: Vec<(String, String)>,
    /// Path guiding (experimental): learn where indirect light comes from in the render's first
    /// samples (iterations of 1, 2, 4, … per pixel until one fills its record budget, at most
    /// spp/4, under --time-limit at most about a third of the time; kept in the image) and
    /// sample those directions too, at surfaces and in media. Unbiased and deterministic (split
    /// and resumed renders learn the same guide). For indirect light through a door ajar or a
    /// window, or off a small bright patch: there it lowered the error 1.2–1.9× at equal time;
    /// through a thin slit and in fog it loses 11–21 % (BENCHMARKS.md, "Path guiding"). A TOML
    /// scene's `[render] guiding = true` turns it on too.
    #[arg(long, help_heading = HEADING_SAMPLING)]
    pub guiding: bool,
    /// No path guiding, also where the scene file turns it on (TOML `[render] guiding = true`).
    #[arg(long, help_heading = HEADING_SAMPLING, hide_short_help = true, conflicts_with = "guiding")]
    pub no_guiding: bool,
    /// Most a sample's direct light may add (its largest colour channel; off by default).
    ///
    /// Light seen by the camera or after one bounce is scaled down to X. Biased, like Cycles'
    /// Clamp Direct: it removes noise by darkening what it cuts; leave it off for references.
    #[arg(long, value_name = "X", help_heading = HEADING_SAMPLING)]
    pub clamp_direct: Option<f32>,
    /// Most a sample's indirect light may add (off by default): tames fireflies.
    ///
    /// Light that bounced twice or more (caustics through glass, small bright reflections) is
    /// scaled down to X in its largest colour channel. Biased, like Cycles' Clamp Indirect:
    /// values around 10 remove fireflies at preview sample counts and darken caustics.
    #[arg(long, value_name = "X", help_heading = HEADING_SAMPLING)]
    pub clamp_indirect: Option<f32>,
    /// Read only files inside the scene file's folder, as the server does.
    ///
    /// By default the command line reads what a scene file names, as pbrt-v4, Mitsuba and
    /// Blender do: `../textures/x.png`, absolute paths, symbolic links into asset libraries.
    /// With this, each is refused with an error naming it.
    #[arg(long, help_heading = HEADING_SCENE, hide_short_help = true)]
    pub confine_paths: bool,
    /// Transparent background: alpha is the coverage of camera rays hitting geometry.
    ///
    /// As Cycles' Film › Transparent: the background the camera sees is left out (the
    /// environment still lights the scene), so the colours are premultiplied by the alpha. An
    /// .exr output gets RGBA (premultiplied, OpenEXR's convention); a .png gets RGBA with
    /// straight alpha (PNG's convention: colour divided by alpha before the view transform).
    /// Path tracers only.
    #[arg(long, help_heading = HEADING_OUTPUT)]
    pub transparent: bool,
    /// Render spectrally: each sample carries three wavelengths, accumulated through CIE 1931.
    ///
    /// RGB colours are upsampled to smooth spectra where they enter a path (Jakob & Hanika 2019;
    /// illuminants × D65), lights given as spectra (blackbody, named, sampled) are exact per
    /// wavelength and dispersive glass (KHR_materials_dispersion) splits white light. The path
    /// tracers, the light tracer, BDPT and MLT (media included), SPPM and VCM; raycast and
    /// Whitted are refused. pbrt files render spectrally without it, as pbrt-v4
    /// does (RGB where the integrator has no spectral path); other formats in linear sRGB.
    #[arg(long, help_heading = HEADING_EXPERT, hide_short_help = true, conflicts_with = "rgb")]
    pub spectral: bool,
    /// Render in linear sRGB, also a pbrt file (which renders spectrally by default).
    #[arg(long, help_heading = HEADING_EXPERT, hide_short_help = true)]
    pub rgb: bool,
}

#[derive(Args, Debug, Clone)]
pub struct InfoArgs {
    /// Scene file or built-in name.
    pub scene: String,
    /// A Mitsuba scene parameter, NAME=VALUE (overrides the file's <default>; repeatable).
    #[arg(short = 'D', long = "define", value_name = "NAME=VALUE", value_parser = trayecto::scene::mitsuba::parse_define)]
    pub define: Vec<(String, String)>,
    /// Read only files inside the scene file's folder, as the server does.
    #[arg(long)]
    pub confine_paths: bool,
}

impl RenderArgs {
    /// The render settings these options describe (checked by [`RenderJob::check`]).
    pub fn settings(&self) -> RenderSettings {
        RenderSettings {
            width: self.width.unwrap_or(512),
            height: self.height.unwrap_or(512),
            // A time-limited render without a sample count runs until the time is up.
            spp: self.spp.unwrap_or(if self.time_limit.is_some() {
                trayecto::render::TIME_LIMIT_SPP
            } else {
                trayecto::render::DEFAULT_SPP
            }),
            seed: self.seed,
            // 0 means every core, as it does for make -j and Cycles.
            threads: self.threads.filter(|&t| t > 0),
            sampler: self.sampler,
            integrator: self
                .integrator
                .unwrap_or_default()
                .with_options(self.raycast_view(), self.shading),
            path: PathSettings {
                max_depth: self
                    .max_depth
                    .unwrap_or(trayecto::integrator::settings::DEFAULT_MAX_DEPTH),
                rr_depth: self.rr_depth,
                rr_scale: self.rr_scale,
                nee: !self.no_nee,
                mis: !self.no_mis,
                secondary: self.secondary,
                clamp_direct: self.clamp_direct.unwrap_or(f32::INFINITY),
                clamp_indirect: self.clamp_indirect.unwrap_or(f32::INFINITY),
                transparent: self.transparent,
                spectral: self.spectral,
                ..Default::default()
            },
            filter: self.filter(),
            noise_threshold: self.noise_threshold,
            time_limit: self.time_limit,
            crop: None,
            // Set by the pipeline when the variance AOV is asked for.
            track_variance: false,
            // Set by the pipeline when the alpha AOV is asked for.
            track_coverage: false,
            guiding: self.guiding,
            photon: trayecto::integrator::sppm::PhotonSettings {
                photons_per_iteration: self.photons_per_iteration,
                radius: self.photon_radius,
                no_merge: self.vcm_no_merge,
            },
            mlt: trayecto::sampling::mlt::MltSettings {
                bootstrap_samples: self.mlt_bootstrap_samples,
                chains: self.mlt_chains,
                large_step_probability: self.mlt_large_step_probability,
                sigma: self.mlt_sigma,
            },
        }
    }

    /// The filter these options describe: --filter (default box) with --filter-radius and
    /// --filter-sigma over pbrt-v4's defaults for it.
    pub fn filter(&self) -> Filter {
        let mut f = Filter::new(self.filter.unwrap_or_default());
        if let Some(r) = self.filter_radius {
            f.radius = [r, r];
        }
        if let Some(s) = self.filter_sigma {
            f.sigma = s;
        }
        f
    }

    /// The raycast view `--aov` picks: with `--integrator raycast`, a single view name.
    fn raycast_view(&self) -> Aov {
        match (&self.integrator, &self.aov) {
            (Some(IntegratorKind::Raycast { .. }), Some(a)) => a.trim().parse().unwrap_or_default(),
            _ => Aov::default(),
        }
    }

    /// The AOV layers `--aov` asks for (none when it picks a raycast view).
    pub fn aov_layers(&self) -> Result<Vec<AovKind>> {
        let Some(list) = &self.aov else {
            return Ok(Vec::new());
        };
        if matches!(self.integrator, Some(IntegratorKind::Raycast { .. }))
            && list.trim().parse::<Aov>().is_ok()
        {
            return Ok(Vec::new());
        }
        AovKind::parse_list(list).map_err(|e| anyhow::anyhow!("invalid setting: --aov: {e}"))
    }

    pub fn world_options(&self) -> WorldOptions {
        WorldOptions {
            accel: self.accel,
            camera: self.camera.clone(),
            default_light: if self.no_default_light {
                Some(DefaultLight::Off)
            } else {
                self.default_light
            },
            env: self.env.clone(),
            env_rotation: self.env_rotation.unwrap_or(0.0),
            camera_override: None,
            variant: self.variant.clone(),
            light_sampler: self.light_sampler,
            texture_filter: self.texture_filter,
            instancing: Default::default(),
            time: trayecto::world::motion::TimeOptions {
                time: self.time,
                frame: self.frame,
                fps: self.fps,
                shutter: self.shutter.as_deref().and_then(parse_shutter),
                steps: self.shutter_steps.unwrap_or(0),
            },
        }
    }

    /// `--frames A..B`, inclusive.
    pub fn frame_range(&self) -> Result<Option<std::ops::RangeInclusive<u32>>> {
        let Some(f) = &self.frames else {
            return Ok(None);
        };
        let parsed = f.split_once("..").and_then(|(a, b)| {
            Some((a.trim().parse::<u32>().ok()?, b.trim().parse::<u32>().ok()?))
        });
        match parsed {
            Some((a, b)) if a <= b => Ok(Some(a..=b)),
            _ => bail!("invalid setting: --frames must be A..B with A <= B (got '{f}')"),
        }
    }

    /// The pipeline job these options describe.
    pub fn job(&self) -> Result<RenderJob> {
        let samples = self
            .samples
            .as_deref()
            .map(trayecto::split::parse_range)
            .transpose()
            .map_err(|e| anyhow::anyhow!("invalid setting: --samples: {e}"))?;
        if (self.filter_radius.is_some() || self.filter_sigma.is_some()) && self.filter.is_none() {
            bail!("invalid setting: --filter-radius and --filter-sigma need --filter NAME");
        }
        if self.filter_sigma.is_some() && self.filter != Some(FilterKind::Gaussian) {
            bail!("invalid setting: --filter-sigma applies to --filter gaussian only");
        }
        let crop = match (&self.crop, &self.pixel_bounds) {
            (Some(c), _) => Some(
                CropSpec::parse(c, false)
                    .map_err(|e| anyhow::anyhow!("invalid setting: --crop: {e}"))?,
            ),
            (None, Some(p)) => Some(
                CropSpec::parse(p, true)
                    .map_err(|e| anyhow::anyhow!("invalid setting: --pixel-bounds: {e}"))?,
            ),
            (None, None) => None,
        };
        for (name, v) in [
            ("--clamp-direct", self.clamp_direct),
            ("--clamp-indirect", self.clamp_indirect),
        ] {
            if let Some(x) = v
                && !(x.is_finite() && x > 0.0)
            {
                bail!("invalid setting: {name} must be a positive number (got {x})");
            }
        }
        if !(self.checkpoint_interval >= 0.0 && self.checkpoint_interval <= 1e9) {
            bail!(
                "invalid setting: --checkpoint-interval must be 0 or more seconds (got {})",
                self.checkpoint_interval
            );
        }
        if self.spectral
            && let Some(k) = self.integrator
            && !k.carries_wavelengths()
        {
            bail!(
                "invalid setting: --spectral needs --integrator path, lighttracer, bdpt, mlt, sppm or vcm (got {})",
                k.name()
            );
        }
        if self.transparent && self.integrator.is_some_and(|k| k != IntegratorKind::Path) {
            bail!("invalid setting: --transparent needs --integrator path");
        }
        let mut aovs = self.aov_layers()?;
        if self.transparent && !aovs.contains(&AovKind::Alpha) {
            aovs.push(AovKind::Alpha);
        }
        if let Some(sh) = &self.shutter
            && parse_shutter(sh).is_none()
        {
            bail!("invalid setting: --shutter must be OPEN,CLOSE in seconds (got '{sh}')");
        }
        let mut world = self.world_options();
        if let Some(f) = &self.camera_from {
            world.camera_override = Some(trayecto::pipeline::camera_from_file(f)?);
        }
        Ok(RenderJob {
            scene: self.scene.clone(),
            world,
            settings: self.settings(),
            // Options left out take the scene file's own value (pbrt's Film, Sampler,
            // Integrator), else the defaults above.
            given: GivenSettings {
                width: self.width.is_some(),
                height: self.height.is_some(),
                spp: self.spp.is_some() || self.time_limit.is_some(),
                max_depth: self.max_depth.is_some(),
                filter: self.filter.is_some(),
                integrator: self.integrator.is_some(),
                spectral: self.spectral || self.rgb,
                guiding: self.guiding || self.no_guiding,
            },
            outputs: vec![OutputSpec {
                path: self.output.clone(),
                exposure: self.exposure,
                tonemap: self.tonemap,
            }],
            split: SplitOptions {
                samples,
                // A resumed render goes on saving into its checkpoint.
                checkpoint: self.checkpoint.clone().or_else(|| self.resume.clone()),
                checkpoint_interval: std::time::Duration::from_secs_f64(self.checkpoint_interval),
                resume: self.resume.clone(),
                // Ctrl-C without a checkpoint still writes the image of the completed passes.
                write_on_interrupt: true,
            },
            crop,
            aovs,
            denoise: self.denoise.then(|| DenoiseOptions {
                library: self.oidn.clone(),
            }),
        })
    }
}

/// The terminal's view of a render: warnings, the summary and the phase report unless `--quiet`
/// (errors only), a progress bar while rendering when stderr is a terminal.
struct Console {
    quiet: bool,
    bar: Option<indicatif::ProgressBar>,
}

impl RenderObserver for Console {
    fn tile_done(&self, done: u64, total: u64) {
        if let Some(b) = &self.bar {
            b.set_length(total);
            b.set_position(done);
        }
    }

    /// The renderer's estimate (`render::remaining_time`), not indicatif's rate of recent
    /// steps: tiles of a pass differ in cost, passes do not.
    fn progress(&self, progress: &trayecto::render::Progress) {
        if let (Some(b), Some(left)) = (&self.bar, progress.remaining) {
            let s = left.as_secs();
            b.set_message(format!("eta {}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60));
        }
    }
}

impl PipelineObserver for Console {
    fn stage_finished(&self, stage: Stage, _took: std::time::Duration) {
        if let (Stage::Render, Some(b)) = (stage, &self.bar) {
            b.finish_and_clear();
        }
    }

    fn log(&self, line: LogLine) {
        if !self.quiet {
            eprintln!("{line}");
        }
    }
}

/// Set by Ctrl-C, SIGTERM and SIGHUP: the render stops after the pass in flight and saves what
/// it has (the checkpoint, else the image of the completed passes).
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// The exit code of a render stopped by Ctrl-C (128 + SIGINT, as shells report it; SIGTERM and
/// SIGHUP, handled alike, end with it too).
pub const EXIT_INTERRUPTED: u8 = 130;

/// `OPEN,CLOSE` in seconds.
fn parse_shutter(s: &str) -> Option<[f64; 2]> {
    let (a, b) = s.split_once(',')?;
    Some([a.trim().parse().ok()?, b.trim().parse().ok()?])
}

/// A render stopped by Ctrl-C: the message says what was saved.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Interrupted(String);

pub fn run_render(args: &RenderArgs) -> Result<()> {
    trayecto::scene::mitsuba::set_defines(args.define.clone());
    let job = args.job()?;
    let frames = args.frame_range()?;
    // A sequence checks itself per frame (`RenderJob::run_frames`: its --resume names a pattern).
    if frames.is_none() {
        job.check()?;
    }
    let bar = if std::io::stderr().is_terminal() && !args.quiet {
        let b = indicatif::ProgressBar::new(1);
        b.set_message("eta ?");
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40.cyan/blue} {percent:>3}% {elapsed_precise} ({msg})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Some(b)
    } else {
        None
    };
    let console = Console {
        quiet: args.quiet,
        bar,
    };
    // Ctrl-C (and SIGTERM, SIGHUP: the `termination` feature of ctrlc) stops after the pass in
    // flight and saves what it has; a second one exits at once. One handler per process: a
    // second render in the same process keeps the first.
    let _ = ctrlc::set_handler(|| {
        if INTERRUPTED.swap(true, std::sync::atomic::Ordering::SeqCst) {
            std::process::exit(EXIT_INTERRUPTED as i32);
        }
    });
    if let Some(m) = args.memory_limit {
        trayecto::limits::set_default_limit(m);
    }
    // Loads stop at Ctrl-C too (checked at each file read and in long loops).
    let load = trayecto::limits::LoadContext::with_paths(
        trayecto::limits::Budget::new(trayecto::limits::default_limit()),
        Some(std::sync::Arc::new(|| {
            INTERRUPTED.load(std::sync::atomic::Ordering::Relaxed)
        })),
        path_rule(args.confine_paths),
    );
    let result = trayecto::limits::scope(load, || match frames {
        Some(range) => job.run_frames(range, &console, &INTERRUPTED).map(|_| ()),
        None => job.run(&console, &INTERRUPTED).map(|_| ()),
    });
    match result {
        Ok(_) => Ok(()),
        Err(e @ PipelineError::Interrupted { .. }) => Err(Interrupted(e.to_string()).into()),
        Err(PipelineError::Cancelled) => Err(Interrupted(
            "interrupted before a pass completed; nothing saved (use --checkpoint FILE to be \
             able to resume)"
                .into(),
        )
        .into()),
        Err(e) => Err(e.into()),
    }
}

pub fn run_merge(args: &MergeArgs) -> Result<()> {
    use trayecto::split::partial::{PartFile, check_merge, merge};
    let partial_output = is_partial_film(&args.output);
    if args.output.is_dir() {
        bail!(
            "{}: is a folder: name a file in it (e.g. -o folder/merged.exr)",
            args.output.display()
        );
    }
    if !partial_output {
        Format::from_path(&args.output)?;
    }
    if !(args.exposure.is_finite() && args.exposure > 0.0) {
        bail!(
            "invalid setting: exposure must be a positive number (got {})",
            args.exposure
        );
    }
    // Every header first: parts of another frame, gaps and overlaps are refused before any
    // pixels are read.
    let mut files = Vec::with_capacity(args.parts.len());
    for p in &args.parts {
        files.push(PartFile::open(p)?);
    }
    let headers: Vec<_> = files
        .iter()
        .map(|f| (f.path.as_path(), &f.header))
        .collect();
    check_merge(&headers, !partial_output).context("cannot merge")?;
    let mut parts = Vec::with_capacity(files.len());
    for f in files {
        parts.push((f.path.clone(), f.read()?));
    }
    let merged = merge(parts, !partial_output).context("cannot merge")?;
    if partial_output {
        merged.write(&args.output)?;
    } else {
        // A `--transparent` frame's parts hold coverage: the image gets its alpha channel (EXR
        // `A`, PNG RGBA), as the single render writes it.
        let layers = trayecto::film::aov::film_layers(&merged.film, &[AovKind::Alpha]);
        let output = trayecto::pipeline::OutputSpec {
            path: args.output.clone(),
            exposure: args.exposure,
            tonemap: args.tonemap,
        };
        trayecto::pipeline::write_outputs(&merged.film.to_image(), None, &[output], &layers)?;
    }
    if args.quiet {
        return Ok(());
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

/// The command line reads what a scene file names unless told to confine it to its folder.
fn path_rule(confine: bool) -> trayecto::limits::PathRule {
    if confine {
        trayecto::limits::PathRule::Confined
    } else {
        trayecto::limits::PathRule::Open
    }
}

pub fn run_info(args: &InfoArgs) -> Result<()> {
    trayecto::scene::mitsuba::set_defines(args.define.clone());
    let load = trayecto::limits::LoadContext::with_paths(
        trayecto::limits::Budget::new(trayecto::limits::default_limit()),
        None,
        path_rule(args.confine_paths),
    );
    trayecto::limits::scope(load, || info(args))
}

fn info(args: &InfoArgs) -> Result<()> {
    let scene = trayecto::scene::load(&args.scene)?;
    // The world takes the scene; keep what is printed that the world does not hold.
    let (name, meshes, objects) = (scene.name.clone(), scene.meshes.len(), scene.objects.len());
    let (lights, cameras) = (scene.lights.clone(), scene.cameras.clone());
    let media = scene.media.clone();
    let scene_warnings = scene.warnings.clone();
    let scene_notes = scene.notes.clone();
    let hints = scene.hints.clone();
    let variants = scene.variants.clone();
    let animation = scene.animation.clone();
    let world = World::build(scene, &WorldOptions::default())?;
    let b = world.bounds;
    println!("scene       {name}");
    if let Some(a) = animation.filter(|a| a.moves()) {
        // What --time/--frame/--frames/--shutter can choose from.
        let (t0, t1) = a.time_range().unwrap_or((0.0, 0.0));
        println!("animation   {t0:.3} s – {t1:.3} s (--time, --frame, --frames, --shutter)");
    }
    println!("meshes      {meshes}");
    println!("objects     {objects}");
    println!("triangles   {}", world.triangle_count());
    println!("primitives  {}", world.primitive_count());
    println!(
        "bounds      [{:.4}, {:.4}, {:.4}] – [{:.4}, {:.4}, {:.4}]",
        b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
    );
    println!("materials   {}", world.materials.len());
    for (i, m) in world.materials.iter().enumerate() {
        let textures = m.texture_refs().count();
        println!(
            "  {i}: '{}' {} base colour {}{}{}",
            m.name,
            m.model.name(),
            vec3(m.base_color),
            if textures > 0 {
                format!(", {textures} texture(s)")
            } else {
                String::new()
            },
            if m.is_emissive() { " (emissive)" } else { "" }
        );
    }
    // Texel memory by storage kind (8-bit textures stay 8-bit).
    let mut kinds: std::collections::BTreeMap<&str, (usize, usize)> = Default::default();
    for t in &world.textures {
        // pbrt-v4 procedural textures are evaluated per hit; their one texel is their mean.
        let kind = if t.procedural.is_some() {
            "procedural"
        } else {
            t.texels.kind()
        };
        let k = kinds.entry(kind).or_default();
        k.0 += 1;
        k.1 += t.texel_bytes();
    }
    let total: usize = kinds.values().map(|k| k.1).sum();
    let texels: usize = world.textures.iter().map(|t| t.texels.len()).sum();
    println!(
        "textures    {} ({:.1} MiB for {texels} texels{})",
        world.textures.len(),
        total as f64 / (1024.0 * 1024.0),
        kinds
            .iter()
            .map(|(k, (n, _))| format!(", {n} {k}"))
            .collect::<String>()
    );
    if !variants.is_empty() {
        // KHR_materials_variants: the names --variant accepts; without it the file's default
        // materials (listed above) are rendered.
        println!(
            "variants    {} (--variant NAME; default: the file's default materials)",
            variants.len()
        );
        for (i, v) in variants.iter().enumerate() {
            println!("  {i}: '{v}'");
        }
    }
    if hints != trayecto::scene::RenderHints::default() {
        let show = |v: Option<u32>| v.map_or("-".to_string(), |v| v.to_string());
        println!(
            "file asks   {}x{} pixels, {} spp, max depth {}{}{}{}{}",
            show(hints.width),
            show(hints.height),
            show(hints.spp),
            show(hints.max_depth),
            hints
                .filter
                .map_or(String::new(), |f| format!(", {} filter", f.describe())),
            hints
                .crop
                .map_or(String::new(), |c| format!(", crop window {c:?}")),
            hints
                .pixel_bounds
                .map_or(String::new(), |c| format!(", pixel bounds {c:?}")),
            if hints.spectral {
                ", spectral (--rgb for RGB)"
            } else {
                ""
            }
        );
    }
    println!(
        "lights      {} ({} area)",
        world.lights.lights.len(),
        world.area_light_count()
    );
    for l in &lights {
        use trayecto::scene::LightDesc as L;
        let what = match l {
            L::Point {
                position: p,
                intensity: i,
                ..
            } => format!("point at {}, {} W/sr", vec3(*p), vec3(*i)),
            L::Spot {
                position: p,
                intensity: i,
                ..
            } => format!("spot at {}, {} W/sr", vec3(*p), vec3(*i)),
            L::Directional {
                direction: d,
                irradiance: e,
                ..
            } => {
                format!("directional towards {}, {} W/m²", vec3(*d), vec3(*e))
            }
            L::Ambient { radiance: r, .. } => format!("ambient, radiance {}", vec3(*r)),
            L::Environment { path, .. } => format!("environment map {}", path.display()),
        };
        println!("  '{}' {what}", l.name());
    }
    println!("cameras     {}", cameras.len());
    for (i, c) in cameras.iter().enumerate() {
        let view = match c.projection {
            trayecto::scene::Projection::Perspective => format!("vfov {:.2}°", c.vfov_deg),
            trayecto::scene::Projection::Orthographic { half_height } => {
                format!("orthographic, window half height {}", num(half_height))
            }
            trayecto::scene::Projection::Spherical(m) => format!("spherical ({m:?})"),
        };
        println!(
            "  {i}: '{}' at {} {view}",
            c.name,
            vec3(c.camera_to_world.w_axis.truncate()),
        );
    }
    for n in &scene_notes {
        println!("note        {n}");
    }
    println!("media       {}", media.len());
    for (i, m) in media.iter().enumerate() {
        use trayecto::scene::MediumKind as K;
        let kind = match &m.kind {
            K::Homogeneous => "homogeneous".to_string(),
            K::Grid { nx, ny, nz, .. } => format!("grid {nx}x{ny}x{nz}"),
            #[allow(unreachable_patterns)]
            _ => "heterogeneous".to_string(),
        };
        println!(
            "  {i}: '{}' {kind}, σa {}, σs {}, scale {}, g {}{}",
            m.name,
            vec3(m.sigma_a),
            vec3(m.sigma_s),
            num(m.scale),
            num(m.g),
            if m.le != trayecto::math::Vec3::ZERO {
                format!(", emits {}", vec3(m.le))
            } else {
                String::new()
            }
        );
    }
    println!(
        "renders     with the {} integrator by default (--integrator path)",
        trayecto::integrator::Integrator::for_world(IntegratorKind::Path, &world).name()
    );
    let warnings: Vec<&String> = scene_warnings.iter().chain(world.warnings.iter()).collect();
    println!("warnings    {}", warnings.len());
    for w in warnings {
        println!("  {w}");
    }
    Ok(())
}

/// A number for `trayecto info`: four significant digits, in scientific notation when very
/// small or large (a denormal albedo printed in full is 30 digits of zeros).
fn num(x: f32) -> String {
    let a = x.abs();
    if x == 0.0 || !x.is_finite() {
        format!("{x}")
    } else if !(1e-3..1e5).contains(&a) {
        format!("{x:.3e}")
    } else {
        let s = format!("{x:.4}");
        let s = s.trim_end_matches('0');
        s.trim_end_matches('.').to_string()
    }
}

/// A vector for `trayecto info`, each component as [`num`] prints it.
fn vec3(v: trayecto::math::Vec3) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

/// `--sample N` is a slip for `--spp N`; clap alone would suggest `--samples`, the farm's sample
/// range, which then fails on `N` with a message about ranges.
fn sample_slip(args: &[std::ffi::OsString]) -> Option<String> {
    let end = args.iter().position(|a| a == "--").unwrap_or(args.len());
    args[..end].iter().find_map(|a| {
        let a = a.to_str()?;
        (a == "--sample" || a.starts_with("--sample=")).then(|| {
            format!(
                "error: unexpected argument '{a}' found\n\n  tip: samples per pixel are \
                 '--spp N' ('--samples A..B' renders only a range of sample indices, for \
                 rendering one frame on several machines)\n\nFor more information, try '--help'."
            )
        })
    })
}

pub fn main() -> ExitCode {
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    if let Some(e) = sample_slip(&args) {
        eprintln!("{e}");
        return ExitCode::from(2);
    }
    let cli = Cli::parse_from(args);
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

/// The guide's options tables (docs/src/rendering.md, docs/src/web-ui.md), generated from clap's own
/// definitions (`scripts/readme-options.sh` rewrites them; the test below fails when they drift).
/// The README leads with the same commands as `--help`.
#[cfg(test)]
mod readme {
    use super::Cli;
    use clap::CommandFactory;

    /// The markdown table of one subcommand's options: flag, default, help.
    fn table(sub: &str) -> String {
        let cmd = Cli::command();
        let cmd = cmd.find_subcommand(sub).expect("subcommand");
        let mut t = String::from("| option | default | meaning |\n|---|---|---|\n");
        for a in cmd.get_arguments() {
            let Some(long) = a.get_long() else { continue };
            if long == "help" || long == "version" {
                continue;
            }
            let takes_value = a.get_action().takes_values();
            let mut flag = match a.get_short() {
                Some(c) => format!("`-{c}`, `--{long}`"),
                None => format!("`--{long}`"),
            };
            if takes_value {
                let v = a
                    .get_value_names()
                    .and_then(|v| v.first().map(|s| s.to_string()))
                    .unwrap_or_else(|| long.to_ascii_uppercase().replace('-', "_"));
                flag = flag.replacen(&format!("`--{long}`"), &format!("`--{long} {v}`"), 1);
            }
            let defaults: Vec<String> = a
                .get_default_values()
                .iter()
                .map(|d| d.to_string_lossy().into_owned())
                .collect();
            let default = if !defaults.is_empty() {
                format!("`{}`", defaults.join(" "))
            } else if takes_value {
                "see meaning".to_string()
            } else {
                "off".to_string()
            };
            let help = a
                .get_long_help()
                .or(a.get_help())
                .map(|h| h.to_string())
                .unwrap_or_default()
                .replace('\n', " ")
                .replace('|', "\\|");
            t.push_str(&format!("| {flag} | {default} | {help} |\n"));
        }
        t
    }

    fn section(readme: &str, sub: &str) -> Option<(usize, usize)> {
        let begin = format!("<!-- options:{sub} begin (scripts/readme-options.sh) -->\n");
        let end = format!("<!-- options:{sub} end -->");
        let b = readme.find(&begin)? + begin.len();
        let e = b + readme[b..].find(&end)?;
        Some((b, e))
    }

    /// Each subcommand's table and the guide chapter that holds it.
    const TABLES: [(&str, &str); 2] = [
        ("render", "docs/src/rendering.md"),
        ("serve", "docs/src/web-ui.md"),
    ];

    fn chapter(file: &str) -> (std::path::PathBuf, String) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
        let text =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        (path, text)
    }

    #[test]
    fn readme_options_tables_match_clap() {
        let regenerate = std::env::var_os("TRAYECTO_REGENERATE_README").is_some();
        for (sub, file) in TABLES {
            let (path, mut doc) = chapter(file);
            let (b, e) =
                section(&doc, sub).unwrap_or_else(|| panic!("{file} has no options:{sub} markers"));
            let want = table(sub);
            if regenerate {
                doc.replace_range(b..e, &want);
                std::fs::write(path, doc).unwrap();
                continue;
            }
            let have = &doc[b..e];
            // Every clap option, with its default, is a row of the table: the same text.
            for (h, w) in have.lines().zip(want.lines()) {
                assert_eq!(
                    h, w,
                    "{file}'s {sub} options table differs from clap; run scripts/readme-options.sh"
                );
            }
            assert_eq!(
                have, want,
                "{file}'s {sub} options table differs from clap; run scripts/readme-options.sh"
            );
        }
    }

    #[test]
    fn every_option_is_listed_with_its_default() {
        // Independent of the generator: each long option and each clap default appears.
        for (sub, file) in TABLES {
            let (_, doc) = chapter(file);
            let (b, e) = section(&doc, sub).unwrap();
            let rows = &doc[b..e];
            let cmd = Cli::command();
            for a in cmd.find_subcommand(sub).unwrap().get_arguments() {
                let Some(long) = a.get_long() else { continue };
                if long == "help" {
                    continue;
                }
                let row = rows
                    .lines()
                    .find(|l| {
                        l.contains(&format!("`--{long}`")) || l.contains(&format!("`--{long} "))
                    })
                    .unwrap_or_else(|| panic!("--{long} ({sub}) is not in {file}'s table"));
                for d in a.get_default_values() {
                    let d = format!("`{}`", d.to_string_lossy());
                    assert!(
                        row.contains(&d),
                        "--{long}: default {d} missing in {file}'s row {row}"
                    );
                }
            }
        }
    }

    #[test]
    fn help_and_readme_lead_with_the_two_commands_and_examples() {
        let help = Cli::command().render_help().to_string();
        // The start lines come before the usage line.
        let usage = help.find("Usage:").expect("usage line");
        assert!(help[..usage].contains(super::HELP_START), "{help}");
        let readme =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
        for line in super::HELP_START.lines().filter(|l| l.starts_with("  ")) {
            // The command (the comment may be worded differently).
            let command = line.split('#').next().unwrap_or("").trim();
            assert!(
                readme.contains(command),
                "README.md lacks the help's command {command:?}"
            );
        }
        // The two commands come before any other section of the README.
        let first_section = readme.find("\n## ").unwrap();
        assert!(readme[first_section..].starts_with("\n## The two commands"));
    }
}
