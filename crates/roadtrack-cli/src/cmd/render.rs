//! `roadtrack render`: boxes, ids, class colours and fading trails over the frames.

use crate::common::{DetectorArgs, FrameArgs, Ui, report_skipped};
use crate::overlay::OverlaySink;
use anyhow::{Context, Result};
use roadtrack::class::ObjectClass;
use roadtrack::detect::FrameDetections;
use roadtrack::detect::background::BackgroundDetectorConfig;
use roadtrack::frame::Frame;
use roadtrack::geometry::BBox;
use roadtrack::io::{read_track_points, read_truth_points, sink, source};
use roadtrack::track::replay::ReplayTracker;
use roadtrack::track::{FramePoints, Pipeline, Tracker};
use roadtrack::track_point::TrackPoint;
use roadtrack_viz::render::{ColourBy, RenderConfig};
use std::path::PathBuf;

/// Draw tracks, or a detector's boxes, over the frames: boxes, ids, class colours and
/// fading trails.
///
/// With --truth, each output frame shows the tracks (left) and the ground truth (right)
/// side by side, each half labelled.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  \
    roadtrack render seq/ --tracks tracks.txt --truth seq/ -o compare.mp4\n  \
    roadtrack render frames/ --tracks trajectories.csv -o overlay/ --trail 50 --end 200\n  \
    roadtrack render seq/ --detector background --truth seq/ -o detections.mp4")]
pub struct Args {
    /// Video file, folder of numbered images, or MOTChallenge sequence folder.
    pub input: PathBuf,
    /// Tracks to draw, read by extension: `.txt` = MOTChallenge tracks file
    /// (frame,id,bb_left,bb_top,bb_width,bb_height,conf,…); `.csv` = trajectories CSV
    /// (`roadtrack track --trajectories`, which carries classes). Or, instead, --detector.
    #[arg(
        long,
        value_name = "T",
        required_unless_present_any = ["detector", "detections"],
        conflicts_with_all = ["detector", "detections"]
    )]
    pub tracks: Option<PathBuf>,
    /// Ground truth to show side by side: a MOTChallenge sequence folder (its gt/gt.txt),
    /// a MOTChallenge gt file, or a trajectories CSV.
    #[arg(long, value_name = "GT")]
    pub truth: Option<PathBuf>,
    /// Output: a name ending in .mp4, .mkv, .avi or .webm writes a video (needs the ffmpeg
    /// program); anything else is a folder that receives NNNNNN.png per frame.
    #[arg(short, long, value_name = "OUT", value_parser = crate::common::frames_output)]
    pub output: PathBuf,
    /// Trail length in frames (0 for no trails).
    #[arg(long, default_value_t = 30, value_name = "N")]
    pub trail: u32,
    /// Colour boxes and trails by track id or by class [default: id for tracks, class
    /// for --detector].
    #[arg(long, value_enum, value_name = "BY")]
    pub colour_by: Option<ColourBy>,
    /// Leave out the id/class labels.
    #[arg(long)]
    pub no_labels: bool,
    /// Label text height, px (default: frame height / 40, within 9–18).
    #[arg(long, value_name = "PX", value_parser = crate::flags::positive_f32)]
    pub label_size: Option<f32>,
    // Instead of --tracks: what --detector finds in each frame (numbered within the frame,
    // no trails).
    #[command(flatten)]
    pub detector: DetectorArgs,
    #[command(flatten)]
    pub frames: FrameArgs,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let tracks_title = match &args.tracks {
        Some(t) => format!(
            "tracks: {}",
            t.file_name()
                .map_or("tracks".into(), |n| n.to_string_lossy().into_owned())
        ),
        None => format!(
            "detections: {}",
            crate::common::detector_name(&args.detector)
        ),
    };
    let drawing_detections = args.tracks.is_none();
    let config = RenderConfig {
        // Choice: a detection has no identity across frames, so detections get no trails
        // and are coloured by class unless --colour-by says otherwise.
        trail_frames: if drawing_detections { 0 } else { args.trail },
        colour_by: args.colour_by.unwrap_or(if drawing_detections {
            ColourBy::Class
        } else {
            ColourBy::Id
        }),
        labels: !args.no_labels,
        label_height_px: args.label_size,
        tracks_title,
        ..RenderConfig::default()
    };
    crate::flags::check_overrides(
        config.validate(),
        &[("label_height_px", "--label-size", true)],
        None,
    )?;
    let options = args.frames.options()?;
    let frames = source::open(&args.input, &options)?;
    let skipped = frames.skip_log();
    let info = frames.info.clone();
    let (tracks, detector) = match &args.tracks {
        Some(t) => (read_track_points(t, info.fps)?, None),
        None => {
            // Choice: `--detector background` is the background detector's default config,
            // as `roadtrack detect` without --config.
            let spec = args
                .detector
                .spec(
                    &args.input,
                    None,
                    || Ok(BackgroundDetectorConfig::default()),
                )?
                .context("internal error: render without --tracks or --detector")?;
            (Vec::new(), Some(spec.build(&args.input, &options, &info)?))
        }
    };
    let truth = match &args.truth {
        Some(p) => Some(read_truth_points(p, info.fps)?),
        None => None,
    };
    ui.detail(format!(
        "{}: {}×{} px, {} fps; {}{}",
        args.input.display(),
        info.width,
        info.height,
        info.fps,
        if detector.is_some() {
            config.tracks_title.clone()
        } else {
            format!("{} track points", tracks.len())
        },
        truth
            .as_ref()
            .map_or(String::new(), |t| format!(", {} truth points", t.len()))
    ));
    // Choice: with --step k the video plays at fps / k, so it runs in real time.
    let video_fps = info.fps / f64::from(options.step);
    let mut out = sink::open_sink(&args.output, video_fps)
        .with_context(|| format!("opening output {}", args.output.display()))?;
    if options.on_bad_frame == roadtrack::io::OnBadFrame::Skip && sink::is_video_path(&args.output)
    {
        // A skipped frame keeps its time in a video: the frame before it is held.
        out = Box::new(sink::HoldOverGaps::new(out, options.step));
    }
    let total = info.selected_frames.map(u64::from);
    let bar = ui.progress(total, "render");
    let mut overlay = OverlaySink::new(&config, truth.as_deref(), out)?;
    let mut pipeline = match detector {
        Some(d) => {
            let mut p = Pipeline::new(Box::new(DetectionsAsPoints));
            p.detector = Some(d);
            p
        }
        None => Pipeline::new(Box::new(ReplayTracker::new(tracks))),
    };
    pipeline.sinks.push(Box::new(&mut overlay));
    pipeline.run(frames, total, &mut |_, _| bar.inc(1))?;
    drop(pipeline);
    bar.finish_and_clear();
    ui.info(format!(
        "{} frames → {}",
        overlay.frames,
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

/// Each frame's detections drawn as they are: one point per detection, numbered within the
/// frame (`render --detector`).
struct DetectionsAsPoints;

impl Tracker for DetectionsAsPoints {
    fn step(
        &mut self,
        frame: &Frame,
        detections: &FrameDetections,
    ) -> roadtrack::Result<Vec<FramePoints>> {
        let points = detections
            .detections
            .iter()
            .map(|d| TrackPoint {
                frame: frame.index,
                time_s: frame.time_s,
                id: d.id,
                class: d.class.clone().unwrap_or(ObjectClass::Unknown),
                // Choice: a detection without a size (a centre only) is drawn as a 10 px box.
                bbox: d
                    .bbox()
                    .unwrap_or_else(|| BBox::from_centre(d.pos_px, 10.0, 10.0)),
                score: d.score.unwrap_or(1.0),
                ground: None,
            })
            .collect();
        Ok(vec![FramePoints::new(frame, points)])
    }

    fn finish(&mut self) -> roadtrack::Result<Vec<FramePoints>> {
        Ok(Vec::new())
    }
}
