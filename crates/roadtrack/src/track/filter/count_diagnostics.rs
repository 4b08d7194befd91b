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

/// One frame's parts of `Σw − true` (they sum to it), in the order of [`PARTS`].
/// Labels, heaviest first, take the closest free object (visible at all) within half its
/// box's longer side + 3 px; a label whose objects are all taken is a duplicate.
fn split_frame(
    labels: &[(Point, f64)],
    total: f64,
    truth: &[(Point, f64, f64, bool, bool)],
    detections: &[Point],
) -> [f64; 9] {
    let mut parts = [0.0; 9];
    let mut order: Vec<usize> = (0..labels.len()).collect();
    order.sort_by(|&a, &b| labels[b].1.total_cmp(&labels[a].1).then(a.cmp(&b)));
    let mut taken = vec![false; truth.len()];
    for &l in &order {
        let (pos, w) = labels[l];
        let mut best: Option<(usize, f64, bool)> = None;
        for (t, &(tp, half, _, _, _)) in truth.iter().enumerate() {
            let d = pos.distance(tp);
            if d <= half + 3.0 && best.is_none_or(|(_, bd, bf)| (!taken[t], -d) > (!bf, -bd)) {
                best = Some((t, d, taken[t]));
            }
        }
        match best {
            Some((t, _, false)) => {
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
            Some((_, _, true)) => parts[6] += w,
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

/// Count error of the detection PHD split per frame into [`PARTS`], seeds 1–3, 300 frames.
/// Run with `cargo test -p roadtrack --lib count_error_split_experiment -- --ignored
/// --nocapture` (env `RT_SCENES=crossing,intersection,road` picks scenes, `RT_CONFIG` a
/// `FilterTrackConfig` TOML instead of the defaults, `RT_FRAMES` the length).
#[test]
#[ignore = "experiment, several minutes"]
fn count_error_split_experiment() -> Result<()> {
    let scenes = std::env::var("RT_SCENES").unwrap_or_else(|_| "crossing".to_owned());
    let frames: u32 = std::env::var("RT_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300);
    for name in scenes.split(',') {
        let (scene, view) = match name {
            "road" => (SceneKind::Road, ViewKind::Aerial),
            "intersection" => (SceneKind::Intersection, ViewKind::Oblique),
            _ => (SceneKind::Crossing, ViewKind::Oblique),
        };
        let cfg = match std::env::var("RT_CONFIG") {
            Ok(path) => FilterTrackConfig::from_toml_file(std::path::Path::new(&path))?,
            Err(_) => FilterTrackConfig::default(),
        };
        let mut sums = [0.0; 9];
        let mut abs_without = [0.0; 9];
        let (mut mae, mut n) = (0.0, 0.0);
        for seed in 1..=3u64 {
            let sim = SimConfig {
                scene,
                view,
                frames,
                ..Default::default()
            };
            let mut tracker = FilterTracker::new(FilterMethod::Phd, &cfg, seed, None)?;
            tracker.record_counts();
            let mut first_seen: std::collections::BTreeMap<u64, u32> = Default::default();
            for step in Simulation::new(&sim, seed)? {
                let step = step?;
                let d = FrameDetections {
                    detections: step.detections.clone(),
                    foreground: None,
                };
                tracker.step(&step.frame, &d)?;
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
            }
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
