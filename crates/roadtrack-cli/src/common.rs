//! Plumbing every subcommand shares: terminal output, progress bars, frame selection.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use roadtrack::io::SourceOptions;
use std::path::Path;

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
    #[arg(long, value_name = "FPS", value_parser = crate::flags::positive)]
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
}

impl FrameArgs {
    /// The frame selection; a bad one is a usage error naming the flags.
    pub fn options(&self) -> Result<SourceOptions> {
        let options = SourceOptions {
            fps: self.fps,
            start: self.start,
            end: self.end,
            step: self.step,
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

/// Loads and validates a TOML config when a path is given (a bad value names the file and
/// the key), else the default.
pub fn load_config<T>(path: Option<&Path>) -> Result<T>
where
    T: serde::de::DeserializeOwned + Default + roadtrack::config::Validate,
{
    match path {
        Some(p) => roadtrack::config::load_toml(p).with_context(|| "reading --config"),
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
}

/// The shared track life cycle after the method (`track`; docs/TRACKING.md).
#[derive(Debug, Clone, clap::Args)]
pub struct LifecycleArgs {
    /// Write a track only once it has been seen in N frames (1: every track).
    #[arg(long, value_name = "N", default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..))]
    pub confirm_hits: u32,
    /// Fill gaps of up to N frames in a track with interpolated boxes (0: none).
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub coast_frames: u32,
    /// The method's output as published: no confirmation, coasting, box smoothing or
    /// per-track class (not with --confirm-hits or --coast-frames), and relaxation
    /// without its second assignment.
    #[arg(long, conflicts_with_all = ["confirm_hits", "coast_frames"])]
    pub as_published: bool,
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
}

/// Which detector finds the objects (`detect`, `track`, `render`, `demo`).
#[derive(Debug, Clone, clap::Args)]
pub struct DetectorArgs {
    /// Object detector (default: background subtraction).
    #[arg(long, value_enum, value_name = "D")]
    pub detector: Option<DetectorArg>,
    /// Detections file for --detector file: a MOTChallenge det.txt or a detections CSV
    /// (.csv); default: det/det.txt of the sequence folder given as input.
    #[arg(long, value_name = "F")]
    pub detections: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub onnx: crate::onnx_detector::OnnxArgs,
}

impl DetectorArgs {
    /// Whether the detections come from a file (`--detector file` or `--detections F`).
    pub fn is_file(&self) -> bool {
        self.detector == Some(DetectorArg::File)
            || (self.detector.is_none() && self.detections.is_some())
    }

    /// Whether the detector is an ONNX model (`--detector onnx`).
    pub fn is_onnx(&self) -> bool {
        self.detector == Some(DetectorArg::Onnx)
    }

    /// The detector asked for; `None` leaves the choice to the method (its own background
    /// detector). `background` is the background detector with `config`.
    pub fn spec(
        &self,
        input: &Path,
        background: impl FnOnce() -> Result<roadtrack::detect::background::BackgroundDetectorConfig>,
    ) -> Result<Option<roadtrack::detect::DetectorSpec>> {
        use roadtrack::detect::DetectorSpec;
        let kind = match (self.detector, &self.detections) {
            (None, Some(_)) => DetectorArg::File,
            (Some(k), _) => k,
            (None, None) => {
                reject_onnx_flags(&self.onnx)?;
                return Ok(None);
            }
        };
        if kind != DetectorArg::Onnx {
            reject_onnx_flags(&self.onnx)?;
        }
        Ok(Some(match kind {
            DetectorArg::Background => {
                if self.detections.is_some() {
                    return Err(crate::flags::conflict(
                        "--detections needs --detector file, not --detector background",
                    ));
                }
                DetectorSpec::Background(background()?)
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
        }))
    }
}

/// The `--detector onnx` flags are usage errors with another detector.
fn reject_onnx_flags(onnx: &crate::onnx_detector::OnnxArgs) -> Result<()> {
    let mut given = onnx.given();
    given.push(("--detector-model", onnx.detector_model.is_some()));
    crate::flags::reject_given(&given, "only with --detector onnx")
}
