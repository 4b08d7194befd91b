//! Where the detection PHD's count error comes from (issue 14): per frame, `Σw − true
//! count` split into the labels' and the objects' parts (an ignored experiment).

use super::{FilterMethod, FilterTrackConfig, FilterTracker};
use crate::detect::FrameDetections;
use crate::error::Result;
use crate::geometry::Point;
use crate::track::Tracker;
use roadtrack_sim::{SceneKind, SimConfig, Simulation, ViewKind};

/// Names of the parts of `Σw − true` (see [`split_frame`]).
const PARTS: [&str; 9] = [
    "tracked w-1",
    "tracked, entering w-1",
    "tracked, at border w-1",
    "missing, detected",
    "missing, not detected",
    "occluded label",
    "duplicate label",
    "false label",
    "unlabelled mass",
];

/// What each label lies on: labels, heaviest first, take the closest free object within
/// half its box's longer side + 3 px (`truth`: centre, that half side). `Some((t, true))`:
/// the label took object `t`; `Some((t, false))`: every object in reach was taken, `t` the
/// nearest (a duplicate); `None`: no object in reach.
fn match_labels(labels: &[(Point, f64)], truth: &[(Point, f64)]) -> Vec<Option<(usize, bool)>> {
    let mut on = vec![None; labels.len()];
    let mut order: Vec<usize> = (0..labels.len()).collect();
    order.sort_by(|&a, &b| labels[b].1.total_cmp(&labels[a].1).then(a.cmp(&b)));
    let mut taken = vec![false; truth.len()];
    for &l in &order {
        let pos = labels[l].0;
        let mut best: Option<(usize, f64, bool)> = None;
        for (t, &(tp, half)) in truth.iter().enumerate() {
            let d = pos.distance(tp);
            if d <= half + 3.0 && best.is_none_or(|(_, bd, bf)| (!taken[t], -d) > (!bf, -bd)) {
                best = Some((t, d, taken[t]));
            }
        }
        on[l] = best.map(|(t, _, was_taken)| {
            taken[t] = true;
            (t, !was_taken)
        });
    }
    on
}

/// One frame's parts of `Σw − true` (they sum to it), in the order of [`PARTS`], labels
/// matched to the objects visible at all by [`match_labels`].
fn split_frame(
    labels: &[(Point, f64)],
    total: f64,
    truth: &[(Point, f64, f64, bool, bool)],
    detections: &[Point],
) -> [f64; 9] {
    let mut parts = [0.0; 9];
    let reach: Vec<(Point, f64)> = truth.iter().map(|t| (t.0, t.1)).collect();
    let mut taken = vec![false; truth.len()];
    for (&(_, w), on) in labels.iter().zip(match_labels(labels, &reach)) {
        match on {
            Some((t, true)) => {
                taken[t] = true;
                let (_, _, vis, entering, border) = truth[t];
                if vis >= 0.3 {
                    let k = if entering {
                        1
                    } else if border {
                        2
                    } else {
                        0
                    };
                    parts[k] += w - 1.0;
                } else {
                    parts[5] += w;
                }
            }
            Some((_, false)) => parts[6] += w,
            None => parts[7] += w,
        }
    }
    for (t, &(tp, half, vis, _, _)) in truth.iter().enumerate() {
        if vis >= 0.3 && !taken[t] {
            let detected = detections.iter().any(|d| d.distance(tp) <= half + 3.0);
            parts[if detected { 3 } else { 4 }] -= 1.0;
        }
    }
    parts[8] = total - labels.iter().map(|l| l.1).sum::<f64>();
    parts
}

/// The scene of an `RT_SCENES` name: `road`, `intersection`, `crossing` are the count
/// experiments' views (the aerial road, the oblique junctions; crossing by default);
/// `SCENE-VIEW` (e.g. `road-oblique`) any other.
fn scene_of(name: &str) -> (SceneKind, ViewKind) {
    let (scene, view) = name.split_once('-').unwrap_or((name, ""));
    let scene = match scene {
        "road" => SceneKind::Road,
        "intersection" => SceneKind::Intersection,
        _ => SceneKind::Crossing,
    };
    let view = match (view, scene) {
        ("aerial", _) | ("", SceneKind::Road) => ViewKind::Aerial,
        _ => ViewKind::Oblique,
    };
    (scene, view)
}

/// Runs the detection PHD of `cfg` over `frames` frames of the scene `name` at `seed` on
/// the simulator's detections, calling `per_step` after each step.
fn run_phd(
    name: &str,
    frames: u32,
    seed: u64,
    cfg: &FilterTrackConfig,
    mut per_step: impl FnMut(&FilterTracker, &roadtrack_sim::SimStep) -> Result<()>,
) -> Result<()> {
    let (scene, view) = scene_of(name);
    let sim = SimConfig {
        scene,
        view,
        frames,
        ..Default::default()
    };
    let mut tracker = FilterTracker::new(FilterMethod::Phd, cfg, seed, None)?;
    tracker.record_counts();
    for step in Simulation::new(&sim, seed)? {
        let step = step?;
        let d = FrameDetections {
            detections: step.detections.clone(),
            foreground: None,
        };
        tracker.step(&step.frame, &d)?;
        per_step(&tracker, &step)?;
    }
    Ok(())
}

/// Count error of the detection PHD split per frame into [`PARTS`], seeds 1–3, 300 frames.
/// Run with `cargo test -p roadtrack --lib count_error_split_experiment -- --ignored
/// --nocapture` (env `RT_SCENES=crossing,intersection,road-oblique` picks scenes, see
/// [`scene_of`]; `RT_CONFIG` a `FilterTrackConfig` TOML instead of the defaults, an
/// absolute path; `RT_FRAMES` the length).
#[test]
#[ignore = "experiment, several minutes"]
fn count_error_split_experiment() -> Result<()> {
    let scenes = std::env::var("RT_SCENES").unwrap_or_else(|_| "crossing".to_owned());
    let frames: u32 = std::env::var("RT_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300);
    for name in scenes.split(',') {
        let cfg = match std::env::var("RT_CONFIG") {
            Ok(path) => FilterTrackConfig::from_toml_file(std::path::Path::new(&path))?,
            Err(_) => FilterTrackConfig::default(),
        };
        let mut sums = [0.0; 9];
        let mut abs_without = [0.0; 9];
        let (mut mae, mut n) = (0.0, 0.0);
        for seed in 1..=3u64 {
            let mut first_seen: std::collections::BTreeMap<u64, u32> = Default::default();
            run_phd(name, frames, seed, &cfg, |tracker, step| {
                let total = tracker.counts().last().map_or(0.0, |c| c.expected);
                let labels: Vec<(Point, f64)> = tracker
                    .phd_labels()
                    .iter()
                    .map(|e| (e.pos, e.weight))
                    .collect();
                let (iw, ih) = step.frame.size();
                let truth: Vec<(Point, f64, f64, bool, bool)> = step
                    .truth
                    .iter()
                    .filter(|t| t.visibility > 0.0)
                    .map(|t| {
                        let b = t.bbox;
                        if t.visibility >= 0.3 {
                            first_seen.entry(t.id).or_insert(step.frame.index);
                        }
                        let entering = first_seen
                            .get(&t.id)
                            .is_some_and(|&f| step.frame.index <= f + 2);
                        let border = b.left <= 1.0
                            || b.top <= 1.0
                            || b.left + b.width >= f64::from(iw) - 1.0
                            || b.top + b.height >= f64::from(ih) - 1.0;
                        (
                            b.centre(),
                            0.5 * b.width.max(b.height),
                            t.visibility,
                            entering,
                            border,
                        )
                    })
                    .collect();
                let seen = truth.iter().filter(|t| t.2 >= 0.3).count() as f64;
                let dets: Vec<Point> = step.detections.iter().map(|d| d.pos_px).collect();
                let parts = split_frame(&labels, total, &truth, &dets);
                let err = total - seen;
                let check: f64 = parts.iter().sum();
                assert!((check - err).abs() < 1e-6, "{check} against {err}");
                mae += err.abs();
                n += 1.0;
                for k in 0..9 {
                    sums[k] += parts[k];
                    abs_without[k] += (err - parts[k]).abs();
                }
                Ok(())
            })?;
        }
        println!("{name}: count MAE {:.3} over {n} frames", mae / n);
        for k in 0..9 {
            println!(
                "  {:<24} mean {:+.3}  MAE without it {:.3}",
                PARTS[k],
                sums[k] / n,
                abs_without[k] / n
            );
        }
    }
    Ok(())
}

/// One row per PHD label and frame for `scripts/count_calibration.py`: the label's weight,
/// its misses in a row (0: detected this frame) and what it lies on, matched as in
/// [`split_frame`] (`V` an object ≥ 0.3 visible, `H` one under 0.3, `D` an object another
/// label took, `N` none; `E` marks a frame without labels), with the frame's true count.
/// `configs/filters-pedestrians.toml`, 300 frames; writes `RT_OUT/SCENE_SEED.csv`. Run
/// with `RT_OUT=/tmp/count_probe RT_SEEDS=1,2,3,4,5,6 cargo test --release -p roadtrack
/// --lib count_after_miss_probe -- --ignored` (env `RT_SCENES` as above).
#[test]
#[ignore = "experiment, writes CSV files"]
fn count_after_miss_probe() -> Result<()> {
    use std::collections::BTreeMap;
    use std::fmt::Write as _;
    let cfg = FilterTrackConfig::from_toml_file(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/filters-pedestrians.toml"
    )))?;
    let out_dir = std::env::var("RT_OUT").unwrap_or_else(|_| "/tmp/count_probe".to_owned());
    std::fs::create_dir_all(&out_dir).map_err(|e| crate::error::Error::io(&out_dir, e))?;
    let scenes = std::env::var("RT_SCENES").unwrap_or_else(|_| "crossing".to_owned());
    let seeds = std::env::var("RT_SEEDS").unwrap_or_else(|_| "1,2,3".to_owned());
    for name in scenes.split(',') {
        for seed in seeds.split(',') {
            let seed: u64 = seed
                .trim()
                .parse()
                .map_err(|_| crate::error::Error::Invalid(format!("RT_SEEDS: {seed}")))?;
            let mut csv = String::from("frame,label,w,misses,on,true_count\n");
            let mut misses: BTreeMap<u32, u32> = BTreeMap::new();
            run_phd(name, 300, seed, &cfg, |tracker, step| {
                let labels = tracker.phd_labels();
                let detected = tracker.phd_detected_labels();
                misses = labels
                    .iter()
                    .map(|e| {
                        let k = if detected.contains(&e.label) {
                            0
                        } else {
                            misses.get(&e.label).map_or(1, |k| k + 1)
                        };
                        (e.label, k)
                    })
                    .collect();
                let truth: Vec<_> = step.truth.iter().filter(|t| t.visibility > 0.0).collect();
                let reach: Vec<(Point, f64)> = truth
                    .iter()
                    .map(|t| (t.bbox.centre(), 0.5 * t.bbox.width.max(t.bbox.height)))
                    .collect();
                let seen = truth.iter().filter(|t| t.visibility >= 0.3).count();
                let weighed: Vec<(Point, f64)> = labels.iter().map(|e| (e.pos, e.weight)).collect();
                let f = step.frame.index;
                for (e, on) in labels.iter().zip(match_labels(&weighed, &reach)) {
                    let on = match on {
                        Some((t, true)) if truth[t].visibility >= 0.3 => 'V',
                        Some((_, true)) => 'H',
                        Some((_, false)) => 'D',
                        None => 'N',
                    };
                    let _ = writeln!(
                        csv,
                        "{f},{},{},{},{on},{seen}",
                        e.label, e.weight, misses[&e.label]
                    );
                }
                if labels.is_empty() {
                    let _ = writeln!(csv, "{f},0,0,0,E,{seen}");
                }
                Ok(())
            })?;
            let path = format!("{out_dir}/{name}_{seed}.csv");
            std::fs::write(&path, csv).map_err(|e| crate::error::Error::io(&path, e))?;
        }
    }
    Ok(())
}
