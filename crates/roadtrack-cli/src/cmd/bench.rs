//! `roadtrack bench`: throughput of each stage on bundled scenarios, with the machine named.

use crate::common::{BadFrameArgs, Ui, report_skipped};
use anyhow::Result;
use roadtrack::detect::background::BackgroundDetectorConfig;
use roadtrack::io::SourceOptions;
use roadtrack_cli::bench::{self, StageResult};
use std::path::PathBuf;

/// Measure the throughput of each stage and print it with the machine's CPU and cores.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack bench --video ../shared/data/vtest.avi --json > bench.json\n  RAYON_NUM_THREADS=2 roadtrack bench --stages cnn"
)]
pub struct Args {
    /// Real video for the decode and detect stages (skipped when absent).
    #[arg(long, default_value = "../shared/data/vtest.avi")]
    pub video: PathBuf,
    /// Frames of the generated 640×480 sequence.
    #[arg(long, default_value_t = 300, value_parser = clap::value_parser!(u32).range(1..=i64::from(roadtrack::limits::MAX_FRAME)))]
    pub frames: u32,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Stages to run, comma-separated (default all).
    #[arg(long, value_delimiter = ',', value_enum, value_name = "STAGE,…")]
    pub stages: Vec<Stage>,
    /// Largest vehicle count of the relaxation scale stage (50, 1 000, 10 000, 100 000).
    #[arg(long, default_value_t = 100_000, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub max_vehicles: usize,
    #[command(flatten)]
    pub bad: BadFrameArgs,
}

/// The stages of `--stages`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Stage {
    /// Video decoding (needs --video and ffmpeg).
    Decode,
    /// Background-subtraction detection.
    Detect,
    /// The traffic simulator.
    Simulate,
    /// Decode, detect, track and write with each method's defaults.
    Pipeline,
    /// Relaxation matching, up to --max-vehicles.
    Relaxation,
    /// The MRF tracker.
    Mrf,
    /// The particle and PHD filters.
    Filters,
    /// Network scoring per window and dense, and a PHD tracking step with a CNN
    /// likelihood (the SSD rows when scripts/setup.sh --models has run).
    Cnn,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let machine = bench::machine();
    let mut results: Vec<StageResult> = Vec::new();
    let want = |s: Stage| args.stages.is_empty() || args.stages.contains(&s);
    let bar = ui.progress(None, "bench");
    let have_video = args.video.is_file() && roadtrack::io::video::ffmpeg_available();
    if !have_video {
        ui.info(format!(
            "note: {} not found or ffmpeg missing; skipping the real-video stages",
            args.video.display()
        ));
    }
    if have_video && want(Stage::Decode) {
        bar.set_message("decode");
        let options = SourceOptions {
            on_bad_frame: args.bad.policy(),
            ..SourceOptions::default()
        };
        let (result, skipped) = bench::decode(&args.video, &options)?;
        results.push(result);
        report_skipped(ui, options.on_bad_frame, &args.video, &skipped, None)?;
    }
    let generated = roadtrack_sim::testkit::moving_boxes(640, 480, args.frames, 12);
    if want(Stage::Detect) {
        bar.set_message("detect");
        if have_video {
            let (label, frames) = bench::load_frames(&args.video, 400, args.bad.policy())?;
            results.push(bench::detect_frames(
                &label,
                &frames,
                &BackgroundDetectorConfig::default(),
            )?);
        }
        results.push(bench::detect_frames(
            "generated 640×480, 12 boxes",
            &generated,
            &BackgroundDetectorConfig::default(),
        )?);
        // The learned detector, when its model is there (models/detector.onnx).
        #[cfg(feature = "cnn")]
        {
            use roadtrack_cnn::centernet::{
                CenterNetConfig, CenterNetDetector, default_model_path,
            };
            let path = default_model_path();
            if path.is_file() {
                // The defaults; the same with the network in tract instead of roadtrack's
                // kernels; without the test-time flip (`--no-flip`): half the
                // compute; with the zoomed level (`--zoom-small 12`): four times the
                // full-size level's compute.
                let d = CenterNetConfig::default;
                for (name, config, whole) in [
                    ("detect-cnn", d(), false),
                    ("detect-cnn, whole network in tract", d(), true),
                    (
                        "detect-cnn --no-flip",
                        CenterNetConfig { flip: false, ..d() },
                        false,
                    ),
                    (
                        "detect-cnn --zoom-small 12",
                        CenterNetConfig {
                            zoom_max_side: 12.0,
                            ..d()
                        },
                        false,
                    ),
                ] {
                    let mut det = CenterNetDetector::load(&path, &config)?;
                    if whole {
                        det = det.whole_in_tract();
                    }
                    results.push(bench::detect_with(
                        name,
                        "generated 640×480, 12 boxes",
                        &generated,
                        &mut det,
                    )?);
                }
            }
        }
    }
    if want(Stage::Simulate) {
        use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
        for (scene, view, name) in [
            (SceneKind::Road, ViewKind::Aerial, "road aerial"),
            (
                SceneKind::Intersection,
                ViewKind::Oblique,
                "intersection oblique",
            ),
        ] {
            bar.set_message(format!("simulate {name}"));
            let cfg = SimConfig {
                scene,
                view,
                ..Default::default()
            };
            let b = bench::sim::benchmark(&cfg, 0, args.frames)?;
            let label = format!("{name} {}×{}", b.size.0, b.size.1);
            results.push(StageResult::new(
                "sim-render",
                &label,
                u64::from(b.frames),
                "frames",
                b.setup_s + b.render_s,
            ));
            results.push(StageResult::new(
                "sim-encode",
                &label,
                u64::from(b.frames),
                "frames",
                b.encode_s,
            ));
        }
    }
    if want(Stage::Pipeline) {
        // Decode + detect + track + write, per method, on a simulated intersection.
        use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
        bar.set_message("pipeline: simulating");
        let dir = tempfile::tempdir()?;
        let seq = dir.path().join("seq");
        let cfg = SimConfig {
            scene: SceneKind::Intersection,
            view: ViewKind::Oblique,
            frames: args.frames,
            ..SimConfig::default()
        };
        roadtrack_sim::simulate(&cfg, 1, &seq, &mut |_, _| {})?;
        bar.set_message("pipeline");
        results.extend(bench::pipeline(
            &seq,
            &format!("intersection oblique 640×480, {} frames", args.frames),
            0,
        )?);
    }
    if want(Stage::Relaxation) {
        for n in [50usize, 1_000, 10_000, 100_000]
            .into_iter()
            .filter(|&n| n <= args.max_vehicles)
        {
            bar.set_message(format!("relaxation {n}"));
            let r = roadtrack::track::relaxation::scale_experiment(n, &Default::default(), 1)?;
            results.push(StageResult::new(
                "relaxation",
                &format!("{n} vehicles, 0.3 m/px network"),
                n as u64,
                "vehicles",
                r.build_s + r.solve_s,
            ));
        }
    }
    if want(Stage::Mrf) {
        bar.set_message("mrf");
        let cfg = roadtrack::track::mrf::MrfConfig::default();
        let b = bench::mrf::bench_mrf(&cfg, &generated, 1, 0)?;
        results.push(StageResult::new(
            "mrf",
            "generated 640×480, 1 thread",
            u64::from(b.frames),
            "frames",
            b.seconds,
        ));
        if have_video {
            let (_, frames) = bench::load_frames(&args.video, 200, args.bad.policy())?;
            let b = bench::mrf::bench_mrf(&cfg, &frames, 1, 0)?;
            results.push(StageResult::new(
                "mrf",
                "vtest.avi 768×576, 1 thread",
                u64::from(b.frames),
                "frames",
                b.seconds,
            ));
        }
    }
    if want(Stage::Filters) {
        bar.set_message("filters");
        let reports = bench::filters::bench_filters(&Default::default(), &mut |_, _| {})?;
        for r in reports {
            results.push(StageResult::new(
                "filter",
                &format!("{} ({} particles)", r.name, r.particles),
                r.frames,
                "frames",
                r.total_ms * r.frames as f64 / 1000.0,
            ));
        }
    }
    #[cfg(not(feature = "cnn"))]
    if want(Stage::Cnn) {
        ui.info("note: built without the `cnn` feature; skipping the cnn stage");
    }
    #[cfg(feature = "cnn")]
    if want(Stage::Cnn) {
        bar.set_message("cnn");
        let ssd = roadtrack_cnn::ssd::default_model_path().filter(|p| p.is_file());
        if ssd.is_none() {
            ui.info("note: SSD model absent (scripts/setup.sh --models); skipping the SSD rows");
        }
        let cfg = bench::filters::FilterBenchConfig::default();
        let (stages, phd) = bench::cnn::bench_cnn(&cfg, ssd.as_deref(), &mut |_, _| {})?;
        results.extend(stages);
        for r in phd {
            let stages = [
                ("predict", r.predict_ms),
                ("likelihood", r.likelihood_ms),
                ("update", r.update_ms),
                ("labels", r.labels_ms),
                ("resample", r.resample_ms),
                ("total", r.total_ms),
            ];
            for (stage, ms) in stages {
                results.push(StageResult::new(
                    &format!("{} {stage}", r.name),
                    &format!(
                        "{}×{}, {} targets × {} ({} particles)",
                        cfg.width, cfg.height, cfg.targets, cfg.particles_per_object, r.particles
                    ),
                    r.frames,
                    "frames",
                    ms * r.frames as f64 / 1000.0,
                ));
            }
        }
    }
    bar.finish_and_clear();

    if args.json {
        let v =
            serde_json::json!({ "machine": machine, "build": build_profile(), "stages": results });
        crate::common::print_out(&format!("{}\n", serde_json::to_string_pretty(&v)?))?;
    } else {
        use std::fmt::Write as _;
        let mut text = format!(
            "machine: {} ({} cores, {} rayon threads), {} build\n",
            machine.cpu,
            machine.cores,
            machine.rayon_threads,
            build_profile()
        );
        // Columns as wide as their longest entry (stage names run from "decode" to
        // "PHD, CNN dense stride 8 likelihood").
        let ws = results
            .iter()
            .map(|r| r.stage.chars().count())
            .max()
            .unwrap_or(0)
            .max(5);
        let wi = results
            .iter()
            .map(|r| r.input.chars().count())
            .max()
            .unwrap_or(0)
            .max(5);
        let _ = writeln!(
            text,
            "{:<ws$} {:<wi$} {:>8} {:>9} {:>12}",
            "stage", "input", "items", "seconds", "per second"
        );
        for r in &results {
            let _ = writeln!(
                text,
                "{:<ws$} {:<wi$} {:>8} {:>9.3} {:>8.1} {}",
                r.stage, r.input, r.items, r.seconds, r.per_second, r.unit
            );
        }
        crate::common::print_out(&text)?;
    }
    Ok(())
}

fn build_profile() -> &'static str {
    if cfg!(debug_assertions) {
        "dev-profile (opt-level 1, dependencies 3)"
    } else {
        "release"
    }
}
