//! Resampling: systematic and stratified (METHODS.md §3 f; the paper uses stratified).
//!
//! Both draw `n` ancestors from weights `w` (not necessarily normalised) so that particle `i`
//! is copied `n·w_i/Σw` times in expectation (unbiased), with far less variance than
//! multinomial resampling. Stratified draws one uniform per stratum `[k/n, (k+1)/n)`;
//! systematic shares one uniform offset across all strata.

use crate::rng::Rng;
use rand::RngExt as _;
use serde::{Deserialize, Serialize};

/// Which resampling scheme to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResamplingScheme {
    /// One uniform per stratum (the paper's choice, METHODS.md §3 f).
    #[default]
    Stratified,
    /// One uniform shared by all strata.
    Systematic,
}

/// Writes `n` ancestor indices into `out` (sorted ascending) drawn from the weights `w` with
/// `scheme`. Leaves `out` empty when `n` is 0 or the total weight is not positive.
pub fn resample(
    scheme: ResamplingScheme,
    w: &[f64],
    n: usize,
    rng: &mut Rng,
    out: &mut Vec<usize>,
) {
    out.clear();
    let total: f64 = w.iter().sum();
    if n == 0 || w.is_empty() || total.is_nan() || total <= 0.0 || !total.is_finite() {
        return;
    }
    out.reserve(n);
    let step = total / n as f64;
    let shared: f64 = rng.random();
    let mut cumulative = w[0];
    let mut i = 0;
    for k in 0..n {
        let u = match scheme {
            ResamplingScheme::Stratified => rng.random::<f64>(),
            ResamplingScheme::Systematic => shared,
        };
        let target = (k as f64 + u) * step;
        while cumulative < target && i + 1 < w.len() {
            i += 1;
            cumulative += w[i];
        }
        out.push(i);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Stream, rng};

    const SCHEMES: [ResamplingScheme; 2] =
        [ResamplingScheme::Stratified, ResamplingScheme::Systematic];

    #[test]
    fn resampling_keeps_the_requested_count() {
        let mut r = rng(3, Stream::Synthetic);
        let mut out = Vec::new();
        for scheme in SCHEMES {
            for n in [0, 1, 7, 70, 1000] {
                resample(scheme, &[0.1, 0.0, 3.0, 0.5], n, &mut r, &mut out);
                assert_eq!(out.len(), n);
                assert!(out.windows(2).all(|p| p[0] <= p[1]));
                assert!(!out.contains(&1), "zero-weight particle chosen");
            }
        }
    }

    #[test]
    fn resampling_is_unbiased() {
        // Mean offspring count of particle i over many draws ≈ n·w_i/Σw.
        let w = [0.05, 0.3, 0.0, 0.15, 0.42, 0.08];
        let total: f64 = w.iter().sum();
        let n = 17;
        let reps = 20_000;
        let mut r = rng(4, Stream::Synthetic);
        let mut out = Vec::new();
        for scheme in SCHEMES {
            let mut counts = [0.0f64; 6];
            for _ in 0..reps {
                resample(scheme, &w, n, &mut r, &mut out);
                for &i in &out {
                    counts[i] += 1.0;
                }
            }
            for i in 0..w.len() {
                let mean = counts[i] / reps as f64;
                let expected = n as f64 * w[i] / total;
                assert!(
                    (mean - expected).abs() < 0.02,
                    "{scheme:?}: particle {i} copied {mean} times on average, expected {expected}"
                );
            }
        }
    }

    #[test]
    fn low_variance_schemes_never_stray_more_than_one_copy() {
        // Both schemes give floor or ceil of n·w_i/Σw... up to one extra copy at stratum edges.
        let w = [0.25, 0.25, 0.25, 0.25];
        let mut r = rng(5, Stream::Synthetic);
        let mut out = Vec::new();
        for scheme in SCHEMES {
            resample(scheme, &w, 8, &mut r, &mut out);
            for i in 0..4 {
                let c = out.iter().filter(|&&j| j == i).count();
                assert!((1..=3).contains(&c), "{scheme:?} gave {c} copies of {i}");
            }
        }
    }

    #[test]
    fn degenerate_weights_give_nothing() {
        let mut r = rng(6, Stream::Synthetic);
        let mut out = vec![1];
        resample(
            ResamplingScheme::Stratified,
            &[0.0, 0.0],
            5,
            &mut r,
            &mut out,
        );
        assert!(out.is_empty());
        resample(
            ResamplingScheme::Stratified,
            &[f64::NAN],
            5,
            &mut r,
            &mut out,
        );
        assert!(out.is_empty());
    }
}
