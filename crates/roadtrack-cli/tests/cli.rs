//! End-to-end tests of the `roadtrack` binary.

mod common;
use common::{bin, fixture, stderr, vtest};

use std::process::{Command, Output};

fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("run roadtrack")
}

#[test]
fn detect_finds_both_rectangles_of_the_tiny_sequence_in_every_frame() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("d.csv");
    let o = run(bin()
        .arg("detect")
        .arg(fixture("tiny_sequence"))
        .arg("-o")
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    let dets = roadtrack::io::detections::read_detections(&out).expect("read output");
    assert_eq!(dets.len(), 20, "2 regions × 10 frames");
    for i in 1..=10u32 {
        let f: Vec<_> = dets.iter().filter(|d| d.frame == i).collect();
        assert_eq!(f.len(), 2, "frame {i}");
        let fi = f64::from(i);
        // Known centres: red (10 + 3i, 20), blue (85 − 5i, 49) — see fixtures/README.md.
        let red = f
            .iter()
            .find(|d| d.colour_rgb.is_some_and(|c| c[0] > 150.0))
            .expect("red");
        let blue = f
            .iter()
            .find(|d| d.colour_rgb.is_some_and(|c| c[2] > 150.0))
            .expect("blue");
        assert!(
            (red.pos_px.x - (10.0 + 3.0 * fi)).abs() < 0.01 && (red.pos_px.y - 20.0).abs() < 0.01,
            "frame {i}: {red:?}"
        );
        assert!(
            (blue.pos_px.x - (85.0 - 5.0 * fi)).abs() < 0.01 && (blue.pos_px.y - 49.0).abs() < 0.01,
            "frame {i}: {blue:?}"
        );
        assert_eq!(red.size_px, Some((12.0, 8.0)));
        assert_eq!(blue.area_px, Some(100.0));
    }
}

#[test]
fn detect_honours_frame_selection_and_writes_overlays() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("d.csv");
    let ov = dir.path().join("ov");
    let o = run(bin()
        .args([
            "detect",
            "--start",
            "3",
            "--end",
            "9",
            "--step",
            "3",
            "--overlay",
        ])
        .arg(&ov)
        .arg(fixture("tiny_sequence"))
        .arg("-o")
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    let dets = roadtrack::io::detections::read_detections(&out).expect("read");
    let mut frames: Vec<u32> = dets.iter().map(|d| d.frame).collect();
    frames.dedup();
    assert_eq!(frames, [3, 6, 9]);
    let mut pngs: Vec<_> = std::fs::read_dir(&ov)
        .expect("overlay dir")
        .map(|e| e.expect("entry").file_name())
        .collect();
    pngs.sort();
    assert_eq!(pngs, ["000003.png", "000006.png", "000009.png"]);
}

#[test]
fn detect_writes_to_stdout_with_dash() {
    let o = run(bin()
        .args(["detect", "-q", "-o", "-"])
        .arg(fixture("tiny_sequence")));
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.starts_with("frame,id,x,y,w,h,r,g,b,area\n"), "{text}");
    assert_eq!(text.lines().count(), 21);
}

#[test]
fn bad_input_exits_1_naming_the_path_and_bad_usage_exits_2() {
    let o = run(bin().args(["detect", "/no/such/input.avi"]));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("/no/such/input.avi"), "{}", stderr(&o));
    let o = run(bin().args(["detect", "--no-such-flag", "x"]));
    assert_eq!(o.status.code(), Some(2));
    let dir = tempfile::tempdir().expect("tempdir");
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[regions]\nmin_area = 3\n").expect("write");
    let o = run(bin()
        .arg("detect")
        .arg(fixture("tiny_sequence"))
        .arg("--config")
        .arg(&bad));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("bad.toml") && stderr(&o).contains("min_area"),
        "{}",
        stderr(&o)
    );
    let o = run(bin()
        .arg("detect")
        .arg(fixture("tiny_sequence"))
        .args(["--step", "0"]));
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--step"), "{}", stderr(&o));
}

#[test]
fn every_command_has_help_with_an_example() {
    let o = run(bin().arg("--help"));
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let commands: Vec<String> = text
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        .filter(|c| c != "help")
        .collect();
    assert!(commands.contains(&"detect".to_owned()), "{text}");
    for c in commands {
        let o = run(bin().args([c.as_str(), "--help"]));
        let h = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success() && h.contains("Example"),
            "`{c} --help` lacks an example:\n{h}"
        );
    }
}

#[test]
fn detect_finds_people_in_vtest() {
    let Some(v) = vtest() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("d.csv");
    let o = run(bin()
        .arg("detect")
        .arg(&v)
        .args(["--start", "100", "--end", "130"])
        .arg("-o")
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    let dets = roadtrack::io::detections::read_detections(&out).expect("read");
    // Several people walk through the square in every frame of this stretch; each is a
    // region taller than wide of a person's size (about 25–60 px wide, 60–110 px tall).
    for f in 100..=130 {
        let people = dets
            .iter()
            .filter(|d| d.frame == f)
            .filter(|d| {
                d.size_px
                    .is_some_and(|(w, h)| h > w && h > 40.0 && h < 140.0)
            })
            .count();
        assert!(people >= 2, "frame {f}: {people} person-shaped regions");
    }
}

/// Every reader's bad-input classes reach the user as exit 1 with file and line.
#[test]
fn check_reports_each_bad_input_class_with_file_and_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cases: &[(&str, &str, &str, &str)] = &[
        ("d.csv", "x,y\n1,2\n1,abc\n", ":3:", "not a number"),
        ("d.csv", "x,y\n1,NaN\n", ":2:", "finite"),
        ("d.csv", "x,y,w,h\n1,2,-3,4\n", ":2:", "negative"),
        ("d.csv", "frame,id,x,y\n1,4,1,2\n1,4,5,5\n", ":3:", "twice"),
        (
            "d.csv",
            "frame,id,x\n1,4,1\n",
            "d.csv",
            "missing required column `y`",
        ),
        (
            "m.csv",
            "id1,id2,probability\n1,2,7\n",
            ":2:",
            "probability",
        ),
        ("t.txt", "1,1,0,0,1,1,1\n1,1,0,0,1,1,1\n", ":2:", "twice"),
        ("gt.txt", "1,1,0,0,-1,1,1,1,1\n", ":1:", "negative"),
        (
            "tr.csv",
            "frame,time_s,id,class,x_px,y_px,w_px,h_px,score\n1,0,1,car,1,1,zz,1,1\n",
            ":2:",
            "w_px",
        ),
        ("me.csv", "step,x,y\n1,2,inf\n", ":2:", "finite"),
        (
            "es.csv",
            "step,label,x,y,vx,vy,weight\n1,1,0,0,0,0,-1\n",
            ":2:",
            "negative",
        ),
    ];
    for (name, text, at, what) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        let o = run(bin().arg("check").arg(&p));
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {text:?}: {e}");
        assert!(
            e.contains(name) && e.contains(at) && e.contains(what),
            "{name}: {text:?}: {e}"
        );
    }
    let p = dir.path().join("ok.csv");
    std::fs::write(&p, "frame,id,x,y\n1,1,1,2\n2,1,3,4\n").expect("write");
    let o = run(bin().arg("check").arg(&p));
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("2 detections in 2 frames"));
}
