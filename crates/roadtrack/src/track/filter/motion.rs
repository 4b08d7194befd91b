//! Constant-velocity system model (METHODS.md §3 "System model", seed 004 eq. 4).
//!
//! ```text
//! v_t ~ N(v_{t−1}, σ²)          (per axis)
//! x_t = x_{t−1} + v_t · dt
//! ```
//!
//! with `σ = k·|v_{t−1}|` (the paper: `k = 0.3` vehicles in the PHD filter, `0.2` pedestrians)
//! or an absolute `σ` (the paper's vehicle particle filter: 10 px). A third form, white-noise
//! acceleration, is the usual point-target model (`roadtrack filter --process-sigma`).

use crate::error::{Error, Result};
use crate::rng::{Rng, Stream, rng_for};
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// How the velocity is perturbed at each step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum VelocityNoise {
    /// `σ = factor·|v|` per axis, at least `min_sigma` (units per unit time).
    ProportionalToSpeed {
        /// `k` in `σ = k·|v|`: 0.3 vehicles (PHD), 0.2 pedestrians (METHODS.md §3).
        factor: f64,
        /// Lower bound on `σ`, so that a particle at rest can start moving.
        // Choice: the paper's σ = k·|v| is 0 at rest, which freezes a particle (and every
        // birth particle) forever; a floor keeps the model able to pick up motion.
        min_sigma: f64,
    },
    /// A fixed `σ` per axis, units per unit time (the paper's vehicle PF: 10 px).
    Absolute {
        /// Standard deviation of the velocity change per step.
        sigma: f64,
    },
    /// Piecewise-constant white-noise acceleration `a ~ N(0, sigma²)` per axis:
    /// `x += v·dt + a·dt²/2`, `v += a·dt`.
    Acceleration {
        /// Standard deviation of the acceleration, units per unit time².
        sigma: f64,
    },
}

/// The constant-velocity model with its velocity noise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ConstantVelocity {
    /// The noise on the velocity.
    pub noise: VelocityNoise,
}

impl ConstantVelocity {
    /// `σ = factor·|v|`, floored at `min_sigma`.
    pub const fn proportional(factor: f64, min_sigma: f64) -> Self {
        Self {
            noise: VelocityNoise::ProportionalToSpeed { factor, min_sigma },
        }
    }

    /// Fixed `σ`.
    pub const fn absolute(sigma: f64) -> Self {
        Self {
            noise: VelocityNoise::Absolute { sigma },
        }
    }

    /// White-noise acceleration with standard deviation `sigma`.
    pub const fn acceleration(sigma: f64) -> Self {
        Self {
            noise: VelocityNoise::Acceleration { sigma },
        }
    }

    /// Checks that every σ is finite and non-negative.
    pub fn validate(&self, config: &'static str) -> Result<()> {
        let values: &[f64] = match &self.noise {
            VelocityNoise::ProportionalToSpeed { factor, min_sigma } => &[*factor, *min_sigma],
            VelocityNoise::Absolute { sigma } | VelocityNoise::Acceleration { sigma } => &[*sigma],
        };
        if values.iter().all(|v| v.is_finite() && *v >= 0.0) {
            Ok(())
        } else {
            Err(Error::config(
                config,
                "motion",
                format!(
                    "noise parameters must be finite and ≥ 0, got {:?}",
                    self.noise
                ),
            ))
        }
    }

    /// Eq. 4: moves one particle by one step of `dt`.
    pub fn propagate_one(&self, s: &mut [f64; 4], dt: f64, rng: &mut Rng) {
        let n1: f64 = StandardNormal.sample(rng);
        let n2: f64 = StandardNormal.sample(rng);
        match self.noise {
            VelocityNoise::ProportionalToSpeed { factor, min_sigma } => {
                let sigma = (factor * s[2].hypot(s[3])).max(min_sigma);
                s[2] += sigma * n1;
                s[3] += sigma * n2;
                s[0] += s[2] * dt;
                s[1] += s[3] * dt;
            }
            VelocityNoise::Absolute { sigma } => {
                s[2] += sigma * n1;
                s[3] += sigma * n2;
                s[0] += s[2] * dt;
                s[1] += s[3] * dt;
            }
            VelocityNoise::Acceleration { sigma } => {
                let (ax, ay) = (sigma * n1, sigma * n2);
                s[0] += s[2] * dt + 0.5 * ax * dt * dt;
                s[1] += s[3] * dt + 0.5 * ay * dt * dt;
                s[2] += ax * dt;
                s[3] += ay * dt;
            }
        }
    }

    /// Moves every particle (flat arrays of equal length) by one step, in parallel.
    ///
    /// Each chunk of 256 particles draws from `rng_for(seed, stream, key(step, c))`,
    /// so the result does not depend on the number of threads.
    #[allow(clippy::too_many_arguments)]
    pub fn propagate(
        &self,
        x: &mut [f64],
        y: &mut [f64],
        vx: &mut [f64],
        vy: &mut [f64],
        dt: f64,
        seed: u64,
        stream: Stream,
        step: u64,
    ) {
        let c = super::CHUNK;
        x.par_chunks_mut(c)
            .zip(y.par_chunks_mut(c))
            .zip(vx.par_chunks_mut(c))
            .zip(vy.par_chunks_mut(c))
            .enumerate()
            .for_each(|(chunk, (((x, y), vx), vy))| {
                let mut rng = rng_for(seed, stream, chunk_key(step, chunk as u64));
                for i in 0..x.len() {
                    let mut s = [x[i], y[i], vx[i], vy[i]];
                    self.propagate_one(&mut s, dt, &mut rng);
                    [x[i], y[i], vx[i], vy[i]] = s;
                }
            });
    }
}

/// A sub-stream key for chunk `chunk` at step `step` (distinct for every pair we use).
pub(crate) fn chunk_key(step: u64, chunk: u64) -> u64 {
    (step << 24) ^ chunk
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::rng;

    #[test]
    fn zero_noise_moves_at_constant_velocity() {
        let m = ConstantVelocity::absolute(0.0);
        let mut s = [1.0, 2.0, 3.0, -1.0];
        let mut r = rng(0, Stream::Synthetic);
        m.propagate_one(&mut s, 2.0, &mut r);
        assert_eq!(s, [7.0, 0.0, 3.0, -1.0]);
    }

    #[test]
    fn proportional_noise_scales_with_speed() {
        let m = ConstantVelocity::proportional(0.3, 0.0);
        let mut r = rng(1, Stream::Synthetic);
        let n = 20_000;
        let mut sum2 = 0.0;
        for _ in 0..n {
            let mut s = [0.0, 0.0, 10.0, 0.0];
            m.propagate_one(&mut s, 1.0, &mut r);
            sum2 += (s[2] - 10.0).powi(2);
        }
        let sd = (sum2 / n as f64).sqrt();
        assert!((sd - 3.0).abs() < 0.1, "σ of v_x {sd}, expected 0.3·10 = 3");
        // At rest the floor applies; with a zero floor nothing moves.
        let mut s = [5.0, 5.0, 0.0, 0.0];
        m.propagate_one(&mut s, 1.0, &mut r);
        assert_eq!(s, [5.0, 5.0, 0.0, 0.0]);
    }

    #[test]
    fn acceleration_noise_has_the_textbook_position_variance() {
        // Var(x) after one step = σ²·dt⁴/4.
        let m = ConstantVelocity::acceleration(2.0);
        let mut r = rng(2, Stream::Synthetic);
        let n = 20_000;
        let mut sum2 = 0.0;
        for _ in 0..n {
            let mut s = [0.0, 0.0, 0.0, 0.0];
            m.propagate_one(&mut s, 1.0, &mut r);
            sum2 += s[0] * s[0];
        }
        let var = sum2 / n as f64;
        assert!((var - 1.0).abs() < 0.05, "var {var}, expected 4/4 = 1");
    }

    #[test]
    fn parallel_propagation_does_not_depend_on_thread_count() {
        let n = 1000;
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            let (mut x, mut y, mut vx, mut vy) =
                (vec![0.0; n], vec![0.0; n], vec![1.0; n], vec![2.0; n]);
            pool.install(|| {
                ConstantVelocity::proportional(0.3, 1.0).propagate(
                    &mut x,
                    &mut y,
                    &mut vx,
                    &mut vy,
                    1.0,
                    9,
                    Stream::Phd,
                    3,
                )
            });
            (x, y, vx, vy)
        };
        assert_eq!(run(1), run(4));
    }

    #[test]
    fn negative_sigma_is_rejected() {
        assert!(ConstantVelocity::absolute(-1.0).validate("Test").is_err());
        assert!(ConstantVelocity::absolute(10.0).validate("Test").is_ok());
    }
}
