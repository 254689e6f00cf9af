//! pbrt-v4's coated models (`CoatedDiffuseMaterial`, `CoatedConductorMaterial`): a dielectric
//! coat over a Lambertian or conductor base with a homogeneous slab between them, evaluated
//! stochastically by [`crate::material::bxdf::Layered`] (pbrt-v4 `LayeredBxDF`).

use super::{Conductor, RoughnessTextures};
use crate::material::Bsdf;
use crate::material::bxdf::Layered;
use crate::material::bxdf::layered::{self, Base};
use crate::material::eval::HitTextures;
use crate::material::microfacet::Ggx;
use crate::math::{Vec2, Vec3};

/// The dielectric coat: relative IOR and GGX α (pbrt `interface.eta`/`interface.roughness` for
/// `coatedconductor`, `eta`/`roughness` for `coateddiffuse`), with per-hit roughness textures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coat {
    pub eta: f32,
    pub alpha: Vec2,
    pub roughness: RoughnessTextures,
    /// η given as a spectrum varying with λ (pbrt's named glasses, sampled η): its
    /// [`crate::spectrum::BsdfSpectra`] id, which spectral rendering follows (`eta` is its
    /// index at 587.56 nm, for RGB).
    pub eta_spectrum: Option<u16>,
}

impl Default for Coat {
    fn default() -> Self {
        Coat {
            eta: 1.5,
            alpha: Vec2::ZERO,
            roughness: RoughnessTextures::default(),
            eta_spectrum: None,
        }
    }
}

/// The slab between coat and base: thickness (σt = 1), medium albedo and HG asymmetry g, and
/// the random walk's length and walks per evaluation. Defaults are pbrt-v4's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slab {
    pub thickness: f32,
    pub albedo: Vec3,
    pub g: f32,
    pub max_depth: u32,
    pub n_samples: u32,
}

impl Default for Slab {
    fn default() -> Self {
        Slab {
            thickness: 0.01,
            albedo: Vec3::ZERO,
            g: 0.0,
            max_depth: 10,
            n_samples: 1,
        }
    }
}

/// pbrt-v4 `coateddiffuse`: the coat over a Lambertian base of the material's base colour.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct CoatedDiffuse {
    pub coat: Coat,
    pub slab: Slab,
}

/// pbrt-v4 `coatedconductor`: the coat over a conductor.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct CoatedConductor {
    pub coat: Coat,
    pub conductor: Conductor,
    pub slab: Slab,
}

impl CoatedDiffuse {
    #[inline]
    pub fn bsdf(&self, tx: &HitTextures, base: impl FnOnce() -> Vec3) -> Bsdf {
        layered_bsdf(
            &self.coat,
            &self.slab,
            Base::Diffuse {
                reflectance: base(),
            },
            tx,
        )
    }
}

impl CoatedConductor {
    #[inline]
    pub fn bsdf(&self, tx: &HitTextures, base: impl FnOnce() -> Vec3) -> Bsdf {
        let conductor = self.conductor.lobe(tx, self.coat.eta, base);
        layered_bsdf(&self.coat, &self.slab, Base::Conductor(conductor), tx)
    }
}

#[inline]
fn layered_bsdf(coat: &Coat, slab: &Slab, base: Base, tx: &HitTextures) -> Bsdf {
    let alpha = coat.roughness.alpha(coat.alpha, tx);
    Bsdf::Layered(Layered {
        coat: layered::Coat {
            eta: coat.eta,
            dist: Ggx::anisotropic(alpha.x, alpha.y),
            eta_spectrum: coat.eta_spectrum,
        },
        base,
        thickness: slab.thickness,
        albedo: slab.albedo,
        g: slab.g,
        max_depth: slab.max_depth,
        n_samples: slab.n_samples,
    })
}

impl Coat {
    pub(super) fn validate(&self) -> Result<(), String> {
        if !(self.eta.is_finite() && self.alpha.is_finite() && self.roughness.factor.is_finite()) {
            return Err("has a non-finite pbrt parameter".into());
        }
        if self.alpha.min_element() < 0.0 || self.roughness.factor.min_element() < 0.0 {
            return Err("has a negative eta, k, albedo, transmittance or roughness".into());
        }
        if self.eta <= 0.0 {
            return Err(format!("coat eta must be positive (got {})", self.eta));
        }
        Ok(())
    }
}

impl Slab {
    pub(super) fn validate(&self) -> Result<(), String> {
        if !(self.thickness.is_finite() && self.albedo.is_finite() && self.g.is_finite()) {
            return Err("has a non-finite pbrt parameter".into());
        }
        if self.albedo.min_element() < 0.0 {
            return Err("has a negative eta, k, albedo, transmittance or roughness".into());
        }
        if self.thickness <= 0.0 {
            return Err(format!(
                "layer thickness must be positive (got {})",
                self.thickness
            ));
        }
        if !(-1.0 < self.g && self.g < 1.0) {
            return Err(format!("layer g must be in (-1, 1) (got {})", self.g));
        }
        if self.albedo.max_element() > 1.0 {
            return Err("layer albedo must be at most 1".into());
        }
        if self.max_depth == 0
            || self.max_depth > 1000
            || self.n_samples == 0
            || self.n_samples > 1000
        {
            return Err(format!(
                "layer maxdepth and nsamples must be in 1..=1000 (got {}, {})",
                self.max_depth, self.n_samples
            ));
        }
        Ok(())
    }
}

impl CoatedDiffuse {
    pub(super) fn validate(&self) -> Result<(), String> {
        self.coat.validate()?;
        self.slab.validate()
    }
}

impl CoatedConductor {
    pub(super) fn validate(&self) -> Result<(), String> {
        // The order of the old flat check: non-finite and negative values first.
        self.conductor.validate()?;
        self.coat.validate()?;
        self.slab.validate()
    }
}
