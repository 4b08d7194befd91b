//! Damaged media on purpose (issue 15): missing frames of a numbered folder, a truncated
//! JPEG, a video cut short, under `--on-bad-frame fail` and `skip`; and `-o -` only where
//! a stream makes sense.

mod common;
use common::{bin, fixture, names, stderr, vtest};

use std::path::{Path, PathBuf};
use std::process::Output;

/// A copy of the tiny sequence fixture (`frame1.png` … `frame10.png`) in `dir/frames`.
fn tiny_copy(dir: &Path) -> PathBuf {
    let out = dir.join("frames");
    std::fs::create_dir(&out).expect("mkdir");
    for name in names(&fixture("tiny_sequence")) {
        std::fs::copy(fixture("tiny_sequence").join(&name), out.join(&name)).expect("copy");
    }
    out
}

/// `roadtrack render INPUT --tracks <empty> -o dir/OUT EXTRA…`: one PNG per frame read.
fn render(dir: &Path, input: &Path, out: &str, extra: &[&str]) -> Output {
    let tracks = dir.join("empty.txt");
    std::fs::write(&tracks, "").expect("tracks");
    bin()
        .arg("render")
        .arg(input)
        .arg("--tracks")
        .arg(&tracks)
        .arg("-o")
        .arg(dir.join(out))
        .args(extra)
        .output()
        .expect("render")
}

fn sidecar(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).expect("sidecar");
    serde_json::from_str(&text).expect("sidecar JSON")
}

fn skipped_frames(v: &serde_json::Value) -> Vec<u64> {
    v["skipped"]
        .as_array()
        .expect("skipped")
        .iter()
        .map(|s| s["frame"].as_u64().expect("frame"))
        .collect()
}

#[test]
fn a_deleted_frame_of_a_numbered_folder_is_a_gap_not_a_renumbering() {
    let dir = tempfile::tempdir().expect("tempdir");
    let frames = tiny_copy(dir.path());
    std::fs::remove_file(frames.join("frame4.png")).expect("rm");
    // fail (the default): exit 1 naming the frame and the folder; no output appears.
    let o = render(dir.path(), &frames, "out", &["-q"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("frame 4") && e.contains("missing") && e.contains("frames"),
        "{e}"
    );
    assert!(!dir.path().join("out").exists());
    // skip: frame 5 stays frame 5; the summary and the sidecar list frame 4.
    let o = render(dir.path(), &frames, "out", &["--on-bad-frame", "skip"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let want: Vec<String> = [1, 2, 3, 5, 6, 7, 8, 9, 10]
        .iter()
        .map(|i| format!("{i:06}.png"))
        .collect();
    assert_eq!(names(&dir.path().join("out")), want);
    let e = stderr(&o);
    assert!(
        e.contains("skipped 1 bad frame") && e.contains("4: missing"),
        "{e}"
    );
    let v = sidecar(&dir.path().join("out.skipped.json"));
    assert_eq!(skipped_frames(&v), [4]);
    assert_eq!(v["skipped_count"], 1);
    assert!(
        v["skipped"][0]["reason"]
            .as_str()
            .expect("reason")
            .contains("missing")
    );
    // Tracking keeps the source's frame numbers and times too.
    let tracks = dir.path().join("tracks.txt");
    let o = bin()
        .arg("track")
        .arg(&frames)
        .args([
            "--method",
            "relaxation",
            "--on-bad-frame",
            "skip",
            "-q",
            "-o",
        ])
        .arg(&tracks)
        .output()
        .expect("track");
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&tracks).expect("tracks");
    let frames_out: std::collections::BTreeSet<u32> = text
        .lines()
        .filter_map(|l| l.split(',').next()?.parse().ok())
        .collect();
    assert!(!frames_out.contains(&4), "{frames_out:?}");
    assert!(frames_out.contains(&10), "{frames_out:?}");
    assert_eq!(
        skipped_frames(&sidecar(&dir.path().join("tracks.txt.skipped.json"))),
        [4]
    );
}

#[test]
fn a_rendered_video_holds_the_frame_before_a_skipped_one_so_time_is_kept() {
    if !roadtrack::io::video::ffmpeg_available() {
        eprintln!("note: ffmpeg missing; skipped");
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let frames = tiny_copy(dir.path());
    std::fs::remove_file(frames.join("frame4.png")).expect("rm");
    std::fs::remove_file(frames.join("frame5.png")).expect("rm");
    let o = render(
        dir.path(),
        &frames,
        "o.mp4",
        &["-q", "--on-bad-frame", "skip"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let src = roadtrack::io::source::open(&dir.path().join("o.mp4"), &Default::default())
        .expect("open video");
    assert_eq!(src.count(), 10, "10 frames long, as the source");
    assert_eq!(
        skipped_frames(&sidecar(&dir.path().join("o.mp4.skipped.json"))),
        [4, 5]
    );
}

#[test]
fn a_missing_frame_of_a_simulated_sequence_fails_detect_and_is_skipped_on_request() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    let o = bin()
        .args([
            "simulate", "--scene", "crossing", "--frames", "6", "-q", "-o",
        ])
        .arg(&seq)
        .output()
        .expect("simulate");
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::remove_file(seq.join("img1/000003.jpg")).expect("rm");
    let out = dir.path().join("det.csv");
    let o = bin()
        .arg("detect")
        .arg(&seq)
        .args(["-q", "-o"])
        .arg(&out)
        .output()
        .expect("detect");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("frame 3: missing"), "{}", stderr(&o));
    assert!(!out.exists());
    let o = bin()
        .arg("detect")
        .arg(&seq)
        .args(["-q", "--on-bad-frame", "skip", "-o"])
        .arg(&out)
        .output()
        .expect("detect");
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).expect("detections");
    let header: Vec<&str> = text.lines().next().expect("header").split(',').collect();
    let col = header
        .iter()
        .position(|c| *c == "frame")
        .expect("frame column");
    let frames: std::collections::BTreeSet<u32> = text
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(col)?.parse().ok())
        .collect();
    assert!(!frames.contains(&3), "{frames:?}");
    assert_eq!(
        skipped_frames(&sidecar(&dir.path().join("det.csv.skipped.json"))),
        [3]
    );
}

#[test]
fn a_truncated_jpeg_fails_naming_frame_and_file_or_is_skipped() {
    let dir = tempfile::tempdir().expect("tempdir");
    let frames = dir.path().join("jpegs");
    std::fs::create_dir(&frames).expect("mkdir");
    for i in 1..=4u8 {
        // A gradient, so most of the file is image data and the cut falls inside it.
        image::RgbImage::from_fn(160, 120, |x, y| {
            image::Rgb([30 * i, (x + y) as u8, (x * y % 256) as u8])
        })
        .save(frames.join(format!("{i:06}.jpg")))
        .expect("save");
    }
    let cut = frames.join("000003.jpg");
    let bytes = std::fs::read(&cut).expect("read");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).expect("truncate");
    let o = render(dir.path(), &frames, "out", &["-q"]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("000003.jpg") && e.contains("frame 3") && e.contains("truncated JPEG"),
        "{e}"
    );
    let o = render(
        dir.path(),
        &frames,
        "out",
        &["-q", "--on-bad-frame", "skip"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        names(&dir.path().join("out")),
        ["000001.png", "000002.png", "000004.png"]
    );
    let v = sidecar(&dir.path().join("out.skipped.json"));
    assert_eq!(skipped_frames(&v), [3]);
    assert!(
        v["skipped"][0]["file"]
            .as_str()
            .expect("file")
            .ends_with("000003.jpg")
    );
    // The sidecar is always written under skip: a clean run leaves an empty list, not the
    // list of the run before.
    std::fs::write(&cut, &bytes).expect("repair");
    let o = render(
        dir.path(),
        &frames,
        "out",
        &["-q", "--on-bad-frame", "skip"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(skipped_frames(&sidecar(&dir.path().join("out.skipped.json"))).is_empty());
    assert_eq!(
        names(dir.path()),
        ["empty.txt", "jpegs", "out", "out.skipped.json"]
    );
}

#[test]
fn a_video_cut_short_fails_or_warns_with_the_frames_it_announced() {
    let Some(vtest) = vtest() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let cut = dir.path().join("cut.avi");
    let bytes = std::fs::read(&vtest).expect("read vtest");
    std::fs::write(&cut, &bytes[..100_000]).expect("cut");
    let out = dir.path().join("det.csv");
    let o = bin()
        .arg("detect")
        .arg(&cut)
        .args(["-q", "-o"])
        .arg(&out)
        .output()
        .expect("detect");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("cut.avi: frame 4: video ended at frame 3 of 795 announced"),
        "{e}"
    );
    assert!(!out.exists());
    let o = bin()
        .arg("detect")
        .arg(&cut)
        .args(["--on-bad-frame", "skip", "-o"])
        .arg(&out)
        .output()
        .expect("detect");
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("warning: skipped 792 bad frames")
            && e.contains("4–795: video ended at frame 3 of 795 announced"),
        "{e}"
    );
    let v = sidecar(&dir.path().join("det.csv.skipped.json"));
    assert_eq!(v["skipped_count"], 792);
    assert_eq!(skipped_frames(&v).first(), Some(&4));
    // bench's decode stage reads its --video the same way.
    for (policy, code) in [("fail", 1), ("skip", 0)] {
        let o = bin()
            .current_dir(dir.path())
            .args([
                "bench", "--video", "cut.avi", "--stages", "decode", "--frames", "2",
            ])
            .args(["--on-bad-frame", policy])
            .output()
            .expect("bench");
        assert_eq!(o.status.code(), Some(code), "{policy}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("video ended at frame 3 of 795"),
            "{policy}: {}",
            stderr(&o)
        );
    }
}

/// Runs `roadtrack ARGS` in `dir` and checks it is a usage error about standard output
/// that leaves `dir` as it was.
fn assert_no_stdout(dir: &Path, args: &[&str]) {
    let before = names(dir);
    let o = bin().current_dir(dir).args(args).output().expect("run");
    assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    assert!(
        stderr(&o).contains("standard output"),
        "{args:?}: {}",
        stderr(&o)
    );
    assert_eq!(names(dir), before, "{args:?} left something");
}

#[test]
fn dash_is_a_usage_error_for_folder_frame_and_plot_outputs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("t.txt"), "").expect("tracks");
    let seq = fixture("tiny_sequence");
    let seq = seq.to_str().expect("utf-8 path");
    for args in [
        vec!["render", seq, "--tracks", "t.txt", "-o", "-"],
        vec!["simulate", "--frames", "2", "-o", "-"],
        vec!["demo", "--frames", "2", "-o", "-"],
        vec!["analyze", "t.txt", "--calibration", "c.toml", "-o", "-"],
        vec!["plot", "t.txt", "-o", "-"],
        vec!["sweep", "pairs", "--plot", "-"],
        vec!["detect", seq, "-o", "d.csv", "--overlay", "-"],
        vec!["detect", seq, "-o", "d.csv", "--masks", "-"],
        vec![
            "track",
            seq,
            "--method",
            "mrf",
            "-o",
            "t2.txt",
            "--object-maps",
            "-",
        ],
    ] {
        assert_no_stdout(d, &args);
    }
    // Where the output is a stream, `-` is standard output.
    let o = bin()
        .current_dir(d)
        .args(["detect", seq, "-q", "--end", "3", "-o", "-"])
        .output()
        .expect("detect -");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!o.stdout.is_empty());
    assert_eq!(names(d), ["t.txt"]);
}

#[cfg(unix)]
#[test]
fn a_png_folder_output_through_a_symlink_replaces_the_target_and_keeps_the_link() {
    let dir = tempfile::tempdir().expect("tempdir");
    let real = dir.path().join("real");
    std::fs::create_dir(&real).expect("mkdir");
    std::fs::write(real.join("stale.png"), "old").expect("stale");
    std::os::unix::fs::symlink("real", dir.path().join("link")).expect("symlink");
    let o = render(
        dir.path(),
        &fixture("tiny_sequence"),
        "link",
        &["-q", "--end", "2"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let meta = std::fs::symlink_metadata(dir.path().join("link")).expect("meta");
    assert!(meta.file_type().is_symlink(), "the link was replaced");
    assert_eq!(names(&real), ["000001.png", "000002.png"]);
}

#[cfg(unix)]
#[test]
fn the_skipped_frames_sidecar_gets_the_umask_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().expect("tempdir");
    let plain = dir.path().join("plain");
    std::fs::File::create(&plain).expect("plain");
    let o = render(
        dir.path(),
        &fixture("tiny_sequence"),
        "out",
        &["-q", "--end", "2", "--on-bad-frame", "skip"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let mode = |p: &Path| std::fs::metadata(p).expect("meta").permissions().mode() & 0o777;
    assert_eq!(mode(&dir.path().join("out.skipped.json")), mode(&plain));
}
