//! Helpers every command-line test shares (`mod common;` in each test file).
#![allow(dead_code)] // each test binary uses some of them

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `roadtrack` binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_roadtrack"))
}

/// A committed fixture of the library crate (`crates/roadtrack/tests/fixtures/REL`).
pub fn fixture(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../roadtrack/tests/fixtures")
        .join(rel)
}

/// Runs `roadtrack -q track SEQ ARGS… -o OUT` on `threads` threads; fails the test with its
/// stderr when it fails. Returns OUT.
pub fn track_ok<A: AsRef<OsStr>>(seq: &Path, args: &[A], threads: &str, out: PathBuf) -> PathBuf {
    let o = bin()
        .env("RAYON_NUM_THREADS", threads)
        .args(["-q", "track"])
        .arg(seq)
        .args(args)
        .arg("-o")
        .arg(&out)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

/// `track_ok` with relaxation on the detections CSV `dets`, then `extra`.
pub fn track_relaxation(
    seq: &Path,
    dets: &Path,
    extra: &[&str],
    threads: &str,
    out: PathBuf,
) -> PathBuf {
    let mut args: Vec<&OsStr> = [
        "--method",
        "relaxation",
        "--detector",
        "file",
        "--detections",
    ]
    .map(OsStr::new)
    .to_vec();
    args.push(dets.as_os_str());
    args.extend(extra.iter().map(OsStr::new));
    track_ok(seq, &args, threads, out)
}

/// Writes `text` to `dir/name` (a settings file for a flag); returns its path as text.
pub fn write_toml(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write");
    path.to_str().expect("utf-8").to_string()
}

/// The rows of a MOT file (`gt.txt`, a tracks file) as numbers.
pub fn mot_rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .expect("read")
        .lines()
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse().expect("number"))
                .collect()
        })
        .collect()
}

/// IoU of two MOT rows' boxes (columns 2–5: left, top, width, height).
pub fn mot_iou(a: &[f64], b: &[f64]) -> f64 {
    let ix = (a[2] + a[4]).min(b[2] + b[4]) - a[2].max(b[2]);
    let iy = (a[3] + a[5]).min(b[3] + b[5]) - a[3].max(b[3]);
    let i = ix.max(0.0) * iy.max(0.0);
    i / (a[4] * a[5] + b[4] * b[5] - i)
}

/// A box stage of `track` (`--walker-boxes`, `--vehicle-boxes`: `flag`, its settings file
/// `config_flag`) on sequence `seq`: without a calibration it is a usage error (exit 2); a
/// nadir calibration, which has no perspective to recover a camera from, exits 1 naming the
/// file and writes nothing; each settings file of `bad` (its text, the field it gets wrong)
/// exits 1 naming the file and the field; the settings flag without the stage's is a usage
/// error.
pub fn box_stage_needs_perspective(
    seq: &Path,
    flag: &str,
    config_flag: &str,
    bad: &[(&str, &str)],
) {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("t.txt");
    let run = |extra: &[&str]| {
        bin()
            .args(["-q", "track"])
            .arg(seq)
            .args(["--method", "relaxation", "--detector", "file"])
            .args(extra)
            .arg("-o")
            .arg(&out)
            .output()
            .expect("run")
    };
    let o = run(&[flag]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--calibration"), "{}", stderr(&o));
    let nadir = dir.path().join("nadir.toml");
    std::fs::write(&nadir, "metres_per_pixel = 0.25\norigin_m = [0.0, 0.0]\n").expect("write");
    let o = run(&[flag, "--calibration", nadir.to_str().expect("utf-8")]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("nadir.toml") && e.contains("perspective"), "{e}");
    assert!(!out.exists(), "no output on error");
    let cal = seq.join("calibration.toml");
    let file = dir.path().join("settings.toml");
    for (text, field) in bad {
        std::fs::write(&file, text).expect("write");
        let o = run(&[
            "--calibration",
            cal.to_str().expect("utf-8"),
            flag,
            config_flag,
            file.to_str().expect("utf-8"),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("settings.toml") && e.contains(field), "{e}");
    }
    let o = run(&[config_flag, file.to_str().expect("utf-8")]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// Standard error, lossily decoded.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Standard output, lossily decoded.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The sorted names in `dir`.
pub fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("read_dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// `../shared/data/vtest.avi` when it and ffmpeg are present (a note on stderr otherwise).
pub fn vtest() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/vtest.avi");
    let ok = p.is_file() && roadtrack::io::video::ffmpeg_available();
    if !ok {
        eprintln!("note: skipping, needs ffmpeg and ../shared/data/vtest.avi");
    }
    ok.then_some(p)
}
