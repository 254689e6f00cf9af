//! The camera: perspective (pinhole or thin lens, PBRT §5.2.3), orthographic (§5.2.2) or
//! spherical (pbrt-v4 `SphericalCamera`, §5.3), generating primary rays through the film.
//! Film coordinates are in pixels, (0, 0) at the top-left corner, x to the right, y down.
//! Camera space looks down −z with +y up and +x to the image's right.

use crate::geometry::Ray;
use crate::math::{Mat4, Vec2, Vec3};
use crate::sampling::equal_area;
use crate::sampling::warp::concentric_disk;
use crate::scene::{CameraDesc, Projection, SphericalMapping};

/// A camera given by where it stands and what it looks at: the web viewport's `camera` request
/// field, `--camera-from` on the command line and the TOML `[[camera]]` table all use it.
/// [`CameraSpec::validate`] refuses what cannot frame a view (NaN, the eye on the target, an up
/// vector along the view, a field of view outside (0°, 179°]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSpec {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov: f32,
}

/// Coordinates beyond this are refused: `look_at` squares distances, which overflows f32 near 1e19.
pub const MAX_CAMERA_COORD: f32 = 1e9;

impl CameraSpec {
    /// The field of view TOML cameras default to (Blender's 50 mm lens on a 36 mm sensor).
    pub const DEFAULT_FOV: f32 = 39.6;

    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [("eye", self.eye), ("target", self.target), ("up", self.up)] {
            if !v.is_finite() || v.abs().max_element() > MAX_CAMERA_COORD {
                return Err(format!(
                    "camera {name} must be three finite numbers of at most {MAX_CAMERA_COORD:e} (got {v})"
                ));
            }
        }
        let view = self.target - self.eye;
        let scale = self
            .eye
            .abs()
            .max_element()
            .max(self.target.abs().max_element())
            .max(1.0);
        if view.length() <= 1e-6 * scale {
            return Err(
                "camera eye and target are the same point: there is no view direction".into(),
            );
        }
        let up = self.up.normalize_or_zero();
        if up == Vec3::ZERO || view.normalize().cross(up).length() < 1e-4 {
            return Err(format!(
                "camera up {} is zero or along the view direction: it cannot say which way is up",
                self.up
            ));
        }
        if !(self.fov.is_finite() && self.fov > 0.0 && self.fov <= 179.0) {
            return Err(format!(
                "camera fov must be a vertical field of view above 0 and at most 179 degrees (got {})",
                self.fov
            ));
        }
        Ok(())
    }

    /// The scene camera this describes (a pinhole focused on the target). Validate first.
    pub fn to_desc(&self, name: &str) -> CameraDesc {
        CameraDesc::look_at(name, self.eye, self.target, self.up, self.fov)
    }

    /// The eye, target (at the focus distance along the view), up and vertical field of view of
    /// a scene camera; the image's shape and the lens are not part of it.
    pub fn from_desc(desc: &CameraDesc) -> CameraSpec {
        let m = desc.camera_to_world;
        let eye = m.transform_point3(Vec3::ZERO);
        let forward = m.transform_vector3(-Vec3::Z).normalize_or_zero();
        let up = m.transform_vector3(Vec3::Y).normalize_or_zero();
        let dist = if desc.focus_distance.is_finite() && desc.focus_distance > 0.0 {
            desc.focus_distance
        } else {
            1.0
        };
        CameraSpec {
            eye,
            target: eye + forward * dist,
            up,
            fov: desc.vfov_deg,
        }
    }

    /// A TOML `[[camera]]` table for this view, as a scene file and `--camera-from` read it.
    pub fn to_toml(&self) -> String {
        let v = |v: Vec3| format!("[{}, {}, {}]", v.x, v.y, v.z);
        format!(
            "[[camera]]\neye = {}\ntarget = {}\nup = {}\nfov = {}\n",
            v(self.eye),
            v(self.target),
            v(self.up),
            self.fov
        )
    }

    /// The first camera of a TOML text: a `[camera]` table or the first of `[[camera]]` tables,
    /// with `eye` and `target` (and optionally `up`, default +y, and `fov`, default 39.6°).
    /// Other keys of the file are not read (a whole TOML scene gives its first camera).
    pub fn from_toml(text: &str) -> Result<CameraSpec, String> {
        let doc: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| e.message().to_string())?;
        let table = match doc.get("camera") {
            Some(toml::Value::Table(t)) => t,
            Some(toml::Value::Array(a)) => match a.first() {
                Some(toml::Value::Table(t)) => t,
                _ => return Err("`camera` must be a table ([camera] or [[camera]])".into()),
            },
            Some(_) => return Err("`camera` must be a table ([camera] or [[camera]])".into()),
            None => return Err("no [camera] table".into()),
        };
        for k in table.keys() {
            if ![
                "name",
                "eye",
                "target",
                "up",
                "fov",
                "aperture",
                "focus_distance",
            ]
            .contains(&k.as_str())
            {
                return Err(format!("camera: unknown key '{k}'"));
            }
        }
        let vec3 = |key: &str, default: Option<Vec3>| -> Result<Vec3, String> {
            match table.get(key) {
                None => default.ok_or_else(|| format!("camera: `{key}` is missing")),
                Some(toml::Value::Array(a)) if a.len() == 3 => {
                    let mut v = [0f32; 3];
                    for (o, x) in v.iter_mut().zip(a) {
                        *o = match x {
                            toml::Value::Float(f) => *f as f32,
                            toml::Value::Integer(i) => *i as f32,
                            _ => return Err(format!("camera: `{key}` must be three numbers")),
                        };
                    }
                    Ok(Vec3::from(v))
                }
                Some(_) => Err(format!("camera: `{key}` must be three numbers")),
            }
        };
        let fov = match table.get("fov") {
            None => Self::DEFAULT_FOV,
            Some(toml::Value::Float(f)) => *f as f32,
            Some(toml::Value::Integer(i)) => *i as f32,
            Some(_) => return Err("camera: `fov` must be a number (degrees)".into()),
        };
        let spec = CameraSpec {
            eye: vec3("eye", None)?,
            target: vec3("target", None)?,
            up: vec3("up", Some(Vec3::Y))?,
            fov,
        };
        spec.validate()?;
        Ok(spec)
    }
}

/// How far a surface point moves when the camera ray through it moves by one pixel: pbrt-v4's
/// `CameraBase::Approximate_dp_dxy`, which gives every hit of a path, not only the first, the
/// footprint of a camera ray reaching that point. Rays stay plain data (no differentials are
/// carried). With a pinhole the first hit's footprint is exact (the offset rays are the camera
/// rays of the neighbouring pixels); a thin lens is treated as its pinhole. Unlike pbrt-v4, the
/// footprint is not shrunk by 1/√spp, so the filtered image does not depend on the sample count.
/// `Default` is off: every lookup then is the unfiltered one.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Footprint {
    pub enabled: bool,
    world_to_camera: Mat4,
    camera_to_world: Mat4,
    pixel: f32,
}

impl Footprint {
    /// (∂p/∂x, ∂p/∂y) at `p` with surface normal `n`: where the rays through the pinhole and the
    /// film points one pixel right and one pixel down of `p`'s meet `p`'s tangent plane (pbrt-v4
    /// `SurfaceInteraction::ComputeDifferentials`). `None` when off, for points behind the camera
    /// and at grazing angles whose offset rays miss the plane.
    #[inline]
    pub fn dp_dxy(&self, p: Vec3, n: Vec3) -> Option<(Vec3, Vec3)> {
        if !self.enabled {
            return None;
        }
        let pc = self.world_to_camera.transform_point3(p);
        if !(pc.z < 0.0) {
            return None;
        }
        // Normals transform by the inverse transpose of world-to-camera.
        let nc = self.camera_to_world.transpose().transform_vector3(n);
        let d = pc / -pc.z;
        let plane = nc.dot(pc);
        let on_plane = |dir: Vec3| dir * (plane / nc.dot(dir)) - pc;
        let dx = on_plane(d + Vec3::X * self.pixel);
        let dy = on_plane(d - Vec3::Y * self.pixel);
        if !(dx.is_finite() && dy.is_finite()) {
            return None;
        }
        Some((
            self.camera_to_world.transform_vector3(dx),
            self.camera_to_world.transform_vector3(dy),
        ))
    }
}

#[derive(Clone, Debug)]
pub struct Camera {
    pub camera_to_world: Mat4,
    pub width: u32,
    pub height: u32,
    /// Half the window's height: tan(vfov / 2) for a perspective camera (the window at depth 1),
    /// camera-space units for an orthographic one; unused by a spherical one.
    half_h: f32,
    aspect: f32,
    pub aperture_radius: f32,
    pub focus_distance: f32,
    projection: Projection,
}

impl Camera {
    pub fn new(desc: &CameraDesc, width: u32, height: u32) -> Camera {
        let aspect = width as f32 / height as f32;
        let half_h = match desc.projection {
            Projection::Orthographic { half_height } => half_height * desc.fit_scale(aspect),
            _ => desc.fitted_tan_half_v(aspect),
        };
        Camera {
            camera_to_world: desc.camera_to_world,
            width,
            height,
            half_h,
            aspect,
            aperture_radius: desc.aperture_radius,
            focus_distance: desc.focus_distance,
            projection: desc.projection,
        }
    }

    /// The camera-space point of film point `film` (in pixels) on the window at depth 1
    /// (perspective) or at depth 0 (orthographic).
    #[inline]
    fn window_point(&self, film: Vec2, depth: f32) -> Vec3 {
        let ndc_x = 2.0 * film.x / self.width as f32 - 1.0;
        let ndc_y = 1.0 - 2.0 * film.y / self.height as f32;
        Vec3::new(
            ndc_x * self.half_h * self.aspect,
            ndc_y * self.half_h,
            -depth,
        )
    }

    /// Whether [`Self::generate_ray`] reads its `lens` sample: a thin lens (aperture above 0) on a
    /// perspective or orthographic camera. A pinhole or spherical camera ignores it, so the
    /// renderer skips those two sampler dimensions instead of computing numbers it would drop.
    #[inline]
    pub fn uses_lens(&self) -> bool {
        self.aperture_radius > 0.0 && !matches!(self.projection, Projection::Spherical(_))
    }

    /// The primary ray through `film`; `lens` in [0,1)² picks the point on the aperture.
    #[inline]
    pub fn generate_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        let (o_cam, d_cam) = match self.projection {
            Projection::Perspective => {
                let d = self.window_point(film, 1.0);
                if self.aperture_radius > 0.0 {
                    // Thin lens: all rays through the film point converge at the plane of focus.
                    let p_lens = concentric_disk(lens) * self.aperture_radius;
                    let focus = d * self.focus_distance; // d.z = −1: at depth focus_distance
                    let o = Vec3::new(p_lens.x, p_lens.y, 0.0);
                    (o, focus - o)
                } else {
                    (Vec3::ZERO, d)
                }
            }
            Projection::Orthographic { .. } => {
                let p = self.window_point(film, 0.0);
                if self.aperture_radius > 0.0 {
                    // pbrt-v4 `OrthographicCamera::GenerateRay`: the ray leaves the lens disk
                    // centred on the camera's axis (not on the film point) towards the film
                    // point's image on the plane of focus; done the same here so that the two
                    // renderers agree.
                    let p_lens = concentric_disk(lens) * self.aperture_radius;
                    let focus = p - Vec3::Z * self.focus_distance;
                    let o = Vec3::new(p_lens.x, p_lens.y, 0.0);
                    (o, focus - o)
                } else {
                    (p, -Vec3::Z)
                }
            }
            Projection::Spherical(mapping) => {
                let uv = Vec2::new(film.x / self.width as f32, film.y / self.height as f32);
                (Vec3::ZERO, spherical_direction(mapping, uv))
            }
        };
        let o = self.camera_to_world.transform_point3(o_cam);
        let dir = self.camera_to_world.transform_vector3(d_cam).normalize();
        Ray::new(o, dir)
    }

    /// The footprint of this camera's pixels, for filtered texture lookups. Only the perspective
    /// projection has one: the footprint's offset rays go through a pinhole, which an orthographic
    /// or spherical camera does not have, so their lookups stay unfiltered.
    pub fn footprint(&self) -> Footprint {
        if self.projection != Projection::Perspective {
            return Footprint::default();
        }
        Footprint {
            enabled: true,
            world_to_camera: self.camera_to_world.inverse(),
            camera_to_world: self.camera_to_world,
            // A pixel's side on the film plane at z = −1: 2·tan(vfov/2)/height (and, as the
            // aspect is width/height, 2·tan(vfov/2)·aspect/width).
            pixel: 2.0 * self.half_h / self.height as f32,
        }
    }

    /// The camera's importance function, or why it has none: only the perspective projection,
    /// pinhole or thin lens, has one ([`CameraImportance`]).
    pub fn importance(&self) -> Result<CameraImportance, NoImportance> {
        match self.projection {
            Projection::Perspective => {}
            Projection::Orthographic { .. } => return Err(NoImportance::Orthographic),
            Projection::Spherical(_) => return Err(NoImportance::Spherical),
        }
        Ok(CameraImportance::new(self))
    }

    /// Projects a world point to film coordinates, if it is in front of a perspective or
    /// orthographic camera (for tests; a spherical camera gives `None`).
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        let pc = self.camera_to_world.inverse().transform_point3(p);
        let (x, y) = match self.projection {
            Projection::Perspective if pc.z < 0.0 => (pc.x / -pc.z, pc.y / -pc.z),
            Projection::Orthographic { .. } if pc.z < 0.0 => (pc.x, pc.y),
            _ => return None,
        };
        let x = x / (self.half_h * self.aspect);
        let y = y / self.half_h;
        Some(Vec2::new(
            (x + 1.0) * 0.5 * self.width as f32,
            (1.0 - y) * 0.5 * self.height as f32,
        ))
    }
}

/// Why a camera has no importance function (light tracing and bidirectional methods need one to
/// connect a light path to the film): only the perspective camera, pinhole or thin lens, has one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NoImportance {
    #[error(
        "an orthographic camera has no importance function here: its rays are parallel, so no light path can be joined to its film"
    )]
    Orthographic,
    #[error(
        "a spherical camera has no importance function here: only perspective cameras (pinhole or thin lens) can receive light paths"
    )]
    Spherical,
}

/// The importance a camera ray carries and the film point it comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Importance {
    /// W_e(p, ω) (pbrt-v4 `PerspectiveCamera::We`).
    pub we: f32,
    /// Film coordinates in pixels, as [`Camera::generate_ray`] takes them.
    pub raster: Vec2,
}

/// A point on the lens seen from a scene point (pbrt-v4 `CameraWiSample`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImportanceSample {
    /// The point on the lens (world space); the camera's position for a pinhole.
    pub p_lens: Vec3,
    /// Unit direction from the scene point towards `p_lens`.
    pub wi: Vec3,
    /// Distance from the scene point to `p_lens`.
    pub dist: f32,
    /// W_e of the ray from `p_lens` towards the scene point.
    pub we: f32,
    /// Solid-angle density of `wi` at the scene point: |p − p_lens|² / (|cos θ_lens| · lens area),
    /// with lens area 1 for a pinhole, whose position is a Dirac delta ([`CameraImportance::is_pinhole`]).
    pub pdf: f32,
    /// Film coordinates in pixels of the camera ray through `p_lens` and the scene point.
    pub raster: Vec2,
}

/// The importance function of a perspective camera, pinhole or thin lens (Veach 1997 §4.A (W_e);
/// pbrt-v4 `PerspectiveCamera::We`, `PDF_We`, `SampleWi`, book §5.4): the camera as a sensor that
/// light paths can reach. It inverts [`Camera::generate_ray`] (the same window, fitted as the
/// film's aspect asks, and the same lens), so a light path landing at a film point lands where a
/// camera ray through that point would start. Plain data: ask [`Camera::importance`] once.
///
/// Normalised as pbrt-v4's: W_e(p, ω) cos θ = p_A(p) p_ω(ω), the densities with which
/// `generate_ray` with uniform film and lens samples produces the ray, so that over the lens and
/// the directions through the film ∫∫ W_e cos θ dω dA = 1. In camera space that is
/// W_e = 1 / (A · A_lens · cos⁴θ), A the film's area on the plane at depth 1 and A_lens = π r²
/// (1 for a pinhole). The densities are converted to world measure through the camera-to-world
/// matrix, which need not be rigid: a pbrt screen window is a shear of camera space, a
/// handedness flip a reflection. The film is the whole image, [0, width) × [0, height) pixels,
/// widened by [`CameraImportance::with_film_margin`] where the reconstruction filter reaches past
/// the image; a crop window is the caller's to apply.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraImportance {
    camera_to_world: Mat4,
    world_to_camera: Mat4,
    width: f32,
    height: f32,
    /// Half the window's extents on the plane at depth 1 (camera space).
    half_w: f32,
    half_h: f32,
    lens_radius: f32,
    focus_distance: f32,
    /// A, the window's area at depth 1 (camera space).
    film_area: f32,
    /// The lens's area in world space (1 for a pinhole).
    lens_area: f32,
    /// |det| of the camera-to-world matrix's linear part: solid angles scale by it.
    det: f32,
    /// The lens plane's world normal, towards the scene.
    n_lens: Vec3,
    /// How far (pixels, per axis) past the image's edges film points still count as on the film.
    margin: Vec2,
}

impl CameraImportance {
    fn new(cam: &Camera) -> CameraImportance {
        let half_w = cam.half_h * cam.aspect;
        CameraImportance {
            camera_to_world: Mat4::IDENTITY,
            world_to_camera: Mat4::IDENTITY,
            width: cam.width as f32,
            height: cam.height as f32,
            half_w,
            half_h: cam.half_h,
            lens_radius: cam.aperture_radius.max(0.0),
            focus_distance: cam.focus_distance,
            film_area: 4.0 * half_w * cam.half_h,
            lens_area: 1.0,
            det: 1.0,
            n_lens: -Vec3::Z,
            margin: Vec2::ZERO,
        }
        .at(cam.camera_to_world)
    }

    /// The same camera placed by `camera_to_world`: a moving camera's importance at a light
    /// path's time (pbrt-v4's cameras evaluate `We`, `PDF_We` and `SampleWi` with their
    /// `CameraTransform` interpolated at the ray's or interaction's time). Everything that
    /// depends on the placement (the inverse, the lens's world area and normal, the solid-angle
    /// scale) is recomputed; the film and the lens are unchanged.
    pub fn at(mut self, camera_to_world: Mat4) -> CameraImportance {
        let m = camera_to_world;
        let world_to_camera = m.inverse();
        self.lens_area = if self.lens_radius > 0.0 {
            let stretch = m
                .transform_vector3(Vec3::X)
                .cross(m.transform_vector3(Vec3::Y))
                .length();
            crate::math::PI * self.lens_radius * self.lens_radius * stretch
        } else {
            1.0
        };
        self.camera_to_world = m;
        self.world_to_camera = world_to_camera;
        self.det = crate::math::Mat3::from_mat4(m).determinant().abs();
        // Normals transform by the inverse transpose.
        self.n_lens = world_to_camera
            .transpose()
            .transform_vector3(-Vec3::Z)
            .normalize();
        self
    }

    /// The same importance over the image widened by `margin` pixels on every side (per axis),
    /// W_e's normalisation unchanged (it stays a density over the image's area). A pixel's
    /// camera samples land up to the filter's radius from its centre, so an edge pixel's measure
    /// reaches radius − ½ pixel past the image: light paths must be able to land there too, or the
    /// edge pixels of a light-traced image lose what their camera samples see outside it
    /// (pbrt-v4's `PerspectiveCamera::We` tests the film's `SampleBounds`, the pixel bounds
    /// widened by the same amount).
    pub fn with_film_margin(mut self, margin: Vec2) -> CameraImportance {
        self.margin = margin.max(Vec2::ZERO);
        self
    }

    /// The lens's centre in world space (the pinhole itself for a pinhole camera).
    #[inline]
    pub fn lens_center(&self) -> Vec3 {
        self.camera_to_world.transform_point3(Vec3::ZERO)
    }

    /// True for a pinhole: the ray's origin is a Dirac delta in position, and the pdfs use a lens
    /// area of 1 as pbrt-v4 does (light tracing then splats W_e / pdf = the delta's weight).
    #[inline]
    pub fn is_pinhole(&self) -> bool {
        self.lens_radius <= 0.0
    }

    /// The lens area A_lens in world space (1 for a pinhole).
    #[inline]
    pub fn lens_area(&self) -> f32 {
        self.lens_area
    }

    /// For a world ray leaving the lens: the world solid-angle density of its direction, the
    /// cosine of its direction with the lens normal and the film point it comes from, if it
    /// comes from the film.
    #[inline]
    fn locate(&self, o: Vec3, d: Vec3) -> Option<(f32, f32, Vec2)> {
        let dw = d.normalize_or_zero();
        let cos_w = self.n_lens.dot(dw);
        if !(cos_w > 0.0) {
            return None;
        }
        let oc = self.world_to_camera.transform_point3(o);
        let dc = self.world_to_camera.transform_vector3(dw);
        // |L⁻¹ ω_w| = 1 / |L ω_c| for the linear part L of camera-to-world.
        let len = dc.length();
        let dc = dc / len;
        let cos = -dc.z;
        if !(cos > 0.0) {
            return None;
        }
        // The point the ray reaches on the plane of focus (at depth 1 for a pinhole), as
        // `generate_ray` aims its rays, scaled back to the window at depth 1.
        let depth = if self.is_pinhole() {
            1.0
        } else {
            self.focus_distance
        };
        let p = oc + dc * (depth / cos);
        let (x, y) = (p.x / depth, p.y / depth);
        let raster = Vec2::new(
            (x / self.half_w + 1.0) * 0.5 * self.width,
            (1.0 - y / self.half_h) * 0.5 * self.height,
        );
        let m = self.margin;
        let inside = raster.x >= -m.x
            && raster.x < self.width + m.x
            && raster.y >= -m.y
            && raster.y < self.height + m.y;
        if !inside {
            return None;
        }
        // Camera space: film points are uniform on the window at depth 1 (and, through a thin
        // lens, on the plane of focus), 1 / (A cos³θ) per solid angle. World solid angle:
        // dω_w / dω_c = |det L| / |L ω_c|³.
        let pdf_dir = 1.0 / (self.film_area * cos * cos * cos * len * len * len * self.det);
        Some((pdf_dir, cos_w, raster))
    }

    /// W_e of the ray leaving the lens at `ray.o` in direction `ray.d` and the film point it comes
    /// from; `None` when it does not come from the film (pbrt-v4 `PerspectiveCamera::We`).
    #[inline]
    pub fn we(&self, ray: &Ray) -> Option<Importance> {
        let (pdf_dir, cos, raster) = self.locate(ray.o, ray.d)?;
        Some(Importance {
            we: pdf_dir / (self.lens_area * cos),
            raster,
        })
    }

    /// The densities with which [`Camera::generate_ray`] with uniform film and lens samples
    /// produces `ray`: (per lens area, per solid angle); (0, 0) off the film (pbrt-v4 `PDF_We`).
    #[inline]
    pub fn pdf_we(&self, ray: &Ray) -> (f32, f32) {
        match self.locate(ray.o, ray.d) {
            Some((pdf_dir, _, _)) => (1.0 / self.lens_area, pdf_dir),
            None => (0.0, 0.0),
        }
    }

    /// A point on the lens chosen by `u` ∈ [0,1)² (the same map as [`Camera::generate_ray`]'s
    /// `lens` sample), seen from the scene point `p`, with the importance arriving at `p` from it;
    /// `None` when the ray from the lens through `p` misses the film (pbrt-v4 `SampleWi`).
    #[inline]
    pub fn sample_wi(&self, p: Vec3, u: Vec2) -> Option<ImportanceSample> {
        let lens = concentric_disk(u) * self.lens_radius;
        let p_lens = self
            .camera_to_world
            .transform_point3(Vec3::new(lens.x, lens.y, 0.0));
        let to_lens = p_lens - p;
        let dist = to_lens.length();
        if !(dist > 0.0) {
            return None;
        }
        let wi = to_lens / dist;
        let cos_lens = self.n_lens.dot(-wi);
        if !(cos_lens > 0.0) {
            return None;
        }
        let imp = self.we(&Ray::new(p_lens, -wi))?;
        Some(ImportanceSample {
            p_lens,
            wi,
            dist,
            we: imp.we,
            pdf: dist * dist / (cos_lens * self.lens_area),
            raster: imp.raster,
        })
    }
}

/// The camera-space direction of image point `uv` ∈ [0,1]² of a spherical camera, as pbrt-v4's
/// `SphericalCamera::GenerateRay` maps it: equirectangular θ = π·v, φ = 2π·u, d = (sin θ cos φ,
/// sin θ sin φ, cos θ), or the equal-area square (after folding points the reconstruction filter
/// put outside the square back in, pbrt-v4 `WrapEqualAreaSquare`); both are z-up, so y and z are
/// swapped to make +y up, and pbrt's +z forward is Trayecto's −z.
#[inline]
fn spherical_direction(mapping: SphericalMapping, uv: Vec2) -> Vec3 {
    let d = match mapping {
        SphericalMapping::Equirectangular => {
            let (sin_t, cos_t) = (crate::math::PI * uv.y).sin_cos();
            let (sin_p, cos_p) = (2.0 * crate::math::PI * uv.x).sin_cos();
            Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t)
        }
        SphericalMapping::EqualArea => equal_area::square_to_sphere(wrap_equal_area_square(uv)),
    };
    Vec3::new(d.x, d.z, -d.y)
}

/// Folds a point just outside [0,1]² back into the square so that the equal-area mapping stays
/// continuous across the square's edges: beyond an edge the octahedral map continues mirrored
/// in that edge and flipped along it (pbrt-v4 `WrapEqualAreaSquare`).
#[inline]
fn wrap_equal_area_square(mut uv: Vec2) -> Vec2 {
    if uv.x < 0.0 {
        uv.x = -uv.x;
        uv.y = 1.0 - uv.y;
    } else if uv.x > 1.0 {
        uv.x = 2.0 - uv.x;
        uv.y = 1.0 - uv.y;
    }
    if uv.y < 0.0 {
        uv.x = 1.0 - uv.x;
        uv.y = -uv.y;
    } else if uv.y > 1.0 {
        uv.x = 1.0 - uv.x;
        uv.y = 2.0 - uv.y;
    }
    uv
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_corners_match_fov() {
        let desc = CameraDesc::look_at("c", Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 90.0);
        let cam = Camera::new(&desc, 200, 100);
        let r = cam.generate_ray(Vec2::new(100.0, 50.0), Vec2::ZERO);
        assert!((r.d - (-Vec3::Z)).length() < 1e-6);
        // Top edge centre: 45° up.
        let top = cam.generate_ray(Vec2::new(100.0, 0.0), Vec2::ZERO);
        assert!((top.d.y - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-5);
        // Right edge: aspect 2 → tan = 2.
        let right = cam.generate_ray(Vec2::new(200.0, 50.0), Vec2::ZERO);
        assert!((right.d.x / -right.d.z - 2.0).abs() < 1e-5);
        let p = cam.project(Vec3::new(1.0, 0.5, 0.0)).unwrap();
        let back = cam.generate_ray(p, Vec2::ZERO);
        let expected = (Vec3::new(1.0, 0.5, 0.0) - Vec3::new(0.0, 0.0, 5.0)).normalize();
        assert!((back.d - expected).length() < 1e-5);
    }

    #[test]
    fn thin_lens_rays_converge_on_focus_plane() {
        let mut desc = CameraDesc::look_at("c", Vec3::ZERO, -Vec3::Z, Vec3::Y, 40.0);
        desc.aperture_radius = 0.5;
        desc.focus_distance = 10.0;
        let cam = Camera::new(&desc, 64, 64);
        let film = Vec2::new(20.0, 40.0);
        let a = cam.generate_ray(film, Vec2::new(0.1, 0.9));
        let b = cam.generate_ray(film, Vec2::new(0.8, 0.3));
        let pa = a.at(10.0 / -a.d.z);
        let pb = b.at(10.0 / -b.d.z);
        assert!((pa - pb).length() < 1e-4, "{pa} vs {pb}");
        assert!((a.o - b.o).length() > 0.01);
    }

    #[test]
    fn camera_spec_refuses_what_cannot_frame_a_view_and_round_trips() {
        let ok = CameraSpec {
            eye: Vec3::new(1.0, 2.0, 5.0),
            target: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            fov: 40.0,
        };
        assert_eq!(ok.validate(), Ok(()));
        let bad = [
            CameraSpec {
                eye: Vec3::new(f32::NAN, 0.0, 0.0),
                ..ok
            },
            CameraSpec {
                target: ok.eye,
                ..ok
            },
            CameraSpec {
                up: Vec3::ZERO,
                ..ok
            },
            CameraSpec {
                up: ok.target - ok.eye,
                ..ok
            },
            CameraSpec { fov: 0.0, ..ok },
            CameraSpec { fov: 180.0, ..ok },
            CameraSpec {
                fov: f32::INFINITY,
                ..ok
            },
            CameraSpec {
                eye: Vec3::splat(1e30),
                ..ok
            },
        ];
        for b in bad {
            assert!(b.validate().is_err(), "{b:?} accepted");
        }
        // desc -> spec -> desc keeps the view (eye, direction, up, fov).
        let d = ok.to_desc("v");
        let back = CameraSpec::from_desc(&d);
        assert!((back.eye - ok.eye).length() < 1e-5);
        let dir = |s: &CameraSpec| (s.target - s.eye).normalize();
        assert!((dir(&back) - dir(&ok)).length() < 1e-5);
        assert!(
            back.to_desc("w")
                .camera_to_world
                .abs_diff_eq(d.camera_to_world, 1e-5)
        );
        assert_eq!(back.fov, 40.0);
        // The TOML snippet reads back as the same camera.
        let t = CameraSpec::from_toml(&ok.to_toml()).unwrap();
        assert_eq!(t, ok);
        assert_eq!(
            CameraSpec::from_toml("[camera]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\n")
                .unwrap()
                .fov,
            CameraSpec::DEFAULT_FOV
        );
        for bad in [
            "",
            "[camera]\neye = [0, 0, 3]\n",
            "[camera]\neye = [0, 0, 3]\ntarget = [0, 0, 3]\n",
            "[camera]\neye = [0, 0]\ntarget = [0, 0, 3]\n",
            "[camera]\neye = [0, 0, 1]\ntarget = [0, 0, 3]\nfov = 'wide'\n",
            "[camera]\neye = [0, 0, 1]\ntarget = [0, 0, 3]\nzoom = 2\n",
            "camera = 3",
            "not toml [",
        ] {
            assert!(CameraSpec::from_toml(bad).is_err(), "{bad:?} accepted");
        }
    }

    /// A camera looking from an arbitrary pose (rotated, translated) with the given lens; with
    /// `window`, through an off-centre, stretched pbrt screen window (a shear of camera space,
    /// as the pbrt loader builds it) and a handedness flip (pbrt's `Scale -1 1 1`).
    fn posed_camera(fov: f32, w: u32, h: u32, aperture: f32, focus: f32, window: bool) -> Camera {
        let mut desc = CameraDesc::look_at(
            "c",
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(-0.5, 0.3, -1.0),
            Vec3::new(0.1, 1.0, 0.0),
            fov,
        );
        desc.aperture_radius = aperture;
        desc.focus_distance = focus;
        if window {
            use crate::math::Vec4;
            let shear = Mat4::from_cols(
                Vec4::new(1.3, 0.0, 0.0, 0.0),
                Vec4::Y,
                Vec4::new(-0.2, 0.15, 1.0, 0.0),
                Vec4::W,
            );
            let flip = Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0));
            desc.camera_to_world = desc.camera_to_world * flip * shear;
        }
        Camera::new(&desc, w, h)
    }

    /// ∫ over the lens and the directions through the film of W_e cos θ = 1 (the normalisation of
    /// pbrt-v4's `PerspectiveCamera::We`), and the direction pdf of `pdf_we` integrates to 1: by
    /// midpoint quadrature in world (θ, φ) around the lens normal, dω = sin θ dθ dφ, for lens
    /// points on a stratified grid. Independent of how `we` maps directions to the film.
    #[test]
    fn importance_integrates_to_one_over_the_film() {
        for (fov, w, h, aperture, focus, window) in [
            (39.6, 64, 64, 0.0, 1.0, false),
            (90.0, 200, 100, 0.0, 1.0, false),
            (20.0, 48, 96, 0.0, 1.0, false),
            (50.0, 80, 60, 0.0, 1.0, true),
            (60.0, 96, 48, 0.3, 4.0, false),
            (30.0, 64, 80, 0.05, 0.7, false),
            (45.0, 64, 64, 0.2, 2.0, true),
        ] {
            let cam = posed_camera(fov, w, h, aperture, focus, window);
            let imp = cam.importance().unwrap();
            let c2w = cam.camera_to_world;
            let axis = imp.n_lens;
            let t1 = axis.any_orthonormal_vector();
            let t2 = axis.cross(t1);
            // θ up to beyond the film's corners as seen from the lens's edges.
            let mut theta_max = 0.0f32;
            for corner in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                for u in [(0.0, 0.5), (1.0, 0.5), (0.5, 0.0), (0.5, 1.0), (0.5, 0.5)] {
                    let film = Vec2::new(corner.0 * w as f32, corner.1 * h as f32);
                    let d = cam.generate_ray(film, Vec2::new(u.0, u.1)).d;
                    theta_max = theta_max.max(d.dot(axis).clamp(-1.0, 1.0).acos());
                }
            }
            let theta_max = (theta_max * 1.05).min(std::f32::consts::FRAC_PI_2);
            let lens_n = if aperture > 0.0 { 4 } else { 1 };
            let (nt, np) = (500, 500);
            let (mut total, mut pdf_total) = (0.0f64, 0.0f64);
            for li in 0..lens_n * lens_n {
                let u = Vec2::new(
                    ((li % lens_n) as f32 + 0.5) / lens_n as f32,
                    ((li / lens_n) as f32 + 0.5) / lens_n as f32,
                );
                let o = c2w.transform_point3((concentric_disk(u) * aperture).extend(0.0));
                let (mut s, mut sp) = (0.0f64, 0.0f64);
                for i in 0..nt {
                    let th = (i as f32 + 0.5) / nt as f32 * theta_max;
                    for j in 0..np {
                        let ph = (j as f32 + 0.5) / np as f32 * 2.0 * std::f32::consts::PI;
                        let d = axis * th.cos() + (t1 * ph.cos() + t2 * ph.sin()) * th.sin();
                        let ray = Ray::new(o, d);
                        let dw = th.sin() as f64;
                        if let Some(e) = imp.we(&ray) {
                            s += e.we as f64 * th.cos() as f64 * dw;
                        }
                        sp += imp.pdf_we(&ray).1 as f64 * dw;
                    }
                }
                let cell = (theta_max / nt as f32 * 2.0 * std::f32::consts::PI / np as f32) as f64;
                total += s * cell / (lens_n * lens_n) as f64 * imp.lens_area() as f64;
                pdf_total += sp * cell / (lens_n * lens_n) as f64;
            }
            let case = format!("fov {fov} {w}x{h} r {aperture} window {window}");
            assert!((total - 1.0).abs() < 5e-3, "{case}: {total}");
            assert!((pdf_total - 1.0).abs() < 5e-3, "{case}: {pdf_total}");
        }
    }

    /// A point on a generated ray, seen from the same lens point by `sample_wi`, lands on the film
    /// point the ray was generated for, with the ray's importance and pdf.
    #[test]
    fn sample_wi_inverts_generate_ray() {
        for (aperture, focus, window) in [
            (0.0, 1.0, false),
            (0.25, 3.0, false),
            (0.0, 1.0, true),
            (0.25, 3.0, true),
        ] {
            let cam = posed_camera(50.0, 120, 80, aperture, focus, window);
            let imp = cam.importance().unwrap();
            for k in 0..50 {
                let f = |i: u32, m: f32| ((k * 7919 + i * 104_729) % 1000) as f32 / 1000.0 * m;
                let film = Vec2::new(0.5 + f(1, 119.0), 0.5 + f(2, 79.0));
                let lens = Vec2::new(f(3, 1.0), f(4, 1.0));
                let ray = cam.generate_ray(film, lens);
                let p = ray.at(0.5 + f(5, 10.0));
                let s = imp.sample_wi(p, lens).unwrap();
                assert!(
                    (s.raster - film).length() < 2e-3 * 120.0,
                    "{film} -> {}",
                    s.raster
                );
                assert!((s.p_lens - ray.o).length() < 1e-4);
                assert!((s.wi + ray.d).length() < 1e-4);
                let e = imp.we(&ray).unwrap();
                assert!((s.we - e.we).abs() <= 1e-3 * e.we);
                assert!((e.raster - film).length() < 2e-3 * 120.0);
                // The solid-angle pdf at p is the lens pdf converted by |p − p_lens|² / cos θ.
                let (pdf_pos, _) = imp.pdf_we(&ray);
                let cos = imp.n_lens.dot(ray.d);
                let expect = pdf_pos * s.dist * s.dist / cos;
                assert!(
                    (s.pdf - expect).abs() <= 1e-3 * expect,
                    "{} vs {expect}",
                    s.pdf
                );
            }
            // Behind the camera or off the film: nothing.
            let back = cam
                .camera_to_world
                .transform_point3(Vec3::new(0.0, 0.0, 5.0));
            assert!(imp.sample_wi(back, Vec2::splat(0.5)).is_none());
            let off = cam
                .camera_to_world
                .transform_point3(Vec3::new(50.0, 0.0, -1.0));
            assert!(imp.sample_wi(off, Vec2::splat(0.5)).is_none());
        }
        // A point on the plane of focus lands on one film point whatever the lens sample.
        let cam = posed_camera(50.0, 120, 80, 0.25, 3.0, false);
        let imp = cam.importance().unwrap();
        let ray = cam.generate_ray(Vec2::new(30.0, 20.0), Vec2::splat(0.5));
        let p = ray.at(3.0 / imp.n_lens.dot(ray.d));
        for u in [Vec2::new(0.1, 0.2), Vec2::new(0.9, 0.6)] {
            let s = imp.sample_wi(p, u).unwrap();
            assert!(
                (s.raster - Vec2::new(30.0, 20.0)).length() < 0.05,
                "{}",
                s.raster
            );
        }
    }

    #[test]
    fn only_perspective_cameras_have_importance() {
        let mut desc = CameraDesc::look_at("c", Vec3::Z, Vec3::ZERO, Vec3::Y, 40.0);
        desc.projection = Projection::Orthographic { half_height: 1.0 };
        let e = Camera::new(&desc, 8, 8).importance().unwrap_err();
        assert_eq!(e, NoImportance::Orthographic);
        assert!(e.to_string().contains("orthographic"));
        desc.projection = Projection::Spherical(SphericalMapping::Equirectangular);
        assert_eq!(
            Camera::new(&desc, 8, 8).importance().unwrap_err(),
            NoImportance::Spherical
        );
    }
}
