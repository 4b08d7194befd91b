//! End-to-end tests of `roadtrack track`.

mod common;
use common::bin;

use roadtrack_sim::{SceneKind, SimConfig, ViewKind};
use std::path::Path;

fn simulate(dir: &Path, scene: SceneKind, view: ViewKind, frames: u32) {
    let cfg = SimConfig {
        scene,
        view,
        frames,
        ..Default::default()
    };
    roadtrack_sim::simulate(&cfg, 5, dir, &mut |_, _| {}).expect("simulate");
}

#[test]
fn relaxation_tracks_simulated_road_with_ground_speeds_and_good_scores() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    simulate(&seq, SceneKind::Road, ViewKind::Aerial, 60);
    let tracks = dir.path().join("t.txt");
    let traj = dir.path().join("t.csv");
    let geo = dir.path().join("t.geojson");
    let o = bin()
        .arg("track")
        .arg(&seq)
        .args(["--method", "relaxation", "-q", "-o"])
        .arg(&tracks)
        .arg("--trajectories")
        .arg(&traj)
        .arg("--calibration")
        .arg(seq.join("calibration.toml"))
        .arg("--geojson")
        .arg(&geo)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let points = roadtrack::io::trajectories::read_trajectories(&traj).expect("trajectories");
    assert!(!points.is_empty());
    assert!(points.iter().all(|p| p.ground.is_some()));
    // Road traffic at the sim's default speed limit: median ground speed of long tracks is
    // a road speed (5–40 m/s), not pixels per frame.
    let mut speeds: Vec<f64> = points
        .iter()
        .filter_map(|p| p.ground.map(|g| g.speed_mps))
        .collect();
    speeds.sort_by(f64::total_cmp);
    let median = speeds[speeds.len() / 2];
    assert!((5.0..40.0).contains(&median), "median speed {median} m/s");
    let gt = roadtrack::io::mot::read_gt(&seq.join("gt/gt.txt")).expect("gt");
    let tr = roadtrack::io::mot::read_tracks(&tracks).expect("tracks");
    // Cars are about 14 × 5 px at 0.33 m/px and the extracted regions include shadows, so
    // box IoU is a poor judge here; the seed 000/004 detection table with a 10 px (3.3 m)
    // centre gate is the measure.
    let table = roadtrack::eval::papers::detection_table(
        &roadtrack::eval::papers::points_from_gt(&gt),
        &roadtrack::eval::papers::points_from_tracks(&tr),
        10.0,
    )
    .expect("table");
    eprintln!("{table:?}");
    assert!(table.recall > 0.5 && table.precision > 0.9, "{table:?}");
    let g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&geo).expect("geojson")).expect("json");
    assert_eq!(g["type"], "FeatureCollection");
}

#[test]
fn mrf_tracks_are_deterministic_for_a_seed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    simulate(&seq, SceneKind::Crossing, ViewKind::Oblique, 30);
    let run = |name: &str| {
        let out = dir.path().join(name);
        let o = bin()
            .arg("track")
            .arg(&seq)
            .args(["--method", "mrf", "-q", "--seed", "3", "-o"])
            .arg(&out)
            .output()
            .expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out).expect("read")
    };
    let a = run("a.txt");
    assert!(!a.is_empty());
    assert_eq!(a, run("b.txt"));
}

#[test]
fn geojson_without_calibration_is_a_usage_error() {
    let o = bin()
        .args(["track", "x", "--method", "mrf", "--geojson", "g.json"])
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn demo_reports_every_method_with_pictures() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("demo");
    let o = bin()
        .args(["demo", "-q", "--frames", "40", "--no-video", "-o"])
        .arg(&out)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = std::fs::read_to_string(out.join("report.md")).expect("report");
    for m in ["relaxation", "mrf", "pf", "phd"] {
        assert!(
            report.contains(&format!("| {m} |")),
            "{m} missing from the metrics table"
        );
        assert!(
            out.join(m).join("overlay_frame.png").is_file(),
            "{m} still missing"
        );
        assert!(
            out.join(m).join("trajectories.png").is_file(),
            "{m} plot missing"
        );
        assert!(
            out.join(m).join("tracks.txt").is_file(),
            "{m} tracks missing"
        );
    }
}

#[cfg(feature = "cnn")]
const TINY_CNN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../roadtrack-cnn/tests/fixtures/tiny_classifier.onnx"
);

/// Tracks in `path` are valid: readable, inside `1..=frames`, finite positive boxes.
#[cfg(feature = "cnn")]
fn check_tracks(path: &Path, frames: u32) {
    let tracks = roadtrack::io::mot::read_tracks(path).expect("tracks");
    assert!(!tracks.is_empty(), "no tracks in {}", path.display());
    for p in &tracks {
        assert!((1..=frames).contains(&p.frame), "frame {}", p.frame);
        let b = p.bbox;
        assert!(b.left.is_finite() && b.top.is_finite() && b.width > 0.0 && b.height > 0.0);
    }
}

#[cfg(feature = "cnn")]
#[test]
fn phd_with_the_tiny_cnn_writes_valid_tracks_and_bad_models_exit_1() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    simulate(&seq, SceneKind::Crossing, ViewKind::Oblique, 12);
    let tracks = dir.path().join("t.txt");
    let o = bin()
        .arg("track")
        .arg(&seq)
        .args(["--method", "phd", "--likelihood", "cnn", "-q", "--model"])
        .arg(TINY_CNN)
        .arg("-o")
        .arg(&tracks)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    check_tracks(&tracks, 12);

    // Missing model, a model that is not ONNX, no --model: exit 1 with the file named.
    let text = dir.path().join("notes.onnx");
    std::fs::write(&text, "not a model\n").expect("write");
    let absent = dir.path().join("absent.onnx");
    for (model, needle) in [
        (Some(absent.as_path()), "absent.onnx"),
        (Some(text.as_path()), "notes.onnx"),
        (None, "--model"),
    ] {
        let mut cmd = bin();
        cmd.arg("track")
            .arg(&seq)
            .args(["--method", "phd", "--likelihood", "cnn", "-q", "-o"])
            .arg(dir.path().join("x.txt"));
        if let Some(m) = model {
            cmd.arg("--model").arg(m);
        }
        let o = cmd.output().expect("run");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(needle), "{err}");
    }
    // The SSD likelihood with a file that is not a TensorFlow graph names it too.
    let o = bin()
        .arg("track")
        .arg(&seq)
        .args(["--method", "phd", "--likelihood", "ssd", "-q", "--model"])
        .arg(TINY_CNN)
        .arg("-o")
        .arg(dir.path().join("x.txt"))
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("tiny_classifier.onnx"));
}

#[cfg(feature = "cnn")]
#[test]
fn a_model_trained_by_train_is_loaded_by_the_tracker_densely_and_per_window() {
    // Train on one seed's sequence, track another seed's: what docs/EXPERIMENTS.md does
    // at full size.
    let dir = tempfile::tempdir().expect("tempdir");
    let train_seq = dir.path().join("train");
    let cfg = SimConfig {
        scene: SceneKind::Crossing,
        view: ViewKind::Oblique,
        frames: 10,
        ..Default::default()
    };
    roadtrack_sim::simulate(&cfg, 9, &train_seq, &mut |_, _| {}).expect("simulate");
    let model = dir.path().join("person.onnx");
    let o = bin()
        .arg("train")
        .arg("--sequence")
        .arg(&train_seq)
        .args(["--epochs", "1", "--max-positives", "60", "--seed", "1"])
        .args(["--input-size", "32x16", "-q", "-o"])
        .arg(&model)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let seq = dir.path().join("seq");
    simulate(&seq, SceneKind::Crossing, ViewKind::Oblique, 10);
    for (method, stride) in [("phd", "8"), ("pf", "0")] {
        let tracks = dir.path().join(format!("{method}.txt"));
        let o = bin()
            .arg("track")
            .arg(&seq)
            .args([
                "--method",
                method,
                "--likelihood",
                "cnn",
                "--dense-stride",
                stride,
            ])
            .arg("--model")
            .arg(&model)
            .args(["-q", "-o"])
            .arg(&tracks)
            .output()
            .expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        check_tracks(&tracks, 10);
    }
}

/// `--likelihood detections` (the filters' default) against the paper's colour likelihood
/// on the same public detections; the flag's usage errors and a bad `[detections]` field.
#[test]
fn filters_weigh_particles_by_the_detections_and_refuse_bad_settings() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    simulate(&seq, SceneKind::Crossing, ViewKind::Oblique, 30);
    let gt = roadtrack::io::mot::read_gt(&seq.join("gt/gt.txt")).expect("gt");
    let truth = roadtrack::eval::papers::points_from_gt(&gt);
    for method in ["pf", "phd"] {
        let score = |likelihood: &str| {
            let out = dir.path().join(format!("{method}_{likelihood}.txt"));
            let o = bin()
                .arg("track")
                .arg(&seq)
                .args([
                    "--method",
                    method,
                    "--detector",
                    "file",
                    "-q",
                    "--seed",
                    "1",
                ])
                .args(["--likelihood", likelihood, "-o"])
                .arg(&out)
                .output()
                .expect("run");
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let tracks = roadtrack::io::mot::read_tracks(&out).expect("tracks");
            let t = roadtrack::eval::papers::detection_table(
                &truth,
                &roadtrack::eval::papers::points_from_tracks(&tracks),
                5.0,
            )
            .expect("table");
            t.precision * t.recall
        };
        let (detections, colour) = (score("detections"), score("colour"));
        assert!(
            detections > 0.6 && detections > colour + 0.2,
            "{method}: detections {detections:.3}, colour {colour:.3}"
        );
    }
    let o = bin()
        .args(["track", "x", "--method", "phd", "--as-published"])
        .args(["--likelihood", "detections"])
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(2), "{}", common::stderr(&o));
    let cfg = dir.path().join("bad.toml");
    std::fs::write(&cfg, "[detections]\ndetection_prob = 2.0\n").expect("write");
    let o = bin()
        .args(["track", "x", "--method", "pf", "--config"])
        .arg(&cfg)
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(1));
    let e = common::stderr(&o);
    assert!(
        e.contains("detections.detection_prob") && e.contains("bad.toml"),
        "{e}"
    );
}
