//! Seed 004's experiments on image sequences (docs/EXPERIMENTS.md "Filters on image
//! sequences"): the particle filter and the labelled SMC-PHD filter with the colour
//! likelihood, started and fed by the foreground detector, on simulator scenes with known
//! truth, and the PHD filter on `vtest.avi`.
//!
//! ```text
//! cargo run --release -p roadtrack --example filter_experiments -- sim OUT_DIR [FRAMES] [SEEDS]
//! cargo run --release -p roadtrack --example filter_experiments -- vtest VIDEO OUT_DIR [FRAMES]
//! ```
//!
//! `sim` writes `OUT_DIR/runs.json` (every run) and `OUT_DIR/tables.md` (means over seeds);
//! `vtest` writes `OUT_DIR/counts.csv`, `OUT_DIR/phd_vtest_count.png` and overlays
//! `OUT_DIR/overlay_NNNNNN.png`.
//! With `FX_LIKELIHOOD=ssd`, `vtest` uses the SSDLite pedestrian detector (dense, after
//! `scripts/setup.sh --models`) instead of the colour likelihood.

use roadtrack::calibration::Calibration;
use roadtrack::class::ObjectClass;
use roadtrack::detect::background::BackgroundDetector;
use roadtrack::detection::Detection;
use roadtrack::eval::papers::{
    DetectionTable, LabelledPoint, RmseConfig, detection_table, trajectory_rmse,
};
use roadtrack::eval::{ClassMode, EvalConfig, evaluate, rows_from_points};
use roadtrack::frame::Frame;
use roadtrack::geometry::Point;
use roadtrack::io::source::{self, SourceOptions};
use roadtrack::likelihood::Likelihood;
use roadtrack::track::filter::config::LikelihoodKind;
use roadtrack::track::filter::motion::ConstantVelocity;
use roadtrack::track::filter::phd::FilterStageTimes;
use roadtrack::track::filter::{FilterMethod, FilterTrackConfig, FilterTracker, FrameCount};
use roadtrack::track::pipeline::run_frames;
use roadtrack::track_point::TrackPoint;
use roadtrack_sim::{SceneKind, SimConfig, Simulation, TruthRow, ViewKind, gt_rows};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// Distance gate of the detection table, px.
// Choice: the paper does not state its gate; 25 px is about half a car's length and a
// pedestrian's width in the 640 × 480 scenes.
const GATE_PX: f64 = 25.0;

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("sim") => {
            let out = PathBuf::from(args.get(1).ok_or("sim OUT_DIR [FRAMES] [SEEDS]")?);
            let frames: u32 = args.get(2).map_or(Ok(200), |s| s.parse())?;
            let seeds: u64 = args.get(3).map_or(Ok(3), |s| s.parse())?;
            sim(&out, frames, seeds)
        }
        Some("vtest") => {
            let video = PathBuf::from(args.get(1).ok_or("vtest VIDEO OUT_DIR [FRAMES]")?);
            let out = PathBuf::from(args.get(2).ok_or("vtest VIDEO OUT_DIR [FRAMES]")?);
            let frames: Option<u32> = args.get(3).map(|s| s.parse()).transpose()?;
            vtest(&video, &out, frames)
        }
        _ => Err(
            "usage: filter_experiments sim OUT_DIR [FRAMES] [SEEDS] | vtest VIDEO OUT_DIR [FRAMES]"
                .into(),
        ),
    }
}

/// One simulator setting.
struct Setting {
    name: &'static str,
    sim: SimConfig,
    /// MOT17 classes evaluated (class-agnostic).
    classes: Vec<u32>,
    pedestrians: bool,
}

fn settings(frames: u32) -> Vec<Setting> {
    let base = SimConfig {
        frames,
        ..Default::default()
    };
    let mut road_aerial = base.clone();
    road_aerial.scene = SceneKind::Road;
    road_aerial.view = ViewKind::Aerial;
    let mut road_oblique = road_aerial.clone();
    road_oblique.view = ViewKind::Oblique;
    let mut inter = base.clone();
    inter.scene = SceneKind::Intersection;
    inter.view = ViewKind::Oblique;
    // Vehicles only: the experiment is the paper's vehicle tracking.
    inter.intersection.pedestrian_groups_per_min_per_entry = 0.0;
    let mut crossing = base;
    crossing.scene = SceneKind::Crossing;
    crossing.view = ViewKind::Oblique;
    // Pedestrians only (the paper's pedestrian videos have no traffic).
    crossing.crossing.inflow_veh_per_h_per_direction = 0.0;
    let veh = vec![3, 4, 5, 6];
    vec![
        Setting {
            name: "road / aerial (vehicles)",
            sim: road_aerial,
            classes: veh.clone(),
            pedestrians: false,
        },
        Setting {
            name: "road / oblique (vehicles)",
            sim: road_oblique,
            classes: veh.clone(),
            pedestrians: false,
        },
        Setting {
            name: "intersection / oblique (vehicles)",
            sim: inter,
            classes: veh,
            pedestrians: false,
        },
        Setting {
            name: "crossing / oblique (pedestrians)",
            sim: crossing,
            classes: vec![1],
            pedestrians: true,
        },
    ]
}

/// The tracker config of a setting: the paper's parameters, pedestrians with σ = 0.2·|v|.
fn track_config(pedestrians: bool, kind: LikelihoodKind) -> FilterTrackConfig {
    let mut cfg = FilterTrackConfig {
        // The image likelihoods are what these tables compare.
        measurements: roadtrack::track::filter::Measurements::Image,
        ..FilterTrackConfig::default()
    };
    cfg.likelihood.kind = kind;
    if pedestrians {
        cfg.pf.motion = ConstantVelocity::proportional(0.2, 1.0);
        cfg.phd.motion = ConstantVelocity::proportional(0.2, 1.0);
        cfg.pf.class = ObjectClass::Pedestrian;
        cfg.phd.class = ObjectClass::Pedestrian;
    } else {
        cfg.pf.class = ObjectClass::Car;
        cfg.phd.class = ObjectClass::Car;
    }
    cfg
}

#[derive(Debug, Serialize)]
struct Run {
    setting: String,
    seed: u64,
    method: String,
    frames: u32,
    truth_objects: u64,
    detection: DetectionTable,
    /// Track ids never matched to a truth object within the gate.
    false_tracks: u64,
    tracks: u64,
    rmse_px: f64,
    rmse_x_px: f64,
    rmse_y_px: f64,
    speed_rmse_px_s: f64,
    rmse_m: f64,
    speed_rmse_kmh: f64,
    mota: f64,
    idf1: f64,
    hota: f64,
    mean_true_count: f64,
    mean_expected_count: f64,
    count_mae: f64,
    filter_ms_per_frame: f64,
    detect_ms_per_frame: f64,
}

fn centres(points: &[TrackPoint]) -> Vec<LabelledPoint> {
    points
        .iter()
        .map(|p| LabelledPoint {
            frame: p.frame,
            id: p.id,
            pos_px: p.bbox.centre(),
        })
        .collect()
}

/// The ground point of a box: its centre from above, its bottom centre from the side.
fn foot_points(points: &[TrackPoint], aerial: bool) -> Vec<LabelledPoint> {
    points
        .iter()
        .map(|p| {
            let c = p.bbox.centre();
            LabelledPoint {
                frame: p.frame,
                id: p.id,
                pos_px: if aerial {
                    c
                } else {
                    Point::new(c.x, c.y + p.bbox.height / 2.0)
                },
            }
        })
        .collect()
}

/// What one filter run produced.
struct FilterRun {
    points: Vec<TrackPoint>,
    counts: Vec<FrameCount>,
    detections: Vec<Detection>,
    stage_times: FilterStageTimes,
    detect_s: f64,
    window_px: Option<(u32, u32)>,
}

/// Runs `method` over `frames` through the tracking pipeline, timing the detector and
/// keeping its detections and the filter's per-frame counts.
fn run_filter(
    method: FilterMethod,
    cfg: &FilterTrackConfig,
    mut detector: BackgroundDetector,
    frames: impl Iterator<Item = roadtrack::Result<Frame>>,
    seed: u64,
    model: Option<Box<dyn Likelihood>>,
) -> Res<FilterRun> {
    let (mut detections, mut detect_s) = (Vec::new(), 0.0);
    let timed = |f: &Frame| {
        let t0 = Instant::now();
        let found = detector.detect_with_mask(f)?;
        detect_s += t0.elapsed().as_secs_f64();
        detections.extend(found.detections.iter().cloned());
        Ok(found)
    };
    let mut tracker = FilterTracker::new(method, cfg, seed, model)?;
    tracker.record_counts();
    let points = run_frames(Some(Box::new(timed)), Box::new(&mut tracker), frames)?;
    Ok(FilterRun {
        points,
        counts: tracker.counts().to_vec(),
        detections,
        stage_times: tracker.stage_times(),
        detect_s,
        window_px: tracker.window_px(),
    })
}

fn run_one(setting: &Setting, seed: u64, method: FilterMethod, kind: LikelihoodKind) -> Res<Run> {
    let cfg = track_config(setting.pedestrians, kind);
    let n = setting.sim.frames;
    let boot = Simulation::new(&setting.sim, seed)?.map(|s| s.map(|s| s.frame));
    let detector = BackgroundDetector::bootstrap(cfg.detector.clone(), boot, Some(n))?;
    let sim = Simulation::new(&setting.sim, seed)?;
    let calibration: Calibration = sim.calibration().clone();
    let mut truth: Vec<TruthRow> = Vec::new();
    let frames = sim.map(|s| {
        s.map(|s| {
            truth.extend(s.truth);
            s.frame
        })
    });
    let t0 = Instant::now();
    let out = run_filter(method, &cfg, detector, frames, seed, None)?;
    let _ = t0;
    // Only objects a foreground detector can see count as truth: at least 30 % visible
    // (the simulator's own detector's rule) and at least the detector's smallest region.
    let min_area = f64::from(cfg.detector.regions.min_area_px);
    let detectable = |t: &TruthRow| t.visibility >= 0.3 && t.bbox.width * t.bbox.height >= min_area;
    let mut gt = gt_rows(&truth);
    for (g, t) in gt.iter_mut().zip(&truth) {
        g.consider = detectable(t);
    }
    truth.retain(detectable);
    let truth_pts: Vec<TrackPoint> = truth.iter().map(TruthRow::to_track_point).collect();
    if std::env::var_os("FX_DEBUG").is_some() {
        let dets: Vec<LabelledPoint> = out
            .detections
            .iter()
            .map(|d| LabelledPoint {
                frame: d.frame,
                id: d.id,
                pos_px: d.pos_px,
            })
            .collect();
        let t = detection_table(&centres(&truth_pts), &dets, GATE_PX)?;
        eprintln!("  raw detections: {t:?}");
        for c in out.counts.iter().step_by(10) {
            eprintln!("  {c:?}");
        }
    }
    let det = detection_table(&centres(&truth_pts), &centres(&out.points), GATE_PX)?;
    let rev = detection_table(&centres(&out.points), &centres(&truth_pts), GATE_PX)?;
    let rcfg = RmseConfig {
        fps: setting.sim.fps,
        ..Default::default()
    };
    let px = trajectory_rmse(&centres(&truth_pts), &centres(&out.points), &rcfg, None)?;
    let aerial = setting.sim.view == ViewKind::Aerial;
    let g = |p: Point| -> Point {
        calibration
            .ground_from_image(p)
            .map_or(Point::new(f64::NAN, f64::NAN), |(x, y)| Point::new(x, y))
    };
    let ground = trajectory_rmse(
        &foot_points(&truth_pts, aerial),
        &foot_points(&out.points, aerial),
        &rcfg,
        Some(&g),
    )?;
    let gm = ground.ground.unwrap_or_default();
    let eval = evaluate(
        &gt,
        &rows_from_points(&out.points).0,
        &EvalConfig {
            mode: ClassMode::ClassAgnostic,
            classes: setting.classes.clone(),
            num_frames: Some(n),
            ..Default::default()
        },
    )?;
    let s = &eval.summary;
    let mut true_count = vec![0usize; n as usize + 1];
    for t in &truth {
        if let Some(c) = true_count.get_mut(t.frame as usize) {
            *c += 1;
        }
    }
    let (mut sum_t, mut sum_e, mut sum_abs) = (0.0, 0.0, 0.0);
    for c in &out.counts {
        let t = true_count.get(c.frame as usize).copied().unwrap_or(0) as f64;
        sum_t += t;
        sum_e += c.expected;
        sum_abs += (c.expected - t).abs();
    }
    let nf = out.counts.len().max(1) as f64;
    let tracks = out
        .points
        .iter()
        .map(|p| p.id)
        .collect::<std::collections::BTreeSet<_>>()
        .len() as u64;
    Ok(Run {
        setting: setting.name.to_owned(),
        seed,
        method: format!(
            "{} {}",
            format!("{method:?}").to_uppercase(),
            match kind {
                LikelihoodKind::Colour => "colour",
                LikelihoodKind::Foreground => "foreground",
                LikelihoodKind::ColourForeground => "colour × foreground",
            }
        ),
        frames: n,
        truth_objects: det.objects,
        detection: det,
        false_tracks: rev.objects - rev.objects_detected,
        tracks,
        rmse_px: px.px.position,
        rmse_x_px: px.px.x,
        rmse_y_px: px.px.y,
        speed_rmse_px_s: px.px.speed,
        rmse_m: gm.position,
        speed_rmse_kmh: gm.speed,
        mota: s.clear.MOTA,
        idf1: s.identity.IDF1,
        hota: s.hota.HOTA,
        mean_true_count: sum_t / nf,
        mean_expected_count: sum_e / nf,
        count_mae: sum_abs / nf,
        filter_ms_per_frame: out.stage_times.total().as_secs_f64() * 1e3 / nf,
        detect_ms_per_frame: out.detect_s * 1e3 / nf,
    })
}

fn sim(out: &Path, frames: u32, seeds: u64) -> Res<()> {
    std::fs::create_dir_all(out)?;
    let mut runs = Vec::new();
    for setting in settings(frames) {
        for seed in 1..=seeds {
            for (method, kind) in [
                (FilterMethod::Pf, LikelihoodKind::Colour),
                (FilterMethod::Phd, LikelihoodKind::Colour),
                (FilterMethod::Pf, LikelihoodKind::ColourForeground),
                (FilterMethod::Phd, LikelihoodKind::ColourForeground),
            ] {
                let t0 = Instant::now();
                let r = run_one(&setting, seed, method, kind)?;
                eprintln!(
                    "{} seed {seed} {}: MOTA {:.3} IDF1 {:.3} HOTA {:.3} TP {} FP {} FN {} \
                     rmse {:.1} px {:.2} m, count {:.2}/{:.2} ({:.1} s)",
                    setting.name,
                    r.method,
                    r.mota,
                    r.idf1,
                    r.hota,
                    r.detection.tp,
                    r.detection.fp,
                    r.detection.fn_,
                    r.rmse_px,
                    r.rmse_m,
                    r.mean_expected_count,
                    r.mean_true_count,
                    t0.elapsed().as_secs_f64()
                );
                runs.push(r);
            }
        }
    }
    roadtrack::io::write_atomic(&out.join("runs.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &runs).map_err(std::io::Error::other)?;
        Ok(())
    })?;
    let md = tables(&runs, frames, seeds);
    roadtrack::io::write_atomic(&out.join("tables.md"), |w| w.write_all(md.as_bytes()))?;
    print!("{md}");
    Ok(())
}

fn mean(runs: &[&Run], f: impl Fn(&Run) -> f64) -> f64 {
    runs.iter().map(|r| f(r)).sum::<f64>() / runs.len().max(1) as f64
}

fn tables(runs: &[Run], frames: u32, seeds: u64) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let mut groups: Vec<(String, String)> = Vec::new();
    for r in runs {
        let k = (r.setting.clone(), r.method.clone());
        if !groups.contains(&k) {
            groups.push(k);
        }
    }
    let _ = writeln!(
        s,
        "Means over seeds 1–{seeds}, {frames} frames each (10 frames/s, 640 × 480). \
         Detection counts are summed over seeds; gate {GATE_PX} px.\n"
    );
    let _ = writeln!(
        s,
        "| scene | method | truth objects | objects tracked | false tracks | TP | FP | FN | precision | recall |"
    );
    let _ = writeln!(
        s,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for (setting, method) in &groups {
        let g: Vec<&Run> = runs
            .iter()
            .filter(|r| &r.setting == setting && &r.method == method)
            .collect();
        let sum = |f: &dyn Fn(&Run) -> u64| g.iter().map(|r| f(r)).sum::<u64>();
        let (tp, fp, fn_) = (
            sum(&|r| r.detection.tp),
            sum(&|r| r.detection.fp),
            sum(&|r| r.detection.fn_),
        );
        let _ = writeln!(
            s,
            "| {setting} | {method} | {} | {} | {} | {tp} | {fp} | {fn_} | {:.3} | {:.3} |",
            sum(&|r| r.truth_objects),
            sum(&|r| r.detection.objects_detected),
            sum(&|r| r.false_tracks),
            tp as f64 / (tp + fp).max(1) as f64,
            tp as f64 / (tp + fn_).max(1) as f64,
        );
    }
    let _ = writeln!(
        s,
        "\n| scene | method | RMSE x px | RMSE y px | RMSE px | speed RMSE px/s | RMSE m | speed RMSE km/h | MOTA | IDF1 | HOTA | mean count (true) | count MAE | filter ms/frame |"
    );
    let _ = writeln!(
        s,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for (setting, method) in &groups {
        let g: Vec<&Run> = runs
            .iter()
            .filter(|r| &r.setting == setting && &r.method == method)
            .collect();
        let _ = writeln!(
            s,
            "| {setting} | {method} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {:.1} | {:.3} | {:.3} | {:.3} | {:.2} ({:.2}) | {:.2} | {:.1} |",
            mean(&g, |r| r.rmse_x_px),
            mean(&g, |r| r.rmse_y_px),
            mean(&g, |r| r.rmse_px),
            mean(&g, |r| r.speed_rmse_px_s),
            mean(&g, |r| r.rmse_m),
            mean(&g, |r| r.speed_rmse_kmh),
            mean(&g, |r| r.mota),
            mean(&g, |r| r.idf1),
            mean(&g, |r| r.hota),
            mean(&g, |r| r.mean_expected_count),
            mean(&g, |r| r.mean_true_count),
            mean(&g, |r| r.count_mae),
            mean(&g, |r| r.filter_ms_per_frame),
        );
    }
    s
}

fn vtest(video: &Path, out: &Path, frames: Option<u32>) -> Res<()> {
    std::fs::create_dir_all(out)?;
    let options = SourceOptions {
        end: frames,
        ..Default::default()
    };
    let mut cfg = track_config(true, LikelihoodKind::Colour);
    if std::env::var("FX_KIND").is_ok_and(|k| k == "colour_foreground") {
        cfg.likelihood.kind = LikelihoodKind::ColourForeground;
    }
    // FX_LIKELIHOOD=ssd: the SSDLite pedestrian detector (dense) instead of the colour
    // histogram (docs/EXPERIMENTS.md "CNN likelihoods in the trackers").
    let ssd = std::env::var("FX_LIKELIHOOD").is_ok_and(|k| k == "ssd");
    let model = if ssd {
        use roadtrack_cnn::model::{ModelKind, ModelSpec, load_model_likelihood};
        load_model_likelihood(&ModelSpec {
            kind: ModelKind::Ssd,
            ..Default::default()
        })?
    } else {
        None
    };
    let t0 = Instant::now();
    let detector = BackgroundDetector::bootstrap_source(cfg.detector.clone(), video, &options)?;
    let run = run_filter(
        FilterMethod::Phd,
        &cfg,
        detector,
        source::open(video, &options)?,
        1,
        model,
    )?;
    let wall = t0.elapsed().as_secs_f64();
    let n = run.counts.len().max(1) as f64;
    eprintln!(
        "{} frames in {wall:.1} s: filter {:.1} ms/frame, detection {:.1} ms/frame, window {:?}",
        run.counts.len(),
        run.stage_times.total().as_secs_f64() * 1e3 / n,
        run.detect_s * 1e3 / n,
        run.window_px
    );
    let mut csv = String::from("frame,expected_count,reported,detections\n");
    for c in &run.counts {
        csv.push_str(&format!(
            "{},{:.4},{},{}\n",
            c.frame, c.expected, c.reported, c.detections
        ));
    }
    roadtrack::io::write_atomic(&out.join("counts.csv"), |w| w.write_all(csv.as_bytes()))?;
    let mean = |f: &dyn Fn(&FrameCount) -> f64| run.counts.iter().map(f).sum::<f64>() / n;
    eprintln!(
        "mean expected count {:.2}, reported {:.2}, detections {:.2}; {} track ids",
        mean(&|c| c.expected),
        mean(&|c| c.reported as f64),
        mean(&|c| c.detections as f64),
        run.points
            .iter()
            .map(|p| p.id)
            .collect::<std::collections::BTreeSet<_>>()
            .len()
    );
    use roadtrack_viz::plot::{Series, line_chart};
    let series = vec![
        Series {
            label: "PHD expected count (Σ weights)".into(),
            points: run
                .counts
                .iter()
                .map(|c| (f64::from(c.frame), c.expected))
                .collect(),
        },
        Series {
            label: "tracks reported".into(),
            points: run
                .counts
                .iter()
                .map(|c| (f64::from(c.frame), c.reported as f64))
                .collect(),
        },
        Series {
            label: "foreground detections".into(),
            points: run
                .counts
                .iter()
                .map(|c| (f64::from(c.frame), c.detections as f64))
                .collect(),
        },
    ];
    line_chart(
        &series,
        if ssd {
            "vtest.avi: labelled SMC-PHD filter, SSDLite likelihood"
        } else {
            "vtest.avi: labelled SMC-PHD filter, colour likelihood"
        },
        "frame",
        "objects",
        &out.join("phd_vtest_count.png"),
    )?;
    // Overlays of a few frames.
    let wanted = [50u32, 150, 300, 450];
    let mut renderer = roadtrack_viz::render::Renderer::new(Default::default())?;
    let by_frame = roadtrack_viz::render::group_by_frame(&run.points);
    for frame in source::open(video, &options)? {
        let frame = frame?;
        let pts = by_frame.get(&frame.index).cloned().unwrap_or_default();
        let img = renderer.render(&frame, &pts);
        if wanted.contains(&frame.index) {
            img.save(out.join(format!("overlay_{:06}.png", frame.index)))?;
        }
    }
    Ok(())
}
