//! Pixel reconstruction filters by filter importance sampling (pbrt-v4, "Physically Based
//! Rendering", 4th ed., §5.4.3 and §8.8; Ernst et al. 2006, "Filter Importance Sampling").
//!
//! Each camera sample of pixel (x, y) is placed at the pixel centre plus an offset drawn from the
//! filter's (absolute) shape, and its radiance is multiplied by the weight `f(p) / (pdf(p) · ∫f)`.
//! A pixel's value is the plain mean of its weighted samples, an unbiased estimate of
//! `∫ f(p) L(centre + p) dp / ∫ f`. Every sample still belongs to one pixel, so pixels stay
//! independent (crop windows, sample ranges, adaptive sampling and any thread count give the same
//! pixels), unlike splatting a sample into its neighbours.
//!
//! Samplers:
//! - `box`: uniform over the square, weight 1 (with the default radius 0.5 the film position is
//!   `pixel + u`, exactly as before filters existed, so default images are unchanged);
//! - `tent` (pbrt's `triangle`): the tent's inverse CDF, weight 1;
//! - `gaussian`, `mitchell`, `blackman-harris`: every filter here is separable, so each axis draws
//!   from a tabulated piecewise-constant distribution of `|f|` (pbrt-v4's `FilterSampler` tabulates
//!   the 2D filter; separable tables give the same distribution at a fraction of the size) and the
//!   weight `f/pdf` corrects the table's approximation exactly. Mitchell's negative lobes give
//!   negative weights.
//!
//! Parameters follow pbrt-v4's `PixelFilter` (radius per axis, Gaussian `sigma`, Mitchell `B`, `C`);
//! Blackman–Harris (not in pbrt) follows Cycles: its radius is Cycles' "filter width".

use crate::math::Vec2;

/// The reconstruction filter's shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FilterKind {
    #[default]
    Box,
    Tent,
    Gaussian,
    Mitchell,
    BlackmanHarris,
}

impl FilterKind {
    pub fn name(self) -> &'static str {
        match self {
            FilterKind::Box => "box",
            FilterKind::Tent => "tent",
            FilterKind::Gaussian => "gaussian",
            FilterKind::Mitchell => "mitchell",
            FilterKind::BlackmanHarris => "blackman-harris",
        }
    }

    /// pbrt-v4's default radius (box 0.5, triangle 2, gaussian 1.5, mitchell 2) and Cycles'
    /// default Blackman–Harris width (1.5 pixels).
    pub fn default_radius(self) -> f32 {
        match self {
            FilterKind::Box => 0.5,
            FilterKind::Tent => 2.0,
            FilterKind::Gaussian => 1.5,
            FilterKind::Mitchell => 2.0,
            FilterKind::BlackmanHarris => 1.5,
        }
    }
}

impl std::str::FromStr for FilterKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "box" => Ok(FilterKind::Box),
            "tent" | "triangle" => Ok(FilterKind::Tent),
            "gaussian" => Ok(FilterKind::Gaussian),
            "mitchell" => Ok(FilterKind::Mitchell),
            "blackman-harris" => Ok(FilterKind::BlackmanHarris),
            other => Err(format!(
                "unknown filter '{other}' (expected box, tent, gaussian, mitchell or blackman-harris)"
            )),
        }
    }
}

/// A reconstruction filter and its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Filter {
    pub kind: FilterKind,
    /// Half-width of the support in pixels along x and y (pbrt's `xradius`, `yradius`).
    pub radius: [f32; 2],
    /// Gaussian standard deviation in pixels (pbrt default 0.5).
    pub sigma: f32,
    /// Mitchell–Netravali B and C (pbrt default 1/3, 1/3).
    pub b: f32,
    pub c: f32,
}

impl Default for Filter {
    fn default() -> Self {
        Filter::new(FilterKind::Box)
    }
}

/// Largest filter radius accepted, in pixels.
pub const MAX_RADIUS: f32 = 16.0;

impl Filter {
    /// The filter with pbrt-v4's default parameters.
    pub fn new(kind: FilterKind) -> Filter {
        let r = kind.default_radius();
        Filter {
            kind,
            radius: [r, r],
            sigma: 0.5,
            b: 1.0 / 3.0,
            c: 1.0 / 3.0,
        }
    }

    /// The default: a box over exactly one pixel (what images were rendered with before filters).
    pub fn is_default_box(&self) -> bool {
        self.kind == FilterKind::Box && self.radius == [0.5, 0.5]
    }

    /// Refuses parameters that make no filter (non-finite, non-positive, a zero integral).
    pub fn validate(&self) -> Result<(), String> {
        for r in self.radius {
            if !(r > 0.0 && r <= MAX_RADIUS) {
                return Err(format!(
                    "the filter radius must be above 0 and at most {MAX_RADIUS} pixels (got {r})"
                ));
            }
        }
        if self.kind == FilterKind::Gaussian && !(self.sigma > 0.0 && self.sigma <= 100.0) {
            return Err(format!(
                "the Gaussian filter's sigma must be above 0 and at most 100 (got {})",
                self.sigma
            ));
        }
        if self.kind == FilterKind::Mitchell
            && !(self.b.is_finite()
                && self.c.is_finite()
                && self.b.abs() <= 10.0
                && self.c.abs() <= 10.0)
        {
            return Err(format!(
                "Mitchell B and C must be finite numbers in [-10, 10] (got {}, {})",
                self.b, self.c
            ));
        }
        for axis in 0..2 {
            let (pos, abs) = integrals(self, axis);
            if !(pos.is_finite() && pos > 1e-6 * abs.max(1e-30)) {
                return Err(format!(
                    "the {} filter with these parameters integrates to {pos:e}, not a positive number",
                    self.kind.name()
                ));
            }
        }
        Ok(())
    }

    /// A short description for logs and partial-film headers.
    pub fn describe(&self) -> String {
        let r = if self.radius[0] == self.radius[1] {
            format!("radius {}", self.radius[0])
        } else {
            format!("radius {}x{}", self.radius[0], self.radius[1])
        };
        match self.kind {
            FilterKind::Gaussian => format!("gaussian {r} sigma {}", self.sigma),
            FilterKind::Mitchell => format!("mitchell {r} B {} C {}", self.b, self.c),
            k => format!("{} {r}", k.name()),
        }
    }

    /// The 1D filter along `axis` at offset `x` (pixels). The 2D filter is the product over both
    /// axes (pbrt-v4's filters are all separable).
    pub fn eval_1d(&self, axis: usize, x: f32) -> f32 {
        let r = self.radius[axis];
        let ax = x.abs();
        if ax > r {
            return 0.0;
        }
        match self.kind {
            FilterKind::Box => 1.0,
            FilterKind::Tent => r - ax,
            FilterKind::Gaussian => (gaussian(x, self.sigma) - gaussian(r, self.sigma)).max(0.0),
            FilterKind::Mitchell => mitchell_1d(2.0 * x / r, self.b, self.c),
            FilterKind::BlackmanHarris => {
                // Cycles' `filter_func_blackman_harris` over the support [-r, r].
                let t = std::f32::consts::TAU * (x / (2.0 * r) + 0.5);
                0.35875 - 0.48829 * t.cos() + 0.14128 * (2.0 * t).cos() - 0.01168 * (3.0 * t).cos()
            }
        }
    }

    /// The 2D filter at offset `p`.
    pub fn eval(&self, p: Vec2) -> f32 {
        self.eval_1d(0, p.x) * self.eval_1d(1, p.y)
    }
}

fn gaussian(x: f32, sigma: f32) -> f32 {
    (-x * x / (2.0 * sigma * sigma)).exp() / (std::f32::consts::TAU * sigma * sigma).sqrt()
}

/// Mitchell & Netravali 1988, "Reconstruction Filters in Computer Graphics", eq. 8, on [-2, 2]
/// (as pbrt-v4's `MitchellFilter::Mitchell1D`).
fn mitchell_1d(x: f32, b: f32, c: f32) -> f32 {
    let x = x.abs();
    if x <= 1.0 {
        ((12.0 - 9.0 * b - 6.0 * c) * x * x * x
            + (-18.0 + 12.0 * b + 6.0 * c) * x * x
            + (6.0 - 2.0 * b))
            / 6.0
    } else if x <= 2.0 {
        ((-b - 6.0 * c) * x * x * x
            + (6.0 * b + 30.0 * c) * x * x
            + (-12.0 * b - 48.0 * c) * x
            + (8.0 * b + 24.0 * c))
            / 6.0
    } else {
        0.0
    }
}

/// Quadrature points per unit of radius for [`integrals`].
const QUAD_PER_PIXEL: usize = 2048;

/// ∫f and ∫|f| of the 1D filter along `axis`, by composite Simpson's rule in f64 (error far
/// below f32 precision for these smooth pieces; the Mitchell kinks at ±r/2 fall on nodes).
fn integrals(f: &Filter, axis: usize) -> (f64, f64) {
    let r = f.radius[axis] as f64;
    let n = ((r * QUAD_PER_PIXEL as f64).ceil() as usize).max(64) * 2;
    let h = 2.0 * r / n as f64;
    let (mut s, mut a) = (0.0f64, 0.0f64);
    for i in 0..=n {
        let x = -r + i as f64 * h;
        let w = if i == 0 || i == n {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        };
        let v = f.eval_1d(axis, x as f32) as f64;
        s += w * v;
        a += w * v.abs();
    }
    (s * h / 3.0, a * h / 3.0)
}

/// Cells per table (per axis) of a tabulated sampler.
const TABLE_CELLS: usize = 1024;

/// A piecewise-constant distribution of |f| over [-r, r] along one axis.
#[derive(Clone, Debug)]
struct Table1D {
    r: f32,
    /// `cdf[i]` = probability of cells `0..i`; `cdf[TABLE_CELLS] = 1`.
    cdf: Vec<f32>,
    /// Probability density of each cell (per pixel of offset).
    pdf: Vec<f32>,
    /// 1 / ∫f: normalises the weight so that its expectation is 1.
    inv_integral: f32,
}

impl Table1D {
    fn new(f: &Filter, axis: usize) -> Table1D {
        let r = f.radius[axis];
        let cell = 2.0 * r as f64 / TABLE_CELLS as f64;
        // Each cell's mass is the mean of |f| over it (16-point midpoint rule), so the table
        // follows the filter between nodes too; its error only costs variance (the weight
        // f/pdf is exact).
        let mut mass = vec![0.0f64; TABLE_CELLS];
        for (i, m) in mass.iter_mut().enumerate() {
            let x0 = -(r as f64) + i as f64 * cell;
            let mut s = 0.0;
            for k in 0..16 {
                let x = x0 + (k as f64 + 0.5) * cell / 16.0;
                s += (f.eval_1d(axis, x as f32) as f64).abs();
            }
            // A floor keeps every cell where f may be non-zero reachable (f/pdf finite).
            *m = s / 16.0;
        }
        let peak = mass.iter().cloned().fold(0.0, f64::max);
        for m in &mut mass {
            *m = m.max(peak * 1e-6);
        }
        let total: f64 = mass.iter().sum();
        let mut cdf = Vec::with_capacity(TABLE_CELLS + 1);
        let mut acc = 0.0f64;
        cdf.push(0.0f32);
        for m in &mass {
            acc += m;
            cdf.push((acc / total) as f32);
        }
        cdf[TABLE_CELLS] = 1.0;
        // The density is taken from the f32 CDF actually sampled, so f/pdf matches the sampler.
        let pdf = (0..TABLE_CELLS)
            .map(|i| ((cdf[i + 1] - cdf[i]) as f64 / cell) as f32)
            .collect();
        let (integral, _) = integrals(f, axis);
        Table1D {
            r,
            cdf,
            pdf,
            inv_integral: (1.0 / integral) as f32,
        }
    }

    /// An offset in [-r, r] drawn from the table and its density.
    #[inline]
    fn sample(&self, u: f32) -> (f32, f32) {
        // Largest i with cdf[i] <= u (cdf[0] = 0 <= u).
        let i = self.cdf.partition_point(|&c| c <= u).clamp(1, TABLE_CELLS) - 1;
        let (c0, c1) = (self.cdf[i], self.cdf[i + 1]);
        let t = if c1 > c0 { (u - c0) / (c1 - c0) } else { 0.5 };
        let cell = 2.0 * self.r / TABLE_CELLS as f32;
        let x = (-self.r + (i as f32 + t.clamp(0.0, 1.0)) * cell).clamp(-self.r, self.r);
        (x, self.pdf[i])
    }

    /// The density the table gives offset `x` (for tests).
    fn pdf_at(&self, x: f32) -> f32 {
        if x.abs() > self.r {
            return 0.0;
        }
        let cell = 2.0 * self.r / TABLE_CELLS as f32;
        let i = (((x + self.r) / cell) as usize).min(TABLE_CELLS - 1);
        self.pdf[i]
    }
}

/// Draws camera-sample offsets from a [`Filter`]; built once per render (the tables allocate),
/// then shared read-only by every thread.
#[derive(Clone, Debug)]
pub struct FilterSampler {
    filter: Filter,
    /// [`Filter::is_default_box`], looked up once per sample.
    default_box: bool,
    /// Per-axis tables for the tabulated filters (empty for box and tent).
    tables: Vec<Table1D>,
}

impl FilterSampler {
    pub fn new(filter: &Filter) -> FilterSampler {
        let tables = match filter.kind {
            FilterKind::Box | FilterKind::Tent => Vec::new(),
            _ => vec![Table1D::new(filter, 0), Table1D::new(filter, 1)],
        };
        FilterSampler {
            filter: *filter,
            default_box: filter.is_default_box(),
            tables,
        }
    }

    pub fn filter(&self) -> &Filter {
        &self.filter
    }

    /// Maps a uniform 2D sample to an offset from the pixel centre and its weight
    /// `f(p) / (pdf(p) · ∫f)` (expectation 1 over the sampler).
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let r = self.filter.radius;
        match self.filter.kind {
            FilterKind::Box => (
                Vec2::new((2.0 * u.x - 1.0) * r[0], (2.0 * u.y - 1.0) * r[1]),
                1.0,
            ),
            FilterKind::Tent => (
                Vec2::new(sample_tent(u.x, r[0]), sample_tent(u.y, r[1])),
                1.0,
            ),
            _ => {
                let (tx, ty) = (&self.tables[0], &self.tables[1]);
                let (x, px) = tx.sample(u.x);
                let (y, py) = ty.sample(u.y);
                let wx = self.filter.eval_1d(0, x) / px * tx.inv_integral;
                let wy = self.filter.eval_1d(1, y) / py * ty.inv_integral;
                (Vec2::new(x, y), wx * wy)
            }
        }
    }

    /// The sampler's density at offset `p` (for tests).
    pub fn pdf(&self, p: Vec2) -> f32 {
        let r = self.filter.radius;
        if p.x.abs() > r[0] || p.y.abs() > r[1] {
            return 0.0;
        }
        match self.filter.kind {
            FilterKind::Box => 1.0 / (4.0 * r[0] * r[1]),
            FilterKind::Tent => {
                ((r[0] - p.x.abs()) / (r[0] * r[0])) * ((r[1] - p.y.abs()) / (r[1] * r[1]))
            }
            _ => self.tables[0].pdf_at(p.x) * self.tables[1].pdf_at(p.y),
        }
    }

    /// The film position of a camera sample of pixel (x, y) and its weight. The default box keeps
    /// the original `pixel + u` arithmetic, so default images are bit-identical to before.
    #[inline]
    pub fn film_point(&self, x: u32, y: u32, u: Vec2) -> (Vec2, f32) {
        if self.default_box {
            return (Vec2::new(x as f32 + u.x, y as f32 + u.y), 1.0);
        }
        let (o, w) = self.sample(u);
        (Vec2::new(x as f32 + 0.5 + o.x, y as f32 + 0.5 + o.y), w)
    }
}

/// Inverse CDF of the tent of radius r on [-r, r] (pbrt-v4 `SampleTent`).
#[inline]
fn sample_tent(u: f32, r: f32) -> f32 {
    if u < 0.5 {
        r * ((2.0 * u).sqrt() - 1.0)
    } else {
        r * (1.0 - (2.0 - 2.0 * u).max(0.0).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::{hash_words, u32_to_unit_f32};

    fn all_filters() -> Vec<Filter> {
        let mut v: Vec<Filter> = [
            FilterKind::Box,
            FilterKind::Tent,
            FilterKind::Gaussian,
            FilterKind::Mitchell,
            FilterKind::BlackmanHarris,
        ]
        .into_iter()
        .map(Filter::new)
        .collect();
        // Non-default parameters: an anisotropic box, a wide Gaussian, a sharp Mitchell.
        v.push(Filter {
            radius: [1.0, 0.75],
            ..Filter::new(FilterKind::Box)
        });
        v.push(Filter {
            radius: [2.5, 2.5],
            sigma: 1.0,
            ..Filter::new(FilterKind::Gaussian)
        });
        v.push(Filter {
            radius: [1.0, 3.0],
            b: 0.0,
            c: 0.5,
            ..Filter::new(FilterKind::Mitchell)
        });
        v
    }

    fn uniform(i: u64, salt: u64) -> f32 {
        u32_to_unit_f32(hash_words(&[i, salt, 0x5eed]) as u32)
    }

    /// The sampled weights average to one: E[f/(pdf·∫f)] = 1 (Monte Carlo, 400k samples, 5σ).
    #[test]
    fn sampled_weights_integrate_to_one() {
        for f in all_filters() {
            f.validate().unwrap();
            let s = FilterSampler::new(&f);
            let n = 400_000u64;
            let (mut sum, mut sq) = (0.0f64, 0.0f64);
            for i in 0..n {
                let (p, w) = s.sample(Vec2::new(uniform(i, 1), uniform(i, 2)));
                assert!(p.x.abs() <= f.radius[0] && p.y.abs() <= f.radius[1]);
                assert!(w.is_finite());
                sum += w as f64;
                sq += (w as f64) * (w as f64);
            }
            let mean = sum / n as f64;
            let sd = ((sq / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
            assert!(
                (mean - 1.0).abs() <= 5.0 * sd + 1e-4,
                "{}: mean weight {mean} (σ {sd})",
                f.describe()
            );
        }
    }

    /// The filters' analytic integrals (pbrt-v4's `Integral()`) match the quadrature used to
    /// normalise the weights: box 2r, triangle r², Mitchell r/2 (per axis).
    #[test]
    fn quadrature_matches_closed_forms() {
        let check = |f: Filter, want: f64| {
            let (got, _) = integrals(&f, 0);
            assert!(
                (got - want).abs() < 1e-5 * want,
                "{}: {got} vs {want}",
                f.describe()
            );
        };
        check(Filter::new(FilterKind::Box), 1.0);
        check(Filter::new(FilterKind::Tent), 4.0);
        check(Filter::new(FilterKind::Mitchell), 1.0);
        // Gaussian: erf-based integral minus the subtracted pedestal, σ=0.5, r=1.5:
        // ∫G = erf(r/(σ√2)) = erf(2.1213203) = 0.99730020; pedestal 2r·G(r).
        let g = Filter::new(FilterKind::Gaussian);
        let ped = 3.0 * (-4.5f64).exp() / (std::f64::consts::TAU * 0.25).sqrt();
        check(g, 0.997_300_2 - ped);
        // Blackman–Harris over [-r, r]: the cosines integrate to zero, 2r·0.35875.
        check(Filter::new(FilterKind::BlackmanHarris), 3.0 * 0.35875);
    }

    /// Chi-square test of each sampler against the density it claims (|f|-shaped for the exact
    /// samplers, the table for the tabulated ones) on a 16×16 grid over the support, and of that
    /// density against |f|/∫|f| (to the table's resolution).
    #[test]
    fn sampler_chi_square_against_filter() {
        for f in all_filters() {
            let s = FilterSampler::new(&f);
            let g = 16usize;
            let n = 200_000u64;
            let mut hist = vec![0u64; g * g];
            let cell = |v: f32, r: f32| (((v + r) / (2.0 * r) * g as f32) as usize).min(g - 1);
            for i in 0..n {
                let (p, _) = s.sample(Vec2::new(uniform(i, 3), uniform(i, 4)));
                hist[cell(p.y, f.radius[1]) * g + cell(p.x, f.radius[0])] += 1;
            }
            // Expected counts: the 2D integral of |f|/∫|f| over each cell (16×16 midpoint rule).
            let (_, ax) = integrals(&f, 0);
            let (_, ay) = integrals(&f, 1);
            let mut chi2 = 0.0f64;
            let mut dof = 0;
            let mut pooled = (0.0f64, 0.0f64);
            for cy in 0..g {
                for cx in 0..g {
                    let (wx, wy) = (2.0 * f.radius[0] / g as f32, 2.0 * f.radius[1] / g as f32);
                    let mut m = 0.0f64;
                    for ky in 0..16 {
                        for kx in 0..16 {
                            let x = -f.radius[0] + (cx as f32 + (kx as f32 + 0.5) / 16.0) * wx;
                            let y = -f.radius[1] + (cy as f32 + (ky as f32 + 0.5) / 16.0) * wy;
                            m += f.eval(Vec2::new(x, y)).abs() as f64;
                        }
                    }
                    let expected = m / 256.0 * (wx * wy) as f64 / (ax * ay) * n as f64;
                    let obs = hist[cy * g + cx] as f64;
                    if expected < 5.0 {
                        pooled.0 += expected;
                        pooled.1 += obs;
                        continue;
                    }
                    chi2 += (obs - expected).powi(2) / expected;
                    dof += 1;
                }
            }
            if pooled.0 >= 5.0 {
                chi2 += (pooled.1 - pooled.0).powi(2) / pooled.0;
                dof += 1;
            }
            // Wilson–Hilferty 1 − 1e-4 quantile of χ²(dof): z = 3.719.
            let k = dof as f64;
            let crit = k * (1.0 - 2.0 / (9.0 * k) + 3.719 * (2.0 / (9.0 * k)).sqrt()).powi(3);
            assert!(
                chi2 < crit,
                "{}: chi-square {chi2:.1} > {crit:.1} ({dof} cells)",
                f.describe()
            );
        }
    }

    /// The density the sampler reports integrates to one and is positive wherever f is not zero
    /// (so f/pdf is finite).
    #[test]
    fn sampler_pdf_is_normalised_and_covers_the_filter() {
        for f in all_filters() {
            let s = FilterSampler::new(&f);
            let g = 400;
            let (wx, wy) = (2.0 * f.radius[0] / g as f32, 2.0 * f.radius[1] / g as f32);
            let mut total = 0.0f64;
            for j in 0..g {
                for i in 0..g {
                    let p = Vec2::new(
                        -f.radius[0] + (i as f32 + 0.5) * wx,
                        -f.radius[1] + (j as f32 + 0.5) * wy,
                    );
                    let pdf = s.pdf(p);
                    if f.eval(p) != 0.0 {
                        assert!(pdf > 0.0, "{} at {p:?}", f.describe());
                    }
                    total += pdf as f64 * (wx * wy) as f64;
                }
            }
            assert!(
                (total - 1.0).abs() < 2e-3,
                "{}: ∫pdf = {total}",
                f.describe()
            );
        }
    }

    #[test]
    fn mitchell_has_negative_weights_and_the_others_do_not() {
        for f in all_filters() {
            let s = FilterSampler::new(&f);
            let neg = (0..50_000u64)
                .filter(|&i| s.sample(Vec2::new(uniform(i, 5), uniform(i, 6))).1 < 0.0)
                .count();
            assert_eq!(neg > 0, f.kind == FilterKind::Mitchell, "{}", f.describe());
        }
    }

    #[test]
    fn absurd_parameters_are_refused() {
        let bad = [
            Filter {
                radius: [0.0, 1.0],
                ..Filter::default()
            },
            Filter {
                radius: [f32::NAN, 1.0],
                ..Filter::default()
            },
            Filter {
                radius: [-1.0, -1.0],
                ..Filter::default()
            },
            Filter {
                radius: [1e9, 1.0],
                ..Filter::default()
            },
            Filter {
                sigma: 0.0,
                ..Filter::new(FilterKind::Gaussian)
            },
            Filter {
                sigma: f32::INFINITY,
                ..Filter::new(FilterKind::Gaussian)
            },
            Filter {
                b: f32::NAN,
                ..Filter::new(FilterKind::Mitchell)
            },
        ];
        for f in bad {
            assert!(f.validate().is_err(), "{f:?}");
        }
        assert!("lanczos".parse::<FilterKind>().is_err());
        assert_eq!("triangle".parse::<FilterKind>(), Ok(FilterKind::Tent));
    }

    /// The default box keeps the pre-filter arithmetic: film position `pixel + u`, weight 1.
    #[test]
    fn default_box_is_the_old_jitter() {
        let s = FilterSampler::new(&Filter::default());
        let u = Vec2::new(0.123_456_7, 0.987_654_3);
        assert_eq!(
            s.film_point(7, 9, u),
            (Vec2::new(7.0 + u.x, 9.0 + u.y), 1.0)
        );
    }
}
