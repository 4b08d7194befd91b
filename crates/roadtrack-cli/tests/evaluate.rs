//! End-to-end tests of `roadtrack evaluate`: the real binary on committed golden cases
//! (TrackEval's numbers, `crates/roadtrack/tests/golden/metrics/`) and on small inputs whose
//! answers are known by hand.

mod common;
use common::{bin, stderr};

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

fn golden(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../roadtrack/tests/golden/metrics")
        .join(name)
}

fn run(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    let mut c = bin();
    c.arg("-q").arg("evaluate");
    for a in args {
        c.arg(a);
    }
    c.output().expect("run roadtrack")
}

fn json_of(o: &Output) -> Value {
    assert!(o.status.success(), "{}", stderr(o));
    serde_json::from_slice(&o.stdout).expect("stdout is one JSON object")
}

/// Every number of `expected` equals the one at the same place in `actual` to 1e-6.
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
            let (e, a) = (e.as_f64().unwrap_or(f64::NAN), a.as_f64().unwrap_or(0.0));
            if (e - a).abs() > 1e-6 || e.is_nan() || a.is_nan() {
                out.push(format!("{path}: TrackEval {e}, ours {a}"));
            }
        }
        (e, a) if e == a => {}
        (e, a) => out.push(format!("{path}: TrackEval {e}, ours {a}")),
    }
}

fn trackeval_of(case: &str) -> Value {
    let text = std::fs::read_to_string(golden(&format!("{case}.json"))).expect("golden json");
    let v: Value = serde_json::from_str(&text).expect("parse golden");
    v["trackeval"].clone()
}

/// A sequence folder: 10 frames of ground truth (3 pedestrians and a car), seqLength 12.
fn sequence(dir: &Path) -> PathBuf {
    let seq = dir.join("seq");
    std::fs::create_dir_all(seq.join("gt")).expect("mkdir");
    let mut gt = String::new();
    for f in 1..=10 {
        for id in 1..=3 {
            gt += &format!("{f},{id},{},{},20,40,1,1,1\n", 30 * id + f, 10 + 5 * id);
        }
        gt += &format!("{f},4,{},200,60,30,1,3,1\n", 100 + 4 * f);
    }
    std::fs::write(seq.join("gt/gt.txt"), gt).expect("write gt");
    std::fs::write(
        seq.join("seqinfo.ini"),
        "[Sequence]\nname=seq\nimDir=img1\nframeRate=25\nseqLength=12\nimWidth=320\nimHeight=240\nimExt=.png\n",
    )
    .expect("write seqinfo");
    seq
}

/// The ground truth of [`sequence`] written as a tracks file, ids shifted by 100.
fn tracks_equal_to_truth(seq: &Path, out: &Path) -> PathBuf {
    let gt = std::fs::read_to_string(seq.join("gt/gt.txt")).expect("read gt");
    let rows: String = gt
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let id: u64 = f[1].parse().expect("id");
            format!(
                "{},{},{},{},{},{},1,-1,-1,-1\n",
                f[0],
                id + 100,
                f[2],
                f[3],
                f[4],
                f[5]
            )
        })
        .collect();
    let p = out.join("tracks.txt");
    std::fs::write(&p, rows).expect("write tracks");
    p
}

#[test]
fn truth_against_itself_is_perfect_and_the_folder_gives_the_sequence_length() {
    let d = tempfile::tempdir().expect("tempdir");
    let seq = sequence(d.path());
    let tracks = tracks_equal_to_truth(&seq, d.path());
    let v = json_of(&run(&[
        &"--truth",
        &seq,
        &"--tracks",
        &tracks,
        &"--classes",
        &"agnostic",
        &"--json",
    ]));
    for k in [
        "MOTA", "MOTP", "IDF1", "IDP", "IDR", "HOTA", "DetA", "AssA", "LocA",
    ] {
        assert_eq!(v[k].as_f64(), Some(1.0), "{k}");
    }
    for (k, n) in [("TP", 40), ("FP", 0), ("FN", 0), ("IDSW", 0), ("MT", 4)] {
        assert_eq!(v[k].as_u64(), Some(n), "{k}");
    }
    assert_eq!(
        v["num_frames"].as_u64(),
        Some(12),
        "seqLength from seqinfo.ini"
    );
    assert_eq!(v["CLR_Frames"].as_u64(), Some(12));
    // Pedestrian mode (TrackEval MOT17): the car is not evaluated and, not being a
    // distractor class, its tracker boxes stay as false positives.
    let p = json_of(&run(&[&"--truth", &seq, &"--tracks", &tracks, &"--json"]));
    assert_eq!(
        (p["TP"].as_u64(), p["FP"].as_u64(), p["FN"].as_u64()),
        (Some(30), Some(10), Some(0))
    );
    assert_eq!(p["IDR"].as_f64(), Some(1.0));
    // The same through the gt file (no seqinfo.ini): the last frame is the length.
    let f = json_of(&run(&[
        &"--truth",
        &seq.join("gt/gt.txt"),
        &"--tracks",
        &tracks,
        &"--json",
    ]));
    assert_eq!(f["num_frames"].as_u64(), Some(10));
}

#[test]
fn golden_cases_give_trackevals_numbers_through_the_cli() {
    for case in ["tud_campus_perturbed", "stadtmitte_distractors"] {
        let expected = trackeval_of(case);
        let n = expected["num_frames"]
            .as_u64()
            .expect("num_frames")
            .to_string();
        let v = json_of(&run(&[
            &"--truth",
            &golden(&format!("{case}.gt.txt")),
            &"--tracks",
            &golden(&format!("{case}.tracks.txt")),
            &"--num-frames",
            &n,
            &"--json",
        ]));
        let mut bad = Vec::new();
        compare(case, &expected, &v, &mut bad);
        assert!(bad.is_empty(), "{}", bad.join("\n"));
    }
    // Without preprocessing, through --no-preprocess.
    let case = "stadtmitte_distractors_no_preproc";
    let expected = trackeval_of(case);
    let v = json_of(&run(&[
        &"--truth",
        &golden(&format!("{case}.gt.txt")),
        &"--tracks",
        &golden(&format!("{case}.tracks.txt")),
        &"--num-frames",
        &"179",
        &"--no-preprocess",
        &"--json",
    ]));
    let mut bad = Vec::new();
    compare(case, &expected, &v, &mut bad);
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The per-class golden case's tracks with their classes, as a trajectories CSV.
fn per_class_trajectories(dir: &Path) -> PathBuf {
    let tracks =
        std::fs::read_to_string(golden("multiclass_per_class.tracks.txt")).expect("tracks");
    let classes =
        std::fs::read_to_string(golden("multiclass_per_class.track_classes.csv")).expect("classes");
    let mut class_of = std::collections::HashMap::new();
    for l in classes.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        class_of.insert((f[0].to_owned(), f[1].to_owned()), f[2].to_owned());
    }
    let mut csv = String::from("frame,time_s,id,class,x_px,y_px,w_px,h_px,score\n");
    for l in tracks.lines() {
        let f: Vec<&str> = l.split(',').collect();
        let name = match class_of[&(f[0].to_owned(), f[1].to_owned())].as_str() {
            "1" => "pedestrian",
            "3" => "car",
            "4" => "bicycle",
            "5" => "motorcycle",
            _ => "truck",
        };
        let n = |i: usize| f[i].parse::<f64>().expect("number");
        csv += &format!(
            "{},0,{},{name},{},{},{},{},1\n",
            f[0],
            f[1],
            n(2) + n(4) / 2.0,
            n(3) + n(5) / 2.0,
            n(4),
            n(5)
        );
    }
    let p = dir.join("trajectories.csv");
    std::fs::write(&p, csv).expect("write trajectories");
    p
}

#[test]
fn per_class_and_agnostic_golden_cases_through_a_trajectories_csv() {
    let d = tempfile::tempdir().expect("tempdir");
    let traj = per_class_trajectories(d.path());
    for (case, mode) in [
        ("multiclass_per_class", "per-class"),
        ("multiclass_agnostic", "agnostic"),
    ] {
        let expected = trackeval_of(case);
        let v = json_of(&run(&[
            &"--truth",
            &golden(&format!("{case}.gt.txt")),
            &"--tracks",
            &traj,
            &"--classes",
            &mode,
            &"--class-list",
            &"1,3,4,5,6",
            &"--num-frames",
            &"40",
            &"--json",
        ]));
        let mut bad = Vec::new();
        compare(case, &expected, &v, &mut bad);
        assert!(bad.is_empty(), "{}", bad.join("\n"));
    }
}

#[test]
fn the_table_names_the_interface_columns_and_json_has_the_interface_keys() {
    let case = "tud_campus_shipped";
    let args: [&dyn AsRef<std::ffi::OsStr>; 4] = [
        &"--truth",
        &golden(&format!("{case}.gt.txt")),
        &"--tracks",
        &golden(&format!("{case}.tracks.txt")),
    ];
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout);
    for col in [
        "HOTA",
        "DetA",
        "AssA",
        "LocA",
        "MOTA",
        "MOTP",
        "IDF1",
        "IDSW",
        "pedestrian",
    ] {
        assert!(table.contains(col), "{col} missing from\n{table}");
    }
    let mut with_json = args.to_vec();
    with_json.push(&"--json");
    let v = json_of(&run(&with_json));
    for k in [
        "MOTA", "MOTP", "FP", "FN", "IDSW", "IDF1", "IDP", "IDR", "HOTA", "DetA", "AssA", "LocA",
    ] {
        assert!(v[k].is_number(), "key {k} missing or not a number");
    }
    // -o writes the same bytes to a file.
    let d = tempfile::tempdir().expect("tempdir");
    let out = d.path().join("report.json");
    let mut to_file = with_json.clone();
    to_file.push(&"-o");
    to_file.push(&out);
    assert!(run(&to_file).status.success());
    let o = run(&with_json);
    assert_eq!(std::fs::read(&out).expect("report"), o.stdout);
}

#[test]
fn usage_errors_exit_2_and_bad_input_exits_1_naming_file_and_line() {
    let d = tempfile::tempdir().expect("tempdir");
    let seq = sequence(d.path());
    let tracks = tracks_equal_to_truth(&seq, d.path());
    let usage: Vec<(Vec<&dyn AsRef<std::ffi::OsStr>>, &str)> = vec![
        (vec![], "--tracks"),
        (vec![&"--tracks", &tracks], "--truth"),
        (vec![&"--truth", &seq], "--tracks"),
        (vec![&"--matches", &tracks], "--match-truth"),
        (vec![&"--ospa", &"--estimates", &tracks], "--truth-points"),
        (
            vec![&"--truth", &seq, &"--detections", &tracks],
            "--gate-px",
        ),
        (
            vec![
                &"--truth",
                &seq,
                &"--tracks",
                &tracks,
                &"--classes",
                &"per-class",
            ],
            "trajectories CSV",
        ),
        (
            vec![
                &"--truth",
                &seq,
                &"--tracks",
                &tracks,
                &"--classes",
                &"nope",
            ],
            "nope",
        ),
        (
            vec![&"--truth", &seq, &"--tracks", &tracks, &"--gate-px", &"5"],
            "--rmse",
        ),
    ];
    for (args, what) in usage {
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{what}: {}", stderr(&o));
        assert!(stderr(&o).contains(what), "{what} not in {}", stderr(&o));
    }
    // A repeated id in frame 2 of the tracks: exit 1 naming the file and line.
    let bad = d.path().join("bad.txt");
    std::fs::write(
        &bad,
        "1,1,0,0,10,10,1,-1,-1,-1\n2,1,0,0,10,10,1,-1,-1,-1\n2,1,5,0,10,10,1,-1,-1,-1\n",
    )
    .expect("write");
    let o = run(&[&"--truth", &seq, &"--tracks", &bad]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("bad.txt:3") && stderr(&o).contains("twice"),
        "{}",
        stderr(&o)
    );
    // A row beyond seqLength (12).
    std::fs::write(&bad, "13,1,0,0,10,10,1,-1,-1,-1\n").expect("write");
    let o = run(&[&"--truth", &seq, &"--tracks", &bad]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("last frame 12"), "{}", stderr(&o));
    // A missing file.
    let o = run(&[&"--truth", &d.path().join("none.txt"), &"--tracks", &tracks]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("none.txt"), "{}", stderr(&o));
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

#[test]
fn rmse_of_a_known_offset_in_px_and_through_a_calibration_in_metres() {
    // Truth: one pedestrian whose box centre moves 2 px per frame in x; the track is 3 px to
    // the right and 4 px lower: x error 3, y error 4, position 5, same speed.
    let d = tempfile::tempdir().expect("tempdir");
    let mut gt = String::new();
    let mut tr = String::new();
    for f in 1..=6 {
        gt += &format!("{f},1,{},20,10,30,1,1,1\n", 2 * f);
        tr += &format!("{f},7,{},24,10,30,1,-1,-1,-1\n", 2 * f + 3);
    }
    let gt = write(d.path(), "gt.txt", &gt);
    let tr = write(d.path(), "tr.txt", &tr);
    let cal = write(d.path(), "cal.toml", "metres_per_pixel = 0.5\n");
    let v = json_of(&run(&[
        &"--truth",
        &gt,
        &"--tracks",
        &tr,
        &"--rmse",
        &"--calibration",
        &cal,
        &"--fps",
        &"10",
        &"--json",
    ]));
    let r = &v["rmse"]["report"];
    assert_eq!(r["pairs"], serde_json::json!([[1, 7]]));
    assert_eq!(r["position_samples"].as_u64(), Some(6));
    assert_eq!(r["speed_samples"].as_u64(), Some(5));
    let close = |x: &Value, want: f64| (x.as_f64().unwrap_or(f64::NAN) - want).abs() < 1e-9;
    assert!(
        close(&r["px"]["x"], 3.0) && close(&r["px"]["y"], 4.0),
        "{r}"
    );
    assert!(close(&r["px"]["position"], 5.0) && close(&r["px"]["speed"], 0.0));
    assert!(close(&r["ground"]["position"], 2.5), "0.5 m per px: {r}");
    assert!(v["MOTA"].is_number(), "the tracking metrics come too");
    // The table names the units.
    let o = run(&[&"--truth", &gt, &"--tracks", &tr, &"--rmse"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("RMSE") && text.contains("px/s"), "{text}");
}

#[test]
fn detection_table_match_rate_occlusion_and_ospa_run_without_tracks() {
    let d = tempfile::tempdir().expect("tempdir");
    // Truth centres (10, 20) and (100, 20) in frame 1, (10, 20) in frame 2.
    let gt = write(
        d.path(),
        "gt.txt",
        "1,1,5,10,10,20,1,1,1\n1,2,95,10,10,20,1,1,1\n2,1,5,10,10,20,1,1,1\n",
    );
    // Frame 1: one near truth 1, one far from everything; frame 2: one near truth 1.
    let dets = write(d.path(), "d.csv", "frame,x,y\n1,12,21\n1,300,300\n2,9,20\n");
    let v = json_of(&run(&[
        &"--truth",
        &gt,
        &"--detections",
        &dets,
        &"--gate-px",
        &"5",
        &"--json",
    ]));
    let t = &v["detection_table"]["table"];
    assert_eq!(
        (t["tp"].as_u64(), t["fp"].as_u64(), t["fn"].as_u64()),
        (Some(2), Some(1), Some(1)),
        "{t}"
    );
    assert_eq!(
        (t["objects_detected"].as_u64(), t["objects"].as_u64()),
        (Some(1), Some(2))
    );
    assert!(
        v.get("MOTA").is_none(),
        "no tracking metrics without --tracks"
    );

    let truth = write(d.path(), "truth.csv", "id1,id2\n1,10\n2,\n3,30\n");
    let matches = write(
        d.path(),
        "m.csv",
        "id1,id2,probability\n1,10,0.9\n2,,0.8\n3,31,0.7\n",
    );
    let v = json_of(&run(&[
        &"--matches",
        &matches,
        &"--match-truth",
        &truth,
        &"--json",
    ]));
    let r = &v["correct_match_rate"];
    assert_eq!(
        (r["n_correct"].as_u64(), r["n_vehicles"].as_u64()),
        (Some(2), Some(3))
    );
    assert_eq!(r["wrong_partner"].as_u64(), Some(1));

    let occ = write(
        d.path(),
        "o.csv",
        "frame,id,visible_blocks,separated\n1,1,2,1\n2,1,2,0\n3,1,5,1\n",
    );
    let v = json_of(&run(&[&"--occlusion", &occ, &"--json"]));
    let bins = v["separation"].as_array().expect("bins");
    assert_eq!(bins.len(), 2);
    assert_eq!(bins[0]["success_rate"].as_f64(), Some(0.5));
    assert_eq!(bins[1]["visible_blocks"].as_u64(), Some(5));
    let o = run(&[&"--occlusion", &occ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("visible blocks"));

    // OSPA: step 1 one estimate 3 units off (OSPA 3); step 2 a missed target (OSPA = c).
    let pts = write(d.path(), "p.csv", "step,x,y\n1,0,0\n2,50,50\n");
    let est = write(
        d.path(),
        "e.csv",
        "step,label,x,y,vx,vy,weight\n1,1,3,0,0,0,1\n",
    );
    let v = json_of(&run(&[
        &"--ospa",
        &"--estimates",
        &est,
        &"--truth-points",
        &pts,
        &"--cutoff",
        &"10",
        &"--order",
        &"1",
        &"--json",
    ]));
    let o = &v["ospa"];
    assert_eq!(o["steps"].as_u64(), Some(2));
    assert_eq!(o["per_step"][0]["ospa"].as_f64(), Some(3.0));
    assert_eq!(o["per_step"][1]["ospa"].as_f64(), Some(10.0));
    assert_eq!(o["mean_ospa"].as_f64(), Some(6.5));
    // A bad cut-off is wrong usage.
    let o = run(&[
        &"--ospa",
        &"--estimates",
        &est,
        &"--truth-points",
        &pts,
        &"--cutoff",
        &"0",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn a_truth_without_pedestrians_warns_that_the_default_scores_pedestrians_only() {
    let d = tempfile::tempdir().expect("tempdir");
    // Two cars (MOT17 class 3) tracked perfectly.
    let gt = write(
        d.path(),
        "gt.txt",
        "1,1,10,10,20,10,1,3,1\n1,2,50,10,20,10,1,3,1\n2,1,12,10,20,10,1,3,1\n2,2,52,10,20,10,1,3,1\n",
    );
    let tracks = write(
        d.path(),
        "t.txt",
        "1,7,10,10,20,10,1,-1,-1,-1\n1,8,50,10,20,10,1,-1,-1,-1\n2,7,12,10,20,10,1,-1,-1,-1\n2,8,52,10,20,10,1,-1,-1,-1\n",
    );
    let o = run(&[&"--truth", &gt, &"--tracks", &tracks, &"--json"]);
    let m = json_of(&o);
    assert!(
        m["HOTA"].as_f64().unwrap_or(0.0) < 0.5,
        "pedestrian mode scores no car: {m}"
    );
    let err = stderr(&o);
    assert!(
        err.contains("no pedestrians") && err.contains("--classes agnostic"),
        "{err}"
    );
    let o = run(&[
        &"--truth",
        &gt,
        &"--tracks",
        &tracks,
        &"--json",
        &"--classes",
        &"agnostic",
    ]);
    assert!((json_of(&o)["HOTA"].as_f64().unwrap_or(0.0) - 1.0).abs() < 1e-9);
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}
