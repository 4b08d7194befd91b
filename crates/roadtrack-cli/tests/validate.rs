//! Hardened inputs: no bad value is accepted silently. A bad file is exit 1 with a message
//! naming the file and the field (or line); a bad flag, or flags that contradict each
//! other, is a usage error (exit 2) naming the flag.

mod common;
use common::{bin, fixture, stderr};

use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run roadtrack")
}

/// Asserts exit status `code` and that stderr contains every needle.
#[track_caller]
fn expect(o: &Output, code: i32, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(code), "{needles:?}: {e}");
    for n in needles {
        assert!(e.contains(n), "{n:?} missing from: {e}");
    }
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Two frames of one track, MOTChallenge layout.
const TRACKS: &str =
    "1,1,10,10,4,4,1,-1,-1,-1\n2,1,14,10,4,4,1,-1,-1,-1\n3,1,18,10,4,4,1,-1,-1,-1\n";

#[test]
fn calibration_arrays_need_their_exact_length_and_nan_is_named_by_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let tracks = write(d, "t.txt", TRACKS);
    let out = d.join("out");
    for (text, field) in [
        (
            "image_from_ground = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]\n",
            "exactly 3 values",
        ),
        (
            "metres_per_pixel = 0.5\norigin_m = [1.0, 2.0, 3.0, 4.0]\n",
            "exactly 2 values",
        ),
        (
            "metres_per_pixel = 0.5\nrotation_deg = nan\n",
            "rotation_deg",
        ),
        ("metres_per_pixel = nan\n", "metres_per_pixel"),
        (
            "metres_per_pixel = 0.5\norigin_m = [0.0, inf]\n",
            "origin_m",
        ),
        (
            "image_from_ground = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]\n",
            "calib.toml: image_from_ground: matrix is singular",
        ),
    ] {
        let calib = write(d, "calib.toml", text);
        let o = run(&[
            "analyze",
            s(&tracks),
            "--calibration",
            s(&calib),
            "-o",
            s(&out),
        ]);
        expect(&o, 1, &["calib.toml", field]);
        assert!(!stderr(&o).contains("Calibration."), "{}", stderr(&o));
    }
}

#[test]
fn zones_with_nan_are_rejected_naming_the_file_and_the_zone() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let tracks = write(d, "t.txt", TRACKS);
    let calib = write(d, "calib.toml", "metres_per_pixel = 0.5\n");
    let out = d.join("out");
    for (text, needles) in [
        (
            "[[line]]\nname = \"stop N\"\na = [nan, 0.0]\nb = [5.0, 0.0]\n",
            ["line", "`stop N`"],
        ),
        (
            "[[zone]]\nname = \"north\"\npolygon = [[0, 0], [1, 0], [1, inf]]\n",
            ["zone", "`north`"],
        ),
        (
            "[[lane]]\nname = \"lane 1\"\npolygon = [[0, 0], [1, 0], [nan, 1]]\n",
            ["lane", "`lane 1`"],
        ),
        (
            "[[line]]\nname = \"l\"\na = [0.0, 0.0, 0.0]\nb = [5.0, 0.0]\n",
            ["exactly 2 values", "line"],
        ),
        (
            "[stitch]\nmax_gap_s = nan\n",
            ["stitch.max_gap_s", "finite"],
        ),
        (
            "[stitch]\nmax_overlap_s = -1.0\n",
            ["stitch.max_overlap_s", "[0, ∞)"],
        ),
    ] {
        let zones = write(d, "zones.toml", text);
        let o = run(&[
            "analyze",
            s(&tracks),
            "--calibration",
            s(&calib),
            "--zones",
            s(&zones),
            "-o",
            s(&out),
        ]);
        expect(&o, 1, &["zones.toml"]);
        expect(&o, 1, &needles);
    }
    let o = run(&[
        "analyze",
        s(&tracks),
        "--calibration",
        s(&calib),
        "--fps",
        "0",
    ]);
    expect(&o, 2, &["--fps", "must be in (0, 1000]"]);
}

#[test]
fn mot_tracks_with_a_column_cut_out_are_rejected_by_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    // bb_left cut out of every line: 9 fields, the rest shifted.
    let cut = write(
        dir.path(),
        "cut.txt",
        "1,1,10,4,4,1,-1,-1,-1\n2,1,10,4,4,1,-1,-1,-1\n",
    );
    let o = run(&["check", "--format", "mot-tracks", s(&cut)]);
    expect(&o, 1, &["cut.txt:1:", "9 fields"]);
    // Cut from one line only.
    let one = write(
        dir.path(),
        "one.txt",
        "1,1,10,10,4,4,1,-1,-1,-1\n2,1,10,4,4,1,-1,-1,-1\n",
    );
    let o = run(&["check", "--format", "mot-tracks", s(&one)]);
    expect(&o, 1, &["one.txt:2:", "line 1 has 10"]);
    let ok = write(dir.path(), "ok.txt", TRACKS);
    expect(&run(&["check", "--format", "mot-tracks", s(&ok)]), 0, &[]);
}

/// A reader that has gone (`roadtrack check F | head -0`): the output ends quietly, exit 0,
/// no panic.
#[test]
fn a_closed_standard_output_is_not_a_panic() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ok = write(dir.path(), "ok.txt", TRACKS);
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    let o = bin()
        .args(["check", "--format", "mot-tracks"])
        .arg(&ok)
        .stdout(writer)
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
}

#[test]
fn an_unknown_bench_stage_is_a_usage_error_listing_the_stages() {
    let o = run(&["bench", "--stages", "warp"]);
    expect(&o, 2, &["warp", "decode", "pipeline", "cnn"]);
}

#[test]
fn flags_of_another_method_or_mode_are_usage_errors() {
    let seq = fixture("tiny_sequence");
    let seq = s(&seq);
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec![
                "track",
                seq,
                "--method",
                "phd",
                "--mrf-variant",
                "legacy",
                "--object-maps",
                "m",
            ],
            "--mrf-variant, --object-maps",
        ),
        (
            vec!["track", seq, "--method", "pf", "--object-maps", "m"],
            "--object-maps",
        ),
        (
            vec![
                "track",
                seq,
                "--method",
                "relaxation",
                "--likelihood",
                "cnn",
            ],
            "--likelihood",
        ),
        (
            vec!["track", seq, "--method", "mrf", "--model", "m.onnx"],
            "--model",
        ),
        (
            vec![
                "track",
                seq,
                "--method",
                "relaxation",
                "--window-scale",
                "2",
            ],
            "--window-scale",
        ),
        (
            vec!["track", seq, "--method", "mrf", "--dense-stride", "4"],
            "--dense-stride",
        ),
        (
            vec!["track", seq, "--method", "phd", "--max-missed-frames", "3"],
            "--max-missed-frames",
        ),
        (
            vec![
                "track",
                seq,
                "--method",
                "mrf",
                "--detector-config",
                "d.toml",
            ],
            "--detector-config",
        ),
        (
            vec!["track", seq, "--method", "phd", "--model", "m.onnx"],
            "--model needs --likelihood",
        ),
        (
            vec![
                "track",
                seq,
                "--method",
                "relaxation",
                "--detector",
                "file",
                "--detector-config",
                "d.toml",
            ],
            "--detector-config",
        ),
        (
            vec![
                "track",
                seq,
                "--method",
                "mrf",
                "--as-published",
                "--confirm-hits",
                "2",
            ],
            "--confirm-hits",
        ),
        (
            vec!["track", seq, "--method", "mrf", "--ground-point", "centre"],
            "--calibration",
        ),
        (
            vec!["track", seq, "--method", "mrf", "--smooth-s", "1"],
            "--calibration",
        ),
        (
            vec![
                "track",
                seq,
                "--method",
                "mrf",
                "--detector",
                "background",
                "--detections",
                "x.txt",
            ],
            "--detections",
        ),
        (
            vec!["detect", seq, "--detector", "file", "--min-area", "5"],
            "--min-area",
        ),
        (vec!["detect", seq, "--motion-gate", "0.2"], "--motion-gate"),
        (vec!["detect", seq, "--dots"], "--dots"),
        (vec!["track", seq, "--method", "mrf", "--dots"], "--dots"),
        (vec!["detect", seq, "--refine-boxes"], "--refine-boxes"),
        (
            vec![
                "detect",
                seq,
                "--detector",
                "background",
                "--refine-pedestrians",
            ],
            "--refine-boxes",
        ),
        (
            vec![
                "detect",
                seq,
                "--detector",
                "background",
                "--motion-gate",
                "0.2",
            ],
            "--motion-gate",
        ),
        (
            vec!["track", seq, "--method", "phd", "--link-colour", "50"],
            "--link-gaps",
        ),
        (
            vec!["detect", seq, "--detections", "x.txt", "--masks", "m"],
            "--masks",
        ),
        (vec!["sweep", "p", "--own-weight", "1"], "--own-weight"),
        (
            vec!["experiment", "p", "--variant", "bidirectional"],
            "--variant",
        ),
        (
            vec![
                "match",
                "a.csv",
                "b.csv",
                "--variant",
                "unidirectional",
                "--backward-support-weight",
                "1",
            ],
            "--backward-support-weight",
        ),
        (
            vec![
                "plot", "--series", "s.csv", "--x", "a", "--y", "b", "--width", "300",
            ],
            "--width",
        ),
    ];
    for (args, flag) in cases {
        let o = bin().current_dir(d).args(&args).output().expect("run");
        expect(&o, 2, &[flag]);
        assert!(stderr(&o).contains("Usage:"), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn bad_flag_values_are_usage_errors_naming_the_flag() {
    let seq = fixture("tiny_sequence");
    let seq = s(&seq);
    let cases: Vec<Vec<&str>> = vec![
        vec!["detect", seq, "--step", "0"],
        vec!["detect", seq, "--start", "0"],
        vec!["detect", seq, "--end", "0"],
        vec!["detect", seq, "--fps", "nan"],
        vec!["detect", seq, "--fps=-5"],
        vec!["detect", seq, "--fps", "-5"],
        vec![
            "analyze",
            "t.txt",
            "--calibration",
            "c.toml",
            "--smooth-s",
            "-0.5",
        ],
        vec!["detect", seq, "--threshold-sigma", "0"],
        vec!["track", seq, "--method", "pf", "--window-scale", "inf"],
        vec![
            "track",
            seq,
            "--method",
            "mrf",
            "--calibration",
            "c.toml",
            "--smooth-s=-1",
        ],
        vec!["track", seq, "--method", "mrf", "--confirm-hits", "0"],
        vec!["analyze", "t.txt", "--calibration", "c.toml", "--fps", "0"],
        vec![
            "analyze",
            "t.txt",
            "--calibration",
            "c.toml",
            "--smooth-s",
            "nan",
        ],
        vec![
            "evaluate",
            "--truth",
            seq,
            "--tracks",
            "t.txt",
            "--iou-threshold",
            "1.5",
        ],
        vec![
            "evaluate",
            "--truth",
            seq,
            "--tracks",
            "t.txt",
            "--num-frames",
            "0",
        ],
        vec![
            "evaluate",
            "--truth",
            seq,
            "--tracks",
            "t.txt",
            "--class-list",
            "1,0",
        ],
        vec![
            "evaluate",
            "--ospa",
            "--estimates",
            "e",
            "--truth-points",
            "p",
            "--alpha",
            "3",
        ],
        vec![
            "evaluate",
            "--ospa",
            "--estimates",
            "e",
            "--truth-points",
            "p",
            "--order",
            "0.5",
        ],
        vec![
            "evaluate",
            "--ospa",
            "--estimates",
            "e",
            "--truth-points",
            "p",
            "--cutoff",
            "nan",
        ],
        vec!["filter", "m.csv", "--detection-prob", "2"],
        vec!["filter", "m.csv", "--dt", "0"],
        vec!["filter", "m.csv", "--particles-per-target", "0"],
        vec!["filter", "m.csv", "--birth-rate=-1"],
        vec!["match", "a.csv", "b.csv", "--epsilon=-1"],
        vec!["match", "a.csv", "b.csv", "--own-weight", "nan"],
        vec!["simulate", "-o", "x", "--frames", "0"],
        vec!["simulate", "-o", "x", "--fps", "0"],
        vec!["simulate", "-o", "x", "--pairs", "0"],
        vec!["simulate", "-o", "x", "--pairs", "1", "--drop", "1"],
        vec!["simulate", "-o", "x", "--pairs", "1", "--position-noise=-1"],
        vec!["simulate", "-o", "x", "--pairs", "1", "--n-pairs", "0"],
        vec!["train", "--sequence", "s", "--train-fraction", "1"],
        vec!["train", "--sequence", "s", "--input-size", "0x3"],
        vec!["train", "--sequence", "s", "--epochs", "0"],
        vec!["train", "--sequence", "s", "--learning-rate=-1"],
        vec!["plot", "t.txt", "--fps", "0"],
        vec![
            "render",
            seq,
            "--tracks",
            "t.txt",
            "-o",
            "o",
            "--label-size",
            "0",
        ],
        vec!["bench", "--frames", "0"],
        vec!["demo", "--frames", "0"],
    ];
    for args in cases {
        let o = run(&args);
        let flag = args
            .iter()
            .rev()
            .find(|a| a.starts_with("--"))
            .expect("a flag");
        let flag = flag.split('=').next().unwrap_or(flag);
        expect(&o, 2, &[flag]);
    }
}

#[test]
fn flag_values_checked_after_parsing_name_the_flag_and_exit_2() {
    let seq = fixture("tiny_sequence");
    let seq = s(&seq);
    for (args, flag) in [
        (vec!["detect", seq, "--start", "5", "--end", "3"], "--end"),
        (
            vec!["detect", seq, "--detector", "cnn", "--motion-gate", "1.5"],
            "--motion-gate",
        ),
        (
            vec![
                "track",
                seq,
                "--method",
                "phd",
                "--link-gaps",
                "5",
                "--link-colour=-1",
            ],
            "--link-colour",
        ),
        (
            vec!["detect", seq, "--min-area", "900", "--max-area", "100"],
            "--min-area",
        ),
        (vec!["plot", "t.txt", "--width", "50"], "--width"),
        (vec!["simulate", "-o", "x", "--width", "8"], "--width"),
        (
            vec![
                "render",
                seq,
                "--tracks",
                "t.txt",
                "-o",
                "o",
                "--label-size",
                "2",
            ],
            "--label-size",
        ),
    ] {
        let o = run(&args);
        expect(&o, 2, &[flag]);
        let e = stderr(&o);
        assert!(
            !e.contains("Config.") && !e.contains("SourceOptions"),
            "{e}"
        );
    }
}

#[test]
fn bad_config_values_name_the_file_and_the_key() {
    let seq = fixture("tiny_sequence");
    let seq = s(&seq);
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (
            vec!["detect", seq],
            "[background]\nthreshold_sigma = nan\n",
            "bad.toml: background.threshold_sigma",
        ),
        (
            vec!["detect", seq],
            "[background]\nmax_sigma = inf\n",
            "bad.toml: background.max_sigma",
        ),
        (
            vec!["track", seq, "--method", "phd"],
            "[pf]\nparticles_per_object = 0\n",
            "bad.toml: pf.particles_per_object",
        ),
        (
            vec!["track", seq, "--method", "pf"],
            "[phd]\nsurvival_prob = nan\n",
            "bad.toml: phd.survival_prob",
        ),
        (
            vec!["track", seq, "--method", "mrf"],
            "cooling = nan\n",
            "bad.toml: cooling",
        ),
        (
            vec!["track", seq, "--method", "relaxation"],
            "own_weight = -1.0\n",
            "bad.toml: own_weight",
        ),
        (
            vec!["track", seq, "--method", "relaxation"],
            "rematch_gate_px = nan\n[relaxation]\nepsilon = 1e-6\n",
            "bad.toml: rematch_gate_px",
        ),
        (
            vec!["track", seq, "--method", "relaxation"],
            "[relaxation]\nepsilon = nan\n",
            "bad.toml: relaxation.epsilon",
        ),
        (
            vec!["match", "a.csv", "b.csv"],
            "neighbour_radius_px = inf\n",
            "bad.toml: neighbour_radius_px",
        ),
        (
            vec!["evaluate", "--truth", seq, "--tracks", "t.txt"],
            "iou_threshold = nan\n",
            "bad.toml: iou_threshold",
        ),
        (
            vec!["filter", "m.csv"],
            "measurement_sigma = nan\n",
            "bad.toml: measurement_sigma",
        ),
        (
            vec!["filter", "m.csv"],
            "merge_distance_sigmas = -1.0\n",
            "bad.toml: merge_distance_sigmas",
        ),
        (
            vec!["filter", "m.csv"],
            "process_sigma = nan\n",
            "bad.toml: process_sigma",
        ),
        (
            vec!["simulate", "-o", "x"],
            "[road]\nlength_m = nan\n",
            "bad.toml: road.length_m",
        ),
    ];
    for (args, text, needle) in cases {
        let bad = write(d, "bad.toml", text);
        let o = bin()
            .current_dir(d)
            .args(&args)
            .arg("--config")
            .arg(&bad)
            .output()
            .expect("run");
        expect(&o, 1, &[needle]);
        assert!(!stderr(&o).contains("Config."), "{}", stderr(&o));
    }
}

/// A bad file given to a flag other than `--config` is reported under that flag's name.
#[test]
fn a_bad_detector_config_is_named_by_its_own_flag() {
    let seq = fixture("tiny_sequence");
    let dir = tempfile::tempdir().expect("tempdir");
    let bad = write(
        dir.path(),
        "bad.toml",
        "[background]\nthreshold_sigma = nan\n",
    );
    let o = run(&[
        "track",
        s(&seq),
        "--method",
        "relaxation",
        "--detector-config",
        s(&bad),
    ]);
    expect(
        &o,
        1,
        &[
            "reading --detector-config",
            "bad.toml: background.threshold_sigma",
        ],
    );
}
