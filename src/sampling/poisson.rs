//! Poisson-disk camera samples (thesis §5.3.2, where Kosarevsky's generator placed the supersamples
//! of a pixel so that no two are too close).
//!
//! One deterministic pattern of [`PATTERN_SIZE`] points on the unit torus is built once with
//! Mitchell's best-candidate algorithm (Mitchell 1991, "Spectrally Optimal Sampling for Distribution
//! Ray Tracing"): each new point is the candidate farthest from the points already placed, with the
//! number of candidates proportional to the points placed. The pattern is progressive: every
//! prefix of `n` points is itself a Poisson-disk-like set, so a pixel with `n` samples uses the first
//! `n`. Each pixel (and each dimension of its stream) shifts the pattern toroidally by a hashed
//! offset (Cranley–Patterson rotation), which makes every sample uniformly distributed and so keeps
//! the estimator unbiased while preserving the minimum distance between a pixel's samples.
//! Beyond `PATTERN_SIZE` samples the pattern repeats with a fresh shift per repetition.

use super::rng::Pcg32;
use crate::math::Vec2;
use std::sync::OnceLock;

pub const PATTERN_SIZE: usize = 1024;
/// Candidates per point already placed (Mitchell's factor), capped for large prefixes.
const CANDIDATE_FACTOR: usize = 8;
const MAX_CANDIDATES: usize = 256;

/// The shared progressive pattern.
pub fn pattern() -> &'static [Vec2] {
    static PATTERN: OnceLock<Vec<Vec2>> = OnceLock::new();
    PATTERN.get_or_init(|| best_candidate(PATTERN_SIZE, 0x5eed))
}

#[inline]
fn torus_d2(a: Vec2, b: Vec2) -> f32 {
    let mut d = (a - b).abs();
    d = d.min(Vec2::ONE - d);
    d.length_squared()
}

/// Mitchell's best-candidate pattern of `n` points, with a uniform grid for nearest-neighbour
/// queries on the torus.
pub fn best_candidate(n: usize, seed: u64) -> Vec<Vec2> {
    let mut rng = Pcg32::new(seed, 0x9e37);
    let g = ((n as f32).sqrt().ceil() as usize).max(1);
    let mut cells: Vec<Vec<u32>> = vec![Vec::new(); g * g];
    let cell_of = |p: Vec2| {
        let cx = ((p.x * g as f32) as usize).min(g - 1);
        let cy = ((p.y * g as f32) as usize).min(g - 1);
        (cx, cy)
    };
    let mut pts: Vec<Vec2> = Vec::with_capacity(n);
    while pts.len() < n {
        let k = pts.len();
        let candidates = (CANDIDATE_FACTOR * k).clamp(1, MAX_CANDIDATES);
        let mut best = Vec2::ZERO;
        let mut best_d2 = -1.0f32;
        for _ in 0..candidates {
            let c = Vec2::new(rng.next_f32(), rng.next_f32());
            let d2 = if k == 0 {
                f32::INFINITY
            } else {
                nearest_d2(&pts, &cells, g, cell_of(c), c, best_d2)
            };
            if d2 > best_d2 {
                best_d2 = d2;
                best = c;
            }
        }
        let (cx, cy) = cell_of(best);
        cells[cy * g + cx].push(pts.len() as u32);
        pts.push(best);
    }
    pts
}

/// Squared toroidal distance from `c` to its nearest point, searching rings of cells outwards.
/// Stops early once the nearest point is known to be closer than `floor` (the candidate cannot win).
fn nearest_d2(
    pts: &[Vec2],
    cells: &[Vec<u32>],
    g: usize,
    (cx, cy): (usize, usize),
    c: Vec2,
    floor: f32,
) -> f32 {
    let mut best = f32::INFINITY;
    let h = 1.0 / g as f32;
    let max_ring = g / 2 + 1;
    for r in 0..=max_ring {
        // Every point in ring r is at least (r − 1)·h away.
        let lower = (r as f32 - 1.0).max(0.0) * h;
        if lower * lower > best {
            break;
        }
        let r = r as isize;
        for dy in -r..=r {
            for dx in -r..=r {
                if dx.abs() != r && dy.abs() != r {
                    continue;
                }
                let x = (cx as isize + dx).rem_euclid(g as isize) as usize;
                let y = (cy as isize + dy).rem_euclid(g as isize) as usize;
                for &i in &cells[y * g + x] {
                    best = best.min(torus_d2(c, pts[i as usize]));
                }
            }
        }
        if best <= floor {
            return best;
        }
    }
    best
}

/// Point `j` of the pattern shifted toroidally by `shift` (each component in [0, 1)).
#[inline]
pub fn shifted(j: usize, shift: Vec2) -> Vec2 {
    let p = pattern()[j % PATTERN_SIZE] + shift;
    let wrap = |v: f32| {
        let w = v - v.floor();
        w.min(super::ONE_MINUS_EPSILON)
    };
    Vec2::new(wrap(p.x), wrap(p.y))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn min_dist(p: &[Vec2]) -> f32 {
        let mut m = f32::INFINITY;
        for i in 0..p.len() {
            for j in 0..i {
                m = m.min(torus_d2(p[i], p[j]));
            }
        }
        m.sqrt()
    }

    #[test]
    fn prefixes_keep_points_apart() {
        let p = pattern();
        for n in [4usize, 16, 64, 256, 1024] {
            // A hexagonal packing of n disks on the unit torus has spacing sqrt(2/(√3 n)); dart
            // throwing reaches roughly 0.65–0.75 of it. White noise would give ~0.1 or less.
            let hex = (2.0 / (3f32.sqrt() * n as f32)).sqrt();
            let d = min_dist(&p[..n]);
            assert!(d > 0.5 * hex, "n {n}: min distance {d} vs hex {hex}");
        }
    }

    #[test]
    fn pattern_is_deterministic_and_in_range() {
        let a = best_candidate(64, 1);
        let b = best_candidate(64, 1);
        assert_eq!(a, b);
        assert!(
            pattern()
                .iter()
                .all(|p| (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y))
        );
        let s = shifted(3, Vec2::new(0.9, 0.99));
        assert!((0.0..1.0).contains(&s.x) && (0.0..1.0).contains(&s.y));
    }
}
