//! `roadtrack demo`: the built-in example.

use crate::common::Ui;
use crate::demo::{DemoConfig, run_demo};
use anyhow::Result;
use std::path::PathBuf;

/// The built-in example: simulate an intersection with pedestrians, track it with every
/// method, evaluate against the truth, write overlays, plots, a traffic analysis and a
/// one-page report.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  roadtrack demo -o demo/ && less demo/report.md")]
pub struct Args {
    /// Output folder.
    #[arg(short, long, default_value = "demo", value_parser = crate::common::folder_output)]
    pub output: PathBuf,
    /// Frames to simulate.
    #[arg(long, default_value_t = 150, value_parser = clap::value_parser!(u32).range(1..=i64::from(roadtrack::limits::MAX_FRAME)))]
    pub frames: u32,
    /// Seed of the simulation and the trackers.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write overlay PNG folders instead of MP4 videos.
    #[arg(long)]
    pub no_video: bool,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let cfg = DemoConfig {
        frames: args.frames,
        seed: args.seed,
        video: !args.no_video,
    };
    let bar = ui.progress(None, "demo");
    let report = run_demo(&cfg, &args.output, &mut |s| {
        bar.set_message(s.to_owned());
        bar.tick();
    })?;
    bar.finish_and_clear();
    println!(
        "{:<12} {:>6} {:>7} {:>7} {:>7} {:>6}",
        "method", "tracks", "MOTA", "IDF1", "HOTA", "IDSW"
    );
    for m in &report.methods {
        println!(
            "{:<12} {:>6} {:>7.3} {:>7.3} {:>7.3} {:>6}",
            m.method, m.tracks, m.mota, m.idf1, m.hota, m.idsw
        );
    }
    println!("report: {}", report.report.display());
    Ok(())
}
