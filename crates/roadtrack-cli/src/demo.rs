//! `roadtrack demo`: the built-in example. Simulates a signalised intersection with
//! pedestrians, runs every tracking method on it, evaluates each against the simulator's
//! ground truth, and writes overlays, plots, a traffic analysis and a one-page report.

use crate::overlay::OverlaySink;
use roadtrack::analysis::ground::GroundStage;
use roadtrack::analysis::{self, Coordinates, CountLine, Site, StitchConfig, Zone};
use roadtrack::calibration::Calibration;
use roadtrack::error::{Error, Result};
use roadtrack::eval::{self, ClassMode, EvalConfig};
use roadtrack::io::{self, SourceOptions, mot, sink, source};
use roadtrack::track::confirm::{LifecycleConfig, LifecycleStage};
use roadtrack::track::pipeline::{MotSink, TrajectoriesSink};
use roadtrack::track::replay::ReplayTracker;
use roadtrack::track::{Method, MethodConfig, Pipeline, track_source};
use roadtrack::track_point::TrackPoint;
use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
use roadtrack_viz::render::RenderConfig;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What the demo runs.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoConfig {
    /// Frames to simulate. Default 150 (15 s at 10 fps).
    pub frames: u32,
    /// Seed of the simulation and of every stochastic tracker.
    pub seed: u64,
    /// Encode the overlays as MP4 when ffmpeg is available (else PNG frames). Default true.
    pub video: bool,
}

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            frames: 150,
            seed: 0,
            video: true,
        }
    }
}

/// The scores of one method.
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
}

/// What the demo wrote.
#[derive(Debug, Clone, Serialize)]
pub struct DemoReport {
    /// The output folder.
    pub dir: PathBuf,
    /// The report page.
    pub report: PathBuf,
    /// Per method.
    pub methods: Vec<MethodResult>,
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
        return Err(Error::config("DemoConfig", "frames", "at least 20 frames"));
    }
    let seq = dir.join("sequence");
    step("simulating an intersection (oblique camera, vehicles and pedestrians)");
    let sim_cfg = SimConfig {
        scene: SceneKind::Intersection,
        view: ViewKind::Oblique,
        frames: cfg.frames,
        ..Default::default()
    };
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
    let mut results = Vec::new();
    let mut sections = String::new();
    for method in methods() {
        let name = method.name();
        step(&format!("tracking with {name}"));
        let mdir = dir.join(name);
        let t0 = std::time::Instant::now();
        let mut points: Vec<TrackPoint> = Vec::new();
        track_source(
            &seq,
            &SourceOptions::default(),
            MethodConfig::defaults(method, cfg.seed).with_calibration(&calibration),
            None,
            vec![
                Box::new(LifecycleStage::new(LifecycleConfig::default())?),
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
        let report = eval::evaluate(&gt, &rows, &eval_cfg)?;
        roadtrack::io::atomic::write_bytes_atomic(
            &mdir.join("metrics.txt"),
            eval::format_table(&report).as_bytes(),
        )?;
        let s = &report.summary;
        results.push(MethodResult {
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
        });
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
            serde_json::to_string_pretty(&analysis)
                .map_err(|e| Error::Invalid(e.to_string()))?
                .as_bytes(),
        )?;
        let _ = writeln!(sections, "\n## {name}\n");
        let _ = writeln!(sections, "![{name} overlay]({name}/overlay_frame.png)\n");
        let _ = writeln!(
            sections,
            "Left: tracks; right: ground truth. Full sequence: `{name}/{}`.\n",
            overlay
                .file_name()
                .map_or(String::new(), |f| f.to_string_lossy().into_owned())
        );
        let _ = writeln!(
            sections,
            "![{name} trajectories]({name}/trajectories.png)\n"
        );
        let _ = writeln!(
            sections,
            "Turning movements (complete trips per origin → destination arm):\n"
        );
        let _ = writeln!(
            sections,
            "| origin | destination | class | count |\n| --- | --- | --- | --- |"
        );
        od_table(&mut sections, &analysis);
        let _ = writeln!(sections, "\n```text\n{}```", eval::format_table(&report));
    }
    // Ground-truth turning movements for comparison.
    let mut truth_g = truth.clone();
    roadtrack::analysis::ground::attach_calibration(&mut truth_g, &calibration, None, 0.5)?;
    let truth_analysis = analysis::analyze(&truth_g, &intersection_site())?;

    let mut page = String::new();
    let _ = writeln!(page, "# roadtrack demo\n");
    let _ = writeln!(
        page,
        "Simulated signalised intersection, oblique camera, {} frames at {fps} fps, seed {}. Ground truth in `sequence/gt/gt.txt`; calibration in `sequence/calibration.toml`. Scores are class-agnostic (the trackers do not classify), TrackEval definitions.\n",
        cfg.frames, cfg.seed
    );
    let _ = writeln!(
        page,
        "| method | tracks | MOTA | IDF1 | HOTA | ID switches | time (s) |\n| --- | --- | --- | --- | --- | --- | --- |"
    );
    for r in &results {
        let _ = writeln!(
            page,
            "| {} | {} | {:.3} | {:.3} | {:.3} | {} | {:.1} |",
            r.method, r.tracks, r.mota, r.idf1, r.hota, r.idsw, r.seconds
        );
    }
    let _ = writeln!(
        page,
        "\nGround-truth turning movements (complete trips):\n\n| origin | destination | class | count |\n| --- | --- | --- | --- |"
    );
    od_table(&mut page, &truth_analysis);
    page.push_str(&sections);
    let report = dir.join("report.md");
    roadtrack::io::atomic::write_bytes_atomic(&report, page.as_bytes())?;
    roadtrack::io::atomic::write_bytes_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&results)
            .map_err(|e| Error::Invalid(e.to_string()))?
            .as_bytes(),
    )?;
    Ok(DemoReport {
        dir: dir.to_owned(),
        report,
        methods: results,
    })
}

/// The complete trips of `a` as table rows (under a header already written), then the
/// objects first and last seen in one arm, apart: they are not turning movements.
fn od_table(out: &mut String, a: &analysis::Analysis) {
    if a.od.is_empty() {
        let _ = writeln!(out, "| (no complete trip in the observed time) | | | 0 |");
    }
    for o in &a.od {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} |",
            o.origin, o.destination, o.class, o.count
        );
    }
    if !a.od_incomplete.is_empty() {
        let list: Vec<String> = a
            .od_incomplete
            .iter()
            .map(|o| format!("{} {} in {}", o.count, o.class, o.origin))
            .collect();
        let _ = writeln!(
            out,
            "\nIncomplete (first and last seen in the same arm, not counted): {}.",
            list.join(", ")
        );
    }
}
