//! Scene description: what every loader (built-in scenes, glTF, OBJ, PLY, FBX, TOML) produces and the
//! renderer consumes. It is plain data in the file's own terms (object-space meshes, transforms,
//! materials with texture references, lights, cameras); [`crate::world::World`] compiles it into the
//! render-time representation.

pub mod animation;
pub mod builtin;
pub mod conventions;
pub mod digest;
pub mod fbx;
pub mod gltf;
pub mod lighting;
pub mod mitsuba;
pub mod obj;
pub mod pbrt;
pub mod ply;
pub mod testscenes;
pub mod toml_scene;
pub mod vol;
pub mod volume;

// Texture decoding moved down to the crate's one image-reading module; loaders still name it here.
pub use crate::image_io;
pub use lighting::{DefaultLight, EnvMapping};

use std::path::Path;

use crate::material::{Material, Texture};
use crate::math::{Mat4, Vec2, Vec3, Vec4};
use std::path::PathBuf;

pub type MeshId = usize;
pub type MaterialId = usize;
/// Index into [`Scene::media`].
pub type MediumId = usize;

/// A participating medium in the file's own terms. Coefficients are RGB per unit
/// world length and are multiplied by `scale` (pbrt-v4's `scale`, Mitsuba's `scale`): σa·scale,
/// σs·scale. `g` is the Henyey–Greenstein asymmetry (−1 back, 0 isotropic, +1 forward; clamped to
/// ±0.99). `le` is emitted radiance (pbrt-v4's `Le` times `Lescale`; not scaled by `scale`): the
/// medium emits σa·Le per unit length (RTE emission term), so a thick absorbing medium glows
/// with radiance `le`.
#[derive(Clone, Debug, PartialEq)]
pub struct MediumDesc {
    pub name: String,
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    pub scale: f32,
    pub g: f32,
    pub le: Vec3,
    pub kind: MediumKind,
    /// σa and σs as the spectra the scene gave (a sampled list), which spectral rendering takes
    /// per wavelength (× `scale`); `sigma_a`/`sigma_s` are their RGB projections, what RGB mode
    /// uses. `None`: upsampled from the RGB.
    pub sigma_spectra: [Option<crate::spectrum::SpectrumTable>; 2],
    /// The emission `Le` as the spectrum the scene gave (a pbrt `blackbody`, a named or sampled
    /// spectrum), of `le` and of a grid's `GridEmission::Radiance`, which carry its RGB
    /// projection (luminance `Lescale`) for RGB mode; spectral rendering takes the spectrum
    /// per wavelength, scaled by that luminance ([`crate::spectrum::Illuminant::at`]). `None`:
    /// upsampled from the RGB.
    pub le_spectrum: Option<crate::spectrum::Illuminant>,
}

/// How the coefficients vary in space.
// A scene description, built once per medium and compiled into `medium::Medium`: the size of
// the Grid variant costs nothing, and boxing it would only obscure the importers' code.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum MediumKind {
    /// The same σa, σs everywhere.
    Homogeneous,
    /// σa, σs times a density from a grid of `nx·ny·nz` voxels (x fastest:
    /// index (z·ny + y)·nx + x) spanning the box `[min, max]` of medium space, which `transform`
    /// (world-from-medium) places in the world. Mitsuba's `.vol` files and pbrt-v4's
    /// `uniformgrid` (`density`, `p0`, `p1` under the CTM of `MakeNamedMedium`) both map onto it;
    /// lookups are trilinear between voxel centres (see `medium::grid`).
    Grid {
        nx: usize,
        ny: usize,
        nz: usize,
        density: Vec<f32>,
        min: Vec3,
        max: Vec3,
        transform: Mat4,
        /// How lookups behave between the outermost voxel centres and the box faces.
        edge: GridEdge,
        /// Emission that varies over the grid (pbrt-v4 `uniformgrid` `Lescale` / `temperature`);
        /// `MediumDesc::le` is a constant Le on top of it (zero for pbrt-v4 grids).
        emission: Option<GridEmission>,
    },
}

/// Lookups of a grid between the outermost voxel centres and the box faces.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GridEdge {
    /// The edge voxel's value is held up to the face (Mitsuba 3 `gridvolume`'s default `clamp`).
    #[default]
    Hold,
    /// Samples outside the grid count as 0, so values fade to the faces (pbrt-v4
    /// `SampledGrid::Lookup`, which returns a default value for out-of-range voxel indices).
    Zero,
}

/// A scalar voxel grid (x fastest: index (z·ny + y)·nx + x) spanning the same box as the medium's
/// density grid; its resolution may differ from the density's.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub data: Vec<f32>,
}

impl VoxelGrid {
    /// A 1×1×1 grid: pbrt-v4's default `Lescale` grid (one sample at the box centre, which with
    /// [`GridEdge::Zero`] fades linearly to half its value at a face's centre).
    pub fn single(v: f32) -> Self {
        VoxelGrid {
            nx: 1,
            ny: 1,
            nz: 1,
            data: vec![v],
        }
    }

    fn validate(&self, what: &str) -> Result<(), String> {
        let n = self
            .nx
            .checked_mul(self.ny)
            .and_then(|v| v.checked_mul(self.nz));
        if n != Some(self.data.len()) || self.data.is_empty() {
            return Err(format!(
                "the {what} grid is {} x {} x {} but has {} values",
                self.nx,
                self.ny,
                self.nz,
                self.data.len()
            ));
        }
        if let Some((i, v)) = self.data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(format!("{what} value {i} is {v}; values must be finite"));
        }
        Ok(())
    }
}

/// Emission of a grid medium (pbrt-v4 `GridMedium::SamplePoint`, media.h): the medium emits
/// σa(p)·Le(p) per unit length with Le(p) = `scale`(p) × a radiance. `scale` ≤ 0 emits nothing.
#[derive(Clone, Debug, PartialEq)]
pub enum GridEmission {
    /// Le(p) = scale(p)·`le` (pbrt-v4 `Le` × `Lescale`; `le` is already normalised as pbrt-v4
    /// normalises an illuminant spectrum, 1/SpectrumToPhotometric).
    Radiance { le: Vec3, scale: VoxelGrid },
    /// Le(p) = scale(p)·B(T) with T = (temperature(p) − `offset`)·`temperature_scale` and B the
    /// Planck spectrum normalised to a peak of 1 (pbrt-v4 `BlackbodySpectrum`), nothing at
    /// T ≤ 100 K (pbrt-v4's cut-off).
    Blackbody {
        temperature: VoxelGrid,
        scale: VoxelGrid,
        temperature_scale: f32,
        offset: f32,
    },
}

/// The media on the two sides of an object's surface: `inside` is the side opposite the geometric
/// normal (behind counter-clockwise faces; inside a closed outward-facing mesh, sphere or box),
/// `outside` the side the normal points to. `None` is vacuum. A ray crossing the surface continues
/// in the medium of the side it goes to. An object without an interface (`Object::medium` is
/// `None`) does not change the medium a ray is in (pbrt-v4's rule for shapes whose interface is
/// not a transition).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct MediumInterface {
    pub inside: Option<MediumId>,
    pub outside: Option<MediumId>,
}

/// A triangle mesh in object space.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
    pub normals: Option<Vec<Vec3>>,
    /// xyz tangent, w = ±1 bitangent sign (glTF convention).
    pub tangents: Option<Vec<Vec4>>,
    pub uv0: Option<Vec<Vec2>>,
    pub uv1: Option<Vec<Vec2>>,
    pub colors: Option<Vec<Vec4>>,
}

/// The shape an object places in the world.
#[derive(Clone, Debug)]
pub enum Shape {
    Mesh(MeshId),
    /// A sphere in object space. Its transform must be a similarity (uniform scale).
    Sphere {
        center: Vec3,
        radius: f32,
    },
    /// An axis-aligned box in object space; any affine transform.
    Cuboid {
        min: Vec3,
        max: Vec3,
    },
    /// A parallelogram `corner + u·e1 + v·e2`, front face along `e1 × e2`.
    Quad {
        corner: Vec3,
        e1: Vec3,
        e2: Vec3,
    },
    /// Cubic Bézier curve segments (pbrt-v4 `curve`), in object space.
    Curves(Box<CurveShape>),
}

/// Cubic Bézier segments swept with a width (pbrt-v4's `curve` shape; [`crate::geometry::curve`]).
#[derive(Clone, Debug, PartialEq)]
pub struct CurveShape {
    /// Control points of each segment.
    pub segments: Vec<[Vec3; 4]>,
    /// Width at each segment's two ends (object space).
    pub widths: Vec<[f32; 2]>,
    pub kind: crate::geometry::curve::CurveType,
    /// For ribbons, the normal at each segment's two ends.
    pub normals: Option<Vec<[Vec3; 2]>>,
    /// Each segment is split into 2^split_depth pieces, each a primitive (pbrt-v4's
    /// `splitdepth`, so the accelerator bounds curved hair tightly).
    pub split_depth: u32,
}

/// One shape placed in the world with a material. Several objects may share a mesh (instancing).
#[derive(Clone, Debug)]
pub struct Object {
    pub name: String,
    pub shape: Shape,
    pub transform: Mat4,
    pub material: MaterialId,
    /// The media this object's surface separates; `None` leaves a crossing ray's medium as it was.
    /// A surface that only bounds a medium uses a material of model
    /// [`crate::material::MaterialModel::Interface`] (no BSDF: rays pass straight through).
    pub medium: Option<MediumInterface>,
}

/// A perspective camera. Camera space looks down −z with +y up (glTF convention).
#[derive(Clone, Debug)]
pub struct CameraDesc {
    pub name: String,
    pub camera_to_world: Mat4,
    /// Vertical field of view in degrees.
    pub vfov_deg: f32,
    /// Aspect ratio the file asks for, if any (the render's width/height wins).
    pub aspect: Option<f32>,
    /// How the view is fitted to an image whose aspect ratio differs from `aspect`.
    pub fit: SensorFit,
    /// Lens radius; 0 is a pinhole.
    pub aperture_radius: f32,
    pub focus_distance: f32,
    /// How film points become rays (pinhole/thin lens by default).
    pub projection: Projection,
}

/// How a camera's field of view is fitted to an image of another aspect ratio than its own.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SensorFit {
    /// As Blender's sensor fit `AUTO` (glTF, FBX, TOML and the built-in scenes): the field of
    /// view across the larger side of the camera's own frame spans the larger side of the image.
    #[default]
    Auto,
    /// As pbrt-v4 (`PerspectiveCamera`'s screen window, a film of any shape) and Mitsuba's
    /// `fov_axis` `smaller`: the field of view spans the image's shorter side, so a pbrt file
    /// rendered at another resolution frames what pbrt-v4 would with that `Film`.
    Shorter,
    /// Mitsuba's `fov_axis` `x` (its default) and its orthographic window: the horizontal field
    /// of view is kept.
    Width,
    /// Mitsuba's `fov_axis` `y`: the vertical field of view is kept.
    Height,
    /// Mitsuba's `fov_axis` `diagonal` (and a `focal_length`): the diagonal field is kept.
    Diagonal,
}

/// A camera's projection (PBRT §5.2–5.4). The camera-to-world matrix and the lens are shared.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Projection {
    /// Rays from the eye (or the thin lens) through a window at tan(vfov/2) (PBRT §5.2.2).
    #[default]
    Perspective,
    /// Parallel rays down the view axis from a window `half_height` camera-space units high
    /// (PBRT §5.2.1, pbrt-v4 `OrthographicCamera`); `vfov_deg` is not used.
    Orthographic { half_height: f32 },
    /// Every direction around the eye, the image being the square of the mapping (pbrt-v4
    /// `SphericalCamera`, PBRT §5.3); `vfov_deg` and the lens are not used.
    Spherical(SphericalMapping),
}

/// The square-to-sphere mappings of pbrt-v4's `SphericalCamera`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SphericalMapping {
    /// Clarberg's equal-area octahedral mapping (pbrt-v4's default, `"equalarea"`).
    EqualArea,
    /// Latitude–longitude: θ = π·v from the pole, φ = 2π·u (`"equirectangular"`).
    Equirectangular,
}

impl CameraDesc {
    /// tan(vfov/2) for an image of aspect ratio `image_aspect` (width / height), fitted by
    /// the camera's [`SensorFit`]: `Auto`, as Blender's sensor fit `AUTO`, keeps the field of
    /// view across the larger side of the camera's own frame (vertical `vfov_deg` × `aspect`
    /// when the frame is wide) on the larger side of the image; `Shorter`, as pbrt-v4, keeps
    /// the field of view across the shorter side; `Width`, `Height` and `Diagonal` (Mitsuba's
    /// `fov_axis`) keep that one. Equal aspect ratios, or a camera without one, keep
    /// `vfov_deg`.
    pub fn fitted_tan_half_v(&self, image_aspect: f32) -> f32 {
        (self.vfov_deg.to_radians() * 0.5).tan() * self.fit_scale(image_aspect)
    }

    /// The factor by which the camera's window height is scaled for an image of aspect ratio
    /// `image_aspect` ([`CameraDesc::fitted_tan_half_v`]; the orthographic window fits the same).
    pub fn fit_scale(&self, image_aspect: f32) -> f32 {
        match self.aspect.filter(|a| a.is_finite() && *a > 0.0) {
            Some(a) if image_aspect.is_finite() && image_aspect > 0.0 => match self.fit {
                SensorFit::Auto => a.max(1.0) / image_aspect.max(1.0),
                // The window's half height is t over the shorter side's share: t for wide
                // frames, t / aspect for tall ones (pbrt-v4 `PerspectiveCamera`).
                SensorFit::Shorter => a.min(1.0) / image_aspect.min(1.0),
                // tan(hfov/2) = tan(vfov/2)·aspect is kept.
                SensorFit::Width => a / image_aspect,
                SensorFit::Height => 1.0,
                SensorFit::Diagonal => ((1.0 + a * a) / (1.0 + image_aspect * image_aspect)).sqrt(),
            },
            _ => 1.0,
        }
    }

    pub fn look_at(name: &str, eye: Vec3, target: Vec3, up: Vec3, vfov_deg: f32) -> CameraDesc {
        let dir = target - eye;
        let view = if dir.length_squared().is_finite() {
            Mat4::look_at_rh(eye, target, up)
        } else {
            // The squared distance overflowed (scenes with coordinates near 1e19 and beyond):
            // normalising would give a zero direction and a singular view; scale it down first.
            Mat4::look_to_rh(eye, dir / dir.abs().max_element(), up)
        };
        CameraDesc {
            name: name.to_string(),
            camera_to_world: view.inverse(),
            vfov_deg,
            aspect: None,
            fit: SensorFit::Auto,
            aperture_radius: 0.0,
            focus_distance: (target - eye).length().max(1e-6),
            projection: Projection::Perspective,
        }
    }
}

/// How a spot light's intensity falls from 1 at its inner cone to 0 at its outer cone, as a
/// function of t = (cos θ − cos outer) / (cos inner − cos outer).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpotFalloff {
    /// t², the ramp of the glTF `KHR_lights_punctual` reference implementation (glTF, FBX, TOML).
    #[default]
    SquaredRamp,
    /// t²(3 − 2t): pbrt-v4's `SpotLight::I`, `SmoothStep(cos θ, cos outer, cos inner)`.
    Smoothstep,
}

/// Lights that are not emissive surfaces. Radiometric units throughout (RGB):
/// intensity in W/sr, irradiance in W/m², radiance in W/(m²·sr).
#[derive(Clone, Debug)]
pub enum LightDesc {
    Point {
        name: String,
        position: Vec3,
        intensity: Vec3,
    },
    Spot {
        name: String,
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        /// Half-angles in radians.
        inner_angle: f32,
        outer_angle: f32,
        /// The shape of the ramp between the two cones.
        falloff: SpotFalloff,
    },
    Directional {
        name: String,
        /// Direction the light travels.
        direction: Vec3,
        irradiance: Vec3,
    },
    /// Uniform radiance from every direction (the thesis's "ambient" light).
    Ambient { name: String, radiance: Vec3 },
    /// Environment map (equirectangular, or pbrt-v4's equal-area square).
    Environment {
        name: String,
        path: PathBuf,
        scale: Vec3,
        mapping: EnvMapping,
        /// World-from-environment rotation.
        transform: Mat4,
    },
}

impl LightDesc {
    pub fn name(&self) -> &str {
        match self {
            LightDesc::Point { name, .. }
            | LightDesc::Spot { name, .. }
            | LightDesc::Directional { name, .. }
            | LightDesc::Ambient { name, .. }
            | LightDesc::Environment { name, .. } => name,
        }
    }
}

#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub name: String,
    /// Where the scene was read from, for messages.
    pub source: Option<PathBuf>,
    pub meshes: Vec<Mesh>,
    pub objects: Vec<Object>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub lights: Vec<LightDesc>,
    pub cameras: Vec<CameraDesc>,
    /// Participating media, referenced by [`MediumInterface`]s and `camera_medium`.
    pub media: Vec<MediumDesc>,
    /// The medium the camera sits in (a global fog when objects do not bound it), for every camera.
    pub camera_medium: Option<MediumId>,
    /// Everything in the file that was not understood or not supported, by name.
    pub warnings: Vec<String>,
    /// What the loader wants the user to know that is not a problem: the plugins a Mitsuba
    /// file used and where Trayecto approximates them (`trayecto info` lists them).
    pub notes: Vec<String>,
    /// The file's own choice of default lighting (TOML `default_light`); the command line wins.
    pub default_light: Option<DefaultLight>,
    /// Render settings the file asks for (pbrt's Film, Sampler, Integrator); the command line
    /// overrides each.
    pub hints: RenderHints,
    /// glTF `KHR_materials_variants`: the file's variant names, in file order.
    pub variants: Vec<String>,
    /// The objects whose material a variant changes ([`Scene::select_variant`]).
    pub variant_objects: Vec<ObjectVariants>,
    /// The variant [`Scene::select_variant`] chose; `None` is the file's default materials.
    pub active_variant: Option<String>,
    /// What moves, kept so [`Scene::pose`] can pose the scene at any time
    /// ([`animation`]); `None` for a static file.
    pub animation: Option<animation::AnimationRef>,
    /// The emission spectra of lights in [`Scene::lights`] that were given as spectra (a pbrt-v4
    /// `blackbody`, named or sampled `I`/`L`), by index: their `LightDesc` holds the RGB
    /// projection, which RGB mode uses; spectral rendering evaluates the spectrum.
    pub light_spectra: Vec<(usize, crate::spectrum::Illuminant)>,
    /// Sampled spectra of BSDF parameters (a conductor's η or k, a dielectric's η given as
    /// `[λ v …]` or a file), which materials name by id ([`Scene::add_bsdf_spectrum`]);
    /// the world holds them as [`crate::spectrum::BsdfSpectra::tables`].
    pub bsdf_spectra: Vec<crate::spectrum::SpectrumTable>,
}

/// One object's materials under `KHR_materials_variants`: the default (the primitive's own
/// `material`) and, per variant index, the material that variant maps it to. Each comes with the
/// medium interface its material implies (glTF volume absorption).
#[derive(Clone, Debug)]
pub struct ObjectVariants {
    pub object: usize,
    pub default: (MaterialId, Option<MediumInterface>),
    pub by_variant: Vec<(usize, MaterialId, Option<MediumInterface>)>,
}

/// Render settings a scene file may carry. `None` leaves the front end's default.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderHints {
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub spp: Option<u32>,
    pub max_depth: Option<u32>,
    /// Crop window [x0, x1, y0, y1] in [0, 1] (pbrt's `cropwindow`).
    pub crop: Option<[f32; 4]>,
    /// Pixel bounds [x0, x1, y0, y1] (pbrt's `pixelbounds`), used when there is no `crop`.
    pub pixel_bounds: Option<[u32; 4]>,
    /// The file's reconstruction filter (pbrt's `PixelFilter`, default Gaussian).
    pub filter: Option<crate::film::filter::Filter>,
    /// The integrator the file asks for when Trayecto has it, by its `--integrator` name (pbrt's
    /// `Integrator "lighttracer"`); `None` renders with the job's (the path tracer by default).
    pub integrator: Option<String>,
    /// AOV layers the file asks for (Mitsuba's `aov` integrator), written when the job asks
    /// for none itself.
    pub aovs: Vec<crate::film::aov::AovKind>,
    /// pbrt's `Integrator "sppm"` parameters `photonsperiteration` (when positive) and `radius`.
    pub photons_per_iteration: Option<u64>,
    pub photon_radius: Option<f32>,
    /// pbrt's `Integrator "mlt"` parameters (its `mutationsperpixel` in `mlt_mutations`, the
    /// render's samples per pixel).
    pub mlt: Option<crate::sampling::mlt::MltSettings>,
    pub mlt_mutations: Option<u32>,
    /// The format renders spectrally by default (pbrt-v4 files: pbrt-v4 always does); the
    /// user's `--spectral`/`--rgb` wins ([`crate::pipeline::GivenSettings::spectral`]).
    pub spectral: bool,
    /// Path guiding as the file asks (TOML `[render] guiding`); the user's `--guiding` /
    /// `--no-guiding` wins ([`crate::pipeline::GivenSettings::guiding`]).
    pub guiding: Option<bool>,
}

impl MediumDesc {
    /// A homogeneous medium.
    pub fn homogeneous(name: &str, sigma_a: Vec3, sigma_s: Vec3, scale: f32, g: f32) -> Self {
        MediumDesc {
            name: name.to_string(),
            sigma_a,
            sigma_s,
            scale,
            g,
            le: Vec3::ZERO,
            kind: MediumKind::Homogeneous,
            sigma_spectra: [None, None],
            le_spectrum: None,
        }
    }

    /// Rejects coefficients that would make NaNs or negative probabilities.
    pub fn validate(&self) -> Result<(), String> {
        let nonneg = |v: Vec3| v.is_finite() && v.cmpge(Vec3::ZERO).all();
        if !nonneg(self.sigma_a) || !nonneg(self.sigma_s) {
            return Err("sigma_a and sigma_s must be finite and non-negative".into());
        }
        if !nonneg(self.le) {
            return Err(format!(
                "emission {:?} must be finite and non-negative",
                self.le.to_array()
            ));
        }
        if !(self.scale.is_finite() && self.scale >= 0.0) {
            return Err(format!(
                "scale {} must be finite and non-negative",
                self.scale
            ));
        }
        if !(self.g.is_finite() && self.g > -1.0 && self.g < 1.0) {
            return Err(format!("g {} must be in (-1, 1)", self.g));
        }
        if !nonneg(self.sigma_a * self.scale) || !nonneg(self.sigma_s * self.scale) {
            return Err("sigma times scale overflows".into());
        }
        if let MediumKind::Grid {
            nx,
            ny,
            nz,
            density,
            min,
            max,
            transform,
            emission,
            ..
        } = &self.kind
        {
            match emission {
                None => {}
                Some(GridEmission::Radiance { le, scale }) => {
                    scale.validate("emission scale")?;
                    if !nonneg(*le) {
                        return Err(format!(
                            "emission {:?} must be finite and non-negative",
                            le.to_array()
                        ));
                    }
                }
                Some(GridEmission::Blackbody {
                    temperature,
                    scale,
                    temperature_scale,
                    offset,
                }) => {
                    scale.validate("emission scale")?;
                    temperature.validate("temperature")?;
                    if !(temperature_scale.is_finite() && offset.is_finite()) {
                        return Err("temperature scale and offset must be finite".into());
                    }
                }
            }
            let n = nx.checked_mul(*ny).and_then(|v| v.checked_mul(*nz));
            if n != Some(density.len()) || density.is_empty() {
                return Err(format!(
                    "the grid is {nx} x {ny} x {nz} but has {} densities",
                    density.len()
                ));
            }
            if let Some((i, v)) = density
                .iter()
                .enumerate()
                .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
            {
                return Err(format!(
                    "density {i} is {v}; densities must be finite and >= 0"
                ));
            }
            if !(min.is_finite() && max.is_finite() && min.cmplt(*max).all()) {
                return Err("the grid bounds must be finite with min < max".into());
            }
            if !crate::math::mat4_is_finite(transform) || !transform.determinant().is_normal() {
                return Err("the grid transform must be finite and invertible".into());
            }
        }
        Ok(())
    }
}

/// Errors of scene loading and validation. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
    /// The cause is in the message and not also a `source()`, so `{:#}` chains say it once.
    #[error("{path}: {}", io_message(error))]
    Io { path: String, error: std::io::Error },
    #[error("unknown built-in scene '{0}' (available: {list})", list = builtin::NAMES.join(", "))]
    UnknownBuiltin(String),
}

/// An I/O error in words a user can act on.
fn io_message(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "no such file".into(),
        std::io::ErrorKind::PermissionDenied => {
            "permission denied (check the file's permissions)".into()
        }
        std::io::ErrorKind::IsADirectory => "is a folder, not a scene file".into(),
        _ => e.to_string(),
    }
}

impl SceneError {
    pub fn invalid(path: impl std::fmt::Display, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: path.to_string(),
            message: message.into(),
        }
    }
}

impl Scene {
    /// Keeps `table` for spectral rendering and returns its id in
    /// [`crate::spectrum::BsdfSpectra`] (the same id for an equal table); `None` when the id
    /// space is full.
    pub fn add_bsdf_spectrum(&mut self, table: crate::spectrum::SpectrumTable) -> Option<u16> {
        let i = match self.bsdf_spectra.iter().position(|t| *t == table) {
            Some(i) => i,
            None => {
                self.bsdf_spectra.push(table);
                self.bsdf_spectra.len() - 1
            }
        };
        u16::try_from(i)
            .ok()?
            .checked_add(crate::spectrum::TABLE_BASE)
    }

    pub fn add_material(&mut self, m: Material) -> MaterialId {
        self.materials.push(m);
        self.materials.len() - 1
    }

    pub fn add_mesh(&mut self, m: Mesh) -> MeshId {
        self.meshes.push(m);
        self.meshes.len() - 1
    }

    pub fn add_object(&mut self, name: &str, shape: Shape, transform: Mat4, material: MaterialId) {
        self.objects.push(Object {
            name: name.to_string(),
            shape,
            transform,
            material,
            medium: None,
        });
    }

    pub fn add_medium(&mut self, m: MediumDesc) -> MediumId {
        self.media.push(m);
        self.media.len() - 1
    }

    /// True if the scene has any participating medium (then the volumetric path tracer runs).
    pub fn has_media(&self) -> bool {
        !self.media.is_empty()
    }

    /// The camera `--camera` names (an index or a name), else the first; `None` when the scene
    /// has none or the selection matches nothing (the world then reports it).
    pub fn camera_by(&self, selection: Option<&str>) -> Option<&CameraDesc> {
        match selection {
            Some(sel) => match sel.parse::<usize>() {
                Ok(i) => self.cameras.get(i),
                Err(_) => self.cameras.iter().find(|c| c.name == sel),
            },
            None => self.cameras.first(),
        }
    }

    /// Number of triangles after instancing.
    pub fn triangle_count(&self) -> usize {
        self.objects
            .iter()
            .map(|o| match o.shape {
                Shape::Mesh(m) => self.meshes.get(m).map_or(0, |m| m.indices.len()),
                _ => 0,
            })
            .sum()
    }

    fn label(&self) -> String {
        match &self.source {
            Some(p) => p.display().to_string(),
            None => self.name.clone(),
        }
    }

    /// Drops every triangle that uses a vertex with a NaN or infinite coordinate (a file's `nan`,
    /// `inf`, or a literal such as `1e39` beyond the range of 32-bit floats), with a warning
    /// naming the mesh: such a triangle has no bounds, so no accelerator could find it, and its
    /// area and normal are NaN. The vertices themselves become the origin, unreferenced, so the
    /// mesh keeps its vertex count and its attribute arrays their length.
    pub fn drop_unbounded_vertices(&mut self) {
        for mesh in &mut self.meshes {
            let Some(first) = mesh.positions.iter().position(|p| !p.is_finite()) else {
                continue;
            };
            let bad: Vec<bool> = mesh.positions.iter().map(|p| !p.is_finite()).collect();
            let vertices = bad.iter().filter(|&&b| b).count();
            let shown = mesh.positions[first];
            let before = mesh.indices.len();
            mesh.indices.retain(|t| {
                t.iter()
                    .all(|&v| !bad.get(v as usize).copied().unwrap_or(false))
            });
            for (p, &b) in mesh.positions.iter_mut().zip(&bad) {
                if b {
                    *p = Vec3::ZERO;
                }
            }
            self.warnings.push(format!(
                "mesh '{}': {vertices} vertex position(s) are not finite numbers (vertex {first} \
                 is ({}, {}, {})); the {} triangle(s) using them were dropped",
                mesh.name,
                shown.x,
                shown.y,
                shown.z,
                before - mesh.indices.len()
            ));
        }
    }

    /// Checks internal consistency (indices in range, finite numbers, material variants) so the
    /// renderer can trust the data. It runs once per loaded scene, in [`load`] / [`load_file`] /
    /// [`load_bytes`] (and on each TOML `include`d file before it is merged); `World::build` trusts
    /// its input, so a scene built in code calls this first. It turns hostile input into a clear
    /// error instead of a panic later.
    pub fn validate(&self) -> Result<(), SceneError> {
        let label = self.label();
        let err = |m: String| Err(SceneError::invalid(&label, m));
        for (i, mesh) in self.meshes.iter().enumerate() {
            let n = mesh.positions.len();
            if n > crate::geometry::PrimRef::MAX_INDEX as usize {
                return err(format!(
                    "mesh {i} '{}' has too many vertices ({n})",
                    mesh.name
                ));
            }
            if let Some(p) = mesh.positions.iter().position(|p| !p.is_finite()) {
                return err(format!(
                    "mesh {i} '{}': vertex {p} has a non-finite position",
                    mesh.name
                ));
            }
            for (t, tri) in mesh.indices.iter().enumerate() {
                if tri.iter().any(|&v| v as usize >= n) {
                    return err(format!(
                        "mesh {i} '{}': triangle {t} references vertex {:?} but the mesh has {n} vertices",
                        mesh.name, tri
                    ));
                }
            }
            let attr_len_ok = |len: Option<usize>| len.is_none_or(|l| l == n);
            if !attr_len_ok(mesh.normals.as_ref().map(|v| v.len()))
                || !attr_len_ok(mesh.tangents.as_ref().map(|v| v.len()))
                || !attr_len_ok(mesh.uv0.as_ref().map(|v| v.len()))
                || !attr_len_ok(mesh.uv1.as_ref().map(|v| v.len()))
                || !attr_len_ok(mesh.colors.as_ref().map(|v| v.len()))
            {
                return err(format!(
                    "mesh {i} '{}': a vertex attribute has a different length than the positions",
                    mesh.name
                ));
            }
        }
        if self.triangle_count() > crate::geometry::PrimRef::MAX_INDEX as usize {
            return err(format!("too many triangles ({})", self.triangle_count()));
        }
        for (i, o) in self.objects.iter().enumerate() {
            if !crate::math::mat4_is_finite(&o.transform) {
                return err(format!(
                    "object {i} '{}' has a non-finite transform",
                    o.name
                ));
            }
            if o.material >= self.materials.len() {
                return err(format!(
                    "object {i} '{}' references material {} of {}",
                    o.name,
                    o.material,
                    self.materials.len()
                ));
            }
            let shape_ok = match &o.shape {
                Shape::Mesh(m) => *m < self.meshes.len(),
                Shape::Sphere { center, radius } => {
                    center.is_finite() && radius.is_finite() && *radius > 0.0
                }
                Shape::Cuboid { min, max } => {
                    min.is_finite() && max.is_finite() && min.cmple(*max).all()
                }
                Shape::Quad { corner, e1, e2 } => {
                    corner.is_finite() && e1.is_finite() && e2.is_finite()
                }
                Shape::Curves(c) => {
                    c.segments.len() == c.widths.len()
                        && c.normals
                            .as_ref()
                            .is_none_or(|n| n.len() == c.segments.len())
                        && c.split_depth <= 10
                        && c.segments.iter().flatten().all(|p| p.is_finite())
                        && c.widths
                            .iter()
                            .flatten()
                            .all(|w| w.is_finite() && *w >= 0.0)
                        && c.normals.iter().flatten().flatten().all(|n| n.is_finite())
                }
            };
            if !shape_ok {
                return err(format!(
                    "object {i} '{}' has an invalid shape (missing mesh, non-finite data, a non-positive \
                     sphere radius or a box with min > max)",
                    o.name
                ));
            }
        }
        for (i, t) in self.textures.iter().enumerate() {
            // A procedural texture's arena: ordered (no cycles), bounded, naming images.
            if let Some(p) = &t.procedural {
                p.validate(&self.textures).map_err(|e| {
                    SceneError::invalid(&label, format!("texture {i} '{}': {e}", t.name))
                })?;
            }
        }
        for (i, m) in self.materials.iter().enumerate() {
            m.validate(self.textures.len()).map_err(|e| {
                SceneError::invalid(&label, format!("material {i} '{}': {e}", m.name))
            })?;
            // A pbrt-v4 `mix` names two other materials of this scene.
            if let Some(mix) = m.mix()
                && mix
                    .materials
                    .iter()
                    .any(|&j| j as usize >= self.materials.len())
            {
                return err(format!(
                    "material {i} '{}' mixes a missing material ({:?})",
                    m.name, mix.materials
                ));
            }
        }
        for (i, m) in self.media.iter().enumerate() {
            m.validate().map_err(|e| {
                SceneError::invalid(&label, format!("medium {i} '{}': {e}", m.name))
            })?;
        }
        let medium_ok = |m: Option<MediumId>| m.is_none_or(|m| m < self.media.len());
        if !medium_ok(self.camera_medium) {
            return err("the camera medium references a missing medium".into());
        }
        for (i, o) in self.objects.iter().enumerate() {
            if let Some(mi) = o.medium
                && !(medium_ok(mi.inside) && medium_ok(mi.outside))
            {
                return err(format!(
                    "object {i} '{}' references a missing medium",
                    o.name
                ));
            }
        }
        // `select_variant` moves objects to these materials and media after loading, so they are
        // checked here with the rest: the world trusts a loaded scene (docs/DESIGN.md §3).
        for ov in &self.variant_objects {
            let name = self.objects.get(ov.object).map(|o| o.name.as_str());
            let Some(name) = name else {
                return err(format!(
                    "a material variant maps object {} of {}",
                    ov.object,
                    self.objects.len()
                ));
            };
            let choices = std::iter::once((ov.default.0, ov.default.1))
                .chain(ov.by_variant.iter().map(|&(_, m, med)| (m, med)));
            for (m, med) in choices {
                if m >= self.materials.len()
                    || med.is_some_and(|mi| !(medium_ok(mi.inside) && medium_ok(mi.outside)))
                {
                    return err(format!(
                        "a material variant of object {} '{name}' references material {m} of {} or a missing medium",
                        ov.object,
                        self.materials.len()
                    ));
                }
            }
        }
        for (i, c) in self.cameras.iter().enumerate() {
            let ok = crate::math::mat4_is_finite(&c.camera_to_world)
                && c.vfov_deg > 0.0
                && c.vfov_deg < 180.0
                && c.aperture_radius >= 0.0
                && c.aperture_radius.is_finite()
                && c.focus_distance > 0.0
                && c.focus_distance.is_finite()
                && match c.projection {
                    Projection::Orthographic { half_height } => {
                        half_height > 0.0 && half_height.is_finite()
                    }
                    _ => true,
                };
            if !ok {
                return err(format!(
                    "camera {i} '{}' is invalid (field of view must be in (0, 180) degrees, focus distance positive)",
                    c.name
                ));
            }
        }
        for l in &self.lights {
            let finite = match l {
                LightDesc::Point {
                    position,
                    intensity,
                    ..
                } => position.is_finite() && intensity.is_finite(),
                LightDesc::Spot {
                    position,
                    direction,
                    intensity,
                    inner_angle,
                    outer_angle,
                    ..
                } => {
                    position.is_finite()
                        && direction.is_finite()
                        && direction.length_squared() > 0.0
                        && intensity.is_finite()
                        && inner_angle.is_finite()
                        && outer_angle.is_finite()
                }
                LightDesc::Directional {
                    direction,
                    irradiance,
                    ..
                } => {
                    direction.is_finite()
                        && direction.length_squared() > 0.0
                        && irradiance.is_finite()
                }
                LightDesc::Ambient { radiance, .. } => radiance.is_finite(),
                LightDesc::Environment {
                    scale, transform, ..
                } => scale.is_finite() && crate::math::mat4_is_finite(transform),
            };
            if !finite {
                return err(format!(
                    "light '{}' has non-finite or degenerate parameters",
                    l.name()
                ));
            }
        }
        Ok(())
    }

    /// Switches every object to its material under variant `name` (glTF `KHR_materials_variants`:
    /// objects the variant does not map keep their default material). An unknown name, or a
    /// scene without variants, is an error listing the valid names.
    pub fn select_variant(&mut self, name: &str) -> Result<(), SceneError> {
        let label = self
            .source
            .as_ref()
            .map_or(self.name.clone(), |p| p.display().to_string());
        let Some(index) = self.variants.iter().position(|v| v == name) else {
            return Err(SceneError::invalid(
                &label,
                if self.variants.is_empty() {
                    format!(
                        "variant '{name}' was asked for, but the scene has no material variants (glTF KHR_materials_variants)"
                    )
                } else {
                    format!(
                        "no material variant '{name}'; the scene's variants are: {}",
                        self.variants
                            .iter()
                            .map(|v| format!("'{v}'"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                },
            ));
        };
        for ov in &self.variant_objects {
            let (material, medium) = ov
                .by_variant
                .iter()
                .find(|(v, ..)| *v == index)
                .map(|&(_, m, med)| (m, med))
                .unwrap_or(ov.default);
            if let Some(o) = self.objects.get_mut(ov.object) {
                o.material = material;
                o.medium = medium;
            }
        }
        self.active_variant = Some(name.to_string());
        Ok(())
    }

    /// True if anything emits light: a light, or a material with emission.
    pub fn has_light(&self) -> bool {
        !self.lights.is_empty()
            || self
                .objects
                .iter()
                .any(|o| self.materials[o.material].is_emissive())
    }

    /// World-space bounds of all objects (conservative for analytic shapes).
    pub fn bounds(&self) -> crate::geometry::Bounds3 {
        use crate::geometry::Bounds3;
        let mut b = Bounds3::EMPTY;
        for o in &self.objects {
            let pts: Vec<Vec3> = match &o.shape {
                Shape::Mesh(m) => self.meshes[*m].positions.clone(),
                Shape::Sphere { center, radius } => {
                    let r = Vec3::splat(*radius);
                    (0..8)
                        .map(|i| Bounds3::new(*center - r, *center + r).corner(i))
                        .collect()
                }
                Shape::Cuboid { min, max } => {
                    (0..8).map(|i| Bounds3::new(*min, *max).corner(i)).collect()
                }
                Shape::Quad { corner, e1, e2 } => {
                    vec![*corner, *corner + *e1, *corner + *e2, *corner + *e1 + *e2]
                }
                // The control points bound each segment (their convex hull holds it).
                Shape::Curves(c) => c.segments.iter().flatten().copied().collect(),
            };
            for p in pts {
                b = b.union_point(o.transform.transform_point3(p));
            }
        }
        b
    }
}

/// A loader: turns a file's bytes into a [`Scene`]. `dir` is the file's folder (referenced files
/// are looked up inside it), `label` names the file in messages.
pub type LoadFn = fn(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError>;

/// A scene file format: the extensions it is recognised by and the loader that reads it.
pub struct SceneFormat {
    pub name: &'static str,
    /// Lower-case, without the dot.
    pub extensions: &'static [&'static str],
    pub load: LoadFn,
    /// Whether a TOML scene may include files of this format as meshes.
    pub includable: bool,
    /// A mesh format (no cameras, lights or materials of its own): listed after scene files.
    pub mesh_only: bool,
}

fn load_ply(bytes: &[u8], _dir: &Path, label: &str) -> Result<Scene, SceneError> {
    ply::load_from_bytes(bytes, label)
}

fn load_fbx(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    fbx::load_bytes(bytes, label, Some(dir))
}

/// The one table of scene formats: [`load`], the TOML include and the server's scene list all
/// read it.
pub const FORMATS: &[SceneFormat] = &[
    SceneFormat {
        name: "glTF 2.0",
        extensions: &["gltf", "glb"],
        load: gltf::load_from_bytes,
        includable: true,
        mesh_only: false,
    },
    SceneFormat {
        name: "Wavefront OBJ",
        extensions: &["obj"],
        load: obj::load_from_bytes,
        includable: true,
        mesh_only: false,
    },
    SceneFormat {
        name: "PLY",
        extensions: &["ply"],
        load: load_ply,
        includable: true,
        mesh_only: true,
    },
    SceneFormat {
        name: "FBX (binary)",
        extensions: &["fbx"],
        load: load_fbx,
        includable: true,
        mesh_only: false,
    },
    SceneFormat {
        name: "pbrt-v4",
        extensions: &["pbrt"],
        load: pbrt::load_from_file_bytes,
        includable: false,
        mesh_only: false,
    },
    SceneFormat {
        name: "Mitsuba 3 XML",
        extensions: &["xml"],
        load: mitsuba::load_from_file_bytes,
        includable: false,
        mesh_only: false,
    },
    SceneFormat {
        name: "Trayecto TOML",
        extensions: &["toml"],
        load: toml_scene::load_from_bytes,
        includable: false,
        mesh_only: false,
    },
];

/// The format a path's extension names (case-insensitive), if any.
pub fn format_for(path: &Path) -> Option<&'static SceneFormat> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    FORMATS
        .iter()
        .find(|f| f.extensions.contains(&ext.as_str()))
}

/// Every extension of [`FORMATS`], as `.gltf, .glb, …` for messages.
pub fn extension_list(includable_only: bool) -> String {
    FORMATS
        .iter()
        .filter(|f| f.includable || !includable_only)
        .flat_map(|f| f.extensions.iter().map(|e| format!(".{e}")))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Loads a scene from a file path, or a built-in scene by name (`cornell`). The format follows the
/// file's extension ([`FORMATS`]).
pub fn load(spec: &str) -> Result<Scene, SceneError> {
    let path = Path::new(spec);
    if builtin::NAMES.contains(&spec) && !path.exists() {
        let scene = builtin::load(spec)?;
        scene.validate()?;
        return Ok(scene);
    }
    // A folder is named as one whatever its name ('/tmp' has no extension, 'x.gltf/' may).
    if path.extension().is_none() && !path.is_dir() {
        if path.exists() {
            return Err(SceneError::invalid(
                spec,
                "the file has no extension, so its format is unknown",
            ));
        }
        return Err(SceneError::UnknownBuiltin(spec.to_string()));
    }
    if !path.is_file() {
        let what = if path.is_dir() {
            "is a folder; give a scene file inside it"
        } else {
            "no such file"
        };
        return Err(SceneError::invalid(
            spec,
            format!(
                "{what} (scene files: {}; built-in scenes: {})",
                extension_list(false),
                builtin::NAMES.join(", ")
            ),
        ));
    }
    load_file(path)
}

/// Reads a scene file: the one place that reads the bytes, picks the loader from [`FORMATS`],
/// names the scene (the file's stem unless the file names itself) and its source, and validates
/// it. Loaders only turn bytes into a [`Scene`]; this function owns everything around that.
pub fn load_file(path: &Path) -> Result<Scene, SceneError> {
    // Under the caller's memory budget and cancel flag, or a fresh default budget.
    crate::limits::scope_or_default(|| load_file_in_scope(path))
}

fn load_file_in_scope(path: &Path) -> Result<Scene, SceneError> {
    let label = path.display().to_string();
    let format = format_of(path, &label)?;
    let bytes = crate::limits::read_file(path).map_err(|e| SceneError::Io {
        path: label.clone(),
        error: e,
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut scene = parse(format, &bytes, dir, &label)?;
    scene.source = Some(path.to_path_buf());
    scene.validate()?;
    Ok(scene)
}

/// [`load_file`] for a file already in memory: `label` is its path (its extension picks the
/// loader; it names the scene in messages) and `dir` the folder its references resolve against.
/// The bytes are parsed, named and validated exactly as [`load_file`] does — the entry point of
/// the fuzz targets and the mutation tests, so they exercise what a user's file goes through.
pub fn load_bytes(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    crate::limits::scope_or_default(|| {
        let format = format_of(Path::new(label), label)?;
        let mut scene = parse(format, bytes, dir, label)?;
        scene.source = Some(PathBuf::from(label));
        scene.validate()?;
        Ok(scene)
    })
}

fn format_of(path: &Path, label: &str) -> Result<&'static SceneFormat, SceneError> {
    format_for(path).ok_or_else(|| {
        let ext = path.extension().unwrap_or_default().to_string_lossy();
        SceneError::invalid(label, format!("unsupported scene format '.{ext}'"))
    })
}

/// Runs the loader and names the scene after the file unless the file names itself.
fn parse(format: &SceneFormat, bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    let mut scene = (format.load)(bytes, dir, label)?;
    scene.drop_unbounded_vertices();
    if scene.name.is_empty() || scene.name == label {
        scene.name = Path::new(label)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| format.extensions[0].to_string());
    }
    Ok(scene)
}

thread_local! {
    static SILENCE_PANICS: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs a loader step that calls into a third-party parser which may panic on hostile input
/// (docs/DESIGN.md §7: never panic), turning a panic into a [`SceneError`] naming the file. The panic's
/// own message is kept off the terminal: the error says what happened.
pub(crate) fn contain_panics<T>(
    label: &str,
    message: &str,
    f: impl FnOnce() -> Result<T, SceneError>,
) -> Result<T, SceneError> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !SILENCE_PANICS.with(|s| s.get()) {
                previous(info);
            }
        }));
    });
    SILENCE_PANICS.with(|s| s.set(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    SILENCE_PANICS.with(|s| s.set(false));
    match result {
        Ok(r) => r,
        Err(_) => Err(SceneError::invalid(label, message)),
    }
}
