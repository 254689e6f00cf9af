//! Where the light-path integrators take their uniform numbers from ([`UniformSource`]): a pixel
//! sample's [`SampleStream`], or the primary-sample vector of a Metropolis chain
//! ([`MltSampler`]).
//!
//! Primary sample space (Kelemen et al. 2002, "A Simple and Robust Mutation Strategy for the
//! Metropolis Light Transport Algorithm"): a path is a deterministic function of the uniform
//! numbers its sampler hands out, so a Markov chain can walk over those numbers instead of over
//! paths. A *large step* replaces every number by a fresh uniform one; a *small step* moves each
//! by a normal offset of deviation σ, wrapped onto [0, 1). Both proposals are symmetric, so the
//! acceptance probability is the ratio of the target values alone. Numbers are made lazily when
//! a path first asks for them (paths have different lengths), and a number not touched for
//! several iterations catches up with all its missed small steps at once (their sum is normal
//! with deviation σ√n), so a proposal only costs the dimensions the path reads (pbrt-v4
//! `MLTSampler`, read as a specification).

use super::ONE_MINUS_EPSILON;
use super::rng::Pcg32;
pub use super::sampler::UniformSource;
use crate::math::Vec2;

/// `Primary::modified` of a number not made yet.
const NEVER: u64 = u64::MAX;

/// One coordinate of the primary-sample vector, with the state needed to undo a rejected
/// proposal.
#[derive(Clone, Copy, Debug, Default)]
struct Primary {
    value: f32,
    /// The iteration that last changed `value`.
    modified: u64,
    backup: f32,
    modified_backup: u64,
}

/// The primary-sample vector of one Markov chain and its mutations. Numbers are asked for by
/// stream (pbrt-v4's camera, light and connection streams): number `j` of stream `i` is
/// coordinate `j · streams + i`, so a path that reads more numbers from one stream does not
/// shift the others'.
#[derive(Clone, Debug)]
pub struct MltSampler {
    x: Vec<Primary>,
    rng: Pcg32,
    sigma: f32,
    large_step_probability: f32,
    streams: u32,
    stream: u32,
    index: u32,
    iteration: u64,
    large_step: bool,
    last_large_step: u64,
}

impl MltSampler {
    /// A chain whose proposals come from `rng`, with small-step deviation `sigma` and large
    /// steps taken with probability `large_step_probability`. Its first iteration is a large
    /// step (every number fresh).
    pub fn new(rng: Pcg32, sigma: f32, large_step_probability: f32, streams: u32) -> MltSampler {
        MltSampler {
            x: Vec::new(),
            rng,
            sigma,
            large_step_probability,
            streams: streams.max(1),
            stream: 0,
            index: 0,
            iteration: 0,
            large_step: true,
            last_large_step: 0,
        }
    }

    /// Takes its proposals from `rng` from now on (the state is kept).
    pub fn reseed(&mut self, rng: Pcg32) {
        self.rng = rng;
    }

    /// Starts the next proposal: a large step with the chain's probability, else a small one.
    pub fn start_iteration(&mut self) {
        self.iteration += 1;
        self.large_step = self.rng.next_f32() < self.large_step_probability;
    }

    /// Whether the current proposal is a large step.
    pub fn is_large_step(&self) -> bool {
        self.large_step
    }

    /// Reads the next numbers from stream `i`, from its first.
    pub fn start_stream(&mut self, i: u32) {
        self.stream = i;
        self.index = 0;
    }

    /// Keeps the proposal as the chain's state.
    pub fn accept(&mut self) {
        if self.large_step {
            self.last_large_step = self.iteration;
        }
    }

    /// Drops the proposal: every number it changed goes back to its value before.
    pub fn reject(&mut self) {
        for p in &mut self.x {
            if p.modified == self.iteration {
                p.value = p.backup;
                p.modified = p.modified_backup;
            }
        }
        self.iteration -= 1;
    }

    /// A standard normal number (Box–Muller from two of the chain's uniforms).
    fn normal(&mut self) -> f32 {
        let u1 = 1.0 - self.rng.next_f32(); // (0, 1]: the logarithm stays finite
        let u2 = self.rng.next_f32();
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }

    /// Coordinate `k` brought up to the current iteration: made fresh where the last large
    /// step has not reached it yet, then mutated by this iteration's step.
    fn ready(&mut self, k: usize) -> f32 {
        if k >= self.x.len() {
            self.x.resize(
                k + 1,
                Primary {
                    modified: NEVER,
                    ..Primary::default()
                },
            );
        }
        // A number never read, or not read since the last large step, is a fresh uniform
        // one as of that step (the large step replaced every number, read or not).
        if self.x[k].modified == NEVER || self.x[k].modified < self.last_large_step {
            self.x[k].value = self.rng.next_f32();
            self.x[k].modified = self.last_large_step;
        }
        let p = self.x[k];
        self.x[k].backup = p.value;
        self.x[k].modified_backup = p.modified;
        let value = if self.large_step {
            self.rng.next_f32()
        } else {
            // The small steps this number missed since it was last changed, all at once.
            let n = (self.iteration - p.modified) as f32;
            let v = p.value + self.normal() * self.sigma * n.sqrt();
            // Wrapped onto [0, 1); `v - floor(v)` rounds up to 1 for tiny negative v.
            (v - v.floor()).clamp(0.0, ONE_MINUS_EPSILON)
        };
        self.x[k].value = value;
        self.x[k].modified = self.iteration;
        value
    }
}

impl UniformSource for MltSampler {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        let k = self.index as usize * self.streams as usize + self.stream as usize;
        self.index += 1;
        self.ready(k)
    }
    #[inline]
    fn next_2d(&mut self) -> Vec2 {
        let x = self.next_1d();
        Vec2::new(x, self.next_1d())
    }
}

/// Metropolis light transport's settings (`--integrator mlt`; pbrt's `Integrator "mlt"`
/// parameters of the same names). `None`: pbrt-v4's default. The mutations per pixel are the
/// render's samples per pixel (pbrt's `mutationsperpixel`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MltSettings {
    /// Bootstrap states per depth (`bootstrapsamples`, 100 000).
    pub bootstrap_samples: Option<u32>,
    /// Markov chains (`chains`, 1000).
    pub chains: Option<u32>,
    /// Probability of a large step (`largestepprobability`, 0.3).
    pub large_step_probability: Option<f32>,
    /// Deviation of a small step's normal offsets (`sigma`, 0.01).
    pub sigma: Option<f32>,
}

impl MltSettings {
    pub fn bootstrap(&self) -> u32 {
        self.bootstrap_samples.unwrap_or(100_000)
    }
    pub fn chain_count(&self) -> u32 {
        self.chains.unwrap_or(1000)
    }
    pub fn large_step(&self) -> f32 {
        self.large_step_probability.unwrap_or(0.3)
    }
    pub fn small_sigma(&self) -> f32 {
        self.sigma.unwrap_or(0.01)
    }

    /// Each field given here, else `other`'s (a job's options over a scene file's).
    pub fn or(self, other: MltSettings) -> MltSettings {
        MltSettings {
            bootstrap_samples: self.bootstrap_samples.or(other.bootstrap_samples),
            chains: self.chains.or(other.chains),
            large_step_probability: self.large_step_probability.or(other.large_step_probability),
            sigma: self.sigma.or(other.sigma),
        }
    }

    /// Refuses values that make no chain or no valid proposal.
    pub fn validate(&self) -> Result<(), String> {
        if self.bootstrap() == 0 || self.chain_count() == 0 {
            return Err("MLT needs at least one bootstrap sample and one chain".into());
        }
        let p = self.large_step();
        if !(0.0..=1.0).contains(&p) {
            return Err(format!("MLT large-step probability {p} is not in [0, 1]"));
        }
        let s = self.small_sigma();
        if !(s > 0.0 && s.is_finite()) {
            return Err(format!("MLT sigma {s} must be positive"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pearson's χ² of `values` in [0, 1) over `bins` equal bins against the uniform density.
    fn chi2_uniform(values: &[f32], bins: usize) -> f64 {
        let mut count = vec![0.0f64; bins];
        for &v in values {
            count[((v * bins as f32) as usize).min(bins - 1)] += 1.0;
        }
        let e = values.len() as f64 / bins as f64;
        count.iter().map(|c| (c - e) * (c - e) / e).sum()
    }

    /// Three numbers of each of the three streams, read as a path would.
    fn read(u: &mut MltSampler) -> Vec<f32> {
        let mut v = Vec::new();
        for s in 0..3 {
            u.start_stream(s);
            v.push(u.next_1d());
            let p = u.next_2d();
            v.extend([p.x, p.y]);
        }
        v
    }

    /// Large steps are fresh uniform numbers (χ² over 20 bins below the 0.1 % critical value
    /// 43.8 of 19 degrees of freedom); small steps stay in [0, 1) however far σ takes them
    /// across the ends and move a number by |N(0, σ²)| on average (σ·√(2/π), distances taken
    /// around the wrap);
    /// rejecting a proposal restores the state before it.
    #[test]
    fn primary_sample_mutations() {
        let rng = |k| Pcg32::new(7, k);
        let mut large = MltSampler::new(rng(1), 0.01, 1.0, 3);
        let mut values = Vec::new();
        for _ in 0..3000 {
            large.start_iteration();
            values.extend(read(&mut large));
            large.accept();
        }
        let c = chi2_uniform(&values, 20);
        assert!(c < 43.8, "large steps: χ² {c}");

        for sigma in [0.01f32, 0.2] {
            let mut small = MltSampler::new(rng(2), sigma, 0.0, 3);
            let mut prev = read(&mut small);
            let (mut values, mut moved) = (Vec::<f32>::new(), 0.0f64);
            for _ in 0..3000 {
                small.start_iteration();
                let v = read(&mut small);
                assert!(v.iter().all(|x| (0.0..1.0).contains(x)), "σ {sigma}: {v:?}");
                for (a, b) in v.iter().zip(&prev) {
                    let d = (a - b).abs();
                    moved += d.min(1.0 - d) as f64;
                }
                values.extend(&v);
                small.accept();
                prev = v;
            }
            if sigma < 0.1 {
                let mean = moved / values.len() as f64;
                let expected = sigma as f64 * (2.0 / std::f64::consts::PI).sqrt();
                assert!(
                    (mean - expected).abs() < 0.05 * expected,
                    "small steps of σ {sigma} moved {mean}, not {expected}"
                );
            }
        }

        let mut u = MltSampler::new(rng(3), 0.05, 0.5, 3);
        let mut state = read(&mut u);
        for _ in 0..200 {
            u.start_iteration();
            let proposal = read(&mut u);
            if proposal[0] < 0.5 {
                u.accept();
                state = proposal;
            } else {
                u.reject();
                // The stored numbers: number j of stream s is coordinate 3j + s.
                let kept: Vec<f32> = (0..9).map(|i| u.x[(i % 3) * 3 + i / 3].value).collect();
                assert_eq!(kept, state, "a rejected proposal was not undone");
            }
        }
    }
}
