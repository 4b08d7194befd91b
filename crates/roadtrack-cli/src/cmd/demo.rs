//! `roadtrack demo`: the built-in example.

use crate::common::{DetectorArgs, Ui};
use crate::demo::{DEFAULT_FPS, DEFAULT_FRAMES, DemoConfig, run_demo};
use anyhow::Result;
use std::path::PathBuf;

/// The built-in example: simulate an intersection with pedestrians over a whole signal
/// cycle, track it with every method, evaluate against the truth, write overlays, plots, a
/// traffic analysis and a one-page report that leads with the best method and sets each
/// method's counts and turning movements beside the truth's.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack demo -o demo/ && less demo/report.md   # the learned detector, without the mirror\n  roadtrack demo --detector file -o demo_det/   # the sequence's det/det.txt\n  roadtrack demo --detector background -o demo_bg/   # each method's own background detector"
)]
pub struct Args {
    /// Output folder.
    #[arg(short, long, default_value = "demo", value_parser = crate::common::folder_output)]
    pub output: PathBuf,
    /// Frames to simulate (the default holds one whole signal cycle).
    #[arg(long, default_value_t = DEFAULT_FRAMES, value_parser = clap::value_parser!(u32).range(1..=i64::from(roadtrack::limits::MAX_FRAME)))]
    pub frames: u32,
    /// Frames per second of the simulation.
    #[arg(long, default_value_t = DEFAULT_FPS, value_name = "FPS", value_parser = roadtrack::limits::parse_fps)]
    pub fps: f64,
    /// Seed of the simulation and the trackers.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write overlay PNG folders instead of MP4 videos.
    #[arg(long)]
    pub no_video: bool,
    // --detector for every method; `file` is the simulated sequence's det/det.txt.
    #[command(flatten)]
    pub detector: DetectorArgs,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    if args.detector.detections.is_some() {
        return Err(crate::flags::conflict(
            "--detections: not for demo; --detector file reads the simulated sequence's \
             det/det.txt",
        ));
    }
    let given = args.detector.detector.is_some() || args.detector.is_file();
    let detector = if given {
        args.detector
    } else {
        crate::demo::default_detector(args.detector)
    };
    if !detector.is_file() {
        // Bad detector flags or an unreadable model fail before the simulation, not after.
        detector.spec(&args.output, None, || Ok(Default::default()))?;
    }
    let cfg = DemoConfig {
        frames: args.frames,
        fps: args.fps,
        seed: args.seed,
        video: !args.no_video,
        detector,
        detector_default: !given,
        ..DemoConfig::default()
    };
    let bar = ui.progress(None, "demo");
    let report = run_demo(&cfg, &args.output, &mut |s| {
        bar.set_message(s.to_owned());
        bar.tick();
    })?;
    bar.finish_and_clear();
    use std::fmt::Write as _;
    let mut text = format!(
        "{:<12} {:>6} {:>7} {:>7} {:>7} {:>6} {:>6} {:>8}\n",
        "method", "tracks", "MOTA", "IDF1", "HOTA", "IDSW", "trips", "turning"
    );
    for m in &report.methods {
        let _ = writeln!(
            text,
            "{:<12} {:>6} {:>7.3} {:>7.3} {:>7.3} {:>6} {:>6} {:>8}",
            m.method,
            m.tracks,
            m.mota,
            m.idf1,
            m.hota,
            m.idsw,
            m.trips,
            m.movement_error
                .map_or("–".into(), |e| format!("{:.0} %", 100.0 * e))
        );
    }
    let _ = writeln!(text, "report: {}", report.report.display());
    crate::common::print_out(&text)?;
    Ok(())
}
