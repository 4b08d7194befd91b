//! Frame sources: a folder of numbered images, a MOTChallenge sequence folder, or a video
//! file decoded by ffmpeg. Each yields frames one at a time, so memory does not grow with
//! the sequence length.

use super::natural::natural_cmp;
use super::seqinfo::SeqInfo;
use super::video::VideoReader;
use crate::error::{Error, Result};
use crate::frame::Frame;
use std::path::{Path, PathBuf};

/// Which frames to read and at what rate (`--fps`, `--start`, `--end`, `--step`).
#[derive(Debug, Clone, PartialEq)]
pub struct SourceOptions {
    /// Frames per second for image folders (default 10); overrides a video's or
    /// `seqinfo.ini`'s rate when set explicitly.
    pub fps: Option<f64>,
    /// First frame to yield, 1-based (default 1).
    pub start: u32,
    /// Last frame to yield, inclusive (default: the last).
    pub end: Option<u32>,
    /// Yield every `step`-th frame from `start` (default 1).
    pub step: u32,
}

impl Default for SourceOptions {
    fn default() -> Self {
        Self {
            fps: None,
            start: 1,
            end: None,
            step: 1,
        }
    }
}

impl SourceOptions {
    /// Fails when the options cannot select frames.
    pub fn validate(&self) -> Result<()> {
        if self.start == 0 {
            return Err(Error::config(
                "SourceOptions",
                "start",
                "frames are numbered from 1",
            ));
        }
        if self.step == 0 {
            return Err(Error::config("SourceOptions", "step", "must be at least 1"));
        }
        if let Some(end) = self.end
            && end < self.start
        {
            return Err(Error::config(
                "SourceOptions",
                "end",
                format!("{end} is before start {}", self.start),
            ));
        }
        if let Some(fps) = self.fps
            && !(fps.is_finite() && fps > 0.0)
        {
            return Err(Error::config(
                "SourceOptions",
                "fps",
                format!("must be positive, found {fps}"),
            ));
        }
        if let Some(fps) = self.fps {
            crate::limits::at_most(fps, crate::limits::MAX_FPS, "frames/s")
                .map_err(|m| Error::config("SourceOptions", "fps", m))?;
        }
        Ok(())
    }

    /// Whether frame `index` is selected.
    pub fn selects(&self, index: u32) -> bool {
        index >= self.start
            && self.end.is_none_or(|e| index <= e)
            && (index - self.start).is_multiple_of(self.step)
    }

    /// How many of `total` frames are selected.
    pub fn count_of(&self, total: u32) -> u32 {
        let last = self.end.map_or(total, |e| e.min(total));
        if last < self.start {
            0
        } else {
            (last - self.start) / self.step + 1
        }
    }
}

/// What kind of source a path is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SourceKind {
    /// A folder of numbered PNG/JPEG images.
    ImageFolder,
    /// A MOTChallenge sequence folder (`seqinfo.ini`, `img1/`).
    MotSequence,
    /// A video file decoded by ffmpeg.
    Video,
}

/// What is known about a source before reading it.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceInfo {
    /// The path given.
    pub path: PathBuf,
    /// Its kind.
    pub kind: SourceKind,
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// Frames per second used for `time_s`.
    pub fps: f64,
    /// Frames in the whole source, when known.
    pub total_frames: Option<u32>,
    /// Frames the options select, when known.
    pub selected_frames: Option<u32>,
}

/// An open frame source: an iterator of frames plus what is known about it.
pub struct FrameSource {
    /// What is known about the source.
    pub info: SourceInfo,
    frames: Box<dyn Iterator<Item = Result<Frame>> + Send>,
}

impl std::fmt::Debug for FrameSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameSource")
            .field("info", &self.info)
            .finish_non_exhaustive()
    }
}

impl Iterator for FrameSource {
    type Item = Result<Frame>;

    fn next(&mut self) -> Option<Self::Item> {
        self.frames.next()
    }
}

/// Default frame rate of image folders, frames/s.
pub const DEFAULT_FPS: f64 = 10.0;

/// Opens `path` as a frame source.
///
/// A folder with `seqinfo.ini` is a MOTChallenge sequence; any other folder is read as
/// numbered images (`.png`, `.jpg`, `.jpeg`, in natural order); a file is a video.
pub fn open(path: &Path, options: &SourceOptions) -> Result<FrameSource> {
    options.validate()?;
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        let seqinfo = path.join("seqinfo.ini");
        if seqinfo.is_file() {
            let info = SeqInfo::read(&seqinfo)?;
            let fps = options.fps.unwrap_or(info.frame_rate);
            let files = list_images(&path.join(&info.im_dir))?;
            open_images(path, SourceKind::MotSequence, files, fps, options)
        } else {
            let files = list_images(path)?;
            open_images(
                path,
                SourceKind::ImageFolder,
                files,
                options.fps.unwrap_or(DEFAULT_FPS),
                options,
            )
        }
    } else {
        let reader = VideoReader::open(path, options.end)?;
        let fps = options.fps.unwrap_or(reader.fps);
        let total = reader.total_frames;
        let info = SourceInfo {
            path: path.to_owned(),
            kind: SourceKind::Video,
            width: reader.width,
            height: reader.height,
            fps,
            total_frames: total,
            selected_frames: total.map(|t| options.count_of(t)),
        };
        let opts = options.clone();
        let frames = reader
            .enumerate()
            .map(|(i, r)| (i as u32 + 1, r))
            .take_while(move |(i, _)| opts.end.is_none_or(|e| *i <= e))
            .filter({
                let opts = options.clone();
                move |(i, r)| r.is_err() || opts.selects(*i)
            })
            .map(move |(index, r)| {
                r.map(|image| Frame {
                    index,
                    time_s: f64::from(index - 1) / fps,
                    image,
                })
            });
        Ok(FrameSource {
            info,
            frames: Box::new(frames),
        })
    }
}

/// The image files of a folder (`.png`, `.jpg`, `.jpeg`, any case) in natural order.
pub fn list_images(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut files = Vec::new();
    for e in entries {
        let e = e.map_err(|err| Error::io(dir, err))?;
        let p = e.path();
        let ext = p
            .extension()
            .map(|x| x.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if p.is_file() && matches!(ext.as_str(), "png" | "jpg" | "jpeg") {
            files.push(p);
        }
    }
    files.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
    if files.is_empty() {
        return Err(Error::format(
            dir,
            "no .png, .jpg or .jpeg images in this folder",
        ));
    }
    Ok(files)
}

fn open_images(
    path: &Path,
    kind: SourceKind,
    files: Vec<PathBuf>,
    fps: f64,
    options: &SourceOptions,
) -> Result<FrameSource> {
    let total =
        u32::try_from(files.len()).map_err(|_| Error::format(path, "more than 2³² images"))?;
    let (width, height) = image::image_dimensions(&files[0]).map_err(|e| Error::Image {
        source: e,
        path: files[0].clone(),
    })?;
    let info = SourceInfo {
        path: path.to_owned(),
        kind,
        width,
        height,
        fps,
        total_frames: Some(total),
        selected_frames: Some(options.count_of(total)),
    };
    let opts = options.clone();
    let frames = files
        .into_iter()
        .enumerate()
        .map(|(i, f)| (i as u32 + 1, f))
        .filter(move |(i, _)| opts.selects(*i))
        .map(move |(index, file)| {
            let image = image::open(&file)
                .map_err(|e| Error::Frame {
                    path: file.clone(),
                    frame: index,
                    message: e.to_string(),
                })?
                .into_rgb8();
            if image.dimensions() != (width, height) {
                return Err(Error::Frame {
                    path: file,
                    frame: index,
                    message: format!(
                        "image is {}×{} px, the first frame is {width}×{height} px",
                        image.width(),
                        image.height()
                    ),
                });
            }
            Ok(Frame {
                index,
                time_s: f64::from(index - 1) / fps,
                image,
            })
        });
    Ok(FrameSource {
        info,
        frames: Box::new(frames),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{Rgb, RgbImage};

    fn folder(n: u32, names: impl Fn(u32) -> String) -> tempfile::TempDir {
        let dir = tempfile::tempdir().expect("tempdir");
        for i in 1..=n {
            let img = RgbImage::from_pixel(8, 6, Rgb([i as u8, 0, 0]));
            img.save(dir.path().join(names(i))).expect("save");
        }
        dir
    }

    #[test]
    fn image_folder_yields_frames_in_natural_order_with_time() -> Result<()> {
        let dir = folder(12, |i| format!("f{i}.png"));
        let src = open(dir.path(), &SourceOptions::default())?;
        assert_eq!(
            (src.info.width, src.info.height, src.info.total_frames),
            (8, 6, Some(12))
        );
        let frames: Vec<Frame> = src.collect::<Result<_>>()?;
        assert_eq!(frames.len(), 12);
        for (k, f) in frames.iter().enumerate() {
            assert_eq!(f.index, k as u32 + 1);
            assert_eq!(f.image.get_pixel(0, 0)[0], k as u8 + 1, "natural order");
            assert!((f.time_s - k as f64 / 10.0).abs() < 1e-12);
        }
        Ok(())
    }

    #[test]
    fn start_end_step_select_frames() -> Result<()> {
        let dir = folder(10, |i| format!("{i:04}.png"));
        let opts = SourceOptions {
            fps: Some(5.0),
            start: 2,
            end: Some(9),
            step: 3,
        };
        let src = open(dir.path(), &opts)?;
        assert_eq!(src.info.selected_frames, Some(3));
        let idx: Vec<u32> = src.map(|f| f.map(|f| f.index)).collect::<Result<_>>()?;
        assert_eq!(idx, [2, 5, 8]);
        let f = open(dir.path(), &opts)?.next().expect("one frame")?;
        assert!((f.time_s - 0.2).abs() < 1e-12);
        Ok(())
    }

    #[test]
    fn mot_sequence_uses_seqinfo() -> Result<()> {
        let dir = tempfile::tempdir().expect("tempdir");
        let img1 = dir.path().join("img1");
        std::fs::create_dir(&img1).expect("mkdir");
        for i in 1..=3 {
            RgbImage::new(4, 4)
                .save(img1.join(format!("{i:06}.jpg")))
                .expect("save");
        }
        SeqInfo {
            name: "x".into(),
            im_dir: "img1".into(),
            frame_rate: 25.0,
            seq_length: 3,
            im_width: 4,
            im_height: 4,
            im_ext: ".jpg".into(),
        }
        .write(&dir.path().join("seqinfo.ini"))?;
        let src = open(dir.path(), &SourceOptions::default())?;
        assert_eq!(
            (src.info.kind, src.info.fps),
            (SourceKind::MotSequence, 25.0)
        );
        assert_eq!(src.count(), 3);
        Ok(())
    }

    #[test]
    fn bad_sources_give_clear_errors() {
        let dir = tempfile::tempdir().expect("tempdir");
        let m = open(dir.path(), &SourceOptions::default())
            .expect_err("empty")
            .to_string();
        assert!(m.contains("no .png"), "{m}");
        let dir = folder(2, |i| format!("{i}.png"));
        RgbImage::new(3, 3)
            .save(dir.path().join("3.png"))
            .expect("save");
        let errs: Vec<_> = open(dir.path(), &SourceOptions::default())
            .expect("open")
            .filter_map(|f| f.err())
            .collect();
        assert_eq!(errs.len(), 1);
        let m = errs[0].to_string();
        assert!(m.contains("frame 3") && m.contains("3×3"), "{m}");
        let m = open(Path::new("/nonexistent/x.avi"), &SourceOptions::default())
            .expect_err("missing")
            .to_string();
        assert!(m.contains("/nonexistent/x.avi"), "{m}");
        let bad = SourceOptions {
            step: 0,
            ..Default::default()
        };
        assert!(open(dir.path(), &bad).is_err());
    }
}
