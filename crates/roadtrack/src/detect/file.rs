//! Public detections as a detector (`--detector file`): a MOTChallenge `det/det.txt` or a
//! detections CSV (`docs/FORMATS.md`), handed out frame by frame.
//!
//! Detections without a mean colour get the mean RGB of their box in the frame (seed 000's
//! colour variants need it); those without a size keep none.

use super::{Detector, FrameDetections};
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::geometry::BBox;
use image::RgbImage;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Which format a detections file is in, from its name: `.csv` is a detections CSV,
/// anything else a MOTChallenge detections file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectionsFormat {
    /// `frame,-1,left,top,width,height,conf,…` without a header.
    Mot,
    /// The detections CSV of INTERFACES.md.
    Csv,
}

impl DetectionsFormat {
    /// The format of `path` by its extension.
    pub fn of(path: &Path) -> Self {
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
        {
            DetectionsFormat::Csv
        } else {
            DetectionsFormat::Mot
        }
    }
}

/// The public detections of a sequence folder: `det/det.txt` when it has one.
pub fn sequence_detections(folder: &Path) -> Option<PathBuf> {
    let p = folder.join("det").join("det.txt");
    p.is_file().then_some(p)
}

/// Detections read from a file.
#[derive(Debug, Clone)]
pub struct FileDetector {
    path: PathBuf,
    by_frame: BTreeMap<u32, Vec<Detection>>,
}

impl FileDetector {
    /// Reads `path` (format by extension, [`DetectionsFormat::of`]). With `last_frame`
    /// (the input's length, when known), a detection for a later frame is an error naming
    /// the file and line: those detections belong to another input.
    ///
    /// # Errors
    /// The file cannot be read or is malformed (file, line, column); it is empty; it has
    /// detections after `last_frame`.
    pub fn open(path: &Path, last_frame: Option<u32>) -> Result<Self> {
        let detections = match DetectionsFormat::of(path) {
            DetectionsFormat::Csv => crate::io::detections::read_detections(path)?,
            DetectionsFormat::Mot => crate::io::mot::read_detections(path)?,
        };
        if detections.is_empty() {
            return Err(Error::format(path, "no detections in the file"));
        }
        if let Some(last) = last_frame
            && let Some(d) = detections.iter().find(|d| d.frame > last)
        {
            let line =
                line_of_frame(path, d.frame).map_or(String::new(), |l| format!(", line {l}"));
            return Err(Error::Invalid(format!(
                "{}{line}: detections for frame {} but the input has only {last} frames \
                 (are these the detections of another video?)",
                path.display(),
                d.frame
            )));
        }
        let mut by_frame: BTreeMap<u32, Vec<Detection>> = BTreeMap::new();
        for d in detections {
            by_frame.entry(d.frame).or_default().push(d);
        }
        Ok(Self {
            path: path.to_owned(),
            by_frame,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// The 1-based line of the first row of `frame` in a detections file (for messages).
fn line_of_frame(path: &Path, frame: u32) -> Option<usize> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut lines = text.lines().enumerate();
    let column = match DetectionsFormat::of(path) {
        DetectionsFormat::Mot => 0,
        DetectionsFormat::Csv => {
            let (_, header) = lines.next()?;
            header.split(',').position(|h| {
                h.trim()
                    .trim_start_matches('\u{feff}')
                    .eq_ignore_ascii_case("frame")
            })?
        }
    };
    lines
        .find(|(_, l)| {
            l.split(',')
                .nth(column)
                .and_then(|f| f.trim().parse::<f64>().ok())
                .is_some_and(|f| f == f64::from(frame))
        })
        .map(|(i, _)| i + 1)
}

/// The pixels `x0..x1 × y0..y1` that `bbox` touches in a `w × h` image (clipped), `None`
/// when it misses the image.
pub(crate) fn pixel_span(bbox: &BBox, w: u32, h: u32) -> Option<(u32, u32, u32, u32)> {
    let x0 = bbox.left.max(0.0).floor() as u32;
    let y0 = bbox.top.max(0.0).floor() as u32;
    let x1 = ((bbox.left + bbox.width).ceil().max(0.0) as u32).min(w);
    let y1 = ((bbox.top + bbox.height).ceil().max(0.0) as u32).min(h);
    (x1 > x0 && y1 > y0).then_some((x0, x1, y0, y1))
}

/// Mean RGB of `image` inside `bbox` (clipped), `None` when the box misses the image.
pub fn mean_colour(image: &RgbImage, bbox: &BBox) -> Option<[f64; 3]> {
    let (x0, x1, y0, y1) = pixel_span(bbox, image.width(), image.height())?;
    let mut sum = [0u64; 3];
    for y in y0..y1 {
        for x in x0..x1 {
            let p = image.get_pixel(x, y).0;
            for k in 0..3 {
                sum[k] += u64::from(p[k]);
            }
        }
    }
    let n = f64::from((x1 - x0) * (y1 - y0));
    Some(sum.map(|s| s as f64 / n))
}

/// The one-pixel box of the image pixel nearest `p`.
fn nearest_pixel(image: &RgbImage, p: crate::geometry::Point) -> BBox {
    let x = p.x.floor().clamp(0.0, f64::from(image.width().max(1) - 1));
    let y = p.y.floor().clamp(0.0, f64::from(image.height().max(1) - 1));
    BBox::new(x, y, 1.0, 1.0)
}

impl Detector for FileDetector {
    fn detect(&mut self, frame: &Frame) -> Result<FrameDetections> {
        let mut detections = self.by_frame.remove(&frame.index).unwrap_or_default();
        for (i, d) in detections.iter_mut().enumerate() {
            // Choice: ids are renumbered 1.. within the frame in file order, as every
            // detector numbers its output (a MOT file's ids are −1).
            d.id = i as u64 + 1;
            if d.colour_rgb.is_none() {
                // Choice: a box that misses the image (public detections may stick out)
                // takes the colour of the image pixel nearest its centre.
                let b = d
                    .bbox()
                    .unwrap_or_else(|| BBox::from_centre(d.pos_px, 1.0, 1.0));
                d.colour_rgb = mean_colour(&frame.image, &b)
                    .or_else(|| mean_colour(&frame.image, &nearest_pixel(&frame.image, d.pos_px)));
            }
        }
        Ok(FrameDetections {
            detections,
            foreground: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point;
    use image::Rgb;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).expect("write");
        p
    }

    fn frame(index: u32) -> Frame {
        let mut image = RgbImage::from_pixel(40, 30, Rgb([10, 20, 30]));
        for y in 10..20 {
            for x in 10..20 {
                image.put_pixel(x, y, Rgb([200, 100, 50]));
            }
        }
        Frame {
            index,
            time_s: 0.0,
            image,
        }
    }

    #[test]
    fn mot_detections_come_back_per_frame_with_the_colour_of_their_box() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = write(
            dir.path(),
            "det.txt",
            "2,-1,10,10,10,10,0.9,-1,-1,-1\n2,-1,0,0,5,5,0.5,-1,-1,-1\n",
        );
        let mut d = FileDetector::open(&p, Some(3))?;
        assert!(d.detect(&frame(1))?.detections.is_empty());
        let f2 = d.detect(&frame(2))?;
        assert_eq!(f2.detections.len(), 2);
        assert!(f2.foreground.is_none());
        let first = &f2.detections[0];
        assert_eq!((first.id, first.pos_px), (1, Point::new(15.0, 15.0)));
        assert_eq!(first.colour_rgb, Some([200.0, 100.0, 50.0]));
        assert_eq!(first.score, Some(0.9));
        assert_eq!(f2.detections[1].colour_rgb, Some([10.0, 20.0, 30.0]));
        Ok(())
    }

    #[test]
    fn detections_after_the_input_and_empty_files_are_errors_naming_file_and_line() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = write(dir.path(), "d.csv", "frame,x,y\n1,5,5\n1,6,6\n9,7,7\n");
        let err = FileDetector::open(&p, Some(4))
            .expect_err("frame 9")
            .to_string();
        assert!(
            err.contains("d.csv, line 4") && err.contains("frame 9"),
            "{err}"
        );
        assert!(FileDetector::open(&p, Some(9)).is_ok());
        let empty = write(dir.path(), "e.txt", "");
        let err = FileDetector::open(&empty, None)
            .expect_err("empty")
            .to_string();
        assert!(err.contains("e.txt"), "{err}");
        Ok(())
    }
}
