//! A light BVH for scenes with many emitters: Conty Estevez & Kulla 2018, "Importance Sampling of
//! Many Lights with Adaptive Tree Splitting", in the form of pbrt-v4's `BVHLightSampler`
//! (Pharr, Jakob & Humphreys, PBRT 4th ed., §12.6.3).
//!
//! Every bounded light (an emissive primitive, a point or a spot) gets a [`LightBounds`]: a box,
//! its power φ and an orientation cone — the directions of its normals (axis `w`, half-angle θo)
//! widened by θe, the angle past the normals at which it still emits. A binary tree is built over
//! them with pbrt's cost (power × orientation-cone measure M_Ω × box area, §12.6.3 eq. 12.6 and the
//! regularisation K_r), and every interior node keeps the union of its children's bounds.
//!
//! The binary tree is flattened into a four-way tree (the default, [`TreeWidth::Four`]; a node's
//! children are its binary grandchildren, [`ChildQuad`]) or an eight-way one
//! ([`TreeWidth::Eight`], `--light-sampler bvh8`: its great-grandchildren, [`ChildOct`]); a leaf child
//! higher up takes one slot itself. Sampling walks down from the root: at each node the
//! children are given an importance as seen from the shading point (φ · cos θ′ / d², times
//! cos θ′ᵢ for the receiver's normal, [`LightBounds::importance`]), all in one SIMD evaluation,
//! and one is chosen in proportion to it, reusing the random number. Unlike pbrt, which chooses
//! between the two children at every binary level, the choice uses the tighter boxes two or
//! three levels down directly and skips the coarser levels: fewer evaluations (four-way vs
//! pbrt: on compare.py's manylight scene 11 % fewer instructions per sample with 2.4 % lower
//! relMSE at 64 spp, BENCHMARKS.md "Light BVH descent"; eight-way vs four-way: the
//! light choice measurements there). The probability of a light is the product of the choices along its path,
//! and [`LightBvh::pmf`] recomputes it exactly — the same function of the same numbers — by
//! walking the light's recorded path (its trail, two or three bits
//! per level), so MIS weights use the probability with which the light was really sampled.

use crate::geometry::Bounds3;
use crate::math::{PI, Vec3, Vec4};
use glam::BVec4A;

/// Below this depth the tree is split by pbrt's cost; past it by count, so that no path is
/// longer than 64 steps (its trail is a `u64`) for up to 2³² lights.
const COST_SPLIT_DEPTH: usize = 30;
/// Buckets per axis for the cost evaluation (pbrt uses 12).
const BUCKETS: usize = 12;
/// Importances are clamped below this so that the sum of two stays finite.
const MAX_IMPORTANCE: f32 = 1e30;

/// The spatial and directional extent of a light's emission (pbrt's `LightBounds`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    pub bounds: Bounds3,
    /// Emitted power (any consistent scale: only ratios matter).
    pub phi: f32,
    /// Axis of the normals' cone (unit).
    pub w: Vec3,
    /// Cosine of the half-angle θo of the normals' cone (−1: all directions).
    pub cos_theta_o: f32,
    /// Cosine of θe, the angle beyond the normals at which light is still emitted (0 for a
    /// Lambertian surface: it emits up to 90° from its normal).
    pub cos_theta_e: f32,
    /// Emits on both sides of its normals.
    pub two_sided: bool,
}

/// cos(max(0, a − b)) from the sines and cosines of a and b (pbrt's `cosSubClamped`).
#[inline]
fn cos_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        1.0
    } else {
        cos_a * cos_b + sin_a * sin_b
    }
}

/// sin(max(0, a − b)) (pbrt's `sinSubClamped`).
#[inline]
fn sin_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        0.0
    } else {
        sin_a * cos_b - cos_a * sin_b
    }
}

#[inline]
fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

#[inline]
fn safe_acos(x: f32) -> f32 {
    x.clamp(-1.0, 1.0).acos()
}

impl LightBounds {
    /// Bounds of a light of power `phi` in `bounds` that emits in every direction (a point; an
    /// emitter with no single normal, whose Lambertian emission reaches 90° from each normal).
    pub fn all_around(bounds: Bounds3, phi: f32) -> LightBounds {
        LightBounds {
            bounds,
            phi,
            w: Vec3::Z,
            cos_theta_o: -1.0,
            cos_theta_e: 0.0,
            two_sided: false,
        }
    }

    /// Unnormalised importance of these lights for a receiver at `p` with normal `n` (zero
    /// vector: a point in a medium, no cosine), pbrt-v4 `LightBounds::Importance`: the largest
    /// cosine the box can present within the emission cone, over d² (clamped below by half the
    /// box's diagonal so that a receiver inside a cluster does not blow it up), times the largest
    /// cosine at the receiver. Zero only where no light of the box can reach `p` from the side
    /// its cone allows. Never NaN, never infinite.
    #[inline]
    pub fn importance(&self, p: Vec3, n: Vec3) -> f32 {
        let pc = (self.bounds.min + self.bounds.max) * 0.5;
        let diag = (self.bounds.max - self.bounds.min).length();
        let d2 = p.distance_squared(pc).max(diag * 0.5);
        // Direction from the lights to the receiver.
        let wi = (p - pc).normalize_or_zero();
        let mut cos_w = self.w.dot(wi);
        if self.two_sided {
            cos_w = cos_w.abs();
        }
        let sin_w = safe_sqrt(1.0 - cos_w * cos_w);
        // Half-angle θb of the cone of directions from p to the box's bounding sphere.
        let r2 = diag * diag * 0.25;
        let dc2 = p.distance_squared(pc);
        let cos_b = if dc2 < r2 || !(dc2 > 0.0) {
            -1.0
        } else {
            safe_sqrt(1.0 - r2 / dc2)
        };
        let sin_b = safe_sqrt(1.0 - cos_b * cos_b);
        // θ′ = max(0, θw − θo − θb): the smallest angle between an emitting normal and a
        // direction toward p.
        let sin_o = safe_sqrt(1.0 - self.cos_theta_o * self.cos_theta_o);
        let cos_x = cos_sub_clamped(sin_w, cos_w, sin_o, self.cos_theta_o);
        let sin_x = sin_sub_clamped(sin_w, cos_w, sin_o, self.cos_theta_o);
        let cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
        if cos_p <= self.cos_theta_e {
            return 0.0;
        }
        let mut importance = self.phi * cos_p / d2;
        if n != Vec3::ZERO {
            // The receiver's cosine, at its most favourable within the box's cone.
            let cos_i = wi.dot(n).abs();
            let sin_i = safe_sqrt(1.0 - cos_i * cos_i);
            importance *= cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
        }
        if importance > 0.0 {
            importance.min(MAX_IMPORTANCE)
        } else {
            // Also NaN (degenerate input).
            0.0
        }
    }

    /// The bounds of two sets of lights together (pbrt's `Union(LightBounds, LightBounds)`).
    pub fn union(&self, o: &LightBounds) -> LightBounds {
        if self.phi == 0.0 {
            return *o;
        }
        if o.phi == 0.0 {
            return *self;
        }
        let (w, cos_theta_o) = cone_union(self.w, self.cos_theta_o, o.w, o.cos_theta_o);
        LightBounds {
            bounds: self.bounds.union(&o.bounds),
            phi: self.phi + o.phi,
            w,
            cos_theta_o,
            cos_theta_e: self.cos_theta_e.min(o.cos_theta_e),
            two_sided: self.two_sided || o.two_sided,
        }
    }

    /// pbrt's surface-area-orientation cost of a node (§12.6.3): φ · M_Ω · area · K_r, with M_Ω
    /// the integral of the cone's cosine-weighted solid angle and K_r the ratio of the longest
    /// extent of `parent` to its extent along `axis`.
    fn cost(&self, parent: &Bounds3, axis: usize) -> f32 {
        let theta_o = safe_acos(self.cos_theta_o);
        let theta_e = safe_acos(self.cos_theta_e);
        let theta_w = (theta_o + theta_e).min(PI);
        let sin_o = safe_sqrt(1.0 - self.cos_theta_o * self.cos_theta_o);
        let m_omega = 2.0 * PI * (1.0 - self.cos_theta_o)
            + PI / 2.0
                * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o
                    + self.cos_theta_o);
        let d = parent.diagonal();
        let kr = d.max_element() / d[axis].max(f32::MIN_POSITIVE);
        self.phi * m_omega * kr * self.bounds.surface_area()
    }
}

/// The smallest cone (axis, cos half-angle) holding two cones (pbrt's `DirectionCone::Union`),
/// widened by a thousandth of a radian so that rounding in the rotation cannot leave a normal
/// outside it.
fn cone_union(wa: Vec3, cos_a: f32, wb: Vec3, cos_b: f32) -> (Vec3, f32) {
    let theta_a = safe_acos(cos_a);
    let theta_b = safe_acos(cos_b);
    let theta_d = safe_acos(wa.dot(wb));
    if (theta_d + theta_b).min(PI) <= theta_a {
        return (wa, cos_a);
    }
    if (theta_d + theta_a).min(PI) <= theta_b {
        return (wb, cos_b);
    }
    let theta_o = (theta_a + theta_d + theta_b) * 0.5 + 1e-3;
    if theta_o >= PI {
        return (Vec3::Z, -1.0);
    }
    let theta_r = theta_o - theta_a;
    let axis = wa.cross(wb);
    if !(axis.length_squared() > 1e-12) {
        return (Vec3::Z, -1.0);
    }
    let k = axis.normalize();
    // Rodrigues' rotation of wa about k (⊥ wa) by θr.
    let w = (wa * theta_r.cos() + k.cross(wa) * theta_r.sin()).normalize_or_zero();
    if w == Vec3::ZERO {
        return (Vec3::Z, -1.0);
    }
    (w, theta_o.cos())
}

/// No child in this slot of a [`ChildQuad`] (its lane has zero power, so it is never chosen).
const NO_CHILD: u32 = u32::MAX;
/// A [`ChildQuad::children`] entry with this bit set is a leaf: the light (its index in the light
/// set) is the other 31 bits. Without it, the entry is the child's index in [`LightBvh::quads`].
const LEAF_BIT: u32 = 1 << 31;

/// The bounds of an interior node's children side by side in SIMD lanes (four for the four-way
/// tree's [`ChildQuad`], eight for the eight-way tree's [`ChildOct`]), with the parts of
/// [`LightBounds::importance`] that depend only on the node precomputed (box centre, half
/// diagonal, squared bounding-sphere radius, sin θo); an empty slot has zero power.
/// [`BoundsLanes::importance_lanes`] gives the children's importance in one pass with the same
/// IEEE operations in the same order as the scalar function (bit for bit, unit tests check it
/// for both widths and every lane type).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct BoundsLanes<const N: usize> {
    cx: [f32; N],
    cy: [f32; N],
    cz: [f32; N],
    /// |diagonal| / 2: the floor of d².
    half_diag: [f32; N],
    /// |diagonal|² / 4: the squared radius of the box's bounding sphere.
    r2: [f32; N],
    wx: [f32; N],
    wy: [f32; N],
    wz: [f32; N],
    cos_o: [f32; N],
    sin_o: [f32; N],
    cos_e: [f32; N],
    phi: [f32; N],
    /// 1 for a two-sided child, else 0.
    two_sided: [f32; N],
}

impl<const N: usize> BoundsLanes<N> {
    /// The lanes of `slots` (one to `N` bounds); empty lanes repeat the first bounds with zero
    /// power, so their importance is 0.
    fn new(slots: &[LightBounds]) -> BoundsLanes<N> {
        let mut lb = [slots[0]; N];
        for (k, l) in lb.iter_mut().enumerate() {
            match slots.get(k) {
                Some(s) => *l = *s,
                None => l.phi = 0.0,
            }
        }
        // The same expressions as `LightBounds::importance`, so the values are bit-identical.
        let centre = |lb: &LightBounds| (lb.bounds.min + lb.bounds.max) * 0.5;
        let diag = |lb: &LightBounds| (lb.bounds.max - lb.bounds.min).length();
        let lanes = |f: &dyn Fn(&LightBounds) -> f32| lb.map(|l| f(&l));
        BoundsLanes {
            cx: lanes(&|lb| centre(lb).x),
            cy: lanes(&|lb| centre(lb).y),
            cz: lanes(&|lb| centre(lb).z),
            half_diag: lanes(&|lb| diag(lb) * 0.5),
            r2: lanes(&|lb| {
                let d = diag(lb);
                d * d * 0.25
            }),
            wx: lanes(&|lb| lb.w.x),
            wy: lanes(&|lb| lb.w.y),
            wz: lanes(&|lb| lb.w.z),
            cos_o: lanes(&|lb| lb.cos_theta_o),
            sin_o: lanes(&|lb| safe_sqrt(1.0 - lb.cos_theta_o * lb.cos_theta_o)),
            cos_e: lanes(&|lb| lb.cos_theta_e),
            phi: lanes(&|lb| lb.phi),
            two_sided: lanes(&|lb| if lb.two_sided { 1.0 } else { 0.0 }),
        }
    }

    /// [`LightBounds::importance`] of lanes `off..off + width of L`, step for step.
    #[inline(always)]
    fn importance_lanes<L: Lanes>(&self, off: usize, p: Vec3, n: Vec3) -> L {
        let ld = |a: &[f32; N]| L::load(a, off);
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let safe_sqrt = |x: L| x.max(zero).sqrt();
        let cos_sub = |sin_a: L, cos_a: L, sin_b: L, cos_b: L| {
            L::select(cos_a.gt(cos_b), one, cos_a * cos_b + sin_a * sin_b)
        };
        let sin_sub = |sin_a: L, cos_a: L, sin_b: L, cos_b: L| {
            L::select(cos_a.gt(cos_b), zero, sin_a * cos_b - cos_a * sin_b)
        };
        // v = p − centre; dc2 = |v|² as `Vec3::distance_squared` sums it.
        let vx = L::splat(p.x) - ld(&self.cx);
        let vy = L::splat(p.y) - ld(&self.cy);
        let vz = L::splat(p.z) - ld(&self.cz);
        let dc2 = vx * vx + vy * vy + vz * vz;
        let d2 = dc2.max(ld(&self.half_diag));
        // `normalize_or_zero`: v · (1/|v|) if that reciprocal is finite and positive, else 0.
        // Here v · 0 instead: it differs from 0 only in the sign of zeros (a finite v with dc2
        // 0 or ∞), which no later step can tell apart (the unit tests cover p at a centre).
        let rcp = one / dc2.sqrt();
        let ok = rcp.lt(L::splat(f32::INFINITY)) & rcp.gt(zero);
        let rcp = L::select(ok, rcp, zero);
        let (wix, wiy, wiz) = (vx * rcp, vy * rcp, vz * rcp);
        let cos_w = ld(&self.wx) * wix + ld(&self.wy) * wiy + ld(&self.wz) * wiz;
        let cos_w = L::select(ld(&self.two_sided).gt(zero), cos_w.abs(), cos_w);
        let sin_w = safe_sqrt(one - cos_w * cos_w);
        let r2 = ld(&self.r2);
        let inside = dc2.lt(r2) | !dc2.gt(zero);
        let cos_b = L::select(inside, L::splat(-1.0), safe_sqrt(one - r2 / dc2));
        let sin_b = safe_sqrt(one - cos_b * cos_b);
        let (sin_o, cos_o) = (ld(&self.sin_o), ld(&self.cos_o));
        let cos_x = cos_sub(sin_w, cos_w, sin_o, cos_o);
        let sin_x = sin_sub(sin_w, cos_w, sin_o, cos_o);
        let cos_p = cos_sub(sin_x, cos_x, sin_b, cos_b);
        let mut importance = ld(&self.phi) * cos_p / d2;
        if n != Vec3::ZERO {
            let cos_i = (wix * L::splat(n.x) + wiy * L::splat(n.y) + wiz * L::splat(n.z)).abs();
            let sin_i = safe_sqrt(one - cos_i * cos_i);
            importance = importance * cos_sub(sin_i, cos_i, sin_b, cos_b);
        }
        // Zero where the cone test fails, and for zero or NaN importance.
        let keep = !cos_p.le(ld(&self.cos_e)) & importance.gt(zero);
        L::select(keep, importance.min(L::splat(MAX_IMPORTANCE)), zero)
    }
}

/// An interior node of the four-way tree: its (up to) four children's bounds in SSE lanes
/// ([`BoundsLanes`]) and their indices. The node *is* its `ChildQuad`: the children's indices
/// sit beside their bounds, so a descent step reads one 256-byte, cache-line-aligned block (four
/// lines) and no separate node array.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct ChildQuad {
    lanes: BoundsLanes<4>,
    /// Per lane: the child's index in [`LightBvh::quads`], or [`LEAF_BIT`] | its light, or
    /// [`NO_CHILD`].
    children: [u32; 4],
}

/// √x per lane, an exactly rounded IEEE square root like `f32::sqrt`.
#[inline(always)]
fn sqrt4(v: Vec4) -> Vec4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        // SAFETY: `sqrtps` needs SSE, which this cfg guarantees (x86_64's baseline). The
        // intrinsic is one instruction; four scalar square roots with the lane extraction and
        // re-insertion around them cost ~12, and this runs five times per descent step.
        unsafe { Vec4::from(std::arch::x86_64::_mm_sqrt_ps(v.into())) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        Vec4::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt(), v.w.sqrt())
    }
}

impl ChildQuad {
    fn new(slots: &[LightBounds]) -> ChildQuad {
        ChildQuad {
            lanes: BoundsLanes::new(slots),
            children: [NO_CHILD; 4],
        }
    }

    /// The four children's [`LightBounds::importance`] in one SSE pass.
    #[inline(always)]
    fn importance(&self, p: Vec3, n: Vec3) -> Vec4 {
        self.lanes.importance_lanes(0, p, n)
    }
}

/// Children per interior node of the light tree (`--light-sampler bvh`: four, `bvh8`: eight).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TreeWidth {
    /// A node's children are its binary grandchildren ([`ChildQuad`], one SSE pass per step).
    #[default]
    Four,
    /// A node's children are its binary great-grandchildren ([`ChildOct`], one AVX 256-bit
    /// pass per step where the CPU has AVX2, two SSE halves giving the same bits elsewhere):
    /// log₈ instead of log₄ steps, each choosing by the tighter boxes three levels down.
    Eight,
}

/// The lane operations [`oct_importance`] is written in, so that the eight-way step's AVX form
/// ([`Avx8`]) and its portable form (two [`Vec4`] halves) run the same IEEE operations in the
/// same order, lane for lane: the same bits (a unit test checks both against the scalar
/// [`LightBounds::importance`]).
trait Lanes:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
{
    type Mask: Copy
        + std::ops::BitAnd<Output = Self::Mask>
        + std::ops::BitOr<Output = Self::Mask>
        + std::ops::Not<Output = Self::Mask>;
    fn splat(x: f32) -> Self;
    /// Lanes `off..off + width` of `a`.
    fn load(a: &[f32], off: usize) -> Self;
    fn sqrt(self) -> Self;
    /// `maxps(self, o)`: `o` where either is NaN (as glam's `Vec4::max` on SSE).
    fn max(self, o: Self) -> Self;
    fn min(self, o: Self) -> Self;
    fn abs(self) -> Self;
    fn lt(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
}

impl Lanes for Vec4 {
    type Mask = BVec4A;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Vec4::splat(x)
    }
    #[inline(always)]
    fn load(a: &[f32], off: usize) -> Self {
        Vec4::from_slice(&a[off..off + 4])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        sqrt4(self)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Vec4::max(self, o)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        Vec4::min(self, o)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Vec4::abs(self)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> BVec4A {
        self.cmplt(o)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> BVec4A {
        self.cmpgt(o)
    }
    #[inline(always)]
    fn le(self, o: Self) -> BVec4A {
        self.cmple(o)
    }
    #[inline(always)]
    fn select(m: BVec4A, a: Self, b: Self) -> Self {
        Vec4::select(m, a, b)
    }
}

/// Eight f32 lanes in one AVX register. Only ever built inside the `#[target_feature(enable =
/// "avx2")]` copies of the eight-way descent, which run only on CPUs with AVX2: that is the
/// safety argument of every `unsafe` intrinsic call below (the functions are `inline(always)`,
/// so they are compiled into those copies).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx8(std::arch::x86_64::__m256);

#[cfg(target_arch = "x86_64")]
mod avx8 {
    use super::{Avx8, Lanes};
    use std::arch::x86_64::*;

    macro_rules! binop {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl std::ops::$tr for Avx8 {
                type Output = Avx8;
                #[inline(always)]
                fn $f(self, o: Avx8) -> Avx8 {
                    // SAFETY: see `Avx8`.
                    Avx8(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }
    binop!(Add, add, _mm256_add_ps);
    binop!(Sub, sub, _mm256_sub_ps);
    binop!(Mul, mul, _mm256_mul_ps);
    binop!(Div, div, _mm256_div_ps);

    /// A lane mask (all ones or all zeros per lane), as a comparison returns it.
    #[derive(Clone, Copy)]
    pub(super) struct Mask8(__m256);

    impl std::ops::BitAnd for Mask8 {
        type Output = Mask8;
        #[inline(always)]
        fn bitand(self, o: Mask8) -> Mask8 {
            // SAFETY: see `Avx8`.
            Mask8(unsafe { _mm256_and_ps(self.0, o.0) })
        }
    }
    impl std::ops::BitOr for Mask8 {
        type Output = Mask8;
        #[inline(always)]
        fn bitor(self, o: Mask8) -> Mask8 {
            // SAFETY: see `Avx8`.
            Mask8(unsafe { _mm256_or_ps(self.0, o.0) })
        }
    }
    impl std::ops::Not for Mask8 {
        type Output = Mask8;
        #[inline(always)]
        fn not(self) -> Mask8 {
            // SAFETY: see `Avx8`.
            Mask8(unsafe { _mm256_xor_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(-1))) })
        }
    }

    impl Lanes for Avx8 {
        type Mask = Mask8;
        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: see `Avx8`.
            Avx8(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn load(a: &[f32], off: usize) -> Self {
            let a = &a[off..off + 8];
            // SAFETY: see `Avx8`; `a` is eight readable f32 (unaligned load).
            Avx8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            // SAFETY: see `Avx8`.
            Avx8(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            // SAFETY: see `Avx8`. Operand order as `_mm_max_ps` in glam's `Vec4::max`.
            Avx8(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            // SAFETY: see `Avx8`.
            Avx8(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: see `Avx8`. Clears the sign bit, as glam's `Vec4::abs`.
            Avx8(unsafe {
                _mm256_and_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff)))
            })
        }
        #[inline(always)]
        fn lt(self, o: Self) -> Mask8 {
            // SAFETY: see `Avx8`. Ordered: false for NaN, as SSE's `cmpltps`.
            Mask8(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> Mask8 {
            // SAFETY: see `Avx8`.
            Mask8(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn le(self, o: Self) -> Mask8 {
            // SAFETY: see `Avx8`.
            Mask8(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn select(m: Mask8, a: Self, b: Self) -> Self {
            // SAFETY: see `Avx8`. `blendvps` picks by each lane's sign bit: the same lanes
            // for whole-lane masks as and/andnot/or.
            Avx8(unsafe { _mm256_blendv_ps(b.0, a.0, m.0) })
        }
    }

    impl Avx8 {
        #[inline(always)]
        pub(super) fn store(self, out: &mut [f32; 8]) {
            // SAFETY: see `Avx8`; `out` is eight writable f32.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) }
        }
    }
}

/// The eight-way tree's interior node: its (up to) eight children's bounds lane by lane
/// ([`BoundsLanes`], as [`ChildQuad`] for four) and the children's indices. 448 bytes, seven
/// cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct ChildOct {
    lanes: BoundsLanes<8>,
    children: [u32; 8],
}

impl ChildOct {
    fn new(slots: &[LightBounds]) -> ChildOct {
        ChildOct {
            lanes: BoundsLanes::new(slots),
            children: [NO_CHILD; 8],
        }
    }

    /// [`BoundsLanes::importance_lanes`] of this node.
    #[inline(always)]
    fn importance_lanes<L: Lanes>(&self, off: usize, p: Vec3, n: Vec3) -> L {
        self.lanes.importance_lanes(off, p, n)
    }

    /// The eight children's importance: one AVX pass with `AVX2`, else two SSE halves (the
    /// same bits).
    #[cfg(test)]
    #[inline(always)]
    fn importance<const AVX2: bool>(&self, p: Vec3, n: Vec3) -> [f32; 8] {
        let mut out = [0.0f32; 8];
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            self.importance_lanes::<Avx8>(0, p, n).store(&mut out);
            return out;
        }
        let lo: Vec4 = self.importance_lanes(0, p, n);
        let hi: Vec4 = self.importance_lanes(4, p, n);
        lo.write_to_slice(&mut out[..4]);
        hi.write_to_slice(&mut out[4..]);
        out
    }

    /// The probabilities of choosing each child from (`p`, `n`) (importance over the sum, the
    /// sum taken pairwise in a fixed order, the division per lane in one vector operation), or
    /// `None` if no child can light the point.
    #[inline(always)]
    fn probabilities<const AVX2: bool>(&self, p: Vec3, n: Vec3) -> Option<[f32; 8]> {
        let total =
            |c: &[f32; 8]| ((c[0] + c[1]) + (c[2] + c[3])) + ((c[4] + c[5]) + (c[6] + c[7]));
        let mut c = [0.0f32; 8];
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            let imp = self.importance_lanes::<Avx8>(0, p, n);
            imp.store(&mut c);
            let t = total(&c);
            if !(t > 0.0) {
                return None;
            }
            (imp / Avx8::splat(t)).store(&mut c);
            return Some(c);
        }
        let lo: Vec4 = self.importance_lanes(0, p, n);
        let hi: Vec4 = self.importance_lanes(4, p, n);
        lo.write_to_slice(&mut c[..4]);
        hi.write_to_slice(&mut c[4..]);
        let t = total(&c);
        if !(t > 0.0) {
            return None;
        }
        (lo / t).write_to_slice(&mut c[..4]);
        (hi / t).write_to_slice(&mut c[4..]);
        Some(c)
    }
}

/// The light BVH over a scene's bounded lights.
#[derive(Clone, Debug, Default)]
pub struct LightBvh {
    /// The interior nodes of the four-way tree, the root first: each its children's bounds and
    /// indices ([`ChildQuad`]).
    quads: Vec<ChildQuad>,
    /// The interior nodes of the eight-way tree ([`TreeWidth::Eight`]; then `quads` is empty),
    /// the root first.
    octs: Vec<ChildOct>,
    /// Children per interior node.
    width: TreeWidth,
    /// A tree of one light: that light (there are no interior nodes).
    root_leaf: Option<u32>,
    /// Number of lights in the tree.
    lights: usize,
    /// The root's bounds, for a tree of one light (a lone leaf has had no importance test).
    root: Option<LightBounds>,
    /// Per light of the light set: its path from the root (bits 2d and 2d + 1 in the four-way
    /// tree, 3d to 3d + 2 in the eight-way one: the slot taken at depth d), or `None` if the
    /// light is not in the tree.
    trails: Vec<Option<u64>>,
    /// Total power of the lights in the tree.
    pub total_power: f32,
    /// The CPU has AVX2: [`Self::sample_remap`] and [`Self::pmf`] run their AVX2 copies.
    avx2: bool,
}

/// A light being placed in the tree.
#[derive(Clone, Copy)]
struct Item {
    lb: LightBounds,
    centroid: Vec3,
    light: u32,
}

enum Build {
    Leaf(LightBounds, u32),
    Interior(LightBounds, Box<[Build; 2]>),
}

impl Build {
    fn bounds(&self) -> &LightBounds {
        match self {
            Build::Leaf(lb, _) | Build::Interior(lb, _) => lb,
        }
    }
}

impl LightBvh {
    /// Builds the tree over `lights`: (index in the light set, bounds) pairs; lights of zero or
    /// non-finite power or bounds are left out (they can never be chosen). `light_count` is the
    /// size of the light set.
    pub fn new(lights: &[(u32, LightBounds)], light_count: usize) -> LightBvh {
        Self::with_width(lights, light_count, TreeWidth::default())
    }

    /// [`Self::new`] with `width` children per interior node.
    pub fn with_width(
        lights: &[(u32, LightBounds)],
        light_count: usize,
        width: TreeWidth,
    ) -> LightBvh {
        let mut items: Vec<Item> = lights
            .iter()
            .filter(|(_, lb)| {
                lb.phi > 0.0
                    && lb.phi.is_finite()
                    && lb.bounds.min.is_finite()
                    && lb.bounds.max.is_finite()
                    && !lb.bounds.is_empty()
            })
            .map(|&(light, lb)| Item {
                lb,
                centroid: lb.bounds.centroid(),
                light,
            })
            .collect();
        let mut bvh = LightBvh {
            quads: Vec::new(),
            octs: Vec::new(),
            width,
            root_leaf: None,
            lights: items.len(),
            root: None,
            trails: vec![None; light_count],
            total_power: 0.0,
            avx2: crate::math::detect_avx2(),
        };
        if items.is_empty() {
            return bvh;
        }
        let root = build(&mut items, 0);
        bvh.total_power = root.bounds().phi;
        bvh.root = Some(*root.bounds());
        let root = bvh.flatten(&root, 0, 0);
        if root & LEAF_BIT != 0 {
            bvh.root_leaf = Some(root & !LEAF_BIT);
        }
        bvh
    }

    /// Appends `b`'s subtree as four- or eight-way nodes and returns its children entry (its
    /// node index, or [`LEAF_BIT`] | light for a leaf). An interior node of the binary tree takes
    /// its grandchildren (four-way) or great-grandchildren (eight-way) as its children (a leaf
    /// above that depth takes one slot itself), so a descent step chooses among four or eight
    /// boxes at once, by the importance of the tighter boxes two or three levels down, with one
    /// SIMD evaluation for two or three binary levels. A binary tree of depth D gives paths of
    /// ⌈D/2⌉ or ⌈D/3⌉ steps of 2 or 3 trail bits: at most D + 2 ≤ 64 bits for the depths `build`
    /// makes (≤ `COST_SPLIT_DEPTH` + 32 for up to 2³² lights, less one for the root's own split).
    fn flatten(&mut self, b: &Build, trail: u64, depth: u32) -> u32 {
        match b {
            Build::Leaf(_, light) => {
                assert!(
                    *light < LEAF_BIT,
                    "light index {light} does not fit the tree"
                );
                self.trails[*light as usize] = Some(trail);
                LEAF_BIT | *light
            }
            Build::Interior(_, children) => {
                fn collect<'a>(b: &'a Build, levels: u32, slots: &mut Vec<&'a Build>) {
                    match b {
                        Build::Interior(_, g) if levels > 0 => {
                            g.iter().for_each(|c| collect(c, levels - 1, slots))
                        }
                        _ => slots.push(b),
                    }
                }
                let (levels, bits) = match self.width {
                    TreeWidth::Four => (1, 2),
                    TreeWidth::Eight => (2, 3),
                };
                assert!(
                    bits * (depth + 1) <= 64,
                    "light tree too deep for its trails"
                );
                let mut slots: Vec<&Build> = Vec::with_capacity(8);
                for c in children.iter() {
                    collect(c, levels, &mut slots);
                }
                let bounds: Vec<LightBounds> = slots.iter().map(|s| *s.bounds()).collect();
                let at = match self.width {
                    TreeWidth::Four => {
                        self.quads.push(ChildQuad::new(&bounds));
                        self.quads.len() - 1
                    }
                    TreeWidth::Eight => {
                        self.octs.push(ChildOct::new(&bounds));
                        self.octs.len() - 1
                    }
                };
                for (k, s) in slots.iter().enumerate() {
                    let id = self.flatten(s, trail | ((k as u64) << (bits * depth)), depth + 1);
                    match self.width {
                        TreeWidth::Four => self.quads[at].children[k] = id,
                        TreeWidth::Eight => self.octs[at].children[k] = id,
                    }
                }
                at as u32
            }
        }
    }

    /// Children per interior node.
    pub fn width(&self) -> TreeWidth {
        self.width
    }

    pub fn is_empty(&self) -> bool {
        self.lights == 0
    }

    /// Number of lights in the tree.
    pub fn len(&self) -> usize {
        self.lights
    }

    /// The probabilities of choosing each child of the interior node `quad` from (`p`, `n`)
    /// (importance over the sum), or `None` if no child can light the point.
    #[inline(always)]
    fn child_probabilities<const AVX2: bool>(quad: &ChildQuad, p: Vec3, n: Vec3) -> Option<Vec4> {
        let c = quad.importance(p, n);
        let total = (c.x + c.y) + (c.z + c.w);
        if !(total > 0.0) {
            return None;
        }
        Some(c / total)
    }

    /// A tree of one light: whether it can light (`p`, `n`) at all (a larger tree tests its
    /// lights through their parents' choices).
    #[inline]
    fn lone_light_reaches(&self, p: Vec3, n: Vec3) -> bool {
        self.root.is_some_and(|lb| lb.importance(p, n) > 0.0)
    }

    /// Chooses a light for a receiver at `p` with normal `n` (zero in a medium) with `u` in
    /// [0, 1): its index in the light set and the probability of having chosen it. `None` when no
    /// light of the tree can reach `p`.
    pub fn sample(&self, p: Vec3, n: Vec3, u: f32) -> Option<(u32, f32)> {
        self.sample_remap(p, n, u)
            .map(|(light, pmf, _)| (light, pmf))
    }

    /// [`Self::sample`] that also returns `u` as remapped at the last level, uniform on [0, 1)
    /// given the choice (see `Distribution1D::sample_discrete_remap`).
    #[inline]
    pub fn sample_remap(&self, p: Vec3, n: Vec3, u: f32) -> Option<(u32, f32, f32)> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is only set when `is_x86_feature_detected!("avx2")` said the CPU
            // has it (`math::detect_avx2`).
            return unsafe { self.sample_remap_avx2(p, n, u) };
        }
        self.sample_remap_impl::<false>(p, n, u)
    }

    /// [`Self::sample_remap`] compiled for the build's baseline CPU (SSE2 on x86-64).
    pub fn sample_remap_portable(&self, p: Vec3, n: Vec3, u: f32) -> Option<(u32, f32, f32)> {
        self.sample_remap_impl::<false>(p, n, u)
    }

    /// [`Self::sample_remap`] compiled with AVX2 enabled: the same SSE operations in VEX form
    /// (three operands, so the register copies of the two-operand SSE form go away) and
    /// AVX's 256-bit form of the eight-way tree's step ([`Avx8`]). No FMA (not enabled, and Rust never contracts
    /// `a * b + c` by itself), so every float is the portable path's bit for bit (a unit test
    /// checks it). Measured reason for the second copy: BENCHMARKS.md (light
    /// choice).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub unsafe fn sample_remap_avx2(&self, p: Vec3, n: Vec3, u: f32) -> Option<(u32, f32, f32)> {
        self.sample_remap_impl::<true>(p, n, u)
    }

    #[inline(always)]
    fn sample_remap_impl<const AVX2: bool>(
        &self,
        p: Vec3,
        n: Vec3,
        mut u: f32,
    ) -> Option<(u32, f32, f32)> {
        if let Some(light) = self.root_leaf {
            return self.lone_light_reaches(p, n).then_some((light, 1.0, u));
        }
        if self.width == TreeWidth::Eight {
            return self.sample_oct::<AVX2>(p, n, u);
        }
        let mut quad = self.quads.first()?;
        let mut pmf = 1.0f32;
        loop {
            let probs = Self::child_probabilities::<AVX2>(quad, p, n)?.to_array();
            let (k, pk, u_next) = choose_slot(&probs, u);
            u = u_next;
            pmf *= pk;
            // A slot of positive probability holds a child (empty slots have no power).
            let child = quad.children[k];
            debug_assert_ne!(child, NO_CHILD);
            if child & LEAF_BIT != 0 {
                return (pmf > 0.0).then_some((child & !LEAF_BIT, pmf, u));
            }
            quad = &self.quads[child as usize];
        }
    }

    /// [`Self::sample_remap_impl`] in the eight-way tree: the same walk over eight slots.
    #[inline(always)]
    fn sample_oct<const AVX2: bool>(
        &self,
        p: Vec3,
        n: Vec3,
        mut u: f32,
    ) -> Option<(u32, f32, f32)> {
        let mut node = self.octs.first()?;
        let mut pmf = 1.0f32;
        loop {
            let probs = node.probabilities::<AVX2>(p, n)?;
            let (k, pk, u_next) = choose_slot(&probs, u);
            u = u_next;
            pmf *= pk;
            let child = node.children[k];
            debug_assert_ne!(child, NO_CHILD);
            if child & LEAF_BIT != 0 {
                return (pmf > 0.0).then_some((child & !LEAF_BIT, pmf, u));
            }
            node = &self.octs[child as usize];
        }
    }

    /// The probability with which [`LightBvh::sample`] from (`p`, `n`) chooses light `light`
    /// (an index into the light set): the same products along the light's path. 0 for lights
    /// not in the tree.
    #[inline]
    pub fn pmf(&self, light: u32, p: Vec3, n: Vec3) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `sample_remap`.
            return unsafe { self.pmf_avx2(light, p, n) };
        }
        self.pmf_impl::<false>(light, p, n)
    }

    /// [`Self::pmf`] compiled for the build's baseline CPU.
    pub fn pmf_portable(&self, light: u32, p: Vec3, n: Vec3) -> f32 {
        self.pmf_impl::<false>(light, p, n)
    }

    /// [`Self::pmf`] compiled with AVX2 (see [`Self::sample_remap_avx2`]).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub unsafe fn pmf_avx2(&self, light: u32, p: Vec3, n: Vec3) -> f32 {
        self.pmf_impl::<true>(light, p, n)
    }

    #[inline(always)]
    fn pmf_impl<const AVX2: bool>(&self, light: u32, p: Vec3, n: Vec3) -> f32 {
        let Some(Some(trail)) = self.trails.get(light as usize) else {
            return 0.0;
        };
        if self.root_leaf.is_some() {
            debug_assert_eq!(self.root_leaf, Some(light));
            return if self.lone_light_reaches(p, n) {
                1.0
            } else {
                0.0
            };
        }
        if self.width == TreeWidth::Eight {
            return self.pmf_oct::<AVX2>(*trail, light, p, n);
        }
        let mut quad = &self.quads[0];
        let mut pmf = 1.0f32;
        let mut depth = 0u32;
        loop {
            let Some(probs) = Self::child_probabilities::<AVX2>(quad, p, n) else {
                return 0.0;
            };
            let k = ((trail >> (2 * depth)) & 3) as usize;
            pmf *= probs.to_array()[k];
            let child = quad.children[k];
            if child & LEAF_BIT != 0 {
                debug_assert_eq!(child & !LEAF_BIT, light);
                return pmf;
            }
            quad = &self.quads[child as usize];
            depth += 1;
        }
    }
}

impl LightBvh {
    /// [`Self::pmf_impl`] in the eight-way tree: three trail bits per step.
    #[inline(always)]
    fn pmf_oct<const AVX2: bool>(&self, trail: u64, light: u32, p: Vec3, n: Vec3) -> f32 {
        let mut node = &self.octs[0];
        let mut pmf = 1.0f32;
        let mut depth = 0u32;
        loop {
            let Some(probs) = node.probabilities::<AVX2>(p, n) else {
                return 0.0;
            };
            let k = ((trail >> (3 * depth)) & 7) as usize;
            pmf *= probs[k];
            let child = node.children[k];
            if child & LEAF_BIT != 0 {
                debug_assert_eq!(child & !LEAF_BIT, light);
                return pmf;
            }
            node = &self.octs[child as usize];
            depth += 1;
        }
    }
}

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// One descent step of both tree widths: the slot whose share of [0, 1) holds `u`, its
/// probability, and `u` remapped to [0, 1) within that share (so one number serves every level).
/// Rounding can leave `u` past the last share, which then takes it (the last slot of positive
/// probability).
#[inline(always)]
fn choose_slot(probs: &[f32], u: f32) -> (usize, f32, f32) {
    let (mut k, mut below) = (0, 0.0f32);
    let mut sum = 0.0f32;
    for (j, &pj) in probs.iter().enumerate() {
        if pj > 0.0 {
            (k, below) = (j, sum);
            if u < sum + pj {
                break;
            }
            sum += pj;
        }
    }
    let pk = probs[k];
    (k, pk, ((u - below).max(0.0) / pk).min(ONE_MINUS_EPSILON))
}

fn build(items: &mut [Item], depth: usize) -> Build {
    if items.len() == 1 {
        return Build::Leaf(items[0].lb, items[0].light);
    }
    let lb = items[1..]
        .iter()
        .fold(items[0].lb, |acc, it| acc.union(&it.lb));
    let centroids = items
        .iter()
        .fold(Bounds3::EMPTY, |b, it| b.union_point(it.centroid));
    let n = items.len();
    let mut mid = n / 2;
    let mut split: Option<(usize, usize)> = None;
    if depth < COST_SPLIT_DEPTH {
        // pbrt's bucketed cost over every axis with a non-zero centroid extent.
        let mut best = f32::INFINITY;
        for axis in 0..3 {
            let (lo, hi) = (centroids.min[axis], centroids.max[axis]);
            if !(hi > lo) {
                continue;
            }
            let mut buckets: [Option<LightBounds>; BUCKETS] = [None; BUCKETS];
            for it in items.iter() {
                let b = bucket_of(it.centroid[axis], lo, hi);
                buckets[b] = Some(match buckets[b] {
                    Some(acc) => acc.union(&it.lb),
                    None => it.lb,
                });
            }
            // Cost of splitting after bucket i: sweep from both ends.
            let mut below: [Option<LightBounds>; BUCKETS] = [None; BUCKETS];
            let mut acc: Option<LightBounds> = None;
            for (i, b) in buckets.iter().enumerate() {
                acc = union_opt(acc, *b);
                below[i] = acc;
            }
            let mut above: Option<LightBounds> = None;
            for i in (0..BUCKETS - 1).rev() {
                above = union_opt(above, buckets[i + 1]);
                let (Some(l), Some(r)) = (below[i], above) else {
                    continue;
                };
                let cost = l.cost(&lb.bounds, axis) + r.cost(&lb.bounds, axis);
                if cost < best {
                    best = cost;
                    split = Some((axis, i));
                }
            }
        }
    }
    if let Some((axis, bucket)) = split {
        let (lo, hi) = (centroids.min[axis], centroids.max[axis]);
        let mut left = 0;
        for i in 0..n {
            if bucket_of(items[i].centroid[axis], lo, hi) <= bucket {
                items.swap(i, left);
                left += 1;
            }
        }
        if left > 0 && left < n {
            mid = left;
        }
    } else {
        // No cost split (coincident centroids or too deep): halve by count along the longest axis.
        let axis = centroids.max_extent();
        items.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
    }
    let (a, b) = items.split_at_mut(mid);
    let children = if n > 4096 {
        let (x, y) = rayon::join(|| build(a, depth + 1), || build(b, depth + 1));
        [x, y]
    } else {
        [build(a, depth + 1), build(b, depth + 1)]
    };
    Build::Interior(lb, Box::new(children))
}

#[inline]
fn bucket_of(c: f32, lo: f32, hi: f32) -> usize {
    (((c - lo) / (hi - lo) * BUCKETS as f32) as usize).min(BUCKETS - 1)
}

fn union_opt(a: Option<LightBounds>, b: Option<LightBounds>) -> Option<LightBounds> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.union(&b)),
        (x, None) | (None, x) => x,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn unit(rng: &mut Pcg32) -> Vec3 {
        loop {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    /// A light's bounds of every kind the tree holds: one-sided and two-sided triangles (a
    /// cone of one direction), spots (θo, θe), points and unions (wide cones, boxes), of zero
    /// or positive extent.
    fn bounds(rng: &mut Pcg32) -> LightBounds {
        let a = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - Vec3::splat(2.0);
        let size = match rng.next_u32() % 3 {
            0 => 0.0,
            1 => 0.01,
            _ => 1.5,
        };
        let b = a + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * size;
        let cos_theta_o = match rng.next_u32() % 4 {
            0 => 1.0,
            1 => -1.0,
            _ => rng.next_f32() * 2.0 - 1.0,
        };
        LightBounds {
            bounds: Bounds3::new(a, b),
            phi: 0.1 + 10.0 * rng.next_f32(),
            w: unit(rng),
            cos_theta_o,
            cos_theta_e: if rng.next_u32().is_multiple_of(2) {
                0.0
            } else {
                rng.next_f32()
            },
            two_sided: rng.next_u32().is_multiple_of(2),
        }
    }

    /// The descent's four-lane importance must be the scalar `LightBounds::importance` bit for
    /// bit, for receivers outside, near and inside the boxes, on surfaces and in media (n = 0),
    /// and empty lanes must have none.
    #[test]
    fn child_quad_importance_is_the_scalar_importance_bit_for_bit() {
        let mut rng = Pcg32::new(23, 7);
        let mut nonzero = 0;
        for _ in 0..20_000 {
            let count = 1 + (rng.next_u32() % 4) as usize;
            let lbs: Vec<LightBounds> = (0..count).map(|_| bounds(&mut rng)).collect();
            let quad = ChildQuad::new(&lbs);
            let a = lbs[0];
            let p = match rng.next_u32() % 3 {
                // At a box's centre or a corner (inside, d = 0, degenerate directions).
                0 => (a.bounds.min + a.bounds.max) * 0.5,
                1 => a.bounds.min,
                _ => {
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0
                        - Vec3::splat(3.0)
                }
            };
            let n = if rng.next_u32().is_multiple_of(4) {
                Vec3::ZERO
            } else {
                unit(&mut rng)
            };
            let lanes = quad.importance(p, n).to_array();
            // The copy compiled with AVX2 enabled (the descent's) gives the same lanes.
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 was detected just above.
                let vex = unsafe { quad_importance_avx2(&quad, p, n) };
                assert_eq!(
                    vex.map(f32::to_bits),
                    lanes.map(f32::to_bits),
                    "{lbs:?} p {p} n {n}"
                );
            }
            for (k, lane) in lanes.iter().enumerate() {
                let scalar = lbs.get(k).map_or(0.0, |lb| lb.importance(p, n));
                assert_eq!(
                    lane.to_bits(),
                    scalar.to_bits(),
                    "{lbs:?} lane {k} p {p} n {n}: {lane} vs scalar {scalar}"
                );
                nonzero += (scalar > 0.0) as u32;
            }
        }
        // The cases are not all trivially zero.
        assert!(nonzero > 20_000, "{nonzero}");
    }

    /// The eight-way step's importance, as two SSE halves and (where the CPU has AVX2) as one
    /// AVX pass, must be the scalar `LightBounds::importance` bit for bit, empty lanes none.
    #[test]
    fn child_oct_importance_is_the_scalar_importance_bit_for_bit() {
        let mut rng = Pcg32::new(29, 5);
        let mut nonzero = 0;
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::is_x86_feature_detected!("avx2");
        for _ in 0..10_000 {
            let count = 1 + (rng.next_u32() % 8) as usize;
            let lbs: Vec<LightBounds> = (0..count).map(|_| bounds(&mut rng)).collect();
            let oct = ChildOct::new(&lbs);
            let a = lbs[(rng.next_u32() as usize) % count];
            let p = match rng.next_u32() % 3 {
                0 => (a.bounds.min + a.bounds.max) * 0.5,
                1 => a.bounds.min,
                _ => {
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0
                        - Vec3::splat(3.0)
                }
            };
            let n = if rng.next_u32().is_multiple_of(4) {
                Vec3::ZERO
            } else {
                unit(&mut rng)
            };
            let lanes = oct.importance::<false>(p, n);
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: AVX2 was detected above.
                let wide = unsafe { oct_importance_avx2(&oct, p, n) };
                assert_eq!(
                    wide.map(f32::to_bits),
                    lanes.map(f32::to_bits),
                    "{lbs:?} p {p} n {n}"
                );
            }
            for (k, lane) in lanes.iter().enumerate() {
                let scalar = lbs.get(k).map_or(0.0, |lb| lb.importance(p, n));
                assert_eq!(
                    lane.to_bits(),
                    scalar.to_bits(),
                    "{lbs:?} lane {k} p {p} n {n}: {lane} vs scalar {scalar}"
                );
                nonzero += (scalar > 0.0) as u32;
            }
        }
        assert!(nonzero > 20_000, "{nonzero}");
    }

    /// `ChildQuad::importance` in a function compiled with AVX2, as the descent's.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn quad_importance_avx2(quad: &ChildQuad, p: Vec3, n: Vec3) -> [f32; 4] {
        quad.importance(p, n).to_array()
    }

    /// `ChildOct::importance::<true>` in a function compiled with AVX2, as the descent's.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn oct_importance_avx2(oct: &ChildOct, p: Vec3, n: Vec3) -> [f32; 8] {
        oct.importance::<true>(p, n)
    }

    /// In both widths, the probability `sample` returns for a light is `pmf`'s bit for bit, the
    /// pmfs over all lights sum to at most 1, and `pmf` is 0 for a light that cannot be chosen.
    #[test]
    fn sampled_pmf_is_the_pmf_walk_in_both_widths() {
        let mut rng = Pcg32::new(41, 9);
        for width in [TreeWidth::Four, TreeWidth::Eight] {
            for count in [1usize, 2, 7, 9, 65, 700] {
                let lights: Vec<(u32, LightBounds)> =
                    (0..count).map(|i| (i as u32, bounds(&mut rng))).collect();
                let bvh = LightBvh::with_width(&lights, count, width);
                assert_eq!(bvh.width(), width);
                for _ in 0..200 {
                    let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0
                        - Vec3::splat(4.0);
                    let n = if rng.next_u32().is_multiple_of(4) {
                        Vec3::ZERO
                    } else {
                        unit(&mut rng)
                    };
                    let total: f64 = (0..count as u32).map(|l| bvh.pmf(l, p, n) as f64).sum();
                    assert!(
                        total <= 1.0 + 1e-5,
                        "{width:?} {count}: pmfs sum to {total}"
                    );
                    for _ in 0..20 {
                        let Some((light, pmf)) = bvh.sample(p, n, rng.next_f32()) else {
                            continue;
                        };
                        assert!(pmf > 0.0);
                        assert_eq!(
                            pmf.to_bits(),
                            bvh.pmf(light, p, n).to_bits(),
                            "{width:?} {count} lights: light {light} at p {p} n {n}"
                        );
                    }
                }
            }
        }
    }

    /// The AVX2 copies of the descent and of `pmf` must give the portable code's results bit
    /// for bit (determinism across machines): random trees of every kind of bounds, receivers
    /// on surfaces and in media, four- and eight-way.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_descent_and_pmf_are_the_portable_ones_bit_for_bit() {
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        }
        let mut rng = Pcg32::new(12, 3);
        let mut chosen = 0;
        for (count, width) in [1usize, 2, 3, 5, 17, 300]
            .into_iter()
            .flat_map(|c| [(c, TreeWidth::Four), (c, TreeWidth::Eight)])
        {
            let lights: Vec<(u32, LightBounds)> =
                (0..count).map(|i| (i as u32, bounds(&mut rng))).collect();
            let bvh = LightBvh::with_width(&lights, count, width);
            for _ in 0..2000 {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0
                    - Vec3::splat(4.0);
                let n = if rng.next_u32().is_multiple_of(4) {
                    Vec3::ZERO
                } else {
                    unit(&mut rng)
                };
                let u = rng.next_f32();
                let portable = bvh.sample_remap_portable(p, n, u);
                // SAFETY: AVX2 was detected above.
                let avx2 = unsafe { bvh.sample_remap_avx2(p, n, u) };
                let bits =
                    |r: Option<(u32, f32, f32)>| r.map(|(l, a, b)| (l, a.to_bits(), b.to_bits()));
                assert_eq!(
                    bits(portable),
                    bits(avx2),
                    "{count} lights, p {p} n {n} u {u}"
                );
                chosen += portable.is_some() as u32;
                let light = rng.next_u32() % count as u32;
                // SAFETY: as above.
                let pmf_avx2 = unsafe { bvh.pmf_avx2(light, p, n) };
                assert_eq!(
                    bvh.pmf_portable(light, p, n).to_bits(),
                    pmf_avx2.to_bits(),
                    "{count} lights, light {light}, p {p} n {n}"
                );
            }
        }
        // Most receivers are lit by some light (the comparison is not of `None`s).
        assert!(chosen > 12_000, "{chosen}");
    }
}
