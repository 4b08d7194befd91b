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
        fps: None,
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
