//! Video decoding through ffmpeg on the real reference file.

use roadtrack::io::{SourceKind, SourceOptions, source, video};
use std::path::Path;

#[test]
fn vtest_decodes_to_795_frames_of_768_by_576() -> roadtrack::Result<()> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/vtest.avi");
    if !p.is_file() || !video::ffmpeg_available() {
        eprintln!("note: skipping, needs ffmpeg and ../shared/data/vtest.avi");
        return Ok(());
    }
    let src = source::open(&p, &SourceOptions::default())?;
    assert_eq!(src.info.kind, SourceKind::Video);
    assert_eq!(
        (src.info.width, src.info.height, src.info.fps),
        (768, 576, 10.0)
    );
    assert_eq!(src.info.total_frames, Some(795));
    let mut n = 0;
    let mut last = 0;
    for f in src {
        let f = f?;
        assert_eq!(f.image.dimensions(), (768, 576));
        n += 1;
        last = f.index;
    }
    assert_eq!((n, last), (795, 795));
    // Selection: every 100th frame from 50 up to 700.
    let opts = SourceOptions {
        start: 50,
        end: Some(700),
        step: 100,
        ..SourceOptions::default()
    };
    let idx: Vec<u32> = source::open(&p, &opts)?
        .map(|f| f.map(|f| f.index))
        .collect::<roadtrack::Result<_>>()?;
    assert_eq!(idx, [50, 150, 250, 350, 450, 550, 650]);
    Ok(())
}

#[test]
fn a_file_that_is_not_a_video_is_a_clear_error() -> roadtrack::Result<()> {
    if !video::ffmpeg_available() {
        eprintln!("note: skipping, needs ffmpeg");
        return Ok(());
    }
    let dir = tempfile::tempdir().map_err(|e| roadtrack::Error::io("tmp", e))?;
    let p = dir.path().join("notes.avi");
    std::fs::write(&p, "this is text").map_err(|e| roadtrack::Error::io(&p, e))?;
    let m = source::open(&p, &SourceOptions::default())
        .expect_err("not a video")
        .to_string();
    assert!(m.contains("notes.avi") && m.contains("ffprobe"), "{m}");
    Ok(())
}

#[test]
fn written_videos_decode_to_the_frames_given_and_appear_only_when_finished() -> roadtrack::Result<()>
{
    if !video::ffmpeg_available() {
        eprintln!("note: skipping, needs ffmpeg");
        return Ok(());
    }
    let dir = tempfile::tempdir().map_err(|e| roadtrack::Error::io("tmp", e))?;
    // Odd size on purpose: yuv420p needs padding to 66 × 41 → 66 × 42.
    let (w, h) = (65, 41);
    for ext in ["mp4", "avi"] {
        let p = dir.path().join(format!("out.{ext}"));
        let mut writer = video::VideoWriter::create(&p, w, h, 5.0)?;
        for i in 0..6u8 {
            // A flat grey level per frame, easy to recognise after lossy coding.
            let img = image::RgbImage::from_pixel(w, h, image::Rgb([40 * i, 40 * i, 40 * i]));
            writer.write_frame(u32::from(i) + 1, &img)?;
        }
        assert!(!p.exists(), "the video appears only after finish");
        writer.finish()?;
        assert!(p.is_file());
        let src = source::open(&p, &SourceOptions::default())?;
        assert_eq!((src.info.width, src.info.height), (66, 42), "{ext}");
        assert!((src.info.fps - 5.0).abs() < 1e-9, "{ext}: {}", src.info.fps);
        let frames: Vec<_> = src.collect::<roadtrack::Result<_>>()?;
        assert_eq!(frames.len(), 6, "{ext}");
        for (i, f) in frames.iter().enumerate() {
            let v = f.image.get_pixel(30, 20).0[0];
            let want = 40 * i as i32;
            assert!(
                (i32::from(v) - want).abs() <= 6,
                "{ext} frame {i}: {v} vs {want}"
            );
        }
        // No temporary file is left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .map_err(|e| roadtrack::Error::io("tmp", e))?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".roadtrack-"))
            .collect();
        assert!(names.is_empty(), "{names:?}");
    }
    Ok(())
}

#[test]
fn a_frame_of_the_wrong_size_and_an_abandoned_video_leave_no_file() -> roadtrack::Result<()> {
    if !video::ffmpeg_available() {
        eprintln!("note: skipping, needs ffmpeg");
        return Ok(());
    }
    let dir = tempfile::tempdir().map_err(|e| roadtrack::Error::io("tmp", e))?;
    let p = dir.path().join("out.mp4");
    let mut writer = video::VideoWriter::create(&p, 32, 32, 10.0)?;
    let e = writer
        .write_frame(1, &image::RgbImage::new(16, 16))
        .expect_err("wrong size");
    assert!(e.to_string().contains("frame 1"), "{e}");
    drop(writer);
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .map_err(|e| roadtrack::Error::io("tmp", e))?
        .collect();
    assert!(left.is_empty(), "{left:?}");
    Ok(())
}

#[test]
fn a_video_cut_short_says_so_or_skips_the_frames_it_announced() -> roadtrack::Result<()> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/vtest.avi");
    if !p.is_file() || !video::ffmpeg_available() {
        eprintln!("note: skipping, needs ffmpeg and ../shared/data/vtest.avi");
        return Ok(());
    }
    let dir = tempfile::tempdir().map_err(|e| roadtrack::Error::io("tmp", e))?;
    let cut = dir.path().join("cut.avi");
    let bytes = std::fs::read(&p).map_err(|e| roadtrack::Error::io(&p, e))?;
    std::fs::write(&cut, &bytes[..100_000]).map_err(|e| roadtrack::Error::io(&cut, e))?;
    // The first 100 kB hold 3 whole frames; the header still announces 795.
    let items: Vec<_> = source::open(&cut, &SourceOptions::default())?.collect();
    assert_eq!(items.iter().filter(|f| f.is_ok()).count(), 3);
    assert_eq!(
        items.len(),
        4,
        "under fail the first bad frame ends the source"
    );
    let m = items[3].as_ref().expect_err("frame 4").to_string();
    assert!(
        m.contains("cut.avi") && m.contains("frame 4") && m.contains("ended at frame 3 of 795"),
        "{m}"
    );
    let skip = SourceOptions {
        on_bad_frame: roadtrack::io::OnBadFrame::Skip,
        step: 2,
        end: Some(100),
        ..SourceOptions::default()
    };
    let src = source::open(&cut, &skip)?;
    let log = src.skip_log();
    let idx: Vec<u32> = src
        .map(|f| f.map(|f| f.index))
        .collect::<roadtrack::Result<_>>()?;
    assert_eq!(idx, [1, 3]);
    let skipped: Vec<u32> = log.frames().iter().map(|s| s.frame).collect();
    assert_eq!(skipped, (5..=99).step_by(2).collect::<Vec<u32>>());
    Ok(())
}

#[test]
fn a_cut_video_without_a_frame_count_is_judged_by_its_duration() -> roadtrack::Result<()> {
    if !video::ffmpeg_available() {
        eprintln!("note: skipping, needs ffmpeg");
        return Ok(());
    }
    let dir = tempfile::tempdir().map_err(|e| roadtrack::Error::io("tmp", e))?;
    let p = dir.path().join("noise.mkv");
    // Matroska states a duration but no frame count. Noise keeps every frame large, so
    // cutting the file cuts frames.
    let mut writer = video::VideoWriter::create(&p, 64, 48, 10.0)?;
    let mut state = 12345u32;
    for i in 1..=30 {
        let img = image::RgbImage::from_fn(64, 48, |_, _| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let v = (state >> 24) as u8;
            image::Rgb([v, v, v])
        });
        writer.write_frame(i, &img)?;
    }
    writer.finish()?;
    let whole: Vec<_> = source::open(&p, &SourceOptions::default())?.collect();
    assert_eq!(whole.len(), 30);
    assert!(
        whole.iter().all(|f| f.is_ok()),
        "the whole file is not cut short"
    );
    let bytes = std::fs::read(&p).map_err(|e| roadtrack::Error::io(&p, e))?;
    std::fs::write(&p, &bytes[..bytes.len() / 2]).map_err(|e| roadtrack::Error::io(&p, e))?;
    let m = source::open(&p, &SourceOptions::default())?
        .find_map(|f| f.err())
        .expect("cut short")
        .to_string();
    assert!(m.contains("noise.mkv") && m.contains("announced"), "{m}");
    Ok(())
}

#[test]
fn a_video_wider_than_the_image_side_limit_is_refused_before_decoding() -> roadtrack::Result<()> {
    if !video::ffmpeg_available() {
        eprintln!("note: skipping, needs ffmpeg");
        return Ok(());
    }
    let dir = tempfile::tempdir().map_err(|e| roadtrack::Error::io("tmp", e))?;
    let p = dir.path().join("wide.nut");
    // 16 400 × 2 px raw frames: tiny on disk, one pixel column past the limit.
    let ok = std::process::Command::new("ffmpeg")
        .args([
            "-v",
            "error",
            "-f",
            "lavfi",
            "-i",
            "color=s=16400x2:d=0.2:r=10",
        ])
        .args(["-c:v", "rawvideo", "-pix_fmt", "rgb24", "-y"])
        .arg(&p)
        .status()
        .map_err(|e| roadtrack::Error::io(&p, e))?
        .success();
    assert!(ok, "ffmpeg made no test video");
    let m = source::open(&p, &SourceOptions::default())
        .expect_err("too wide")
        .to_string();
    assert!(m.contains("wide.nut") && m.contains("16384"), "{m}");
    Ok(())
}
