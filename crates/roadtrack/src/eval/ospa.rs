//! OSPA and GOSPA distances between finite point sets, per time step, for the filters
//! (seed 004; METHODS.md §3 evaluates them by RMSE only, these are the standard
//! set-level measures that also charge for wrong counts).
//!
//! With `X` of size `m`, `Y` of size `n`, `m ≤ n` (swap otherwise), cut-off distance
//! `d_c(x, y) = min(c, ‖x − y‖)` and permutations `π` of `Y`'s indices:
//!
//! ```text
//! OSPA_p,c(X, Y)    = ( (1/n) · [ min_π Σ_{i≤m} d_c(x_i, y_π(i))^p + c^p (n − m) ] )^(1/p)
//! GOSPA_p,c,α(X, Y) = ( min_π Σ_{i≤m} d_c(x_i, y_π(i))^p + (c^p / α) (n − m) )^(1/p)
//! ```
//!
//! (Schuhmacher, Vo & Vo 2008; Rahmathullah, García-Fernández & Svensson 2017.)
//! OSPA of two empty sets is 0 and of one empty set `c`; GOSPA of two empty sets is 0.
//! With `α = 2` GOSPA splits into localisation error of the assigned pairs (those closer
//! than `c`), missed targets and false targets, each costing `c^p / 2`.

use crate::assignment::linear_sum_assignment;
use crate::error::{Error, Result};
use crate::geometry::Point;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of OSPA and GOSPA.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OspaConfig {
    /// Cut-off `c`, in the points' units. Default 20.
    // Choice: 20 px is about a pedestrian's width in the paper's 640 × 480 video (seed 004);
    // the papers do not use OSPA, so there is no value to follow.
    pub cutoff: f64,
    /// Order `p ≥ 1`. Default 1 (the error reads in the points' units).
    pub order: f64,
    /// GOSPA's `α ∈ (0, 2]`. Default 2 (the only value with the miss/false split).
    pub alpha: f64,
}

impl Default for OspaConfig {
    fn default() -> Self {
        Self {
            cutoff: 20.0,
            order: 1.0,
            alpha: 2.0,
        }
    }
}

impl OspaConfig {
    /// Checks ranges.
    ///
    /// # Errors
    /// `cutoff ≤ 0`, `order < 1`, `alpha` outside `(0, 2]`, or a non-finite value.
    pub fn validate(&self) -> Result<()> {
        if !(self.cutoff > 0.0 && self.cutoff.is_finite()) {
            return Err(Error::config(
                "OspaConfig",
                "cutoff",
                format!("{} must be > 0", self.cutoff),
            ));
        }
        if !(self.order >= 1.0 && self.order.is_finite()) {
            return Err(Error::config(
                "OspaConfig",
                "order",
                format!("{} must be ≥ 1", self.order),
            ));
        }
        if !(self.alpha > 0.0 && self.alpha <= 2.0) {
            return Err(Error::config(
                "OspaConfig",
                "alpha",
                format!("{} outside (0, 2]", self.alpha),
            ));
        }
        Ok(())
    }
}

/// GOSPA and its parts.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Gospa {
    /// The distance.
    pub distance: f64,
    /// `Σ d^p` over assigned pairs closer than the cut-off (before the `1/p` power).
    pub localisation: f64,
    /// Truth points left unassigned (α = 2 split; pairs at ≥ c count as one miss and one false).
    pub missed: usize,
    /// Estimated points left unassigned.
    pub false_targets: usize,
}

/// The optimal assignment of the smaller set: `Σ d_c^p` and the pairs' distances.
fn assign(x: &[Point], y: &[Point], cfg: &OspaConfig) -> Result<(f64, Vec<f64>)> {
    let cost: Vec<f64> = x
        .iter()
        .flat_map(|a| {
            y.iter()
                .map(move |b| a.distance(*b).min(cfg.cutoff).powf(cfg.order))
        })
        .collect();
    let pairs = linear_sum_assignment(&cost, x.len(), y.len())?;
    let total = pairs.iter().map(|&(i, j)| cost[i * y.len() + j]).sum();
    let dists = pairs.iter().map(|&(i, j)| x[i].distance(y[j])).collect();
    Ok((total, dists))
}

/// OSPA distance between `x` and `y`.
///
/// # Errors
/// An invalid config or a non-finite coordinate.
pub fn ospa(x: &[Point], y: &[Point], cfg: &OspaConfig) -> Result<f64> {
    cfg.validate()?;
    check(x)?;
    check(y)?;
    let (small, large) = if x.len() <= y.len() { (x, y) } else { (y, x) };
    let n = large.len();
    if n == 0 {
        return Ok(0.0);
    }
    let (total, _) = assign(small, large, cfg)?;
    let card = cfg.cutoff.powf(cfg.order) * (n - small.len()) as f64;
    Ok(((total + card) / n as f64).powf(1.0 / cfg.order))
}

/// GOSPA distance from `truth` to `estimate`, with its miss / false-target split.
///
/// # Errors
/// As [`ospa`].
pub fn gospa(truth: &[Point], estimate: &[Point], cfg: &OspaConfig) -> Result<Gospa> {
    cfg.validate()?;
    check(truth)?;
    check(estimate)?;
    let (small, large) = if truth.len() <= estimate.len() {
        (truth, estimate)
    } else {
        (estimate, truth)
    };
    let (total, dists) = assign(small, large, cfg)?;
    let cp = cfg.cutoff.powf(cfg.order);
    let distance =
        (total + cp / cfg.alpha * (large.len() - small.len()) as f64).powf(1.0 / cfg.order);
    let close: Vec<f64> = dists.into_iter().filter(|&d| d < cfg.cutoff).collect();
    Ok(Gospa {
        distance,
        localisation: close.iter().map(|d| d.powf(cfg.order)).sum(),
        missed: truth.len() - close.len(),
        false_targets: estimate.len() - close.len(),
    })
}

fn check(p: &[Point]) -> Result<()> {
    match p.iter().find(|q| !(q.x.is_finite() && q.y.is_finite())) {
        Some(q) => Err(Error::Invalid(format!(
            "OSPA: non-finite point ({}, {})",
            q.x, q.y
        ))),
        None => Ok(()),
    }
}

/// OSPA and GOSPA at one time step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OspaStep {
    /// The step.
    pub step: u64,
    /// Number of truth points.
    pub n_truth: usize,
    /// Number of estimates.
    pub n_estimates: usize,
    /// OSPA.
    pub ospa: f64,
    /// GOSPA.
    pub gospa: Gospa,
}

/// OSPA and GOSPA at every step present in either input, in step order. Inputs are
/// `(step, point)`; for example truth read with [`crate::io::points::read_measurements`]
/// (the `step,x,y` layout) and a filter's estimates.
///
/// # Errors
/// As [`ospa`].
pub fn ospa_series(
    truth: &[(u64, Point)],
    estimates: &[(u64, Point)],
    cfg: &OspaConfig,
) -> Result<Vec<OspaStep>> {
    let mut by_step: BTreeMap<u64, (Vec<Point>, Vec<Point>)> = BTreeMap::new();
    for &(s, p) in truth {
        by_step.entry(s).or_default().0.push(p);
    }
    for &(s, p) in estimates {
        by_step.entry(s).or_default().1.push(p);
    }
    by_step
        .into_iter()
        .map(|(step, (t, e))| {
            Ok(OspaStep {
                step,
                n_truth: t.len(),
                n_estimates: e.len(),
                ospa: ospa(&t, &e, cfg)?,
                gospa: gospa(&t, &e, cfg)?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Stream, rng};
    use proptest::prelude::*;
    use rand::RngExt;

    fn p(x: f64, y: f64) -> Point {
        Point::new(x, y)
    }

    /// Minimum of `Σ d_c^p` over injections of the smaller set, by trying every permutation.
    fn brute(x: &[Point], y: &[Point], c: f64, order: f64) -> f64 {
        let (s, l) = if x.len() <= y.len() { (x, y) } else { (y, x) };
        fn rec(s: &[Point], l: &[Point], i: usize, used: &mut [bool], c: f64, o: f64) -> f64 {
            if i == s.len() {
                return 0.0;
            }
            let mut best = f64::INFINITY;
            for j in 0..l.len() {
                if !used[j] {
                    used[j] = true;
                    let d = s[i].distance(l[j]).min(c).powf(o);
                    best = best.min(d + rec(s, l, i + 1, used, c, o));
                    used[j] = false;
                }
            }
            best
        }
        rec(s, l, 0, &mut vec![false; l.len()], c, order)
    }

    #[test]
    fn hand_computed_cases() -> Result<()> {
        let cfg = OspaConfig {
            cutoff: 10.0,
            order: 2.0,
            alpha: 2.0,
        };
        // Identical sets: 0. Empty vs empty: 0. Empty vs one: c.
        assert_eq!(ospa(&[p(1.0, 1.0)], &[p(1.0, 1.0)], &cfg)?, 0.0);
        assert_eq!(ospa(&[], &[], &cfg)?, 0.0);
        assert_eq!(ospa(&[], &[p(0.0, 0.0)], &cfg)?, 10.0);
        // One pair 3-4-5 apart plus one unmatched: sqrt((25 + 100) / 2).
        let x = [p(0.0, 0.0)];
        let y = [p(3.0, 4.0), p(50.0, 50.0)];
        assert!((ospa(&x, &y, &cfg)? - (125.0f64 / 2.0).sqrt()).abs() < 1e-12);
        // GOSPA: sqrt(25 + 100 / 2); one false target, no miss.
        let g = gospa(&x, &y, &cfg)?;
        assert!((g.distance - 75.0f64.sqrt()).abs() < 1e-12);
        assert_eq!((g.localisation, g.missed, g.false_targets), (25.0, 0, 1));
        // A pair beyond the cut-off counts as one miss and one false target.
        let g = gospa(&[p(0.0, 0.0)], &[p(30.0, 0.0)], &cfg)?;
        assert_eq!((g.missed, g.false_targets, g.distance), (1, 1, 10.0));
        // p = 1: OSPA is the mean cut-off distance.
        let c1 = OspaConfig { order: 1.0, ..cfg };
        assert_eq!(
            ospa(
                &[p(0.0, 0.0), p(10.0, 0.0)],
                &[p(1.0, 0.0), p(12.0, 0.0)],
                &c1
            )?,
            1.5
        );
        Ok(())
    }

    fn pts(r: &mut crate::rng::Rng, n: usize) -> Vec<Point> {
        (0..n)
            .map(|_| p(r.random_range(0.0..40.0), r.random_range(0.0..40.0)))
            .collect()
    }

    #[test]
    fn matches_a_brute_force_reference_on_random_sets() -> Result<()> {
        let mut r = rng(3, Stream::Synthetic);
        for _ in 0..200 {
            let cfg = OspaConfig {
                cutoff: r.random_range(1.0..30.0),
                order: [1.0, 2.0, 3.0][r.random_range(0..3usize)],
                alpha: 2.0,
            };
            let (nx, ny) = (r.random_range(0..6usize), r.random_range(0..6usize));
            let x = pts(&mut r, nx);
            let y = pts(&mut r, ny);
            let n = nx.max(ny);
            let b = brute(&x, &y, cfg.cutoff, cfg.order);
            let cp = cfg.cutoff.powf(cfg.order);
            let gap = nx.abs_diff(ny) as f64;
            let want_ospa = if n == 0 {
                0.0
            } else {
                ((b + cp * gap) / n as f64).powf(1.0 / cfg.order)
            };
            let want_gospa = (b + cp / 2.0 * gap).powf(1.0 / cfg.order);
            assert!((ospa(&x, &y, &cfg)? - want_ospa).abs() < 1e-9);
            assert!((ospa(&y, &x, &cfg)? - want_ospa).abs() < 1e-9, "symmetric");
            assert!((gospa(&x, &y, &cfg)?.distance - want_gospa).abs() < 1e-9);
        }
        Ok(())
    }

    proptest! {
        /// OSPA is a metric bounded by c: the triangle inequality holds.
        #[test]
        fn ospa_obeys_the_triangle_inequality(
            a in prop::collection::vec((0.0..50.0f64, 0.0..50.0f64), 0..5),
            b in prop::collection::vec((0.0..50.0f64, 0.0..50.0f64), 0..5),
            c in prop::collection::vec((0.0..50.0f64, 0.0..50.0f64), 0..5),
        ) {
            let to = |v: &Vec<(f64, f64)>| v.iter().map(|&(x, y)| p(x, y)).collect::<Vec<_>>();
            let (a, b, c) = (to(&a), to(&b), to(&c));
            let cfg = OspaConfig::default();
            let ab = ospa(&a, &b, &cfg).unwrap_or(f64::NAN);
            let bc = ospa(&b, &c, &cfg).unwrap_or(f64::NAN);
            let ac = ospa(&a, &c, &cfg).unwrap_or(f64::NAN);
            prop_assert!(ac <= ab + bc + 1e-9 && ac <= cfg.cutoff + 1e-12);
        }
    }

    #[test]
    fn series_covers_every_step_and_bad_configs_fail() -> Result<()> {
        let s = ospa_series(
            &[(1, p(0.0, 0.0)), (3, p(1.0, 1.0))],
            &[(2, p(0.0, 0.0))],
            &OspaConfig::default(),
        )?;
        assert_eq!(s.iter().map(|x| x.step).collect::<Vec<_>>(), [1, 2, 3]);
        assert_eq!((s[0].ospa, s[2].n_truth), (20.0, 1));
        assert!(
            ospa(
                &[],
                &[],
                &OspaConfig {
                    order: 0.5,
                    ..OspaConfig::default()
                }
            )
            .is_err()
        );
        assert!(ospa(&[p(f64::NAN, 0.0)], &[], &OspaConfig::default()).is_err());
        Ok(())
    }
}
