//! Upper bounds on sizes (docs/FORMATS.md, "Limits"): each input that used to abort on a
//! failed allocation, hang, or take gigabytes is refused at once with exit 1 naming the
//! file and line or the config field, or exit 2 naming the flag. Every case here would
//! take minutes or gigabytes without its bound, so each test is also a timing check.

mod common;
use common::{bin, fixture, stderr};

use std::path::Path;
use std::process::Output;
use std::time::{Duration, Instant};

/// Runs `roadtrack -q ARGS` and checks it ended quickly (the bound trips before any
/// allocation or loop).
fn run(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    let t = Instant::now();
    let mut c = bin();
    c.arg("-q");
    for a in args {
        c.arg(a);
    }
    let o = c.output().expect("run roadtrack");
    assert!(
        t.elapsed() < Duration::from_secs(30),
        "took {:?}: {}",
        t.elapsed(),
        stderr(&o)
    );
    o
}

/// Asserts exit `code` and that stderr holds every one of `words`.
fn refused(o: &Output, code: i32, words: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(code), "{e}");
    for w in words {
        assert!(e.contains(w), "stderr lacks {w:?}: {e}");
    }
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

const GT_ROW: &str = "1,1,10,10,20,20,1,1,1\n";
const TRACK_ROW: &str = "1,1,10,10,20,20,1,-1,-1,-1\n";

// 1. evaluate: frames.

#[test]
fn evaluate_refuses_a_num_frames_flag_above_the_limit() {
    let d = tempfile::tempdir().expect("tempdir");
    let gt = write(d.path(), "gt.txt", GT_ROW);
    let tr = write(d.path(), "tracks.txt", TRACK_ROW);
    let o = run(&[
        &"evaluate",
        &"--truth",
        &gt,
        &"--tracks",
        &tr,
        &"--num-frames",
        &"2000000000",
    ]);
    refused(&o, 2, &["--num-frames", "2000000000"]);
}

#[test]
fn evaluate_refuses_a_gt_or_tracks_row_at_frame_2e9() {
    let d = tempfile::tempdir().expect("tempdir");
    let gt_ok = write(d.path(), "gt_ok.txt", GT_ROW);
    let tr_ok = write(d.path(), "tracks_ok.txt", TRACK_ROW);
    let gt = write(
        d.path(),
        "gt.txt",
        &format!("{GT_ROW}2000000000,1,10,10,20,20,1,1,1\n"),
    );
    let tr = write(
        d.path(),
        "tracks.txt",
        &format!("{TRACK_ROW}2000000000,1,10,10,20,20,1,-1,-1,-1\n"),
    );
    let o = run(&[&"evaluate", &"--truth", &gt, &"--tracks", &tr_ok]);
    refused(&o, 1, &["gt.txt:2", "frame", "10000000"]);
    let o = run(&[&"evaluate", &"--truth", &gt_ok, &"--tracks", &tr]);
    refused(&o, 1, &["tracks.txt:2", "frame", "10000000"]);
    // The largest frame allowed is accepted.
    let tr = write(
        d.path(),
        "tracks_max.txt",
        &format!("{TRACK_ROW}10000000,1,10,10,20,20,1,-1,-1,-1\n"),
    );
    let o = run(&[&"evaluate", &"--truth", &gt_ok, &"--tracks", &tr]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn evaluate_refuses_a_seqinfo_seq_length_above_the_limit() {
    let d = tempfile::tempdir().expect("tempdir");
    let seq = d.path().join("SEQ");
    std::fs::create_dir_all(seq.join("gt")).expect("mkdir");
    write(&seq.join("gt"), "gt.txt", GT_ROW);
    write(
        &seq,
        "seqinfo.ini",
        "[Sequence]\nname=SEQ\nframeRate=10\nseqLength=1000000000\nimWidth=640\nimHeight=480\n",
    );
    let tr = write(d.path(), "tracks.txt", TRACK_ROW);
    let o = run(&[&"evaluate", &"--truth", &seq, &"--tracks", &tr]);
    refused(&o, 1, &["seqinfo.ini:4", "seqLength", "10000000"]);
}

// 2. train: input size.

#[test]
fn train_refuses_an_input_size_above_the_limit_before_reading_data() {
    let o = run(&[
        &"train",
        &"--sequence",
        &fixture("tiny_sequence"),
        &"--input-size",
        &"100000x100000",
    ]);
    refused(&o, 2, &["--input-size", "100000", "1024"]);
}

// 3. filter: steps and measurements per step.

#[test]
fn filter_refuses_a_step_above_the_limit() {
    let d = tempfile::tempdir().expect("tempdir");
    let m = write(
        d.path(),
        "measurements.csv",
        "step,x,y\n0,1,1\n2000000000,5,5\n",
    );
    let o = run(&[&"filter", &m, &"-o", &d.path().join("e.csv")]);
    refused(&o, 1, &["measurements.csv:3", "step", "10000000"]);
}

#[test]
fn filter_refuses_too_many_measurements_in_one_step() {
    let d = tempfile::tempdir().expect("tempdir");
    let mut text = String::from("step,x,y\n");
    for i in 0..5000 {
        text.push_str(&format!("1,{},{}\n", i % 100, i / 100));
    }
    let m = write(d.path(), "measurements.csv", &text);
    let o = run(&[&"filter", &m, &"-o", &d.path().join("e.csv")]);
    // Row 1 001 (line 1 002) is the first one over 1 000.
    refused(&o, 1, &["measurements.csv:1002", "step", "1000"]);
}

// 4. simulate: rates and time spans.

#[test]
fn simulate_refuses_a_frame_rate_above_the_limit() {
    let d = tempfile::tempdir().expect("tempdir");
    let o = run(&[&"simulate", &"--fps", &"1e308", &"-o", &d.path().join("s")]);
    refused(&o, 2, &["--fps", "1000"]);
    let o = run(&[&"simulate", &"--fps", &"0", &"-o", &d.path().join("s")]);
    refused(&o, 2, &["--fps"]);
}

#[test]
fn simulate_refuses_a_warmup_above_the_limit() {
    let d = tempfile::tempdir().expect("tempdir");
    let cfg = write(d.path(), "sim.toml", "warmup_s = 1e12\n");
    let o = run(&[&"simulate", &"--config", &cfg, &"-o", &d.path().join("s")]);
    refused(&o, 1, &["warmup_s", "86400"]);
    // A tiny traffic step over a long simulation is too many steps.
    let cfg = write(
        d.path(),
        "steps.toml",
        "warmup_s = 80000\nmax_step_s = 1e-6\n",
    );
    let o = run(&[&"simulate", &"--config", &cfg, &"-o", &d.path().join("s")]);
    refused(&o, 1, &["max_step_s", "traffic steps"]);
}

#[test]
fn simulate_refuses_trajectories_spanning_more_than_a_day() {
    let d = tempfile::tempdir().expect("tempdir");
    let header = "time_s,id,class,x_m,y_m,heading_deg,length_m,width_m\n";
    let traj = write(
        d.path(),
        "traj.csv",
        &format!("{header}0,1,car,0,0,0,4.5,1.8\n1000000,1,car,10,0,0,4.5,1.8\n"),
    );
    let o = run(&[
        &"simulate",
        &"--from-trajectories",
        &traj,
        &"-o",
        &d.path().join("s"),
    ]);
    refused(&o, 1, &["traj.csv:3", "time_s", "86400"]);
}

// 5. particle counts.

#[test]
fn track_refuses_particle_counts_above_the_limit() {
    let d = tempfile::tempdir().expect("tempdir");
    for (method, toml, field) in [
        (
            "phd",
            "birth_particles_per_detection = 100000000\n",
            "birth_particles_per_detection",
        ),
        (
            "pf",
            "[pf]\nparticles_per_object = 100000000\n",
            "particles_per_object",
        ),
        ("phd", "[phd]\nmax_particles = 100000000\n", "max_particles"),
    ] {
        let cfg = write(d.path(), "f.toml", toml);
        let o = run(&[
            &"track",
            &fixture("tiny_sequence"),
            &"--method",
            &method,
            &"--config",
            &cfg,
            &"-o",
            &d.path().join("t.txt"),
        ]);
        refused(&o, 1, &[field, "exceeds the limit"]);
    }
    // Births may not exceed the particle cap either.
    let cfg = write(
        d.path(),
        "f.toml",
        "birth_particles_per_detection = 30000\n[phd]\nmax_particles = 20000\n",
    );
    let o = run(&[
        &"track",
        &fixture("tiny_sequence"),
        &"--method",
        &"phd",
        &"--config",
        &cfg,
        &"-o",
        &d.path().join("t.txt"),
    ]);
    refused(&o, 1, &["birth_particles_per_detection", "max_particles"]);
}

#[test]
fn filter_refuses_particles_per_target_above_the_limit() {
    let d = tempfile::tempdir().expect("tempdir");
    let m = write(d.path(), "measurements.csv", "step,x,y\n0,1,1\n");
    let o = run(&[
        &"filter",
        &m,
        &"--particles-per-target",
        &"100000000",
        &"-o",
        &d.path().join("e.csv"),
    ]);
    // A flag: a usage error naming it.
    refused(&o, 2, &["--particles-per-target", "100000"]);
}

// 6. match: a dense scene stays bounded; the bounds themselves are checked.

#[test]
fn match_on_a_dense_scene_is_bounded_and_the_label_cap_is_a_bounded_flag() {
    let d = tempfile::tempdir().expect("tempdir");
    // 2 000 vehicles in a 1 000 px square: ~180 in each gate and ~250 within R, i.e.
    // ~360 000 labels and hundreds of millions of support entries without the caps.
    let frame = |dx: f64| {
        let mut s = String::from("id,x,y,r,g,b\n");
        for i in 0..2000u64 {
            let (x, y) = ((i * 7919 % 1000) as f64, (i * 104_729 % 997) as f64);
            s.push_str(&format!("{},{},{},{},0,0\n", i + 1, x + dx, y, i % 256));
        }
        s
    };
    let f1 = write(d.path(), "f1.csv", &frame(0.0));
    let f2 = write(d.path(), "f2.csv", &frame(2.0));
    let out = d.path().join("m.csv");
    let o = run(&[&"match", &f1, &f2, &"-o", &out]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = std::fs::read_to_string(&out).expect("read").lines().count();
    assert!(rows > 2000, "{rows} rows");
    let o = run(&[&"match", &f1, &f2, &"--max-labels", &"0", &"-o", &out]);
    refused(&o, 2, &["--max-labels"]);
    let o = run(&[
        &"match",
        &f1,
        &f2,
        &"--max-neighbours",
        &"100000",
        &"-o",
        &out,
    ]);
    refused(&o, 2, &["--max-neighbours", "4096"]);
    let cfg = write(d.path(), "r.toml", "max_labels = 100000\n");
    let o = run(&[&"match", &f1, &f2, &"--config", &cfg, &"-o", &out]);
    refused(&o, 1, &["max_labels", "4096"]);
}

// 7. The general sweep: a few more of the bounds, through the command line.

#[test]
fn other_counts_and_spans_are_bounded() {
    let d = tempfile::tempdir().expect("tempdir");
    // A pair Δt of 1e308 s used to simulate that long.
    let o = run(&[
        &"simulate",
        &"--pairs",
        &"1e308",
        &"-o",
        &d.path().join("p"),
    ]);
    refused(&o, 2, &["--pairs", "86400"]);
    let o = run(&[
        &"simulate",
        &"--pairs",
        &"1.5",
        &"--n-pairs",
        &"4000000000",
        &"-o",
        &d.path().join("p"),
    ]);
    refused(&o, 2, &["--n-pairs", "100000"]);
    // With epsilon 0 the relaxation never converges: the iteration cap must be bounded.
    let f = fixture("relaxation/1-platoon/frame1.csv");
    let f2 = fixture("relaxation/1-platoon/frame2.csv");
    let o = run(&[
        &"match",
        &f,
        &f2,
        &"--max-iterations",
        &"4000000000",
        &"-o",
        &d.path().join("m.csv"),
    ]);
    refused(&o, 2, &["--max-iterations", "100000"]);
    // A likelihood window larger than any image.
    let cfg = write(d.path(), "f.toml", "[likelihood]\nmin_window_px = 100000\n");
    let o = run(&[
        &"track",
        &fixture("tiny_sequence"),
        &"--method",
        &"pf",
        &"--config",
        &cfg,
        &"-o",
        &d.path().join("t.txt"),
    ]);
    refused(&o, 1, &["min_window_px", "16384"]);
}

#[test]
fn filter_refuses_a_measurement_far_outside_any_scene() {
    // One coordinate of 1e308 used to stretch the default region until the filter
    // reported no estimate at all, with exit 0.
    let d = tempfile::tempdir().expect("tempdir");
    let m = write(
        d.path(),
        "measurements.csv",
        "step,x,y\n1,10,10\n2,1e308,10\n",
    );
    let o = run(&[&"filter", &m, &"-o", &d.path().join("e.csv")]);
    refused(&o, 1, &["measurements.csv:3", "`x`", "1e9"]);
}
