//! The paper's parameter sweep (METHODS.md §1 "Defaults"): `A ∈ {0, 0.1, …, 1}`,
//! `B, C ∈ {0, 0.2, …, 10}` — 11 × 51 × 51 = 28 611 settings — scored by correct-match
//! rate over a folder of problems.
//!
//! Labels, support lists and the start depend only on `T, R, D` and the variant, so each
//! problem is built once ([`RelaxationProblem`]) and only the iterations run per setting.
//! Settings run in parallel; each setting's result is computed alone, so the table is the
//! same at any thread count.

use super::experiment::{Problem, problem_dirs};
use super::{RelaxationConfig, RelaxationProblem, UpdateWeights};
use crate::error::Result;
use rayon::prelude::*;
use std::path::Path;

/// Evenly spaced values `start, start + step, …` (`count` of them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Steps {
    /// First value.
    pub start: f64,
    /// Spacing.
    pub step: f64,
    /// Number of values.
    pub count: usize,
}

impl Steps {
    /// The `i`-th value, rounded to 1e-9 so that `0.1 · 3` prints as 0.3.
    pub fn value(&self, i: usize) -> f64 {
        ((self.start + self.step * i as f64) * 1e9).round() / 1e9
    }
}

/// The grid of `A, B, C` to sweep. `Default` is the paper's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepGrid {
    /// `A`: default 0 to 1 by 0.1.
    pub own_weight: Steps,
    /// `B`: default 0 to 10 by 0.2.
    pub forward_support_weight: Steps,
    /// `C`: default 0 to 10 by 0.2.
    pub backward_support_weight: Steps,
}

impl Default for SweepGrid {
    fn default() -> Self {
        let bc = Steps {
            start: 0.0,
            step: 0.2,
            count: 51,
        };
        Self {
            own_weight: Steps {
                start: 0.0,
                step: 0.1,
                count: 11,
            },
            forward_support_weight: bc,
            backward_support_weight: bc,
        }
    }
}

impl SweepGrid {
    /// Number of settings.
    pub fn len(&self) -> usize {
        self.own_weight.count
            * self.forward_support_weight.count
            * self.backward_support_weight.count
    }

    /// Whether the grid is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `n`-th setting, `A` slowest, `C` fastest.
    pub fn setting(&self, n: usize) -> UpdateWeights {
        let nc = self.backward_support_weight.count;
        let nb = self.forward_support_weight.count;
        UpdateWeights {
            own_weight: self.own_weight.value(n / (nb * nc)),
            forward_support_weight: self.forward_support_weight.value(n / nc % nb),
            backward_support_weight: self.backward_support_weight.value(n % nc),
        }
    }
}

/// One setting's score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepRow {
    /// `A, B, C`.
    pub weights: UpdateWeights,
    /// Frame-1 vehicles decided as in the truth, over all problems.
    pub correct: usize,
    /// Frame-1 vehicles over all problems.
    pub total: usize,
}

impl SweepRow {
    /// Correct-match rate (1 when there are no vehicles).
    pub fn rate(&self) -> f64 {
        if self.total == 0 {
            1.0
        } else {
            self.correct as f64 / self.total as f64
        }
    }
}

/// The rate surface and its best setting.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepResult {
    /// One row per setting, in grid order.
    pub rows: Vec<SweepRow>,
    /// The best setting. Choice: on ties the first in grid order (smallest `A`, then `B`,
    /// then `C`).
    pub best: Option<SweepRow>,
    /// Number of problems.
    pub problems: usize,
}

impl SweepResult {
    /// Writes the rate table as CSV, header `a,b,c,correct,total,rate`, atomically.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        crate::io::write_atomic(path, |w| {
            writeln!(w, "a,b,c,correct,total,rate")?;
            for r in &self.rows {
                let u = r.weights;
                writeln!(
                    w,
                    "{},{},{},{},{},{:.6}",
                    u.own_weight,
                    u.forward_support_weight,
                    u.backward_support_weight,
                    r.correct,
                    r.total,
                    r.rate()
                )?;
            }
            Ok(())
        })
    }
}

/// Sweeps `grid` over the problems under `problems_dir` (see [`problem_dirs`]) with the
/// other parameters (`T, R, D`, epsilon, iterations, variant, decision) from `cfg`.
/// `progress` gets (settings done, total).
///
/// For the unidirectional variants `C` has no effect (eq. 19 with `C = 0`); the grid is
/// swept all the same.
///
/// # Errors
/// A problem that cannot be loaded or built (see [`Problem::load`],
/// [`RelaxationProblem::new`]).
pub fn sweep(
    problems_dir: &Path,
    cfg: &RelaxationConfig,
    grid: &SweepGrid,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<SweepResult> {
    cfg.validate()?;
    let dirs = problem_dirs(problems_dir)?;
    let problems = dirs
        .par_iter()
        .map(|d| {
            let p = Problem::load(d)?;
            let r = RelaxationProblem::new(&p.frame1, &p.frame2, cfg)
                .map_err(|e| crate::Error::Invalid(format!("{}: {e}", d.display())))?;
            Ok((p, r))
        })
        .collect::<Result<Vec<_>>>()?;
    let unidirectional = !cfg.variant.bidirectional();
    let total = grid.len();
    let mut rows = Vec::with_capacity(total);
    const BATCH: usize = 512;
    let mut n = 0;
    while n < total {
        let end = (n + BATCH).min(total);
        let part: Vec<SweepRow> = (n..end)
            .into_par_iter()
            .map(|s| {
                let mut w = grid.setting(s);
                let reported = w;
                if unidirectional {
                    w.backward_support_weight = 0.0;
                }
                let (mut correct, mut vehicles) = (0, 0);
                for (p, r) in &problems {
                    let sol = r.solve(&w, cfg.epsilon, cfg.max_iterations);
                    correct += p.correct(&r.decide(&sol, cfg.decision).partner);
                    vehicles += p.frame1.len();
                }
                SweepRow {
                    weights: reported,
                    correct,
                    total: vehicles,
                }
            })
            .collect();
        rows.extend(part);
        n = end;
        progress(n as u64, total as u64);
    }
    let mut best: Option<SweepRow> = None;
    for r in &rows {
        if best.is_none_or(|b| r.correct > b.correct) {
            best = Some(*r);
        }
    }
    Ok(SweepResult {
        rows,
        best,
        problems: problems.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_papers_grid_has_28611_settings_in_order() {
        let g = SweepGrid::default();
        assert_eq!(g.len(), 28_611);
        let first = g.setting(0);
        assert_eq!(
            (
                first.own_weight,
                first.forward_support_weight,
                first.backward_support_weight
            ),
            (0.0, 0.0, 0.0)
        );
        let s = g.setting(1);
        assert_eq!(s.backward_support_weight, 0.2);
        let s = g.setting(51);
        assert_eq!(
            (s.forward_support_weight, s.backward_support_weight),
            (0.2, 0.0)
        );
        let last = g.setting(g.len() - 1);
        assert_eq!(
            (
                last.own_weight,
                last.forward_support_weight,
                last.backward_support_weight
            ),
            (1.0, 10.0, 10.0)
        );
        assert_eq!(g.setting(3 * 51 * 51).own_weight, 0.3);
    }

    #[test]
    fn sweep_over_the_fixtures_finds_a_perfect_setting() -> Result<()> {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/relaxation");
        // A small grid around the paper's values keeps the test quick.
        let grid = SweepGrid {
            own_weight: Steps {
                start: 0.0,
                step: 0.5,
                count: 3,
            },
            forward_support_weight: Steps {
                start: 0.0,
                step: 1.0,
                count: 3,
            },
            backward_support_weight: Steps {
                start: 0.0,
                step: 1.0,
                count: 3,
            },
        };
        let mut last = (0, 0);
        let res = sweep(
            Path::new(dir),
            &RelaxationConfig::default(),
            &grid,
            &mut |d, t| last = (d, t),
        )?;
        assert_eq!(last, (27, 27));
        assert_eq!(res.rows.len(), 27);
        assert_eq!(res.problems, 3);
        let best = res.best.expect("non-empty grid");
        assert_eq!(best.correct, best.total);
        // The paper's setting (A 0.5, B 1, C 1) is in the grid and is perfect too.
        let paper = res
            .rows
            .iter()
            .find(|r| r.weights == RelaxationConfig::default().weights())
            .expect("paper's setting");
        assert_eq!(paper.correct, paper.total);
        let tmp = tempfile::tempdir().map_err(|e| crate::Error::io("tmp", e))?;
        let out = tmp.path().join("s.csv");
        res.write_csv(&out)?;
        let text = std::fs::read_to_string(&out).map_err(|e| crate::Error::io(&out, e))?;
        assert_eq!(text.lines().count(), 28);
        assert!(
            text.starts_with("a,b,c,correct,total,rate\n0,0,0,"),
            "{text}"
        );
        Ok(())
    }
}
