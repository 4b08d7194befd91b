//! `roadtrack evaluate`: tracking metrics with TrackEval's definitions (CLEAR MOT, identity,
//! HOTA) and the papers' own measures (correct-match rate, position / speed RMSE, detection
//! table, occlusion separation success), plus OSPA / GOSPA for point filters.

use crate::common::{Ui, load_config};
use anyhow::{Context, Result};
use roadtrack::calibration::Calibration;
use roadtrack::eval::ospa::{OspaConfig, OspaStep, ospa_series};
use roadtrack::eval::papers::{
    DetectionTable, LabelledPoint, MatchRate, RmseConfig, RmseReport, SeparationBin,
    correct_match_rate, detection_table, points_from_gt, points_from_tracks, separation_success,
    trajectory_rmse,
};
use roadtrack::eval::{
    ClassMode, EvalConfig, EvalReport, evaluate, evaluate_classified, format_table,
    rows_from_points,
};
use roadtrack::geometry::Point;
use roadtrack::io::mot::{MotGtRow, MotTrackRow, read_gt, read_tracks};
use roadtrack::io::seqinfo::SeqInfo;
use roadtrack::io::{
    detections::read_detections, matches::read_matches, occlusion::read_occlusion,
    points::read_estimates, points::read_measurements, trajectories::read_trajectories,
    write_atomic,
};
use serde_json::{Map, Value, json};
use std::path::{Path, PathBuf};

/// Evaluate tracker output against ground truth, or run one of the papers' measures.
///
/// With --truth and --tracks: CLEAR MOT (MOTA, MOTP, TP, FP, FN, IDSW, Frag, MT/PT/ML),
/// identity (IDF1, IDP, IDR) and HOTA (HOTA, DetA, AssA, LocA, …) exactly as TrackEval
/// computes them, with MOTChallenge preprocessing (distractor removal). A readable table by
/// default; --json prints one object whose top-level keys are TrackEval's names. The other
/// measures add sections (JSON keys `rmse`, `detection_table`, `correct_match_rate`,
/// `separation`, `ospa`); those that do not need --tracks run without it.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:\n  \
    roadtrack evaluate --truth seq/ --tracks tracks.txt\n  \
    roadtrack evaluate --truth seq/gt/gt.txt --tracks trajectories.csv --classes per-class --json\n  \
    roadtrack evaluate --truth seq/ --tracks tracks.txt --rmse --calibration calib.toml\n  \
    roadtrack evaluate --truth seq/ --detections detections.csv --gate-px 20\n  \
    roadtrack evaluate --matches matches.csv --match-truth problem/truth.csv\n  \
    roadtrack evaluate --occlusion outcomes.csv\n  \
    roadtrack evaluate --ospa --estimates estimates.csv --truth-points truth.csv --cutoff 20 --order 1")]
pub struct Args {
    /// Ground truth: a MOTChallenge gt.txt, or a sequence folder (its gt/gt.txt; its
    /// seqinfo.ini gives the sequence length and the frame rate).
    #[arg(long, value_name = "GT")]
    pub truth: Option<PathBuf>,
    /// Tracker output: MOTChallenge tracks (.txt) or a trajectories CSV (.csv, whose classes
    /// allow --classes per-class).
    #[arg(
        long,
        value_name = "T",
        requires = "truth",
        required_unless_present_any = ["matches", "detections", "occlusion", "ospa"]
    )]
    pub tracks: Option<PathBuf>,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write the table or JSON here instead of standard output (`-`).
    #[arg(short, long, default_value = "-")]
    pub output: PathBuf,
    /// TOML file with an `EvalConfig` (mode, classes, distractor_classes, preprocess,
    /// iou_threshold, num_frames); flags override it.
    #[arg(long, value_name = "F.toml")]
    pub config: Option<PathBuf>,
    /// Class handling: `pedestrian` (MOT17, default), `per-class` (each class on its own,
    /// tracker classes from a trajectories CSV) or `agnostic` (classes merged).
    #[arg(long, value_enum, value_name = "MODE")]
    pub classes: Option<ClassMode>,
    /// MOT17 class numbers evaluated in per-class and agnostic modes (default 1,3,4,5,6).
    #[arg(long, value_delimiter = ',', value_name = "C,C,…", value_parser = clap::value_parser!(u32).range(1..))]
    pub class_list: Option<Vec<u32>>,
    /// Skip MOTChallenge preprocessing (TrackEval DO_PREPROC = False).
    #[arg(long)]
    pub no_preprocess: bool,
    /// IoU a CLEAR / identity match needs (default 0.5).
    #[arg(long, value_name = "T", value_parser = crate::flags::fraction)]
    pub iou_threshold: Option<f64>,
    /// Sequence length in frames (default: seqinfo.ini's seqLength, else the last frame);
    /// at most 10 000 000.
    #[arg(long, value_name = "N",
        value_parser = clap::value_parser!(u32).range(1..=i64::from(roadtrack::limits::MAX_FRAME)))]
    pub num_frames: Option<u32>,
    /// Also compute position RMSE in x and y and speed RMSE (px, px/s; with --calibration
    /// also m and km/h) of tracks associated with truth objects.
    #[arg(long, requires = "tracks")]
    pub rmse: bool,
    /// Distance gate, px: associates tracks with truth objects for --rmse (default 100) and
    /// matches detections for --detections (required there).
    #[arg(long, value_name = "PX", value_parser = crate::flags::positive)]
    pub gate_px: Option<f64>,
    /// Calibration TOML (`roadtrack simulate` writes one) for RMSE in ground units.
    #[arg(long, value_name = "C.toml", requires = "rmse")]
    pub calibration: Option<PathBuf>,
    /// Frame rate for speeds (default: seqinfo.ini's frameRate, else 10).
    #[arg(long, value_name = "FPS", value_parser = roadtrack::limits::parse_fps)]
    pub fps: Option<f64>,
    /// Detections CSV: the detection table TP / FP / FN against the truth within --gate-px.
    #[arg(long, value_name = "D.csv", requires_all = ["truth", "gate_px"])]
    pub detections: Option<PathBuf>,
    /// Matches CSV (`roadtrack match`): correct-match rate against --match-truth.
    #[arg(long, value_name = "M.csv", requires = "match_truth")]
    pub matches: Option<PathBuf>,
    /// Truth of a matching problem (`id1,id2`, empty id2 = no partner).
    #[arg(long, value_name = "truth.csv", requires = "matches")]
    pub match_truth: Option<PathBuf>,
    /// Occlusion outcomes CSV (`frame,id,visible_blocks,separated`): separation success
    /// rate per visible area.
    #[arg(long, value_name = "O.csv")]
    pub occlusion: Option<PathBuf>,
    /// OSPA and GOSPA per step between --estimates and --truth-points.
    #[arg(long, requires_all = ["estimates", "truth_points"])]
    pub ospa: bool,
    /// Filter estimates CSV (`step,label,x,y,vx,vy,weight`).
    #[arg(long, value_name = "E.csv", requires = "ospa")]
    pub estimates: Option<PathBuf>,
    /// Truth points CSV with columns `step,x,y` (other columns ignored).
    #[arg(long, value_name = "P.csv", requires = "ospa")]
    pub truth_points: Option<PathBuf>,
    /// OSPA cut-off c, in the points' units (default 20).
    #[arg(long, value_name = "C", requires = "ospa", value_parser = crate::flags::positive)]
    pub cutoff: Option<f64>,
    /// OSPA order p ≥ 1 (default 1).
    #[arg(long, value_name = "P", requires = "ospa", value_parser = ospa_order)]
    pub order: Option<f64>,
    /// GOSPA α in (0, 2] (default 2).
    #[arg(long, value_name = "A", requires = "ospa", value_parser = gospa_alpha)]
    pub alpha: Option<f64>,
}

/// `--order`: a finite p ≥ 1.
fn ospa_order(s: &str) -> Result<f64, String> {
    let v = crate::flags::finite(s)?;
    if v >= 1.0 {
        Ok(v)
    } else {
        Err(format!("must be ≥ 1, found {s}"))
    }
}

/// `--alpha`: α in (0, 2].
fn gospa_alpha(s: &str) -> Result<f64, String> {
    let v = crate::flags::positive(s)?;
    if v <= 2.0 {
        Ok(v)
    } else {
        Err(format!("must be in (0, 2], found {s}"))
    }
}

/// Wrong usage: clap's message format and exit status 2.
fn usage(msg: impl std::fmt::Display) -> ! {
    clap::Error::raw(clap::error::ErrorKind::ArgumentConflict, format!("{msg}\n")).exit()
}

/// Ground truth and what its folder says about the sequence.
struct Truth {
    rows: Vec<MotGtRow>,
    seq: Option<SeqInfo>,
}

fn read_truth(path: &Path) -> Result<Truth> {
    if path.is_dir() {
        let gt = path.join("gt").join("gt.txt");
        if !gt.is_file() {
            anyhow::bail!(
                "{}: folder has no gt/gt.txt; give a MOTChallenge sequence folder or a gt file",
                path.display()
            );
        }
        let ini = path.join("seqinfo.ini");
        let seq = if ini.is_file() {
            Some(SeqInfo::read(&ini)?)
        } else {
            None
        };
        Ok(Truth {
            rows: read_gt(&gt)?,
            seq,
        })
    } else {
        Ok(Truth {
            rows: read_gt(path)?,
            seq: None,
        })
    }
}

fn is_csv(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
}

/// Tracker rows, with their MOT17 classes when the file has them.
fn read_tracker(path: &Path) -> Result<(Vec<MotTrackRow>, Option<Vec<u32>>)> {
    if is_csv(path) {
        let (rows, classes) = rows_from_points(&read_trajectories(path)?);
        Ok((rows, Some(classes)))
    } else {
        Ok((read_tracks(path)?, None))
    }
}

/// The default `--classes pedestrian` (MOT17) scores class 1 only: on a truth without
/// pedestrians (a road of vehicles) every score is 0 whatever the tracker did. Say so on
/// stderr (even with `-q`: the numbers would mislead), with the flag that scores the rest.
fn warn_if_no_pedestrians(rows: &[MotGtRow], cfg: &EvalConfig, truth: Option<&Path>) {
    if cfg.mode != ClassMode::Pedestrian || rows.iter().any(|r| r.class == 1) {
        return;
    }
    let others = rows
        .iter()
        .filter(|r| cfg.classes.contains(&r.class))
        .count();
    if others > 0 {
        eprintln!(
            "warning: {} has no pedestrians (MOT17 class 1) but {others} boxes of other \
             classes; --classes pedestrian (the default, MOT17's) scores pedestrians only: \
             use --classes agnostic (all classes merged) or per-class",
            truth.unwrap_or(Path::new("the truth")).display()
        );
    }
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let mut cfg: EvalConfig = load_config(args.config.as_deref())?;
    if let Some(c) = args.classes {
        cfg.mode = c;
    }
    if let Some(l) = &args.class_list {
        cfg.classes.clone_from(l);
    }
    if args.no_preprocess {
        cfg.preprocess = false;
    }
    if let Some(t) = args.iou_threshold {
        cfg.iou_threshold = t;
    }
    crate::flags::check_overrides(
        cfg.validate(),
        &[
            (
                "iou_threshold",
                "--iou-threshold",
                args.iou_threshold.is_some(),
            ),
            ("classes", "--class-list", args.class_list.is_some()),
            ("classes", "--classes", args.classes.is_some()),
        ],
        args.config.as_deref(),
    )?;
    if let Some(t) = &args.tracks
        && cfg.mode == ClassMode::PerClass
        && !is_csv(t)
    {
        usage(format!(
            "--classes per-class needs tracker classes: give a trajectories CSV as --tracks, \
             not {} (MOTChallenge tracks have no class)",
            t.display()
        ));
    }
    if args.gate_px.is_some() && !args.rmse && args.detections.is_none() {
        usage("--gate-px is used by --rmse and --detections; give one of them");
    }
    if args.fps.is_some() && !args.rmse {
        usage("--fps is used by --rmse only");
    }

    let truth = args.truth.as_deref().map(read_truth).transpose()?;
    let seq = truth.as_ref().and_then(|t| t.seq.as_ref());
    if cfg.num_frames.is_none() {
        cfg.num_frames = args.num_frames.or(seq.map(|s| s.seq_length));
    } else if args.num_frames.is_some() {
        cfg.num_frames = args.num_frames;
    }

    let mut json_out = Map::new();
    let mut text = String::new();

    // Tracking metrics.
    let tracker = args.tracks.as_deref().map(read_tracker).transpose()?;
    if let (Some(t), Some(_)) = (&truth, &tracker) {
        warn_if_no_pedestrians(&t.rows, &cfg, args.truth.as_deref());
    }
    if let (Some(t), Some((rows, classes))) = (&truth, &tracker) {
        let bar = ui.progress(None, "evaluate");
        bar.tick();
        let report: EvalReport = match classes {
            Some(c) => evaluate_classified(&t.rows, rows, c, &cfg),
            None => evaluate(&t.rows, rows, &cfg),
        }
        .with_context(|| {
            format!(
                "evaluating {} against {}",
                args.tracks.as_deref().unwrap_or(Path::new("")).display(),
                args.truth.as_deref().unwrap_or(Path::new("")).display()
            )
        })?;
        bar.finish_and_clear();
        text.push_str(&format_table(&report));
        if let Value::Object(m) = serde_json::to_value(&report)? {
            json_out.extend(m);
        }
    }

    // Position and speed RMSE.
    if args.rmse
        && let (Some(t), Some((rows, _))) = (&truth, &tracker)
    {
        let rmse_cfg = RmseConfig {
            fps: args
                .fps
                .or(seq.map(|s| s.frame_rate))
                .unwrap_or(RmseConfig::default().fps),
            gate_px: args.gate_px.unwrap_or(RmseConfig::default().gate_px),
        };
        let tp = points_from_gt(&t.rows);
        let kp = points_from_tracks(rows);
        let calibration = args
            .calibration
            .as_deref()
            .map(|p| -> Result<(PathBuf, Calibration)> {
                Ok((p.to_owned(), Calibration::load(p)?))
            })
            .transpose()?;
        let report = match &calibration {
            Some((path, cal)) => {
                check_on_ground(cal, path, "truth", &tp)?;
                check_on_ground(cal, path, "tracks", &kp)?;
                let map = |p: Point| {
                    cal.ground_from_image(p)
                        .map_or(Point::new(f64::NAN, f64::NAN), |(x, y)| Point::new(x, y))
                };
                trajectory_rmse(&tp, &kp, &rmse_cfg, Some(&map))?
            }
            None => trajectory_rmse(&tp, &kp, &rmse_cfg, None)?,
        };
        text.push_str(&rmse_table(&report, &rmse_cfg));
        json_out.insert(
            "rmse".into(),
            json!({ "fps": rmse_cfg.fps, "gate_px": rmse_cfg.gate_px, "report": report }),
        );
    }

    // Detection table.
    if let (Some(path), Some(t), Some(gate)) = (&args.detections, &truth, args.gate_px) {
        let dets: Vec<LabelledPoint> = read_detections(path)?
            .iter()
            .map(|d| LabelledPoint {
                frame: d.frame,
                id: d.id,
                pos_px: d.pos_px,
            })
            .collect();
        let table = detection_table(&points_from_gt(&t.rows), &dets, gate)?;
        text.push_str(&detection_text(&table, gate));
        json_out.insert(
            "detection_table".into(),
            json!({ "gate_px": gate, "table": table }),
        );
    }

    // Correct-match rate.
    if let (Some(m), Some(mt)) = (&args.matches, &args.match_truth) {
        let rate = correct_match_rate(&read_matches(m)?, &read_matches(mt)?)
            .with_context(|| format!("comparing {} with {}", m.display(), mt.display()))?;
        text.push_str(&match_text(&rate));
        json_out.insert("correct_match_rate".into(), serde_json::to_value(rate)?);
    }

    // Occlusion separation success.
    if let Some(o) = &args.occlusion {
        let bins = separation_success(&read_occlusion(o)?, None);
        text.push_str(&separation_text(&bins));
        json_out.insert("separation".into(), serde_json::to_value(&bins)?);
    }

    // OSPA / GOSPA.
    if let (true, Some(e), Some(p)) = (args.ospa, &args.estimates, &args.truth_points) {
        let defaults = OspaConfig::default();
        let ocfg = OspaConfig {
            cutoff: args.cutoff.unwrap_or(defaults.cutoff),
            order: args.order.unwrap_or(defaults.order),
            alpha: args.alpha.unwrap_or(defaults.alpha),
        };
        if let Err(err) = ocfg.validate() {
            usage(err);
        }
        let truth_pts: Vec<(u64, Point)> = read_measurements(p)?
            .iter()
            .map(|m| (m.step, m.pos))
            .collect();
        let est: Vec<(u64, Point)> = read_estimates(e)?.iter().map(|m| (m.step, m.pos)).collect();
        let steps = ospa_series(&truth_pts, &est, &ocfg)?;
        let (mean_ospa, mean_gospa) = means(&steps);
        text.push_str(&format!(
            "OSPA / GOSPA (c = {}, p = {}, α = {}) over {} steps: mean OSPA {:.4}, mean GOSPA {:.4}\n",
            ocfg.cutoff,
            ocfg.order,
            ocfg.alpha,
            steps.len(),
            mean_ospa,
            mean_gospa
        ));
        json_out.insert(
            "ospa".into(),
            json!({
                "cutoff": ocfg.cutoff, "order": ocfg.order, "alpha": ocfg.alpha,
                "steps": steps.len(), "mean_ospa": mean_ospa, "mean_gospa": mean_gospa,
                "per_step": steps,
            }),
        );
    }

    let body = if args.json {
        serde_json::to_string_pretty(&Value::Object(json_out))? + "\n"
    } else {
        text.trim_start_matches('\n').to_owned()
    };
    write_atomic(&args.output, |w| w.write_all(body.as_bytes()))?;
    Ok(())
}

/// Every point must map to the ground: a point above the horizon has no ground position.
fn check_on_ground(
    cal: &Calibration,
    path: &Path,
    what: &str,
    points: &[LabelledPoint],
) -> Result<()> {
    if let Some(p) = points
        .iter()
        .find(|p| cal.ground_from_image(p.pos_px).is_none())
    {
        anyhow::bail!(
            "{}: {what} frame {}, id {} at ({}, {}) px is on or above the horizon; no ground position",
            path.display(),
            p.frame,
            p.id,
            p.pos_px.x,
            p.pos_px.y
        );
    }
    Ok(())
}

fn means(steps: &[OspaStep]) -> (f64, f64) {
    if steps.is_empty() {
        return (0.0, 0.0);
    }
    let n = steps.len() as f64;
    (
        steps.iter().map(|s| s.ospa).sum::<f64>() / n,
        steps.iter().map(|s| s.gospa.distance).sum::<f64>() / n,
    )
}

fn rmse_table(r: &RmseReport, cfg: &RmseConfig) -> String {
    let mut s = format!(
        "\nRMSE: {} track/truth pairs (gate {} px), {} position and {} speed samples at {} fps\n",
        r.pairs.len(),
        cfg.gate_px,
        r.position_samples,
        r.speed_samples,
        cfg.fps
    );
    s += &format!(
        "{:<6} {:>10} {:>10} {:>10} {:>12}\n",
        "units", "x", "y", "position", "speed"
    );
    s += &format!(
        "{:<6} {:>10.3} {:>10.3} {:>10.3} {:>12}\n",
        "px",
        r.px.x,
        r.px.y,
        r.px.position,
        format!("{:.3} px/s", r.px.speed)
    );
    if let Some(g) = &r.ground {
        s += &format!(
            "{:<6} {:>10.4} {:>10.4} {:>10.4} {:>12}\n",
            "m",
            g.x,
            g.y,
            g.position,
            format!("{:.3} km/h", g.speed)
        );
    }
    s
}

fn detection_text(t: &DetectionTable, gate: f64) -> String {
    format!(
        "\nDetections (gate {gate} px): TP {}, FP {}, FN {}, precision {:.4}, recall {:.4}; \
         objects detected {} of {}\n",
        t.tp, t.fp, t.fn_, t.precision, t.recall, t.objects_detected, t.objects
    )
}

fn match_text(r: &MatchRate) -> String {
    format!(
        "\nCorrect-match rate: {} of {} = {:.4} (wrong partner {}, missed partner {}, false \
         partner {}, undecided {})\n",
        r.n_correct,
        r.n_vehicles,
        r.rate,
        r.wrong_partner,
        r.missed_partner,
        r.false_partner,
        r.undecided
    )
}

fn separation_text(bins: &[SeparationBin]) -> String {
    let mut s = format!(
        "\nOcclusion separation success\n{:>14} {:>8} {:>10} {:>8}\n",
        "visible blocks", "cases", "separated", "rate"
    );
    for b in bins {
        s += &format!(
            "{:>14} {:>8} {:>10} {:>8.4}\n",
            b.visible_blocks, b.n, b.separated, b.success_rate
        );
    }
    s
}
