//! Fixed-lag smoothing of the labels' existence, for the count (issue 14 target 2).
//!
//! The filter's count Σw at frame t uses the detections up to t only. A person the
//! detector misses for one frame loses most of a label's weight (Bernoulli rule: `w` → `(1
//! − p_D)·w̃ / (1 − p_D·w̃)`) although the next frame detects them again, and a birth on a
//! false detection weighs 0.31 until the frames after it show nothing there. Both are
//! decided by the next few frames. This smoother reads each label as a Bernoulli component
//! (as [`super::map_cardinality`] does) with no rebirth and computes its existence at frame
//! t given the frames up to `t + L`: the forward-backward smoother of a Bernoulli filter
//! (Vo, Vo, Cantoni & Ristic, "Bernoulli forward-backward smoothing for joint target
//! detection and tracking", IEEE TSP 59(9), 2011) with the birth term of a label that
//! already exists removed.
//!
//! No model beyond the filter's own is needed: the evidence of frame j for a label is the
//! odds ratio of its weight after the update to its weight after the survival step,
//! `ℓ_j = odds(r_j) / odds(p_s·r_{j−1})`, which is the Bernoulli update's likelihood ratio
//! (`1 − p_D` for a miss). A label absent at frame j (deleted, merged) has `ℓ_j = 0`.
//! Backwards, with `β_{T+1} = 1`:
//!
//! `β_j = ℓ_j · (p_s·β_{j+1} + 1 − p_s)`, `r_{t|T} = r_t·B / (r_t·B + 1 − r_t)`,
//! `B = p_s·β_{t+1} + 1 − p_s`.
//!
//! The smoothed count is Σ r_{t|T} (and its mode), reported `L` frames late.
//!
//! Choice: a label heavier than 1 (the paper's PHD update can give one label two objects'
//! mass) is smoothed on its first object (`min(w, 1)`); the mass above 1 passes through.

use std::collections::{BTreeMap, VecDeque};

/// One frame's label weights.
pub type LabelWeights = BTreeMap<u32, f64>;

/// Odds of a probability kept inside (0, 1), so that certain labels stay finite.
fn odds(r: f64) -> f64 {
    let r = r.clamp(1e-12, 1.0 - 1e-12);
    r / (1.0 - r)
}

/// The existence of one label at the first frame of `weights` given the later ones
/// (`None`: the label is gone at that frame), with survival probability `p_s`.
#[must_use]
pub fn smoothed_existence(weights: &[Option<f64>], p_s: f64) -> f64 {
    let Some(&Some(r0)) = weights.first() else {
        return 0.0;
    };
    if weights.len() == 1 {
        return r0;
    }
    let mut beta = 1.0f64;
    for j in (1..weights.len()).rev() {
        let evidence = match (weights[j - 1], weights[j]) {
            (Some(prev), Some(now)) => odds(now.min(1.0)) / odds(p_s * prev.min(1.0)),
            _ => 0.0,
        };
        beta = evidence * (p_s * beta + 1.0 - p_s);
    }
    let b = p_s * beta + 1.0 - p_s;
    let r = r0.clamp(0.0, 1.0);
    let s = if b.is_finite() {
        r * b / (r * b + 1.0 - r)
    } else {
        1.0
    };
    // NaN only from a NaN weight: count it as the filter would, nothing.
    let s = if s.is_nan() { 0.0 } else { s };
    s + (r0 - 1.0).max(0.0)
}

/// Fixed-lag smoother over a run: push each frame's label weights, get back the smoothed
/// weights of the frame `lag` frames earlier.
#[derive(Debug, Clone)]
pub struct ExistenceSmoother {
    lag: usize,
    p_s: f64,
    window: VecDeque<LabelWeights>,
}

impl ExistenceSmoother {
    /// A smoother with `lag` frames of look-ahead (0: the filter's own weights) and the
    /// filter's survival probability.
    #[must_use]
    pub fn new(lag: usize, survival_prob: f64) -> Self {
        Self {
            lag,
            p_s: survival_prob,
            window: VecDeque::with_capacity(lag + 1),
        }
    }

    /// Adds a frame; returns the smoothed weights of the frame `lag` frames back, once
    /// there is one.
    pub fn push(&mut self, weights: LabelWeights) -> Option<Vec<f64>> {
        self.window.push_back(weights);
        if self.window.len() > self.lag {
            let out = self.oldest();
            self.window.pop_front();
            Some(out)
        } else {
            None
        }
    }

    /// The smoothed weights of the frames still held, oldest first, each with the
    /// frames after it that there are (the end of a run).
    pub fn finish(&mut self) -> Vec<Vec<f64>> {
        let mut out = Vec::with_capacity(self.window.len());
        while !self.window.is_empty() {
            out.push(self.oldest());
            self.window.pop_front();
        }
        out
    }

    fn oldest(&self) -> Vec<f64> {
        let Some(first) = self.window.front() else {
            return Vec::new();
        };
        first
            .iter()
            .map(|(label, &w)| {
                let chain: Vec<Option<f64>> = std::iter::once(Some(w))
                    .chain(self.window.iter().skip(1).map(|f| f.get(label).copied()))
                    .collect();
                smoothed_existence(&chain, self.p_s)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// P(E_0 = 1 | evidence) by enumerating every existence path of a label that cannot be
    /// reborn: prior `r0`, survival `p_s`, and likelihood ratio `l[j]` for frame j ≥ 1.
    fn brute_force(r0: f64, l: &[f64], p_s: f64) -> f64 {
        let (mut alive, mut total) = (0.0, 0.0);
        // Death after k frames alive (k = 1..=n+1, n+1: alive throughout), or absent at 0.
        let n = l.len();
        for k in 1..=n + 1 {
            let mut p = r0;
            for (j, lj) in l.iter().enumerate() {
                if j + 1 < k {
                    p *= p_s * lj;
                } else if j + 1 == k {
                    p *= 1.0 - p_s;
                }
            }
            alive += p;
            total += p;
        }
        total += 1.0 - r0;
        alive / total
    }

    /// The Bernoulli update's weights for likelihood ratios `l` from `r0`.
    fn forward(r0: f64, l: &[f64], p_s: f64) -> Vec<Option<f64>> {
        let mut r = r0;
        let mut out = vec![Some(r)];
        for &lj in l {
            let pred = p_s * r;
            r = lj * pred / (lj * pred + 1.0 - pred);
            out.push(Some(r));
        }
        out
    }

    #[test]
    fn the_recursion_matches_enumerating_every_existence_path() {
        let cases: [(f64, &[f64]); 6] = [
            (0.31, &[0.1]),
            (0.31, &[0.1, 0.1, 0.1]),
            (0.9, &[0.05, 40.0]),
            (0.5, &[3.0, 0.05, 0.05, 25.0]),
            (0.99, &[0.05, 0.05, 0.05, 0.05, 0.05]),
            (0.2, &[]),
        ];
        for p_s in [0.9, 0.99] {
            for (r0, l) in cases {
                let weights = forward(r0, l, p_s);
                let got = smoothed_existence(&weights, p_s);
                let want = brute_force(r0, l, p_s);
                assert!(
                    (got - want).abs() < 1e-9,
                    "r0 {r0}, l {l:?}, p_s {p_s}: {got} against {want}"
                );
            }
        }
    }

    #[test]
    fn a_miss_between_detections_is_an_object_and_a_label_that_dies_is_not() {
        let p_s = 0.99;
        // Detected, missed once (p_D 0.95), detected again.
        let w = forward(0.99, &[0.05, 50.0], p_s);
        let missed = w[1].unwrap_or(0.0);
        assert!(missed < 0.9, "the filter's weight {missed}");
        assert!(smoothed_existence(&w[1..], p_s) > 0.99);
        // A birth on a false detection, then gone.
        let gone = [Some(0.31), Some(0.02), None];
        assert!(smoothed_existence(&gone, p_s) < 0.02);
        // With no later frame the smoother is the filter.
        assert!((smoothed_existence(&[Some(0.42)], p_s) - 0.42).abs() < 1e-12);
        // The mass above one object passes through.
        assert!((smoothed_existence(&[Some(1.7)], p_s) - 1.7).abs() < 1e-9);
    }

    #[test]
    fn the_fixed_lag_smoother_returns_each_frame_once_in_order() {
        let frames: Vec<LabelWeights> = (0..5)
            .map(|k| {
                [(1, 0.9), (2, 0.1 * f64::from(k + 1))]
                    .into_iter()
                    .collect()
            })
            .collect();
        for lag in 0..4 {
            let mut s = ExistenceSmoother::new(lag, 0.99);
            let mut out: Vec<Vec<f64>> = frames.iter().filter_map(|f| s.push(f.clone())).collect();
            assert_eq!(out.len(), frames.len().saturating_sub(lag));
            out.extend(s.finish());
            assert_eq!(out.len(), frames.len(), "lag {lag}");
            // Frame by frame against the function on the same window.
            for (t, o) in out.iter().enumerate() {
                let end = (t + lag + 1).min(frames.len());
                for (i, label) in [1u32, 2].iter().enumerate() {
                    let chain: Vec<Option<f64>> = frames[t..end]
                        .iter()
                        .map(|f| f.get(label).copied())
                        .collect();
                    assert_eq!(
                        o[i],
                        smoothed_existence(&chain, 0.99),
                        "lag {lag} frame {t}"
                    );
                }
            }
            if lag == 0 {
                assert_eq!(out[3], vec![0.9, 0.4]);
            }
        }
    }
}
