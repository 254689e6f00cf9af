//! A perfect mirror.

use super::BsdfSample;
use crate::math::Vec3;

/// Perfect mirror with a tint: a single Dirac lobe, so `eval` and `pdf` are zero for every pair
/// of directions and only `sample` produces light.
#[derive(Clone, Copy, Debug)]
pub struct Mirror {
    pub color: Vec3,
}

impl Mirror {
    #[inline]
    pub fn eval(&self, _wo: Vec3, _wi: Vec3) -> Vec3 {
        Vec3::ZERO
    }

    #[inline]
    pub fn pdf(&self, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    #[inline]
    pub fn sample(&self, wo: Vec3) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        Some(BsdfSample {
            wi,
            f: self.color / wi.z,
            pdf: 1.0,
            specular: true,
            eta: 1.0,
        })
    }
}
