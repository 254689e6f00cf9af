//! Participating media (issue #18; thesis §2.10, the radiative transfer equation): what a ray meets
//! between surfaces. A medium is described in the scene by [`crate::scene::MediumDesc`] and compiled
//! here into [`Medium`]: absorption and scattering coefficients σa, σs (RGB, per unit world length),
//! a Henyey–Greenstein phase function ([`phase`]) and, for heterogeneous media, a density grid
//! ([`grid`]) that scales σa and σs point by point.
//!
//! Distances are sampled by delta tracking against a majorant σ_maj ≥ σt (Woodcock et al. 1965;
//! the null-scattering formulation of Miller, Georgiev and Jarosz 2019 as pbrt-v4 §14.1 uses it):
//! a homogeneous medium's majorant is σt itself, a grid's is σt times the bound of its
//! [`grid::MajorantGrid`] cell: 16³ cells over the grid's box, walked by a DDA, each holding the
//! largest density the trilinear lookup can return inside it (pbrt-v4 §11.4.3), so empty and
//! thin regions cost few or no null collisions (none happen outside the box).
//! [`Medium::sample_t_maj`] walks those majorant segments and hands every tentative collision to
//! the caller, who decides between absorption, real and null scattering.

pub mod grid;
pub mod phase;
pub mod world;

pub use grid::{DensityGrid, GridError, read_vol};
pub use phase::HenyeyGreenstein;

use crate::geometry::Ray;
use crate::math::Vec3;
use crate::sampling::rng::Pcg32;

/// Local coefficients at a point of a medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MediumProperties {
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
}

/// A compiled medium: RGB coefficients per unit world length (already multiplied by the
/// description's `scale`), the phase function and an optional density grid.
#[derive(Clone, Debug)]
pub struct Medium {
    pub name: String,
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    pub phase: HenyeyGreenstein,
    pub grid: Option<DensityGrid>,
    /// Emitted radiance: the medium adds σa(p)·Le per unit length (the RTE's emission term,
    /// pbrt-v4 §11.1.4); zero for most media.
    pub le: Vec3,
}

/// One stretch of a ray with a constant majorant, ending at `t1` in the ray's (unit-speed)
/// parameter (it starts where the tracker is).
#[derive(Clone, Copy, Debug)]
struct MajorantSegment {
    t1: f32,
    sigma_maj: Vec3,
}

impl Medium {
    pub fn homogeneous(name: &str, sigma_a: Vec3, sigma_s: Vec3, g: f32) -> Medium {
        Medium {
            name: name.to_string(),
            sigma_a,
            sigma_s,
            phase: HenyeyGreenstein::new(g),
            grid: None,
            le: Vec3::ZERO,
        }
    }

    /// Compiles a scene description (validated by `Scene::validate`).
    pub fn from_desc(desc: &crate::scene::MediumDesc) -> Result<Medium, GridError> {
        let mut m = Medium::homogeneous(
            &desc.name,
            desc.sigma_a * desc.scale,
            desc.sigma_s * desc.scale,
            desc.g,
        );
        m.le = desc.le;
        if let crate::scene::MediumKind::Grid {
            nx,
            ny,
            nz,
            density,
            min,
            max,
            transform,
        } = &desc.kind
        {
            m.grid = Some(DensityGrid::new(
                *nx,
                *ny,
                *nz,
                density.clone(),
                *transform * grid::box_to_world(*min, *max),
            )?);
        }
        Ok(m)
    }

    pub fn sigma_t(&self) -> Vec3 {
        self.sigma_a + self.sigma_s
    }

    /// True if the medium only absorbs: then transmittance is applied analytically on every path
    /// (Beer–Lambert along the real path length), never sampled, so absorbing glass costs no noise.
    pub fn is_absorbing_only(&self) -> bool {
        self.sigma_s == Vec3::ZERO
    }

    /// Coefficients at world point `p`.
    #[inline]
    pub fn properties(&self, p: Vec3) -> MediumProperties {
        match &self.grid {
            None => MediumProperties {
                sigma_a: self.sigma_a,
                sigma_s: self.sigma_s,
            },
            Some(g) => {
                let d = g.density(p);
                MediumProperties {
                    sigma_a: self.sigma_a * d,
                    sigma_s: self.sigma_s * d,
                }
            }
        }
    }

    /// Transmittance along `ray` (unit direction) over `[0, t_max)` for an absorbing-only
    /// homogeneous medium, exp(−σt·d) per channel (Beer–Lambert). For other media the caller
    /// tracks (see [`Medium::sample_t_maj`]).
    #[inline]
    pub fn analytic_transmittance(&self, t_max: f32) -> Vec3 {
        debug_assert!(self.grid.is_none());
        let st = self.sigma_t();
        if t_max.is_infinite() {
            return Vec3::select(st.cmpgt(Vec3::ZERO), Vec3::ZERO, Vec3::ONE);
        }
        (-st * t_max).exp()
    }

    /// Starts delta tracking against the majorant along `ray` (unit direction) over `[0, t_max)`,
    /// with distances sampled in channel `channel` (the hero channel); see [`Tracker`].
    #[inline]
    pub fn tracker(&self, ray: &Ray, t_max: f32, channel: usize) -> Tracker {
        let mut tr = Tracker {
            o: ray.o,
            d: ray.d,
            t: 0.0,
            seg: None,
            dda: None,
            t_maj: Vec3::ONE,
            channel,
        };
        match &self.grid {
            None => {
                tr.seg = Some(MajorantSegment {
                    t1: t_max,
                    sigma_maj: self.sigma_t(),
                });
            }
            Some(g) => {
                let (o, d) = g.to_unit(ray);
                if let Some((t0, t1)) = grid::clip_unit(o, d, t_max) {
                    tr.t = t0;
                    let mut dda = grid::Dda::new(o, d, t0, t1);
                    tr.seg = next_segment(&mut dda, g, self.sigma_t());
                    tr.dda = Some(dda);
                }
            }
        }
        tr
    }

    /// Delta tracking with a callback, in the shape of pbrt-v4's `SampleT_maj` (§14.2.1): for each
    /// tentative collision the callback receives (point, local coefficients, σ_maj, T_maj since
    /// the previous collision) and returns whether to go on. Returns T_maj from the last
    /// collision to `t_max` (all ones if the callback stopped the walk).
    pub fn sample_t_maj(
        &self,
        ray: &Ray,
        t_max: f32,
        channel: usize,
        rng: &mut Pcg32,
        mut callback: impl FnMut(Vec3, MediumProperties, Vec3, Vec3) -> bool,
    ) -> Vec3 {
        let mut tr = self.tracker(ray, t_max, channel);
        loop {
            match tr.step(self, rng) {
                TrackStep::End { t_maj } => return t_maj,
                TrackStep::Collision {
                    p,
                    props,
                    sigma_maj,
                    t_maj,
                } => {
                    if !callback(p, props, sigma_maj, t_maj) {
                        return Vec3::ONE;
                    }
                }
            }
        }
    }
}

/// One step of delta tracking.
#[derive(Clone, Copy, Debug)]
pub enum TrackStep {
    /// A tentative collision at `p`; `t_maj` is exp(−σ_maj·s) over the free flight `s` that led
    /// to it (per channel).
    Collision {
        p: Vec3,
        props: MediumProperties,
        sigma_maj: Vec3,
        t_maj: Vec3,
    },
    /// The walk passed the end of the ray; `t_maj` is exp(−σ_maj·s) over the last stretch.
    End { t_maj: Vec3 },
}

/// Delta-tracking state along one ray: free flights s ~ σ_maj[h]·exp(−σ_maj[h]·s) in the hero
/// channel h, so the flight's pdf is σ_maj[h]·T_maj[h] and reaching the end has probability
/// T_maj[h]. The caller turns each collision into absorption, scattering or a null collision.
///
/// The majorant is piecewise constant along the ray: one segment for a homogeneous medium, one
/// per majorant-grid cell for a grid (walked by [`grid::Dda`]). At a segment's end the flight is
/// sampled afresh against the next segment's majorant (the exponential is memoryless, so this
/// is exact: pbrt-v4's `SampleT_maj`, §14.2.1), and T_maj accumulates over the segments crossed.
#[derive(Clone, Copy, Debug)]
pub struct Tracker {
    o: Vec3,
    d: Vec3,
    t: f32,
    seg: Option<MajorantSegment>,
    dda: Option<grid::Dda>,
    /// exp(−∫σ_maj) since the last collision, over the segments already left.
    t_maj: Vec3,
    channel: usize,
}

/// The next non-empty stretch of a grid's majorant walk.
#[inline]
fn next_segment(dda: &mut grid::Dda, g: &DensityGrid, sigma_t: Vec3) -> Option<MajorantSegment> {
    let (_, t1, bound) = dda.next(&g.majorants)?;
    Some(MajorantSegment {
        t1,
        sigma_maj: sigma_t * bound,
    })
}

impl Tracker {
    #[inline]
    pub fn step(&mut self, medium: &Medium, rng: &mut Pcg32) -> TrackStep {
        loop {
            let Some(seg) = self.seg else {
                let t_maj = self.t_maj;
                self.t_maj = Vec3::ONE;
                return TrackStep::End { t_maj };
            };
            let sm = seg.sigma_maj;
            let sh = sm[self.channel];
            if sh > 0.0 {
                let u = rng.next_f32();
                // Exponential sample; 1 − u is in (0, 1].
                let step = -(1.0 - u).ln() / sh;
                let t_next = self.t + step;
                if t_next < seg.t1 {
                    self.t = t_next;
                    let p = self.o + self.d * t_next;
                    let t_maj = self.t_maj * (-sm * step).exp();
                    self.t_maj = Vec3::ONE;
                    return TrackStep::Collision {
                        p,
                        props: medium.properties(p),
                        sigma_maj: sm,
                        t_maj,
                    };
                }
            }
            // Past the segment's end (or nothing can happen in the hero channel there; the
            // other channels still attenuate by exp(−σ_maj·d)): on to the next segment.
            self.t_maj *= exp_segment(sm, seg.t1 - self.t);
            self.t = seg.t1;
            self.seg = match (&mut self.dda, &medium.grid) {
                (Some(dda), Some(g)) => next_segment(dda, g, medium.sigma_t()),
                _ => None,
            };
        }
    }
}

/// exp(−σ·d) per channel, with an infinite `d` giving 0 where σ > 0 and 1 where σ = 0.
#[inline]
fn exp_segment(sigma: Vec3, d: f32) -> Vec3 {
    if d.is_infinite() {
        Vec3::select(sigma.cmpgt(Vec3::ZERO), Vec3::ZERO, Vec3::ONE)
    } else {
        (-sigma * d).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ratio tracking (Novák et al. 2014) built on `sample_t_maj`: T = Π σn/σ_maj × T_maj(end)/…,
    /// here in the single-channel form, to check the walk against the analytic transmittance.
    fn ratio_tracking(m: &Medium, ray: &Ray, t_max: f32, channel: usize, rng: &mut Pcg32) -> f32 {
        let mut tr = 1.0f32;
        m.sample_t_maj(ray, t_max, channel, rng, |_, mp, sm, _| {
            let sn = sm[channel] - mp.sigma_a[channel] - mp.sigma_s[channel];
            tr *= (sn / sm[channel]).max(0.0);
            tr > 0.0
        });
        tr
    }

    #[test]
    fn homogeneous_slab_transmittance_is_beer_lambert_per_channel() {
        // Chromatic: each channel has its own σt; analytic exp(−σt d).
        let m = Medium::homogeneous(
            "slab",
            Vec3::new(0.2, 0.5, 1.5),
            Vec3::new(0.1, 0.0, 0.5),
            0.3,
        );
        let d = 1.7;
        let want = (-m.sigma_t() * d).exp();
        // Probability of crossing without a collision, estimated by the free-flight sampler of
        // each channel: the fraction of walks that reach the end must be exp(−σt[c]·d).
        let ray = Ray::new(Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.0, 0.6, 0.8));
        let mut rng = Pcg32::new(7, 1);
        let n = 200_000;
        for c in 0..3 {
            let mut passed = 0u32;
            for _ in 0..n {
                let mut hit = false;
                m.sample_t_maj(&ray, d, c, &mut rng, |_, _, _, _| {
                    hit = true;
                    false
                });
                passed += u32::from(!hit);
            }
            let est = passed as f32 / n as f32;
            let sd = (want[c] * (1.0 - want[c]) / n as f32).sqrt();
            assert!(
                (est - want[c]).abs() < 5.0 * sd + 1e-6,
                "channel {c}: crossing fraction {est}, Beer–Lambert {}",
                want[c]
            );
        }
        // The T_maj returned for an event-free walk is the analytic transmittance of the rest.
        let absorbing = Medium::homogeneous("abs", Vec3::new(0.3, 0.9, 2.0), Vec3::ZERO, 0.0);
        let t = absorbing.analytic_transmittance(d);
        assert!(
            (t - (-Vec3::new(0.3, 0.9, 2.0) * d).exp())
                .abs()
                .max_element()
                < 1e-6
        );
    }

    /// With the majorant grid, a ray through the empty part of a grid that is dense elsewhere
    /// meets no tentative collisions at all (a global majorant would give about σt·max·length
    /// of them), and the walk still ends with T_maj = 1 there.
    #[test]
    fn empty_cells_cost_no_collisions() {
        let n = 16;
        let mut data = vec![0.0f32; n * n * n];
        // A dense block in the corner x, y, z < 4/16 of the box.
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    data[(z * n + y) * n + x] = 50.0;
                }
            }
        }
        let mut m = Medium::homogeneous("g", Vec3::splat(0.5), Vec3::splat(1.5), 0.0);
        m.grid = Some(DensityGrid::new(n, n, n, data, crate::math::Mat4::IDENTITY).unwrap());
        let mut rng = Pcg32::new(9, 2);
        // Along x at y = z = 0.7: far from the block.
        let ray = Ray::new(Vec3::new(-1.0, 0.7, 0.7), Vec3::X);
        let mut collisions = 0;
        let t = m.sample_t_maj(&ray, 3.0, 1, &mut rng, |_, _, _, _| {
            collisions += 1;
            true
        });
        assert_eq!(collisions, 0);
        assert_eq!(t, Vec3::ONE);
        // Through the block: collisions do happen (σt·density = 100 per unit length).
        let ray = Ray::new(Vec3::new(-1.0, 0.1, 0.1), Vec3::X);
        let mut collisions = 0;
        m.sample_t_maj(&ray, 3.0, 1, &mut rng, |_, _, _, _| {
            collisions += 1;
            collisions < 1000
        });
        assert!(
            collisions > 5,
            "{collisions} collisions through the dense block"
        );
    }

    #[test]
    fn grid_ratio_tracking_matches_quadrature_of_the_density() {
        // A 4×3×5 grid with a ramp in x: ratio tracking's mean must equal exp(−∫σt ds) computed by
        // fine quadrature of the same trilinear density.
        let (nx, ny, nz) = (4, 3, 5);
        let mut data = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    data.push(0.2 + 0.3 * x as f32 + 0.1 * ((y + z) % 2) as f32);
                }
            }
        }
        let grid = DensityGrid::new(
            nx,
            ny,
            nz,
            data,
            crate::math::Mat4::from_scale_rotation_translation(
                Vec3::new(2.0, 1.0, 1.5),
                glam::Quat::IDENTITY,
                Vec3::new(-1.0, -0.5, -0.75),
            ),
        )
        .unwrap();
        let mut m = Medium::homogeneous("g", Vec3::splat(0.8), Vec3::splat(0.6), 0.0);
        m.grid = Some(grid);
        let ray = Ray::new(
            Vec3::new(-2.0, -0.2, 0.1),
            Vec3::new(1.0, 0.1, -0.05).normalize(),
        );
        let t_max = 3.5;
        // Quadrature: midpoint rule with 20 000 steps.
        let steps = 20_000;
        let dt = t_max / steps as f32;
        let mut tau = 0.0f64;
        for i in 0..steps {
            let p = ray.at((i as f32 + 0.5) * dt);
            tau += (m.properties(p).sigma_a.x + m.properties(p).sigma_s.x) as f64 * dt as f64;
        }
        let want = (-tau).exp();
        assert!(
            want > 0.05 && want < 0.9,
            "test needs a mid-range T, got {want}"
        );
        let mut rng = Pcg32::new(3, 5);
        let n = 100_000;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let t = ratio_tracking(&m, &ray, t_max, 0, &mut rng) as f64;
            sum += t;
            sum2 += t * t;
        }
        let mean = sum / n as f64;
        let sd = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!(
            (mean - want).abs() < 5.0 * sd + 1e-4,
            "ratio tracking {mean} ± {sd}, quadrature {want}"
        );
    }
}
