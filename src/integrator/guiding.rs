//! Path guiding (docs/DESIGN.md, "Path guiding"): a learned approximation of the incident
//! radiance field, from which the path tracer samples directions in a one-sample MIS mixture with
//! the BSDF.
//!
//! The field is an SD-tree (Müller, Gross and Novák 2017, "Practical Path Guiding for Efficient
//! Light-Transport Simulation"): a binary tree over the scene's bounds (split at the middle of
//! its cell, the axes in turn) whose leaves each hold a directional quadtree over the square
//! [0, 1]² of the cylindrical map (cos θ, φ/2π) of the sphere, which preserves area (so the
//! solid-angle density is the square's divided by 4π). A quadtree node keeps the radiance that
//! reached each of its four quadrants; sampling descends by those sums and a point is uniform in
//! the leaf quadrant reached (Müller 2017 §3.3). Each spatial leaf also learns the probability
//! of sampling the BSDF rather than the guide, by stochastic gradient descent (Adam) on the
//! KL divergence between the mixture and the product f·Lᵢ·cos (Müller 2019, "Practical Path
//! Guiding in Production", §10.2), clamped to [`ALPHA_MIN`, `ALPHA_MAX`] so that the BSDF always
//! keeps some probability (the mixture then covers every direction the BSDF does: unbiased).
//!
//! Learning is iterative: the render's first passes, of 1, 2, 4, … samples per pixel, are the
//! training iterations, and their samples stay in the image (`render::guide_training_passes`).
//! After an iteration, its records (a path vertex's position, the direction it continued in and
//! the radiance that came back along it) are splatted into a tree whose structure was refined
//! from the previous iteration's; that tree becomes the guide the next iteration samples with,
//! and its refinement the tree the next records go into. The records are merged in a fixed
//! order (passes in order, tiles in order, samples in order; each leaf's in that order when the
//! leaves learn in parallel), so the guide is a function of the seed and the settings, never of
//! the thread count.

use crate::material::Bsdf;
use crate::material::bxdf::BsdfSample;
use crate::math::{Frame, PI, Vec2, Vec3, luminance};
use crate::medium::HenyeyGreenstein;

/// Smallest and largest probability of sampling the BSDF: the guide never takes every sample
/// (its density may be zero where light arrives), nor the BSDF (which would waste the guide).
/// A BSDF-branch sample where the guide's density is near zero weighs up to 1/α more than
/// BSDF sampling would, at every guided bounce, and those samples make the fireflies that set
/// relMSE: with α ≥ 0.1 veach-ajar's was 1.7–2.5 against 1.4 unguided at 64 spp, with α ≥ 0.3
/// 1.26–1.46, with α ≥ 0.7 1.02–1.23; on gap-room at 384×288 the floor 0.7 turned the guide's
/// halved median error into a lower mean as well (BENCHMARKS.md, "Path guiding").
pub const ALPHA_MIN: f32 = 0.7;
pub const ALPHA_MAX: f32 = 0.9;
/// A quadtree node is subdivided while it holds more than this share of its tree's radiance
/// (Müller 2017's ρ).
const FLUX_SHARE: f32 = 0.01;
/// Deepest quadtree level (2⁻²⁰ of the square's side: far below any useful resolution).
const MAX_DEPTH: u32 = 20;
/// A spatial leaf splits when the last iteration put more than `SPLIT_C` · √(samples per pixel
/// of the iteration) records into it (Müller 2017 §3.4 uses 12000 at a megapixel; renders here
/// are smaller, and a cell's directional tree needs a few thousand records to learn anything).
const SPLIT_C: f32 = 4000.0;

/// [`SPLIT_C`], unless the environment variable `TRAYECTO_GUIDING_SPLIT` sets another (a
/// benchmarking knob, `bench/guiding.py`; the image stays a function of seed, settings and it).
fn split_c() -> f32 {
    static C: std::sync::OnceLock<f32> = std::sync::OnceLock::new();
    *C.get_or_init(|| {
        std::env::var("TRAYECTO_GUIDING_SPLIT")
            .ok()
            .and_then(|v| v.parse().ok())
            .filter(|c: &f32| *c > 0.0)
            .unwrap_or(SPLIT_C)
    })
}
/// Memory bound: at most this many spatial leaves, and this many quadtree nodes over all of them
/// (32 bytes each: 32 MiB). A tree at the cap stops refining; the image stays unbiased.
pub const MAX_LEAVES: usize = 1 << 14;
pub const MAX_QUAD_NODES: usize = 1 << 20;
/// The spatial forest's trees: one per dominant axis and sign of the surface normal (faced
/// toward the arriving path), and one for medium vertices. A floor, a wall and a ceiling then
/// never share a directional distribution: each tree's leaves learn radiance arriving over one
/// hemisphere's worth of directions, instead of an average over surfaces facing apart whose
/// mass half lies below any one of them (measured: docs/DESIGN.md "Path guiding").
pub const ROOTS: usize = 7;
pub const MEDIUM_BIN: u8 = 6;

/// Benchmarking knob: `TRAYECTO_GUIDING_OFF` lists refinements to leave out (`bins`, `filter`,
/// `nee`), so that `bench/guiding.py` can measure each one's share; unset in normal use.
fn knob_off(name: &str) -> bool {
    static OFF: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    OFF.get_or_init(|| std::env::var("TRAYECTO_GUIDING_OFF").unwrap_or_default())
        .split(',')
        .any(|k| k == name)
}

/// Benchmarking knob: `TRAYECTO_GUIDING_ALPHA` fixes the BSDF's share of the mixture (within
/// [`ALPHA_MIN`, `ALPHA_MAX`]) instead of the learned one, to measure what the learning gives.
fn fixed_alpha() -> Option<f32> {
    static A: std::sync::OnceLock<Option<f32>> = std::sync::OnceLock::new();
    *A.get_or_init(|| {
        std::env::var("TRAYECTO_GUIDING_ALPHA")
            .ok()
            .and_then(|v| v.parse::<f32>().ok())
            .map(|a| a.clamp(ALPHA_MIN, ALPHA_MAX))
    })
}

/// Measured settings of where the guide is used (docs/DESIGN.md "Path guiding"), each with a
/// benchmarking knob: `TRAYECTO_GUIDING_ALPHA_MIN` (the BSDF's least share, [`ALPHA_MIN`] by
/// default), `TRAYECTO_GUIDING_MIN_RECORDS` (a leaf whose iteration splatted fewer records is
/// left to the BSDF: 1 by default) and `TRAYECTO_GUIDING_DEPTH` (vertices from this bounce on are
/// left to the BSDF: none by default). Each decides from the guide and the vertex alone, so
/// the estimate stays unbiased whatever they are.
#[derive(Clone, Copy, Debug)]
struct Knobs {
    alpha_min: f32,
    min_records: u32,
    depth: u32,
}

fn knobs() -> &'static Knobs {
    static K: std::sync::OnceLock<Knobs> = std::sync::OnceLock::new();
    K.get_or_init(|| {
        fn var<T: std::str::FromStr>(name: &str) -> Option<T> {
            std::env::var(name).ok().and_then(|v| v.parse().ok())
        }
        Knobs {
            alpha_min: var::<f32>("TRAYECTO_GUIDING_ALPHA_MIN")
                .map_or(ALPHA_MIN, |a| a.clamp(0.01, ALPHA_MAX)),
            min_records: var("TRAYECTO_GUIDING_MIN_RECORDS").unwrap_or(1),
            depth: var("TRAYECTO_GUIDING_DEPTH").unwrap_or(u32::MAX),
        }
    })
}

/// Whether a vertex after `bounces` scattering events may be guided ([`Knobs`]).
#[inline]
pub fn guides_bounce(bounces: u32) -> bool {
    bounces < knobs().depth
}

/// Whether training records light samples too (`TRAYECTO_GUIDING_OFF=nee` leaves them out).
pub fn records_nee() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| !knob_off("nee"))
}

/// The surface tree of a vertex with geometric normal `ng` reached along `wo` (pointing back
/// along the path): chosen by the normal faced toward the side the path came from.
#[inline]
pub fn normal_bin(ng: Vec3, wo: Vec3) -> u8 {
    static ONE_TREE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    if *ONE_TREE.get_or_init(|| knob_off("bins")) {
        return 0;
    }
    let n = if ng.dot(wo) < 0.0 { -ng } else { ng };
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    (2 * axis + (n[axis] < 0.0) as usize) as u8
}

/// A 64-bit integer hash (the SplitMix64 finalizer): the filters' jitter is a function of the
/// record's place in its iteration, never of which thread made it.
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[inline]
fn unit(bits: u64) -> f32 {
    (bits >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// Adam's step size and moment decays (Kingma and Ba 2015), as Müller 2019 uses them.
const ADAM_LR: f32 = 0.01;
const ADAM_B1: f32 = 0.9;
const ADAM_B2: f32 = 0.999;

/// One training record: where a path vertex was, the direction it continued in, and what the
/// rest of the path found along it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    pub p: Vec3,
    /// The vertex's tree in the forest ([`normal_bin`], or [`MEDIUM_BIN`]).
    pub bin: u8,
    /// The sampled direction (world space, unit).
    pub wi: Vec3,
    /// Luminance of the incident radiance estimate Lᵢ along `wi`.
    pub radiance: f32,
    /// Luminance of f(wo, wi)·|cos θᵢ| at the vertex.
    pub f_cos: f32,
    /// Densities of `wi` under the BSDF, the guide (0 without one) and the mixture it was drawn
    /// from, and the BSDF's share of that mixture.
    pub pdf_bsdf: f32,
    pub pdf_guide: f32,
    pub pdf: f32,
    pub alpha: f32,
}

#[derive(Clone, Copy, Debug, Default)]
struct QuadNode {
    /// Index of each quadrant's child node in [`Guide::quads`]; 0 for a leaf quadrant (node 0 is
    /// never a child: it is the first tree's root).
    child: [u32; 4],
    sum: [f32; 4],
}

#[derive(Clone, Copy, Debug)]
struct SpatialNode {
    /// Index of the first of the two children in [`Guide::spatial`] (the second follows); 0 for
    /// a leaf.
    children: u32,
    axis: u8,
    /// The leaf's index in [`Guide::leaves`] (leaves only).
    leaf: u32,
}

#[derive(Clone, Copy, Debug)]
struct Leaf {
    root: u32,
    /// Records splatted into this leaf in the iteration that filled it.
    count: u32,
    /// The BSDF's share of the mixture: α = clamp(sigmoid(θ)); Adam's moments, and β₁ᵗ and
    /// β₂ᵗ after its t steps (its bias corrections).
    theta: f32,
    m: f32,
    v: f32,
    b1t: f32,
    b2t: f32,
}

/// The learned incident-radiance field: an SD-tree.
#[derive(Clone, Debug)]
pub struct Guide {
    min: Vec3,
    inv_extent: Vec3,
    extent: Vec3,
    spatial: Vec<SpatialNode>,
    leaves: Vec<Leaf>,
    quads: Vec<QuadNode>,
}

/// A guided vertex: the guide, the spatial leaf holding the vertex and the BSDF's share of the
/// mixture there.
#[derive(Clone, Copy, Debug)]
pub struct Mix<'a> {
    pub guide: &'a Guide,
    pub leaf: u32,
    pub alpha: f32,
}

/// Direction to the point of the cylindrical square (Müller 2017 eq. 10: z = cos θ).
#[inline]
fn square_to_dir(p: Vec2) -> Vec3 {
    let cos = (2.0 * p.x - 1.0).clamp(-1.0, 1.0);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * p.y).sin_cos();
    Vec3::new(sin * c, sin * s, cos)
}

#[inline]
fn dir_to_square(d: Vec3) -> Vec2 {
    let x = ((d.z.clamp(-1.0, 1.0) + 1.0) * 0.5).min(1.0 - f32::EPSILON / 2.0);
    let mut phi = d.y.atan2(d.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let y = (phi * (0.5 / PI)).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
    Vec2::new(x, y)
}

#[inline]
fn sigmoid(t: f32) -> f32 {
    1.0 / (1.0 + (-t).exp())
}

impl Guide {
    /// A guide over `min..max` with one leaf and an empty (uniform) directional tree.
    pub fn new(min: Vec3, max: Vec3) -> Guide {
        // A little margin so that points on the bounds fall inside, and no axis of zero width.
        let ext = (max - min).max(Vec3::splat(1e-3));
        let min = min - ext * 1e-3;
        let extent = ext * 1.002;
        Guide {
            min,
            inv_extent: extent.recip(),
            extent,
            spatial: (0..ROOTS as u32)
                .map(|k| SpatialNode {
                    children: 0,
                    axis: 0,
                    leaf: k,
                })
                .collect(),
            leaves: (0..ROOTS as u32)
                .map(|k| Leaf {
                    root: k,
                    count: 0,
                    theta: 0.0,
                    m: 0.0,
                    v: 0.0,
                    b1t: 1.0,
                    b2t: 1.0,
                })
                .collect(),
            quads: vec![QuadNode::default(); ROOTS],
        }
    }

    pub fn leaf_count(&self) -> usize {
        self.leaves.len()
    }

    pub fn quad_node_count(&self) -> usize {
        self.quads.len()
    }

    /// Bytes the tree holds.
    pub fn memory(&self) -> usize {
        self.quads.len() * std::mem::size_of::<QuadNode>()
            + self.leaves.len() * std::mem::size_of::<Leaf>()
            + self.spatial.len() * std::mem::size_of::<SpatialNode>()
    }

    /// The spatial leaf of tree `bin` holding `p` (points outside the bounds go to the nearest
    /// cell).
    #[inline]
    pub fn leaf_at(&self, p: Vec3, bin: u8) -> u32 {
        self.locate(p, bin).0
    }

    /// [`Guide::leaf_at`] and the leaf cell's extent (world units).
    #[inline]
    fn locate(&self, p: Vec3, bin: u8) -> (u32, Vec3) {
        let mut c = ((p - self.min) * self.inv_extent).clamp(Vec3::ZERO, Vec3::ONE);
        let mut size = self.extent;
        let mut n = bin as usize % ROOTS;
        loop {
            let node = self.spatial[n];
            if node.children == 0 {
                return (node.leaf, size);
            }
            let a = node.axis as usize;
            let hi = c[a] >= 0.5;
            c[a] = if hi { c[a] * 2.0 - 1.0 } else { c[a] * 2.0 };
            size[a] *= 0.5;
            n = node.children as usize + hi as usize;
        }
    }

    /// The mixture of tree `bin` ([`normal_bin`]; media: [`MEDIUM_BIN`]) at `p`, if its leaf
    /// learned anything (an empty leaf leaves the vertex to the BSDF alone).
    #[inline]
    pub fn mix_in(&self, p: Vec3, bin: u8) -> Option<Mix<'_>> {
        let leaf = self.leaf_at(p, bin);
        let l = &self.leaves[leaf as usize];
        let total: f32 = self.quads[l.root as usize].sum.iter().sum();
        let k = knobs();
        (total > 0.0 && total.is_finite() && l.count >= k.min_records).then(|| Mix {
            guide: self,
            leaf,
            alpha: fixed_alpha().unwrap_or_else(|| sigmoid(l.theta).clamp(k.alpha_min, ALPHA_MAX)),
        })
    }

    /// Solid-angle density of the guide of `leaf` at the unit direction `d` (world space).
    #[inline]
    pub fn pdf(&self, leaf: u32, d: Vec3) -> f32 {
        let mut p = dir_to_square(d);
        let mut n = self.leaves[leaf as usize].root as usize;
        let mut density = 1.0 / (4.0 * PI);
        for _ in 0..=MAX_DEPTH {
            let q = &self.quads[n];
            let total = q.sum[0] + q.sum[1] + q.sum[2] + q.sum[3];
            if !(total > 0.0) {
                return 0.0;
            }
            let (ix, iy) = ((p.x >= 0.5) as usize, (p.y >= 0.5) as usize);
            let i = ix + 2 * iy;
            density *= 4.0 * q.sum[i] / total;
            if q.child[i] == 0 {
                break;
            }
            n = q.child[i] as usize;
            p = Vec2::new(p.x * 2.0 - ix as f32, p.y * 2.0 - iy as f32);
        }
        density
    }

    /// A direction drawn from the guide of `leaf` with `u` (Müller 2017 §3.3: descend by the
    /// quadrants' sums, then uniformly in the leaf quadrant). The leaf's tree must hold some
    /// radiance ([`Guide::mix_in`]).
    #[inline]
    pub fn sample(&self, leaf: u32, u: Vec2) -> Vec3 {
        self.sample_pdf(leaf, u).0
    }

    /// [`Guide::sample`] and the direction's density ([`Guide::pdf`]), found on the way down.
    #[inline]
    pub fn sample_pdf(&self, leaf: u32, u: Vec2) -> (Vec3, f32) {
        let mut n = self.leaves[leaf as usize].root as usize;
        let mut density = 1.0 / (4.0 * PI);
        let (mut ux, mut uy) = (u.x, u.y);
        let (mut ox, mut oy, mut size) = (0.0f32, 0.0f32, 1.0f32);
        for _ in 0..=MAX_DEPTH {
            let q = &self.quads[n];
            let s = q.sum;
            let total = s[0] + s[1] + s[2] + s[3];
            // Left column (ix = 0) holds quadrants 0 and 2.
            let left = (s[0] + s[2]) / total;
            let ix = if ux < left {
                ux = (ux / left).min(1.0 - f32::EPSILON / 2.0);
                0
            } else {
                ux = ((ux - left) / (1.0 - left)).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
                1
            };
            let col = s[ix] + s[ix + 2];
            let low = s[ix] / col;
            let iy = if uy < low {
                uy = (uy / low).min(1.0 - f32::EPSILON / 2.0);
                0
            } else {
                uy = ((uy - low) / (1.0 - low)).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
                1
            };
            size *= 0.5;
            ox += ix as f32 * size;
            oy += iy as f32 * size;
            density *= 4.0 * s[ix + 2 * iy] / total;
            let c = q.child[ix + 2 * iy];
            if c == 0 {
                break;
            }
            n = c as usize;
        }
        (
            square_to_dir(Vec2::new(ox + ux * size, oy + uy * size)),
            density,
        )
    }

    /// Side of the leaf quadrant of `leaf`'s tree that holds the square point `p`.
    fn quad_size_at(&self, leaf: u32, mut p: Vec2) -> f32 {
        let mut n = self.leaves[leaf as usize].root as usize;
        let mut size = 1.0f32;
        for _ in 0..=MAX_DEPTH {
            let (ix, iy) = ((p.x >= 0.5) as usize, (p.y >= 0.5) as usize);
            size *= 0.5;
            let c = self.quads[n].child[ix + 2 * iy];
            if c == 0 {
                break;
            }
            n = c as usize;
            p = Vec2::new(p.x * 2.0 - ix as f32, p.y * 2.0 - iy as f32);
        }
        size
    }

    /// Where record `r`, the `i`-th of its iteration (`key`), lands: its leaf, and with the
    /// stochastic box filter ([`Learner::learn`]) the target leaf and square point of its
    /// splat, drawn from a hash of `i`.
    fn place(&self, r: &Record, i: u64, key: u64, filter: bool) -> Splat {
        let mut s = Splat {
            leaf: u32::MAX,
            target: u32::MAX,
            at: Vec2::ZERO,
            value: 0.0,
            grad: f32::NAN,
        };
        if !(r.pdf > 0.0) || !r.radiance.is_finite() || !r.p.is_finite() {
            return s;
        }
        let (leaf, size) = self.locate(r.p, r.bin);
        s.leaf = leaf;
        if r.pdf_guide > 0.0 || r.alpha < 1.0 {
            s.grad = adam_gradient(r);
        }
        let h0 = mix64(key ^ i);
        let h1 = mix64(h0);
        let h2 = mix64(h1);
        let j = Vec3::new(unit(h0), unit(h0 << 24), unit(h1)) - Vec3::splat(0.5);
        s.target = if filter {
            self.leaf_at(r.p + j * size, r.bin)
        } else {
            leaf
        };
        let value = r.radiance / r.pdf;
        if diag_on() && r.bin < 6 && value > 0.0 && value.is_finite() {
            let mut n = Vec3::ZERO;
            n[(r.bin / 2) as usize] = if r.bin.is_multiple_of(2) { 1.0 } else { -1.0 };
            let k = if r.wi.dot(n) > 0.0 { 2 } else { 3 };
            DIAG[k].fetch_add(value as u64 + 1, std::sync::atomic::Ordering::Relaxed);
        }
        if value > 0.0 && value.is_finite() {
            let sq = dir_to_square(r.wi);
            let side = if filter {
                self.quad_size_at(s.target, sq)
            } else {
                0.0
            };
            let (jx, jy) = (unit(h1 << 24) - 0.5, unit(h2) - 0.5);
            let x = (sq.x + jx * side).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
            let y = (sq.y + jy * side)
                .rem_euclid(1.0)
                .min(1.0 - f32::EPSILON / 2.0);
            s.at = Vec2::new(x, y);
            s.value = value;
        }
        s
    }

    /// Copies the structure of `src`'s tree rooted at `n` into `self.quads` with zero sums,
    /// subdivided where `src`'s quadrants hold more than [`FLUX_SHARE`] of `total` (a quadrant
    /// never seen is assumed to split its share evenly) and while `budget` nodes remain. Returns
    /// the new root's index.
    fn refine_quad(
        &mut self,
        src: &[QuadNode],
        n: Option<usize>,
        share: [f32; 4],
        depth: u32,
        budget: &mut usize,
    ) -> u32 {
        let idx = self.quads.len();
        self.quads.push(QuadNode::default());
        for (i, &s) in share.iter().enumerate() {
            if !(s > FLUX_SHARE && depth < MAX_DEPTH && *budget >= 1) {
                continue;
            }
            let child = n.and_then(|n| {
                let c = src[n].child[i];
                (c != 0).then_some(c as usize)
            });
            let sub = match child {
                Some(c) => {
                    let cs = src[c].sum;
                    let ct = cs[0] + cs[1] + cs[2] + cs[3];
                    if ct > 0.0 {
                        cs.map(|x| s * x / ct)
                    } else {
                        [s / 4.0; 4]
                    }
                }
                None => [s / 4.0; 4],
            };
            *budget -= 1;
            let c = self.refine_quad(src, child, sub, depth + 1, budget);
            self.quads[idx].child[i] = c;
        }
        idx as u32
    }

    /// The next iteration's empty tree: spatial leaves that received more than
    /// [`SPLIT_C`]·√`spp` records are split (repeatedly, assuming the records halve with each
    /// split), every directional tree is refined by the radiance it holds, and each leaf keeps
    /// its BSDF share and Adam state. Both stay under [`MAX_LEAVES`] and [`MAX_QUAD_NODES`].
    fn refined(&self, spp: u32) -> Guide {
        let threshold = split_c() * (spp.max(1) as f32).sqrt();
        let mut g = Guide {
            min: self.min,
            inv_extent: self.inv_extent,
            extent: self.extent,
            spatial: Vec::with_capacity(self.spatial.len()),
            leaves: Vec::with_capacity(self.leaves.len()),
            quads: Vec::new(),
        };
        // Spatial structure first (leaf roots filled in below).
        struct Pending {
            old_leaf: u32,
        }
        let mut pending: Vec<Pending> = Vec::new();
        // Depth-first copy of each tree: (old node, new node index, axis of a new split, records
        // assumed in this cell). The roots keep their indices.
        for _ in 0..ROOTS {
            g.spatial.push(SpatialNode {
                children: 0,
                axis: 0,
                leaf: 0,
            });
        }
        let mut stack: Vec<_> = (0..ROOTS).rev().map(|k| (k, k, 0u8, None::<f32>)).collect();
        let mut leaves_left = MAX_LEAVES.saturating_sub(self.leaves.len());
        while let Some((old, new, axis, split_count)) = stack.pop() {
            let o = self.spatial[old];
            let (children_of_old, count) = match split_count {
                Some(c) => (None, c),
                None if o.children != 0 => (Some(o.children as usize), 0.0),
                None => (None, self.leaves[o.leaf as usize].count as f32),
            };
            let split = match children_of_old {
                Some(_) => true,
                None => count > threshold && leaves_left > 0,
            };
            if split {
                if children_of_old.is_none() {
                    leaves_left -= 1;
                }
                let c = g.spatial.len();
                g.spatial[new].children = c as u32;
                let ax = match children_of_old {
                    Some(_) => o.axis,
                    None => axis,
                };
                g.spatial[new].axis = ax;
                for k in 0..2 {
                    g.spatial.push(SpatialNode {
                        children: 0,
                        axis: 0,
                        leaf: 0,
                    });
                    let next_axis = (ax + 1) % 3;
                    match children_of_old {
                        Some(oc) => stack.push((oc + k, c + k, next_axis, None)),
                        // A new split: both halves copy this leaf, with half its records.
                        None => stack.push((old, c + k, next_axis, Some(count / 2.0))),
                    }
                }
            } else {
                g.spatial[new].leaf = pending.len() as u32;
                g.spatial[new].axis = axis;
                let old_leaf = if o.children == 0 {
                    o.leaf
                } else {
                    unreachable!("an old inner node is always split")
                };
                pending.push(Pending { old_leaf });
            }
        }
        // Directional trees, each leaf with an equal share of the node budget.
        let per_leaf = (MAX_QUAD_NODES / pending.len().max(1)).max(1);
        for pl in &pending {
            let ol = self.leaves[pl.old_leaf as usize];
            let s = self.quads[ol.root as usize].sum;
            let t = s[0] + s[1] + s[2] + s[3];
            let share = if t > 0.0 { s.map(|x| x / t) } else { [0.25; 4] };
            let mut budget = per_leaf - 1;
            let root = g.refine_quad(&self.quads, Some(ol.root as usize), share, 0, &mut budget);
            g.leaves.push(Leaf {
                root,
                count: 0,
                ..ol
            });
        }
        g
    }
}

/// The training state of a render: the guide paths sample with (none before the first
/// iteration ends) and the tree the current iteration's records go into.
#[derive(Clone, Debug)]
pub struct Learner {
    guide: Option<std::sync::Arc<Guide>>,
    building: Guide,
    /// Iterations learned so far (the filters' jitter differs from one to the next).
    iteration: u64,
}

impl Learner {
    /// A learner for a scene within `min..max`.
    pub fn new(min: Vec3, max: Vec3) -> Learner {
        Learner {
            guide: None,
            building: Guide::new(min, max),
            iteration: 0,
        }
    }

    /// The guide learned so far.
    pub fn guide(&self) -> Option<std::sync::Arc<Guide>> {
        self.guide.clone()
    }

    /// Ends a training iteration of `spp` samples per pixel whose records are `records`, in
    /// their fixed order: the BSDF shares take their Adam steps, the records are splatted (the
    /// radiance divided by the density the direction was drawn with, an estimate of the
    /// radiance integrated over each quadrant), the filled tree becomes the guide and its
    /// refinement the next iteration's tree.
    ///
    /// Splatting filters each record over a box the size of the cell it falls in, spatially and
    /// directionally (Müller 2019, "Practical Path Guiding in Production"), stochastically:
    /// the record lands at one point drawn uniformly in the box (the spatial leaf's extent
    /// centred on its position, the leaf quadrant's side centred on its direction, φ wrapping
    /// around), whose expectation is the box filter's splat. Neighbouring cells then share what
    /// their records saw, which a tree trained on few records per cell needs.
    ///
    /// In parallel on the current rayon pool, bit for bit the serial result: where each record
    /// lands (its leaf, the filtered target leaf and square point, a function of the record and
    /// its index alone) is found for all records in parallel; then each spatial leaf, whose
    /// Adam state and quadtree nodes no other leaf touches, takes its records' Adam steps and
    /// splats in record order, the leaves in parallel. Every float sum therefore adds the same
    /// terms in the same order as one loop over the records would.
    pub fn learn<'r>(&mut self, records: impl IntoIterator<Item = &'r Record>, spp: u32) {
        use rayon::prelude::*;
        self.iteration += 1;
        let key = mix64(self.iteration.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        let filter = !knob_off("filter");
        let records: Vec<&Record> = records.into_iter().collect();
        let b = &self.building;
        let n_leaves = b.leaves.len();
        let splats: Vec<Splat> = records
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .map(|(i, r)| b.place(r, i as u64, key, filter))
            .collect();
        // The gradients by leaf (for Adam) and the splats by target leaf, each in record order.
        let adam = group(n_leaves, splats.iter().map(Splat::adam));
        let dep = group(n_leaves, splats.iter().map(Splat::deposit));
        let b = &mut self.building;
        // Each leaf's quadtree nodes are one contiguous run of `quads`, from its root to the
        // next leaf's root: `Guide::new` and `refined`, the only builders of a tree, lay each
        // leaf's quadtree out depth-first after the previous one's. Split them apart.
        let roots: Vec<usize> = b.leaves.iter().map(|l| l.root as usize).collect();
        assert!(
            roots.first() == Some(&0) && roots.windows(2).all(|w| w[0] < w[1]),
            "the leaves' quadtrees are laid out one after another"
        );
        let mut jobs = Vec::with_capacity(n_leaves);
        let mut rest: &mut [QuadNode] = &mut b.quads[..];
        let total = rest.len();
        for (k, leaf) in b.leaves.iter_mut().enumerate() {
            let (start, end) = (roots[k], roots.get(k + 1).copied().unwrap_or(total));
            let (mine, tail) = std::mem::take(&mut rest).split_at_mut(end - start);
            rest = tail;
            let (a, d) = (adam.of(k), dep.of(k));
            if !a.is_empty() || !d.is_empty() {
                jobs.push((leaf, mine, start, a, d));
            }
        }
        jobs.into_par_iter()
            .for_each(|(leaf, quads, base, a, d)| learn_leaf(leaf, quads, base, a, d));
        let next = self.building.refined(spp);
        let next_count = next.leaves.len();
        let filled = std::mem::replace(&mut self.building, next);
        if std::env::var_os("TRAYECTO_GUIDING_LOG").is_some() {
            // What the iteration learned (`bench/guiding.py --log`).
            let with_flux = filled
                .leaves
                .iter()
                .filter(|l| filled.quads[l.root as usize].sum.iter().sum::<f32>() > 0.0)
                .count();
            let alpha: f32 = filled
                .leaves
                .iter()
                .map(|l| sigmoid(l.theta).clamp(ALPHA_MIN, ALPHA_MAX))
                .sum::<f32>()
                / filled.leaves.len() as f32;
            let records: u32 = filled.leaves.iter().map(|l| l.count).sum();
            eprintln!(
                "guiding: iteration of {spp} spp: {records} records, {} leaves ({with_flux} with radiance), {} quadtree nodes, mean BSDF share {alpha:.3}; next tree {next_count} leaves",
                filled.leaves.len(),
                filled.quads.len(),
            );
        }
        self.guide = Some(std::sync::Arc::new(filled));
    }
}

/// Where one record lands ([`Guide::place`]): its spatial leaf (`u32::MAX` for a record left
/// out), the leaf its filtered splat goes to, the square point there and the value (0: nothing
/// to splat), and its Adam gradient ([`adam_gradient`]; NaN: no step).
#[derive(Clone, Copy, Debug)]
struct Splat {
    leaf: u32,
    target: u32,
    at: Vec2,
    value: f32,
    grad: f32,
}

impl Splat {
    fn adam(&self) -> Option<(u32, f32)> {
        (self.leaf != u32::MAX && !self.grad.is_nan()).then_some((self.leaf, self.grad))
    }

    fn deposit(&self) -> Option<(u32, (Vec2, f32))> {
        (self.target != u32::MAX).then_some((self.target, (self.at, self.value)))
    }
}

/// Values grouped by leaf, each group in record order: a counting sort, whose scatter reads
/// the splats in order and writes one run per leaf, so that each leaf's learning then reads its
/// values contiguously (reading the records of a leaf where they lie, scattered over the
/// iteration's, was a cache miss per record: most of the learning's time).
struct Groups<T> {
    start: Vec<u32>,
    vals: Vec<T>,
}

impl<T> Groups<T> {
    fn of(&self, k: usize) -> &[T] {
        &self.vals[self.start[k] as usize..self.start[k + 1] as usize]
    }
}

fn group<T: Copy + Default>(
    n: usize,
    items: impl Iterator<Item = Option<(u32, T)>> + Clone,
) -> Groups<T> {
    let mut start = vec![0u32; n + 1];
    for (k, _) in items.clone().flatten() {
        start[k as usize + 1] += 1;
    }
    for k in 0..n {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut vals = vec![T::default(); start[n] as usize];
    for (k, v) in items.flatten() {
        vals[fill[k as usize] as usize] = v;
        fill[k as usize] += 1;
    }
    Groups { start, vals }
}

/// One leaf's share of an iteration ([`Learner::learn`]): the Adam steps of the records in its
/// cell (their gradients `adam`) and the splats of those filtered into it (`dep`: square point
/// and value), each in record order, into its quadtree `quads` (the nodes from index `base` on).
fn learn_leaf(
    leaf: &mut Leaf,
    quads: &mut [QuadNode],
    base: usize,
    adam: &[f32],
    dep: &[(Vec2, f32)],
) {
    for &g in adam {
        adam_step(leaf, g);
    }
    for &(at, value) in dep {
        leaf.count = leaf.count.saturating_add(1);
        if value > 0.0 {
            // Adds the value to every node on the path to the square point.
            let mut n = leaf.root as usize;
            let mut p = at;
            for _ in 0..=MAX_DEPTH {
                let (ix, iy) = ((p.x >= 0.5) as usize, (p.y >= 0.5) as usize);
                let q = ix + 2 * iy;
                let node = &mut quads[n - base];
                node.sum[q] += value;
                let c = node.child[q];
                if c == 0 {
                    break;
                }
                n = c as usize;
                p = Vec2::new(p.x * 2.0 - ix as f32, p.y * 2.0 - iy as f32);
            }
        }
    }
}

/// The gradient of the KL divergence from the normalized product F = f·Lᵢ·cos to the mixture
/// q = α·p_bsdf + (1−α)·p_guide with respect to α, estimated with a record drawn from the
/// mixture (Müller 2019 §10.2): −(F/q)·(p_bsdf − p_guide)/q. [`adam_step`] multiplies it by
/// dα/dθ.
fn adam_gradient(r: &Record) -> f32 {
    -(r.f_cos * r.radiance / r.pdf) * (r.pdf_bsdf - r.pdf_guide) / r.pdf
}

/// One Adam step on a leaf's BSDF share with a record's gradient `g` ([`adam_gradient`]).
fn adam_step(l: &mut Leaf, g: f32) {
    let a = sigmoid(l.theta);
    let g = g * a * (1.0 - a);
    if !g.is_finite() {
        return;
    }
    l.b1t *= ADAM_B1;
    l.b2t *= ADAM_B2;
    l.m = ADAM_B1 * l.m + (1.0 - ADAM_B1) * g;
    l.v = ADAM_B2 * l.v + (1.0 - ADAM_B2) * g * g;
    let mh = l.m / (1.0 - l.b1t);
    let vh = l.v / (1.0 - l.b2t);
    // θ stays where the clamp still answers to it.
    l.theta = (l.theta - ADAM_LR * mh / (vh.sqrt() + 1e-8)).clamp(-4.0, 4.0);
}

/// Diagnostic counters (`TRAYECTO_GUIDING_DIAG=1`, printed at the end of a render): guide
/// samples drawn, those whose direction the BSDF does not reflect into (f = 0: the path ends),
/// and the splatted flux above and below each record's tree normal. They checked that the guide
/// does not aim below the surface (BENCHMARKS.md, "Path guiding").
pub static DIAG: [std::sync::atomic::AtomicU64; 4] = [
    std::sync::atomic::AtomicU64::new(0),
    std::sync::atomic::AtomicU64::new(0),
    std::sync::atomic::AtomicU64::new(0),
    std::sync::atomic::AtomicU64::new(0),
];
/// Whether [`DIAG`] counts (read once).
pub fn diag_on() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var_os("TRAYECTO_GUIDING_DIAG").is_some())
}

/// Whether a vertex with this BSDF is guided: a guide cannot help a Dirac lobe, and the
/// transmissive BSDFs (glass, hair, thin sheets) are left to their own sampling, which knows
/// the η crossed.
#[inline]
pub fn guidable(bsdf: &Bsdf) -> bool {
    !bsdf.is_specular() && !bsdf.is_transmissive() && !bsdf.is_black()
}

/// What [`sample_mixture`] drew: the sample in the local frame (its `pdf` the mixture's, or for
/// a Dirac lobe the lobe's probability times the BSDF's share), the world direction, and the
/// densities a training record needs.
#[derive(Clone, Copy, Debug)]
pub struct MixSample {
    pub bs: BsdfSample,
    pub wi: Vec3,
    pub pdf_bsdf: f32,
    pub pdf_guide: f32,
}

/// One-sample MIS between the BSDF and the guide (Müller 2017 §5.1 with the learned share):
/// `u_pick` < α samples the BSDF (with the rescaled number as its lobe choice), otherwise the
/// guide; either way the sample's density is the mixture's α·p_bsdf + (1 − α)·p_guide, so the
/// estimate f·cos/q is unbiased wherever the BSDF is non-zero. `None` when the BSDF sample fails
/// or the guide's direction carries no BSDF value.
#[inline]
pub fn sample_mixture(
    bsdf: &Bsdf,
    frame: &Frame,
    wo_local: Vec3,
    mix: &Mix,
    u_pick: f32,
    u: Vec2,
) -> Option<MixSample> {
    let a = mix.alpha;
    if u_pick < a {
        let bs = bsdf.sample(wo_local, (u_pick / a).min(1.0 - f32::EPSILON / 2.0), u)?;
        let wi = frame.to_world(bs.wi);
        if bs.specular {
            // Only the BSDF produces a Dirac direction: its estimate divides by α as well.
            return Some(MixSample {
                bs: BsdfSample {
                    pdf: bs.pdf * a,
                    ..bs
                },
                wi,
                pdf_bsdf: bs.pdf,
                pdf_guide: 0.0,
            });
        }
        let pg = mix.guide.pdf(mix.leaf, wi);
        Some(MixSample {
            bs: BsdfSample {
                pdf: a * bs.pdf + (1.0 - a) * pg,
                ..bs
            },
            wi,
            pdf_bsdf: bs.pdf,
            pdf_guide: pg,
        })
    } else {
        let (wi, pg) = mix.guide.sample_pdf(mix.leaf, u);
        let wl = frame.to_local(wi);
        let f = bsdf.eval(wo_local, wl);
        if diag_on() {
            DIAG[0].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if f == Vec3::ZERO {
                DIAG[1].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
        }
        if f == Vec3::ZERO {
            return None;
        }
        let pb = bsdf.pdf(wo_local, wl);
        let pdf = a * pb + (1.0 - a) * pg;
        if !(pdf > 0.0) {
            return None;
        }
        Some(MixSample {
            bs: BsdfSample {
                wi: wl,
                f,
                pdf,
                specular: false,
                eta: 1.0,
            },
            wi,
            pdf_bsdf: pb,
            pdf_guide: pg,
        })
    }
}

/// One-sample MIS between a medium's phase function and the guide (volume path guiding,
/// Herholz et al. 2019, with the learned share as at surfaces), for light travelling along
/// `d_in`: `u_pick` < α samples the phase function, otherwise the guide. Returns the direction
/// leaving the vertex, the mixture's density, and the phase function's and the guide's densities
/// there. The estimate multiplies by p_phase/q: unbiased since the phase function is positive
/// everywhere.
#[inline]
pub fn sample_phase_mixture(
    phase: &HenyeyGreenstein,
    d_in: Vec3,
    mix: &Mix,
    u_pick: f32,
    u: Vec2,
) -> (Vec3, f32, f32, f32) {
    let d = if u_pick < mix.alpha {
        phase.sample(d_in, u).d_out
    } else {
        mix.guide.sample(mix.leaf, u)
    };
    let pp = phase.eval(d_in, d);
    let pg = mix.guide.pdf(mix.leaf, d);
    (d, mix.alpha * pp + (1.0 - mix.alpha) * pg, pp, pg)
}

/// The phase–guide mixture's density at the leaving direction `d` ([`sample_phase_mixture`]).
#[inline]
pub fn phase_mixture_pdf(phase: &HenyeyGreenstein, d_in: Vec3, d: Vec3, mix: &Mix) -> f32 {
    mix.alpha * phase.eval(d_in, d) + (1.0 - mix.alpha) * mix.guide.pdf(mix.leaf, d)
}

/// The mixture's density at the local direction `wl` (world `wi`): what next-event estimation
/// weighs its light samples against at a guided vertex.
#[inline]
pub fn mixture_pdf(bsdf: &Bsdf, wo_local: Vec3, wl: Vec3, wi: Vec3, mix: &Mix) -> f32 {
    mix.alpha * bsdf.pdf(wo_local, wl) + (1.0 - mix.alpha) * mix.guide.pdf(mix.leaf, wi)
}

/// A vertex waiting for the radiance its continuation brings back: the path's radiance and
/// throughput when it chose its direction.
#[derive(Clone, Copy, Debug)]
pub struct Pending {
    pub record: Record,
    pub l_before: Vec3,
    pub beta_after: Vec3,
    /// What the emitter found by this vertex's direction added to the path (left out of the
    /// record's radiance: [`learns_direct`]).
    pub direct: Vec3,
}

/// Whether the records carry the direct light (the emitter a direction hits, and the light
/// samples) besides the indirect. Off by default: next-event estimation already samples the
/// lights, and a guide that learns them too sends its samples where NEE went, while its density
/// there takes MIS weight from NEE's light samples (measured: BENCHMARKS.md "Path guiding").
/// `TRAYECTO_GUIDING_DIRECT=1` learns them (a benchmarking knob).
pub fn learns_direct() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var_os("TRAYECTO_GUIDING_DIRECT").is_some())
}

/// Whether Russian roulette at a guided vertex judges the path by the throughput BSDF sampling
/// would have given it (β·q/p_bsdf) rather than β: a guided direction toward bright light has a
/// small β (its density q is high) precisely because much light comes back along it, and
/// roulette on β would end most of those paths, undoing the guide (`TRAYECTO_GUIDING_OFF=rr`
/// keeps roulette on β).
pub fn rr_as_bsdf() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| !knob_off("rr"))
}

/// What a guided path needs: the guide (none in the first training iteration), and while
/// training, where its records go. `pending` is scratch storage reused path after path.
#[derive(Debug, Default)]
pub struct Guiding<'a> {
    pub guide: Option<&'a Guide>,
    pub records: Option<&'a mut Vec<Record>>,
    pub pending: Vec<Pending>,
}

/// Paths record at most this many vertices each (deeper ones carry little radiance).
pub const MAX_RECORDED_VERTICES: usize = 16;

impl Guiding<'_> {
    /// Ends a path whose radiance came to `l`: each recorded vertex's incident radiance is what
    /// the path gathered after it, divided by the throughput up to it.
    pub fn finish(&mut self, l: Vec3) {
        if let Some(out) = self.records.as_deref_mut() {
            for p in self.pending.drain(..) {
                let li = (l - p.l_before - p.direct) / p.beta_after;
                let li = luminance(Vec3::select(p.beta_after.cmpgt(Vec3::ZERO), li, Vec3::ZERO));
                if li.is_finite() {
                    out.push(Record {
                        radiance: li.max(0.0),
                        ..p.record
                    });
                }
            }
        }
        self.pending.clear();
    }
}
