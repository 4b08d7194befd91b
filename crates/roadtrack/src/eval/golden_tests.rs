//! Parity with TrackEval: every golden case under `tests/golden/metrics/` (made by
//! `scripts/golden_metrics.py`, see the README there) is evaluated and every value
//! TrackEval reported is compared to 1e-6.

use super::*;
use crate::io::mot::{read_gt, read_tracks};
use serde_json::Value;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/metrics")
}

/// Walks `expected` and reports every leaf of `actual` that differs.
fn compare(path: &str, expected: &Value, actual: &Value, out: &mut Vec<String>) {
    match (expected, actual) {
        (Value::Object(e), Value::Object(a)) => {
            for (k, ev) in e {
                match a.get(k) {
                    Some(av) => compare(&format!("{path}.{k}"), ev, av, out),
                    None => out.push(format!("{path}.{k}: missing")),
                }
            }
        }
        (Value::Array(e), Value::Array(a)) if e.len() == a.len() => {
            for (i, (ev, av)) in e.iter().zip(a).enumerate() {
                compare(&format!("{path}[{i}]"), ev, av, out);
            }
        }
        (Value::Number(e), Value::Number(a)) => {
            let (e, a) = (
                e.as_f64().unwrap_or(f64::NAN),
                a.as_f64().unwrap_or(f64::NAN),
            );
            if (e - a).abs() > 1e-6 || e.is_nan() || a.is_nan() {
                out.push(format!("{path}: TrackEval {e}, ours {a}"));
            }
        }
        (e, a) if e == a => {}
        (e, a) => out.push(format!("{path}: TrackEval {e}, ours {a}")),
    }
}

fn config_of(v: &Value) -> EvalConfig {
    let mut cfg = EvalConfig::default();
    if let Some(m) = v.get("mode").and_then(Value::as_str) {
        cfg.mode = serde_json::from_value(Value::String(m.to_owned())).unwrap_or_default();
    }
    if let Some(c) = v.get("classes").and_then(Value::as_array) {
        cfg.classes = c
            .iter()
            .filter_map(Value::as_u64)
            .map(|c| c as u32)
            .collect();
    }
    if let Some(p) = v.get("preprocess").and_then(Value::as_bool) {
        cfg.preprocess = p;
    }
    cfg.num_frames = v
        .get("num_frames")
        .and_then(Value::as_u64)
        .map(|n| n as u32);
    cfg
}

fn run_case(json: &Path) -> Result<Vec<String>> {
    let text = std::fs::read_to_string(json).map_err(|e| Error::io(json, e))?;
    let doc: Value = serde_json::from_str(&text).map_err(|e| Error::Invalid(e.to_string()))?;
    let stem = json.with_extension("");
    let file = |suffix: &str| PathBuf::from(format!("{}.{suffix}", stem.display()));
    let gt = read_gt(&file("gt.txt"))?;
    let tracks = read_tracks(&file("tracks.txt"))?;
    let cfg = config_of(&doc["config"]);
    let classes_path = file("track_classes.csv");
    let report = if classes_path.exists() {
        let text =
            std::fs::read_to_string(&classes_path).map_err(|e| Error::io(&classes_path, e))?;
        let mut by_key = HashMap::new();
        for line in text.lines().skip(1) {
            let v: Vec<u64> = line.split(',').filter_map(|s| s.parse().ok()).collect();
            if let [f, id, c] = v[..] {
                by_key.insert((f as u32, id), c as u32);
            }
        }
        let classes: Vec<u32> = tracks
            .iter()
            .map(|r| by_key.get(&(r.frame, r.id)).copied().unwrap_or(0))
            .collect();
        evaluate_classified(&gt, &tracks, &classes, &cfg)?
    } else {
        evaluate(&gt, &tracks, &cfg)?
    };
    let actual = serde_json::to_value(&report).map_err(|e| Error::Invalid(e.to_string()))?;
    let mut diffs = Vec::new();
    compare("", &doc["trackeval"], &actual, &mut diffs);
    Ok(diffs)
}

#[test]
fn every_golden_case_agrees_with_trackeval_to_1e6() -> Result<()> {
    let dir = golden_dir();
    let mut cases: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| Error::io(&dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    cases.sort();
    assert!(
        cases.len() >= 6,
        "expected at least 6 golden cases in {dir:?}"
    );
    let mut failures = Vec::new();
    for c in &cases {
        let diffs = run_case(c)?;
        if !diffs.is_empty() {
            failures.push(format!("{}:\n  {}", c.display(), diffs.join("\n  ")));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    Ok(())
}
