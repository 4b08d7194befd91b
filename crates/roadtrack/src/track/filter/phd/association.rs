//! Step d) with detections and exclusive labels ([`LabelledPhd::update_detections_exclusive`]):
//! the labelled multi-Bernoulli update (Reuter, Vo, Vo & Dietmayer 2014) in which a
//! detection belongs to at most one label, with the marginal association probabilities
//! of loopy belief propagation (Williams & Lau 2014).

use super::{BoxMeasurement, LabelledPhd};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// How the labels of the Bernoulli update with detections share the detections
/// (`[detections] label_association`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelAssociation {
    /// Each label weighs every detection against the clutter and the other labels'
    /// predicted likelihood mass, `κ' = κ + C_j − C_ℓ,j`
    /// ([`LabelledPhd::update_detections`]): two labels on one detection both keep
    /// their existence, so one object can hold two labels.
    Shared,
    /// A detection is the measurement of at most one label (labelled multi-Bernoulli):
    /// each label's existence and density are the mixture over "missed" and "detection
    /// `j`" weighted by the marginal association probabilities
    /// ([`LabelledPhd::update_detections_exclusive`]).
    #[default]
    Exclusive,
}

/// Marginal association probabilities by loopy belief propagation (Williams & Lau 2014).
/// `psi[ℓ·m + j]` is the ratio of "label ℓ has detection j" to "label ℓ is missed" (both
/// against detection j being clutter or a new object). Returns `(p_miss[ℓ],
/// p[ℓ·m + j])`, each label's row summing to 1 with its miss probability. Sequential and
/// in a fixed order (deterministic).
pub fn marginal_associations(psi: &[f64], n_labels: usize, m: usize) -> (Vec<f64>, Vec<f64>) {
    // mu[ℓ·m + j]: label → detection; nu[ℓ·m + j]: detection → label.
    let mut nu = vec![1.0; n_labels * m];
    let mut mu = vec![0.0; n_labels * m];
    // Choice: 200 iterations or a largest change below 1e-10 (the messages converge in a
    // few tens of iterations on crowds of 30; Williams & Lau prove convergence).
    for _ in 0..200 {
        for l in 0..n_labels {
            let row = l * m..(l + 1) * m;
            let s: f64 = psi[row.clone()]
                .iter()
                .zip(&nu[row.clone()])
                .map(|(p, v)| p * v)
                .sum();
            for j in 0..m {
                let k = l * m + j;
                mu[k] = psi[k] / (1.0 + s - psi[k] * nu[k]).max(f64::MIN_POSITIVE);
            }
        }
        let mut change = 0.0f64;
        for j in 0..m {
            let s: f64 = (0..n_labels).map(|l| mu[l * m + j]).sum();
            for l in 0..n_labels {
                let k = l * m + j;
                let v = 1.0 / (1.0 + s - mu[k]).max(f64::MIN_POSITIVE);
                change = change.max((v - nu[k]).abs());
                nu[k] = v;
            }
        }
        if change < 1e-10 {
            break;
        }
    }
    let mut p_miss = vec![1.0; n_labels];
    let mut p = vec![0.0; n_labels * m];
    for (l, miss) in p_miss.iter_mut().enumerate() {
        let row = l * m..(l + 1) * m;
        let norm = 1.0
            + psi[row.clone()]
                .iter()
                .zip(&nu[row.clone()])
                .map(|(a, b)| a * b)
                .sum::<f64>();
        *miss = 1.0 / norm;
        for k in row {
            p[k] = psi[k] * nu[k] / norm;
        }
    }
    (p_miss, p)
}

/// Everything the exclusive update needs (per label `s`: `slot`'s index; `m` detections).
struct Exclusive {
    /// `g_ij`, row `i`.
    g: Vec<f64>,
    slot: BTreeMap<u32, usize>,
    w_label: Vec<f64>,
    c_label: Vec<f64>,
    c_all: Vec<f64>,
    r_miss: Vec<f64>,
    psi: Vec<f64>,
    p_miss: Vec<f64>,
    p_assoc: Vec<f64>,
}

impl LabelledPhd {
    /// For each of `z`, the probability that an existing label (not a clutter or new
    /// object) is its source: `Σ_ℓ p_ℓj` of [`LabelledPhd::update_detections_exclusive`]
    /// on the current particles; 1 where a label that finds the detection plausible
    /// (`ψ_ℓj ≥ 1`) is more likely missed than detected (`p_ℓ0 ≥ 0.5`: the detection may be
    /// that label's object, seen again). `label_pd` as in
    /// [`LabelledPhd::update_detections_exclusive`].
    pub fn detection_claims(
        &self,
        z: &[BoxMeasurement],
        detection_prob: f64,
        clutter_per_frame: f64,
        label_pd: &BTreeMap<u32, f64>,
    ) -> Vec<f64> {
        let kappa = clutter_per_frame / self.region().area();
        let e = self.exclusive(z, detection_prob, kappa, None, label_pd);
        let m = z.len();
        let nl = e.slot.len();
        (0..m)
            .map(|j| {
                let idle = (0..nl).any(|s| e.psi[s * m + j] >= 1.0 && e.p_miss[s] >= 0.5);
                if idle {
                    1.0
                } else {
                    (0..nl).map(|s| e.p_assoc[s * m + j]).sum()
                }
            })
            .collect()
    }

    /// The association of [`LabelledPhd::update_detections_exclusive`].
    fn exclusive(
        &self,
        z: &[BoxMeasurement],
        pd: f64,
        kappa: f64,
        image_h: Option<&[f64]>,
        label_pd: &BTreeMap<u32, f64>,
    ) -> Exclusive {
        let p = &self.particles;
        let n = p.len();
        let m = z.len();
        let a = |i: usize| image_h.map_or(1.0, |h| h.get(i).copied().unwrap_or(0.0));
        let (x, y) = (&p.x, &p.y);
        let mut slot: BTreeMap<u32, usize> = BTreeMap::new();
        for &l in &p.label {
            if l != 0 {
                let next = slot.len();
                slot.entry(l).or_insert(next);
            }
        }
        let nl = slot.len();
        // p_D per label (slot order): its own where given, else the one p_D.
        let mut pd_slot = vec![pd; nl];
        for (l, &s) in &slot {
            if let Some(&v) = label_pd.get(l) {
                pd_slot[s] = v;
            }
        }
        // Without per-label values (the paper's model) no lookup per particle.
        let pd_of = |i: usize| {
            if label_pd.is_empty() {
                pd
            } else {
                slot.get(&p.label[i]).map_or(pd, |&s| pd_slot[s])
            }
        };
        // g per particle and detection (parallel over particles, each row independent).
        let g: Vec<f64> = (0..n)
            .into_par_iter()
            .flat_map_iter(|i| {
                let f = pd_of(i) * a(i);
                z.iter().map(move |zj| f * zj.density(x[i], y[i]))
            })
            .collect();
        // Sums in particle order (deterministic): W̃_ℓ, C_ℓ,j and the unlabelled C⁰_j.
        let mut w_label = vec![0.0; nl];
        let mut c_label = vec![0.0; nl * m];
        let mut c_free = vec![0.0; m];
        for i in 0..n {
            let (wi, gi) = (p.w[i], &g[i * m..(i + 1) * m]);
            match slot.get(&p.label[i]) {
                Some(&s) => {
                    w_label[s] += wi;
                    for (c, gij) in c_label[s * m..(s + 1) * m].iter_mut().zip(gi) {
                        *c += gij * wi;
                    }
                }
                None => {
                    for (c, gij) in c_free.iter_mut().zip(gi) {
                        *c += gij * wi;
                    }
                }
            }
        }
        let c_all: Vec<f64> = (0..m)
            .map(|j| c_free[j] + (0..nl).map(|s| c_label[s * m + j]).sum::<f64>())
            .collect();
        // ψ_ℓj and each label's existence after a missed detection.
        let mut psi = vec![0.0; nl * m];
        let mut r_miss = vec![0.0; nl];
        for s in 0..nl {
            let wl = w_label[s];
            if !(wl > 0.0 && wl.is_finite()) {
                continue;
            }
            let (r, pd) = (wl.min(1.0), pd_slot[s]);
            let miss = 1.0 - r * pd;
            r_miss[s] = if miss > 0.0 {
                r * (1.0 - pd) / miss
            } else {
                0.0
            };
            for j in 0..m {
                let l_mean = c_label[s * m + j] / wl;
                let v = r * l_mean / (kappa + c_free[j]) / miss.max(f64::MIN_POSITIVE);
                psi[s * m + j] = if v.is_finite() { v } else { 0.0 };
            }
        }
        let (p_miss, p_assoc) = marginal_associations(&psi, nl, m);
        Exclusive {
            g,
            slot,
            w_label,
            c_label,
            c_all,
            r_miss,
            psi,
            p_miss,
            p_assoc,
        }
    }

    /// Step d) on detections `z` with exclusive labels (labelled multi-Bernoulli; Reuter
    /// et al. 2014). With `g_ij = p_D · N(z_j; x_i, σ_j²) · a_i` as in
    /// [`LabelledPhd::update_detections`], label `ℓ` (existence `r = min(W̃_ℓ, 1)`,
    /// density `w̃_i / W̃_ℓ`) has
    ///
    /// ```text
    /// L_ℓj = Σ_{i∈ℓ} w̃_i g_ij / W̃_ℓ                  (its mean likelihood of z_j)
    /// ψ_ℓj = r·L_ℓj / (κ + C⁰_j) / (1 − r·p_D)           (C⁰_j: unlabelled particles' C_j)
    /// p_ℓ0, p_ℓj = marginal association probabilities  (loopy belief propagation on ψ)
    /// r'   = Σ_j p_ℓj + p_ℓ0 · r(1 − p_D)/(1 − r·p_D)
    /// ŵ_i = (w̃_i / W̃_ℓ) · [p_ℓ0 · r(1 − p_D)/(1 − r·p_D) + Σ_j p_ℓj · g_ij / L_ℓj]
    /// ```
    ///
    /// so a detection explains one label: of two labels on one object the weaker loses
    /// its existence as at a missed detection. A label alone near its detections gets
    /// exactly [`LabelledPhd::update_detections`]'s Bernoulli update. Unlabelled (birth)
    /// particles keep the PHD form over every particle's `C_j`. `h` as there. A label in
    /// `label_pd` has that `p_D` in place of `detection_prob` (the occlusion model,
    /// [`super::occlusion`]); an empty map is the paper's one `p_D`.
    ///
    /// Returns, per label, the index of its most probable detection where `p_ℓj` is above
    /// the label's `p_ℓ0` (ties: the first).
    pub fn update_detections_exclusive(
        &mut self,
        z: &[BoxMeasurement],
        detection_prob: f64,
        clutter_per_frame: f64,
        image_h: Option<&[f64]>,
        label_pd: &BTreeMap<u32, f64>,
    ) -> BTreeMap<u32, usize> {
        let pd = detection_prob;
        let kappa = clutter_per_frame / self.region().area();
        let m = z.len();
        let Exclusive {
            g,
            slot,
            w_label,
            c_label,
            c_all,
            r_miss,
            p_miss,
            p_assoc,
            ..
        } = self.exclusive(z, pd, kappa, image_h, label_pd);
        let p = &mut self.particles;
        let n = p.len();
        let h = super::detections::label_rule_scores(&p.x, &p.y, z, image_h);
        let nl = slot.len();
        // Per label: the factor of w̃_i is (1/W̃)·[p_0·r_miss + Σ_j p_j·g_ij / L_j], with
        // p_j / L_j = p_j·W̃ / C_ℓ,j.
        let mut coef = vec![0.0; nl * m];
        for s in 0..nl {
            for j in 0..m {
                let c = c_label[s * m + j];
                if c > 0.0 && p_assoc[s * m + j] > 0.0 {
                    coef[s * m + j] = p_assoc[s * m + j] * w_label[s] / c;
                }
            }
        }
        let label = &p.label;
        let factors: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|i| {
                let gi = &g[i * m..(i + 1) * m];
                match slot.get(&label[i]) {
                    Some(&s) => {
                        let wl = w_label[s];
                        if !(wl > 0.0 && wl.is_finite()) {
                            return 0.0;
                        }
                        let k = &coef[s * m..(s + 1) * m];
                        let det: f64 = gi.iter().zip(k).map(|(gij, kj)| gij * kj).sum();
                        (p_miss[s] * r_miss[s] + det) / wl
                    }
                    None => {
                        let psi_i: f64 = gi
                            .iter()
                            .zip(&c_all)
                            .map(|(gij, c)| gij / (kappa + c))
                            .sum();
                        (1.0 - pd) + psi_i
                    }
                }
            })
            .collect();
        p.h = h;
        for (w, f) in p.w.iter_mut().zip(&factors) {
            *w *= f;
        }
        let mut best = BTreeMap::new();
        for (&l, &s) in &slot {
            let row = &p_assoc[s * m..(s + 1) * m];
            // The first of equal maxima: `max_by` keeps the last, so compare reversed.
            if let Some((j, &pj)) = row
                .iter()
                .enumerate()
                .rev()
                .max_by(|a, b| a.1.total_cmp(b.1))
                && pj > p_miss[s]
            {
                best.insert(l, j);
            }
        }
        best
    }
}
