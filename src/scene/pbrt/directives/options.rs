//! Rendering options, given before `WorldBegin`: the camera, film, sampler, integrator, pixel
//! filter, accelerator, colour space and `Option` (pbrt-v4 file format, "Scene-wide rendering
//! options"). Most become hints (`Scene::hints`) or warnings; the camera and film are read at
//! the end (`Loader::camera_and_film`).

use crate::math::Mat4;
use crate::scene::SceneError;
use crate::scene::pbrt::{Cursor, Loader, invert};

impl Loader {
    pub(super) fn option_directives(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
    ) -> Result<bool, SceneError> {
        match name {
            "Option" => {
                let list = p.params(at)?;
                for prm in &list.params {
                    self.warn(format!(
                        "{at}: Option \"{} {}\" does not change how Trayecto renders and was ignored",
                        prm.ty, prm.name
                    ));
                }
            }
            "ColorSpace" => {
                let n = p.string(at)?;
                if n != "srgb" {
                    self.warn(format!(
                        "{at}: ColorSpace \"{n}\": Trayecto renders in linear sRGB; the file's RGB values are read as sRGB"
                    ));
                }
            }
            "Camera" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                if self.world_begun {
                    return Err(SceneError::invalid(at, "Camera after WorldBegin"));
                }
                if !["perspective", "orthographic", "spherical"].contains(&ty.as_str()) {
                    self.warn(format!(
                        "{at}: Camera \"{ty}\" is not supported; a perspective camera with the same parameters is used"
                    ));
                }
                // A moving camera: its end transform, for motion blur.
                self.camera_end = (self.gs.ctm != self.gs.ctm_end).then_some(self.gs.ctm_end);
                // pbrt names the camera's coordinate system "camera".
                if let Some(inv) = invert(&self.gs.ctm) {
                    self.named_coord.insert("camera".into(), inv);
                }
                self.settings.camera = Some((self.gs.ctm, list, at.to_string(), ty));
                // pbrt-v4: the camera sits in the current outside medium.
                if !self.gs.medium_outside.is_empty() {
                    self.camera_medium = Some((self.gs.medium_outside.clone(), at.to_string()));
                }
            }
            "Film" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                if !matches!(ty.as_str(), "rgb" | "gbuffer" | "spectral") {
                    self.warn(format!("{at}: Film \"{ty}\" is unknown; read as \"rgb\""));
                }
                self.settings.film = Some((list, at.to_string()));
            }
            "Sampler" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let spp = list.int("pixelsamples", 16);
                if spp > 0 {
                    self.scene.hints.spp = Some(spp.min(1 << 20) as u32);
                }
                self.note_unused(&list, &format!("Sampler \"{ty}\""), at);
                self.warn_once(
                    "sampler",
                    format!("{at}: Sampler \"{ty}\": Trayecto uses its own sample generator (--sampler); pixelsamples is used"),
                );
            }
            "Integrator" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let depth_v = list.int("maxdepth", 5);
                if depth_v >= 0 {
                    self.scene.hints.max_depth = Some(depth_v.min(100_000) as u32);
                }
                if ty == "sppm" {
                    // pbrt-v4's defaults: one photon path per pixel, radius 1; its iterations
                    // are the sampler's pixel samples (an older file's `iterations` too).
                    let n = list.int("photonsperiteration", -1);
                    self.scene.hints.photons_per_iteration = (n > 0).then_some(n as u64);
                    self.scene.hints.photon_radius = Some(list.float("radius", 1.0));
                    let it = list.int("iterations", 0);
                    if it > 0 {
                        self.scene.hints.spp = Some(it.min(1 << 20) as u32);
                    }
                    let _ = list.int("seed", 0);
                }
                if ty == "mlt" {
                    // pbrt-v4's defaults where the file gives none (`MltSettings`).
                    let n =
                        |k: &str| (list.int(k, 0) > 0).then(|| list.int(k, 0).min(1 << 30) as u32);
                    let x = |k: &str| list.has(k).then(|| list.float(k, 0.0));
                    self.scene.hints.mlt = Some(crate::sampling::mlt::MltSettings {
                        bootstrap_samples: n("bootstrapsamples"),
                        chains: n("chains"),
                        large_step_probability: x("largestepprobability"),
                        sigma: x("sigma"),
                    });
                    // pbrt-v4 renders 100 mutations per pixel when the file gives none.
                    let m = list.int("mutationsperpixel", 100).clamp(1, 1 << 20);
                    self.scene.hints.mlt_mutations = Some(m as u32);
                    let _ = list.int("seed", 0);
                }
                if matches!(ty.as_str(), "bdpt" | "mlt") && list.bool("regularize", false) {
                    self.warn(format!(
                        "{at}: Integrator \"{ty}\": \"regularize\" is not implemented; rendered \
                         without (unbiased)"
                    ));
                }
                if matches!(ty.as_str(), "lighttracer" | "bdpt" | "sppm" | "mlt") {
                    self.scene.hints.integrator = Some(ty.clone());
                } else if !matches!(ty.as_str(), "path" | "volpath") {
                    self.warn(format!(
                        "{at}: Integrator \"{ty}\": Trayecto renders with its path tracer; maxdepth is used"
                    ));
                }
                // Options of pbrt's path tracers that Trayecto's already does its own way.
                for k in ["regularize", "lightsampler"] {
                    if list.has(k) {
                        let _ = list.bool(k, false);
                        let _ = list.string(k);
                    }
                }
                self.note_unused(&list, &format!("Integrator \"{ty}\""), at);
            }
            "PixelFilter" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                self.pixel_filter(&ty, &list, at)?;
                self.note_unused(&list, &format!("PixelFilter \"{ty}\""), at);
            }
            "Accelerator" => {
                let _ = p.string(at)?;
                let _ = p.params(at)?;
            }
            "WorldBegin" => {
                self.world_begun = true;
                self.gs.ctm = Mat4::IDENTITY;
                self.gs.ctm_end = Mat4::IDENTITY;
                self.named_coord.insert("world".into(), Mat4::IDENTITY);
            }
            "WorldEnd" => {
                // pbrt-v3; pbrt-v4 ends the world at the end of the file.
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}
