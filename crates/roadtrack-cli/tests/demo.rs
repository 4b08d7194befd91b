//! End-to-end tests of `roadtrack demo`: short runs (the default, a whole signal cycle,
//! is measured in docs/EXPERIMENTS.md, not here).

mod common;
use common::{bin, stderr};

use std::path::Path;

/// Runs the demo into `out` with `args`; its report page.
fn demo(out: &Path, args: &[&str]) -> String {
    let o = bin()
        .args(["demo", "-q", "--no-video"])
        .args(args)
        .arg("-o")
        .arg(out)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::read_to_string(out.join("report.md")).expect("report")
}

/// The rows of the table under the first line of `page` that starts with `header`, split
/// into trimmed cells.
fn table(page: &str, header: &str) -> Vec<Vec<String>> {
    page.lines()
        .skip_while(|l| !l.starts_with(header))
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_owned())
                .collect()
        })
        .collect()
}

/// The scores table lists every method once, best HOTA first, and the page leads with it.
fn check_methods_best_first(page: &str) -> Vec<String> {
    let rows = table(page, "| method | tracks |");
    let names: Vec<String> = rows.iter().map(|r| r[0].clone()).collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(sorted, ["mrf", "pf", "phd", "relaxation"], "{page}");
    let hota: Vec<f64> = rows.iter().map(|r| r[4].parse().expect("HOTA")).collect();
    assert!(
        hota.windows(2).all(|w| w[0] >= w[1]),
        "methods not in HOTA order: {names:?} {hota:?}"
    );
    let first = page.lines().find(|l| !l.is_empty() && !l.starts_with('#'));
    assert!(
        first.is_some_and(|l| l.starts_with(&format!("**Best method: {}**", names[0]))),
        "{first:?}"
    );
    // Each method's section follows in the same order.
    let sections: Vec<usize> = names
        .iter()
        .map(|n| page.find(&format!("\n## {n}\n")).expect("section"))
        .collect();
    assert!(sections.windows(2).all(|w| w[0] < w[1]), "{sections:?}");
    names
}

#[test]
fn demo_reports_every_method_best_first_with_pictures_and_counts() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("demo");
    let page = demo(&out, &["--frames", "40"]);
    let names = check_methods_best_first(&page);
    for m in &names {
        for f in [
            "overlay_frame.png",
            "trajectories.png",
            "tracks.txt",
            "analysis.json",
        ] {
            assert!(out.join(m).join(f).is_file(), "{m}/{f} missing");
        }
    }
    // The counts table: a column for the truth and one per method, best first.
    let header = page
        .lines()
        .find(|l| l.starts_with("| line, direction |"))
        .expect("counts table");
    assert_eq!(
        header,
        format!("| line, direction | truth | {} |", names.join(" | "))
    );
    // The default detector: the learned one without the mirror, run once for all.
    assert!(
        page.contains("`--detector cnn --no-flip` (the demo's default")
            && page.contains("run once for every method"),
        "{page}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).expect("json"))
            .expect("summary.json");
    assert_eq!(summary["detector"].as_str(), Some("cnn"));
    assert_eq!(summary["detector_default"].as_bool(), Some(true));
    assert!(summary["detect_seconds"].as_f64().is_some_and(|t| t > 0.0));
    // Each method's own background detector, when asked for.
    let out = dir.path().join("demo_bg");
    let page = demo(&out, &["--frames", "20", "--detector", "background"]);
    assert!(page.contains("`--detector background`"), "{page}");
    assert!(!page.contains("default"), "{page}");
    // The learned detector's flags apply to the default detector, and the report says so.
    let out = dir.path().join("demo_kept");
    let page = demo(&out, &["--frames", "20", "--keep-second-peaks"]);
    assert!(
        page.contains("`--detector cnn --keep-second-peaks --no-flip` (the demo's default"),
        "{page}"
    );
}

/// With the sequence's own detections, over long enough for a car to cross the junction:
/// the truth's turning movements are trips between two arms, set beside every method's,
/// with the objects seen in one arm only apart.
#[test]
fn demo_with_public_detections_counts_complete_trips_beside_the_truth() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("demo");
    let page = demo(&out, &["--frames", "100", "--detector", "file"]);
    assert!(page.contains("`--detector file`"), "{page}");
    let names = check_methods_best_first(&page);
    let rows = table(&page, "| movement | truth |");
    let movements: Vec<&Vec<String>> = rows.iter().filter(|r| r[0].contains(" → ")).collect();
    assert!(!movements.is_empty(), "no turning movement: {page}");
    for r in &movements {
        let (a, b) = r[0].split_once(" → ").expect("A → B");
        assert_ne!(a, b, "a same-arm row among the turning movements: {r:?}");
        assert_eq!(r.len(), 2 + names.len(), "{r:?}");
    }
    let truth_trips: u64 = movements
        .iter()
        .map(|r| r[1].parse::<u64>().expect("count"))
        .sum();
    assert!(
        truth_trips > 0,
        "the truth has no trip through the junction: {page}"
    );
    let row = |name: &str| rows.iter().find(|r| r[0] == name).cloned();
    assert_eq!(
        row("**complete trips**").map(|r| r[1].clone()),
        Some(format!("**{truth_trips}**"))
    );
    let incomplete = row("incomplete (one arm only)").expect("incomplete row");
    assert!(
        incomplete[1].parse::<u64>().expect("count") > 0,
        "{incomplete:?}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).expect("json"))
            .expect("summary.json");
    assert_eq!(summary["truth_trips"].as_u64(), Some(truth_trips));
    assert_eq!(summary["detector"].as_str(), Some("file"));
    let listed: Vec<&str> = summary["methods"]
        .as_array()
        .expect("methods")
        .iter()
        .map(|m| m["method"].as_str().expect("name"))
        .collect();
    assert_eq!(listed, names);
}

#[test]
fn demo_detector_flags_that_cannot_apply_are_usage_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    for args in [
        vec!["--detections", "det.txt"],
        vec!["--detector", "onnx"],
        vec!["--detector", "background", "--layout", "yolo"],
    ] {
        let o = bin()
            .args(["demo", "-q", "--frames", "20", "-o"])
            .arg(dir.path().join("d"))
            .args(&args)
            .output()
            .expect("run");
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(
            !dir.path().join("d").exists(),
            "{args:?} simulated before failing"
        );
    }
}
