//! [`CenterNetConfig`]: the learned detector's decoding settings, with the box gain's terms
//! and the zoom's constants they refer to.

use serde::{Deserialize, Serialize};

use super::CLASSES;
use roadtrack::detect::nested::NestedConfig;
use roadtrack::error::{Error, Result, check_range};

/// Decoding settings of the learned detector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CenterNetConfig {
    /// Heat-map peaks below this are dropped. Default 0.4.
    pub min_score: f64,
    /// Class-wise NMS IoU. Default 0.45.
    pub iou_threshold: f64,
    /// A box overlapping a better box of another class by more than this IoU is dropped
    /// (one object seen as car and lorry). Default 0.7.
    pub cross_class_iou: f64,
    /// At most this many detections per frame. Default 300.
    pub max_detections: usize,
    /// Boxes whose longer side is below this (px) are dropped. Default 3.
    pub min_side: f64,
    /// Pyramid: also run the network on the frame shrunk this many times (area average),
    /// for objects larger than the network sees at full size (a car 150–300 px long near
    /// an oblique camera); 1 = the full-size frame only. Default 2.
    pub pyramid: u32,
    /// Pyramid: heat-map peaks of the shrunk level below this are dropped. Default 0.3.
    pub coarse_min_score: f64,
    /// Per-class lowest scores (`[class_min_score]`, `--class-min-score`): a class given
    /// here keeps its heat-map peaks from this score on, at every level, in place of
    /// [`CenterNetConfig::min_score`] and [`CenterNetConfig::coarse_min_score`]. Default:
    /// none given.
    pub class_min_score: ClassMinScore,
    /// Pyramid: a full-size detection whose longer side is at least this (px) is left to
    /// the shrunk level. Default 96.
    pub fine_max_side: f64,
    /// Pyramid: a shrunk-level detection whose longer side (in frame px) is below this is
    /// left to the full-size level. Default 48.
    pub coarse_min_side: f64,
    /// Pyramid: a full-size vehicle detection lying at least this fraction inside a larger
    /// vehicle box of the shrunk level is dropped (a part of a large vehicle). Default 0.7.
    pub part_fraction: f64,
    /// Zoom: when > 0, the network also runs on the frame enlarged
    /// [`CenterNetConfig::zoom_factor`] times (bilinear), for objects too small for it at
    /// full size (far vehicles and walkers of an oblique view), and its boxes whose longer
    /// side (in frame px) is below this are used as [`CenterNetConfig::zoom_mode`] says.
    /// `zoom_factor`² times the full-size level's compute; with a calibration
    /// ([`CenterNetDetector::with_zoom_calibration`](super::CenterNetDetector::with_zoom_calibration)) only the rows where cars are that
    /// small are enlarged. Default 0 (off).
    pub zoom_max_side: f64,
    /// Zoom: the enlargement of the zoomed level, 2–4. Default [`ZOOM`] (2).
    pub zoom_factor: u32,
    /// Zoom: how the zoomed level's boxes join the others'. Default
    /// [`ZoomMode::Level`].
    pub zoom_mode: ZoomMode,
    /// Nested boxes: a box lying mostly inside a larger box of its group (vehicles of any
    /// class, pedestrians) is dropped, after NMS, the pyramid and the zoom
    /// ([`drop_nested`](super::drop_nested)). Default 0.6 for vehicles, 0.7 for pedestrians.
    pub nested: NestedConfig,
    /// Second peaks: a vehicle box whose longer side is at least
    /// [`CenterNetConfig::second_peak_min_side`] and under this (px), whose centre lies
    /// inside a better-scored vehicle box grown [`CenterNetConfig::second_peak_grow`] times
    /// about its centre, along that box's longer side ([`CenterNetConfig::second_peak_along`]),
    /// is a second heat-map peak on that vehicle and is dropped, after the nested-box rule
    /// ([`drop_second_peaks`](super::drop_second_peaks)). 0 = off. Default 24.
    pub second_peak_max_side: f64,
    /// Second peaks: boxes whose longer side is under this (px) are never dropped. Default 8.
    pub second_peak_min_side: f64,
    /// Second peaks: how much the better box is grown for the test (≥ 1). Default 1.1.
    pub second_peak_grow: f64,
    /// Second peaks: the centres' offset along the better box's longer side must be at least
    /// this many times their offset across it (0: any direction). Default 3.
    pub second_peak_along: f64,
    /// Test-time flip: the network also runs on the frame mirrored left–right and each
    /// cell's heat, log size and offsets are the mean of the two runs (mirrored back,
    /// [`average_flipped`](super::average_flipped)). Twice the compute. Default on.
    pub flip: bool,
    /// Test-time flip upside down too: with [`CenterNetConfig::flip`] four runs (as is,
    /// mirrored, upside down, both), else two. For nadir views, where nothing has an up.
    /// Default off.
    pub flip_vertical: bool,
    /// Box gain: each output box is scaled about its centre by its class's size-dependent
    /// width and height factors from the model's `roadtrack.box_gain` metadata
    /// ([`BOX_GAIN_KEY`], [`box_factor`]; written by `roadtrack train --detector
    /// --box-gain`), after NMS and the nested-box rule, so the factors change the boxes'
    /// sizes and not which boxes are kept. A model without the key is unchanged; false: the
    /// network's sizes as they come (what `scripts/box_gain.py` measures the gain on).
    /// Default true.
    pub box_gain: bool,
}

/// How the zoomed level ([`CenterNetConfig::zoom_max_side`]) joins the other levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ZoomMode {
    /// A pyramid level of its own: under `zoom_max_side` px (in the zoomed rows) every box
    /// comes from the enlarged frame; the full-size level's boxes of that size are
    /// dropped before NMS ([`replace_small`](super::replace_small)). The network's box error is a fraction of
    /// its 4 px cell, so at twice the pixels it is half as large in frame px.
    Level,
    /// The first version: a zoomed box is added only where it overlaps no box of the
    /// other levels (after their NMS) by IoU > [`ZOOM_OVERLAP_IOU`] ([`add_zoomed`](super::add_zoomed)); the
    /// other levels' boxes are unchanged.
    Add,
}

/// Lowest score per heat-map channel ([`CenterNetConfig::class_min_score`]); a class left
/// out keeps the level's own threshold.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClassMinScore {
    /// Cars.
    pub car: Option<f64>,
    /// Lorries and buses (the bus/truck channel).
    pub lorry: Option<f64>,
    /// Motorcycles and bicycles.
    pub motorcycle: Option<f64>,
    /// Pedestrians.
    pub pedestrian: Option<f64>,
}

impl ClassMinScore {
    /// The names `--class-min-score` and the TOML table take, in channel order.
    pub const NAMES: [&'static str; CLASSES] = ["car", "lorry", "motorcycle", "pedestrian"];

    /// The given scores in channel order.
    pub fn by_channel(&self) -> [Option<f64>; CLASSES] {
        [self.car, self.lorry, self.motorcycle, self.pedestrian]
    }

    /// The threshold of each channel at a level whose own threshold is `level`.
    pub fn thresholds(&self, level: f64) -> [f64; CLASSES] {
        self.by_channel().map(|v| v.unwrap_or(level))
    }

    /// `CLASS=S[,CLASS=S…]` (`--class-min-score`): class names as [`ClassMinScore::NAMES`]
    /// (or `truck`, `bus`, `bicycle`), scores in `[0, 1]`.
    pub fn parse(text: &str) -> std::result::Result<Self, String> {
        let mut out = Self::default();
        for item in text.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            let (name, value) = item
                .split_once('=')
                .ok_or_else(|| format!("`{item}`: expected CLASS=SCORE, e.g. lorry=0.2"))?;
            let v: f64 = value
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| (0.0..=1.0).contains(v))
                .ok_or_else(|| format!("`{item}`: the score must be a number in [0, 1]"))?;
            let slot = match name.trim() {
                "car" => &mut out.car,
                "lorry" | "truck" | "bus" => &mut out.lorry,
                "motorcycle" | "bicycle" => &mut out.motorcycle,
                "pedestrian" => &mut out.pedestrian,
                other => {
                    return Err(format!(
                        "`{other}`: unknown class; one of {}",
                        Self::NAMES.join(", ")
                    ));
                }
            };
            *slot = Some(v);
        }
        Ok(out)
    }
}

/// The model metadata key of the box gain ([`CenterNetConfig::box_gain`]): sixteen
/// comma-separated numbers, `a_w, b_w, a_h, b_h` for each heat-map channel (car, bus/truck,
/// bicycle/motorcycle, pedestrian), the terms of [`box_factor`].
pub const BOX_GAIN_KEY: &str = "roadtrack.box_gain";

/// Box gain: the reference size, px, at which a class's factors are `e^a`.
pub const BOX_GAIN_REF_PX: f64 = 32.0;

/// Box gain: the range of box sizes `√(w h)`, px, over which the factors change; beyond
/// it they are those of its ends.
// Choice: 8–64 px. The held-out renders of scripts/box_gain.py have walkers from 2.5 to
// 85 px (5 345 matches, 98 % within 5–51 px); under 8 px a box is two of the network's
// cells, and over 64 px the few walkers there (median ln(w_true/w) −0.03 over 70 px tall)
// would be shrunk by the line more than they need: the line is not extrapolated.
pub const BOX_GAIN_SIZE_RANGE_PX: (f64, f64) = (8.0, 64.0);

/// The width and height factors of a box of the network's size `w × h` under the gain
/// terms `[a_w, b_w, a_h, b_h]` of its class: `e^(a + b ln(s / 32))` for each side, `s =
/// √(w h)` clamped to [`BOX_GAIN_SIZE_RANGE_PX`]. A line in log size, because the network
/// pulls sizes toward the middle of what it was trained on: small walkers come out too
/// small and large ones a little too large (docs/DETECTION.md "Box gain").
pub fn box_factor(terms: &[f64; 4], w: f64, h: f64) -> (f64, f64) {
    let (lo, hi) = BOX_GAIN_SIZE_RANGE_PX;
    let l = ((w * h).sqrt().clamp(lo, hi) / BOX_GAIN_REF_PX).ln();
    (
        (terms[0] + terms[1] * l).exp(),
        (terms[2] + terms[3] * l).exp(),
    )
}

/// Zoom: a zoomed-level box overlapping a box of the other levels by more than this IoU is
/// that object again and is not added.
// Choice: 0.3, class-agnostic: a small box on an object the other levels found is a second
// box on it whatever its class; adjacent far cars of 8–12 px overlap less.
pub const ZOOM_OVERLAP_IOU: f64 = 0.3;

/// Zoom: the default enlargement of the zoomed level ([`CenterNetConfig::zoom_factor`]).
// Choice: 2. A far car of 4–8 px becomes 8–16 px, sizes the network finds at full size
// (road oblique vehicle recall 0.34 → 0.48, docs/DETECTION.md "Zoom"); 3 costs 2.25 times
// the compute of 2 over the same rows and pays only where most objects are under 8 px
// (the oblique road with a calibration; docs/DETECTION.md "Zoom factor").
pub const ZOOM: u32 = 2;

impl Default for CenterNetConfig {
    fn default() -> Self {
        Self {
            // Choice: 0.4. With the 8 000-step model (seed 0 scenes) it trades recall for
            // precision on the oblique scenes (intersection R/P 0.65/0.58 at 0.3, 0.46/0.78
            // at 0.4), and tracking from it scores higher: intersection/oblique seed 1,
            // relaxation HOTA 0.330 → 0.366, MRF 0.331 → 0.341 (docs/EXPERIMENTS.md
            // "Learned detector").
            min_score: 0.4,
            iou_threshold: 0.45,
            cross_class_iou: 0.7,
            max_detections: 300,
            // Choice: 3 px. On the simulator's oblique scenes (seed 0) every box with a
            // longer side under 2 px was false (4 190 and 4 073 of them on the intersection
            // and the crossing, against no true one), 2–3 px nearly so; aerial pedestrians of
            // that size are not found at IoU 0.5 anyway (docs/EXPERIMENTS.md).
            min_side: 3.0,
            // Choice: one coarse level at half size, as the trainer's zoomed-out crops
            // (1.4–3.2 frame px per crop px) see objects; the size ranges overlap by a
            // factor 2 and NMS settles the overlap (SNIP's scale-specific ranges, Singh
            // & Davis 2018). Measured in docs/EXPERIMENTS.md "Learned detector".
            pyramid: 2,
            // Choice: 0.3. The shrunk level's peaks on large oblique vehicles are weaker;
            // against 0.4 (seed 0 scenes) oblique vehicle recall / precision rose on the
            // intersection 0.28 / 0.67 → 0.39 / 0.72 and the crossing 0.04 / 0.53 →
            // 0.26 / 0.60, aerial scenes unchanged; 0.2 lost precision (crossing 0.43).
            coarse_min_score: 0.3,
            // Choice: none. Lorries' and buses' peaks run lower than cars', and `lorry=0.2`
            // finds far more of them on held-out seeds 4-6, but the pipelines from video do
            // not track better on its boxes (aerial HOTA -0.005 to +0.002; docs/DETECTION.md
            // "Lowest score per class").
            class_min_score: ClassMinScore::default(),
            fine_max_side: 96.0,
            coarse_min_side: 48.0,
            part_fraction: 0.7,
            // Choice: off. It adds recall on far-field oblique views (road oblique
            // vehicles, seed 0); without a calibration it costs precision on the aerial
            // intersection and four times the compute (docs/DETECTION.md "Zoom").
            zoom_max_side: 0.0,
            zoom_factor: ZOOM,
            // Choice: a level. Replacing the full-size level's small boxes, not only adding
            // where they are missing, gives them the zoomed level's placement: best HOTA
            // from video at PX 16, seeds 1–3, add → level: oblique road 0.381 → 0.406,
            // oblique intersection 0.539 → 0.562 (docs/EXPERIMENTS.md "Zoom as a level").
            zoom_mode: ZoomMode::Level,
            nested: NestedConfig::default(),
            // Choice: 8–24 px, grown 1.1 times, along the longer side (3 : 1). A car of 12–16
            // px seen from above spans three or four of the network's 4 px cells, and its
            // heat can peak twice along it, 6–8 px apart: two boxes overlapping by IoU
            // 0.3–0.45, which NMS keeps (seed 0, aerial crossing: 293 of its 594 loose false
            // boxes). Their centres lie inside each other's boxes, offset along the car (on
            // the aerial scenes of seeds 1–3, 1 188 of 1 206 such pairs at least three times
            // further along the better box's longer side than across it; on the oblique road
            // 30 of 231); those of cars queued bumper to bumper do not. In an oblique view a
            // queued car's centre lies inside the box of the car in front, higher in the
            // image: without the 24 px limit (grown 1.2 times) the seed-0 oblique
            // intersection's vehicle recall fell 0.865 → 0.768; without the lower limit and
            // the direction the far field of the oblique road lost its small overlapping cars
            // (HOTA from video, seed 2, 0.389 → 0.356). Grown 1.1 times against 1 or 1.2: the
            // best F1 on the aerial scenes of seeds 0–2 (docs/DETECTION.md "Second peaks").
            second_peak_max_side: 24.0,
            second_peak_min_side: 8.0,
            second_peak_grow: 1.1,
            second_peak_along: 3.0,
            // Choice: on. The network's boxes scatter (centre sd 1.4–2.8 px, size sd
            // 18–31 % on aerial cars) more than they are biased, and the mean of two views
            // halves the variance of what is independent in them: vehicle R / P at IoU 0.5,
            // seed 0, road aerial 0.83 / 0.78 → 0.88 / 0.85, crossing aerial 0.86 / 0.69 →
            // 0.93 / 0.75 (docs/DETECTION.md "Test-time flip"), for half the frame rate.
            flip: true,
            flip_vertical: false,
            // Choice: on. The shipped model's small walkers' boxes are too small (median
            // ln(w_true/w) +0.13 to +0.25 under 40 px tall on held-out renders of the
            // training's random cameras), and the gain is part of the model: a model
            // without the key is not scaled (docs/DETECTION.md "Box gain").
            box_gain: true,
        }
    }
}

impl roadtrack::config::Validate for CenterNetConfig {
    fn validate(&self) -> Result<()> {
        for (field, v) in [
            ("min_score", self.min_score),
            ("iou_threshold", self.iou_threshold),
            ("cross_class_iou", self.cross_class_iou),
            ("part_fraction", self.part_fraction),
            ("coarse_min_score", self.coarse_min_score),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::config(
                    "CenterNetConfig",
                    field,
                    format!("must be in [0, 1], got {v}"),
                ));
            }
        }
        for (field, v) in [
            ("second_peak_max_side", self.second_peak_max_side),
            ("second_peak_min_side", self.second_peak_min_side),
            ("second_peak_along", self.second_peak_along),
        ] {
            check_range("CenterNetConfig", field, v, 0.0..)?;
        }
        check_range(
            "CenterNetConfig",
            "second_peak_grow",
            self.second_peak_grow,
            1.0..=4.0,
        )?;
        if !(1..=8).contains(&self.pyramid) {
            return Err(Error::config(
                "CenterNetConfig",
                "pyramid",
                format!("must be 1 (off) to 8, got {}", self.pyramid),
            ));
        }
        if !(self.zoom_max_side.is_finite() && self.zoom_max_side >= 0.0) {
            return Err(Error::config(
                "CenterNetConfig",
                "zoom_max_side",
                format!("must be ≥ 0 px (0 = off), got {}", self.zoom_max_side),
            ));
        }
        if !(2..=4).contains(&self.zoom_factor) {
            return Err(Error::config(
                "CenterNetConfig",
                "zoom_factor",
                format!("must be 2 to 4, got {}", self.zoom_factor),
            ));
        }
        if !(self.min_side.is_finite() && self.min_side >= 0.0) {
            return Err(Error::config(
                "CenterNetConfig",
                "min_side",
                format!("must be ≥ 0 px, got {}", self.min_side),
            ));
        }
        for (field, v) in [
            ("fine_max_side", self.fine_max_side),
            ("coarse_min_side", self.coarse_min_side),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::config(
                    "CenterNetConfig",
                    field,
                    format!("must be > 0 px, got {v}"),
                ));
            }
        }
        for (name, v) in ClassMinScore::NAMES
            .iter()
            .zip(self.class_min_score.by_channel())
        {
            if let Some(v) = v
                && !(0.0..=1.0).contains(&v)
            {
                return Err(Error::config(
                    "CenterNetConfig",
                    format!("class_min_score.{name}"),
                    format!("must be in [0, 1], got {v}"),
                ));
            }
        }
        self.nested.validate("CenterNetConfig.nested")?;
        if self.max_detections == 0 {
            return Err(Error::config(
                "CenterNetConfig",
                "max_detections",
                "must be at least 1",
            ));
        }
        Ok(())
    }
}
