//! Parameters of the MRF tracker ([`MrfConfig`], [`MrfVariant`]; docs/MRF.md "Parameters").

use super::object_map::BLOCK_PX;
use crate::detect::background_model::BackgroundConfig;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Which model of the paper to run (METHODS.md §2 "Two variants").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum MrfVariant {
    /// 2000 model: `M` and `D` use each object's representative (most frequent) vector;
    /// no `f` term; vectors are not optimised.
    #[cfg_attr(
        feature = "clap",
        value(help = "2000: representative vector per object, no smoothness term")
    )]
    Legacy,
    /// 2004 model: local per-block vectors, optimised jointly with the ids, and the `f`
    /// smoothness term (eq. 4).
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "2004: local vectors with the smoothness term")
    )]
    Improved,
}

/// Parameters of the MRF tracker (METHODS.md §2). `Default` is the paper's values where
/// the paper gives them (weights `a, b, c, f`, `μ_N`, `μ_M`, 8-px blocks, ±24 px window,
/// 3-block border); the rest are this project's choices, documented in docs/MRF.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MrfConfig {
    /// Model variant. Default improved (2004).
    pub variant: MrfVariant,
    /// `a`, eq. 3/5: weight of the neighbour term. Default 1/2.
    pub neighbour_weight: f64,
    /// `b`, eq. 1/5: weight of the overlap term. Default 1/256.
    pub overlap_weight: f64,
    /// `c`, eq. 1/5: weight of the texture term (luminance SAD). Default 32/1 000 000.
    pub texture_weight: f64,
    /// `f`, eq. 4/5: weight of the motion-vector smoothness term (improved only). Default 1/4.
    pub smoothness_weight: f64,
    /// `μ_N`, eq. 3: neighbours with the same id at the minimum. Default 8.
    pub neighbour_target: f64,
    /// `μ_M`, eq. 1: overlapping pixels at the minimum. Default 64.
    pub overlap_target: f64,
    /// Block side, px. Default 8 (the only value supported: the matching kernel is
    /// specialised for 8-px rows).
    pub block_px: u32,
    /// Block-matching search window half-width in each axis, px (Step 1). Default 24.
    pub search_radius_px: u32,
    /// Gibbs temperature of the first sweep (energy units). Default 4.
    pub initial_temperature: f64,
    /// Factor applied to the temperature after each sweep. Default 0.7.
    pub cooling: f64,
    /// Floor of the temperature. Default 0.05.
    pub min_temperature: f64,
    /// Sweep cap (Step 5). Default 20.
    pub max_iterations: u32,
    /// Step 5: stop when fewer than this many blocks changed id in a sweep… Default 1.
    pub n_th_id: u32,
    /// …and fewer than this many changed vector by more than `v_diff_px`. Default 1.
    pub n_th_mv: u32,
    /// Step 5: a vector change `|Δv_x| + |Δv_y|` above this counts as a change, px. Default 1.
    pub v_diff_px: u32,
    /// A `t − 1` block moved by its vector offers its id to every block of `X(t)` it
    /// overlaps by at least this many pixels, besides its rounded target (Step 2
    /// extension, see docs/MRF.md; 65 = the paper's rounding only). Default 65: the
    /// extension did not help on our scenes (docs/MRF.md).
    pub min_overlap_px: u32,
    /// Improved variant: the vectors the sampler proposes for an id lie within this many px
    /// (per axis) of the id's representative vector (see `gibbs::proposals`). Default 0;
    /// 48 switches the bound off.
    pub local_vector_tolerance_px: u32,
    /// Blocks along each frame edge excluded from tracking (the paper's experiment: 3).
    pub border_blocks: u32,
    /// Smallest connected region of unclaimed moving blocks that becomes a new object,
    /// blocks. Default 4.
    pub birth_min_blocks: u32,
    /// A block is moving when at least this fraction of its pixels are foreground.
    /// Default 0.25.
    pub moving_fraction: f64,
    /// Objects smaller than this many blocks are not reported (they are still tracked).
    /// Default 2.
    pub min_output_blocks: u32,
    /// Background subtraction (the spine's model; the paper says only "background
    /// subtraction"). Default: median start-up, no shadow suppression, no hold.
    pub background: BackgroundConfig,
    /// Start objects from the detector's boxes and split regions that hold several boxes
    /// (module [`boxes`]) instead of the paper's births from unclaimed moving regions, and
    /// report each object with its box. Only where the tracker is given detections
    /// ([`crate::track::Tracker::step`]); [`MrfTracker::step`] alone tracks from pixels.
    /// Default true; `--as-published` turns it off.
    pub use_detections: bool,
    /// A labelled block that block matching finds again with the same texture (mean
    /// absolute difference per pixel at most `keep_max_mean_diff`) carries its id to its
    /// target block even where background subtraction does not mark that block moving,
    /// once its object has travelled `keep_min_travel_px`: a zero vector is a motion too
    /// (a vehicle that stops at a light stays on the map). Default true; `--as-published`
    /// turns it off.
    pub keep_matched_blocks: bool,
    /// Mean absolute luminance difference per pixel below which a block match counts as
    /// the same texture, grey levels. Default 8.
    pub keep_max_mean_diff: f64,
    /// Distance an object must have travelled (sum of its representative vectors'
    /// `|vx| + |vy|`) before its matched blocks are kept, px. Default 8 (one block): a
    /// flicker or a false box that never moved is not kept.
    pub keep_min_travel_px: f64,
    /// With detections: an object that no box has matched for more than this many frames
    /// ends (its blocks are cleared). Default 10.
    pub max_missed_frames: u32,
    /// With detections: a box that no object's blocks claim goes back to an object that
    /// was expected there (its last box moved with its blocks) when their IoU reaches
    /// this. Default 0.3.
    pub revive_iou: f64,
    /// With detections: weight of the block IoU (a box's blocks against an object's blocks
    /// on the Object-map) beside the IoU of the box and the object's expected box when
    /// boxes are matched to objects. Default 0.25.
    pub block_overlap_weight: f64,
    /// With detections: smoothing of an object's box velocity, the weight of the newest
    /// displacement (exponential smoothing). Default 0.1.
    pub velocity_smoothing: f64,
    /// With detections: an object matched in consecutive frames is reported at
    /// `a · box + (1 − a) · expected box` (centre and size), with
    /// `a = clamp(smaller box side / box_smoothing_px, 0.25, 1)`: boxes narrower than this
    /// are smoothed, px. Default 16; 0 reports the detector's boxes as they are.
    pub box_smoothing_px: f64,
    /// With detections: whether the box written is the blended one (`box_smoothing_px`) or
    /// the detector's own; the blended box is what the association predicts from either
    /// way. Default false: the detector's box.
    // Choice: the blend only looks back and lags a box that moves or grows; the offline
    // box fit after the tracker (`--smooth-boxes`, on by default) smooths the written
    // boxes looking both ways. Writing the detector's box raised the MRF's HOTA on all six
    // simulated video scenes from public detections (+0.004 to +0.045) and on five of six
    // from the learned detector's boxes (crossing/oblique −0.001; docs/EXPERIMENTS.md
    // "Writing the detection's centre"). True writes the blend (before 2026-11-29).
    pub write_smoothed_box: bool,
    /// With detections: an object's box velocity starts as the mean of its first
    /// displacements (the k-th with weight `max(1/k, velocity_smoothing)`) instead of at
    /// rest. Default true.
    pub velocity_warmup: bool,
    /// With detections: weight of the appearance similarity (module
    /// [`super::appearance`]: mean colour of a box's upper and lower halves against the
    /// object's) in the score of a box and an object. Default 2; 0 = off.
    pub appearance_weight: f64,
    /// With detections: mean colour difference (grey levels, averaged over the six
    /// channels) at which the appearance similarity reaches 0. Default 40.
    pub appearance_scale: f64,
    /// With detections: weight of a matched box's colours in the object's appearance
    /// (exponential smoothing). Default 0.05.
    pub appearance_smoothing: f64,
    /// With detections: fraction of the box width, around its centre, whose colours are
    /// read. Default 0.5.
    pub appearance_inner_fraction: f64,
    /// With detections: how boxes are matched to objects. Default optimal.
    pub association: Association,
    /// With detections: weight of the centre-distance term `max(0, 1 − d / gate)` in the
    /// score of a box and an object (`d`: distance of the box centre from the object's
    /// expected box centre, px). Default 2; 0 = boxes and blocks overlap only.
    pub distance_weight: f64,
    /// With detections: the distance gate, px: `max(gate_px, gate_width_factor · box
    /// width)`. Default 8.
    pub gate_px: f64,
    /// With detections: see `gate_px`. Default 1.
    pub gate_width_factor: f64,
    /// With detections: a box never continues an object whose last box was of a class it
    /// cannot be ([`ObjectClass::may_be_same_object`]: a pedestrian and a car, lorry or
    /// bus); it starts an object of its own. Default true.
    ///
    /// [`ObjectClass::may_be_same_object`]: crate::class::ObjectClass::may_be_same_object
    pub keep_classes_apart: bool,
    /// With detections: lowest score of a box and an object (the sum of the terms above:
    /// block IoU, box IoU, distance, appearance) at which the box may continue the object;
    /// a box whose every pair scores less starts an object of its own. Default 0: any
    /// candidate pair may match (before 2026-12-01). configs/mrf-intersection.toml sets 1.
    // Choice: 1, in the junction file only (docs/EXPERIMENTS.md "A lowest score for a box
    // to continue an object"): the MRF on the demo's boxes, 14 seeds, HOTA 0.578 → 0.583
    // (better on 11 of 14), turning error 24.1 → 21.1 %; the oblique crossing's pipeline
    // from video, held-out seeds 4–6 0.619 → 0.633, seeds 1–3 0.616 → 0.644; the oblique
    // intersection's 0.715 → 0.718 and 0.708 → 0.715; no sequence lower. 0.75 / 1.25 / 1.5
    // on the crossing's seeds 4–6: 0.626 / 0.628 / 0.626.
    pub min_match_score: f64,
    /// With detections: an object no box matched whose expected box lies less than this
    /// fraction inside the frame has left the view and ends at once, before
    /// `max_missed_frames`. Default 0.5; 0 = off.
    pub end_outside_fraction: f64,
    /// With detections: whether an object that no box matched this frame is written (its
    /// last box, moved with its blocks) or left out of the frame. Default true. With false
    /// an object is written only in the frames where a box matched it, and the track life
    /// cycle after the method fills the gaps with boxes interpolated between them
    /// (`track --coast-frames N`, N at least `max_missed_frames`).
    // Choice: the block-moved box is the seed's tracking between detections and stays the
    // default; offline, a box interpolated between the boxes before and after a gap lands
    // closer (oblique intersection from video, seeds 4–6, junction file with
    // `max_missed_frames` 40 and `--coast-frames 40`: HOTA 0.597 written, 0.605 left out;
    // docs/EXPERIMENTS.md "Interpolating the MRF's gaps"). configs/mrf-intersection.toml
    // sets false.
    pub write_unmatched: bool,
}

/// How the boxes of a frame are matched to objects ([`MrfConfig::association`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Association {
    /// One-to-one by descending score (the matching before issue 14).
    Greedy,
    /// One-to-one of maximum total score (Hungarian).
    #[default]
    Optimal,
}

impl Default for MrfConfig {
    fn default() -> Self {
        Self {
            variant: MrfVariant::Improved,
            neighbour_weight: 0.5,
            overlap_weight: 1.0 / 256.0,
            texture_weight: 32.0 / 1_000_000.0,
            smoothness_weight: 0.25,
            neighbour_target: 8.0,
            overlap_target: 64.0,
            block_px: BLOCK_PX,
            search_radius_px: 24,
            initial_temperature: 4.0,
            cooling: 0.7,
            min_temperature: 0.05,
            max_iterations: 20,
            n_th_id: 1,
            n_th_mv: 1,
            v_diff_px: 1,
            min_overlap_px: 65,
            local_vector_tolerance_px: 0,
            border_blocks: 3,
            birth_min_blocks: 4,
            moving_fraction: 0.25,
            min_output_blocks: 2,
            // Choice: the MRF keeps the median start-up without shadow suppression or hold
            // (`BackgroundConfig::as_published`). With the detector's newer defaults its
            // occlusion scenarios lose ids (a parked-looking object held in the foreground
            // is split between regions) and on vtest.avi fewer walkers keep their ids from
            // frame 30 to 60; the MRF reads every foreground block, not regions, so it gains
            // little from them. `[background] startup = "persistent"` opts in.
            background: BackgroundConfig::default().as_published(),
            use_detections: true,
            keep_matched_blocks: true,
            keep_max_mean_diff: 8.0,
            keep_min_travel_px: 8.0,
            max_missed_frames: 10,
            revive_iou: 0.3,
            block_overlap_weight: 0.25,
            velocity_smoothing: 0.1,
            box_smoothing_px: 16.0,
            write_smoothed_box: false,
            // Choice (issue 14, means over seeds 1–3 from public detections, HOTA / IDF1 on
            // intersection and crossing, docs/MRF.md "Detections"): the old greedy IoU
            // matching 0.686 / 0.786 and 0.663 / 0.770; Hungarian with the centre-distance
            // term (weight 1, gate max(8 px, box width)) 0.741 / 0.884 and 0.685 / 0.802 — a
            // 5 px pedestrian leaves its expected box's IoU within a frame or two and was
            // restarted as a new id; greedy with it 0.728 / 0.867 and 0.690 / 0.806;
            // distance weight 2 0.741 / 0.883 and 0.699 / 0.821 (4: 0.738 and 0.695); a
            // gate of twice the width 0.737 and 0.667; the velocity warm-up 0.740 and
            // 0.702; the appearance term (weight 2, scale 40, smoothing 0.05) 0.751 /
            // 0.898 and 0.707 / 0.829 (weight 1 or 3, scale 20, smoothing 0.02 or 0.2: at
            // most 0.704 on the crossing). Road/aerial 0.647 / 0.825 → 0.690 / 0.884.
            velocity_warmup: true,
            appearance_weight: 2.0,
            appearance_scale: 40.0,
            appearance_smoothing: 0.05,
            appearance_inner_fraction: 0.5,
            association: Association::Optimal,
            distance_weight: 2.0,
            gate_px: 8.0,
            gate_width_factor: 1.0,
            keep_classes_apart: true,
            min_match_score: 0.0,
            end_outside_fraction: 0.5,
            write_unmatched: true,
        }
    }
}

impl crate::config::Validate for MrfConfig {
    fn validate(&self) -> crate::error::Result<()> {
        MrfConfig::validate(self)
    }
}

impl MrfConfig {
    /// The paper's model as published: births from pixels only, no kept blocks, the
    /// background model's later additions off (`--as-published`).
    pub fn as_published(mut self) -> Self {
        self.use_detections = false;
        self.keep_matched_blocks = false;
        self.background = self.background.as_published();
        self
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        let err = |field, reason: String| Err(Error::config("MrfConfig", field, reason));
        for (field, v) in [
            ("neighbour_weight", self.neighbour_weight),
            ("overlap_weight", self.overlap_weight),
            ("texture_weight", self.texture_weight),
            ("smoothness_weight", self.smoothness_weight),
            ("neighbour_target", self.neighbour_target),
            ("overlap_target", self.overlap_target),
            ("keep_max_mean_diff", self.keep_max_mean_diff),
            ("keep_min_travel_px", self.keep_min_travel_px),
            ("block_overlap_weight", self.block_overlap_weight),
            ("distance_weight", self.distance_weight),
            ("gate_px", self.gate_px),
            ("gate_width_factor", self.gate_width_factor),
            ("appearance_weight", self.appearance_weight),
            ("appearance_scale", self.appearance_scale),
            ("min_match_score", self.min_match_score),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return err(field, format!("must be finite and ≥ 0, found {v}"));
            }
        }
        if self.block_px != BLOCK_PX {
            return err(
                "block_px",
                format!("only {BLOCK_PX} is supported, found {}", self.block_px),
            );
        }
        if self.search_radius_px > 127 {
            return err(
                "search_radius_px",
                format!("must be ≤ 127, found {}", self.search_radius_px),
            );
        }
        if !(self.initial_temperature.is_finite() && self.initial_temperature > 0.0) {
            return err(
                "initial_temperature",
                format!("must be > 0, found {}", self.initial_temperature),
            );
        }
        if !(self.min_temperature.is_finite() && self.min_temperature > 0.0) {
            return err(
                "min_temperature",
                format!("must be > 0, found {}", self.min_temperature),
            );
        }
        if !(self.cooling > 0.0 && self.cooling <= 1.0) {
            return err(
                "cooling",
                format!("must be in (0, 1], found {}", self.cooling),
            );
        }
        if self.max_iterations == 0 {
            return err("max_iterations", "must be at least 1".into());
        }
        if let Err(m) = crate::limits::at_most(
            self.max_iterations,
            crate::limits::MAX_ITERATIONS,
            "iterations",
        ) {
            return err("max_iterations", m);
        }
        if !(self.moving_fraction > 0.0 && self.moving_fraction <= 1.0) {
            return err(
                "moving_fraction",
                format!("must be in (0, 1], found {}", self.moving_fraction),
            );
        }
        if !(self.box_smoothing_px.is_finite() && self.box_smoothing_px >= 0.0) {
            return err(
                "box_smoothing_px",
                format!("must be finite and ≥ 0, found {}", self.box_smoothing_px),
            );
        }
        if !(self.velocity_smoothing > 0.0 && self.velocity_smoothing <= 1.0) {
            return err(
                "velocity_smoothing",
                format!("must be in (0, 1], found {}", self.velocity_smoothing),
            );
        }
        for (field, v) in [
            ("appearance_smoothing", self.appearance_smoothing),
            ("appearance_inner_fraction", self.appearance_inner_fraction),
        ] {
            if !(v > 0.0 && v <= 1.0) {
                return err(field, format!("must be in (0, 1], found {v}"));
            }
        }
        if !(0.0..=1.0).contains(&self.end_outside_fraction) {
            return err(
                "end_outside_fraction",
                format!("must be in [0, 1], found {}", self.end_outside_fraction),
            );
        }
        if !(0.0..=1.0).contains(&self.revive_iou) {
            return err(
                "revive_iou",
                format!("must be in [0, 1], found {}", self.revive_iou),
            );
        }
        if let Err(m) =
            crate::limits::at_most(self.max_missed_frames, crate::limits::MAX_FRAME, "frames")
        {
            return err("max_missed_frames", m);
        }
        if self.birth_min_blocks == 0 {
            return err("birth_min_blocks", "must be at least 1".into());
        }
        self.background
            .validate()
            .map_err(|e| e.in_table("background"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers() {
        let c = MrfConfig::default(); // METHODS.md §2
        assert_eq!(
            (
                c.neighbour_weight,
                c.overlap_weight,
                c.texture_weight,
                c.smoothness_weight
            ),
            (0.5, 1.0 / 256.0, 32e-6, 0.25)
        );
        assert_eq!((c.neighbour_target, c.overlap_target), (8.0, 64.0));
        assert_eq!(
            (c.block_px, c.search_radius_px, c.border_blocks),
            (8, 24, 3)
        );
        assert_eq!(c.variant, MrfVariant::Improved);
        assert!(c.validate().is_ok());
    }

    #[test]
    fn config_reads_from_toml_and_rejects_typos() -> Result<()> {
        let c: MrfConfig = toml::from_str("variant = \"legacy\"\nsearch_radius_px = 16\n")
            .map_err(|e| Error::Invalid(e.to_string()))?;
        assert_eq!(c.variant, MrfVariant::Legacy);
        assert_eq!(c.search_radius_px, 16);
        assert!(toml::from_str::<MrfConfig>("serch_radius_px = 16").is_err());
        let bad = MrfConfig {
            block_px: 16,
            ..MrfConfig::default()
        };
        assert!(bad.validate().is_err());
        for v in [-0.1, 1.5, f64::NAN] {
            let bad = MrfConfig {
                end_outside_fraction: v,
                ..MrfConfig::default()
            };
            let m = bad.validate().expect_err("out of range").to_string();
            assert!(m.contains("end_outside_fraction"), "{m}");
        }
        Ok(())
    }
}
