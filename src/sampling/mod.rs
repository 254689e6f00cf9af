//! Sampling: random numbers, the per-pixel sample streams (independent, stratified), the warps
//! from the unit square onto the domains the integrator needs, and discrete distributions.
//! Every warp has a matching pdf, checked by chi-square tests in `tests/`.

pub mod distribution;
pub mod equal_area;
pub mod poisson;
pub mod rng;
pub mod sampler;
pub mod sobol;
pub mod warp;
pub mod zsobol;

pub use distribution::Distribution1D;
pub use sampler::{SampleStream, SamplerKind, SamplerSetup};
