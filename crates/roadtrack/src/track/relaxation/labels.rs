//! Candidate labels (METHODS.md §1 "Labels"; eqs. 2–6 and 12).
//!
//! A real label of frame-1 vehicle `a_i` is the displacement `λ_ik = (x_k − x_i, y_k − y_i)`
//! to a frame-2 vehicle `b_k` inside the square gate `|Δx| ≤ D, |Δy| ≤ D` (eq. 3); every
//! vehicle also has the no-match label `λ_p`, which is not stored here (it is the extra
//! slot `none` of [`super::Probabilities`]). Backward labels `λ'_ki` of `b_k` are the same
//! pairs seen from frame 2; the gate is symmetric, so they are the transpose.
//!
//! Storage is compressed rows: the real labels of `a_i` are `fwd_start[i]..fwd_start[i+1]`,
//! sorted by frame-2 index; those of `b_k` are `bwd_start[k]..bwd_start[k+1]`, sorted by
//! frame-1 index. `fwd_twin[e]` is the backward label of the same pair, and back.

use super::grid::PointGrid;
use crate::error::{Error, Result};
use crate::geometry::Point;
use rayon::prelude::*;

/// Vehicles per parallel block when building; below this the work runs on one thread.
pub(crate) const PAR_BLOCK: usize = 2048;

/// Eq. 3: whether displacement `d` lies inside the square gate of half-width `gate`.
pub fn in_gate(d: [f64; 2], gate: f64) -> bool {
    d[0].abs() <= gate && d[1].abs() <= gate
}

/// The displacement from `from` to `to`, px.
pub fn displacement(from: Point, to: Point) -> [f64; 2] {
    [to.x - from.x, to.y - from.y]
}

/// The real labels of both frames (eqs. 3, 5, 6, 12).
#[derive(Debug, Clone, PartialEq)]
pub struct LabelGraph {
    /// Number of frame-1 vehicles `m`.
    pub m: usize,
    /// Number of frame-2 vehicles `n`.
    pub n: usize,
    /// Row starts of the forward labels (`m + 1` entries).
    pub fwd_start: Vec<u32>,
    /// Frame-2 index `k` of each forward label.
    pub fwd_target: Vec<u32>,
    /// Displacement `λ_ik = b_k − a_i` of each forward label, px.
    pub fwd_disp: Vec<[f64; 2]>,
    /// Backward label of the same pair.
    pub fwd_twin: Vec<u32>,
    /// Row starts of the backward labels (`n + 1` entries).
    pub bwd_start: Vec<u32>,
    /// Frame-1 index `i` of each backward label.
    pub bwd_target: Vec<u32>,
    /// Displacement `λ'_ki = a_i − b_k` of each backward label, px.
    pub bwd_disp: Vec<[f64; 2]>,
    /// Forward label of the same pair.
    pub bwd_twin: Vec<u32>,
}

impl LabelGraph {
    /// The labels of every vehicle of `frame1` (positions `p`) and `frame2` (positions `q`)
    /// within the gate of half-width `gate_px`, found through a uniform grid over frame 2.
    ///
    /// # Errors
    /// More than `u32::MAX` labels or vehicles.
    pub fn new(p: &[Point], q: &[Point], gate_px: f64) -> Result<Self> {
        Self::nearest(p, q, gate_px, usize::MAX)
    }

    /// [`LabelGraph::new`] with at most `max_labels` real labels per vehicle, in both
    /// directions: the pair `(a_i, b_k)` is a label when `b_k` is among the `max_labels`
    /// nearest frame-2 vehicles in `a_i`'s gate and `a_i` among the `max_labels` nearest
    /// frame-1 vehicles in `b_k`'s gate (Euclidean distance, ties to the lower index). When
    /// no gate holds more than `max_labels` vehicles this is exactly [`LabelGraph::new`].
    ///
    /// # Errors
    /// More than `u32::MAX` labels or vehicles; `max_labels` of 0.
    // Choice: mutual nearest, so that forward and backward rows (the transpose) are both
    // bounded, which bounds the label lists, the support lists built on them and the
    // probabilities: in a dense scene the gate holds hundreds of vehicles and memory grew
    // with density (6 GB for 10 000 detections in 2 000 px).
    pub fn nearest(p: &[Point], q: &[Point], gate_px: f64, max_labels: usize) -> Result<Self> {
        if p.len() >= u32::MAX as usize || q.len() >= u32::MAX as usize {
            return Err(Error::Invalid("too many vehicles (at most 2³² − 1)".into()));
        }
        if max_labels == 0 {
            return Err(Error::config(
                "RelaxationConfig",
                "max_labels",
                "must be at least 1",
            ));
        }
        // The vehicles of `to` in the gate of `a`, ascending by index: all of them, or the
        // `max_labels` nearest; the flag says whether some were left out.
        let in_gate_of = |a: Point, grid: &PointGrid, to: &[Point]| -> (Vec<u32>, bool) {
            let mut ks = Vec::new();
            grid.for_each_candidate(
                a.x - gate_px,
                a.y - gate_px,
                a.x + gate_px,
                a.y + gate_px,
                |k| {
                    if in_gate(displacement(a, to[k as usize]), gate_px) {
                        ks.push(k);
                    }
                },
            );
            let cut = ks.len() > max_labels;
            if cut {
                let d2 = |k: u32| {
                    let d = displacement(a, to[k as usize]);
                    d[0] * d[0] + d[1] * d[1]
                };
                ks.select_nth_unstable_by(max_labels - 1, |&x, &y| {
                    d2(x).total_cmp(&d2(y)).then(x.cmp(&y))
                });
                ks.truncate(max_labels);
            }
            ks.sort_unstable();
            (ks, cut)
        };
        let grid = PointGrid::new(q.iter().copied(), gate_px.max(1.0));
        let candidates_of = |i: usize| in_gate_of(p[i], &grid, q).0;
        let mut rows: Vec<Vec<u32>> = if p.len() > PAR_BLOCK {
            (0..p.len()).into_par_iter().map(candidates_of).collect()
        } else {
            (0..p.len()).map(candidates_of).collect()
        };
        if max_labels < q.len().max(p.len()) {
            // The frame-2 side: drop pairs outside b_k's nearest (only where b_k's gate
            // holds more than max_labels, so nothing changes below the bound).
            let grid1 = PointGrid::new(p.iter().copied(), gate_px.max(1.0));
            let back_of = |k: usize| {
                let (is, cut) = in_gate_of(q[k], &grid1, p);
                cut.then_some(is)
            };
            let back: Vec<Option<Vec<u32>>> = if q.len() > PAR_BLOCK {
                (0..q.len()).into_par_iter().map(back_of).collect()
            } else {
                (0..q.len()).map(back_of).collect()
            };
            if back.iter().any(Option::is_some) {
                for (i, row) in rows.iter_mut().enumerate() {
                    row.retain(|&k| {
                        back[k as usize]
                            .as_ref()
                            .is_none_or(|is| is.binary_search(&(i as u32)).is_ok())
                    });
                }
            }
        }
        let total: usize = rows.iter().map(Vec::len).sum();
        if total >= u32::MAX as usize {
            return Err(Error::Invalid(format!(
                "{total} candidate labels exceed 2³² − 1; reduce the gate"
            )));
        }
        let mut fwd_start = Vec::with_capacity(p.len() + 1);
        let mut fwd_target = Vec::with_capacity(total);
        fwd_start.push(0u32);
        for r in &rows {
            fwd_target.extend_from_slice(r);
            fwd_start.push(fwd_target.len() as u32);
        }
        drop(rows);
        let mut fwd_disp = Vec::with_capacity(total);
        for i in 0..p.len() {
            for e in fwd_start[i] as usize..fwd_start[i + 1] as usize {
                fwd_disp.push(displacement(p[i], q[fwd_target[e] as usize]));
            }
        }
        // Transpose by counting: iterating i ascending keeps each backward row sorted by i.
        let mut bwd_start = vec![0u32; q.len() + 1];
        for &k in &fwd_target {
            bwd_start[k as usize + 1] += 1;
        }
        for k in 0..q.len() {
            bwd_start[k + 1] += bwd_start[k];
        }
        let mut fill: Vec<u32> = bwd_start[..q.len()].to_vec();
        let mut bwd_target = vec![0u32; total];
        let mut bwd_disp = vec![[0.0; 2]; total];
        let mut bwd_twin = vec![0u32; total];
        let mut fwd_twin = vec![0u32; total];
        for i in 0..p.len() {
            for e in fwd_start[i] as usize..fwd_start[i + 1] as usize {
                let k = fwd_target[e] as usize;
                let b = fill[k] as usize;
                fill[k] += 1;
                bwd_target[b] = i as u32;
                // Exact: IEEE subtraction is antisymmetric, so this equals a_i − b_k.
                bwd_disp[b] = [-fwd_disp[e][0], -fwd_disp[e][1]];
                bwd_twin[b] = e as u32;
                fwd_twin[e] = b as u32;
            }
        }
        Ok(Self {
            m: p.len(),
            n: q.len(),
            fwd_start,
            fwd_target,
            fwd_disp,
            fwd_twin,
            bwd_start,
            bwd_target,
            bwd_disp,
            bwd_twin,
        })
    }

    /// Number of real labels (pairs inside the gate).
    pub fn n_labels(&self) -> usize {
        self.fwd_target.len()
    }

    /// Forward label indices of `a_i`.
    pub fn fwd_range(&self, i: usize) -> std::ops::Range<usize> {
        self.fwd_start[i] as usize..self.fwd_start[i + 1] as usize
    }

    /// Backward label indices of `b_k`.
    pub fn bwd_range(&self, k: usize) -> std::ops::Range<usize> {
        self.bwd_start[k] as usize..self.bwd_start[k + 1] as usize
    }

    /// The same graph seen from the other frame (frame 2 becomes frame 1).
    pub fn swapped(&self) -> Self {
        Self {
            m: self.n,
            n: self.m,
            fwd_start: self.bwd_start.clone(),
            fwd_target: self.bwd_target.clone(),
            fwd_disp: self.bwd_disp.clone(),
            fwd_twin: self.bwd_twin.clone(),
            bwd_start: self.fwd_start.clone(),
            bwd_target: self.fwd_target.clone(),
            bwd_disp: self.fwd_disp.clone(),
            bwd_twin: self.fwd_twin.clone(),
        }
    }

    /// Heap bytes held.
    pub fn heap_bytes(&self) -> usize {
        4 * (self.fwd_start.capacity()
            + self.fwd_target.capacity()
            + self.fwd_twin.capacity()
            + self.bwd_start.capacity()
            + self.bwd_target.capacity()
            + self.bwd_twin.capacity())
            + 16 * (self.fwd_disp.capacity() + self.bwd_disp.capacity())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gate_is_a_closed_square() {
        assert!(in_gate([150.0, -150.0], 150.0));
        assert!(!in_gate([150.0001, 0.0], 150.0));
        // A point at distance 200 on the diagonal is inside the 150 px square.
        assert!(in_gate([141.0, 141.0], 150.0));
    }

    #[test]
    fn labels_are_the_pairs_inside_the_gate_and_backward_is_the_transpose() -> Result<()> {
        let p = [Point::new(0.0, 0.0), Point::new(100.0, 0.0)];
        let q = [
            Point::new(10.0, 10.0),
            Point::new(200.0, 0.0),
            Point::new(-160.0, 0.0),
        ];
        let g = LabelGraph::new(&p, &q, 150.0)?;
        // a_0 sees b_0 only (b_1 is 200 px away, b_2 160 px); a_1 sees b_0 (−90, 10) and
        // b_1 (100, 0).
        assert_eq!(g.fwd_start, vec![0, 1, 3]);
        assert_eq!(g.fwd_target, vec![0, 0, 1]);
        assert_eq!(g.fwd_disp, vec![[10.0, 10.0], [-90.0, 10.0], [100.0, 0.0]]);
        assert_eq!(g.bwd_start, vec![0, 2, 3, 3]);
        assert_eq!(g.bwd_target, vec![0, 1, 1]);
        assert_eq!(
            g.bwd_disp,
            vec![[-10.0, -10.0], [90.0, -10.0], [-100.0, 0.0]]
        );
        for e in 0..g.n_labels() {
            assert_eq!(g.bwd_twin[g.fwd_twin[e] as usize] as usize, e);
        }
        Ok(())
    }

    #[test]
    fn nearest_bounds_both_directions_and_changes_nothing_below_the_bound() -> Result<()> {
        // 400 vehicles in a 40 px square: every gate holds all 400.
        let pts = |off: f64| -> Vec<Point> {
            (0..400u64)
                .map(|i| Point::new((i * 37 % 40) as f64 + off, (i * 53 % 41) as f64))
                .collect()
        };
        let (p, q) = (pts(0.0), pts(1.5));
        let all = LabelGraph::new(&p, &q, 150.0)?;
        assert_eq!(all.n_labels(), 400 * 400);
        let g = LabelGraph::nearest(&p, &q, 150.0, 8)?;
        assert!((0..g.m).all(|i| g.fwd_range(i).len() <= 8));
        assert!((0..g.n).all(|k| g.bwd_range(k).len() <= 8));
        // Each kept pair is among the 8 nearest of both ends: the true partner (1.5 px
        // away, the nearest) always is.
        for i in 0..g.m {
            let ks: Vec<u32> = g.fwd_range(i).map(|e| g.fwd_target[e]).collect();
            assert!(ks.contains(&(i as u32)), "vehicle {i} lost its partner");
        }
        for e in 0..g.n_labels() {
            assert_eq!(g.bwd_twin[g.fwd_twin[e] as usize] as usize, e);
        }
        // At or above the largest gate count the graph is the unbounded one.
        assert_eq!(LabelGraph::nearest(&p, &q, 150.0, 400)?, all);
        assert!(LabelGraph::nearest(&p, &q, 150.0, 0).is_err());
        Ok(())
    }

    #[test]
    fn empty_frames_give_empty_graphs() -> Result<()> {
        let g = LabelGraph::new(&[], &[Point::new(1.0, 1.0)], 150.0)?;
        assert_eq!((g.m, g.n, g.n_labels()), (0, 1, 0));
        assert_eq!(g.bwd_start, vec![0, 0]);
        let g = LabelGraph::new(&[Point::new(1.0, 1.0)], &[], 150.0)?;
        assert_eq!((g.m, g.n, g.n_labels()), (1, 0, 0));
        Ok(())
    }
}
