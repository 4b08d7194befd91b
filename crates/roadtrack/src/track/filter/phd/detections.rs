//! Step d) with detections as measurements ([`LabelledPhd::update_detections`]): the
//! standard SMC-PHD update (Vo, Singh & Doucet 2003) over box measurements, each with its
//! own `σ` per axis (see [`crate::track::filter::detections`]).

use super::{LabelAssociation, LabelUpdate, LabelledPhd};
use crate::geometry::Point;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// One detection as a measurement: its box centre and the standard deviation of the
/// centre's error per axis, px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxMeasurement {
    /// Box centre.
    pub pos: Point,
    /// `σ_x`, `σ_y` (> 0).
    pub sigma: Point,
}

impl BoxMeasurement {
    /// `exp(−d²/2)` with `d` the Mahalanobis distance of `(x, y)` from the centre: the
    /// unit-peak kernel (the label rules' `h`).
    pub fn kernel(&self, x: f64, y: f64) -> f64 {
        let dx = (x - self.pos.x) / self.sigma.x;
        let dy = (y - self.pos.y) / self.sigma.y;
        (-0.5 * (dx * dx + dy * dy)).exp()
    }

    /// The Gaussian density `N(z; (x, y), diag(σ_x², σ_y²))`.
    pub fn density(&self, x: f64, y: f64) -> f64 {
        self.kernel(x, y) / (2.0 * std::f64::consts::PI * self.sigma.x * self.sigma.y)
    }
}

/// What the PHD's detection step needs of the detection model
/// (`DetectionLikelihoodConfig::phd_model` in [`crate::track::filter::detections`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectionModel {
    /// `p_D`.
    pub detection_prob: f64,
    /// `λ_c`, false detections per frame.
    pub clutter_per_frame: f64,
    /// Births only at detections farther than this many `σ` from every label.
    pub birth_gate_sigmas: f64,
    /// Step d) for labelled particles.
    pub label_update: LabelUpdate,
    /// With [`LabelUpdate::Bernoulli`]: whether a detection can explain several labels.
    pub association: LabelAssociation,
    /// With [`LabelAssociation::Exclusive`]: a detection inside the birth gate still
    /// proposes a birth when the labels' probability of being its source
    /// ([`LabelledPhd::detection_claims`]) is below this; 0: the gate alone.
    pub birth_claim_below: f64,
    /// With [`LabelAssociation::Exclusive`]: a label whose box is less than this fraction
    /// visible behind the labels in front of it is detected with `p_D · v / v_full`
    /// ([`super::occlusion`]); 0: one `p_D` for all (the paper).
    pub occlusion_full_visibility: f64,
    /// With [`LabelAssociation::Exclusive`]: a label is written at the centre of its most
    /// probable detection, when that is more probable than a miss, instead of at its mean.
    pub write_detection_centre: bool,
}

impl LabelledPhd {
    /// Step c) with detections: `per_point` birth particles drawn around each of `points`
    /// (Gaussian with the measurement's `σ`), each point's particles under a fresh label,
    /// velocities from the birth prior, importance-weighted so that the birth intensity
    /// stays `μ_Γ` uniform over the region: `w = (μ_Γ / A) / (n · Σ_j N(x; z_j, σ_j²))`.
    /// `sides[j]`: the longer side of point `j`'s box, px (0 without one), which with
    /// [`super::PhdConfig::birth_speed_box_fraction`] widens its velocity prior; missing
    /// entries count as 0. Returns the new labels in the order of `points`.
    // Choice: each detection that no label explains proposes one labelled birth (adaptive
    // births of labelled RFS filters, Reuter et al. 2014) instead of unlabelled particles
    // that the mesh rule labels later: with pedestrians 10–20 px apart a mesh cell (or a
    // merge distance) that fits one person does not exist, and the Bernoulli update then
    // decides existence per birth (≈ μ_Γ·p_D / (λ_c + μ_Γ·p_D) at the first detection).
    pub fn add_labelled_births(
        &mut self,
        points: &[BoxMeasurement],
        sides: &[f64],
        per_point: usize,
    ) -> Vec<u32> {
        let mu = self.config().birth_rate;
        if points.is_empty() || per_point == 0 || mu <= 0.0 {
            return Vec::new();
        }
        let per_point = self.births_per_point(per_point, points.len());
        let (s0, k) = (
            self.config().birth_speed_sigma,
            self.config().birth_speed_box_fraction,
        );
        let (region, area) = (self.region(), self.region().area());
        let mut labels = Vec::with_capacity(points.len());
        for (j, z) in points.iter().enumerate() {
            let s = s0.max(k * sides.get(j).copied().unwrap_or(0.0));
            let label = self.new_label();
            labels.push(label);
            for _ in 0..per_point {
                let pos = Point::new(
                    z.pos.x + z.sigma.x * self.gaussian(),
                    z.pos.y + z.sigma.y * self.gaussian(),
                );
                if !region.contains(pos) {
                    continue;
                }
                let q: f64 = points.iter().map(|zj| zj.density(pos.x, pos.y)).sum();
                let w = (mu / area) / (per_point as f64 * q);
                let vel = Point::new(s * self.gaussian(), s * self.gaussian());
                self.particles.push(pos, vel, w, label);
            }
        }
        labels
    }

    /// Step e) with detections: the border-exit and merge rules only. The likelihood,
    /// split and mesh rules are the image form's way of making and keeping labels; with
    /// detections every birth is labelled ([`LabelledPhd::add_labelled_births`]) and a
    /// label whose object is not detected is a missed detection, not a lost label.
    pub fn update_labels_detections(&mut self) {
        self.rule_border_exit();
        self.rule_merge();
    }

    /// Step d) on detections `z` (METHODS.md eqs. 11–12 with the Gaussian detection
    /// likelihood in place of the window score; Vo, Singh & Doucet 2003):
    ///
    /// ```text
    /// g_ij = p_D · N(z_j; x_i, diag(σ_x,j², σ_y,j²)) · a_i
    /// C_j  = Σ_i g_ij · w̃_i
    /// ŵ_i = [(1 − p_D) + Σ_j g_ij / (κ + C_j)] · w̃_i          (update = Phd)
    /// ```
    ///
    /// with `κ = clutter_per_frame / area` and `a_i` the particle's image likelihood when
    /// `image_h` is given (1 otherwise). With [`LabelUpdate::Bernoulli`] each label is one
    /// Bernoulli component with `f_i = (1 − p_D) + Σ_j g_ij / (κ + C_j − C_ℓ,j)` (as
    /// [`LabelledPhd::update_points`]); unlabelled (birth) particles keep the PHD form.
    /// `h_i = a_i · max_j exp(−d_ij²/2)` (`d`: Mahalanobis distance) is stored for the
    /// label rules.
    pub fn update_detections(
        &mut self,
        z: &[BoxMeasurement],
        detection_prob: f64,
        clutter_per_frame: f64,
        update: LabelUpdate,
        image_h: Option<&[f64]>,
    ) {
        let pd = detection_prob;
        let kappa = clutter_per_frame / self.region().area();
        let p = &mut self.particles;
        let n = p.len();
        let m = z.len();
        let a = |i: usize| image_h.map_or(1.0, |h| h.get(i).copied().unwrap_or(0.0));
        let (x, y) = (&p.x, &p.y);
        let g = |i: usize, j: usize| pd * z[j].density(x[i], y[i]) * a(i);
        let h = label_rule_scores(x, y, z, image_h);
        // C_j summed in particle order for each j (parallel over j: deterministic).
        let w = &p.w;
        let c: Vec<f64> = (0..m)
            .into_par_iter()
            .map(|j| (0..n).map(|i| g(i, j) * w[i]).sum())
            .collect();
        let labelled = update == LabelUpdate::Bernoulli;
        let mut slot: BTreeMap<u32, usize> = BTreeMap::new();
        if labelled {
            for &l in &p.label {
                if l != 0 {
                    let next = slot.len();
                    slot.entry(l).or_insert(next);
                }
            }
        }
        let mut c_label = vec![0.0; slot.len() * m];
        if labelled && m > 0 {
            for (i, (l, wi)) in p.label.iter().zip(w).enumerate() {
                if let Some(&s) = slot.get(l) {
                    for j in 0..m {
                        c_label[s * m + j] += g(i, j) * wi;
                    }
                }
            }
        }
        let label = &p.label;
        // Per particle: (PHD factor for unlabelled or update = Phd, Bernoulli factor f_i).
        let factors: Vec<(Option<f64>, f64)> = (0..n)
            .into_par_iter()
            .map(|i| match slot.get(&label[i]) {
                Some(&s) => {
                    let own = &c_label[s * m..(s + 1) * m];
                    let f = (1.0 - pd)
                        + (0..m)
                            .map(|j| g(i, j) / (kappa + (c[j] - own[j]).max(0.0)))
                            .sum::<f64>();
                    (None, f)
                }
                None => {
                    let psi: f64 = (0..m).map(|j| g(i, j) / (kappa + c[j])).sum();
                    (Some((1.0 - pd) + psi), 0.0)
                }
            })
            .collect();
        p.h = h;
        let mut bernoulli = Vec::with_capacity(if labelled { n } else { 0 });
        for (w, (phd, f)) in p.w.iter_mut().zip(&factors) {
            if let Some(k) = phd {
                *w *= k;
            }
            if labelled {
                bernoulli.push(*f);
            }
        }
        if labelled {
            self.bernoulli_labels(&bernoulli);
        }
    }
}

/// `h_i = a_i · max_j exp(−d_ij²/2)` per particle (`d`: Mahalanobis distance to detection
/// `j`, `a_i` the image likelihood when given, else 1), stored for the label rules by both
/// detection updates. Parallel over particles, each independent: deterministic.
pub(super) fn label_rule_scores(
    x: &[f64],
    y: &[f64],
    z: &[super::BoxMeasurement],
    image_h: Option<&[f64]>,
) -> Vec<f64> {
    let a = |i: usize| image_h.map_or(1.0, |h| h.get(i).copied().unwrap_or(0.0));
    (0..x.len())
        .into_par_iter()
        .map(|i| {
            let best = z
                .iter()
                .map(|zj| zj.kernel(x[i], y[i]))
                .fold(0.0f64, f64::max);
            best * a(i)
        })
        .collect()
}
