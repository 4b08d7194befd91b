//! HOTA (Luiten et al. 2021) as TrackEval's `HOTA` computes it.
//!
//! Two passes over the frames. The first accumulates, for every (ground-truth id, tracker
//! id) pair, the soft overlap count `Σ_t IoU / (row sum + column sum − IoU)`, giving a
//! global alignment score `A = count / (n_gt + n_tr − count)`. The second matches boxes
//! per frame by a linear assignment maximising `A · IoU` and, for every localisation
//! threshold `α ∈ {0.05, 0.10, …, 0.95}`, keeps the matches with `IoU ≥ α − ε`:
//!
//! ```text
//! DetA = TP / (TP + FN + FP)     DetRe = TP / (TP + FN)     DetPr = TP / (TP + FP)
//! AssA = 1/TP Σ_matches TPA / (TPA + FNA + FPA)   (AssRe, AssPr likewise)
//! HOTA = √(DetA · AssA)          LocA = mean IoU of the matches      OWTA = √(DetRe · AssA)
//! ```
//!
//! The reported scalars are means over the 19 values of α; `HOTA(0)` and `LocA(0)` are the
//! values at α = 0.05 and `HOTALocA(0)` their product.

use super::FastMap as HashMap;
use super::preprocess::{EPS, EvalSequence};
use crate::assignment::positive_max_score_pairs;
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// Number of localisation thresholds α.
pub const N_ALPHA: usize = 19;

/// The thresholds α, bit for bit as `numpy.arange(0.05, 0.99, 0.05)`.
pub fn alphas() -> [f64; N_ALPHA] {
    std::array::from_fn(|i| 0.05 + i as f64 * 0.05)
}

/// HOTA curves over α, with TrackEval's field names.
#[allow(non_snake_case)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HotaCurves {
    /// The thresholds α.
    pub alpha: Vec<f64>,
    /// HOTA at each α.
    pub HOTA: Vec<f64>,
    /// Detection accuracy at each α.
    pub DetA: Vec<f64>,
    /// Association accuracy at each α.
    pub AssA: Vec<f64>,
    /// Detection recall at each α.
    pub DetRe: Vec<f64>,
    /// Detection precision at each α.
    pub DetPr: Vec<f64>,
    /// Association recall at each α.
    pub AssRe: Vec<f64>,
    /// Association precision at each α.
    pub AssPr: Vec<f64>,
    /// Localisation accuracy at each α.
    pub LocA: Vec<f64>,
    /// Open-world tracking accuracy at each α.
    pub OWTA: Vec<f64>,
    /// True positives at each α.
    pub HOTA_TP: Vec<f64>,
    /// False negatives at each α.
    pub HOTA_FN: Vec<f64>,
    /// False positives at each α.
    pub HOTA_FP: Vec<f64>,
}

impl Default for HotaCurves {
    fn default() -> Self {
        let z = vec![0.0; N_ALPHA];
        Self {
            alpha: alphas().to_vec(),
            HOTA: z.clone(),
            DetA: z.clone(),
            AssA: z.clone(),
            DetRe: z.clone(),
            DetPr: z.clone(),
            AssRe: z.clone(),
            AssPr: z.clone(),
            LocA: z.clone(),
            OWTA: z.clone(),
            HOTA_TP: z.clone(),
            HOTA_FN: z.clone(),
            HOTA_FP: z,
        }
    }
}

/// HOTA results: means over α, the α = 0.05 values, and the curves.
#[allow(non_snake_case)]
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct HotaMetrics {
    /// Higher-order tracking accuracy (mean over α).
    pub HOTA: f64,
    /// Detection accuracy.
    pub DetA: f64,
    /// Association accuracy.
    pub AssA: f64,
    /// Detection recall.
    pub DetRe: f64,
    /// Detection precision.
    pub DetPr: f64,
    /// Association recall.
    pub AssRe: f64,
    /// Association precision.
    pub AssPr: f64,
    /// Localisation accuracy.
    pub LocA: f64,
    /// Open-world tracking accuracy.
    pub OWTA: f64,
    /// HOTA at α = 0.05.
    #[serde(rename = "HOTA(0)")]
    pub hota_0: f64,
    /// LocA at α = 0.05.
    #[serde(rename = "LocA(0)")]
    pub loca_0: f64,
    /// `HOTA(0) · LocA(0)`.
    #[serde(rename = "HOTALocA(0)")]
    pub hota_loca_0: f64,
    /// Every field per α.
    pub per_alpha: HotaCurves,
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

impl HotaMetrics {
    /// TrackEval `_compute_final_fields`, then the means over α.
    fn finalize(mut c: HotaCurves) -> Self {
        for a in 0..N_ALPHA {
            let (tp, fn_, fp) = (c.HOTA_TP[a], c.HOTA_FN[a], c.HOTA_FP[a]);
            c.DetRe[a] = tp / (tp + fn_).max(1.0);
            c.DetPr[a] = tp / (tp + fp).max(1.0);
            c.DetA[a] = tp / (tp + fn_ + fp).max(1.0);
            c.HOTA[a] = (c.DetA[a] * c.AssA[a]).sqrt();
            c.OWTA[a] = (c.DetRe[a] * c.AssA[a]).sqrt();
        }
        let hota_0 = c.HOTA[0];
        let loca_0 = c.LocA[0];
        Self::summarise(c, hota_0, loca_0, hota_0 * loca_0)
    }

    fn summarise(c: HotaCurves, hota_0: f64, loca_0: f64, hota_loca_0: f64) -> Self {
        Self {
            HOTA: mean(&c.HOTA),
            DetA: mean(&c.DetA),
            AssA: mean(&c.AssA),
            DetRe: mean(&c.DetRe),
            DetPr: mean(&c.DetPr),
            AssRe: mean(&c.AssRe),
            AssPr: mean(&c.AssPr),
            LocA: mean(&c.LocA),
            OWTA: mean(&c.OWTA),
            hota_0,
            loca_0,
            hota_loca_0,
            per_alpha: c,
        }
    }

    /// TrackEval `combine_sequences` / `combine_classes_det_averaged`: counts summed,
    /// association scores and LocA weighted by the true positives.
    pub(crate) fn combine_sum(parts: &[&HotaMetrics]) -> HotaMetrics {
        let mut c = HotaCurves::default();
        for a in 0..N_ALPHA {
            for p in parts {
                c.HOTA_TP[a] += p.per_alpha.HOTA_TP[a];
                c.HOTA_FN[a] += p.per_alpha.HOTA_FN[a];
                c.HOTA_FP[a] += p.per_alpha.HOTA_FP[a];
            }
            let tp = c.HOTA_TP[a];
            let weighted = |get: fn(&HotaCurves) -> &Vec<f64>| {
                parts
                    .iter()
                    .map(|p| get(&p.per_alpha)[a] * p.per_alpha.HOTA_TP[a])
                    .sum::<f64>()
            };
            c.AssRe[a] = weighted(|x| &x.AssRe) / tp.max(1.0);
            c.AssPr[a] = weighted(|x| &x.AssPr) / tp.max(1.0);
            c.AssA[a] = weighted(|x| &x.AssA) / tp.max(1.0);
            c.LocA[a] = weighted(|x| &x.LocA).max(1e-10) / tp.max(1e-10);
        }
        Self::finalize(c)
    }

    /// TrackEval `combine_classes_class_averaged` (`ignore_empty_classes = False`): counts
    /// summed, every score averaged over the parts.
    pub(crate) fn combine_class_average(parts: &[&HotaMetrics]) -> HotaMetrics {
        let n = parts.len().max(1) as f64;
        let mut c = HotaCurves::default();
        for a in 0..N_ALPHA {
            let avg = |get: fn(&HotaCurves) -> &Vec<f64>| {
                parts.iter().map(|p| get(&p.per_alpha)[a]).sum::<f64>() / n
            };
            let sum = |get: fn(&HotaCurves) -> &Vec<f64>| {
                parts.iter().map(|p| get(&p.per_alpha)[a]).sum::<f64>()
            };
            c.HOTA_TP[a] = sum(|x| &x.HOTA_TP);
            c.HOTA_FN[a] = sum(|x| &x.HOTA_FN);
            c.HOTA_FP[a] = sum(|x| &x.HOTA_FP);
            c.HOTA[a] = avg(|x| &x.HOTA);
            c.DetA[a] = avg(|x| &x.DetA);
            c.AssA[a] = avg(|x| &x.AssA);
            c.DetRe[a] = avg(|x| &x.DetRe);
            c.DetPr[a] = avg(|x| &x.DetPr);
            c.AssRe[a] = avg(|x| &x.AssRe);
            c.AssPr[a] = avg(|x| &x.AssPr);
            c.LocA[a] = avg(|x| &x.LocA);
            c.OWTA[a] = avg(|x| &x.OWTA);
        }
        let avg0 = |get: fn(&HotaMetrics) -> f64| parts.iter().map(|p| get(p)).sum::<f64>() / n;
        let (h0, l0, hl0) = (
            avg0(|p| p.hota_0),
            avg0(|p| p.loca_0),
            avg0(|p| p.hota_loca_0),
        );
        Self::summarise(c, h0, l0, hl0)
    }
}

/// HOTA of one preprocessed sequence.
pub(crate) fn hota(seq: &EvalSequence) -> Result<HotaMetrics> {
    let mut c = HotaCurves::default();
    if seq.n_tr_dets == 0 || seq.n_gt_dets == 0 {
        // TrackEval's early return: only the counts and LocA = 1 are set; nothing is
        // finalised, so every score stays 0.
        let (fn_, fp) = if seq.n_tr_dets == 0 {
            (seq.n_gt_dets as f64, 0.0)
        } else {
            (0.0, seq.n_tr_dets as f64)
        };
        c.HOTA_FN = vec![fn_; N_ALPHA];
        c.HOTA_FP = vec![fp; N_ALPHA];
        c.LocA = vec![1.0; N_ALPHA];
        return Ok(HotaMetrics::summarise(c, 0.0, 1.0, 0.0));
    }
    let (ng_ids, nt_ids) = (seq.n_gt_ids, seq.n_tr_ids);
    // Pass 1: soft overlap counts per id pair, and the number of frames of each id.
    let mut potential: HashMap<(usize, usize), f64> = HashMap::default();
    let mut gt_id_count = vec![0.0; ng_ids];
    let mut tr_id_count = vec![0.0; nt_ids];
    let mut row_sum = Vec::new();
    let mut col_sum = Vec::new();
    for fr in &seq.frames {
        let (ng, nt) = (fr.gt.len(), fr.tr.len());
        row_sum.clear();
        row_sum.extend((0..ng).map(|g| (0..nt).map(|t| fr.similarity(g, t)).sum::<f64>()));
        col_sum.clear();
        col_sum.extend((0..nt).map(|t| (0..ng).map(|g| fr.similarity(g, t)).sum::<f64>()));
        for (g, &rs) in row_sum.iter().enumerate() {
            for (t, &cs) in col_sum.iter().enumerate() {
                let s = fr.similarity(g, t);
                let denom = cs + rs - s;
                if denom > EPS && s != 0.0 {
                    *potential.entry((fr.gt[g], fr.tr[t])).or_insert(0.0) += s / denom;
                }
            }
        }
        for &g in &fr.gt {
            gt_id_count[g] += 1.0;
        }
        for &t in &fr.tr {
            tr_id_count[t] += 1.0;
        }
    }
    let alignment = |g: usize, t: usize| -> f64 {
        match potential.get(&(g, t)) {
            Some(&p) => p / (gt_id_count[g] + tr_id_count[t] - p),
            None => 0.0,
        }
    };
    // Pass 2: per-frame matching and counts per α.
    let alpha = alphas();
    // For each id pair, how many frames it was matched with IoU passing exactly the first
    // k thresholds (k = 1..=19); a match passing α_k passes every smaller α.
    let mut passed: HashMap<(usize, usize), [f64; N_ALPHA]> = HashMap::default();
    let mut score = Vec::new();
    for fr in &seq.frames {
        let (ng, nt) = (fr.gt.len(), fr.tr.len());
        if ng == 0 || nt == 0 {
            for a in 0..N_ALPHA {
                c.HOTA_FP[a] += nt as f64;
                c.HOTA_FN[a] += ng as f64;
            }
            continue;
        }
        score.clear();
        for g in 0..ng {
            for t in 0..nt {
                let s = fr.similarity(g, t);
                score.push(if s == 0.0 {
                    0.0
                } else {
                    alignment(fr.gt[g], fr.tr[t]) * s
                });
            }
        }
        // Pairs with score 0 have IoU 0 and pass no threshold.
        let pairs = positive_max_score_pairs(&score, ng, nt)?;
        let mut k_at = [0usize; N_ALPHA];
        let mut loc_at = [0.0; N_ALPHA];
        for &(g, t) in &pairs {
            let s = fr.similarity(g, t);
            let k = alpha.iter().take_while(|&&a| s >= a - EPS).count();
            if k > 0 {
                passed.entry((fr.gt[g], fr.tr[t])).or_insert([0.0; N_ALPHA])[k - 1] += 1.0;
            }
            for a in 0..k {
                k_at[a] += 1;
                loc_at[a] += s;
            }
        }
        for a in 0..N_ALPHA {
            let k = k_at[a];
            c.HOTA_TP[a] += k as f64;
            c.HOTA_FN[a] += (ng - k) as f64;
            c.HOTA_FP[a] += (nt - k) as f64;
            if k > 0 {
                c.LocA[a] += loc_at[a];
            }
        }
    }
    let mut entries: Vec<((usize, usize), [f64; N_ALPHA])> = passed.into_iter().collect();
    entries.sort_unstable_by_key(|(k, _)| *k);
    let (mut ass_a, mut ass_re, mut ass_pr) = ([0.0; N_ALPHA], [0.0; N_ALPHA], [0.0; N_ALPHA]);
    for ((g, t), hist) in entries {
        let (gc, tc) = (gt_id_count[g], tr_id_count[t]);
        // Matches at α_a = frames that passed at least a + 1 thresholds.
        let mut m = 0.0;
        for a in (0..N_ALPHA).rev() {
            m += hist[a];
            if m > 0.0 {
                ass_a[a] += m * (m / (gc + tc - m).max(1.0));
                ass_re[a] += m * (m / gc.max(1.0));
                ass_pr[a] += m * (m / tc.max(1.0));
            }
        }
    }
    for a in 0..N_ALPHA {
        let tp = c.HOTA_TP[a].max(1.0);
        c.AssA[a] = ass_a[a] / tp;
        c.AssRe[a] = ass_re[a] / tp;
        c.AssPr[a] = ass_pr[a] / tp;
        c.LocA[a] = c.LocA[a].max(1e-10) / c.HOTA_TP[a].max(1e-10);
    }
    Ok(HotaMetrics::finalize(c))
}
