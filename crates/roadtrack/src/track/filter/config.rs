//! Configuration of the image filters (`roadtrack track --method pf|phd --config F.toml`:
//! tables `[detector]`, `[pf]`, `[phd]`, `[likelihood]`).

use super::detections::{DetectionLikelihoodConfig, Measurements};
use super::particle::ParticleFilterConfig;
use super::phd::PhdConfig;
use crate::detect::background::BackgroundDetectorConfig;
use crate::error::{Error, Result};
pub use crate::likelihood::foreground::LikelihoodKind;
use crate::likelihood::{BorderPolicy, ColourLikelihoodConfig, Window};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which filter tracks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FilterMethod {
    /// The basic particle filter, `ρ` particles per object ([`ParticleFilterTracker`]).
    Pf,
    /// The labelled SMC-PHD filter ([`PhdTracker`]).
    Phd,
}

impl std::str::FromStr for FilterMethod {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "pf" => Ok(Self::Pf),
            "phd" => Ok(Self::Phd),
            _ => Err(Error::Invalid(format!(
                "unknown filter method {s:?}: expected pf or phd"
            ))),
        }
    }
}

/// Where the colour likelihood's reference histogram comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ColourReference {
    /// Each PF object's own start detection (the classic colour tracker, Pérez et al.
    /// 2002). The PHD filter, which needs one class likelihood, always uses `shared`.
    #[default]
    PerObject,
    /// The mean histogram of the detections of the first
    /// [`TrackLikelihoodConfig::reference_frames`] frames that have any: one "class"
    /// likelihood for every object, as the paper's CNN.
    Shared,
}

/// Where the PHD filter's birth particles go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BirthSource {
    /// Around the detections no label explains ([`super::LabelledPhd::add_births_at`]).
    #[default]
    Detections,
    /// The paper's fixed grid of [`PhdConfig::birth_grid_points`] points.
    Grid,
    /// Both.
    Both,
}

/// The likelihood of the image trackers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackLikelihoodConfig {
    /// What `h` measures. Default colour.
    pub kind: LikelihoodKind,
    /// Foreground fraction of a window that counts as a whole object (`h = 1`). Default 0.5.
    // Choice: a window matched to an object's box is about half covered by its mask (boxes
    // of oblique vehicles and of pedestrians are far from filled).
    pub foreground_full: f64,
    /// Histogram bins per RGB channel. Default 8.
    pub bins_per_channel: u32,
    /// Sample every `pixel_step`-th row and column of the window. Default 2.
    pub pixel_step: u32,
    /// `λ` in `h = exp(−λ·(1 − BC))`. Default 5.
    // Choice: 5, not Pérez's 20: the PHD update needs h near 1 on an object for its weight
    // to stay above the report threshold (docs/FILTERS.md, "Properties of the paper's
    // update"); with λ = 20 a window slightly off the object already scores < 0.05.
    pub sharpness: f64,
    /// The window is the detection's box (PF, per object) or the median detection box of
    /// the reference frames (shared) times this. Default 1.
    pub window_scale: f64,
    /// Smallest window side, px. Default 8.
    pub min_window_px: u32,
    /// Border handling of the window. Default clamp.
    pub border: BorderPolicy,
    /// Where the reference histogram comes from (PF). Default per object.
    pub reference: ColourReference,
    /// Frames with detections whose boxes make the shared reference (and the shared window
    /// size). Default 10. Frames before the reference is complete are buffered and then
    /// tracked as every other frame.
    pub reference_frames: u32,
    /// Dense mode: score a grid of this spacing once per frame and answer particles by
    /// bilinear lookup ([`DenseLikelihood`] over [`GridScorer`]); 0 = score every particle's
    /// window. Applies to a shared likelihood only. Default 0.
    pub dense_stride_px: u32,
}

impl Default for TrackLikelihoodConfig {
    fn default() -> Self {
        Self {
            kind: LikelihoodKind::Colour,
            foreground_full: 0.5,
            bins_per_channel: 8,
            pixel_step: 2,
            sharpness: 5.0,
            window_scale: 1.0,
            min_window_px: 8,
            border: BorderPolicy::Clamp,
            reference: ColourReference::PerObject,
            reference_frames: 10,
            dense_stride_px: 0,
        }
    }
}

impl TrackLikelihoodConfig {
    /// The colour likelihood config for a window of `size` px (before scaling).
    pub(crate) fn colour(&self, size: (f64, f64)) -> ColourLikelihoodConfig {
        let side = |v: f64| {
            let v = (v * self.window_scale).round();
            if v.is_finite() {
                (v as u32).max(self.min_window_px)
            } else {
                self.min_window_px
            }
        };
        ColourLikelihoodConfig {
            bins_per_channel: self.bins_per_channel,
            window: Window::new(side(size.0), side(size.1), self.border),
            pixel_step: self.pixel_step,
            sharpness: self.sharpness,
        }
    }
}

/// Everything `roadtrack track --method pf|phd` needs besides the input and the seed
/// (`--config F.toml`: tables `[detector]`, `[pf]`, `[phd]`, `[likelihood]`,
/// `[detections]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FilterTrackConfig {
    /// Foreground extraction (track starts, births, support, box sizes).
    pub detector: BackgroundDetectorConfig,
    /// The particle filter (Table 5 defaults).
    pub pf: ParticleFilterConfig,
    /// The labelled SMC-PHD filter (Table 9 defaults).
    pub phd: PhdConfig,
    /// The colour likelihood.
    pub likelihood: TrackLikelihoodConfig,
    /// What the particles are weighed by: the image likelihood (the paper), the
    /// detections, or both. Default detections.
    // Choice: the detection likelihood is the default because it measured better on every
    // simulated scene (docs/EXPERIMENTS.md "Filters with detections as measurements");
    // `--as-published` and `--likelihood colour|cnn|ssd` give the paper's image likelihood.
    pub measurements: Measurements,
    /// The detection likelihood's model (`[detections]`).
    pub detections: DetectionLikelihoodConfig,
    /// Where PHD births go. Default detections.
    // Choice: the paper's grid births rely on a classifier that scores background ≈ 0; a
    // colour histogram scores background windows of similar colour well above α_mesh, so
    // grid births there start phantom labels. `grid` and `both` are available.
    pub births: BirthSource,
    /// Birth particles per detection. Default 70 (`ρ`).
    pub birth_particles_per_detection: usize,
    /// Spread of birth particles around a detection, px. Default 4.
    pub birth_spread_px: f64,
    /// A detection within this distance of a label's predicted position is explained by
    /// it and seeds no birth, px. Default 30 (the PF's new-object gate).
    pub birth_gate_px: f64,
    /// A track is supported in a frame when a detection lies within this distance, px.
    /// Default 30.
    pub support_gate_px: f64,
    /// A track (PF object or PHD label) without support for more frames than this ends;
    /// 0 disables the rule. Default 20 (2 s at 10 frames/s).
    // Choice: the paper gives no rule for ending tracks besides the likelihood and border
    // rules. With a colour likelihood a track that slid onto similar background keeps a
    // high likelihood forever; the foreground detector is independent evidence.
    pub max_frames_without_detection: u32,
    /// Give each estimate the box size of its nearest detection within
    /// [`FilterTrackConfig::support_gate_px`] (else its last size, else the window).
    /// Default true.
    // Choice: the filters estimate a position only; box-based metrics (IoU) need a size.
    pub box_from_detections: bool,
    /// PHD: frames of look-ahead for the smoothed count ([`super::FrameCount::smoothed`],
    /// `phd::ExistenceSmoother`): a label's existence at frame t given the frames up to
    /// t + this. 0 = off (the smoothed count is Σw). Default 0;
    /// configs/filters-pedestrians.toml sets 1. The tracks are not affected.
    // Choice: off by default. The smoother reads each label as an independent Bernoulli
    // component; labels that share detections and hold a fractional weight for many
    // frames (dense dots seen from above, far cars; and any label with Table 9's p_s 0.9,
    // whose steady weights the survival step lowers every frame) are raised by it, so the
    // count runs high there (aerial crossing with the defaults: MAE 1.7 -> 4.5-7.2). With
    // filters-pedestrians.toml on people and vehicles seen from the side and the road from
    // above it lowers the count MAE by 0.1-0.2 (docs/EXPERIMENTS.md "The count smoothed
    // over the next frame").
    pub count_lag_frames: u32,
}

impl Default for FilterTrackConfig {
    fn default() -> Self {
        Self {
            detector: BackgroundDetectorConfig::default(),
            pf: ParticleFilterConfig::default(),
            phd: PhdConfig::default(),
            likelihood: TrackLikelihoodConfig::default(),
            measurements: Measurements::Detections,
            detections: DetectionLikelihoodConfig::default(),
            births: BirthSource::Detections,
            birth_particles_per_detection: 70,
            birth_spread_px: 4.0,
            birth_gate_px: 30.0,
            support_gate_px: 30.0,
            max_frames_without_detection: 20,
            box_from_detections: true,
            count_lag_frames: 0,
        }
    }
}

impl crate::config::Validate for FilterTrackConfig {
    fn validate(&self) -> crate::error::Result<()> {
        FilterTrackConfig::validate(self)
    }
}

impl FilterTrackConfig {
    /// Checks every range, nested configs included.
    pub fn validate(&self) -> Result<()> {
        let c = "FilterTrackConfig";
        self.detector
            .validate()
            .map_err(|e| e.in_table("detector"))?;
        self.pf.validate().map_err(|e| e.in_table("pf"))?;
        self.phd.validate().map_err(|e| e.in_table("phd"))?;
        self.detections
            .validate()
            .map_err(|e| e.in_table("detections"))?;
        crate::limits::at_most(
            self.likelihood.min_window_px,
            crate::limits::MAX_IMAGE_SIDE,
            "longest image side",
        )
        .map_err(|m| Error::config(c, "likelihood.min_window_px", m))?;
        self.likelihood
            .colour((32.0, 32.0))
            .validate()
            .map_err(|e| e.in_table("likelihood"))?;
        let l = &self.likelihood;
        if !(l.window_scale.is_finite() && l.window_scale > 0.0) {
            return Err(Error::config(c, "likelihood.window_scale", "must be > 0"));
        }
        if !(l.foreground_full > 0.0 && l.foreground_full <= 1.0) {
            return Err(Error::config(
                c,
                "likelihood.foreground_full",
                "must be in (0, 1]",
            ));
        }
        if l.min_window_px == 0 {
            return Err(Error::config(c, "likelihood.min_window_px", "must be ≥ 1"));
        }
        if l.reference_frames == 0 {
            return Err(Error::config(
                c,
                "likelihood.reference_frames",
                "must be ≥ 1",
            ));
        }
        for (v, f) in [
            (self.birth_spread_px, "birth_spread_px"),
            (self.birth_gate_px, "birth_gate_px"),
            (self.support_gate_px, "support_gate_px"),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::config(
                    c,
                    f,
                    format!("must be finite and ≥ 0, got {v}"),
                ));
            }
        }
        use crate::limits::{MAX_COUNT_LAG_FRAMES, MAX_PARTICLES_PER_OBJECT, at_most};
        at_most(
            self.birth_particles_per_detection,
            MAX_PARTICLES_PER_OBJECT,
            "particles per object",
        )
        .and_then(|()| {
            at_most(
                self.birth_particles_per_detection,
                self.phd.max_particles,
                "phd.max_particles",
            )
        })
        .map_err(|m| Error::config(c, "birth_particles_per_detection", m))?;
        at_most(
            self.count_lag_frames,
            MAX_COUNT_LAG_FRAMES,
            "frames of look-ahead",
        )
        .map_err(|m| Error::config(c, "count_lag_frames", m))?;
        Ok(())
    }

    /// Reads a TOML file (missing fields take the defaults) and validates it.
    ///
    /// # Errors
    /// When the file cannot be read or parsed, or a value is out of range.
    pub fn from_toml_file(path: &Path) -> Result<Self> {
        let cfg: Self = crate::config::load_toml(path)?;
        cfg.validate()?;
        Ok(cfg)
    }
}
