//! Damaged media: what a frame source does with a frame it cannot read (`--on-bad-frame`),
//! the record of skipped frames and its JSON sidecar, and the checks that find damage a
//! lenient decoder would let through (a truncated JPEG, a gap in a folder's numbering).

use super::atomic::write_atomic;
use crate::error::{Error, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

/// What a frame source does with a frame it cannot read: a missing or undecodable image, a
/// frame of another size, a truncated JPEG, a video that ends before the frame count it
/// announced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnBadFrame {
    /// Stop with an error naming the frame and the file (the default).
    #[default]
    Fail,
    /// Leave the frame out and go on: the frames around it keep their numbers and times,
    /// so the skipped frame is a gap in time. The skipped frames are recorded in the
    /// source's [`SkipLog`].
    Skip,
}

/// One frame a source left out under [`OnBadFrame::Skip`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SkippedFrame {
    /// The frame's number in the source (1-based).
    pub frame: u32,
    /// The file (an image, the video) or, for a frame missing from a folder, the folder.
    pub file: PathBuf,
    /// Why it was left out.
    pub reason: String,
}

impl SkippedFrame {
    /// The record of a bad-frame error; `None` for other errors (a missing program, an I/O
    /// failure of the pipe), which stop the run under either policy.
    pub fn from_error(e: &Error, source: &Path) -> Option<Self> {
        match e {
            Error::Frame {
                path,
                frame,
                message,
            } => Some(Self {
                frame: *frame,
                file: path.clone(),
                reason: message.clone(),
            }),
            Error::FrameSize {
                frame,
                got,
                expected,
            } => Some(Self {
                frame: *frame,
                file: source.to_owned(),
                reason: format!(
                    "frame is {}×{} px, expected {}×{} px",
                    got.0, got.1, expected.0, expected.1
                ),
            }),
            _ => None,
        }
    }
}

/// The frames a source skipped so far, shared between the source and whoever reports them
/// after the source has been consumed ([`super::FrameSource::skip_log`]).
#[derive(Debug, Clone, Default)]
pub struct SkipLog(Arc<Mutex<Vec<SkippedFrame>>>);

impl SkipLog {
    /// Records a skipped frame.
    pub fn push(&self, frame: SkippedFrame) {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(frame);
    }

    /// The frames skipped so far, in the order they were met.
    pub fn frames(&self) -> Vec<SkippedFrame> {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

/// The sidecar that lists the skipped frames of a run writing `output`:
/// `<output>.skipped.json` beside it (`frames/` → `frames.skipped.json`); `None` for `-`
/// (standard output) and for a device or FIFO (`/dev/null`: no file is made beside it),
/// whose runs report them on standard error only.
pub fn sidecar_path(output: &Path) -> Option<PathBuf> {
    if output.as_os_str() == "-" {
        return None;
    }
    // Choice: the sidecar goes beside regular files and folders only; metadata follows
    // symbolic links, and a path that does not exist yet will be a regular file or folder.
    if std::fs::metadata(output).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        return None;
    }
    // Drops a trailing `/` so a folder's sidecar lies beside it, not in it.
    let clean: PathBuf = output.components().collect();
    let name = clean.file_name()?.to_string_lossy().into_owned();
    Some(clean.with_file_name(format!("{name}.skipped.json")))
}

#[derive(Serialize)]
struct Sidecar<'a> {
    source: &'a Path,
    on_bad_frame: &'static str,
    skipped_count: usize,
    skipped: &'a [SkippedFrame],
}

/// Writes the sidecar of `source`'s skipped frames to `path`, atomically. It is written
/// even when nothing was skipped (an empty list), so a sidecar always belongs to the last
/// run that wrote its output.
///
/// # Errors
/// The file cannot be written.
pub fn write_sidecar(path: &Path, source: &Path, skipped: &[SkippedFrame]) -> Result<()> {
    let doc = Sidecar {
        source,
        on_bad_frame: "skip",
        skipped_count: skipped.len(),
        skipped,
    };
    write_atomic(path, |w| {
        serde_json::to_writer_pretty(&mut *w, &doc).map_err(std::io::Error::other)?;
        w.write_all(b"\n")
    })
}

/// A short account of skipped frames for a run's summary: runs of consecutive frames with
/// the same reason as one range, e.g. `4: missing …; 10–12: video ended …`.
pub fn summarize(skipped: &[SkippedFrame]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < skipped.len() {
        let first = &skipped[i];
        let mut j = i;
        while j + 1 < skipped.len()
            && skipped[j + 1].reason == first.reason
            && skipped[j + 1].frame == skipped[j].frame + 1
        {
            j += 1;
        }
        let range = if j == i {
            first.frame.to_string()
        } else {
            format!("{}–{}", first.frame, skipped[j].frame)
        };
        parts.push(format!("{range}: {}", first.reason));
        i = j + 1;
    }
    const SHOWN: usize = 8;
    if parts.len() > SHOWN {
        let more = parts.len() - SHOWN;
        parts.truncate(SHOWN);
        parts.push(format!("and {more} more"));
    }
    parts.join("; ")
}

/// Whether a JPEG file's bytes reach its end-of-image marker.
///
/// Choice: the `image` crate's JPEG decoder fills what a truncated file lacks with grey
/// and reports no error, and exposes no warnings; so the bytes are checked before
/// decoding. Entropy-coded data never holds `FF D9` (a data byte `FF` is stuffed as
/// `FF 00`), so a complete file has `FF D9` after its last start-of-scan marker `FF DA`;
/// bytes after that marker (padding, data some cameras append) are allowed. Damage in the
/// middle of the data that leaves the markers whole is not found here: the decoder decides.
///
/// # Errors
/// What is wrong, for the frame's error message.
pub fn check_jpeg_complete(bytes: &[u8]) -> std::result::Result<(), String> {
    if bytes.len() < 4 || bytes[0] != 0xFF || bytes[1] != 0xD8 {
        return Err("not a JPEG file (no start-of-image marker FF D8)".into());
    }
    let last_sos = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    let Some(sos) = last_sos else {
        return Err(
            "truncated or damaged JPEG: no image data (no start-of-scan marker FF DA)".into(),
        );
    };
    if bytes[sos..].windows(2).any(|w| w == [0xFF, 0xD9]) {
        Ok(())
    } else {
        Err(format!(
            "truncated JPEG: the file ends after {} bytes without its end-of-image marker \
             FF D9",
            bytes.len()
        ))
    }
}

/// The number a file name ends with (`000004.jpg` → 4, `frame_12.png` → 12).
fn trailing_number(path: &Path) -> Option<u64> {
    let stem = path.file_stem()?.to_str()?;
    let digits = stem.len() - stem.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    if digits == 0 {
        return None;
    }
    stem[stem.len() - digits..].parse().ok()
}

/// The frame number of each file of a folder (files in natural order), from the numbers
/// their names end with, so a deleted file is a gap in time rather than a renumbering.
///
/// Choice: a folder counts as numbered when every name ends in a number, no two files share
/// a number, and the numbers span at most twice as many frames as there are files (so
/// names that are timestamps, or every tenth frame of a film, are not read as mostly
/// missing frames). Numbers from 1 are the frame numbers; a folder numbered from 0 is
/// shifted by one (`000000.png` is frame 1). Anything else is numbered by position, 1, 2,
/// 3, …, as before. For a `sequence` (a MOTChallenge `img1/`, numbered from 1 by
/// convention) the span is counted from frame 1.
pub fn frame_numbers(files: &[PathBuf], sequence: bool) -> Vec<u32> {
    let positional = || (1..=files.len() as u32).collect();
    let Some(numbers) = files
        .iter()
        .map(|f| trailing_number(f))
        .collect::<Option<Vec<u64>>>()
    else {
        return positional();
    };
    let mut sorted = numbers.clone();
    sorted.sort_unstable();
    if sorted.windows(2).any(|w| w[0] == w[1]) {
        return positional();
    }
    let (Some(&lo), Some(&hi)) = (sorted.first(), sorted.last()) else {
        return positional();
    };
    let shift = u64::from(lo == 0);
    if hi + shift > u64::from(u32::MAX) {
        return positional();
    }
    let from = if sequence { 1 } else { lo + shift };
    let span = (hi + shift).saturating_sub(from) + 1;
    if span > 2 * files.len() as u64 {
        return positional();
    }
    // In natural order the numbers rise, except where the names' prefixes differ.
    if numbers.windows(2).any(|w| w[0] > w[1]) {
        return positional();
    }
    numbers.iter().map(|&n| (n + shift) as u32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths(names: &[&str]) -> Vec<PathBuf> {
        names.iter().map(PathBuf::from).collect()
    }

    #[test]
    fn numbered_folders_keep_their_gaps() {
        let f = paths(&["000001.jpg", "000002.jpg", "000004.jpg"]);
        assert_eq!(frame_numbers(&f, false), [1, 2, 4]);
        let f = paths(&["f0.png", "f1.png", "f3.png"]);
        assert_eq!(
            frame_numbers(&f, false),
            [1, 2, 4],
            "0-based shifted by one"
        );
        let f = paths(&["a.png", "b.png"]);
        assert_eq!(frame_numbers(&f, false), [1, 2], "unnumbered: by position");
        let f = paths(&["1.png", "1.jpg"]);
        assert_eq!(
            frame_numbers(&f, false),
            [1, 2],
            "shared number: by position"
        );
        let f = paths(&["20240101120000.png", "20240101120010.png"]);
        assert_eq!(frame_numbers(&f, false), [1, 2], "timestamps: by position");
        let f = paths(&["000005.png", "000006.png"]);
        assert_eq!(frame_numbers(&f, false), [5, 6]);
        let f = paths(&["000001.png", "000009.png"]);
        assert_eq!(frame_numbers(&f, false), [1, 2], "sparse: by position");
        let f = paths(&["000003.png", "000004.png"]);
        assert_eq!(frame_numbers(&f, false), [3, 4]);
        assert_eq!(frame_numbers(&f, true), [3, 4], "a sequence counts from 1");
        let f = paths(&["000004.png", "000005.png"]);
        assert_eq!(
            frame_numbers(&f, true),
            [1, 2],
            "mostly missing: by position"
        );
    }

    #[test]
    fn truncated_jpegs_are_found() {
        let mut bytes = Vec::new();
        image::RgbImage::from_pixel(16, 16, image::Rgb([200, 10, 10]))
            .write_to(
                &mut std::io::Cursor::new(&mut bytes),
                image::ImageFormat::Jpeg,
            )
            .expect("encode");
        assert_eq!(check_jpeg_complete(&bytes), Ok(()));
        let mut padded = bytes.clone();
        padded.extend_from_slice(&[0, 0, 0]);
        assert_eq!(check_jpeg_complete(&padded), Ok(()), "padding after FF D9");
        let cut = &bytes[..bytes.len() - 20];
        let m = check_jpeg_complete(cut).expect_err("truncated");
        assert!(m.contains("truncated JPEG"), "{m}");
        assert!(check_jpeg_complete(b"\x89PNG....").is_err());
    }

    #[test]
    fn summaries_group_runs_of_frames() {
        let s = |frame, reason: &str| SkippedFrame {
            frame,
            file: "x".into(),
            reason: reason.into(),
        };
        let v = [s(3, "a"), s(5, "b"), s(6, "b"), s(7, "b"), s(9, "b")];
        assert_eq!(summarize(&v), "3: a; 5–7: b; 9: b");
        assert_eq!(
            sidecar_path(Path::new("out/frames/")),
            Some(PathBuf::from("out/frames.skipped.json"))
        );
        assert_eq!(sidecar_path(Path::new("-")), None);
        #[cfg(unix)]
        assert_eq!(sidecar_path(Path::new("/dev/null")), None);
    }
}
