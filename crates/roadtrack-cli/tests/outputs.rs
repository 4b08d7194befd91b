//! How the command writes its outputs (issue 15, "Writing outputs"): devices and FIFOs in
//! place, symbolic links followed, folders swapped in whole, nothing left behind after
//! SIGINT or SIGTERM.

mod common;
use common::{bin, names};

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn tiny() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../roadtrack/tests/fixtures/tiny_sequence")
}

#[cfg(unix)]
#[test]
fn tracks_to_a_fifo_are_written_through_it_and_it_stays_a_fifo() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().expect("tempdir");
    let fifo = dir.path().join("out.fifo");
    if !Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        eprintln!("note: mkfifo unavailable; skipped");
        return;
    }
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).expect("read fifo"))
    };
    let o = bin()
        .arg("track")
        .arg(tiny())
        .args(["--method", "relaxation", "-q", "-o"])
        .arg(&fifo)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = reader.join().expect("reader");
    assert!(text.lines().count() >= 10, "{text}");
    let ft = std::fs::symlink_metadata(&fifo).expect("meta").file_type();
    assert!(ft.is_fifo(), "the FIFO was replaced");
    assert_eq!(names(dir.path()), ["out.fifo"]);
}

#[cfg(unix)]
#[test]
fn an_output_through_a_symlink_replaces_its_target_and_keeps_the_link() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("real.txt"), "old").expect("write");
    std::os::unix::fs::symlink("real.txt", dir.path().join("link.txt")).expect("symlink");
    let o = bin()
        .current_dir(dir.path())
        .arg("track")
        .arg(tiny())
        .args(["--method", "relaxation", "-q", "-o", "link.txt"])
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let link = std::fs::symlink_metadata(dir.path().join("link.txt")).expect("meta");
    assert!(link.file_type().is_symlink());
    let text = std::fs::read_to_string(dir.path().join("real.txt")).expect("read");
    assert!(text.starts_with("1,"), "{text}");
}

#[test]
fn a_png_folder_output_holds_exactly_the_frames_of_the_last_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("frames");
    std::fs::create_dir(&out).expect("mkdir");
    for i in 1..=40 {
        std::fs::write(out.join(format!("{i:06}.png")), "stale").expect("write");
    }
    let tracks = dir.path().join("t.txt");
    let o = bin()
        .arg("track")
        .arg(tiny())
        .args(["--method", "relaxation", "-q", "-o"])
        .arg(&tracks)
        .output()
        .expect("track");
    assert!(o.status.success());
    let o = bin()
        .arg("render")
        .arg(tiny())
        .arg("--tracks")
        .arg(&tracks)
        .args(["--end", "3", "-q", "-o"])
        .arg(&out)
        .output()
        .expect("render");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(names(&out), ["000001.png", "000002.png", "000003.png"]);
    assert_eq!(names(dir.path()), ["frames", "t.txt"]);
    // Frames cannot go to standard output, and no folder named `-` appears.
    let o = bin()
        .current_dir(dir.path())
        .arg("render")
        .arg(tiny())
        .arg("--tracks")
        .arg(&tracks)
        .args(["-q", "-o", "-"])
        .output()
        .expect("render -");
    assert_eq!(o.status.code(), Some(2), "a usage error");
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("standard output"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(names(dir.path()), ["frames", "t.txt"]);
}

#[test]
fn simulating_fewer_frames_into_an_old_sequence_leaves_no_stale_frames() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    for frames in ["12", "3"] {
        let o = bin()
            .args([
                "simulate", "--scene", "crossing", "--frames", frames, "-q", "-o",
            ])
            .arg(&seq)
            .output()
            .expect("simulate");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_eq!(names(&seq.join("img1")).len(), 3);
    assert_eq!(names(dir.path()), ["seq"]);
}

/// Starts a long render to `out`, waits until its temporary output exists, sends `signal`
/// and returns the exit code.
#[cfg(unix)]
fn interrupt_render(dir: &Path, seq: &Path, out: &str, signal: &str) -> Option<i32> {
    let tracks = dir.join("t.txt");
    std::fs::write(&tracks, "").expect("empty tracks");
    let mut child = bin()
        .current_dir(dir)
        .arg("render")
        .arg(seq)
        .arg("--tracks")
        .arg(&tracks)
        .args(["-q", "-o", out])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let start = Instant::now();
    // Wait for the temporary output: the run is then writing.
    while !names(dir).iter().any(|n| n.starts_with(".roadtrack-")) {
        if start.elapsed() > Duration::from_secs(60) || child.try_wait().ok().flatten().is_some() {
            let _ = child.kill();
            panic!("no temporary output appeared");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(200));
    let sent = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .is_ok_and(|s| s.success());
    assert!(sent, "kill {signal}");
    let status = child.wait().expect("wait");
    use std::os::unix::process::ExitStatusExt;
    status.code().or(status.signal().map(|s| 128 + s))
}

#[cfg(unix)]
#[test]
fn sigint_and_sigterm_leave_no_temporary_files_and_exit_130_and_143() {
    let dir = tempfile::tempdir().expect("tempdir");
    let seq = dir.path().join("seq");
    let o = bin()
        .args([
            "simulate", "--scene", "crossing", "--frames", "300", "-q", "-o",
        ])
        .arg(&seq)
        .output()
        .expect("simulate");
    assert!(o.status.success());
    let work = dir.path().join("work");
    std::fs::create_dir(&work).expect("mkdir");
    let mut cases = vec![("frames", "-TERM", 143), ("frames", "-INT", 130)];
    if roadtrack::io::video::ffmpeg_available() {
        cases.push(("overlay.mp4", "-TERM", 143));
        cases.push(("overlay.mp4", "-INT", 130));
    } else {
        eprintln!("note: ffmpeg missing; video outputs not tested");
    }
    for (out, signal, code) in cases {
        let got = interrupt_render(&work, &seq, out, signal);
        assert_eq!(got, Some(code), "{out} {signal}");
        assert_eq!(names(&work), ["t.txt"], "{out} {signal}: leftovers");
    }
}

#[cfg(unix)]
#[test]
fn a_finished_video_gets_the_umask_mode() {
    use std::os::unix::fs::PermissionsExt;
    if !roadtrack::io::video::ffmpeg_available() {
        eprintln!("note: ffmpeg missing; skipped");
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let tracks = dir.path().join("t.txt");
    std::fs::write(&tracks, "").expect("tracks");
    let plain = dir.path().join("plain");
    std::fs::File::create(&plain).expect("plain");
    let video = dir.path().join("o.mp4");
    let o = bin()
        .arg("render")
        .arg(tiny())
        .arg("--tracks")
        .arg(&tracks)
        .args(["-q", "-o"])
        .arg(&video)
        .output()
        .expect("render");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mode = |p: &Path| std::fs::metadata(p).expect("meta").permissions().mode() & 0o777;
    assert_eq!(mode(&video), mode(&plain));
}
