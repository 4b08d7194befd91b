//! End-to-end tests of `roadtrack render` and `roadtrack plot` on the committed tiny
//! sequence (fixtures/README.md: a red 12 × 8 box with top-left (4 + 3i, 16) and a blue
//! 10 × 10 box with top-left (80 − 5i, 44) in frame i of 10, 96 × 72 px).

mod common;
use common::{bin, stderr};

use roadtrack_viz::overlay::id_colour;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tiny() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../roadtrack/tests/fixtures/tiny_sequence")
}

fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("run roadtrack")
}

/// Tracks that follow the fixture's boxes exactly: id 1 the red box, id 2 the blue one.
fn write_tracks(dir: &Path) -> PathBuf {
    let p = dir.join("tracks.txt");
    let mut s = String::new();
    for i in 1..=10 {
        s += &format!("{i},1,{},16,12,8,1,-1,-1,-1\n", 4 + 3 * i);
        s += &format!("{i},2,{},44,10,10,1,-1,-1,-1\n", 80 - 5 * i);
    }
    std::fs::write(&p, s).expect("write tracks");
    p
}

/// Ground truth of the same boxes: id 1 a car (class 3), id 2 a pedestrian (class 1).
fn write_gt(dir: &Path) -> PathBuf {
    let p = dir.join("gt.txt");
    let mut s = String::new();
    for i in 1..=10 {
        s += &format!("{i},1,{},16,12,8,1,3,1\n", 4 + 3 * i);
        s += &format!("{i},2,{},44,10,10,1,1,1\n", 80 - 5 * i);
    }
    std::fs::write(&p, s).expect("write gt");
    p
}

fn rgb(p: &Path) -> image::RgbImage {
    image::open(p).expect("decode png").to_rgb8()
}

#[test]
fn render_draws_boxes_and_trails_where_the_tracks_are_and_is_deterministic() {
    let d = tempfile::tempdir().expect("tempdir");
    let tracks = write_tracks(d.path());
    let outs: Vec<PathBuf> = ["a", "b"].iter().map(|n| d.path().join(n)).collect();
    for out in &outs {
        let o = run(bin()
            .arg("render")
            .arg(tiny())
            .arg("--tracks")
            .arg(&tracks)
            .arg("-o")
            .arg(out));
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let names: Vec<_> = (1..=10).map(|i| format!("{i:06}.png")).collect();
    for n in &names {
        let (a, b) = (outs[0].join(n), outs[1].join(n));
        assert_eq!(
            std::fs::read(&a).expect("a"),
            std::fs::read(&b).expect("b"),
            "{n}"
        );
    }
    let f5 = rgb(&outs[0].join("000005.png"));
    assert_eq!(f5.dimensions(), (96, 72));
    // Frame 5: red box left edge at x = 19, rows 16..24; blue box right edge x = 64.
    assert_eq!(f5.get_pixel(19, 20), &id_colour(1));
    assert_eq!(f5.get_pixel(64, 49), &id_colour(2));
    // The red box's trail runs back along y = 20 from its centre (25, 20) to frame 1's
    // centre (13, 20): at x = 16 it is drawn, faded (4 frames old of 30) over the frame.
    let under = rgb(&tiny().join("frame5.png"));
    let (t, u) = (f5.get_pixel(16, 20), under.get_pixel(16, 20));
    assert_ne!(t, u, "trail pixel unchanged");
    let c = id_colour(1);
    for k in 0..3 {
        let (got, base, want) = (t.0[k] as f32, u.0[k] as f32, c.0[k] as f32);
        // Blended between the frame and the id colour, much nearer the colour.
        assert!(
            (got - want).abs() <= (base - want).abs() * 0.25 + 1.0,
            "{t:?} {u:?} {c:?}"
        );
    }
}

#[test]
fn render_with_truth_is_side_by_side_and_reads_trajectory_csvs() {
    let d = tempfile::tempdir().expect("tempdir");
    let gt = write_gt(d.path());
    // The red box's track as a trajectories CSV (centres), with classes.
    let csv = d.path().join("traj.csv");
    let mut s = String::from("frame,time_s,id,class,x_px,y_px,w_px,h_px,score\n");
    for i in 1..=10 {
        s += &format!("{i},0,1,car,{},20,12,8,1\n", 10 + 3 * i);
    }
    std::fs::write(&csv, s).expect("csv");
    let out = d.path().join("sbs");
    let o = run(bin()
        .arg("render")
        .arg(tiny())
        .args(["--end", "4", "--no-labels", "--tracks"])
        .arg(&csv)
        .arg("--truth")
        .arg(&gt)
        .arg("-o")
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    let n = std::fs::read_dir(&out).expect("out").count();
    assert_eq!(n, 4, "--end 4");
    let f4 = rgb(&out.join("000004.png"));
    assert_eq!(f4.dimensions(), (192, 72), "double width");
    // Frame 4: red box left edge x = 16 on the left half; truth's on the right half.
    assert_eq!(f4.get_pixel(16, 20), &id_colour(1));
    assert_eq!(f4.get_pixel(96 + 16, 20), &id_colour(1));
    // Blue truth box (id 2), top-left (60, 44): only on the right half.
    assert_eq!(f4.get_pixel(96 + 60, 48), &id_colour(2));
    assert_ne!(f4.get_pixel(60, 48), &id_colour(2));
}

#[test]
fn render_writes_a_video_when_ffmpeg_is_present() {
    if !roadtrack::io::video::ffmpeg_available() {
        eprintln!("note: skipping video output, needs ffmpeg");
        return;
    }
    let d = tempfile::tempdir().expect("tempdir");
    let tracks = write_tracks(d.path());
    let gt = write_gt(d.path());
    let out = d.path().join("overlay.mp4");
    let o = run(bin()
        .arg("render")
        .arg(tiny())
        .arg("--tracks")
        .arg(&tracks)
        .arg("--truth")
        .arg(&gt)
        .arg("-o")
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    let src = roadtrack::io::source::open(&out, &Default::default()).expect("open video");
    assert_eq!((src.info.width, src.info.height), (192, 72));
    assert_eq!(src.count(), 10);
}

#[test]
fn render_reports_bad_tracks_with_file_and_line_and_exits_1() {
    let d = tempfile::tempdir().expect("tempdir");
    let bad = d.path().join("bad.txt");
    std::fs::write(&bad, "1,1,0,0,4,4,1,-1,-1,-1\n2,1,x,0,4,4,1,-1,-1,-1\n").expect("write");
    let o = run(bin()
        .arg("render")
        .arg(tiny())
        .arg("--tracks")
        .arg(&bad)
        .arg("-o")
        .arg(d.path().join("o")));
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("bad.txt:2") && e.contains("bb_left"), "{e}");
    let o = run(bin().arg("render").arg(tiny()).arg("-o").arg("x"));
    assert_eq!(
        o.status.code(),
        Some(2),
        "missing --tracks is a usage error"
    );
}

/// `render --detections F` (`--detector file`) draws each frame's detections, coloured by
/// class, without trails; `--detector background` renders too; tracks and a detector
/// together, or neither, are usage errors.
#[test]
fn render_draws_a_detectors_boxes_instead_of_tracks() {
    let d = tempfile::tempdir().expect("tempdir");
    // The fixture's two boxes as public detections (MOTChallenge det.txt, no class).
    let det = d.path().join("det.txt");
    let mut s = String::new();
    for i in 1..=10 {
        s += &format!("{i},-1,{},16,12,8,0.9,-1,-1,-1\n", 4 + 3 * i);
        s += &format!("{i},-1,{},44,10,10,0.8,-1,-1,-1\n", 80 - 5 * i);
    }
    std::fs::write(&det, s).expect("write det");
    let out = d.path().join("det_overlay");
    let o = run(bin()
        .arg("render")
        .arg(tiny())
        .arg("--detections")
        .arg(&det)
        .arg("-o")
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    let f5 = rgb(&out.join("000005.png"));
    let unknown = roadtrack_viz::overlay::class_colour(&roadtrack::ObjectClass::Unknown);
    // Frame 5: the red box's left edge at x = 19 and the blue box's right edge at x = 64,
    // both in the colour of their class (unknown), not of a track id.
    assert_eq!(f5.get_pixel(19, 20), &unknown);
    assert_eq!(f5.get_pixel(64, 49), &unknown);
    // No trail: left of the red box, on its row, the frame shows through unchanged.
    let under = rgb(&tiny().join("frame5.png"));
    assert_eq!(f5.get_pixel(16, 20), under.get_pixel(16, 20));

    let out = d.path().join("bg_overlay");
    let o = run(bin()
        .arg("render")
        .arg(tiny())
        .args(["--detector", "background", "-o"])
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(common::names(&out).len(), 10);

    let tracks = write_tracks(d.path());
    let o = run(bin()
        .arg("render")
        .arg(tiny())
        .arg("--tracks")
        .arg(&tracks)
        .args(["--detector", "background", "-o"])
        .arg(d.path().join("x")));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--detector"), "{}", stderr(&o));
}

#[test]
fn plot_writes_trajectories_over_the_first_frame_and_time_space_svg() {
    let d = tempfile::tempdir().expect("tempdir");
    let tracks = write_tracks(d.path());
    let png = d.path().join("traj.png");
    let o = run(bin()
        .arg("plot")
        .arg(&tracks)
        .arg("--background")
        .arg(tiny())
        .args(["--width", "500", "--height", "400", "-o"])
        .arg(&png));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(rgb(&png).dimensions(), (500, 400));
    let svg = d.path().join("ts.svg");
    let o = run(bin()
        .arg("plot")
        .arg(&tracks)
        .args(["--time-space", "--axis", "x", "-o"])
        .arg(&svg));
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).expect("svg");
    assert!(text.contains("<svg"));
    let lines = text
        .lines()
        .filter(|l| l.contains("<polyline") && l.contains("stroke-width=\"2\""))
        .count();
    assert_eq!(lines, 2, "one line per id");
}

#[test]
fn plot_charts_series_from_a_table_and_refuses_bad_usage() {
    let d = tempfile::tempdir().expect("tempdir");
    let table = d.path().join("sweep.csv");
    std::fs::write(
        &table,
        "variant,dt,rate\nd,1,0.98\nd,2,0.95\na,1,0.9\na,2,0.8\n",
    )
    .expect("write");
    let png = d.path().join("rate.png");
    let o = run(bin()
        .arg("plot")
        .arg("--series")
        .arg(&table)
        .args(["--x", "dt", "--y", "rate", "--group", "variant", "-o"])
        .arg(&png));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(rgb(&png).dimensions(), roadtrack_viz::plot::LINE_CHART_SIZE);
    // A column that is not there: exit 1 naming it.
    let o = run(bin()
        .arg("plot")
        .arg("--series")
        .arg(&table)
        .args(["--x", "dt", "--y", "nope", "-o"])
        .arg(&png));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("nope"), "{}", stderr(&o));
    // Neither tracks nor --series; --series without --y: usage errors.
    assert_eq!(run(bin().arg("plot")).status.code(), Some(2));
    let o = run(bin()
        .arg("plot")
        .arg("--series")
        .arg(&table)
        .args(["--x", "dt"]));
    assert_eq!(o.status.code(), Some(2));
    // An unsupported extension: exit 1 with the remedy.
    let tracks = write_tracks(d.path());
    let o = run(bin()
        .arg("plot")
        .arg(&tracks)
        .arg("-o")
        .arg(d.path().join("a.jpg")));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains(".png or .svg"), "{}", stderr(&o));
}
