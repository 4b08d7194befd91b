//! `roadtrack bench`: throughput of each stage on bundled scenarios, with the machine named.

use crate::common::Ui;
use anyhow::Result;
use roadtrack::bench::{self, StageResult};
use roadtrack::detector::DetectorConfig;
use roadtrack::io::SourceOptions;
use std::path::PathBuf;

/// Measure the throughput of each stage and print it with the machine's CPU and cores.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack bench --video ../shared/data/vtest.avi --json > bench.json"
)]
pub struct Args {
    /// Real video for the decode and detect stages (skipped when absent).
    #[arg(long, default_value = "../shared/data/vtest.avi")]
    pub video: PathBuf,
    /// Frames of the generated 640×480 sequence.
    #[arg(long, default_value_t = 300)]
    pub frames: u32,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let machine = bench::machine();
    let mut results: Vec<StageResult> = Vec::new();
    let bar = ui.progress(None, "bench");
    if args.video.is_file() && roadtrack::io::video::ffmpeg_available() {
        bar.set_message("decode");
        results.push(bench::decode(&args.video, &SourceOptions::default())?);
        bar.set_message("detect");
        let (label, frames) = bench::load_frames(&args.video, 400)?;
        results.push(bench::detect_frames(
            &label,
            &frames,
            &DetectorConfig::default(),
        )?);
    } else {
        ui.info(format!(
            "note: {} not found or ffmpeg missing; skipping the real-video stages",
            args.video.display()
        ));
    }
    bar.set_message("generate");
    let frames = bench::moving_boxes(640, 480, args.frames, 12);
    bar.set_message("detect");
    results.push(bench::detect_frames(
        "generated 640×480, 12 boxes",
        &frames,
        &DetectorConfig::default(),
    )?);
    bar.finish_and_clear();

    if args.json {
        let v =
            serde_json::json!({ "machine": machine, "build": build_profile(), "stages": results });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "machine: {} ({} cores, {} rayon threads), {} build",
            machine.cpu,
            machine.cores,
            machine.rayon_threads,
            build_profile()
        );
        println!(
            "{:<10} {:<34} {:>8} {:>9} {:>12}",
            "stage", "input", "items", "seconds", "per second"
        );
        for r in &results {
            println!(
                "{:<10} {:<34} {:>8} {:>9.3} {:>8.1} {}",
                r.stage, r.input, r.items, r.seconds, r.per_second, r.unit
            );
        }
    }
    Ok(())
}

fn build_profile() -> &'static str {
    if cfg!(debug_assertions) {
        "debug"
    } else {
        "release"
    }
}
