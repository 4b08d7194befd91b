//! Identity metrics (Ristani et al. 2016) as TrackEval's `Identity` computes them.
//!
//! Every ground-truth id is matched to at most one tracker id for the whole sequence so that
//! the number of frames in which matched pairs overlap with `IoU ≥ 0.5` (IDTP) is largest:
//!
//! ```text
//! IDFN = Σ_gt frames − IDTP        IDFP = Σ_tracker frames − IDTP
//! IDR = IDTP / (IDTP + IDFN)       IDP = IDTP / (IDTP + IDFP)
//! IDF1 = IDTP / (IDTP + ½ IDFP + ½ IDFN)          (denominators at least 1)
//! ```
//!
//! TrackEval solves a `(G + T) × (G + T)` assignment with dummy rows and columns whose
//! optimum is exactly the maximum-weight bipartite matching on the overlap counts, so the
//! value (and hence every metric) is the same when the matching is solved directly, one
//! connected component of the "overlapped at least once" graph at a time, which keeps every
//! matrix small.

use super::FastMap as HashMap;
use super::preprocess::EvalSequence;
use crate::assignment::max_score_assignment;
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// Identity results with TrackEval's field names.
#[allow(non_snake_case)]
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct IdentityMetrics {
    /// ID F1 score.
    pub IDF1: f64,
    /// ID recall.
    pub IDR: f64,
    /// ID precision.
    pub IDP: f64,
    /// Identity true positives.
    pub IDTP: u64,
    /// Identity false negatives.
    pub IDFN: u64,
    /// Identity false positives.
    pub IDFP: u64,
}

impl IdentityMetrics {
    pub(crate) fn finalize(&mut self) {
        let (tp, fn_, fp) = (self.IDTP as f64, self.IDFN as f64, self.IDFP as f64);
        self.IDR = tp / (tp + fn_).max(1.0);
        self.IDP = tp / (tp + fp).max(1.0);
        self.IDF1 = tp / (tp + 0.5 * fp + 0.5 * fn_).max(1.0);
    }

    pub(crate) fn combine_sum(parts: &[&IdentityMetrics]) -> IdentityMetrics {
        let mut r = IdentityMetrics::default();
        for p in parts {
            r.IDTP += p.IDTP;
            r.IDFN += p.IDFN;
            r.IDFP += p.IDFP;
        }
        r.finalize();
        r
    }

    pub(crate) fn combine_class_average(parts: &[&IdentityMetrics]) -> IdentityMetrics {
        let mut r = Self::combine_sum(parts);
        let n = parts.len().max(1) as f64;
        r.IDF1 = parts.iter().map(|p| p.IDF1).sum::<f64>() / n;
        r.IDR = parts.iter().map(|p| p.IDR).sum::<f64>() / n;
        r.IDP = parts.iter().map(|p| p.IDP).sum::<f64>() / n;
        r
    }
}

/// Union–find root with path halving.
fn root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// Largest total weight of a one-to-one matching on a sparse bipartite graph with
/// non-negative weights, solved per connected component.
pub(crate) fn max_weight_matching(
    n_left: usize,
    n_right: usize,
    weights: &HashMap<(usize, usize), f64>,
) -> Result<f64> {
    let mut parent: Vec<usize> = (0..n_left + n_right).collect();
    let mut edges: Vec<((usize, usize), f64)> = weights.iter().map(|(k, v)| (*k, *v)).collect();
    edges.sort_by_key(|(k, _)| *k);
    for &((l, r), _) in &edges {
        let (a, b) = (root(&mut parent, l), root(&mut parent, n_left + r));
        if a != b {
            parent[a] = b;
        }
    }
    let mut comps: HashMap<usize, (Vec<usize>, Vec<usize>)> = HashMap::default();
    for &((l, r), _) in &edges {
        let c = root(&mut parent, l);
        let e = comps.entry(c).or_default();
        e.0.push(l);
        e.1.push(r);
    }
    let mut keys: Vec<usize> = comps.keys().copied().collect();
    keys.sort_unstable();
    let mut total = 0.0;
    for k in keys {
        let Some((mut ls, mut rs)) = comps.remove(&k) else {
            continue;
        };
        ls.sort_unstable();
        ls.dedup();
        rs.sort_unstable();
        rs.dedup();
        let li: HashMap<usize, usize> = ls.iter().enumerate().map(|(i, &l)| (l, i)).collect();
        let ri: HashMap<usize, usize> = rs.iter().enumerate().map(|(i, &r)| (r, i)).collect();
        let mut m = vec![0.0; ls.len() * rs.len()];
        for &((l, r), w) in &edges {
            if let (Some(&i), Some(&j)) = (li.get(&l), ri.get(&r)) {
                m[i * rs.len() + j] = w;
            }
        }
        for (i, j) in max_score_assignment(&m, ls.len(), rs.len())? {
            total += m[i * rs.len() + j];
        }
    }
    Ok(total)
}

/// Identity metrics of one preprocessed sequence; `threshold` is the IoU for a match (0.5).
pub(crate) fn identity(seq: &EvalSequence, threshold: f64) -> Result<IdentityMetrics> {
    let mut res = IdentityMetrics::default();
    if seq.n_tr_dets == 0 {
        res.IDFN = seq.n_gt_dets as u64;
        return Ok(res);
    }
    if seq.n_gt_dets == 0 {
        res.IDFP = seq.n_tr_dets as u64;
        return Ok(res);
    }
    let mut potential: HashMap<(usize, usize), f64> = HashMap::default();
    for fr in &seq.frames {
        for (gi, &g) in fr.gt.iter().enumerate() {
            for (ti, &t) in fr.tr.iter().enumerate() {
                if fr.similarity(gi, ti) >= threshold {
                    *potential.entry((g, t)).or_insert(0.0) += 1.0;
                }
            }
        }
    }
    let idtp = max_weight_matching(seq.n_gt_ids, seq.n_tr_ids, &potential)?;
    res.IDTP = idtp.round() as u64;
    res.IDFN = seq.n_gt_dets as u64 - res.IDTP;
    res.IDFP = seq.n_tr_dets as u64 - res.IDTP;
    res.finalize();
    Ok(res)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matching_is_solved_per_component_and_summed() -> Result<()> {
        // Component {0,1} × {0,1}: best 5 + 4 (not the greedy 6 + 0); component {2} × {2}: 3.
        let w: HashMap<(usize, usize), f64> =
            [((0, 0), 6.0), ((0, 1), 5.0), ((1, 0), 4.0), ((2, 2), 3.0)]
                .into_iter()
                .collect();
        assert_eq!(max_weight_matching(3, 3, &w)?, 12.0);
        Ok(())
    }
}
