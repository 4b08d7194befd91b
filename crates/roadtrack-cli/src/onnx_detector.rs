//! `--detector onnx`: any ONNX object detector (roadtrack-cnn's `OnnxDetector`; without the
//! `cnn` feature a clear error).

use anyhow::Result;
use std::path::{Path, PathBuf};

/// The output layouts of `--layout` (roadtrack-cnn's `Layout`; here so that the flag
/// parses without the `cnn` feature).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LayoutArg {
    /// Tell from the output shapes.
    Auto,
    /// One output [1, N, 4+C]: cx, cy, w, h (input px), C class scores.
    Yolo,
    /// One output [1, 4+C, N] (ultralytics' export).
    YoloT,
    /// One output [1, N, 5+C]: cx, cy, w, h, objectness, C class scores.
    Yolox,
    /// Two outputs: boxes [1, Q, 4] (normalised cx, cy, w, h) + logits [1, Q, C].
    Detr,
}

/// How the frame is fitted into the model input (`--resize`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ResizeArg {
    /// Keep the aspect, pad with grey 114, centred (ultralytics).
    Letterbox,
    /// Keep the aspect, pad right and bottom (YOLOX).
    LetterboxTopLeft,
    /// Scale each axis to fill the input.
    Stretch,
}

/// How DETR logits become scores (`--detr-scores`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DetrScoresArg {
    /// Independent sigmoid per class (RT-DETR, D-FINE).
    Sigmoid,
    /// Softmax with a last "no object" column (DETR).
    Softmax,
}

/// How the learned detector's zoomed level joins the others (`--zoom-mode`;
/// roadtrack-cnn's `ZoomMode`, here so that the flag parses without the `cnn` feature).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ZoomModeArg {
    /// Boxes under PX come from the enlarged frame only (a pyramid level of their own).
    Level,
    /// Enlarged-frame boxes are added only where the other levels have none.
    Add,
}

/// The flags of `--detector onnx` (docs/DETECTION.md "ONNX detectors").
#[derive(Debug, Clone, Default, clap::Args)]
pub struct OnnxArgs {
    /// --detector onnx: the detector model (ONNX). `detect` also takes it as --model, and
    /// `track` too when --likelihood is colour.
    #[arg(long, value_name = "F.onnx")]
    pub detector_model: Option<PathBuf>,
    /// --detector onnx: settings TOML (`OnnxDetectorConfig`); the flags below override it.
    #[arg(long, value_name = "F.toml")]
    pub onnx_config: Option<PathBuf>,
    /// --detector onnx: output layout [default: auto].
    #[arg(long, value_enum, value_name = "L")]
    pub layout: Option<LayoutArg>,
    /// --detector onnx|cnn: lowest score kept [default: 0.25; --detector cnn 0.4].
    #[arg(long, value_name = "S", value_parser = crate::flags::probability)]
    pub min_score: Option<f64>,
    /// --detector onnx|cnn: class-wise NMS IoU threshold [default: 0.45].
    #[arg(long, value_name = "IOU", value_parser = crate::flags::probability)]
    pub iou_threshold: Option<f64>,
    /// --detector onnx: model input HxW, e.g. 640x640 [default: the model's, else 640x640].
    #[arg(long, value_name = "HxW", value_parser = input_size)]
    pub input_size: Option<[u32; 2]>,
    /// --detector onnx: pixel multiplier, 0.00392156862745098 (1/255, inputs 0..1) or 1
    /// (0..255, YOLOX) [default: 1/255].
    #[arg(long, value_name = "S", value_parser = crate::flags::positive_f32)]
    pub input_scale: Option<f32>,
    /// --detector onnx: feed B, G, R planes (YOLOX) instead of R, G, B.
    #[arg(long)]
    pub bgr: bool,
    /// --detector onnx: how the frame is fitted in [default: letterbox].
    #[arg(long, value_enum, value_name = "R")]
    pub resize: Option<ResizeArg>,
    /// --detector onnx: DETR logits [default: sigmoid].
    #[arg(long, value_enum, value_name = "F")]
    pub detr_scores: Option<DetrScoresArg>,
    /// --detector onnx: model class index → roadtrack class, e.g. 0=pedestrian,2=car
    /// (only these kept) [default: the 80 COCO classes, person → pedestrian, bicycle, car,
    /// motorcycle, bus, truck kept].
    #[arg(long, value_name = "MAP")]
    pub classes: Option<String>,
    /// --detector cnn: also run the network on the frame shrunk K times, for objects too
    /// large for it at full size (cars near an oblique camera); 1 = full size only
    /// [default: 2].
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..=8))]
    pub pyramid: Option<u32>,
    /// --detector cnn: lowest score kept on the shrunk pyramid level [default: 0.3].
    #[arg(long, value_name = "S", value_parser = crate::flags::probability)]
    pub coarse_min_score: Option<f64>,
    /// --detector cnn: lowest score per class, at every level, in place of --min-score and
    /// --coarse-min-score, e.g. lorry=0.2 (classes car, lorry, motorcycle, pedestrian)
    /// [default: none].
    #[cfg(feature = "cnn")]
    #[arg(long, value_name = "CLASS=S,…", value_parser = roadtrack_cnn::centernet::ClassMinScore::parse)]
    pub class_min_score: Option<roadtrack_cnn::centernet::ClassMinScore>,
    /// --detector cnn: also run the network on the frame enlarged twice (--zoom-factor) and
    /// take its boxes smaller than PX (frame px) as --zoom-mode says, for far objects and
    /// walkers side by side (4× the compute); with --calibration only the rows where a car
    /// is under PX px [default: off].
    #[arg(long, value_name = "PX", value_parser = crate::flags::positive)]
    pub zoom_small: Option<f64>,
    /// --detector cnn --zoom-small: the enlargement, 2–4 (K² times the full-size compute
    /// over the enlarged rows); 3 for an oblique road whose far cars are under 8 px
    /// [default: 2].
    #[arg(long, value_name = "K", requires = "zoom_small",
          value_parser = clap::value_parser!(u32).range(2..=4))]
    pub zoom_factor: Option<u32>,
    /// --detector cnn --zoom-small: `level`, every box under PX comes from the enlarged
    /// frame; `add`, its boxes are added only where the other levels have none
    /// [default: level].
    #[arg(long, value_name = "MODE", requires = "zoom_small")]
    pub zoom_mode: Option<ZoomModeArg>,
    /// --detector cnn: keep a box lying mostly inside a larger box of its group (vehicles,
    /// pedestrians); by default it is dropped as a part of that object.
    #[arg(long)]
    pub keep_nested: bool,
    /// --detector cnn: keep a second box on a small vehicle (8–24 px, its centre inside the
    /// better box, along it); by default it is dropped as a second peak of that vehicle.
    #[arg(long)]
    pub keep_second_peaks: bool,
    /// --detector cnn: run the network on the frame only, not also on its mirror image
    /// (by default the two are averaged: better boxes for twice the compute).
    #[arg(long)]
    pub no_flip: bool,
    /// --detector cnn: also average the frame upside down (and, unless --no-flip, mirrored
    /// and upside down): for nadir (aerial) views; twice the compute again.
    #[arg(long)]
    pub flip_vertical: bool,
    /// --detector cnn: leave the boxes at the network's sizes, without the model's box gain
    /// (per-class size factors in its metadata, docs/DETECTION.md "Box gain").
    #[arg(long)]
    pub no_box_gain: bool,
}

/// `HxW` or `S` (square) → `[h, w]`.
fn input_size(s: &str) -> Result<[u32; 2], String> {
    let parse = |t: &str| {
        t.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| (1..=8192).contains(v))
            .ok_or_else(|| format!("`{s}`: expected HxW in px (1–8192), e.g. 640x640"))
    };
    match s.split_once(['x', 'X']) {
        Some((h, w)) => Ok([parse(h)?, parse(w)?]),
        None => {
            let v = parse(s)?;
            Ok([v, v])
        }
    }
}

impl OnnxArgs {
    /// The given flags by name (for "only with --detector onnx" errors).
    pub fn given(&self) -> Vec<(&'static str, bool)> {
        let mut given = vec![
            ("--onnx-config", self.onnx_config.is_some()),
            ("--layout", self.layout.is_some()),
            ("--min-score", self.min_score.is_some()),
            ("--iou-threshold", self.iou_threshold.is_some()),
            ("--input-size", self.input_size.is_some()),
            ("--input-scale", self.input_scale.is_some()),
            ("--bgr", self.bgr),
            ("--resize", self.resize.is_some()),
            ("--detr-scores", self.detr_scores.is_some()),
            ("--classes", self.classes.is_some()),
        ];
        given.extend(self.cnn_only());
        given
    }

    /// The flags only `--detector cnn` takes, by name, and whether each was given.
    fn cnn_only(&self) -> Vec<(&'static str, bool)> {
        let mut flags = vec![
            ("--pyramid", self.pyramid.is_some()),
            ("--coarse-min-score", self.coarse_min_score.is_some()),
            ("--zoom-small", self.zoom_small.is_some()),
            ("--zoom-mode", self.zoom_mode.is_some()),
            ("--zoom-factor", self.zoom_factor.is_some()),
        ];
        #[cfg(feature = "cnn")]
        flags.push(("--class-min-score", self.class_min_score.is_some()));
        flags.extend(self.cnn_switches());
        flags
    }

    /// The learned detector's on/off flags, by name, and whether each was given.
    fn cnn_switches(&self) -> [(&'static str, bool); 5] {
        [
            ("--keep-nested", self.keep_nested),
            ("--keep-second-peaks", self.keep_second_peaks),
            ("--no-flip", self.no_flip),
            ("--flip-vertical", self.flip_vertical),
            ("--no-box-gain", self.no_box_gain),
        ]
    }

    /// The learned detector's flags as given, for a report: ` --no-flip --zoom-small 16`, …
    pub fn cnn_flags(&self) -> String {
        let valued = [
            ("--min-score", self.min_score),
            ("--iou-threshold", self.iou_threshold),
            ("--pyramid", self.pyramid.map(f64::from)),
            ("--coarse-min-score", self.coarse_min_score),
            ("--zoom-small", self.zoom_small),
            ("--zoom-factor", self.zoom_factor.map(f64::from)),
        ];
        let mut out = String::new();
        for (flag, v) in valued {
            if let Some(v) = v {
                out.push_str(&format!(" {flag} {v}"));
            }
        }
        if let Some(mode) = self.zoom_mode {
            out.push_str(match mode {
                ZoomModeArg::Level => " --zoom-mode level",
                ZoomModeArg::Add => " --zoom-mode add",
            });
        }
        #[cfg(feature = "cnn")]
        if let Some(c) = &self.class_min_score {
            let given: Vec<String> = roadtrack_cnn::centernet::ClassMinScore::NAMES
                .iter()
                .zip(c.by_channel())
                .filter_map(|(name, v)| v.map(|v| format!("{name}={v}")))
                .collect();
            out.push_str(&format!(" --class-min-score {}", given.join(",")));
        }
        for (flag, on) in self.cnn_switches() {
            if on {
                out.push(' ');
                out.push_str(flag);
            }
        }
        out
    }

    /// The given flags that `--detector cnn` does not take (it takes --min-score and
    /// --iou-threshold).
    pub fn given_not_cnn(&self) -> Vec<(&'static str, bool)> {
        let cnn = self.cnn_only();
        self.given()
            .into_iter()
            .filter(|(f, _)| {
                !matches!(*f, "--min-score" | "--iou-threshold") && !cnn.iter().any(|(c, _)| c == f)
            })
            .collect()
    }

    /// The learned detector, loaded (`--detector cnn`): --detector-model (or --model),
    /// else the shipped models/detector.onnx. `nested_in_detector`: false when a motion gate
    /// drops the nested boxes after gating instead ([`OnnxArgs::gate_nested`]).
    #[cfg(feature = "cnn")]
    pub fn cnn_spec(
        &self,
        calibration: Option<&roadtrack::calibration::Calibration>,
        nested_in_detector: bool,
    ) -> Result<roadtrack::detect::DetectorSpec> {
        use roadtrack_cnn::centernet::{CenterNetConfig, CenterNetDetector, default_model_path};
        let path = self
            .detector_model
            .clone()
            .unwrap_or_else(default_model_path);
        if !path.exists() {
            anyhow::bail!(
                "--detector cnn: no model at {}; give --model F.onnx or train one with \
                 `roadtrack train --detector -o {}` (scripts/setup.sh --models)",
                path.display(),
                path.display()
            );
        }
        let mut config = CenterNetConfig::default();
        if let Some(s) = self.min_score {
            config.min_score = s;
        }
        if let Some(s) = self.iou_threshold {
            config.iou_threshold = s;
        }
        if let Some(k) = self.pyramid {
            config.pyramid = k;
        }
        if let Some(s) = self.coarse_min_score {
            config.coarse_min_score = s;
        }
        if let Some(c) = self.class_min_score {
            config.class_min_score = c;
        }
        if let Some(px) = self.zoom_small {
            config.zoom_max_side = px;
        }
        if let Some(k) = self.zoom_factor {
            config.zoom_factor = k;
        }
        if let Some(mode) = self.zoom_mode {
            config.zoom_mode = match mode {
                ZoomModeArg::Level => roadtrack_cnn::centernet::ZoomMode::Level,
                ZoomModeArg::Add => roadtrack_cnn::centernet::ZoomMode::Add,
            };
        }
        config.flip = !self.no_flip;
        config.flip_vertical = self.flip_vertical;
        config.box_gain = !self.no_box_gain;
        if self.keep_second_peaks {
            config.second_peak_max_side = 0.0;
        }
        if self.keep_nested || !nested_in_detector {
            config.nested = roadtrack::detect::nested::NestedConfig::OFF;
        }
        let mut detector = CenterNetDetector::load(&path, &config)?;
        if let (Some(px), Some(c)) = (self.zoom_small, calibration) {
            warn_if_zoom_top_down(px, c);
            detector = detector.with_zoom_calibration(c.clone());
        }
        Ok(roadtrack::detect::DetectorSpec::Given(Box::new(detector)))
    }

    /// Without the `cnn` feature there is no ONNX runtime.
    #[cfg(not(feature = "cnn"))]
    pub fn cnn_spec(
        &self,
        _calibration: Option<&roadtrack::calibration::Calibration>,
        _nested_in_detector: bool,
    ) -> Result<roadtrack::detect::DetectorSpec> {
        anyhow::bail!(
            "--detector cnn needs roadtrack built with the `cnn` feature \
             (cargo build -p roadtrack-cli --features cnn)"
        )
    }

    /// The nested-box rule a motion gate in front of the learned detector applies after
    /// gating: the detector's default, or off with --keep-nested.
    // Choice: after gating, not in the detector. A large box on static structure (a sign
    // with a person behind it on vtest.avi) would otherwise take the person's head and legs
    // boxes with it, and the gate would then drop the large box: the person unboxed.
    pub fn gate_nested(&self) -> roadtrack::detect::nested::NestedConfig {
        if self.keep_nested {
            roadtrack::detect::nested::NestedConfig::OFF
        } else {
            roadtrack::detect::nested::NestedConfig::default()
        }
    }

    /// The model path: --detector-model (or what the command took as --model).
    fn model(&self) -> Result<&Path> {
        self.detector_model.as_deref().ok_or_else(|| {
            crate::flags::invalid(
                "--detector onnx needs the model: --model F.onnx (or --detector-model F.onnx)",
            )
        })
    }

    /// The detector, loaded (`--detector onnx`).
    #[cfg(feature = "cnn")]
    pub fn spec(&self) -> Result<roadtrack::detect::DetectorSpec> {
        use roadtrack_cnn::detector::{
            Channels, DetrScores, Layout, OnnxDetector, OnnxDetectorConfig, Resize,
        };
        let model = self.model()?;
        crate::flags::reject_given(
            &self.cnn_only(),
            "only with --detector cnn, not --detector onnx",
        )?;
        let mut config: OnnxDetectorConfig =
            crate::common::load_flag_config(self.onnx_config.as_deref(), "--onnx-config")?;
        if let Some(l) = self.layout {
            config.layout = match l {
                LayoutArg::Auto => Layout::Auto,
                LayoutArg::Yolo => Layout::Yolo,
                LayoutArg::YoloT => Layout::YoloT,
                LayoutArg::Yolox => Layout::Yolox,
                LayoutArg::Detr => Layout::Detr,
            };
        }
        if let Some(s) = self.min_score {
            config.min_score = s;
        }
        if let Some(s) = self.iou_threshold {
            config.iou_threshold = s;
        }
        if let Some(s) = self.input_size {
            config.input_size = Some(s);
        }
        if let Some(s) = self.input_scale {
            config.preprocessing.input_scale = s;
        }
        if self.bgr {
            config.channels = Channels::Bgr;
        }
        if let Some(r) = self.resize {
            config.resize = match r {
                ResizeArg::Letterbox => Resize::Letterbox,
                ResizeArg::LetterboxTopLeft => Resize::LetterboxTopLeft,
                ResizeArg::Stretch => Resize::Stretch,
            };
        }
        if let Some(d) = self.detr_scores {
            config.detr_scores = match d {
                DetrScoresArg::Sigmoid => DetrScores::Sigmoid,
                DetrScoresArg::Softmax => DetrScores::Softmax,
            };
        }
        if let Some(c) = &self.classes {
            config.classes = Some(c.clone());
        }
        crate::flags::check_overrides(
            roadtrack::config::Validate::validate(&config),
            &[("classes", "--classes", self.classes.is_some())],
            self.onnx_config.as_deref(),
        )?;
        let detector = OnnxDetector::load(model, &config)?;
        Ok(roadtrack::detect::DetectorSpec::Given(Box::new(detector)))
    }

    /// Without the `cnn` feature there is no ONNX runtime.
    #[cfg(not(feature = "cnn"))]
    pub fn spec(&self) -> Result<roadtrack::detect::DetectorSpec> {
        self.model()?;
        anyhow::bail!(
            "--detector onnx needs roadtrack built with the `cnn` feature \
             (cargo build -p roadtrack-cli --features cnn)"
        )
    }
}

/// The zoom is for oblique views: on a top-down (nadir) calibration in which a car is
/// under the zoom's limit the whole frame is enlarged, and the network boxes enlarged
/// top-down vehicles badly (docs/DETECTION.md "Zoom"). Say so on stderr, even with `-q`:
/// the output would be worse than without the flag.
#[cfg(feature = "cnn")]
fn warn_if_zoom_top_down(px: f64, calibration: &roadtrack::calibration::Calibration) {
    let Some(mpp) = calibration.metres_per_pixel() else {
        return;
    };
    let car_px = roadtrack_cnn::centernet::ZOOM_CAR_LENGTH_M / mpp;
    if car_px < px {
        eprintln!(
            "warning: --zoom-small {px} on a top-down view: at {mpp} m/px a car is {car_px:.1} \
             px, so the whole frame is enlarged; the zoom is for oblique views (on the \
             simulator's aerial road it lowers HOTA from 0.60 to 0.32, docs/DETECTION.md \
             \"Zoom\"); give a smaller --zoom-small or leave it out"
        );
    }
}
