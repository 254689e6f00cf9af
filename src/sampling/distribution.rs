//! Piecewise-constant 1D distribution sampled by inverting its CDF (PBRT §A.5.1 / §13.3.1); used to
//! choose lights in proportion to power.

use super::ONE_MINUS_EPSILON;

#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    pub func: Vec<f32>,
    /// cdf[0] = 0, cdf[n] = 1.
    pub cdf: Vec<f32>,
    pub func_int: f32,
    /// A guide table over the CDF (the "cutpoint" or guide-table method: Chen & Asau 1974; Devroye,
    /// "Non-Uniform Random Variate Generation", 1986, §III.2.4): `guide[j]` is the number of CDF
    /// entries ≤ j/K for j = 0..=K, K = `guide.len() - 1` a power of two. For u in
    /// [j/K, (j+1)/K) the entries ≤ u are all of the first `guide[j]` and none past
    /// `guide[j + 1]`, so the search only looks between the two, and finds the same index as
    /// a search of the whole CDF (same comparisons, fewer of them, fewer cache lines). Empty for
    /// short distributions, which search the whole CDF.
    guide: Vec<u32>,
}

impl Distribution1D {
    /// Builds from non-negative weights. Negative or non-finite weights count as zero; if every
    /// weight is zero the distribution is uniform.
    pub fn new(weights: &[f32]) -> Distribution1D {
        let n = weights.len();
        let func: Vec<f32> = weights
            .iter()
            .map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 })
            .collect();
        let mut cdf = vec![0.0f64; n + 1];
        for i in 0..n {
            cdf[i + 1] = cdf[i] + func[i] as f64 / n as f64;
        }
        let total = cdf[n];
        let (func, cdf) = if total > 0.0 {
            (
                func,
                cdf.iter()
                    .map(|&c| (c / total) as f32)
                    .collect::<Vec<f32>>(),
            )
        } else {
            (
                vec![1.0; n],
                (0..=n).map(|i| i as f32 / n.max(1) as f32).collect(),
            )
        };
        let func_int = if total > 0.0 { total as f32 } else { 1.0 };
        let mut cdf = cdf;
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        // About 8 entries per slot (so a slot's search takes ~3 steps on an even CDF), at most
        // 128 slots: an environment map's rows each get one.
        let guide = if n >= 32 {
            let k = (n / 8).next_power_of_two().min(128);
            (0..=k)
                .map(|j| cdf.partition_point(|&c| c <= j as f32 / k as f32) as u32)
                .collect()
        } else {
            Vec::new()
        };
        Distribution1D {
            func,
            cdf,
            func_int,
            guide,
        }
    }

    /// The number of CDF entries ≤ u (`cdf.partition_point(|&c| c <= u)`), through the guide
    /// table when there is one and u is in [0, 1).
    #[inline]
    fn count_le(&self, u: f32) -> usize {
        if self.guide.len() >= 2 && (0.0..1.0).contains(&u) {
            // u · K is exact (K is a power of two), so j/K ≤ u < (j+1)/K and j < K.
            let j = (u * (self.guide.len() - 1) as f32) as usize;
            let (lo, hi) = (self.guide[j] as usize, self.guide[j + 1] as usize);
            lo + self.cdf[lo..hi].partition_point(|&c| c <= u)
        } else {
            self.cdf.partition_point(|&c| c <= u)
        }
    }

    pub fn len(&self) -> usize {
        self.func.len()
    }

    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Chooses an index with probability proportional to its weight; returns (index, probability).
    #[inline]
    pub fn sample_discrete(&self, u: f32) -> (usize, f32) {
        let n = self.func.len();
        // Largest i with cdf[i] <= u.
        let i = match self.count_le(u) {
            0 => 0,
            k => (k - 1).min(n - 1),
        };
        // Skip zero-probability entries that a cdf plateau could land on.
        let mut i = i;
        while i + 1 < n && self.cdf[i + 1] <= self.cdf[i] {
            i += 1;
        }
        (i, self.discrete_pdf(i))
    }

    /// [`Self::sample_discrete`] that also returns `u` remapped onto [0, 1) within the chosen
    /// index's CDF interval, `(u - cdf[i]) / (cdf[i+1] - cdf[i])`: given the choice it is again
    /// uniform, so a caller can reuse it for the next decision (PBRT-v4 §A.1, `SampleDiscrete`'s
    /// `uRemapped`; Mitsuba 3's `DiscreteDistribution::sample_reuse`). Its resolution is u's
    /// times the interval's width: callers that need many bits check the probability.
    #[inline]
    pub fn sample_discrete_remap(&self, u: f32) -> (usize, f32, f32) {
        if self.func.len() == 1 {
            // One entry (a scene with one light, e.g. the Cornell box): the general path's
            // numbers are known without the CDF search: cdf = [0, 1], so the remap is u
            // itself, and the probability is w / (w · 1) = 1 exactly (`func_int` is w: the
            // f64 sum of one f32 divided by 1 is exact; and 1 / 1 for the all-zero fallback).
            // A unit test checks this equals the general path bit for bit.
            return (0, 1.0, u.clamp(0.0, ONE_MINUS_EPSILON));
        }
        self.sample_discrete_remap_general(u)
    }

    /// [`Self::sample_discrete_remap`] by the CDF search, for any number of entries.
    #[inline]
    fn sample_discrete_remap_general(&self, u: f32) -> (usize, f32, f32) {
        let (i, pmf) = self.sample_discrete(u);
        let width = self.cdf[i + 1] - self.cdf[i];
        let rest = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.5
        };
        (i, pmf, rest)
    }

    /// Probability of choosing index `i`.
    #[inline]
    pub fn discrete_pdf(&self, i: usize) -> f32 {
        self.func[i] / (self.func_int * self.func.len() as f32)
    }

    /// Continuous sample in [0, 1) with density proportional to the function; returns (x, pdf, index).
    #[inline]
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let (i, _) = self.sample_discrete(u);
        let n = self.func.len();
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            (u - self.cdf[i]) / width
        } else {
            0.5
        };
        let x = ((i as f32 + du.clamp(0.0, 1.0)) / n as f32).min(1.0 - f32::EPSILON);
        (x, self.func[i] / self.func_int, i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discrete_probabilities_match_weights() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, 0.0]);
        assert!((d.discrete_pdf(0) - 0.25).abs() < 1e-6);
        assert_eq!(d.discrete_pdf(1), 0.0);
        assert!((d.discrete_pdf(2) - 0.75).abs() < 1e-6);
        let mut counts = [0usize; 4];
        for k in 0..10_000 {
            let u = (k as f32 + 0.5) / 10_000.0;
            counts[d.sample_discrete(u).0] += 1;
        }
        assert_eq!(counts[1], 0);
        assert_eq!(counts[3], 0);
        assert!((counts[2] as f32 / 10_000.0 - 0.75).abs() < 0.01);
    }

    /// The remapped number is uniform within each choice: the remaps of a fine uniform grid over
    /// [0, 1) fill every sixteenth of [0, 1) equally for each index, and the remap of an
    /// interval's start is 0.
    #[test]
    fn remapped_numbers_are_uniform_per_choice() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, 0.5]);
        let n = 1 << 16;
        let mut bins = [[0u32; 16]; 4];
        for k in 0..n {
            let u = (k as f32 + 0.5) / n as f32;
            let (i, pmf, rest) = d.sample_discrete_remap(u);
            assert_eq!((i, pmf), d.sample_discrete(u));
            assert!((0.0..1.0).contains(&rest));
            bins[i][(rest * 16.0) as usize] += 1;
        }
        assert_eq!(bins[1], [0; 16]);
        for i in [0, 2, 3] {
            let total: u32 = bins[i].iter().sum();
            for b in bins[i] {
                assert!(
                    (b as f32 - total as f32 / 16.0).abs() <= 2.0,
                    "{i}: {:?}",
                    bins[i]
                );
            }
        }
        let (i, _, rest) = d.sample_discrete_remap(d.cdf[2]);
        assert_eq!((i, rest), (2, 0.0));
    }

    /// The one-entry shortcut returns what the CDF search returns, bit for bit, for weights
    /// of every kind (zero and non-finite ones fall back to uniform) and numbers at and past
    /// the ends of [0, 1).
    #[test]
    fn one_entry_shortcut_is_the_general_path_bit_for_bit() {
        let weights = [
            1.0,
            0.3,
            7.0e-3,
            3.0e38,
            1.0e-40,
            f32::MIN_POSITIVE,
            0.0,
            -2.0,
            f32::NAN,
            f32::INFINITY,
        ];
        let mut us = vec![0.0, -0.0, 1.0, 1.5, -0.25, ONE_MINUS_EPSILON, 1.0e-30];
        us.extend((0..1000).map(|k| (k as f32 + 0.37) / 1000.0));
        for w in weights {
            let d = Distribution1D::new(&[w]);
            for &u in &us {
                let (i, pmf, rest) = d.sample_discrete_remap(u);
                let (gi, gpmf, grest) = d.sample_discrete_remap_general(u);
                assert_eq!(
                    (i, pmf.to_bits(), rest.to_bits()),
                    (gi, gpmf.to_bits(), grest.to_bits()),
                    "w {w} u {u}: ({i}, {pmf}, {rest}) vs ({gi}, {gpmf}, {grest})"
                );
                assert_eq!(pmf.to_bits(), d.discrete_pdf(0).to_bits(), "w {w}");
            }
        }
    }

    /// The guide table's search finds the index a search of the whole CDF finds, for every u
    /// tried: CDFs with zero plateaus, one dominant entry, ties at slot boundaries, and numbers at,
    /// just beside and between CDF values and slot boundaries, outside [0, 1) and NaN.
    #[test]
    fn guided_search_is_the_whole_search() {
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut dists = Vec::new();
        for n in [32usize, 33, 100, 512, 1024, 1031] {
            // Even, random, mostly zero with a few lamps, and one dominant entry.
            dists.push(vec![1.0; n]);
            dists.push((0..n).map(|_| next()).collect::<Vec<_>>());
            dists.push(
                (0..n)
                    .map(|_| if next() < 0.05 { 1000.0 * next() } else { 0.0 })
                    .collect(),
            );
            let mut one = vec![1e-3; n];
            one[n / 3] = 1e6;
            dists.push(one);
        }
        let mut checked = 0;
        for w in &dists {
            let d = Distribution1D::new(w);
            assert!(d.guide.len() >= 2, "n = {} has no guide", w.len());
            let k = (d.guide.len() - 1) as f32;
            let mut us = vec![0.0, -0.0, 1.0, -1e-9, 1.5, f32::NAN, ONE_MINUS_EPSILON];
            for &c in &d.cdf {
                us.extend([c, c.next_up(), c.next_down()]);
            }
            for j in 0..=d.guide.len() {
                let b = j as f32 / k;
                us.extend([b, b.next_up(), b.next_down()]);
            }
            us.extend((0..4000).map(|_| next()));
            for u in us {
                let whole = d.cdf.partition_point(|&c| c <= u);
                assert_eq!(d.count_le(u), whole, "n = {}, u = {u}", w.len());
                checked += 1;
            }
        }
        assert!(checked > 100_000, "{checked}");
    }

    #[test]
    fn zero_weights_are_uniform() {
        let d = Distribution1D::new(&[0.0, 0.0]);
        assert!((d.discrete_pdf(0) - 0.5).abs() < 1e-6);
        let d = Distribution1D::new(&[f32::NAN, 1.0]);
        assert_eq!(d.discrete_pdf(0), 0.0);
    }
}
