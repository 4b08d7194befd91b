//! Detections as measurements (issue 14): the detection likelihood of the image filters.
//!
//! The paper's observation is the image (a classifier scores the window at each particle,
//! METHODS.md §3); when the pipeline has detections (`--detector file|background|onnx`)
//! they can be the measurements instead, as in the point filter: each detection is a
//! point measurement `z_j` (its box centre) with a Gaussian error whose standard deviation
//! per axis is a fraction of its box side, detected with probability `p_D`, among clutter
//! of `λ_c` false detections per frame uniform over the image (`κ = λ_c / area`):
//!
//! ```text
//! g_ij = p_D · N(z_j; (x_i, y_i), diag(σ_x,j², σ_y,j²))
//! PHD (Vo, Singh & Doucet 2003; METHODS.md eqs. 11–12 with h = g):
//!   C_j = Σ_i g_ij · w̃_i,   ŵ_i = [(1 − p_D) + Σ_j g_ij / (κ + C_j)] · w̃_i
//! PF, the object's detection z_a (one-to-one, closest first, within a gate):
//!   w_i ∝ (1 − p_D)·κ + g_ia            (no detection: the weights stay equal)
//! ```
//!
//! [`Measurements`] selects the paper's image likelihood, the detections, or both (the
//! image likelihood `h_i` then multiplies `g_ij`).

pub use super::phd::BoxMeasurement;
use super::phd::{DetectionModel, LabelAssociation, LabelUpdate};
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::geometry::Point;
use serde::{Deserialize, Serialize};

/// What the image filters weigh their particles by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Measurements {
    /// The image likelihood `h(y | x)` of the window at each particle (the paper; colour or
    /// a network, [`super::config::TrackLikelihoodConfig`]); detections only start tracks.
    Image,
    /// The detections as point measurements with `p_D` and clutter
    /// ([`DetectionLikelihoodConfig`]); no image likelihood is evaluated.
    Detections,
    /// Both: `g_ij` times the particle's image likelihood `h_i`.
    DetectionsAndImage,
}

impl Measurements {
    /// Whether the detections are measurements.
    pub fn uses_detections(self) -> bool {
        !matches!(self, Self::Image)
    }

    /// Whether the image likelihood is evaluated.
    pub fn uses_image(self) -> bool {
        !matches!(self, Self::Detections)
    }
}

/// The detection likelihood's model (TOML table `[detections]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectionLikelihoodConfig {
    /// `p_D`: probability that an object present is detected in a frame. Default 0.9.
    // Choice: the simulator's public detections miss 5 % of the objects at least 30 %
    // visible and every less visible one; 0.9 covers both without being told the scene.
    pub detection_prob: f64,
    /// `λ_c`: expected false detections per frame, uniform over the image. Default 1.
    // Choice: the simulator's detector adds 0.5 per frame; a background detector more
    // (shadows, noise). Twice the simulator's keeps a lone false detection from starting
    // a confirmed track in one frame.
    pub clutter_per_frame: f64,
    /// `σ` per axis as a fraction of the detection box's side on that axis. Default 0.05.
    // Choice: the error of a box centre grows with the box (a detector's localisation
    // error is a fraction of the object); 0.05 of a 14 × 40 px pedestrian is 2 px (the
    // floor) × 2 px, of a 150 × 80 px car 7.5 × 4 px. On crossing/oblique 0.05 gave the
    // PF HOTA 0.688 against 0.678 with 0.15 (docs/EXPERIMENTS.md).
    pub sigma_box_fraction: f64,
    /// Smallest `σ`, px (also the `σ` of a detection without a box). Default 2.
    pub min_sigma_px: f64,
    /// PF: a detection is an object's when it is the closest free one within this many
    /// standard deviations of its predicted position (particle spread and `σ` combined).
    /// Default 4.
    pub pf_gate_sigmas: f64,
    /// PF: an object started less than this many detections ago ends at its first frame
    /// without one (tentative objects do not coast). Default 3.
    // Choice: a false detection (0.5 per frame in the simulator) otherwise starts an object
    // that coasts for `max_lost_frames` and is reported all that time.
    pub pf_tentative_detections: u32,
    /// PF: in a frame where an object took a detection, the box written is centred on the
    /// detection instead of the particles' weighted mean (the particles are unchanged; the
    /// support deleter and the box sizer read the written box; without a detection the
    /// mean is written). Default false.
    // Choice: the posterior mean lags an object that speeds up, slows down or turns (a
    // motion model that mostly keeps the velocity), and the offline box fit after the
    // tracker (`--smooth-boxes`) smooths the written boxes looking both ways. From public
    // detections this raised the PF's HOTA on all six simulated video scenes (+0.006 to
    // +0.023), from the learned detector's boxes on five (crossing/oblique −0.003;
    // docs/EXPERIMENTS.md "Writing the detection's centre"). Off by default, where the
    // estimate is the method's output; configs/filters-pedestrians.toml sets it.
    pub pf_write_detection_centre: bool,
    /// PHD with `label_association = "exclusive"`: a label whose most probable source this
    /// frame is a detection (its marginal association probability above that of a miss)
    /// is written at that detection's centre instead of its particles' mean. Default
    /// false.
    // Choice: as `pf_write_detection_centre`, for the same reason; the labels' weights and
    // particles are unchanged. configs/filters-pedestrians.toml sets it.
    pub phd_write_detection_centre: bool,
    /// PHD: a detection within this many `σ` of a label's predicted position is explained
    /// by it and proposes no birth. Default 5.
    // Choice: 3 σ let a label that lags its object by a few px start a second label on
    // it; 8 σ suppressed births beside walking neighbours (crossing/oblique HOTA 0.669,
    // 0.681, 0.659 for 3, 5, 8).
    pub birth_gate_sigmas: f64,
    /// PHD: `β_center` with detections, px (replaces `[phd] merge_distance`). Default 0
    /// (no merging).
    // Choice: the paper's 40 px merges pedestrians walking side by side (10–20 px apart);
    // births are gated by the labels already, and every merge distance tried cost
    // identities where people pass or occlude each other (crossing/oblique PHD HOTA 0.52
    // at 5 px, 0.60 at 0 px with the other defaults; 0.60 at 3 px, 0.67 at 0 px with the
    // pedestrian config).
    pub merge_distance_px: f64,
    /// The PHD's step d) for labelled particles with these measurements. Default
    /// Bernoulli.
    // Choice: detections are not the paper's observation (as points are not), so the PHD
    // takes the form whose count follows the objects, as the point filter does
    // (docs/FILTERS.md "Expected count"); `phd` gives Vo et al.'s update.
    pub label_update: LabelUpdate,
    /// PHD with `label_update = "bernoulli"`: `exclusive` (a detection is the measurement
    /// of at most one label, labelled multi-Bernoulli with loopy belief propagation) or
    /// `shared` (every label weighs every detection, the form before). Default exclusive.
    // Choice: with shared detections two labels can follow one person and one label can
    // hold a neighbour's detection too (crossing/oblique: 0.35 duplicate labels per
    // frame); the LMB's one-to-one association (Reuter et al. 2014) is the standard
    // remedy and equals the shared form for a label alone (docs/EXPERIMENTS.md "Filters
    // with detections as measurements").
    pub label_association: LabelAssociation,
    /// PHD with `label_association = "exclusive"`: a detection within
    /// `birth_gate_sigmas` of a label still proposes a birth when the labels are its
    /// source with a probability below this (their marginal association probability);
    /// 0 leaves the gate alone. In [0, 1]. Default 0.5.
    // Choice: the distance gate alone leaves a person who walks within 5 σ of a
    // neighbour's label without a label (crossing/oblique: 0.47 detected people per
    // frame without one, 0.08 with this rule), and the association knows that the
    // neighbour's label has its own detection. Means over four filter seeds: crossing
    // HOTA 0.677 → 0.685 (defaults), 0.674 → 0.689 (filters-pedestrians.toml; 0.2 and
    // 0.8 gave 0.688 and 0.684), intersection 0.663 → 0.670 (docs/EXPERIMENTS.md).
    pub birth_claim_below: f64,
    /// PHD with `label_association = "exclusive"`: occlusion-aware `p_D`. A label whose
    /// predicted box (its last matched detection's size) is a fraction `v` visible behind
    /// the boxes of labels in front of it (lower bottom edge, existence ≥ 0.5) is detected
    /// with `p_D · min(1, v / occlusion_full_visibility)`, so a person walking behind
    /// another keeps their label through the misses. In [0, 1]; 0 (default) keeps the
    /// paper's single `p_D`.
    // Choice: off by default (the paper's model); configs/filters-pedestrians.toml sets it
    // where people occlude each other (docs/EXPERIMENTS.md "Occlusion-aware p_D").
    pub occlusion_full_visibility: f64,
}

impl Default for DetectionLikelihoodConfig {
    fn default() -> Self {
        Self {
            detection_prob: 0.9,
            clutter_per_frame: 1.0,
            sigma_box_fraction: 0.05,
            min_sigma_px: 2.0,
            pf_gate_sigmas: 4.0,
            pf_tentative_detections: 3,
            pf_write_detection_centre: false,
            phd_write_detection_centre: false,
            birth_gate_sigmas: 5.0,
            merge_distance_px: 0.0,
            label_update: LabelUpdate::Bernoulli,
            label_association: LabelAssociation::Exclusive,
            birth_claim_below: 0.5,
            occlusion_full_visibility: 0.0,
        }
    }
}

impl DetectionLikelihoodConfig {
    /// Checks every range.
    ///
    /// # Errors
    /// The first field out of range, named as in the `[detections]` table.
    pub fn validate(&self) -> Result<()> {
        let c = "DetectionLikelihoodConfig";
        if !(self.detection_prob > 0.0 && self.detection_prob <= 1.0) {
            return Err(Error::config(c, "detection_prob", "must be in (0, 1]"));
        }
        for (v, f) in [
            (self.clutter_per_frame, "clutter_per_frame"),
            (self.sigma_box_fraction, "sigma_box_fraction"),
            (self.min_sigma_px, "min_sigma_px"),
            (self.pf_gate_sigmas, "pf_gate_sigmas"),
            (self.birth_gate_sigmas, "birth_gate_sigmas"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::config(
                    c,
                    f,
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        if !(self.birth_claim_below >= 0.0 && self.birth_claim_below <= 1.0) {
            return Err(Error::config(
                c,
                "birth_claim_below",
                format!("must be in [0, 1], got {}", self.birth_claim_below),
            ));
        }
        if !(self.occlusion_full_visibility >= 0.0 && self.occlusion_full_visibility <= 1.0) {
            return Err(Error::config(
                c,
                "occlusion_full_visibility",
                format!("must be in [0, 1], got {}", self.occlusion_full_visibility),
            ));
        }
        if self.occlusion_full_visibility > 0.0
            && !(self.label_update == LabelUpdate::Bernoulli
                && self.label_association == LabelAssociation::Exclusive)
        {
            return Err(Error::config(
                c,
                "occlusion_full_visibility",
                "needs label_update = \"bernoulli\" and label_association = \"exclusive\"",
            ));
        }
        if !(self.merge_distance_px.is_finite() && self.merge_distance_px >= 0.0) {
            return Err(Error::config(
                c,
                "merge_distance_px",
                "must be finite and ≥ 0",
            ));
        }
        Ok(())
    }

    /// The measurement of `d`: its centre and `σ` per axis.
    pub fn measurement(&self, d: &Detection) -> BoxMeasurement {
        let (w, h) = d.size_px.unwrap_or((0.0, 0.0));
        let s = |side: f64| {
            let v = self.sigma_box_fraction * side;
            if v.is_finite() {
                v.max(self.min_sigma_px)
            } else {
                self.min_sigma_px
            }
        };
        BoxMeasurement {
            pos: d.pos_px,
            sigma: Point::new(s(w), s(h)),
        }
    }

    /// The PHD's part of the model ([`super::phd::PhdTracker::step_with_detections`]).
    pub fn phd_model(&self) -> DetectionModel {
        DetectionModel {
            detection_prob: self.detection_prob,
            clutter_per_frame: self.clutter_per_frame,
            birth_gate_sigmas: self.birth_gate_sigmas,
            label_update: self.label_update,
            association: self.label_association,
            birth_claim_below: self.birth_claim_below,
            occlusion_full_visibility: self.occlusion_full_visibility,
            write_detection_centre: self.phd_write_detection_centre,
        }
    }

    /// The measurements of `dets`, in order.
    pub fn measurements(&self, dets: &[Detection]) -> Vec<BoxMeasurement> {
        dets.iter().map(|d| self.measurement(d)).collect()
    }
}

/// Greedy one-to-one assignment: pairs `(object, measurement)` with squared Mahalanobis
/// distance at most `gate²`, taken closest first (ties by object, then measurement index),
/// each object and measurement at most once, never a pair `allowed(object, measurement)`
/// refuses. `objects`: predicted mean and the variance of the prediction per axis.
pub fn assign_closest(
    objects: &[(Point, Point)],
    measurements: &[BoxMeasurement],
    gate: f64,
    allowed: &dyn Fn(usize, usize) -> bool,
) -> Vec<Option<usize>> {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, (p, var)) in objects.iter().enumerate() {
        for (j, m) in measurements.iter().enumerate() {
            if !allowed(i, j) {
                continue;
            }
            let vx = var.x + m.sigma.x * m.sigma.x;
            let vy = var.y + m.sigma.y * m.sigma.y;
            let d2 = (p.x - m.pos.x).powi(2) / vx + (p.y - m.pos.y).powi(2) / vy;
            if d2 <= gate * gate {
                pairs.push((d2, i, j));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut out = vec![None; objects.len()];
    let mut used = vec![false; measurements.len()];
    for (_, i, j) in pairs {
        if out[i].is_none() && !used[j] {
            out[i] = Some(j);
            used[j] = true;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_measurement_takes_its_sigma_from_the_box_with_a_floor() {
        let cfg = DetectionLikelihoodConfig {
            sigma_box_fraction: 0.15,
            ..Default::default()
        };
        let d = Detection {
            size_px: Some((10.0, 40.0)),
            ..Detection::at(1, 1, Point::new(5.0, 6.0))
        };
        let m = cfg.measurement(&d);
        assert_eq!(m.pos, Point::new(5.0, 6.0));
        assert_eq!(m.sigma, Point::new(2.0, 6.0));
        assert!((m.kernel(5.0, 6.0) - 1.0).abs() < 1e-12);
        // One σ off on x: exp(−1/2).
        assert!((m.kernel(7.0, 6.0) - (-0.5f64).exp()).abs() < 1e-12);
        let mut bad = cfg;
        bad.detection_prob = 0.0;
        assert!(bad.validate().is_err());
        bad = cfg;
        bad.min_sigma_px = f64::NAN;
        assert!(bad.validate().is_err());
    }

    #[test]
    fn assignment_takes_the_closest_pairs_once_within_the_gate() {
        let m = |x: f64| BoxMeasurement {
            pos: Point::new(x, 0.0),
            sigma: Point::new(1.0, 1.0),
        };
        let objects = [
            (Point::new(0.0, 0.0), Point::new(0.0, 0.0)),
            (Point::new(1.0, 0.0), Point::new(0.0, 0.0)),
            (Point::new(50.0, 0.0), Point::new(0.0, 0.0)),
        ];
        // Object 1 is closest to the measurement at 0.9; object 0 takes the one at -2.
        let got = assign_closest(&objects, &[m(0.9), m(-2.0)], 4.0, &|_, _| true);
        assert_eq!(got, vec![Some(1), Some(0), None]);
        // Object 1 may not take the first: object 0 does, and object 1 the other.
        let got = assign_closest(&objects, &[m(0.9), m(-2.0)], 4.0, &|i, j| (i, j) != (1, 0));
        assert_eq!(got, vec![Some(0), Some(1), None]);
    }
}
