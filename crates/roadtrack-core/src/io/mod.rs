//! Input and output: frame sources and the file formats of INTERFACES.md.
//!
//! A frame source is any `Iterator<Item = Result<Frame>>`; [`source::open`] picks the right
//! one for a path (folder of numbered images, MOTChallenge sequence, video file). Every
//! writer goes through [`atomic::write_atomic`], so an interrupted run never leaves a
//! half-written file that looks complete.

pub mod atomic;
pub mod bad_frame;
pub mod detections;
pub mod geojson;
pub mod matches;
pub mod mot;
pub mod natural;
pub mod occlusion;
pub mod points;
pub mod seqinfo;
pub mod series;
pub mod sink;
pub mod source;
pub mod table;
pub mod trajectories;
pub mod video;

pub use atomic::{AtomicFile, write_atomic};
pub use bad_frame::{OnBadFrame, SkipLog, SkippedFrame};
pub use source::{FrameSource, SourceInfo, SourceKind, SourceOptions};

use crate::error::Result;
use crate::track_point::TrackPoint;
use std::path::{Path, PathBuf};

/// Reads tracks from a MOTChallenge tracks file or a trajectories CSV, chosen by extension:
/// `.csv` is a trajectories CSV ([`trajectories::read_trajectories`]); anything else is a
/// MOTChallenge tracks file ([`mot::read_tracks`]), whose rows get unknown class and time
/// `(frame − 1) / fps`.
///
/// # Errors
/// As the reader chosen.
pub fn read_track_points(path: &Path, fps: f64) -> Result<Vec<TrackPoint>> {
    if has_extension(path, "csv") {
        trajectories::read_trajectories(path)
    } else {
        Ok(mot::read_tracks(path)?
            .iter()
            .map(|r| r.to_track_point(fps))
            .collect())
    }
}

/// Reads ground truth as track points: a MOTChallenge sequence folder (its `gt/gt.txt`), a
/// MOTChallenge ground-truth file, or a trajectories CSV (`.csv`). Rows of a MOTChallenge
/// file marked `consider = 0` are left out, as evaluation ignores them.
///
/// # Errors
/// As the reader chosen; a folder without `gt/gt.txt`.
pub fn read_truth_points(path: &Path, fps: f64) -> Result<Vec<TrackPoint>> {
    let file: PathBuf = if path.is_dir() {
        let gt = path.join("gt").join("gt.txt");
        if !gt.is_file() {
            return Err(crate::Error::format(
                path,
                "folder has no gt/gt.txt; give a MOTChallenge sequence folder or a gt file",
            ));
        }
        gt
    } else {
        path.to_owned()
    };
    if has_extension(&file, "csv") {
        return trajectories::read_trajectories(&file);
    }
    // Choice: non-considered rows (distractors, static people) are not drawn, matching
    // what the metrics count.
    Ok(mot::read_gt(&file)?
        .iter()
        .filter(|r| r.consider)
        .map(|r| r.to_track_point(fps))
        .collect())
}

/// Reads `path` as UTF-8 text.
///
/// # Errors
/// [`crate::Error::Io`] when the file cannot be read; [`crate::Error::Parse`] naming the
/// line of the first byte that is not UTF-8 (the file was read: an I/O error would wrongly
/// say it cannot be accessed).
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| crate::Error::io(path, e))?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes[..at].iter().filter(|&&b| b == b'\n').count() as u64 + 1;
        crate::Error::parse(
            path,
            line,
            "-",
            format!("not UTF-8 text (byte 0x{:02x} at offset {at})", bytes[at]),
        )
    })
}

fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
}
