//! Geometry: rays, bounding boxes and the ray–primitive intersection routines of the thesis
//! (§5.1.3–5.1.6): triangles (Möller–Trumbore), spheres, boxes (Williams et al. slab test) and quads.
//! Every routine returns the hit point with a conservative bound on its floating-point error so the
//! integrator can spawn the next ray without a scene-dependent epsilon.

pub mod bounds;
pub mod cuboid;
pub mod curve;
pub mod instance;
pub mod mesh;
pub mod motion;
pub mod primitive;
pub mod quad;
pub mod sample;
pub mod sphere;
pub mod triangle;

pub use bounds::Bounds3;
pub use primitive::{GeometryStore, PrimRef, PrimitiveKind, ShadingDerivatives, SurfaceHit};

use crate::math::{Vec3, offset_ray_origin};

/// A ray `o + t·d` restricted to `t ∈ (0, t_max)`. `d` need not be normalised.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
    pub t_max: f32,
    /// The moment the ray sees, as a fraction u ∈ [0, 1) of the shutter (docs/DESIGN.md,
    /// "Motion blur"): moving primitives are intersected where they are at u. 0 for a still,
    /// whose geometry has no motion and never reads it. A ray spawned from a hit takes the hit's
    /// time ([`Ray::with_time`], [`SurfaceHit::time`]), as pbrt-v4's `SpawnRay` does.
    pub time: f32,
}

impl Ray {
    #[inline]
    pub fn new(o: Vec3, d: Vec3) -> Ray {
        Ray {
            o,
            d,
            t_max: f32::INFINITY,
            time: 0.0,
        }
    }

    /// The ray at shutter time `time` (see [`Ray::time`]).
    #[inline(always)]
    pub fn with_time(self, time: f32) -> Ray {
        Ray { time, ..self }
    }

    /// True if the origin and direction are finite. A ray that is not (a camera placed at an
    /// overflowed distance, a direction normalised from an overflowed cross product, both possible
    /// with finite coordinates near `f32::MAX`) hits nothing: its slab tests are NaN, which the
    /// BVH's node test treats as a hit of every lane, empty lanes included, so it must not reach
    /// the traversal.
    #[inline(always)]
    pub fn is_traceable(&self) -> bool {
        self.o.is_finite() && self.d.is_finite()
    }

    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }

    /// A ray leaving surface point `p` (error bound `p_error`, geometric normal `n`) in direction `d`.
    #[inline]
    pub fn spawn(p: Vec3, p_error: Vec3, n: Vec3, d: Vec3) -> Ray {
        Ray::new(offset_ray_origin(p, p_error, n, d), d)
    }

    /// A shadow ray between two surface points, offset at both ends so neither surface occludes it
    /// (PBRT `SpawnRayTo` with two interactions). `t_max` stops just short of the target.
    #[inline]
    pub fn spawn_to(
        p_from: Vec3,
        err_from: Vec3,
        n_from: Vec3,
        p_to: Vec3,
        err_to: Vec3,
        n_to: Vec3,
    ) -> Ray {
        let pf = offset_ray_origin(p_from, err_from, n_from, p_to - p_from);
        let pt = offset_ray_origin(p_to, err_to, n_to, pf - p_to);
        Ray {
            o: pf,
            d: pt - pf,
            t_max: 1.0 - SHADOW_EPSILON,
            time: 0.0,
        }
    }
}

/// Fraction of a shadow ray's length left out at its far end, so the light's own surface does not
/// occlude it. Relative, so it is scale-independent.
pub const SHADOW_EPSILON: f32 = 1e-4;

/// Precomputed per-ray data for box tests: reciprocal direction and its signs (Williams et al. 2005,
/// "An Efficient and Robust Ray–Box Intersection Algorithm").
#[derive(Clone, Copy, Debug)]
pub struct RayInv {
    pub inv_d: Vec3,
    pub neg: [usize; 3],
}

impl RayInv {
    #[inline]
    pub fn new(d: Vec3) -> RayInv {
        let inv_d = Vec3::ONE / d;
        RayInv {
            inv_d,
            neg: [
                (inv_d.x < 0.0) as usize,
                (inv_d.y < 0.0) as usize,
                (inv_d.z < 0.0) as usize,
            ],
        }
    }
}
