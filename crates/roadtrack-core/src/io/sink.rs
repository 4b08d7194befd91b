//! Where rendered frames go: a folder of PNG files or a video file.
//!
//! [`open_sink`] picks by the output path: a name ending in `.mp4`, `.mkv`, `.avi` or
//! `.webm` is a video ([`super::video::VideoWriter`], encoded by the ffmpeg program);
//! anything else is a folder that receives `NNNNNN.png` per frame (the frame's 1-based
//! number, zero-padded to 6 digits), each written atomically.

use super::atomic::AtomicDir;
use super::video::VideoWriter;
use crate::error::{Error, Result};
use image::RgbImage;
use std::path::{Path, PathBuf};

/// A destination for a sequence of frames.
///
/// Implemented by [`PngFolder`] and [`VideoWriter`]; tests use ten-line collectors.
pub trait FrameSink {
    /// Writes frame number `index` (1-based, as in the source).
    fn write_frame(&mut self, index: u32, image: &RgbImage) -> Result<()>;
    /// Completes the output (a video is only in place after this); later calls do nothing.
    fn finish(&mut self) -> Result<()>;
}

/// Extensions that make [`open_sink`] write a video.
pub const VIDEO_EXTENSIONS: [&str; 4] = ["mp4", "mkv", "avi", "webm"];

/// Whether `path` names a video file by its extension (case-insensitive).
pub fn is_video_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| VIDEO_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// A folder of PNG files, one per frame, swapped in whole at [`FrameSink::finish`]
/// ([`AtomicDir`]): an interrupted render leaves no frames, and a finished one no stale
/// frames of an earlier run.
#[derive(Debug)]
pub struct PngFolder {
    dir: Option<AtomicDir>,
}

impl PngFolder {
    /// Writes into `dir` (created when missing, replaced when it exists).
    ///
    /// # Errors
    /// `dir` is `-` or exists and is not a folder; the temporary folder cannot be made.
    pub fn create(dir: &Path) -> Result<Self> {
        Ok(Self {
            dir: Some(AtomicDir::create(dir)?),
        })
    }

    /// The path frame `index` is written to while the run lasts.
    pub fn frame_path(&self, index: u32) -> PathBuf {
        let dir = self
            .dir
            .as_ref()
            .map_or(Path::new("."), AtomicDir::temp_path);
        dir.join(format!("{index:06}.png"))
    }
}

/// `image` encoded as PNG.
pub fn encode_png(image: &RgbImage, path_for_errors: &Path) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|source| Error::Image {
            source,
            path: path_for_errors.to_owned(),
        })?;
    Ok(bytes)
}

impl FrameSink for PngFolder {
    fn write_frame(&mut self, index: u32, image: &RgbImage) -> Result<()> {
        if self.dir.is_none() {
            return Err(Error::Invalid("internal error: frame after finish".into()));
        }
        let path = self.frame_path(index);
        std::fs::write(&path, encode_png(image, &path)?).map_err(|e| Error::io(&path, e))
    }

    fn finish(&mut self) -> Result<()> {
        self.dir.take().map_or(Ok(()), AtomicDir::commit)
    }
}

impl FrameSink for VideoWriter {
    fn write_frame(&mut self, index: u32, image: &RgbImage) -> Result<()> {
        VideoWriter::write_frame(self, index, image)
    }

    fn finish(&mut self) -> Result<()> {
        VideoWriter::finish(self)
    }
}

/// A video sink that starts ffmpeg when the first frame tells the size.
#[derive(Debug)]
struct LazyVideo {
    path: PathBuf,
    fps: f64,
    writer: Option<VideoWriter>,
}

impl FrameSink for LazyVideo {
    fn write_frame(&mut self, index: u32, image: &RgbImage) -> Result<()> {
        if self.writer.is_none() {
            let (w, h) = image.dimensions();
            self.writer = Some(VideoWriter::create(&self.path, w, h, self.fps)?);
        }
        match &mut self.writer {
            Some(w) => w.write_frame(index, image),
            None => Ok(()),
        }
    }

    fn finish(&mut self) -> Result<()> {
        match &mut self.writer {
            Some(w) => w.finish(),
            None => Err(Error::Invalid(format!(
                "{}: no frames to write; the video was not created",
                self.path.display()
            ))),
        }
    }
}

/// A video sink that keeps time over skipped frames (`--on-bad-frame skip`): when a frame
/// arrives more than `step` frames after the one before, the one before is held (written
/// again) for the missing frames, so the video stays as long as the source and later frames
/// keep their times. A PNG folder needs none of this: its file names carry the frame
/// numbers.
pub struct HoldOverGaps {
    inner: Box<dyn FrameSink>,
    step: u32,
    last: Option<(u32, RgbImage)>,
}

impl HoldOverGaps {
    /// Wraps `inner`, whose frames are `step` source frames apart (`--step`).
    pub fn new(inner: Box<dyn FrameSink>, step: u32) -> Self {
        Self {
            inner,
            step: step.max(1),
            last: None,
        }
    }
}

impl FrameSink for HoldOverGaps {
    fn write_frame(&mut self, index: u32, image: &RgbImage) -> Result<()> {
        if let Some((k, held)) = &self.last
            && index > *k
        {
            for _ in 1..(index - k) / self.step {
                self.inner.write_frame(*k, held)?;
            }
        }
        self.inner.write_frame(index, image)?;
        self.last = Some((index, image.clone()));
        Ok(())
    }

    fn finish(&mut self) -> Result<()> {
        self.inner.finish()
    }
}

/// A sink for `path`: a video when [`is_video_path`], else a PNG folder. `fps` is the
/// video's frame rate (ignored for PNG folders).
///
/// # Errors
/// A PNG folder that cannot be created, or a non-positive `fps` for a video. ffmpeg is
/// only started at the first frame, so its errors come from [`FrameSink::write_frame`].
pub fn open_sink(path: &Path, fps: f64) -> Result<Box<dyn FrameSink>> {
    if is_video_path(path) {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(Error::Invalid(format!(
                "video frame rate must be positive, found {fps}"
            )));
        }
        Ok(Box::new(LazyVideo {
            path: path.to_owned(),
            fps,
            writer: None,
        }))
    } else {
        Ok(Box::new(PngFolder::create(path)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_are_held_over_at_the_frame_step() -> Result<()> {
        struct Log(std::sync::Arc<std::sync::Mutex<Vec<(u32, u8)>>>);
        impl FrameSink for Log {
            fn write_frame(&mut self, index: u32, image: &RgbImage) -> Result<()> {
                if let Ok(mut v) = self.0.lock() {
                    v.push((index, image.get_pixel(0, 0)[0]));
                }
                Ok(())
            }
            fn finish(&mut self) -> Result<()> {
                Ok(())
            }
        }
        let got = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut sink = HoldOverGaps::new(Box::new(Log(got.clone())), 2);
        for i in [1u8, 3, 9, 11] {
            sink.write_frame(
                u32::from(i),
                &RgbImage::from_pixel(1, 1, image::Rgb([i, 0, 0])),
            )?;
        }
        sink.finish()?;
        let got = got.lock().map(|v| v.clone()).unwrap_or_default();
        // Frames 5 and 7 are missing: frame 3 is shown in their place.
        assert_eq!(got, [(1, 1), (3, 3), (3, 3), (3, 3), (9, 9), (11, 11)]);
        Ok(())
    }

    #[test]
    fn video_paths_are_recognised_by_extension() {
        assert!(is_video_path(Path::new("out/a.MP4")));
        assert!(is_video_path(Path::new("a.webm")));
        assert!(!is_video_path(Path::new("frames")));
        assert!(!is_video_path(Path::new("a.png")));
    }

    #[test]
    fn png_folder_writes_numbered_frames_that_decode_to_the_same_pixels() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let out = dir.path().join("frames");
        let mut sink = open_sink(&out, 10.0)?;
        let img = RgbImage::from_fn(7, 5, |x, y| image::Rgb([x as u8 * 30, y as u8 * 40, 9]));
        sink.write_frame(3, &img)?;
        sink.finish()?;
        let back = image::open(out.join("000003.png"))
            .map_err(|source| Error::Image {
                source,
                path: out.clone(),
            })?
            .to_rgb8();
        assert_eq!(back, img);
        Ok(())
    }

    #[test]
    fn a_file_in_the_way_of_the_png_folder_is_an_error() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let f = dir.path().join("x");
        std::fs::write(&f, "x").map_err(|e| Error::io(&f, e))?;
        assert!(open_sink(&f, 10.0).is_err());
        Ok(())
    }
}
