//! CLEAR MOT metrics (Bernardin & Stiefelhagen 2008) exactly as TrackEval's `CLEAR` computes
//! them.
//!
//! Per frame, a linear assignment maximises `1000 · [tracker continues the ground-truth
//! object's match of the previous frame] + IoU` over pairs with `IoU ≥ 0.5 − ε`; pairs with a
//! positive score are true positives. An ID switch is a match whose tracker id differs from
//! the last tracker id matched to that object at any earlier frame. Frames with no ground
//! truth or no tracker boxes do not reset the "previous frame" used by the bonus.
//!
//! ```text
//! MOTA = (TP − FP − IDSW) / max(1, TP + FN)      MODA = (TP − FP) / max(1, TP + FN)
//! MOTP = Σ IoU(matches) / max(1, TP)             sMOTA = (Σ IoU − FP − IDSW) / max(1, TP + FN)
//! MT: tracked ratio > 0.8;  PT: ≥ 0.2 and not MT;  ML: the rest
//! Frag = Σ_objects (number of times tracking (re)starts − 1)
//! ```

use super::preprocess::{EPS, EvalSequence};
use crate::assignment::positive_max_score_pairs;
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// CLEAR MOT results with TrackEval's field names.
#[allow(non_snake_case)]
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ClearMetrics {
    /// Multiple-object tracking accuracy.
    pub MOTA: f64,
    /// Multiple-object tracking precision: mean IoU of the matches.
    pub MOTP: f64,
    /// Multiple-object detection accuracy (MOTA without ID switches).
    pub MODA: f64,
    /// Detection recall `TP / (TP + FN)`.
    pub CLR_Re: f64,
    /// Detection precision `TP / (TP + FP)`.
    pub CLR_Pr: f64,
    /// Mostly-tracked ratio.
    pub MTR: f64,
    /// Partially-tracked ratio.
    pub PTR: f64,
    /// Mostly-lost ratio.
    pub MLR: f64,
    /// Soft MOTA (IoU-weighted true positives).
    pub sMOTA: f64,
    /// Detection F1.
    pub CLR_F1: f64,
    /// False positives per frame.
    pub FP_per_frame: f64,
    /// MOTA with `log10(IDSW)` in place of IDSW.
    pub MOTAL: f64,
    /// Sum of the IoU of all matches.
    pub MOTP_sum: f64,
    /// True positives (matches).
    pub CLR_TP: u64,
    /// False negatives (missed ground-truth boxes).
    pub CLR_FN: u64,
    /// False positives (unmatched tracker boxes).
    pub CLR_FP: u64,
    /// Identity switches.
    pub IDSW: u64,
    /// Mostly-tracked objects (tracked in more than 80 % of their frames).
    pub MT: u64,
    /// Partially-tracked objects.
    pub PT: u64,
    /// Mostly-lost objects (tracked in less than 20 % of their frames).
    pub ML: u64,
    /// Fragmentations.
    pub Frag: u64,
    /// Frames evaluated.
    pub CLR_Frames: u64,
    /// Alias of `CLR_TP` (INTERFACES.md key).
    pub TP: u64,
    /// Alias of `CLR_FP` (INTERFACES.md key).
    pub FP: u64,
    /// Alias of `CLR_FN` (INTERFACES.md key).
    pub FN: u64,
}

impl ClearMetrics {
    /// TrackEval `_compute_final_fields`: everything that derives from the counts and
    /// `MOTP_sum`.
    pub(crate) fn finalize(&mut self) {
        let f = |x: u64| x as f64;
        let n_ids = f(self.MT + self.ML + self.PT);
        self.MTR = f(self.MT) / n_ids.max(1.0);
        self.MLR = f(self.ML) / n_ids.max(1.0);
        self.PTR = f(self.PT) / n_ids.max(1.0);
        let (tp, fn_, fp, sw) = (f(self.CLR_TP), f(self.CLR_FN), f(self.CLR_FP), f(self.IDSW));
        self.CLR_Re = tp / (tp + fn_).max(1.0);
        self.CLR_Pr = tp / (tp + fp).max(1.0);
        self.MODA = (tp - fp) / (tp + fn_).max(1.0);
        self.MOTA = (tp - fp - sw) / (tp + fn_).max(1.0);
        self.MOTP = self.MOTP_sum / tp.max(1.0);
        self.sMOTA = (self.MOTP_sum - fp - sw) / (tp + fn_).max(1.0);
        self.CLR_F1 = tp / (tp + 0.5 * fn_ + 0.5 * fp).max(1.0);
        self.FP_per_frame = fp / f(self.CLR_Frames).max(1.0);
        let safe_log_idsw = if self.IDSW > 0 { sw.log10() } else { sw };
        self.MOTAL = (tp - fp - safe_log_idsw) / (tp + fn_).max(1.0);
        self.sync_aliases();
    }

    fn sync_aliases(&mut self) {
        self.TP = self.CLR_TP;
        self.FP = self.CLR_FP;
        self.FN = self.CLR_FN;
    }

    /// Sums the counts of `parts` and recomputes the ratios (TrackEval `combine_sequences`
    /// and `combine_classes_det_averaged`).
    pub(crate) fn combine_sum(parts: &[&ClearMetrics]) -> ClearMetrics {
        let mut r = ClearMetrics::default();
        for p in parts {
            r.CLR_TP += p.CLR_TP;
            r.CLR_FN += p.CLR_FN;
            r.CLR_FP += p.CLR_FP;
            r.IDSW += p.IDSW;
            r.MT += p.MT;
            r.PT += p.PT;
            r.ML += p.ML;
            r.Frag += p.Frag;
            r.CLR_Frames += p.CLR_Frames;
            r.MOTP_sum += p.MOTP_sum;
        }
        r.finalize();
        r
    }

    /// Sums the counts and averages every ratio over `parts` (TrackEval
    /// `combine_classes_class_averaged` with `ignore_empty_classes = False`).
    pub(crate) fn combine_class_average(parts: &[&ClearMetrics]) -> ClearMetrics {
        let mut r = Self::combine_sum(parts);
        let n = parts.len().max(1) as f64;
        let mean = |get: fn(&ClearMetrics) -> f64| parts.iter().map(|p| get(p)).sum::<f64>() / n;
        r.MOTA = mean(|m| m.MOTA);
        r.MOTP = mean(|m| m.MOTP);
        r.MODA = mean(|m| m.MODA);
        r.CLR_Re = mean(|m| m.CLR_Re);
        r.CLR_Pr = mean(|m| m.CLR_Pr);
        r.MTR = mean(|m| m.MTR);
        r.PTR = mean(|m| m.PTR);
        r.MLR = mean(|m| m.MLR);
        r.sMOTA = mean(|m| m.sMOTA);
        r.CLR_F1 = mean(|m| m.CLR_F1);
        r.FP_per_frame = mean(|m| m.FP_per_frame);
        r.MOTAL = mean(|m| m.MOTAL);
        r.MOTP_sum = mean(|m| m.MOTP_sum);
        r
    }
}

/// CLEAR metrics of one preprocessed sequence; `threshold` is the IoU for a match (0.5).
pub(crate) fn clear(seq: &EvalSequence, threshold: f64) -> Result<ClearMetrics> {
    let mut res = ClearMetrics::default();
    // TrackEval's early returns keep every other field 0 (MLR = 1, no CLR_Frames).
    if seq.n_tr_dets == 0 {
        res.CLR_FN = seq.n_gt_dets as u64;
        res.ML = seq.n_gt_ids as u64;
        res.MLR = 1.0;
        res.sync_aliases();
        return Ok(res);
    }
    if seq.n_gt_dets == 0 {
        res.CLR_FP = seq.n_tr_dets as u64;
        res.MLR = 1.0;
        res.sync_aliases();
        return Ok(res);
    }
    let n = seq.n_gt_ids;
    let mut gt_id_count = vec![0u64; n];
    let mut gt_matched_count = vec![0u64; n];
    let mut gt_frag_count = vec![0u64; n];
    // Last tracker id matched to each object at any earlier frame (for IDSW), and in the
    // previous evaluated frame only (for the continuation bonus).
    let mut prev_tracker_id: Vec<Option<usize>> = vec![None; n];
    let mut prev_timestep_tracker_id: Vec<Option<usize>> = vec![None; n];
    let mut tracked_last: Vec<usize> = Vec::new();
    let mut score = Vec::new();
    for fr in &seq.frames {
        let (ng, nt) = (fr.gt.len(), fr.tr.len());
        if ng == 0 {
            res.CLR_FP += nt as u64;
            continue;
        }
        if nt == 0 {
            res.CLR_FN += ng as u64;
            for &g in &fr.gt {
                gt_id_count[g] += 1;
            }
            continue;
        }
        score.clear();
        for (gi, &g) in fr.gt.iter().enumerate() {
            for (ti, &t) in fr.tr.iter().enumerate() {
                let s = fr.similarity(gi, ti);
                let bonus = if prev_timestep_tracker_id[g] == Some(t) {
                    1000.0
                } else {
                    0.0
                };
                score.push(if s < threshold - EPS { 0.0 } else { bonus + s });
            }
        }
        let matches: Vec<(usize, usize)> = positive_max_score_pairs(&score, ng, nt)?
            .into_iter()
            .filter(|&(gi, ti)| score[gi * nt + ti] > EPS)
            .collect();
        for &(gi, ti) in &matches {
            let (g, t) = (fr.gt[gi], fr.tr[ti]);
            if prev_tracker_id[g].is_some_and(|p| p != t) {
                res.IDSW += 1;
            }
        }
        for &g in &fr.gt {
            gt_id_count[g] += 1;
        }
        // Frag: objects matched now but not in the previous evaluated frame.
        for &(gi, _) in &matches {
            let g = fr.gt[gi];
            if prev_timestep_tracker_id[g].is_none() {
                gt_frag_count[g] += 1;
            }
        }
        for g in tracked_last.drain(..) {
            prev_timestep_tracker_id[g] = None;
        }
        for &(gi, ti) in &matches {
            let (g, t) = (fr.gt[gi], fr.tr[ti]);
            gt_matched_count[g] += 1;
            prev_tracker_id[g] = Some(t);
            prev_timestep_tracker_id[g] = Some(t);
            tracked_last.push(g);
        }
        let k = matches.len() as u64;
        res.CLR_TP += k;
        res.CLR_FN += ng as u64 - k;
        res.CLR_FP += nt as u64 - k;
        // Python's `sum` over the matches in row order, then added to the total.
        let frame_sum: f64 = matches.iter().map(|&(gi, ti)| fr.similarity(gi, ti)).sum();
        res.MOTP_sum += frame_sum;
    }
    for g in 0..n {
        if gt_id_count[g] == 0 {
            continue;
        }
        let ratio = gt_matched_count[g] as f64 / gt_id_count[g] as f64;
        if ratio > 0.8 {
            res.MT += 1;
        } else if ratio >= 0.2 {
            res.PT += 1;
        }
    }
    res.ML = n as u64 - res.MT - res.PT;
    res.Frag = gt_frag_count
        .iter()
        .filter(|&&c| c > 0)
        .map(|c| c - 1)
        .sum();
    res.CLR_Frames = seq.n_timesteps() as u64;
    res.finalize();
    Ok(res)
}
