//! Sampling: random numbers, the per-pixel sample streams (independent, stratified), the warps
//! from the unit square onto the domains the integrator needs, and discrete distributions.
//! Every warp has a matching pdf, checked by chi-square tests in `tests/`.

pub mod distribution;
pub mod equal_area;
pub mod mlt;
pub mod poisson;
pub mod rng;
pub mod sampler;
pub mod sobol;
pub mod warp;
pub mod zsobol;

/// The largest f32 below 1: where a sample in [0, 1) is clamped after arithmetic that may round
/// it up to 1 (pbrt-v4's `OneMinusEpsilon`). Here, below the samplers and warps that all use it.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

pub use distribution::Distribution1D;
pub use sampler::{Numbers, SampleStream, SamplerKind, SamplerSetup, UniformSource};
