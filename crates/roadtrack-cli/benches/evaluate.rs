//! Times `metrics::evaluate` on a MOT17-sized input made by
//! `python scripts/golden_metrics.py --bench DIR` and checks the numbers against
//! TrackEval's (DIR/expected.json). See docs/PERFORMANCE.md "Evaluation".
//!
//! ```sh
//! cargo bench -p roadtrack-cli --bench evaluate -- DIR [REPS]
//! ```

use roadtrack::eval::{EvalConfig, evaluate};
use roadtrack::io::mot::{read_gt, read_tracks};
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = roadtrack_cli::bench::bench_args();
    let dir = Path::new(
        args.first()
            .ok_or("usage: cargo bench -p roadtrack-cli --bench evaluate -- DIR [REPS]")?,
    );
    let reps: usize = args.get(1).map_or(Ok(5), |s| s.parse())?;
    let expected: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("expected.json"))?)?;
    let mut times = Vec::new();
    let mut eval_times: Vec<f64> = Vec::new();
    let mut report = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        let gt = read_gt(&dir.join("gt.txt"))?;
        let tracks = read_tracks(&dir.join("tracks.txt"))?;
        let cfg = EvalConfig {
            num_frames: Some(600),
            ..EvalConfig::default()
        };
        let t1 = Instant::now();
        let r = evaluate(&gt, &tracks, &cfg)?;
        times.push(t0.elapsed().as_secs_f64());
        eval_times.push(t1.elapsed().as_secs_f64());
        report = Some(r);
    }
    let report = serde_json::to_value(report.ok_or("no repetition")?)?;
    let mut worst: f64 = 0.0;
    let mut n = 0;
    if let Some(te) = expected["trackeval"].as_object() {
        for (k, v) in te {
            if let (Some(e), Some(a)) = (v.as_f64(), report[k].as_f64()) {
                worst = worst.max((e - a).abs());
                n += 1;
            }
        }
    }
    let min = times.iter().copied().fold(f64::INFINITY, f64::min);
    println!(
        "roadtrack evaluate (read + HOTA + CLEAR + Identity): {} s; min {min:.4} s",
        times
            .iter()
            .map(|t| format!("{t:.4}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!("{n} scalar metrics compared with TrackEval, largest difference {worst:.3e}");
    let eval_min = eval_times.iter().copied().fold(f64::INFINITY, f64::min);
    println!("  of which evaluate (IoU, preprocessing, metrics): min {eval_min:.4} s");
    let te_min = |key: &str| {
        expected[key].as_array().map(|v| {
            v.iter()
                .filter_map(serde_json::Value::as_f64)
                .fold(f64::INFINITY, f64::min)
        })
    };
    if let Some(t) = te_min("trackeval_seconds") {
        println!(
            "TrackEval end to end: min {t:.3} s → {:.1}× faster",
            t / min
        );
    }
    if let (Some(l), Some(m)) = (
        te_min("trackeval_load_seconds"),
        te_min("trackeval_metrics_seconds"),
    ) {
        println!(
            "TrackEval preprocessing + metrics: min {m:.3} s (its loading with IoU: {l:.3} s) \
             → {:.1}× faster than our evaluate, which also computes the IoU",
            m / eval_min
        );
    }
    if worst > 1e-6 {
        return Err(format!("differs from TrackEval by {worst}").into());
    }
    Ok(())
}
