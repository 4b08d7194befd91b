//! `roadtrack demo`: the built-in example. Simulates a signalised intersection with
//! pedestrians over a whole signal cycle, runs every tracking method on it, evaluates each
//! against the simulator's ground truth, and writes overlays, plots, a traffic analysis and
//! a one-page report (`report.rs`) that leads with the best method and sets each method's
//! counts and turning movements beside the truth's.

mod report;

use crate::common::DetectorArgs;
use crate::overlay::OverlaySink;
use anyhow::{Context, Result};
use roadtrack::analysis::ground::{GroundStage, OffGroundFilter};
use roadtrack::analysis::{self, Analysis, Coordinates, CountLine, Site, StitchConfig, Zone};
use roadtrack::calibration::Calibration;
use roadtrack::eval::{self, ClassMode, EvalConfig};
use roadtrack::io::{self, SourceOptions, mot, sink, source};
use roadtrack::track::confirm::{LifecycleConfig, LifecycleStage};
use roadtrack::track::pipeline::{MotSink, TrajectoriesSink};
use roadtrack::track::relaxation::tracker::RelaxationTrackerConfig;
use roadtrack::track::replay::ReplayTracker;
use roadtrack::track::{Method, MethodConfig, Pipeline, track_source};
use roadtrack::track_point::TrackPoint;
use roadtrack_sim::config::IntersectionSignalConfig;
use roadtrack_sim::{IntersectionConfig, SceneKind, SimConfig, ViewKind};
use roadtrack_viz::render::RenderConfig;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The demo's frame rate, frames/s.
pub const DEFAULT_FPS: f64 = 10.0;
/// The demo's frames by default: one signal cycle of [`demo_signal`] and a little more.
pub const DEFAULT_FRAMES: u32 = 700;

/// What the demo runs.
#[derive(Debug, Clone)]
pub struct DemoConfig {
    /// Frames to simulate. Default [`DEFAULT_FRAMES`].
    pub frames: u32,
    /// Frame rate, frames/s. Default [`DEFAULT_FPS`].
    pub fps: f64,
    /// Seed of the simulation and of every stochastic tracker.
    pub seed: u64,
    /// Encode the overlays as MP4 when ffmpeg is available (else PNG frames). Default true.
    pub video: bool,
    /// The detector every method uses (`--detector`; none: each method's own background
    /// detector). `--detector file` reads the simulated sequence's `det/det.txt`.
    pub detector: DetectorArgs,
    /// Relaxation's tracker settings.
    pub relaxation: RelaxationTrackerConfig,
}

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            frames: DEFAULT_FRAMES,
            fps: DEFAULT_FPS,
            seed: 0,
            video: true,
            detector: DetectorArgs::default(),
            relaxation: RelaxationTrackerConfig::default(),
        }
    }
}

/// The demo's signal plan: the simulator's phases (N–S through, N–S left, E–W through,
/// E–W left, pedestrians) with shorter greens, so that one whole cycle fits a demo that
/// runs in a minute.
// Choice: 12 s through, 5 s left, 8 s walk, 3 s yellow and 2 s all-red: a 64 s cycle
// instead of the simulator's 104 s, so that 700 frames at 10 frames/s hold a whole cycle
// wherever the seed starts it (the arrivals per hour are the simulator's).
pub fn demo_signal() -> IntersectionSignalConfig {
    IntersectionSignalConfig {
        through_green_s: 12.0,
        left_green_s: 5.0,
        pedestrian_green_s: 8.0,
        yellow_s: 3.0,
        all_red_s: 2.0,
    }
}

/// The simulation the demo tracks.
pub fn demo_sim_config(frames: u32, fps: f64) -> SimConfig {
    SimConfig {
        scene: SceneKind::Intersection,
        view: ViewKind::Oblique,
        frames,
        fps,
        intersection: IntersectionConfig {
            signal: demo_signal(),
            ..IntersectionConfig::default()
        },
        ..SimConfig::default()
    }
}

/// Length of the demo's signal cycle, s.
pub fn cycle_s(sim: &SimConfig) -> f64 {
    roadtrack_sim::scene::Scene::build(sim, 0.0)
        .signal
        .map_or(0.0, |s| s.cycle_s())
}

/// The scores and traffic counts of one method.
#[derive(Debug, Clone, Serialize)]
pub struct MethodResult {
    /// Method name.
    pub method: String,
    /// Track ids found.
    pub tracks: usize,
    /// Boxes written.
    pub boxes: usize,
    /// Wall time of tracking, s.
    pub seconds: f64,
    /// Class-agnostic CLEAR/identity/HOTA against the simulator's ground truth.
    pub mota: f64,
    /// IDF1.
    pub idf1: f64,
    /// HOTA.
    pub hota: f64,
    /// Identity switches.
    pub idsw: f64,
    /// Complete trips (turning movements), all classes.
    pub trips: u64,
    /// Objects first and last seen in one arm (not turning movements).
    pub incomplete: u64,
    /// Turning-movement error: Σ over movements of |count − truth's| / the truth's trips.
    pub movement_error: Option<f64>,
}

/// What the demo wrote.
#[derive(Debug, Clone, Serialize)]
pub struct DemoReport {
    /// The output folder.
    pub dir: PathBuf,
    /// The report page.
    pub report: PathBuf,
    /// Per method, best (highest HOTA) first.
    pub methods: Vec<MethodResult>,
}

/// One method's run, for the report.
struct MethodRun {
    result: MethodResult,
    analysis: Analysis,
    /// The eval table.
    metrics: String,
    /// File name of the overlay (video or folder).
    overlay: String,
}

/// The methods the demo compares, in the papers' order.
pub fn methods() -> [Method; 4] {
    Method::ALL
}

/// The intersection's approach arms and a counting line per arm, in ground metres
/// (the simulator's intersection is centred on (0, 0) with arms along ±x and ±y).
pub fn intersection_site() -> Site {
    let rect = |x0: f64, x1: f64, y0: f64, y1: f64| vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
    Site {
        coordinates: Coordinates::Ground,
        line: vec![
            CountLine {
                name: "north".into(),
                a: [12.0, 16.0],
                b: [-12.0, 16.0],
            },
            CountLine {
                name: "south".into(),
                a: [-12.0, -16.0],
                b: [12.0, -16.0],
            },
            CountLine {
                name: "east".into(),
                a: [16.0, -12.0],
                b: [16.0, 12.0],
            },
            CountLine {
                name: "west".into(),
                a: [-16.0, 12.0],
                b: [-16.0, -12.0],
            },
        ],
        zone: vec![
            Zone {
                name: "N".into(),
                polygon: rect(-12.0, 12.0, 16.0, 120.0),
            },
            Zone {
                name: "S".into(),
                polygon: rect(-12.0, 12.0, -120.0, -16.0),
            },
            Zone {
                name: "E".into(),
                polygon: rect(16.0, 120.0, -12.0, 12.0),
            },
            Zone {
                name: "W".into(),
                polygon: rect(-120.0, -16.0, -12.0, 12.0),
            },
        ],
        lane: Vec::new(),
        stitch: StitchConfig::default(),
    }
}

/// Runs the demo into `dir`; `step` is told what is being done.
pub fn run_demo(cfg: &DemoConfig, dir: &Path, step: &mut dyn FnMut(&str)) -> Result<DemoReport> {
    if cfg.frames < 20 {
        return Err(roadtrack::Error::config("DemoConfig", "frames", "at least 20 frames").into());
    }
    let seq = dir.join("sequence");
    step("simulating an intersection (oblique camera, vehicles and pedestrians)");
    let sim_cfg = demo_sim_config(cfg.frames, cfg.fps);
    roadtrack_sim::simulate(&sim_cfg, cfg.seed, &seq, &mut |_, _| {})?;
    let fps = sim_cfg.fps;
    let calibration = Calibration::load(&seq.join("calibration.toml"))?;
    let gt = mot::read_gt(&seq.join("gt").join("gt.txt"))?;
    let truth = io::read_truth_points(&seq, fps)?;
    let background = source::open(&seq, &SourceOptions::default())?
        .next()
        .transpose()?
        .map(|f| f.image);
    let eval_cfg = EvalConfig {
        mode: ClassMode::ClassAgnostic,
        num_frames: Some(cfg.frames),
        ..Default::default()
    };
    // Ground-truth counts and turning movements, the yardstick of every method's.
    let mut truth_g = truth.clone();
    analysis::ground::attach_calibration(&mut truth_g, &calibration, None, 0.5)?;
    let truth_analysis = analysis::analyze(&truth_g, &intersection_site())?;
    let mut runs = Vec::new();
    for method in methods() {
        let name = method.name();
        step(&format!("tracking with {name}"));
        let mdir = dir.join(name);
        let config = match MethodConfig::defaults(method, cfg.seed) {
            MethodConfig::Relaxation { detector, .. } => MethodConfig::Relaxation {
                tracker: Box::new(cfg.relaxation.clone()),
                detector,
            },
            other => other,
        }
        .with_calibration(&calibration);
        let own = config.background_detector();
        let detector = cfg
            .detector
            .spec(&seq, || Ok(own))
            .with_context(|| format!("the detector of {name}"))?;
        let t0 = std::time::Instant::now();
        let mut points: Vec<TrackPoint> = Vec::new();
        track_source(
            &seq,
            &SourceOptions::default(),
            config,
            detector,
            vec![
                Box::new(LifecycleStage::new(LifecycleConfig::default())?),
                Box::new(OffGroundFilter::new(&calibration, None)),
                Box::new(GroundStage::new(&calibration, None, 0.5)?),
            ],
            vec![
                Box::new(MotSink::create(&mdir.join("tracks.txt"))?),
                Box::new(TrajectoriesSink::create(
                    &mdir.join("trajectories.csv"),
                    true,
                )?),
                Box::new(&mut points),
            ],
            &mut |_, _| {},
        )?;
        let seconds = t0.elapsed().as_secs_f64();
        let (rows, _) = eval::rows_from_points(&points);
        let scores = eval::evaluate(&gt, &rows, &eval_cfg)?;
        let metrics = eval::format_table(&scores);
        roadtrack::io::atomic::write_bytes_atomic(&mdir.join("metrics.txt"), metrics.as_bytes())?;
        step(&format!("rendering {name}"));
        let video = cfg.video && roadtrack::io::video::ffmpeg_available();
        let overlay = if video {
            mdir.join("overlay.mp4")
        } else {
            mdir.join("overlay")
        };
        // The overlay, and a still of the middle frame with the trails built up to it.
        let mut sink = OverlaySink::new(
            &RenderConfig::default(),
            Some(&truth),
            sink::open_sink(&overlay, fps)?,
        )?;
        sink.keep_still(cfg.frames / 2);
        let mut render = Pipeline::new(Box::new(ReplayTracker::new(points.clone())));
        render.sinks.push(Box::new(&mut sink));
        render.run(
            source::open(&seq, &SourceOptions::default())?,
            None,
            &mut |_, _| {},
        )?;
        drop(render);
        if let Some(img) = sink.take_still() {
            let still = mdir.join("overlay_frame.png");
            roadtrack::io::atomic::write_bytes_atomic(&still, &sink::encode_png(&img, &still)?)?;
        }
        roadtrack_viz::plot::plot_trajectories(
            &points,
            background.as_ref(),
            &roadtrack_viz::plot::PlotConfig {
                title: Some(format!("{name}: trajectories")),
                ..Default::default()
            },
            &mdir.join("trajectories.png"),
        )?;
        let analysis = analysis::analyze(&points, &intersection_site())?;
        roadtrack::io::atomic::write_bytes_atomic(
            &mdir.join("analysis.json"),
            to_json(&analysis)?.as_bytes(),
        )?;
        let s = &scores.summary;
        let result = MethodResult {
            method: name.to_owned(),
            tracks: points
                .iter()
                .map(|p| p.id)
                .collect::<std::collections::BTreeSet<_>>()
                .len(),
            boxes: points.len(),
            seconds,
            mota: s.clear.MOTA,
            idf1: s.identity.IDF1,
            hota: s.hota.HOTA,
            idsw: s.clear.IDSW as f64,
            trips: report::trips(&analysis),
            incomplete: analysis.od_incomplete.iter().map(|o| o.count).sum(),
            movement_error: report::movement_error(&analysis, &truth_analysis),
        };
        runs.push(MethodRun {
            result,
            analysis,
            metrics,
            overlay: overlay
                .file_name()
                .map_or(String::new(), |f| f.to_string_lossy().into_owned()),
        });
    }
    // Best first. Choice: ties in HOTA keep the papers' order (a stable sort).
    runs.sort_by(|a, b| b.result.hota.total_cmp(&a.result.hota));
    let facts = report::Facts {
        frames: cfg.frames,
        fps,
        seed: cfg.seed,
        cycle_s: cycle_s(&sim_cfg),
        detector: crate::cmd::render::detector_name(&cfg.detector),
        detector_given: cfg.detector.detector.is_some() || cfg.detector.is_file(),
    };
    let page = report::page(&facts, &truth_analysis, &runs);
    let report = dir.join("report.md");
    roadtrack::io::atomic::write_bytes_atomic(&report, page.as_bytes())?;
    let results: Vec<MethodResult> = runs.into_iter().map(|r| r.result).collect();
    roadtrack::io::atomic::write_bytes_atomic(
        &dir.join("summary.json"),
        to_json(&report::Summary {
            facts: &facts,
            truth_trips: report::trips(&truth_analysis),
            truth_incomplete: truth_analysis.od_incomplete.iter().map(|o| o.count).sum(),
            methods: &results,
        })?
        .as_bytes(),
    )?;
    Ok(DemoReport {
        dir: dir.to_owned(),
        report,
        methods: results,
    })
}

fn to_json<T: Serialize>(value: &T) -> Result<String> {
    Ok(serde_json::to_string_pretty(value).context("writing JSON")?)
}
