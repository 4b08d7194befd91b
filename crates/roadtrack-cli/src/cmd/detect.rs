//! `roadtrack detect`: moving-object extraction for fixed cameras.

use crate::common::{DetectorArgs, FrameArgs, Ui, load_config, report_skipped};
use anyhow::{Context, Result};
use roadtrack::detect::DetectorSpec;
use roadtrack::detect::background::BackgroundDetectorConfig;
use roadtrack::detect::background_model::Startup;
use roadtrack::io::atomic::AtomicDir;
use roadtrack::io::{detections::write_detections, source};
use std::path::PathBuf;

/// Find the objects in every frame (by default: background subtraction → regions).
///
/// For each object: centre, box, mean RGB (and area, class, score where the detector gives
/// them), written as a detections CSV.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack detect ../shared/data/vtest.avi -o detections.csv --overlay overlay/ --end 100\n  roadtrack detect seq/ --detector onnx --model yolox_s.onnx --input-scale 1 --bgr --resize letterbox-top-left"
)]
pub struct Args {
    /// Video file, folder of numbered images, or MOTChallenge sequence folder.
    pub input: PathBuf,
    /// Output detections CSV (`-` for standard output).
    #[arg(short, long, default_value = "detections.csv")]
    pub output: PathBuf,
    /// TOML file with a `BackgroundDetectorConfig` ([background], [regions] and [split]
    /// tables; [dots] and [refine] for `--dots` and `--refine-boxes`, with any detector).
    #[arg(long, value_name = "F.toml")]
    pub config: Option<PathBuf>,
    /// Smallest region kept, px² (overrides the config).
    #[arg(long, value_name = "PX2")]
    pub min_area: Option<u32>,
    /// Largest region kept, px² (overrides the config).
    #[arg(long, value_name = "PX2")]
    pub max_area: Option<u32>,
    /// Foreground threshold in standard deviations (overrides the config).
    #[arg(long, value_name = "K", value_parser = crate::flags::positive)]
    pub threshold_sigma: Option<f64>,
    /// How the initial background is made: persistent (the most persistent colour, keeps
    /// queued vehicles out of the background) or median (the earlier behaviour); overrides
    /// the config.
    #[arg(long, value_enum, value_name = "S")]
    pub startup: Option<Startup>,
    /// Camera calibration TOML (as `roadtrack simulate` writes), for --split, or for
    /// --detector cnn --zoom-small (zoom only where cars are small), or for --dots (dot boxes
    /// at the ground scale, only where walkers are under 2 px).
    #[arg(long, value_name = "F.toml")]
    pub calibration: Option<PathBuf>,
    /// Split regions longer than one vehicle at their position into the vehicles they hold
    /// (sets [split] enabled; needs --calibration).
    #[arg(long, requires = "calibration")]
    pub split: bool,
    /// Also write each frame with the detected boxes drawn, as PNG, into this folder.
    #[arg(long, value_name = "DIR", value_parser = crate::common::folder_output)]
    pub overlay: Option<PathBuf>,
    /// Also write each frame's cleaned foreground mask, as PNG, into this folder.
    #[arg(long, value_name = "DIR", value_parser = crate::common::folder_output)]
    pub masks: Option<PathBuf>,
    /// The detector model for --detector onnx (the same as --detector-model).
    #[arg(long, value_name = "F.onnx", conflicts_with = "detector_model")]
    pub model: Option<PathBuf>,
    #[command(flatten)]
    pub detector: DetectorArgs,
    #[command(flatten)]
    pub frames: FrameArgs,
}

pub fn run(mut args: Args, ui: &Ui) -> Result<()> {
    if args.model.is_some() {
        if !args.detector.is_onnx() {
            return Err(crate::flags::conflict(
                "--model: only with --detector onnx or cnn",
            ));
        }
        args.detector.onnx.detector_model = args.model.take();
    }
    if args.detector.is_file() || args.detector.is_onnx() {
        crate::flags::reject_given(
            &[
                // With --dots or --refine-boxes a background model runs beside the detector:
                // its config (and their `[dots]` and `[refine]` tables) applies.
                (
                    "--config",
                    args.config.is_some() && !args.detector.dots && !args.detector.refine_boxes,
                ),
                ("--min-area", args.min_area.is_some()),
                ("--max-area", args.max_area.is_some()),
                ("--threshold-sigma", args.threshold_sigma.is_some()),
                ("--masks", args.masks.is_some()),
                ("--startup", args.startup.is_some()),
                (
                    "--calibration",
                    args.calibration.is_some()
                        && args.detector.onnx.zoom_small.is_none()
                        && !args.detector.dots,
                ),
                ("--split", args.split),
            ],
            if args.detector.is_onnx() {
                "only for the background detector, not --detector onnx"
            } else {
                "only for the background detector, not --detector file"
            },
        )?;
    }
    let mut config: BackgroundDetectorConfig = load_config(args.config.as_deref())?;
    if let Some(s) = args.startup {
        config.background.startup = s;
    }
    if let Some(path) = &args.calibration {
        config.calibration = Some(Box::new(roadtrack::calibration::Calibration::load(path)?));
    }
    if args.split {
        config.split.enabled = true;
    }
    if let Some(a) = args.min_area {
        config.regions.min_area_px = a;
    }
    if let Some(a) = args.max_area {
        config.regions.max_area_px = a;
    }
    if let Some(k) = args.threshold_sigma {
        config.background.threshold_sigma = k;
    }
    crate::flags::check_overrides(
        config.validate(),
        &[
            ("regions.min_area_px", "--min-area", args.min_area.is_some()),
            // min > max is reported at min_area_px, whichever flag set it.
            ("regions.min_area_px", "--max-area", args.max_area.is_some()),
            (
                "background.threshold_sigma",
                "--threshold-sigma",
                args.threshold_sigma.is_some(),
            ),
        ],
        args.config.as_deref(),
    )?;
    let options = args.frames.options()?;
    let info = source::open(&args.input, &options)?.info;
    let total = info.selected_frames;
    ui.detail(format!(
        "{}: {}×{} px, {} fps, {} frames selected",
        args.input.display(),
        info.width,
        info.height,
        info.fps,
        total.map_or("unknown".into(), |t| t.to_string())
    ));
    let bar = ui.progress(None, "background");
    let spec = args
        .detector
        .spec(&args.input, config.calibration.as_deref(), || {
            Ok(config.clone())
        })?
        .unwrap_or(DetectorSpec::Background(config));
    let mut detector = spec.build(&args.input, &options, &info)?;
    bar.finish_and_clear();
    let frames = source::open(&args.input, &options)?;
    let skipped = frames.skip_log();
    let bar = ui.progress(total.map(u64::from), "detect");
    let mut overlay = args.overlay.as_deref().map(AtomicDir::create).transpose()?;
    let mut masks = args.masks.as_deref().map(AtomicDir::create).transpose()?;
    let mut all = Vec::new();
    let mut n_frames = 0u64;
    let batch_len = detector.batch_len().max(1);
    let mut frames = frames.into_iter();
    let mut batch = Vec::with_capacity(batch_len);
    loop {
        if !roadtrack::detect::next_batch(&mut frames, batch_len, &mut batch)? {
            break;
        }
        let results = roadtrack::detect::detect_checked(detector.as_mut(), &batch)?;
        for (frame, found) in batch.iter().zip(results) {
            if let Some(dir) = &overlay {
                let mut img = frame.image.clone();
                for d in &found.detections {
                    if let Some(b) = d.bbox() {
                        roadtrack_viz::overlay::draw_box(
                            &mut img,
                            &b,
                            roadtrack_viz::overlay::id_colour(d.id),
                        );
                    }
                }
                save_png(dir.temp_path(), frame.index, &img)?;
            }
            if let (Some(dir), Some(mask)) = (&masks, &found.foreground) {
                save_png(dir.temp_path(), frame.index, mask)?;
            }
            all.extend(found.detections);
            n_frames += 1;
            bar.inc(1);
        }
    }
    for dir in [overlay.take(), masks.take()].into_iter().flatten() {
        dir.commit()?;
    }
    bar.finish_and_clear();
    write_detections(&args.output, &all)?;
    ui.info(format!(
        "{} detections in {} frames → {}",
        all.len(),
        n_frames,
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

/// Saves `img` as `dir/NNNNNN.png` atomically.
pub fn save_png<P, C>(
    dir: &std::path::Path,
    index: u32,
    img: &image::ImageBuffer<P, C>,
) -> Result<()>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let path = dir.join(format!("{index:06}.png"));
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .with_context(|| format!("encoding {}", path.display()))?;
    roadtrack::io::atomic::write_bytes_atomic(&path, &bytes)?;
    Ok(())
}
