//! [`CenterNetDetector`]: the learned detector (roadtrack's kernels or tract), as a roadtrack
//! [`Detector`] and as a dense score map for the filters' likelihood.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use image::RgbImage;
use serde::{Deserialize, Serialize};
use tract_onnx::prelude::*;

use super::native::{Isa, NativeNet};
use super::views::{
    add_zoomed, average_flipped, decode_peaks, drop_nested, drop_second_peaks, flat, flip_input,
    merge_levels, replace_small, score_map_of, shrink, zoom_rows,
};
use super::{CLASSES, INPUT_MULTIPLE, KIND, STRIDE, channel_class};
use crate::detector::decode::{Candidate, nms};
use crate::onnx::{
    metadata, model_error, preprocessing_from_metadata, read_image_model, tract_load,
};
use crate::window::Preprocessing;
use roadtrack::calibration::Calibration;
use roadtrack::class::ObjectClass;
use roadtrack::detect::FrameDetections;
use roadtrack::detect::nested::NestedConfig;
use roadtrack::detection::Detection;
use roadtrack::error::{Error, Result, check_range};
use roadtrack::frame::Frame;
use roadtrack::geometry::BBox;
use roadtrack::likelihood::{DenseScorer, ScoreMap};

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
    /// ([`CenterNetDetector::with_zoom_calibration`]) only the rows where cars are that
    /// small are enlarged. Default 0 (off).
    pub zoom_max_side: f64,
    /// Zoom: the enlargement of the zoomed level, 2–4. Default [`ZOOM`] (2).
    pub zoom_factor: u32,
    /// Zoom: how the zoomed level's boxes join the others'. Default
    /// [`ZoomMode::Level`].
    pub zoom_mode: ZoomMode,
    /// Nested boxes: a box lying mostly inside a larger box of its group (vehicles of any
    /// class, pedestrians) is dropped, after NMS, the pyramid and the zoom
    /// ([`drop_nested`]). Default 0.6 for vehicles, 0.7 for pedestrians.
    pub nested: NestedConfig,
    /// Second peaks: a vehicle box whose longer side is at least
    /// [`CenterNetConfig::second_peak_min_side`] and under this (px), whose centre lies
    /// inside a better-scored vehicle box grown [`CenterNetConfig::second_peak_grow`] times
    /// about its centre, along that box's longer side ([`CenterNetConfig::second_peak_along`]),
    /// is a second heat-map peak on that vehicle and is dropped, after the nested-box rule
    /// ([`drop_second_peaks`]). 0 = off. Default 24.
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
    /// [`average_flipped`]). Twice the compute. Default on.
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
    /// dropped before NMS ([`replace_small`]). The network's box error is a fraction of
    /// its 4 px cell, so at twice the pixels it is half as large in frame px.
    Level,
    /// The first version: a zoomed box is added only where it overlaps no box of the
    /// other levels (after their NMS) by IoU > [`ZOOM_OVERLAP_IOU`] ([`add_zoomed`]); the
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

/// The shipped model's path: `models/detector.onnx` of the current directory when it has
/// one, else of the repository roadtrack was built from. Choice: the working directory
/// first, so a clone's own model wins over the build tree's.
pub fn default_model_path() -> PathBuf {
    let local = PathBuf::from("models/detector.onnx");
    if local.is_file() {
        return local;
    }
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/detector.onnx");
    if built.is_file() { built } else { local }
}

/// The network outputs of one frame, cropped to the frame's cells.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatMaps {
    /// Cells across.
    pub cols: usize,
    /// Cells down.
    pub rows: usize,
    /// `CLASSES × rows × cols` probabilities.
    pub heat: Vec<f32>,
    /// `4 × rows × cols`: `ln(w/4)`, `ln(h/4)`, `dx`, `dy`.
    pub boxes: Vec<f32>,
}

/// The network of the model `proto` (at `path`) packed for roadtrack's kernels, when it is
/// the graph `roadtrack train --detector` writes ([`super::onnx_model`]); `None` otherwise.
// Choice: only a graph equal node for node to the one roadtrack writes runs in the native
// kernels, so a model edited by hand still runs as it is written, whole in tract.
fn native_of(proto: &tract_onnx::pb::ModelProto, path: &Path) -> Option<NativeNet> {
    let net = super::weights_of(proto, path).ok()?;
    let ours = super::onnx_model(&net).ok()?;
    if ours.graph.as_ref()?.node != proto.graph.as_ref()?.node {
        return None;
    }
    NativeNet::new(&net)
}

/// The zoomed level's rows (frame px, `[top, bottom)`) and boxes (frame px, best first).
type ZoomLevel = ((f64, f64), Vec<Candidate>);

/// The learned centre-point detector (module docs of [`super`]).
pub struct CenterNetDetector {
    path: PathBuf,
    proto: tract_onnx::pb::ModelProto,
    prep: Preprocessing,
    config: CenterNetConfig,
    plans: Mutex<HashMap<(usize, usize), Arc<TypedRunnableModel>>>,
    /// The network in roadtrack's kernels (`None`: in tract).
    native: Option<NativeNet>,
    /// With the zoom: the camera, to enlarge only the rows where objects are small.
    zoom_calibration: Option<Calibration>,
    /// The box gain's terms per heat-map channel (the model's [`BOX_GAIN_KEY`], all 0 —
    /// factors of 1 — without it or with [`CenterNetConfig::box_gain`] off).
    gain: [[f64; 4]; CLASSES],
}

impl std::fmt::Debug for CenterNetDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CenterNetDetector")
            .field("path", &self.path)
            .field("prep", &self.prep)
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

impl CenterNetDetector {
    /// Loads a model written by `roadtrack train --detector`.
    ///
    /// # Errors
    /// [`Error::Io`] when unreadable; [`Error::Format`] naming the file when it is not
    /// ONNX, not such a detector (no `roadtrack.kind = centernet` metadata, or outputs other
    /// than `heatmap` 4 × and `boxes` 4 × at stride 4), or tract cannot run it.
    pub fn load(path: &Path, config: &CenterNetConfig) -> Result<Self> {
        roadtrack::config::Validate::validate(config)?;
        let (proto, _dims) = read_image_model(path)?;
        if metadata(&proto, "roadtrack.kind") != Some(KIND) {
            return Err(model_error(
                path,
                "not a roadtrack learned detector (no `roadtrack.kind = centernet` metadata; \
                 write one with `roadtrack train --detector`, or use --detector onnx for \
                 other detectors)",
            ));
        }
        let prep = preprocessing_from_metadata(&proto);
        prep.validate()?;
        let model_gain = super::box_gain_of(&proto, path)?;
        let gain = if config.box_gain {
            model_gain
        } else {
            [[0.0; 4]; CLASSES]
        };
        let native = native_of(&proto, path);
        let det = Self {
            path: path.to_path_buf(),
            proto,
            prep,
            config: config.clone(),
            plans: Mutex::new(HashMap::new()),
            native,
            zoom_calibration: None,
            gain,
        };
        // Fail now on a model tract cannot run or with other outputs.
        let probe = INPUT_MULTIPLE * 2;
        let out = det.run_padded(vec![0.0; 3 * probe * probe], probe, probe)?;
        let want = probe / STRIDE;
        if out.0.shape() != [1, CLASSES, want, want] || out.1.shape() != [1, 4, want, want] {
            return Err(model_error(
                path,
                format!(
                    "not a roadtrack learned detector: outputs {:?} and {:?} on a {probe} × \
                     {probe} input, expected [1, {CLASSES}, {want}, {want}] and [1, 4, {want}, {want}]",
                    out.0.shape(),
                    out.1.shape()
                ),
            ));
        }
        Ok(det)
    }

    /// The same detector with the network run by tract (for comparisons: `roadtrack bench`
    /// and the tests).
    #[must_use]
    pub fn whole_in_tract(mut self) -> Self {
        self.native = None;
        self.plans = Mutex::new(HashMap::new());
        self
    }

    /// Whether the network runs in roadtrack's kernels ([`NativeNet`]); `false`: in tract.
    pub fn is_native(&self) -> bool {
        self.native.is_some()
    }

    /// The model file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The input preprocessing (from the model's metadata).
    pub fn preprocessing(&self) -> &Preprocessing {
        &self.prep
    }

    /// The decoding settings.
    pub fn config(&self) -> &CenterNetConfig {
        &self.config
    }

    /// The box gain's terms `[a_w, b_w, a_h, b_h]` applied per heat-map channel
    /// ([`CenterNetConfig::box_gain`], [`box_factor`]).
    pub fn box_gain(&self) -> [[f64; 4]; CLASSES] {
        self.gain
    }

    fn run_error(&self, e: impl std::fmt::Display) -> Error {
        Error::Invalid(format!("{}: running the model: {e:#}", self.path.display()))
    }

    fn plan(&self, h: usize, w: usize) -> Result<Arc<TypedRunnableModel>> {
        let mut plans = self
            .plans
            .lock()
            .map_err(|_| Error::Invalid("detector plan cache poisoned".into()))?;
        if let Some(p) = plans.get(&(h, w)) {
            return Ok(Arc::clone(p));
        }
        let loaded = tract_load(&self.proto, [1, 3, h, w]);
        let plan =
            loaded.map_err(|e| model_error(&self.path, format!("tract cannot load it: {e:#}")))?;
        plans.insert((h, w), Arc::clone(&plan));
        Ok(plan)
    }

    /// One of the native network's outputs (`c` channels on an `h × w` input) as tract's
    /// `1 × c × h/4 × w/4` array.
    fn array(
        &self,
        c: usize,
        h: usize,
        w: usize,
        v: Vec<f32>,
    ) -> Result<tract_ndarray::ArrayD<f32>> {
        tract_ndarray::ArrayD::from_shape_vec(
            tract_ndarray::IxDyn(&[1, c, h / STRIDE, w / STRIDE]),
            v,
        )
        .map_err(|e| model_error(&self.path, format!("native output: {e}")))
    }

    /// The preprocessed `image` padded to `ph × pw` (as [`CenterNetDetector::input`]),
    /// mirrored left–right (`flip.0`) and/or upside down (`flip.1`) as [`flip_input`] mirrors
    /// it, into the interior of the channels-last `(ph + 2) × (pw + 2) × 3` buffer `out`;
    /// every interior value is written (padding 0).
    fn fill_channels_last(
        &self,
        image: &RgbImage,
        (ph, pw): (usize, usize),
        (fx, fy): (bool, bool),
        out: &mut [f32],
    ) {
        let (w, h) = (image.width() as usize, image.height() as usize);
        let p = &self.prep;
        let gain: [f32; 3] = std::array::from_fn(|c| p.input_scale / p.std[c]);
        let offset: [f32; 3] = std::array::from_fn(|c| -p.mean[c] / p.std[c]);
        let raw = image.as_raw();
        for r in 0..ph {
            let dst = &mut out[((r + 1) * (pw + 2) + 1) * 3..][..pw * 3];
            let y = if fy { ph - 1 - r } else { r };
            if y >= h {
                dst.fill(0.0);
                continue;
            }
            let src = raw[y * w * 3..][..w * 3].chunks_exact(3);
            let put = |d: &mut [f32], s: &[u8]| {
                for k in 0..3 {
                    d[k] = gain[k] * f32::from(s[k]) + offset[k];
                }
            };
            // The image's columns land at 0..w, or mirrored at pw − w..pw; the rest is padding.
            if fx {
                let (pad, img) = dst.split_at_mut((pw - w) * 3);
                pad.fill(0.0);
                img.chunks_exact_mut(3)
                    .zip(src.rev())
                    .for_each(|(d, s)| put(d, s));
            } else {
                let (img, pad) = dst.split_at_mut(w * 3);
                pad.fill(0.0);
                img.chunks_exact_mut(3)
                    .zip(src)
                    .for_each(|(d, s)| put(d, s));
            }
        }
    }

    /// Runs the network on a preprocessed `3 × h × w` input (`h`, `w` multiples of 16).
    fn run_padded(
        &self,
        input: Vec<f32>,
        h: usize,
        w: usize,
    ) -> Result<(tract_ndarray::ArrayD<f32>, tract_ndarray::ArrayD<f32>)> {
        if let Some(native) = &self.native {
            let (heat, boxes) = native.run(&input, h, w, Isa::best());
            return Ok((
                self.array(CLASSES, h, w, heat)?,
                self.array(4, h, w, boxes)?,
            ));
        }
        let plan = self.plan(h, w)?;
        let t = Tensor::from_shape(&[1, 3, h, w], &input).map_err(|e| self.run_error(e))?;
        let out = plan.run(tvec![t.into()]).map_err(|e| self.run_error(e))?;
        if out.len() != 2 {
            return Err(model_error(
                &self.path,
                format!("expected 2 outputs (heatmap, boxes), found {}", out.len()),
            ));
        }
        let get = |i: usize| -> Result<tract_ndarray::ArrayD<f32>> {
            let v = out[i].cast_to::<f32>().map_err(|e| self.run_error(e))?;
            let view = v
                .to_plain_array_view::<f32>()
                .map_err(|e| self.run_error(e))?;
            Ok(view.to_owned())
        };
        Ok((get(0)?, get(1)?))
    }

    /// The raw outputs `(heatmap, boxes)`, row-major `1 × 4 × h/4 × w/4` each, of a
    /// preprocessed `3 × h × w` input (`h`, `w` multiples of 16).
    ///
    /// # Errors
    /// Sides that are not multiples of 16; the model fails to run.
    pub fn forward(&self, input: Vec<f32>, h: usize, w: usize) -> Result<(Vec<f32>, Vec<f32>)> {
        if !h.is_multiple_of(INPUT_MULTIPLE)
            || !w.is_multiple_of(INPUT_MULTIPLE)
            || h == 0
            || w == 0
        {
            return Err(Error::Invalid(format!(
                "detector input {h} × {w}: sides must be positive multiples of {INPUT_MULTIPLE}"
            )));
        }
        let (a, b) = self.run_padded(input, h, w)?;
        Ok((flat(&a).into_owned(), flat(&b).into_owned()))
    }

    /// The preprocessed, padded input of `image`: `(values, padded h, padded w)`. Padding
    /// (right and bottom, to multiples of 16) is 0 after preprocessing, i.e. the mean colour.
    pub fn input(&self, image: &RgbImage) -> (Vec<f32>, usize, usize) {
        let (w, h) = (image.width() as usize, image.height() as usize);
        let ph = h.div_ceil(INPUT_MULTIPLE).max(1) * INPUT_MULTIPLE;
        let pw = w.div_ceil(INPUT_MULTIPLE).max(1) * INPUT_MULTIPLE;
        let mut out = vec![0.0f32; 3 * ph * pw];
        let p = &self.prep;
        let gain: [f32; 3] = std::array::from_fn(|c| p.input_scale / p.std[c]);
        let offset: [f32; 3] = std::array::from_fn(|c| -p.mean[c] / p.std[c]);
        for (y, row) in image.rows().enumerate() {
            for (x, px) in row.enumerate() {
                for c in 0..3 {
                    out[c * ph * pw + y * pw + x] = gain[c] * f32::from(px.0[c]) + offset[c];
                }
            }
        }
        (out, ph, pw)
    }

    /// The network's heat maps and box maps of `image`, cropped to the frame's cells.
    ///
    /// # Errors
    /// The model fails to run.
    pub fn heat_maps(&self, image: &RgbImage) -> Result<HeatMaps> {
        let (w, h) = (image.width() as usize, image.height() as usize);
        let ph = h.div_ceil(INPUT_MULTIPLE).max(1) * INPUT_MULTIPLE;
        let pw = w.div_ceil(INPUT_MULTIPLE).max(1) * INPUT_MULTIPLE;
        let mut flips = Vec::new();
        if self.config.flip {
            flips.push((true, false));
        }
        if self.config.flip_vertical {
            flips.push((false, true));
            if self.config.flip {
                flips.push((true, true));
            }
        }
        // The network's outputs on the frame as it is, then on each mirrored view.
        let mut outs = Vec::with_capacity(flips.len() + 1);
        if let Some(native) = &self.native {
            // The native network reads its channels-last input straight from the image,
            // mirrored as each view asks: no planar copy, no mirrored copy.
            for (x, y) in std::iter::once((false, false)).chain(flips.iter().copied()) {
                let (heat, boxes) = native.run_filled(ph, pw, Isa::best(), &mut |buf| {
                    self.fill_channels_last(image, (ph, pw), (x, y), buf);
                });
                outs.push((
                    self.array(CLASSES, ph, pw, heat)?,
                    self.array(4, ph, pw, boxes)?,
                ));
            }
        } else {
            let (input, _, _) = self.input(image);
            let flipped: Vec<Vec<f32>> = flips
                .iter()
                .map(|&(x, y)| flip_input(&input, ph, pw, x, y))
                .collect();
            outs.push(self.run_padded(input, ph, pw)?);
            for m in flipped {
                outs.push(self.run_padded(m, ph, pw)?);
            }
        }
        let mut outs = outs.into_iter();
        let (mut heat, mut boxes) = outs
            .next()
            .ok_or_else(|| Error::Invalid("the detector ran no pass".into()))?;
        let (oh, ow) = (ph / STRIDE, pw / STRIDE);
        if !flips.is_empty() {
            let mut views = Vec::with_capacity(flips.len());
            for ((mh, mb), &(x, y)) in outs.zip(&flips) {
                if heat.shape() != mh.shape()
                    || boxes.shape() != mb.shape()
                    || boxes.shape() != [1, 4, oh, ow]
                {
                    return Err(model_error(
                        &self.path,
                        format!(
                            "output shape {:?}, expected [1, 4, {oh}, {ow}]",
                            boxes.shape()
                        ),
                    ));
                }
                views.push((mh, mb, x, y));
            }
            average_flipped(&mut heat, &mut boxes, &views);
        }
        let cols = (image.width() as usize).div_ceil(STRIDE).max(1);
        let rows = (image.height() as usize).div_ceil(STRIDE).max(1);
        let crop = |a: &tract_ndarray::ArrayD<f32>, ch: usize| -> Result<Vec<f32>> {
            if a.shape() != [1, ch, oh, ow] {
                return Err(model_error(
                    &self.path,
                    format!(
                        "output shape {:?}, expected [1, {ch}, {oh}, {ow}]",
                        a.shape()
                    ),
                ));
            }
            let flat = flat(a);
            let mut out = Vec::with_capacity(ch * rows * cols);
            for c in 0..ch {
                for r in 0..rows {
                    out.extend_from_slice(&flat[c * oh * ow + r * ow..][..cols]);
                }
            }
            Ok(out)
        };
        Ok(HeatMaps {
            cols,
            rows,
            heat: crop(&heat, CLASSES)?,
            boxes: crop(&boxes, 4)?,
        })
    }

    /// The objects in `image`, best first: `(box in image px, class, score)`.
    ///
    /// # Errors
    /// The model fails to run.
    pub fn detect_boxes(&self, image: &RgbImage) -> Result<Vec<(BBox, ObjectClass, f64)>> {
        let min_side = self.config.min_side;
        let mut cands = self.pyramid_candidates(image)?;
        let mut zoomed = if self.config.zoom_max_side > 0.0 {
            self.zoom_level(image)?
        } else {
            None
        };
        if self.config.zoom_mode == ZoomMode::Level
            && let Some((rows, boxes)) = zoomed.take()
        {
            replace_small(&mut cands, boxes, rows, self.config.zoom_max_side);
        }
        cands.retain(|c| c.w.max(c.h) >= min_side);
        let kept = nms(cands, self.config.iou_threshold, usize::MAX);
        // Cross-class suppression: `kept` is sorted by score.
        let mut out: Vec<Candidate> = Vec::new();
        for c in kept {
            if out.len() >= self.config.max_detections {
                break;
            }
            if out
                .iter()
                .all(|k| k.class == c.class || k.iou(&c) <= self.config.cross_class_iou)
            {
                out.push(c);
            }
        }
        if let Some((_, boxes)) = zoomed {
            add_zoomed(&mut out, boxes, &self.config);
        }
        let out = drop_second_peaks(drop_nested(out, &self.config), &self.config);
        let (w, h) = (f64::from(image.width()), f64::from(image.height()));
        Ok(out
            .into_iter()
            .filter_map(|mut c| {
                let (gw, gh) =
                    box_factor(&self.gain[c.class], c.w * c.gain_scale, c.h * c.gain_scale);
                c.w *= gw;
                c.h *= gh;
                let x0 = (c.cx - c.w / 2.0).clamp(0.0, w);
                let y0 = (c.cy - c.h / 2.0).clamp(0.0, h);
                let x1 = (c.cx + c.w / 2.0).clamp(0.0, w);
                let y1 = (c.cy + c.h / 2.0).clamp(0.0, h);
                (x1 > x0 && y1 > y0).then(|| {
                    (
                        BBox::new(x0, y0, x1 - x0, y1 - y0),
                        channel_class(c.class),
                        c.score,
                    )
                })
            })
            .collect())
    }

    /// Heat-map peaks of the full-size frame and, with [`CenterNetConfig::pyramid`] `k > 1`,
    /// of the frame shrunk `k` times, each level keeping the sizes it is made for; a
    /// full-size vehicle box lying mostly inside a larger coarse vehicle box is dropped.
    fn pyramid_candidates(&self, image: &RgbImage) -> Result<Vec<Candidate>> {
        let cfg = &self.config;
        let fine = decode_peaks(
            &self.heat_maps(image)?,
            &cfg.class_min_score.thresholds(cfg.min_score),
        );
        let k = cfg.pyramid;
        if k <= 1
            || image.width() < k * INPUT_MULTIPLE as u32
            || image.height() < k * INPUT_MULTIPLE as u32
        {
            return Ok(fine);
        }
        let small = shrink(image, k);
        let coarse = decode_peaks(
            &self.heat_maps(&small)?,
            &cfg.class_min_score.thresholds(cfg.coarse_min_score),
        );
        Ok(merge_levels(fine, coarse, k, cfg))
    }

    /// With the zoom ([`CenterNetConfig::zoom_max_side`]): enlarge only the rows where a
    /// car measures under `zoom_max_side` px through `calibration` ([`zoom_rows`]), and
    /// none when there are no such rows (an aerial view of cars larger than that).
    #[must_use]
    pub fn with_zoom_calibration(mut self, calibration: Calibration) -> Self {
        self.zoom_calibration = Some(calibration);
        self
    }

    /// The zoomed level: the rows it covers (frame px, `[top, bottom)`) and the heat-map
    /// peaks of the frame (or, with a calibration, of its [`zoom_rows`] with a margin of
    /// `zoom_max_side` rows) enlarged [`CenterNetConfig::zoom_factor`] times (bilinear),
    /// in frame px, from [`CenterNetConfig::min_side`] up to below
    /// [`CenterNetConfig::zoom_max_side`], centres inside the rows, class-wise NMS at
    /// [`CenterNetConfig::iou_threshold`]; best first. `None` where no row is enlarged.
    fn zoom_level(&self, image: &RgbImage) -> Result<Option<ZoomLevel>> {
        let cfg = &self.config;
        let (w, h) = image.dimensions();
        let rows = match &self.zoom_calibration {
            Some(cal) => match zoom_rows(cal, w, h, cfg.zoom_max_side) {
                Some(r) => r,
                None => return Ok(None),
            },
            None => (0, h),
        };
        let margin = cfg.zoom_max_side.ceil() as u32;
        let top = rows.0.saturating_sub(margin);
        let bottom = (rows.1 + margin).min(h);
        if bottom <= top || w == 0 {
            return Ok(None);
        }
        let band = image::imageops::crop_imm(image, 0, top, w, bottom - top).to_image();
        let zoom = cfg.zoom_factor;
        let big = image::imageops::resize(
            &band,
            w * zoom,
            (bottom - top) * zoom,
            image::imageops::FilterType::Triangle,
        );
        let z = f64::from(zoom);
        let (y0, y1) = (f64::from(rows.0), f64::from(rows.1));
        let floor = cfg.class_min_score.thresholds(cfg.min_score);
        let cands: Vec<Candidate> = decode_peaks(&self.heat_maps(&big)?, &floor)
            .into_iter()
            .map(|c| Candidate {
                cx: c.cx / z,
                cy: c.cy / z + f64::from(top),
                w: c.w / z,
                h: c.h / z,
                gain_scale: z,
                ..c
            })
            .filter(|c| {
                let side = c.w.max(c.h);
                side >= cfg.min_side && side < cfg.zoom_max_side && c.cy >= y0 && c.cy < y1
            })
            .collect();
        Ok(Some(((y0, y1), nms(cands, cfg.iou_threshold, usize::MAX))))
    }

    /// The heat map of `channels` (their maximum per cell) as a score map: cell `(r, c)`
    /// centred at image px `(4c + 2, 4r + 2)`.
    ///
    /// # Errors
    /// The model fails to run.
    pub fn score_map(&self, image: &RgbImage, channels: &[usize]) -> Result<ScoreMap> {
        let maps = self.heat_maps(image)?;
        Ok(score_map_of(&maps, channels))
    }
}

impl CenterNetDetector {
    /// [`Detector::detect`] on `&self`: the result depends on `frame` alone.
    fn frame_detections(&self, frame: &Frame) -> Result<FrameDetections> {
        let boxes = self.detect_boxes(&frame.image)?;
        let detections = boxes
            .into_iter()
            .enumerate()
            .map(|(i, (bbox, class, score))| Detection {
                frame: frame.index,
                id: i as u64 + 1,
                pos_px: bbox.centre(),
                size_px: Some((bbox.width, bbox.height)),
                colour_rgb: roadtrack::detect::file::mean_colour(&frame.image, &bbox),
                class: Some(class),
                score: Some(score),
                area_px: None,
            })
            .collect();
        Ok(FrameDetections {
            detections,
            foreground: None,
        })
    }
}

crate::stateless_detector!(CenterNetDetector);

/// The detector's heat map as the filters' dense likelihood (seed 004's score map): the
/// channels of the filter's target class.
#[derive(Debug, Clone)]
pub struct CenterNetDense {
    /// The detector.
    pub detector: Arc<CenterNetDetector>,
    /// Heat-map channels whose maximum is the score.
    pub channels: Vec<usize>,
}

impl DenseScorer for CenterNetDense {
    fn score_map(&self, image: &RgbImage) -> Result<ScoreMap> {
        self.detector.score_map(image, &self.channels)
    }
}
