//! Trayecto: a physically based offline renderer (a backward path tracer).
//!
//! The modules follow a photon's life backwards from the camera:
//! [`scene`] (what loaders produce) → [`world`] (compiled for rendering: [`geometry`] and
//! [`accel`]) → [`camera`] rays → [`integrator`] (where each path's fate is decided, using
//! [`material`] BSDFs, [`light`] sampling and [`sampling`]) → [`film`] → [`render`] (the driver),
//! with the front ends ([`cli`]) on top.

// `!(x > 0.0)` is used on purpose throughout: unlike `x <= 0.0` it also rejects NaN, which is how
// hostile or degenerate data is kept out of the renderer.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod accel;
pub mod camera;
pub mod denoise;
pub mod film;
pub mod geometry;
pub mod image_io;
pub mod integrator;
pub mod light;
pub mod limits;
pub mod material;
pub mod math;
pub mod medium;
pub mod phases;
pub mod pipeline;
pub mod render;
pub mod sampling;
pub mod scene;
#[cfg(feature = "server")]
pub mod server;
pub mod spectrum;
pub mod split;
pub mod world;

/// The render identity of this build: a SHA-256 (hex) of the crate's sources, `Cargo.toml`,
/// `Cargo.lock`, the enabled features and the target, computed by `build.rs`. It changes whenever
/// the code that makes the image may have changed, which `CARGO_PKG_VERSION` does not: partial
/// films record it and merge only parts with the same identity (docs/DESIGN.md, partial films).
pub const RENDER_IDENTITY: &str = env!("TRAYECTO_RENDER_IDENTITY");
