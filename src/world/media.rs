//! What integrators ask of the world about participating media (pbrt-v4's `Medium` and
//! `MediumInterface` queries, Mitsuba's `Scene::ray_test` with transmittance): the medium the
//! camera sits in, a medium by index, which medium a ray is in after crossing a surface, and the
//! transmittance along a shadow ray. Integrators do not read `World::media` themselves.

use super::World;
use crate::geometry::Ray;
use crate::math::Vec3;
use crate::medium::{Medium, TrackStep};
use crate::sampling::rng::Pcg32;

/// Most interface surfaces a shadow ray crosses before it counts as blocked (as the
/// volumetric path tracer bounds its own crossings).
const MAX_CROSSINGS: u32 = 256;

/// The mean of the three channels (the hero-wavelength MIS weights' normaliser, pbrt-v4 §14.2.2).
#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

impl World {
    /// True if the scene has media or medium interfaces: then only the volumetric path tracer
    /// renders it correctly.
    #[inline]
    pub fn has_media(&self) -> bool {
        self.media.active
    }

    /// The medium the camera sits in (`None`: vacuum).
    #[inline]
    pub fn camera_medium(&self) -> Option<usize> {
        self.media.camera_medium
    }

    /// Medium `index` (an index a ray's medium or [`World::camera_medium`] gave).
    #[inline]
    pub fn medium(&self, index: usize) -> &Medium {
        &self.media.media[index]
    }

    /// True if surfaces of `material` only separate media (no surface scattering: a ray
    /// carries on through them).
    #[inline]
    pub fn is_interface(&self, material: u32) -> bool {
        self.media.is_passthrough(material)
    }

    /// The medium a ray leaving a surface of `material` in direction `d` travels in, given the
    /// surface's outward geometric normal `ng` and the medium `current` the ray was in.
    #[inline]
    pub fn medium_after(
        &self,
        material: u32,
        d: Vec3,
        ng: Vec3,
        current: Option<usize>,
    ) -> Option<usize> {
        self.media.after_crossing(material, d, ng, current)
    }

    /// Transmittance along a shadow ray through interface surfaces and media, as (T, r_l, r_u
    /// factors) of ratio tracking; `None` if an opaque surface blocks it. `shadow` goes from the
    /// scattering point towards the light and stops just short of it (`t_max` in units of `d`).
    /// `channel` is the hero channel tracking samples with, `shadow_rays` counts the rays traced.
    pub fn transmittance(
        &self,
        shadow: &Ray,
        medium: Option<usize>,
        channel: usize,
        rng: &mut Pcg32,
        shadow_rays: &mut u64,
    ) -> Option<(Vec3, Vec3, Vec3)> {
        self.transmittance_at(shadow, medium, channel, None, rng, shadow_rays)
    }

    /// [`World::transmittance`] at the wavelengths `lambda` of a spectral path (the media's
    /// coefficients upsampled there, [`Medium::coefficients`]); RGB for `None`.
    pub fn transmittance_at(
        &self,
        shadow: &Ray,
        mut medium: Option<usize>,
        channel: usize,
        lambda: Option<Vec3>,
        rng: &mut Pcg32,
        shadow_rays: &mut u64,
    ) -> Option<(Vec3, Vec3, Vec3)> {
        let len = shadow.d.length();
        if !(len > 0.0) {
            return None;
        }
        let d = shadow.d / len;
        let end = if shadow.t_max.is_finite() {
            Some(shadow.o + shadow.d * shadow.t_max)
        } else {
            None
        };
        let mut ray = Ray {
            o: shadow.o,
            d,
            t_max: shadow.t_max * len,
            time: shadow.time,
        };
        let (mut t_ray, mut r_l, mut r_u) = (Vec3::ONE, Vec3::ONE, Vec3::ONE);
        for _ in 0..MAX_CROSSINGS {
            *shadow_rays += 1;
            let hit = self.intersect(&ray);
            if let Some(h) = &hit
                && !self.is_interface(h.material)
            {
                return None;
            }
            let seg = hit.as_ref().map_or(ray.t_max, |h| h.t);
            if let Some(mi) = medium {
                let m: &Medium = self.medium(mi);
                let c = m.coefficients(lambda);
                if m.is_analytic() {
                    t_ray *= m.analytic_transmittance_in(&c, seg);
                } else {
                    let mut tracker = m.tracker_in(&c, &ray, seg, channel);
                    loop {
                        match tracker.step(m, rng) {
                            TrackStep::End { t_maj } => {
                                let th = t_maj[channel];
                                if !(th > 0.0) {
                                    return None;
                                }
                                t_ray *= t_maj / th;
                                r_l *= t_maj / th;
                                r_u *= t_maj / th;
                                break;
                            }
                            TrackStep::Collision {
                                props,
                                sigma_maj,
                                t_maj,
                                ..
                            } => {
                                let sigma_n =
                                    (sigma_maj - props.sigma_a - props.sigma_s).max(Vec3::ZERO);
                                let pdf = t_maj[channel] * sigma_maj[channel];
                                t_ray *= t_maj * sigma_n / pdf;
                                r_l *= t_maj * sigma_maj / pdf;
                                r_u *= t_maj * sigma_n / pdf;
                                if !(t_ray.max_element() > 0.0) {
                                    return None;
                                }
                                // Russian roulette on a faint estimate (unbiased: divided by the
                                // survival probability), as ratio tracking's long tails are costly.
                                let tr = t_ray / mean(r_l + r_u);
                                if tr.max_element() < 0.05 {
                                    if rng.next_f32() < 0.75 {
                                        return None;
                                    }
                                    t_ray /= 0.25;
                                }
                            }
                        }
                    }
                }
            }
            let Some(h) = hit else {
                return Some((t_ray, r_l, r_u));
            };
            medium = self.medium_after(h.material, d, h.ng, medium);
            let next = Ray::spawn(h.p, h.p_error, h.ng, d).with_time(h.time);
            let t_max = match end {
                Some(e) => (e - next.o).dot(d),
                None => f32::INFINITY,
            };
            if !(t_max > 0.0) {
                return Some((t_ray, r_l, r_u));
            }
            ray = Ray { t_max, ..next };
        }
        None
    }
}
