//! Ray–triangle intersection (Möller & Trumbore 1997, "Fast, Minimum Storage Ray/Triangle
//! Intersection"; the thesis §5.1.4). The hit point is rebuilt from barycentrics, whose error bound
//! is PBRT eq. 3.31, rather than from `o + t·d`, which carries the error of `t`.

use super::Ray;
use crate::math::{Vec3, gamma};

/// A triangle's world-space vertices, stored inline for the intersection loop.
#[derive(Clone, Copy, Debug)]
pub struct TriangleVerts {
    pub p0: Vec3,
    pub p1: Vec3,
    pub p2: Vec3,
}

/// Result of a triangle test: distance and the barycentrics of `p1` and `p2`.
#[derive(Clone, Copy, Debug)]
pub struct TriangleHit {
    pub t: f32,
    pub b1: f32,
    pub b2: f32,
}

/// A triangle as its first vertex and two edges, the form the Möller–Trumbore test reads. The BVH
/// keeps its triangles in this form so a leaf test skips the two edge subtractions; the edges are
/// the same `p1 − p0`, `p2 − p0` the test would compute, so the hit is bit-identical.
#[derive(Clone, Copy, Debug)]
pub struct TriangleEdges {
    pub p0: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
}

impl TriangleEdges {
    /// Möller–Trumbore. Both faces are hit (culling is a shading decision, not a geometric one).
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<TriangleHit> {
        let (e1, e2) = (self.e1, self.e2);
        let pvec = ray.d.cross(e2);
        let det = e1.dot(pvec);
        // A degenerate triangle or a ray in its plane: no hit. `!(x != 0)` also rejects NaN.
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv_det = 1.0 / det;
        let tvec = ray.o - self.p0;
        let b1 = tvec.dot(pvec) * inv_det;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let qvec = tvec.cross(e1);
        let b2 = ray.d.dot(qvec) * inv_det;
        if b2 < 0.0 || b1 + b2 > 1.0 {
            return None;
        }
        let t = e2.dot(qvec) * inv_det;
        // Reject hits too close to the origin to be distinguished from it: the spawned origin is
        // already offset by its error bound, so t must only be positive beyond rounding of t.
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        Some(TriangleHit { t, b1, b2 })
    }
}

/// Up to eight triangles in structure-of-arrays form, the layout of a BVH leaf (Embree's
/// Triangle8; Wald et al. 2014, "Embree: A Kernel Framework for Efficient CPU Ray Tracing"):
/// nine rows of eight floats, `stride` apart in `soa`, from `start`: rows 0..3 are the lanes'
/// `p0` x, y, z, rows 3..6 their `e1`, rows 6..9 their `e2`. Lane `i` is triangle `i`; lanes at
/// or past the leaf's count hold whatever follows it.
#[derive(Clone, Copy)]
pub struct Triangles8<'a> {
    soa: &'a [f32],
    start: usize,
    stride: usize,
}

impl<'a> Triangles8<'a> {
    /// The eight lanes from `start` of rows `stride` apart. Panics unless all nine rows lie in
    /// `soa` (one check for the nine loads).
    #[inline(always)]
    pub fn new(soa: &'a [f32], start: usize, stride: usize) -> Triangles8<'a> {
        assert!(
            stride >= 8 && start <= stride - 8 && soa.len() >= 9 * stride,
            "eight lanes from {start} of rows {stride} apart do not fit in {} floats",
            soa.len()
        );
        Triangles8 { soa, start, stride }
    }

    /// Row `r` (0..9).
    #[inline(always)]
    fn row(&self, r: usize) -> &[f32] {
        &self.soa[r * self.stride + self.start..][..8]
    }

    /// Lane `i` as a triangle.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> TriangleEdges {
        let c = |r: usize| self.row(r)[i];
        TriangleEdges {
            p0: Vec3::new(c(0), c(1), c(2)),
            e1: Vec3::new(c(3), c(4), c(5)),
            e2: Vec3::new(c(6), c(7), c(8)),
        }
    }

    /// The closest hit among the first `n` lanes, tested one after the other with
    /// [`TriangleEdges::intersect`] and `t_max` shrinking to each hit: the lane and its hit.
    /// Among equal distances the lowest lane wins (a later one must be strictly closer).
    #[inline(always)]
    pub fn intersect_scalar(
        &self,
        n: usize,
        ray: &Ray,
        mut t_max: f32,
    ) -> Option<(usize, TriangleHit)> {
        let mut best = None;
        for i in 0..n {
            if let Some(h) = self.lane(i).intersect(ray, t_max) {
                t_max = h.t;
                best = Some((i, h));
            }
        }
        best
    }

    /// [`Self::intersect_scalar`] on all eight lanes at once in AVX2: the same Möller–Trumbore
    /// operations per lane in the same order (glam's `cross` is `a.y·b.z − b.y·a.z`, …, its `dot`
    /// `(x·x + y·y) + z·z`; IEEE multiplication commutes; no FMA), so each lane's `t`, `b1`, `b2`
    /// are the scalar ones bit for bit. The scalar early-outs become lane masks with the same
    /// NaN behaviour: the `det`, `b1` and `t` tests accept only ordered comparisons, the `b2`
    /// test rejects only ordered ones (`b2 < 0 || b1 + b2 > 1`), as the scalar code. Every lane
    /// is tested against the same `t_max`; the closest valid lane wins, the lowest on a tie —
    /// exactly the lane the sequential loop ends with.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    pub unsafe fn intersect_avx2(
        &self,
        n: usize,
        ray: &Ray,
        t_max: f32,
    ) -> Option<(usize, TriangleHit)> {
        use std::arch::x86_64::*;
        // SAFETY: `new` checked that the nine rows `r · stride + start .. + 8` lie in `soa`:
        // 32 readable bytes each (unaligned loads). Unchecked because nine bounds checks per
        // leaf were ~8 % of ToyCar's closest-hit instructions (callgrind).
        let (p0x, p0y, p0z, e1x, e1y, e1z, e2x, e2y, e2z) = unsafe {
            let p = self.soa.as_ptr().add(self.start);
            let s = self.stride;
            (
                _mm256_loadu_ps(p),
                _mm256_loadu_ps(p.add(s)),
                _mm256_loadu_ps(p.add(2 * s)),
                _mm256_loadu_ps(p.add(3 * s)),
                _mm256_loadu_ps(p.add(4 * s)),
                _mm256_loadu_ps(p.add(5 * s)),
                _mm256_loadu_ps(p.add(6 * s)),
                _mm256_loadu_ps(p.add(7 * s)),
                _mm256_loadu_ps(p.add(8 * s)),
            )
        };
        let (ox, oy, oz) = (
            _mm256_set1_ps(ray.o.x),
            _mm256_set1_ps(ray.o.y),
            _mm256_set1_ps(ray.o.z),
        );
        let (dx, dy, dz) = (
            _mm256_set1_ps(ray.d.x),
            _mm256_set1_ps(ray.d.y),
            _mm256_set1_ps(ray.d.z),
        );
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        // pvec = d × e2
        let px = _mm256_sub_ps(_mm256_mul_ps(dy, e2z), _mm256_mul_ps(e2y, dz));
        let py = _mm256_sub_ps(_mm256_mul_ps(dz, e2x), _mm256_mul_ps(e2z, dx));
        let pz = _mm256_sub_ps(_mm256_mul_ps(dx, e2y), _mm256_mul_ps(e2x, dy));
        // det = e1 · pvec; rejected if zero or not finite (NaN included).
        let det = _mm256_add_ps(
            _mm256_add_ps(_mm256_mul_ps(e1x, px), _mm256_mul_ps(e1y, py)),
            _mm256_mul_ps(e1z, pz),
        );
        let abs_det = _mm256_and_ps(det, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff)));
        let mut valid = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_NEQ_OQ>(det, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(abs_det, _mm256_set1_ps(f32::INFINITY)),
        );
        let inv_det = _mm256_div_ps(one, det);
        // tvec = o − p0; b1 = (tvec · pvec) / det, accepted in [0, 1].
        let tx = _mm256_sub_ps(ox, p0x);
        let ty = _mm256_sub_ps(oy, p0y);
        let tz = _mm256_sub_ps(oz, p0z);
        let b1 = _mm256_mul_ps(
            _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(tx, px), _mm256_mul_ps(ty, py)),
                _mm256_mul_ps(tz, pz),
            ),
            inv_det,
        );
        valid = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_GE_OQ>(b1, zero));
        valid = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_LE_OQ>(b1, one));
        // qvec = tvec × e1; b2 = (d · qvec) / det, rejected if b2 < 0 or b1 + b2 > 1.
        let qx = _mm256_sub_ps(_mm256_mul_ps(ty, e1z), _mm256_mul_ps(e1y, tz));
        let qy = _mm256_sub_ps(_mm256_mul_ps(tz, e1x), _mm256_mul_ps(e1z, tx));
        let qz = _mm256_sub_ps(_mm256_mul_ps(tx, e1y), _mm256_mul_ps(e1x, ty));
        let b2 = _mm256_mul_ps(
            _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(dx, qx), _mm256_mul_ps(dy, qy)),
                _mm256_mul_ps(dz, qz),
            ),
            inv_det,
        );
        valid = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_NLT_UQ>(b2, zero));
        valid = _mm256_and_ps(
            valid,
            _mm256_cmp_ps::<_CMP_NGT_UQ>(_mm256_add_ps(b1, b2), one),
        );
        // t = (e2 · qvec) / det, accepted in (0, t_max).
        let t = _mm256_mul_ps(
            _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(e2x, qx), _mm256_mul_ps(e2y, qy)),
                _mm256_mul_ps(e2z, qz),
            ),
            inv_det,
        );
        valid = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero));
        valid = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_LT_OQ>(t, _mm256_set1_ps(t_max)));
        let mut mask = _mm256_movemask_ps(valid) as u32 & ((1u32 << n.min(8)) - 1);
        if mask == 0 {
            return None;
        }
        let (mut ts, mut b1s, mut b2s) = ([0.0f32; 8], [0.0f32; 8], [0.0f32; 8]);
        // SAFETY: each array is `[f32; 8]`: 32 writable bytes (unaligned stores).
        unsafe {
            _mm256_storeu_ps(ts.as_mut_ptr(), t);
            _mm256_storeu_ps(b1s.as_mut_ptr(), b1);
            _mm256_storeu_ps(b2s.as_mut_ptr(), b2);
        }
        let mut best = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        while mask != 0 {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if ts[i] < ts[best] {
                best = i;
            }
        }
        Some((
            best,
            TriangleHit {
                t: ts[best],
                b1: b1s[best],
                b2: b2s[best],
            },
        ))
    }
}

impl TriangleVerts {
    /// The vertex-and-edges form of this triangle.
    #[inline]
    pub fn edges(&self) -> TriangleEdges {
        TriangleEdges {
            p0: self.p0,
            e1: self.p1 - self.p0,
            e2: self.p2 - self.p0,
        }
    }

    /// Möller–Trumbore on the edge form (see [`TriangleEdges::intersect`]).
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<TriangleHit> {
        self.edges().intersect(ray, t_max)
    }

    /// Point on the triangle at barycentrics `(1−b1−b2, b1, b2)` and its absolute error bound.
    #[inline]
    pub fn point(&self, b1: f32, b2: f32) -> (Vec3, Vec3) {
        let b0 = 1.0 - b1 - b2;
        let a = self.p0 * b0;
        let b = self.p1 * b1;
        let c = self.p2 * b2;
        let p = a + b + c;
        let err = (a.abs() + b.abs() + c.abs()) * gamma(7);
        (p, err)
    }

    /// Unnormalised geometric normal; its direction follows the counter-clockwise winding
    /// (p0 → p1 → p2), which defines the front face.
    #[inline]
    pub fn normal_unnormalized(&self) -> Vec3 {
        (self.p1 - self.p0).cross(self.p2 - self.p0)
    }

    /// Unit geometric normal (front face as in [`Self::normal_unnormalized`]); +z for a degenerate
    /// triangle, which has no direction of its own, so shading and light sampling stay finite.
    #[inline]
    pub fn unit_normal(&self) -> Vec3 {
        let n = self.normal_unnormalized();
        if n.length_squared() > 0.0 {
            n.normalize()
        } else {
            Vec3::Z
        }
    }

    #[inline]
    pub fn area(&self) -> f32 {
        0.5 * self.normal_unnormalized().length()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> TriangleVerts {
        TriangleVerts {
            p0: Vec3::new(0.0, 0.0, 0.0),
            p1: Vec3::new(1.0, 0.0, 0.0),
            p2: Vec3::new(0.0, 1.0, 0.0),
        }
    }

    #[test]
    fn hit_front_and_back() {
        let t = tri();
        let front = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
        let h = t.intersect(&front, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.b1 - 0.25).abs() < 1e-6 && (h.b2 - 0.25).abs() < 1e-6);
        let back = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z);
        assert!(t.intersect(&back, f32::INFINITY).is_some());
        // The normal follows the CCW winding: +z.
        assert!(t.normal_unnormalized().z > 0.0);
    }

    #[test]
    fn misses() {
        let t = tri();
        // Outside each edge.
        for o in [
            Vec3::new(-0.1, 0.5, 1.0),
            Vec3::new(0.5, -0.1, 1.0),
            Vec3::new(0.6, 0.6, 1.0),
        ] {
            assert!(t.intersect(&Ray::new(o, -Vec3::Z), f32::INFINITY).is_none());
        }
        // Behind the origin.
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::Z);
        assert!(t.intersect(&r, f32::INFINITY).is_none());
        // Beyond t_max.
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
        assert!(t.intersect(&r, 0.5).is_none());
    }

    #[test]
    fn grazing_ray_in_plane_misses() {
        let t = tri();
        let r = Ray::new(Vec3::new(-1.0, 0.25, 0.0), Vec3::X);
        assert!(t.intersect(&r, f32::INFINITY).is_none());
    }

    #[test]
    fn degenerate_triangle_never_hits() {
        let t = TriangleVerts {
            p0: Vec3::ZERO,
            p1: Vec3::X,
            p2: Vec3::X * 2.0,
        };
        let r = Ray::new(Vec3::new(0.5, 0.0, 1.0), -Vec3::Z);
        assert!(t.intersect(&r, f32::INFINITY).is_none());
    }

    #[test]
    fn far_from_origin_hit_point_within_error_bound() {
        let off = Vec3::new(1e5, -2e5, 3e5);
        let t = TriangleVerts {
            p0: off,
            p1: off + Vec3::X * 10.0,
            p2: off + Vec3::Y * 10.0,
        };
        let r = Ray::new(off + Vec3::new(2.0, 3.0, 50.0), -Vec3::Z);
        let h = t.intersect(&r, f32::INFINITY).unwrap();
        let (p, err) = t.point(h.b1, h.b2);
        let exact = off + Vec3::new(2.0, 3.0, 0.0);
        for i in 0..3 {
            // The bound is conservative: the true plane (z = off.z exactly) lies within it.
            assert!(
                (p[i] - exact[i]).abs() <= err[i] + 0.05,
                "axis {i}: {p} vs {exact} ± {err}"
            );
        }
        assert!((p.z - exact.z).abs() <= err.z);
    }

    #[test]
    fn nan_ray_never_hits() {
        let r = Ray::new(Vec3::new(f32::NAN, 0.0, 1.0), -Vec3::Z);
        assert!(tri().intersect(&r, f32::INFINITY).is_none());
    }

    /// A pool of hostile triangles: a grid of triangles sharing edges and vertices (integer and
    /// fractional coordinates), a duplicate (a tie at every hit), degenerate ones (collinear,
    /// a point, a zero edge), a tiny one, one far from the origin, and ones with NaN or infinite
    /// vertices.
    fn hostile_pool() -> Vec<TriangleVerts> {
        let mut pool = Vec::new();
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        for i in 0..3 {
            for j in 0..3 {
                let (x, y) = (i as f32 * 0.5, j as f32 * 0.3);
                let (a, b, c, d) = (
                    v(x, y, 0.1 * i as f32),
                    v(x + 0.5, y, 0.1 * i as f32),
                    v(x + 0.5, y + 0.3, 0.1 * (i + 1) as f32),
                    v(x, y + 0.3, 0.1 * i as f32),
                );
                pool.push(TriangleVerts {
                    p0: a,
                    p1: b,
                    p2: c,
                });
                pool.push(TriangleVerts {
                    p0: a,
                    p1: c,
                    p2: d,
                });
            }
        }
        let unit = TriangleVerts {
            p0: v(0.0, 0.0, 0.0),
            p1: v(1.0, 0.0, 0.0),
            p2: v(0.0, 1.0, 0.0),
        };
        pool.push(unit);
        pool.push(unit);
        pool.push(TriangleVerts {
            p0: v(1.0, 0.0, 0.0),
            p1: v(1.0, 1.0, 0.0),
            p2: v(0.0, 1.0, 0.0),
        });
        pool.push(TriangleVerts {
            p0: v(0.0, 0.0, 0.0),
            p1: v(1.0, 1.0, 0.0),
            p2: v(2.0, 2.0, 0.0),
        });
        pool.push(TriangleVerts {
            p0: v(0.5, 0.5, 0.0),
            p1: v(0.5, 0.5, 0.0),
            p2: v(0.5, 0.5, 0.0),
        });
        pool.push(TriangleVerts {
            p0: v(0.2, 0.2, 0.0),
            p1: v(0.2, 0.2, 0.0),
            p2: v(0.2, 0.9, 0.0),
        });
        pool.push(TriangleVerts {
            p0: v(0.3, 0.3, 0.0),
            p1: v(0.3 + 1e-6, 0.3, 0.0),
            p2: v(0.3, 0.3 + 1e-6, 0.0),
        });
        let off = v(3e5, -2e5, 1e5);
        pool.push(TriangleVerts {
            p0: off,
            p1: off + v(10.0, 0.0, 0.0),
            p2: off + v(0.0, 10.0, 0.0),
        });
        pool.push(TriangleVerts {
            p0: v(f32::NAN, 0.0, 0.0),
            p1: v(1.0, 0.0, 0.0),
            p2: v(0.0, 1.0, 0.0),
        });
        pool.push(TriangleVerts {
            p0: v(0.0, 0.0, 0.0),
            p1: v(f32::INFINITY, 0.0, 0.0),
            p2: v(0.0, 1.0, 0.0),
        });
        pool
    }

    /// The AVX2 eight-lane test finds exactly the hit of the scalar test run lane after lane
    /// (lane, t, b1, b2 bit for bit, or both none) on hostile cases: rays aimed at shared
    /// vertices and edges and at duplicated triangles (ties, which the lowest lane must win),
    /// degenerate and NaN/infinite triangles, rays with NaN, infinite or zero direction
    /// components, `t_max` equal to a lane's exact hit distance (must miss), one ulp above it,
    /// zero, negative and NaN, and lane counts 0..=8. Fails if a comparison's NaN or equality
    /// behaviour differs (`≤` for `<`, an ordered `b2` test), if a tie picks another lane, if
    /// lanes past the count are read, or if the arithmetic rounds differently (an FMA).
    #[test]
    fn eight_lane_test_agrees_with_scalar_on_hostile_cases() {
        #[cfg(target_arch = "x86_64")]
        {
            if !std::is_x86_feature_detected!("avx2") {
                eprintln!("no AVX2 on this CPU: the eight-lane test is not exercised");
                return;
            }
            let pool = hostile_pool();
            let mut rng = crate::sampling::rng::Pcg32::new(23, 8);
            let pick =
                |n: usize, rng: &mut crate::sampling::rng::Pcg32| (rng.next_u32() as usize) % n;
            let key = |h: Option<(usize, TriangleHit)>| {
                h.map(|(l, h)| (l, h.t.to_bits(), h.b1.to_bits(), h.b2.to_bits()))
            };
            let (mut hits, mut ties, mut edge_hits, mut t_max_ties) = (0, 0, 0, 0);
            for case in 0..200_000 {
                let lanes: Vec<TriangleEdges> = (0..8)
                    .map(|_| pool[pick(pool.len(), &mut rng)].edges())
                    .collect();
                let mut rows = [[0.0f32; 8]; 9];
                for (l, t) in lanes.iter().enumerate() {
                    for axis in 0..3 {
                        rows[axis][l] = t.p0[axis];
                        rows[3 + axis][l] = t.e1[axis];
                        rows[6 + axis][l] = t.e2[axis];
                    }
                }
                let flat: Vec<f32> = rows.iter().flatten().copied().collect();
                let tris = Triangles8::new(&flat, 0, 8);
                let n = if case % 5 == 0 { pick(9, &mut rng) } else { 8 };
                // Aim at a vertex, an edge point or an inner point of a lane (or anywhere).
                let target = {
                    let t = lanes[pick(8, &mut rng)];
                    let (p1, p2) = (t.p0 + t.e1, t.p0 + t.e2);
                    let f = [0.0, 0.5, 1.0, 0.25, 1.0 / 3.0][pick(5, &mut rng)];
                    match pick(6, &mut rng) {
                        0 => t.p0,
                        1 => p1,
                        2 => t.p0 + (p1 - t.p0) * f,
                        3 => p1 + (p2 - p1) * f,
                        4 => t.p0 + (p2 - t.p0) * f,
                        _ => Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0,
                    }
                };
                let o = match pick(4, &mut rng) {
                    0 => target + Vec3::new(0.0, 0.0, 1.0),
                    1 => target - Vec3::new(0.0, 0.0, 2.5),
                    _ => {
                        target
                            + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                                * 4.0
                    }
                };
                let mut d = target - o;
                match pick(12, &mut rng) {
                    0 => d.x = f32::NAN,
                    1 => d.y = f32::INFINITY,
                    2 => d = Vec3::ZERO,
                    3 => d.x = 0.0,
                    _ => {}
                }
                let mut o = o;
                if pick(40, &mut rng) == 0 {
                    o.z = f32::NAN;
                }
                let ray = Ray::new(o, d);
                let full = tris.intersect_scalar(n, &ray, f32::INFINITY);
                let t_max = match (pick(8, &mut rng), full) {
                    (0 | 1, Some((_, h))) => h.t,
                    (2, Some((_, h))) => crate::math::next_float_up(h.t),
                    (3, _) => 0.0,
                    (4, _) => -1.0,
                    (5, _) => f32::NAN,
                    _ => f32::INFINITY,
                };
                t_max_ties += (full.is_some_and(|(_, h)| h.t == t_max)) as usize;
                let want = tris.intersect_scalar(n, &ray, t_max);
                // SAFETY: AVX2 was detected above.
                let got = unsafe { tris.intersect_avx2(n, &ray, t_max) };
                assert_eq!(
                    key(got),
                    key(want),
                    "case {case}: n {n}, ray {ray:?}, t_max {t_max}"
                );
                if let Some((lane, h)) = want {
                    hits += 1;
                    edge_hits += (h.b2 == 0.0 || h.b1 == 0.0 || h.b1 + h.b2 == 1.0) as usize;
                    ties += (lane + 1..n).any(|l| {
                        lanes[l]
                            .intersect(&ray, f32::INFINITY)
                            .is_some_and(|o| o.t == h.t)
                    }) as usize;
                }
            }
            assert!(
                hits > 30_000 && ties > 3_000 && edge_hits > 3_000 && t_max_ties > 10_000,
                "{hits} hits, {ties} ties, {edge_hits} on edges, {t_max_ties} t_max ties"
            );
        }
    }
}
