//! Linear sum assignment (rectangular, minimum cost), as SciPy's
//! `scipy.optimize.linear_sum_assignment`.
//!
//! TrackEval matches boxes with SciPy's solver, and when several assignments are optimal the
//! one it returns decides which pairs count as matches (and so the ID switches and the HOTA
//! association counts). To reproduce TrackEval's numbers exactly we use the `lsap` crate, a
//! line-by-line port of SciPy's shortest-augmenting-path solver (Crouse 2016), which returns the
//! same assignment as SciPy on ties: it transposes tall matrices, scans columns in the same
//! order and breaks equal reduced costs in favour of a free column.
//!
//! It is the crate's only assignment solver: the metrics ([`crate::eval`]) and the
//! relaxation's optimal-assignment baseline
//! ([`crate::track::relaxation::baselines::optimal_assignment`]) both call it.

use crate::error::{Error, Result};

/// Minimum-cost assignment of the `n_rows × n_cols` matrix `cost` (row-major).
///
/// Returns `min(n_rows, n_cols)` pairs `(row, col)` sorted by row, exactly what SciPy's
/// `linear_sum_assignment(cost)` returns. An empty matrix gives no pairs.
///
/// # Errors
/// A cost that is NaN or infinite, or a `cost` whose length is not `n_rows · n_cols`.
pub fn linear_sum_assignment(
    cost: &[f64],
    n_rows: usize,
    n_cols: usize,
) -> Result<Vec<(usize, usize)>> {
    if cost.len() != n_rows * n_cols {
        return Err(Error::Invalid(format!(
            "assignment: cost matrix has {} entries, expected {n_rows} × {n_cols}",
            cost.len()
        )));
    }
    if n_rows == 0 || n_cols == 0 {
        return Ok(Vec::new());
    }
    if let Some(bad) = cost.iter().find(|c| !c.is_finite()) {
        return Err(Error::Invalid(format!(
            "assignment: cost matrix holds a non-finite value {bad}"
        )));
    }
    let owned = cost.to_vec();
    let (rows, cols) = lsap::solve(n_rows, n_cols, &owned, false).map_err(|e| {
        Error::Invalid(format!(
            "assignment: solver failed ({e:?}) on a finite matrix"
        ))
    })?;
    Ok(rows.into_iter().zip(cols).collect())
}

/// Maximum-score assignment, solved as SciPy is called by TrackEval:
/// `linear_sum_assignment(-score)`.
///
/// # Errors
/// As [`linear_sum_assignment`].
pub fn max_score_assignment(
    score: &[f64],
    n_rows: usize,
    n_cols: usize,
) -> Result<Vec<(usize, usize)>> {
    let negated: Vec<f64> = score.iter().map(|s| -s).collect();
    linear_sum_assignment(&negated, n_rows, n_cols)
}

/// The pairs with a positive score in SciPy's maximum-score assignment
/// (`linear_sum_assignment(-score)`, then the pairs whose score is above 0), sorted by row.
///
/// Fast path, exact whatever the solver's tie-breaking: when every row and every column
/// holds at most one positive score, each positive pair is in *every* optimal assignment
/// (dropping it loses a positive score and gains nothing, since its row and column have no
/// other positive entry), so the answer is the positive pairs themselves. Only frames where
/// boxes compete run the solver, on the full matrix as TrackEval does.
///
/// # Errors
/// As [`linear_sum_assignment`].
pub fn positive_max_score_pairs(
    score: &[f64],
    n_rows: usize,
    n_cols: usize,
) -> Result<Vec<(usize, usize)>> {
    if score.len() != n_rows * n_cols {
        return linear_sum_assignment(score, n_rows, n_cols);
    }
    let mut row_count = vec![0u32; n_rows];
    let mut col_count = vec![0u32; n_cols];
    let mut pairs = Vec::new();
    let mut competing = false;
    for i in 0..n_rows {
        for j in 0..n_cols {
            let s = score[i * n_cols + j];
            if s.is_nan() || s.is_infinite() {
                return linear_sum_assignment(score, n_rows, n_cols);
            }
            if s > 0.0 {
                row_count[i] += 1;
                col_count[j] += 1;
                competing |= row_count[i] > 1 || col_count[j] > 1;
                pairs.push((i, j));
            }
        }
    }
    if !competing {
        return Ok(pairs);
    }
    Ok(max_score_assignment(score, n_rows, n_cols)?
        .into_iter()
        .filter(|&(i, j)| score[i * n_cols + j] > 0.0)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Stream, rng};
    use rand::RngExt;

    /// Minimum total cost over all injective maps of the smaller side, by enumeration.
    fn brute_force_min(cost: &[f64], n_rows: usize, n_cols: usize) -> f64 {
        fn rec(
            cost: &[f64],
            n_rows: usize,
            n_cols: usize,
            row: usize,
            used: &mut Vec<bool>,
            transpose: bool,
        ) -> f64 {
            let (nr, nc) = if transpose {
                (n_cols, n_rows)
            } else {
                (n_rows, n_cols)
            };
            if row == nr {
                return 0.0;
            }
            let mut best = f64::INFINITY;
            for c in 0..nc {
                if used[c] {
                    continue;
                }
                used[c] = true;
                let v = if transpose {
                    cost[c * n_cols + row]
                } else {
                    cost[row * n_cols + c]
                };
                best = best.min(v + rec(cost, n_rows, n_cols, row + 1, used, transpose));
                used[c] = false;
            }
            best
        }
        let transpose = n_rows > n_cols;
        let nc = if transpose { n_rows } else { n_cols };
        rec(cost, n_rows, n_cols, 0, &mut vec![false; nc], transpose)
    }

    #[test]
    fn matches_brute_force_on_random_rectangular_matrices() -> Result<()> {
        let mut r = rng(11, Stream::Synthetic);
        for _ in 0..300 {
            let n_rows = r.random_range(1..6usize);
            let n_cols = r.random_range(1..6usize);
            // Small integer costs make ties common.
            let cost: Vec<f64> = (0..n_rows * n_cols)
                .map(|_| f64::from(r.random_range(0..4u8)))
                .collect();
            let pairs = linear_sum_assignment(&cost, n_rows, n_cols)?;
            assert_eq!(pairs.len(), n_rows.min(n_cols));
            let total: f64 = pairs.iter().map(|&(i, j)| cost[i * n_cols + j]).sum();
            assert_eq!(total, brute_force_min(&cost, n_rows, n_cols));
            assert!(pairs.windows(2).all(|w| w[0].0 < w[1].0));
        }
        Ok(())
    }

    #[test]
    fn constant_matrix_gives_the_identity_as_scipy_does() -> Result<()> {
        assert_eq!(
            linear_sum_assignment(&[0.0; 9], 3, 3)?,
            [(0, 0), (1, 1), (2, 2)]
        );
        // Tall matrix: transposed internally, pairs returned sorted by row.
        assert_eq!(
            linear_sum_assignment(&[1.0, 0.0, 0.0, 1.0, 5.0, 5.0], 3, 2)?,
            [(0, 1), (1, 0)]
        );
        Ok(())
    }

    #[test]
    fn fast_path_gives_the_solver_s_positive_pairs() -> Result<()> {
        let mut r = rng(12, Stream::Synthetic);
        for _ in 0..500 {
            let n_rows = r.random_range(0..7usize);
            let n_cols = r.random_range(0..7usize);
            // Sparse non-negative scores with ties, as IoU-like matrices.
            let score: Vec<f64> = (0..n_rows * n_cols)
                .map(|_| {
                    if r.random_range(0..4u8) == 0 {
                        f64::from(r.random_range(1..3u8))
                    } else {
                        0.0
                    }
                })
                .collect();
            let full: Vec<(usize, usize)> = max_score_assignment(&score, n_rows, n_cols)?
                .into_iter()
                .filter(|&(i, j)| score[i * n_cols + j] > 0.0)
                .collect();
            assert_eq!(positive_max_score_pairs(&score, n_rows, n_cols)?, full);
        }
        Ok(())
    }

    #[test]
    fn maximisation_negates() -> Result<()> {
        assert_eq!(
            max_score_assignment(&[0.9, 0.1, 0.8, 0.7], 2, 2)?,
            [(0, 0), (1, 1)]
        );
        Ok(())
    }

    #[test]
    fn bad_matrices_are_errors() {
        assert!(linear_sum_assignment(&[f64::NAN], 1, 1).is_err());
        assert!(linear_sum_assignment(&[1.0, 2.0], 1, 3).is_err());
        assert!(matches!(
            linear_sum_assignment(&[], 0, 4).as_deref(),
            Ok([])
        ));
    }
}
