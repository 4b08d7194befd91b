//! Frame sources: a folder of numbered images, a MOTChallenge sequence folder, or a video
//! file decoded by ffmpeg. Each yields frames one at a time, so memory does not grow with
//! the sequence length.
//!
//! A frame that cannot be read (an undecodable or truncated image, a frame of another
//! size, a gap in a numbered folder, a video that ends before the frame count it announced)
//! is an error naming the frame and the file, or, with [`OnBadFrame::Skip`], left out and
//! recorded in the source's [`SkipLog`]. Frames keep the source's numbering either way, so
//! a missing frame is a gap in time, not a renumbering.
//!
//! Images are decoded on a thread of their own, a few frames ahead of the reader
//! ([`Prefetch`]), so decoding overlaps whatever the reader does with each frame. A video
//! is decoded by the ffmpeg process, beside the reader already.

use super::bad_frame::{OnBadFrame, SkipLog, SkippedFrame, check_jpeg_complete, frame_numbers};
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
    /// What to do with a frame that cannot be read (`--on-bad-frame`; default: fail).
    pub on_bad_frame: OnBadFrame,
}

impl Default for SourceOptions {
    fn default() -> Self {
        Self {
            fps: None,
            start: 1,
            end: None,
            step: 1,
            on_bad_frame: OnBadFrame::Fail,
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

    /// How many of the frames `first..=last` are selected.
    pub fn count_between(&self, first: u32, last: u32) -> u32 {
        let before = first.saturating_sub(1);
        self.count_of(last).saturating_sub(self.count_of(before))
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
///
/// Under [`OnBadFrame::Skip`] it leaves out the frames it cannot read and records them in
/// its [`SkipLog`] ([`FrameSource::skip_log`]); under [`OnBadFrame::Fail`] such a frame is
/// an error item. Other errors (a missing ffmpeg, a failing pipe) are error items either
/// way.
pub struct FrameSource {
    /// What is known about the source.
    pub info: SourceInfo,
    frames: Box<dyn Iterator<Item = Result<Frame>> + Send>,
    on_bad_frame: OnBadFrame,
    skipped: SkipLog,
    /// Under fail: a bad frame was met, so the source has ended.
    failed: bool,
}

impl FrameSource {
    fn new(
        info: SourceInfo,
        frames: Box<dyn Iterator<Item = Result<Frame>> + Send>,
        options: &SourceOptions,
    ) -> Self {
        Self {
            info,
            frames,
            on_bad_frame: options.on_bad_frame,
            skipped: SkipLog::default(),
            failed: false,
        }
    }

    /// A handle on the frames skipped so far, to read after the source has been consumed.
    pub fn skip_log(&self) -> SkipLog {
        self.skipped.clone()
    }
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

    /// The next frame; under fail the first error is the source's last item (a reader
    /// that samples frames cannot pass over it and report a later one).
    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        loop {
            match self.frames.next()? {
                Err(e) if self.on_bad_frame == OnBadFrame::Skip => {
                    match SkippedFrame::from_error(&e, &self.info.path) {
                        Some(s) => self.skipped.push(s),
                        None => return Some(Err(e)),
                    }
                }
                Err(e) => {
                    self.failed = true;
                    return Some(Err(e));
                }
                item => return Some(item),
            }
        }
    }
}

/// Default frame rate of image folders, frames/s.
pub const DEFAULT_FPS: f64 = 10.0;

/// Opens `path` as a frame source.
///
/// A folder with `seqinfo.ini` is a MOTChallenge sequence; any other folder is read as
/// numbered images (`.png`, `.jpg`, `.jpeg`, in natural order; see
/// [`super::bad_frame::frame_numbers`] for how names become frame numbers); a file is a
/// video.
pub fn open(path: &Path, options: &SourceOptions) -> Result<FrameSource> {
    options.validate()?;
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        let seqinfo = path.join("seqinfo.ini");
        if seqinfo.is_file() {
            let info = SeqInfo::read(&seqinfo)?;
            let fps = options.fps.unwrap_or(info.frame_rate);
            let dir = path.join(&info.im_dir);
            let files = list_images(&dir)?;
            let folder = ImageFolder {
                kind: SourceKind::MotSequence,
                dir,
                files,
                announced: Some(info.seq_length),
            };
            open_images(path, folder, fps, options)
        } else {
            let files = list_images(path)?;
            let folder = ImageFolder {
                kind: SourceKind::ImageFolder,
                dir: path.to_owned(),
                files,
                announced: None,
            };
            open_images(path, folder, options.fps.unwrap_or(DEFAULT_FPS), options)
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
        let announced = reader.announced_frames();
        let frames = VideoFrames {
            path: path.to_owned(),
            reader,
            options: options.clone(),
            fps,
            read: 0,
            announced,
            missing: None,
            done: false,
        };
        Ok(FrameSource::new(info, Box::new(frames), options))
    }
}

/// The frames of a video, numbered as decoded, then one bad-frame error for each selected
/// frame the video announced but did not deliver.
struct VideoFrames {
    path: PathBuf,
    reader: VideoReader,
    options: SourceOptions,
    fps: f64,
    /// Frames decoded so far.
    read: u32,
    /// The frame count the container announced (or its duration implies).
    announced: Option<u32>,
    /// Frames still to report as missing (next, last) and why.
    missing: Option<(u32, u32, String)>,
    done: bool,
}

impl VideoFrames {
    /// After the decoder stopped at frame `self.read`: the frames up to the announced
    /// count (within `--end`) from `from` on are missing.
    fn ended(&mut self, from: u32) {
        self.done = true;
        let Some(announced) = self.announced else {
            return;
        };
        let last = self.options.end.map_or(announced, |e| e.min(announced));
        if from <= last {
            self.missing = Some((
                from,
                last,
                format!(
                    "video ended at frame {} of {announced} announced (cut short or damaged)",
                    self.read
                ),
            ));
        }
    }
}

impl Iterator for VideoFrames {
    type Item = Result<Frame>;

    fn next(&mut self) -> Option<Result<Frame>> {
        loop {
            if let Some((next, last, reason)) = &mut self.missing {
                while *next <= *last {
                    let k = *next;
                    *next += 1;
                    if self.options.selects(k) {
                        return Some(Err(Error::Frame {
                            path: self.path.clone(),
                            frame: k,
                            message: reason.clone(),
                        }));
                    }
                }
                self.missing = None;
                return None;
            }
            if self.done {
                return None;
            }
            match self.reader.next() {
                Some(Ok(image)) => {
                    self.read += 1;
                    let index = self.read;
                    if self.options.end.is_some_and(|e| index > e) {
                        self.done = true;
                        return None;
                    }
                    if self.options.selects(index) {
                        return Some(Ok(Frame {
                            index,
                            time_s: f64::from(index - 1) / self.fps,
                            image,
                        }));
                    }
                }
                Some(Err(e)) => {
                    // The decoder is finished after an error: the frame it failed on is
                    // bad, and so is every announced frame after it.
                    let failed = self.read + 1;
                    self.ended(failed + 1);
                    let is_frame_error = matches!(e, Error::Frame { .. });
                    if !is_frame_error || self.options.selects(failed) {
                        return Some(Err(e));
                    }
                }
                None => self.ended(self.read + 1),
            }
        }
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

/// The images of a folder or of a sequence's image folder.
struct ImageFolder {
    kind: SourceKind,
    /// The folder holding the images.
    dir: PathBuf,
    files: Vec<PathBuf>,
    /// The frame count `seqinfo.ini` announces.
    announced: Option<u32>,
}

/// Decodes one image file, frame `frame` of its folder.
///
/// # Errors
/// [`Error::Frame`] naming the file: unreadable, truncated (a JPEG without its end
/// marker, see [`check_jpeg_complete`]) or undecodable.
pub fn read_image(file: &Path, frame: u32) -> Result<image::RgbImage> {
    let bad = |message: String| Error::Frame {
        path: file.to_owned(),
        frame,
        message,
    };
    let bytes = std::fs::read(file).map_err(|e| bad(format!("cannot read: {e}")))?;
    let format = image::ImageFormat::from_path(file).ok();
    if format == Some(image::ImageFormat::Jpeg) {
        check_jpeg_complete(&bytes).map_err(bad)?;
    }
    let decoded = match format {
        Some(f) => image::load_from_memory_with_format(&bytes, f),
        None => image::load_from_memory(&bytes),
    };
    Ok(decoded.map_err(|e| bad(e.to_string()))?.into_rgb8())
}

fn open_images(
    path: &Path,
    folder: ImageFolder,
    fps: f64,
    options: &SourceOptions,
) -> Result<FrameSource> {
    let ImageFolder {
        kind,
        dir,
        files,
        announced,
    } = folder;
    if u32::try_from(files.len()).is_err() {
        return Err(Error::format(path, "more than 2³² images"));
    }
    let sequence = kind == SourceKind::MotSequence;
    let numbers = frame_numbers(&files, sequence);
    let numbered: Vec<(u32, PathBuf)> = numbers.into_iter().zip(files).collect();
    // Choice: a sequence's frames run from 1 to the larger of its last image and
    // seqinfo.ini's seqLength, so lost frames at either end are missing frames; a plain
    // folder's run from its first image to its last (it announces nothing more).
    let first = if sequence { 1 } else { numbered[0].0 };
    let last_file = numbered[numbered.len() - 1].0;
    let last = announced.map_or(last_file, |n| n.max(last_file));
    // The size comes from the first image whose header reads (under skip; under fail a
    // bad first header is the first frame's error).
    let mut size = None;
    for (frame, file) in &numbered {
        match image::image_dimensions(file) {
            Ok(d) => {
                size = Some(d);
                break;
            }
            Err(e) if options.on_bad_frame == OnBadFrame::Fail => {
                return Err(Error::Frame {
                    path: file.clone(),
                    frame: *frame,
                    message: e.to_string(),
                });
            }
            Err(_) => {}
        }
    }
    let Some((width, height)) = size else {
        return Err(Error::format(&dir, "no image in this folder can be read"));
    };
    let info = SourceInfo {
        path: path.to_owned(),
        kind,
        width,
        height,
        fps,
        total_frames: Some(last),
        selected_frames: Some(options.count_between(first, last)),
    };
    let opts = options.clone();
    let end = options.end.map_or(last, |e| e.min(last));
    let mut files = numbered.into_iter().peekable();
    let frames = (first..=end)
        .filter(move |k| opts.selects(*k))
        .map(move |index| {
            while files.next_if(|(n, _)| *n < index).is_some() {}
            let Some((_, file)) = files.next_if(|(n, _)| *n == index) else {
                return Err(Error::Frame {
                    path: dir.clone(),
                    frame: index,
                    message: format!(
                        "missing: no image for this frame (the folder's images are \
                         numbered as frames {first}–{last_file}{})",
                        if last > last_file {
                            format!(", seqinfo.ini announces {last}")
                        } else {
                            String::new()
                        }
                    ),
                });
            };
            let image = read_image(&file, index)?;
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
    Ok(FrameSource::new(
        info,
        Box::new(Prefetch::Idle(Box::new(frames))),
        options,
    ))
}

/// Frames decoded ahead of the reader before it waits for them.
const DECODED_AHEAD: usize = 2;

/// Frames read on a thread of their own, started at the first frame asked for (a source
/// opened only for its [`SourceInfo`] decodes nothing), at most [`DECODED_AHEAD`] frames
/// ahead of the reader, in order, errors included. Dropping it stops the thread after
/// the frame it is decoding.
// Choice: JPEG decoding was a quarter of `track --method mrf`'s CPU on the demo's
// sequence, on the thread that tracks (docs/PERFORMANCE.md "Frames decoded ahead"). The
// frames and their errors are the same in the same order; only when they are decoded
// changes, up to DECODED_AHEAD + 1 frames past the last one the reader takes.
enum Prefetch {
    /// Not started.
    Idle(Box<dyn Iterator<Item = Result<Frame>> + Send>),
    /// The decoding thread's frames, and the thread.
    Running(
        std::sync::mpsc::Receiver<Result<Frame>>,
        std::thread::JoinHandle<()>,
    ),
    /// Ended.
    Done,
}

impl Iterator for Prefetch {
    type Item = Result<Frame>;

    fn next(&mut self) -> Option<Result<Frame>> {
        if let Self::Idle(_) = self {
            let Self::Idle(frames) = std::mem::replace(self, Self::Done) else {
                return None;
            };
            let (tx, rx) = std::sync::mpsc::sync_channel(DECODED_AHEAD);
            let started = std::thread::Builder::new()
                .name("roadtrack-frames".into())
                .spawn(move || {
                    for frame in frames {
                        if tx.send(frame).is_err() {
                            return;
                        }
                    }
                });
            match started {
                Ok(thread) => *self = Self::Running(rx, thread),
                Err(e) => {
                    return Some(Err(Error::Invalid(format!(
                        "cannot start the thread that decodes the frames: {e}"
                    ))));
                }
            }
        }
        let Self::Running(rx, _) = self else {
            return None;
        };
        if let Ok(frame) = rx.recv() {
            return Some(frame);
        }
        // The frames ended, or the decoder panicked: its panic goes on here, as it did
        // when frames were decoded on the reader's thread.
        if let Self::Running(_, thread) = std::mem::replace(self, Self::Done)
            && let Err(panic) = thread.join()
        {
            std::panic::resume_unwind(panic);
        }
        None
    }
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

    fn tiny(index: u32) -> Frame {
        Frame {
            index,
            time_s: 0.0,
            image: RgbImage::new(2, 2),
        }
    }

    /// The frames read ahead come in order with their errors between them; a reader that
    /// stops early leaves an endless source behind without waiting for it.
    #[test]
    fn frames_read_ahead_keep_their_order_and_errors() {
        let items = (1..=40).map(|k| {
            if k % 7 == 0 {
                Err(Error::Invalid(format!("frame {k}: bad")))
            } else {
                Ok(tiny(k))
            }
        });
        let got: Vec<std::result::Result<u32, String>> = Prefetch::Idle(Box::new(items))
            .map(|f| f.map(|f| f.index).map_err(|e| e.to_string()))
            .collect();
        let want: Vec<std::result::Result<u32, String>> = (1..=40)
            .map(|k| {
                if k % 7 == 0 {
                    Err(format!("frame {k}: bad"))
                } else {
                    Ok(k)
                }
            })
            .collect();
        assert_eq!(got, want);
        let mut endless = Prefetch::Idle(Box::new((1..).map(|k| Ok(tiny(k)))));
        assert_eq!(
            endless.nth(4).map(|f| f.map(|f| f.index).ok()),
            Some(Some(5))
        );
        drop(endless);
    }

    /// A decoder that panics panics the reader, as on the reader's own thread; it does not
    /// end the frames early as if the source were shorter.
    #[test]
    fn a_panic_while_reading_ahead_reaches_the_reader() {
        let frames = (1..=5).map(|k| {
            assert!(k < 3, "decoder failed at frame {k}");
            Ok(tiny(k))
        });
        let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            Prefetch::Idle(Box::new(frames)).count()
        }));
        assert!(read.is_err(), "{read:?}");
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
            ..SourceOptions::default()
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
    fn skip() -> SourceOptions {
        SourceOptions {
            on_bad_frame: OnBadFrame::Skip,
            ..SourceOptions::default()
        }
    }

    #[test]
    fn a_missing_number_is_a_bad_frame_and_a_gap_in_time() -> Result<()> {
        let dir = folder(5, |i| format!("{i:06}.png"));
        std::fs::remove_file(dir.path().join("000003.png")).expect("rm");
        let src = open(dir.path(), &SourceOptions::default())?;
        assert_eq!(src.info.total_frames, Some(5));
        let items: Vec<Result<Frame>> = src.collect();
        assert_eq!(
            items.len(),
            3,
            "under fail the first bad frame ends the source"
        );
        let m = items[2].as_ref().expect_err("frame 3 missing").to_string();
        assert!(m.contains("frame 3") && m.contains("missing"), "{m}");
        let src = open(dir.path(), &skip())?;
        let log = src.skip_log();
        let frames: Vec<Frame> = src.collect::<Result<_>>()?;
        let idx: Vec<u32> = frames.iter().map(|f| f.index).collect();
        assert_eq!(idx, [1, 2, 4, 5], "frame 4 stays frame 4");
        assert!((frames[2].time_s - 0.3).abs() < 1e-12);
        assert_eq!(frames[2].image.get_pixel(0, 0)[0], 4, "the image of 000004");
        let skipped = log.frames();
        assert_eq!(skipped.len(), 1);
        assert_eq!(skipped[0].frame, 3);
        assert_eq!(skipped[0].file, dir.path());
        Ok(())
    }

    #[test]
    fn a_truncated_jpeg_is_a_bad_frame() -> Result<()> {
        let dir = tempfile::tempdir().expect("tempdir");
        for i in 1..=3 {
            RgbImage::from_pixel(32, 24, Rgb([90, 90, 90]))
                .save(dir.path().join(format!("{i}.jpg")))
                .expect("save");
        }
        let p = dir.path().join("2.jpg");
        let bytes = std::fs::read(&p).expect("read");
        std::fs::write(&p, &bytes[..bytes.len() / 2]).expect("cut");
        let err = open(dir.path(), &SourceOptions::default())?
            .find_map(|f| f.err())
            .expect("an error")
            .to_string();
        assert!(
            err.contains("2.jpg") && err.contains("frame 2") && err.contains("truncated"),
            "{err}"
        );
        let src = open(dir.path(), &skip())?;
        let log = src.skip_log();
        let idx: Vec<u32> = src.map(|f| f.map(|f| f.index)).collect::<Result<_>>()?;
        assert_eq!(idx, [1, 3]);
        assert_eq!(log.frames()[0].file, p);
        Ok(())
    }

    #[test]
    fn a_sequence_shorter_than_its_seqinfo_has_missing_frames_at_the_end() -> Result<()> {
        let dir = tempfile::tempdir().expect("tempdir");
        let img1 = dir.path().join("img1");
        std::fs::create_dir(&img1).expect("mkdir");
        for i in 2..=3 {
            RgbImage::new(4, 4)
                .save(img1.join(format!("{i:06}.png")))
                .expect("save");
        }
        SeqInfo {
            name: "x".into(),
            im_dir: "img1".into(),
            frame_rate: 25.0,
            seq_length: 4,
            im_width: 4,
            im_height: 4,
            im_ext: ".png".into(),
        }
        .write(&dir.path().join("seqinfo.ini"))?;
        let src = open(dir.path(), &skip())?;
        let log = src.skip_log();
        let idx: Vec<u32> = src.map(|f| f.map(|f| f.index)).collect::<Result<_>>()?;
        assert_eq!(idx, [2, 3]);
        let missing: Vec<u32> = log.frames().iter().map(|s| s.frame).collect();
        assert_eq!(missing, [1, 4]);
        Ok(())
    }
}
