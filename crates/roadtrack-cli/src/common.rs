//! Plumbing every subcommand shares: terminal output, progress bars, frame selection.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use roadtrack::io::SourceOptions;
use roadtrack::io::bad_frame::{self, OnBadFrame, SkipLog};
use std::path::{Path, PathBuf};

/// How much to print. Progress bars go to stderr and only when it is a terminal.
#[derive(Debug, Clone, Copy)]
pub struct Ui {
    quiet: bool,
    verbose: u8,
}

impl Ui {
    pub fn new(quiet: bool, verbose: u8) -> Self {
        Self { quiet, verbose }
    }

    /// A progress bar over `total` items (a spinner when unknown); hidden with `-q` or when
    /// stderr is not a terminal.
    pub fn progress(&self, total: Option<u64>, what: &str) -> ProgressBar {
        if self.quiet {
            return ProgressBar::hidden();
        }
        let bar = match total {
            Some(t) => ProgressBar::with_draw_target(Some(t), ProgressDrawTarget::stderr()),
            None => ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr()),
        };
        let template = if total.is_some() {
            "{msg:>10} [{bar:30}] {pos}/{len} {per_sec} eta {eta}"
        } else {
            "{msg:>10} {spinner} {pos} {per_sec}"
        };
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_message(what.to_owned());
        bar
    }

    /// A line for the user on stderr, unless `-q`.
    pub fn info(&self, msg: impl AsRef<str>) {
        if !self.quiet {
            eprintln!("{}", msg.as_ref());
        }
    }

    /// A line shown only with `-v`.
    pub fn detail(&self, msg: impl AsRef<str>) {
        if !self.quiet && self.verbose > 0 {
            eprintln!("{}", msg.as_ref());
        }
    }
}

/// Frame selection flags for every command that reads frames.
#[derive(Debug, Clone, clap::Args)]
pub struct FrameArgs {
    /// Frames per second (image folders default to 10; overrides a video's own rate).
    #[arg(long, value_name = "FPS", value_parser = roadtrack::limits::parse_fps)]
    pub fps: Option<f64>,
    /// First frame to read (1-based).
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub start: u32,
    /// Last frame to read, inclusive.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub end: Option<u32>,
    /// Read every N-th frame from --start.
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub step: u32,
    #[command(flatten)]
    pub bad: BadFrameArgs,
}

impl FrameArgs {
    /// The frame selection; a bad one is a usage error naming the flags.
    pub fn options(&self) -> Result<SourceOptions> {
        let options = SourceOptions {
            fps: self.fps,
            start: self.start,
            end: self.end,
            step: self.step,
            on_bad_frame: self.bad.policy(),
        };
        crate::flags::check_overrides(
            options.validate(),
            &[
                ("start", "--start", true),
                ("step", "--step", true),
                ("end", "--end", true),
                ("fps", "--fps", true),
            ],
            None,
        )?;
        Ok(options)
    }
}

/// `--on-bad-frame` (docs/FORMATS.md, "Damaged input").
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BadFrameArg {
    /// Stop with an error naming the frame and the file.
    Fail,
    /// Leave the frame out (a gap in time), list it in the summary and in
    /// `<output>.skipped.json`.
    Skip,
}

/// What to do with a frame that cannot be read, for every command that reads frames.
#[derive(Debug, Clone, clap::Args)]
pub struct BadFrameArgs {
    /// A frame that cannot be read (undecodable or truncated image, missing number in a
    /// numbered folder, video shorter than it announces): fail (exit 1, naming frame and
    /// file) or skip (a gap in time, listed in the summary and in <OUTPUT>.skipped.json).
    #[arg(long, value_enum, default_value_t = BadFrameArg::Fail, value_name = "WHAT")]
    pub on_bad_frame: BadFrameArg,
}

impl BadFrameArgs {
    /// The source's policy.
    pub fn policy(&self) -> OnBadFrame {
        match self.on_bad_frame {
            BadFrameArg::Fail => OnBadFrame::Fail,
            BadFrameArg::Skip => OnBadFrame::Skip,
        }
    }
}

/// Writes `text` to standard output. A reader that has gone (`roadtrack demo | head`) ends
/// the output quietly, where `println!` would panic.
pub fn print_out(text: &str) -> Result<()> {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.context("writing to standard output"),
    }
}

/// After a run under `--on-bad-frame skip`: tells the skipped frames of `source` on stderr
/// and writes them to the sidecar of `output` (`<output>.skipped.json`; none for `-` or
/// without an output). Does nothing under `fail`.
pub fn report_skipped(
    ui: &Ui,
    policy: OnBadFrame,
    source: &Path,
    log: &SkipLog,
    output: Option<&Path>,
) -> Result<()> {
    if policy != OnBadFrame::Skip {
        return Ok(());
    }
    let skipped = log.frames();
    let sidecar: Option<PathBuf> = output.and_then(bad_frame::sidecar_path);
    if let Some(p) = &sidecar {
        bad_frame::write_sidecar(p, source, &skipped)?;
    }
    if !skipped.is_empty() {
        ui.info(format!(
            "warning: skipped {} bad frame{} of {}: {}{}",
            skipped.len(),
            if skipped.len() == 1 { "" } else { "s" },
            source.display(),
            bad_frame::summarize(&skipped),
            sidecar.map_or(String::new(), |p| format!(" (list: {})", p.display()))
        ));
    }
    Ok(())
}

/// `-o -` (standard output) only where a stream makes sense: these clap value parsers turn
/// it into a usage error (exit 2) for outputs that are folders, frames or plots, which
/// would otherwise make a folder or file named `-`.
pub fn folder_output(s: &str) -> std::result::Result<PathBuf, String> {
    not_stdout(
        s,
        "a folder of files cannot go to standard output; give a folder name",
    )
}

/// A MOTChallenge tracks output (`track -o`): any name but one ending in `.csv`, which every
/// reader takes for a trajectories CSV with a header; `-` is standard output.
pub fn mot_output(s: &str) -> std::result::Result<PathBuf, String> {
    if std::path::Path::new(s)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
    {
        return Err(
            "-o writes MOTChallenge rows without a header, which roadtrack reads back \
                    only from a name not ending in .csv (e.g. tracks.txt); for the CSV with a \
                    header, frame times and classes, give --trajectories F.csv"
                .to_owned(),
        );
    }
    Ok(PathBuf::from(s))
}

/// As [`folder_output`], for `render`'s frames (a folder of PNG files or a video file).
pub fn frames_output(s: &str) -> std::result::Result<PathBuf, String> {
    not_stdout(
        s,
        "frames cannot go to standard output; give a folder name, or a video file name \
         ending in .mp4, .mkv, .avi or .webm",
    )
}

/// As [`folder_output`], for plots (the format comes from the extension).
pub fn plot_output(s: &str) -> std::result::Result<PathBuf, String> {
    not_stdout(
        s,
        "a plot cannot go to standard output; give a file name ending in .png or .svg",
    )
}

fn not_stdout(s: &str, why: &str) -> std::result::Result<PathBuf, String> {
    if s == "-" {
        Err(why.to_owned())
    } else {
        Ok(PathBuf::from(s))
    }
}

/// Loads and validates a TOML config when a path is given (a bad value names the file and
/// the key), else the default.
pub fn load_config<T>(path: Option<&Path>) -> Result<T>
where
    T: serde::de::DeserializeOwned + Default + roadtrack::config::Validate,
{
    load_flag_config(path, "--config")
}

/// [`load_config`] for the file of another flag, which its errors name.
pub fn load_flag_config<T>(path: Option<&Path>, flag: &str) -> Result<T>
where
    T: serde::de::DeserializeOwned + Default + roadtrack::config::Validate,
{
    match path {
        Some(p) => roadtrack::config::load_toml(p).with_context(|| format!("reading {flag}")),
        None => Ok(T::default()),
    }
}

/// The object detectors of `--detector`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DetectorArg {
    /// Background subtraction (a background learnt from the input, then regions).
    Background,
    /// Public detections from a file: --detections F, by default the sequence's det/det.txt.
    File,
    /// Any ONNX object detector, --model F.onnx: YOLO, YOLOX, RT-DETR, D-FINE exports
    /// (docs/DETECTION.md "ONNX detectors").
    Onnx,
    /// roadtrack's learned detector (`train --detector`), --model F.onnx, default
    /// models/detector.onnx (docs/DETECTION.md "Learned detector").
    Cnn,
}

/// The shared track life cycle after the method (`track`; docs/TRACKING.md).
#[derive(Debug, Clone, clap::Args)]
pub struct LifecycleArgs {
    /// Write a track only once it has been seen in N frames (1: every track).
    #[arg(long, value_name = "N", default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..))]
    pub confirm_hits: u32,
    /// Fill gaps of up to N frames in a track with interpolated boxes (0: none).
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub coast_frames: u32,
    /// The method's output as published: no confirmation, coasting, box smoothing or
    /// per-track class (not with --confirm-hits or --coast-frames), relaxation without
    /// its second assignment, and the background detector as it was (median start-up, no
    /// shadow suppression, hold, ghost suppression or region splitting; region centroids).
    #[arg(long, conflicts_with_all = ["confirm_hits", "coast_frames", "link_gaps", "extend_frames", "smooth_boxes", "smooth_vehicle_boxes", "orient_walkers", "smooth_robust"])]
    pub as_published: bool,
    /// Offline gap closing: join a track that ends to one that starts up to N frames later
    /// (or up to 4 frames earlier) where its motion leads, under the first one's id, with
    /// interpolated boxes between (0: off). Holds the whole run's points until the end.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub link_gaps: u32,
    /// With --link-gaps: also match colours. A track's end and a start whose mean colours
    /// (centre of the box, RGB 0–255) are more than D apart never join, and closer ones
    /// pay for the difference. 0 leaves colour out.
    #[arg(long, value_name = "D", default_value_t = 0.0, requires = "link_gaps")]
    pub link_colour: f64,
    /// Offline extension: carry each confirmed track up to N frames past its first and
    /// last points along the detections no track took, while they stay on the line of
    /// its motion (0: off). Holds the whole run's points and detections until the end
    /// (docs/TRACKING.md "Extension").
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub extend_frames: u32,
    /// Smooth each track's boxes offline: each box becomes a straight-line fit, in time,
    /// of its track's boxes over the N frames on each side, centre and size (0: off).
    /// Holds the longest window back [default: 5].
    #[arg(long, value_name = "N")]
    pub smooth_boxes: Option<u32>,
    /// The smoothing window of vehicles' boxes (car, truck, bus, motorcycle; 0: none);
    /// 9 suits top-down views, where a car's image path is straight [default:
    /// --smooth-boxes].
    #[arg(long, value_name = "N")]
    pub smooth_vehicle_boxes: Option<u32>,
    /// Top-down views only: turn each pedestrian's smoothed box to their direction of
    /// motion, as the box of a footprint narrower along the walk than across it (same
    /// area). For walkers of a few pixels seen from above (`--dots`); needs the box
    /// smoothing (docs/TRACKING.md "Walkers seen from above").
    #[arg(long)]
    pub orient_walkers: bool,
    /// Fit the centres of the boxes of walkers and unclassified tracks robustly (Huber,
    /// k = 1.345 robust scales), so that a box that lands on a neighbour or a false dot for
    /// a frame or two does not pull the track's path; vehicles keep least squares. For
    /// walkers seen from above (docs/TRACKING.md "Walkers seen from above").
    #[arg(long)]
    pub smooth_robust: bool,
}

impl LifecycleArgs {
    /// The stage's configuration; a value out of range is a usage error naming the flag.
    pub fn config(&self) -> Result<roadtrack::track::confirm::LifecycleConfig> {
        use roadtrack::track::confirm::LifecycleConfig;
        if self.as_published {
            return Ok(LifecycleConfig::off());
        }
        let config = LifecycleConfig {
            confirm_hits: self.confirm_hits,
            max_coast_frames: self.coast_frames,
            ..LifecycleConfig::default()
        };
        crate::flags::check_overrides(
            config.validate(),
            &[
                ("confirm_hits", "--confirm-hits", true),
                ("max_coast_frames", "--coast-frames", true),
                (
                    "confirm_hits/max_coast_frames",
                    "--confirm-hits/--coast-frames",
                    true,
                ),
            ],
            None,
        )?;
        Ok(config)
    }

    /// The box smoother's configuration: [`SmoothConfig::recommended`] unless told
    /// otherwise; off with `--as-published` or `--smooth-boxes 0`.
    ///
    /// [`SmoothConfig::recommended`]: roadtrack::track::smooth::SmoothConfig::recommended
    pub fn smooth(&self) -> Result<roadtrack::track::smooth::SmoothConfig> {
        use roadtrack::track::smooth::SmoothConfig;
        let mut config = match self.smooth_boxes {
            _ if self.as_published => SmoothConfig::uniform(0),
            Some(k) => SmoothConfig::uniform(k),
            None => SmoothConfig::recommended(),
        };
        if let Some(k) = self.smooth_vehicle_boxes {
            config.vehicle_half_window_frames = Some(k);
        }
        config.orient_walkers = self.orient_walkers;
        if self.smooth_robust {
            // Choice: Huber's usual k (95 % efficiency at Gaussian noise); on the aerial
            // junctions (seed 1) k = 1.0 and 2.0 gave HOTA within 0.002 of it.
            config.huber_k = 1.345;
        }
        crate::flags::check_overrides(
            config.validate(),
            &[
                ("vehicle_half_window_frames", "--smooth-vehicle-boxes", true),
                ("half_window_frames", "--smooth-boxes", true),
                ("orient_walkers", "--orient-walkers", true),
                ("huber_k", "--smooth-robust", true),
            ],
            None,
        )?;
        Ok(config)
    }

    /// The extension stage's configuration (off unless `--extend-frames`).
    pub fn extend(&self) -> Result<roadtrack::track::extend::ExtendConfig> {
        let config = roadtrack::track::extend::ExtendConfig {
            max_frames: self.extend_frames,
            ..Default::default()
        };
        crate::flags::check_overrides(
            config.validate(),
            &[("max_frames", "--extend-frames", true)],
            None,
        )?;
        Ok(config)
    }

    /// The gap-closing stage's configuration (off unless `--link-gaps`).
    pub fn link(&self) -> Result<roadtrack::track::link::LinkConfig> {
        use roadtrack::track::link::LinkConfig;
        let config = LinkConfig {
            max_gap_frames: self.link_gaps,
            colour_gate: self.link_colour,
            ..LinkConfig::recommended()
        };
        crate::flags::check_overrides(
            config.validate(),
            &[
                ("max_gap_frames/max_overlap_frames", "--link-gaps", true),
                ("colour_gate", "--link-colour", true),
            ],
            None,
        )?;
        Ok(config)
    }
}

/// Which detector finds the objects (`detect`, `track`, `render`, `demo`).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct DetectorArgs {
    /// Object detector (default: background subtraction; `demo`: the learned detector
    /// without the mirror image, `cnn --no-flip`).
    #[arg(long, value_enum, value_name = "D")]
    pub detector: Option<DetectorArg>,
    /// Detections file for --detector file: a MOTChallenge det.txt or a detections CSV
    /// (.csv); default: det/det.txt of the sequence folder given as input.
    #[arg(long, value_name = "F")]
    pub detections: Option<std::path::PathBuf>,
    /// Keep only the boxes of --detector cnn, onnx or file whose pixels are at least this
    /// fraction foreground for a background model learnt from the input (0–1, e.g. 0.2):
    /// drops static clutter on a fixed camera (posts, windows), and with it objects that
    /// never move. Off by default.
    #[arg(long, value_name = "FRACTION")]
    pub motion_gate: Option<f64>,
    /// Also find pedestrians too small for the detector (1–2 px walkers seen from a drone
    /// or a high pole) as dots of the difference from a background model learnt from the
    /// input; boxed at a person's footprint. With --calibration, only where a footprint is
    /// under 2 px. Off by default.
    #[arg(long)]
    pub dots: bool,
    /// Fit each box of the detector (not pedestrians') to the pixels that differ from a
    /// background model learnt from the input, or, for a vehicle the model has absorbed
    /// (parked, queued), from the road around it: tighter vehicle boxes on a fixed camera
    /// (docs/DETECTION.md "Refined boxes"). Off by default.
    #[arg(long)]
    pub refine_boxes: bool,
    /// With --refine-boxes, fit pedestrians' boxes too: where people walk apart (a junction
    /// seen from a pole), not in crowds, whose fitted boxes join.
    #[arg(long, requires = "refine_boxes")]
    pub refine_pedestrians: bool,
    #[command(flatten)]
    pub onnx: crate::onnx_detector::OnnxArgs,
}

impl DetectorArgs {
    /// Whether the detections come from a file (`--detector file` or `--detections F`).
    pub fn is_file(&self) -> bool {
        self.detector == Some(DetectorArg::File)
            || (self.detector.is_none() && self.detections.is_some())
    }

    /// Whether the detector is a model file (`--detector onnx` or `cnn`): `--model` is its
    /// model.
    pub fn is_onnx(&self) -> bool {
        matches!(self.detector, Some(DetectorArg::Onnx | DetectorArg::Cnn))
    }

    /// The detector asked for; `None` leaves the choice to the method (its own background
    /// detector). `background` is the background detector with `config`; `calibration`
    /// (`--calibration`) limits the learned detector's zoom to the rows where cars are
    /// small.
    pub fn spec(
        &self,
        input: &Path,
        calibration: Option<&roadtrack::calibration::Calibration>,
        background: impl FnOnce() -> Result<roadtrack::detect::background::BackgroundDetectorConfig>,
    ) -> Result<Option<roadtrack::detect::DetectorSpec>> {
        use roadtrack::detect::DetectorSpec;
        let kind = match (self.detector, &self.detections) {
            (None, Some(_)) => DetectorArg::File,
            (Some(k), _) => k,
            (None, None) => {
                reject_onnx_flags(&self.onnx)?;
                if self.motion_gate.is_some() {
                    return Err(crate::flags::conflict(
                        "--motion-gate needs --detector cnn, onnx or file",
                    ));
                }
                if self.dots || self.refine_boxes {
                    let flag = if self.dots {
                        "--dots"
                    } else {
                        "--refine-boxes"
                    };
                    return Err(crate::flags::conflict(format!(
                        "{flag} needs --detector (background, cnn, onnx or file)"
                    )));
                }
                return Ok(None);
            }
        };
        // Checked before any model is opened, so a bad value is a usage error first.
        let gate = match self.motion_gate {
            Some(fraction) => {
                let gate = roadtrack::detect::motion_gate::MotionGateConfig {
                    min_foreground_fraction: fraction,
                    ..Default::default()
                };
                crate::flags::check_overrides(
                    gate.validate(),
                    &[("min_foreground_fraction", "--motion-gate", true)],
                    None,
                )?;
                Some(gate)
            }
            None => None,
        };
        if kind == DetectorArg::Background && self.motion_gate.is_some() {
            return Err(crate::flags::conflict(
                "--motion-gate needs --detector cnn, onnx or file, not --detector background",
            ));
        }
        if kind == DetectorArg::Cnn {
            crate::flags::reject_given(
                &self.onnx.given_not_cnn(),
                "only with --detector onnx, not --detector cnn",
            )?;
        } else if kind != DetectorArg::Onnx {
            reject_onnx_flags(&self.onnx)?;
        }
        let spec = match kind {
            DetectorArg::Background => {
                if self.detections.is_some() {
                    return Err(crate::flags::conflict(
                        "--detections needs --detector file, not --detector background",
                    ));
                }
                // Never gated (refused above).
                let cfg = background()?;
                let spec = DetectorSpec::Background(cfg.clone());
                return self.with_dots_and_fit(spec, calibration, || Ok(cfg));
            }
            DetectorArg::File => {
                let path = match &self.detections {
                    Some(p) => p.clone(),
                    None => {
                        roadtrack::detect::file::sequence_detections(input).with_context(|| {
                            format!(
                                "--detector file: {} has no det/det.txt; give --detections F",
                                input.display()
                            )
                        })?
                    }
                };
                DetectorSpec::File(path)
            }
            DetectorArg::Onnx => {
                if self.detections.is_some() {
                    return Err(crate::flags::conflict(
                        "--detections needs --detector file, not --detector onnx",
                    ));
                }
                self.onnx.spec()?
            }
            DetectorArg::Cnn => {
                if self.detections.is_some() {
                    return Err(crate::flags::conflict(
                        "--detections needs --detector file, not --detector cnn",
                    ));
                }
                self.onnx.cnn_spec(calibration, gate.is_none())?
            }
        };
        let Some(mut gate) = gate else {
            return self.with_dots_and_fit(spec, calibration, background);
        };
        if kind == DetectorArg::Cnn {
            gate.nested = self.onnx.gate_nested();
        }
        let cfg = background()?;
        let gated = DetectorSpec::MotionGated(Box::new(spec), cfg.clone(), gate);
        self.with_dots_and_fit(gated, calibration, || Ok(cfg))
    }

    /// `spec` with `--dots` and `--refine-boxes` added when asked for (the dots against the
    /// detector's own boxes, then the boxes refined).
    fn with_dots_and_fit(
        &self,
        spec: roadtrack::detect::DetectorSpec,
        calibration: Option<&roadtrack::calibration::Calibration>,
        background: impl FnOnce() -> Result<roadtrack::detect::background::BackgroundDetectorConfig>,
    ) -> Result<Option<roadtrack::detect::DetectorSpec>> {
        use roadtrack::detect::DetectorSpec;
        if !self.dots && !self.refine_boxes {
            return Ok(Some(spec));
        }
        let cfg = background()?;
        let spec = if self.dots {
            DetectorSpec::WithDots(
                Box::new(spec),
                cfg.clone(),
                cfg.dots.clone(),
                calibration.map(|c| Box::new(c.clone())),
            )
        } else {
            spec
        };
        let refine = roadtrack::detect::refine::RefineConfig {
            pedestrians: self.refine_pedestrians || cfg.refine.pedestrians,
            ..cfg.refine.clone()
        };
        Ok(Some(if self.refine_boxes {
            DetectorSpec::Refined(Box::new(spec), cfg, refine)
        } else {
            spec
        }))
    }
}

/// The `--detector onnx` flags are usage errors with another detector.
fn reject_onnx_flags(onnx: &crate::onnx_detector::OnnxArgs) -> Result<()> {
    let not_cnn = onnx.given_not_cnn();
    let (mut both, cnn): (Vec<_>, Vec<_>) = onnx
        .given()
        .into_iter()
        .filter(|g| !not_cnn.contains(g))
        .partition(|(f, _)| matches!(*f, "--min-score" | "--iou-threshold"));
    both.push(("--detector-model", onnx.detector_model.is_some()));
    // Each flag named with the detectors that take it (`--zoom-small` is the learned
    // detector's alone).
    crate::flags::reject_given(&not_cnn, "only with --detector onnx")?;
    crate::flags::reject_given(&cnn, "only with --detector cnn")?;
    crate::flags::reject_given(&both, "only with --detector onnx or cnn")
}

/// The detector's name as `--detector` spells it (`file` for `--detections F` alone).
pub fn detector_name(args: &DetectorArgs) -> String {
    use clap::ValueEnum;
    let kind = if args.is_file() {
        Some(DetectorArg::File)
    } else {
        args.detector
    };
    kind.and_then(|k| k.to_possible_value())
        .map_or("background".into(), |v| v.get_name().to_owned())
}
