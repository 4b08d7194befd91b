//! Video files through the `ffmpeg` program: frames arrive as raw RGB over a pipe
//! ([`VideoReader`]) and leave the same way ([`VideoWriter`]).
//!
//! Size, rate and frame count come from `ffprobe`. This needs no C libraries at build time
//! and decodes every format the installed ffmpeg knows (DEPENDENCY_NOTES.md §1: about
//! 500 frames/s of 768×576 on one core here).

use super::atomic::TempOutput;
use crate::error::{Error, Result};
use image::RgbImage;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::thread::JoinHandle;

const INSTALL_HINT: &str =
    "install ffmpeg (Debian/Ubuntu: `sudo apt-get install ffmpeg`, or run scripts/setup.sh)";

/// Decodes a video file frame by frame.
#[derive(Debug)]
pub struct VideoReader {
    path: PathBuf,
    ffmpeg: Ffmpeg,
    stdout: Option<ChildStdout>,
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// Frame rate reported by the container, frames/s.
    pub fps: f64,
    /// Frame count reported by the container, when it has one.
    pub total_frames: Option<u32>,
    /// Duration reported by the stream or the container, s, when known.
    pub duration_s: Option<f64>,
    frames_read: u32,
    done: bool,
}

/// What `ffprobe` says about a video's first video stream.
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Frame rate, frames/s.
    pub fps: f64,
    /// Frame count, when the container states it.
    pub total_frames: Option<u32>,
    /// Duration, s, when the stream or the container states it.
    pub duration_s: Option<f64>,
}

fn spawn_error(program: &'static str, e: &std::io::Error) -> Error {
    if e.kind() == std::io::ErrorKind::NotFound {
        Error::External {
            program,
            message: format!(
                "not found on PATH; it is needed to read and write video files: {INSTALL_HINT}"
            ),
        }
    } else {
        Error::External {
            program,
            message: format!("cannot start: {e}"),
        }
    }
}

/// A running `ffmpeg` with its stderr read on a thread (so a chatty ffmpeg never blocks on
/// a full pipe; the text is joined when it is finished, for error messages). The one place
/// where [`VideoReader`] and [`VideoWriter`] start and stop the program.
#[derive(Debug)]
struct Ffmpeg {
    child: Arc<Mutex<Option<Child>>>,
    stderr: Option<JoinHandle<String>>,
}

/// Every ffmpeg process started, for [`kill_ffmpeg_processes`].
static CHILDREN: Mutex<Vec<Weak<Mutex<Option<Child>>>>> = Mutex::new(Vec::new());

/// Kills every ffmpeg process this program still runs (for a signal handler that is about
/// to exit, so no encoder finishes a file behind it). Returns how many it killed.
pub fn kill_ffmpeg_processes() -> usize {
    let children = match CHILDREN.lock() {
        Ok(c) => c.clone(),
        Err(poisoned) => poisoned.into_inner().clone(),
    };
    children
        .iter()
        .filter_map(Weak::upgrade)
        .filter(|c| {
            c.lock()
                .ok()
                .and_then(|mut c| c.as_mut().map(|c| c.kill().is_ok()))
                .unwrap_or(false)
        })
        .count()
}

impl Ffmpeg {
    /// Starts `cmd` and returns the process with its piped stdin and stdout (when piped).
    fn spawn(cmd: &mut Command) -> Result<(Self, Option<ChildStdin>, Option<ChildStdout>)> {
        let mut child = cmd.spawn().map_err(|e| spawn_error("ffmpeg", &e))?;
        let stdin = child.stdin.take();
        let stdout = child.stdout.take();
        let stderr = child.stderr.take().map(|mut s| {
            std::thread::spawn(move || {
                let mut buf = String::new();
                let _ = s.read_to_string(&mut buf);
                buf
            })
        });
        let child = Arc::new(Mutex::new(Some(child)));
        if let Ok(mut all) = CHILDREN.lock() {
            all.retain(|w| w.strong_count() > 0);
            all.push(Arc::downgrade(&child));
        }
        let ffmpeg = Self { child, stderr };
        Ok((ffmpeg, stdin, stdout))
    }

    fn take(&self) -> Option<Child> {
        match self.child.lock() {
            Ok(mut c) => c.take(),
            Err(poisoned) => poisoned.into_inner().take(),
        }
    }

    /// Waits for ffmpeg to exit (the caller closes its pipes first). `Some((status,
    /// messages))` when it failed; `None` when it succeeded or was already waited for.
    ///
    /// # Errors
    /// The wait itself failed (named after `path`, the video).
    fn wait(&mut self, path: &Path) -> Result<Option<(ExitStatus, String)>> {
        let Some(mut c) = self.take() else {
            return Ok(None);
        };
        let status = c.wait().map_err(|e| Error::io(path, e))?;
        let stderr = self
            .stderr
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        Ok((!status.success()).then_some((status, stderr)))
    }

    /// Kills ffmpeg when it still runs and reaps it (a reader or writer dropped early).
    fn kill(&mut self) {
        if let Some(mut c) = self.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Whether `ffmpeg` and `ffprobe` can be run.
pub fn ffmpeg_available() -> bool {
    ["ffmpeg", "ffprobe"].iter().all(|p| {
        Command::new(p)
            .arg("-version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    })
}

/// Asks `ffprobe` for the size, rate and frame count of `path`'s first video stream.
pub fn probe(path: &Path) -> Result<Probe> {
    let out = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
        .arg("stream=width,height,r_frame_rate,avg_frame_rate,nb_frames,duration:format=duration")
        .args(["-of", "default=noprint_wrappers=1"])
        .arg(path)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| spawn_error("ffprobe", &e))?;
    if !out.status.success() {
        let msg = String::from_utf8_lossy(&out.stderr).trim().to_owned();
        return Err(Error::Frame {
            path: path.to_owned(),
            frame: 1,
            message: format!("ffprobe cannot read it as a video: {msg}"),
        });
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let get = |k: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(k).and_then(|r| r.strip_prefix('=')))
            .map(str::trim)
    };
    let bad = |what: &str| Error::Frame {
        path: path.to_owned(),
        frame: 1,
        message: format!(
            "no video stream with a {what} (ffprobe said: {})",
            text.trim()
        ),
    };
    let width: u32 = get("width")
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| bad("width"))?;
    let height: u32 = get("height")
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| bad("height"))?;
    let rate = |s: &str| -> Option<f64> {
        let (n, d) = s.split_once('/').unwrap_or((s, "1"));
        let (n, d): (f64, f64) = (n.parse().ok()?, d.parse().ok()?);
        (d > 0.0 && n > 0.0).then_some(n / d)
    };
    let fps = get("avg_frame_rate")
        .and_then(rate)
        .or_else(|| get("r_frame_rate").and_then(rate))
        .ok_or_else(|| bad("frame rate"))?;
    let total_frames = get("nb_frames").and_then(|s| s.parse().ok());
    // The stream's duration when it has one (listed first), else the container's.
    let duration_s = text
        .lines()
        .filter_map(|l| l.strip_prefix("duration="))
        .find_map(|s| s.trim().parse::<f64>().ok())
        .filter(|d| d.is_finite() && *d > 0.0);
    if width == 0 || height == 0 {
        return Err(bad("non-zero size"));
    }
    // A frame buffer is width × height × 3 bytes: bound the sides before any is made.
    let side = crate::limits::MAX_IMAGE_SIDE;
    if width > side || height > side {
        return Err(Error::Frame {
            path: path.to_owned(),
            frame: 1,
            message: format!(
                "{width}×{height} px exceeds the limit of {side} px a side (docs/FORMATS.md, Limits)"
            ),
        });
    }
    Ok(Probe {
        width,
        height,
        fps,
        total_frames,
        duration_s,
    })
}

impl VideoReader {
    /// Probes `path` and starts decoding; stops decoding after frame `end` (1-based) when
    /// set.
    pub fn open(path: &Path, end: Option<u32>) -> Result<Self> {
        let p = probe(path)?;
        let mut cmd = Command::new("ffmpeg");
        cmd.args(["-v", "error", "-nostdin", "-i"]).arg(path);
        if let Some(end) = end {
            cmd.args(["-frames:v", &end.to_string()]);
        }
        cmd.args(["-an", "-sn", "-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let (ffmpeg, _, stdout) = Ffmpeg::spawn(&mut cmd)?;
        Ok(Self {
            path: path.to_owned(),
            ffmpeg,
            stdout,
            width: p.width,
            height: p.height,
            fps: p.fps,
            total_frames: p.total_frames,
            duration_s: p.duration_s,
            frames_read: 0,
            done: false,
        })
    }

    /// The frame count the video announces: the container's frame count, else the one its
    /// duration implies.
    ///
    /// Choice: a duration is rounded when stored, so the count it implies, ⌊duration × fps⌋,
    /// is lowered by one frame: a video that ends one frame early by its duration alone is
    /// not called cut short.
    pub fn announced_frames(&self) -> Option<u32> {
        self.total_frames.or_else(|| {
            let n = (self.duration_s? * self.fps + 1e-6).floor();
            (n >= 2.0 && n < f64::from(u32::MAX)).then(|| n as u32 - 1)
        })
    }

    fn finish(&mut self) -> Result<()> {
        self.done = true;
        self.stdout = None;
        match self.ffmpeg.wait(&self.path)? {
            None => Ok(()),
            Some((status, stderr)) => Err(Error::Frame {
                path: self.path.clone(),
                frame: self.frames_read + 1,
                message: format!("ffmpeg failed ({status}): {}", stderr.trim()),
            }),
        }
    }
}

impl Iterator for VideoReader {
    type Item = Result<RgbImage>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let n = self.width as usize * self.height as usize * 3;
        let mut buf = vec![0u8; n];
        let stdout = self.stdout.as_mut()?;
        let mut filled = 0;
        while filled < n {
            match stdout.read(&mut buf[filled..]) {
                Ok(0) => break,
                Ok(k) => filled += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    self.done = true;
                    return Some(Err(Error::io(&self.path, e)));
                }
            }
        }
        if filled == 0 {
            return self.finish().err().map(Err);
        }
        if filled < n {
            let frame = self.frames_read + 1;
            let err = self.finish().err().unwrap_or(Error::Frame {
                path: self.path.clone(),
                frame,
                message: format!("truncated frame: {filled} of {n} bytes"),
            });
            return Some(Err(err));
        }
        self.frames_read += 1;
        RgbImage::from_raw(self.width, self.height, buf).map(Ok)
    }
}

/// The encoders the installed ffmpeg lists (`ffmpeg -encoders`), read once per process.
fn ffmpeg_encoders() -> Result<&'static str> {
    static ENCODERS: OnceLock<String> = OnceLock::new();
    if let Some(e) = ENCODERS.get() {
        return Ok(e);
    }
    let out = Command::new("ffmpeg")
        .args(["-hide_banner", "-encoders"])
        .stdin(Stdio::null())
        .output()
        .map_err(|e| spawn_error("ffmpeg", &e))?;
    Ok(ENCODERS.get_or_init(|| String::from_utf8_lossy(&out.stdout).into_owned()))
}

/// Whether the installed ffmpeg has the encoder `name`.
fn has_encoder(list: &str, name: &str) -> bool {
    list.lines()
        .any(|l| l.split_whitespace().nth(1) == Some(name))
}

/// The encoder and its options for a container extension, from what ffmpeg has.
// Choice: H.264 (libx264, CRF 23 — x264's own default —, preset veryfast) for .mp4/.mkv
// because every player reads it. On the demo's overlay (700 frames, 1280 × 480) CRF 23 against
// 20 encodes in 9.8 s instead of 16.0 s at 10.6 MB instead of 19.0 MB, 40.6 dB PSNR (the labels
// stay sharp; docs/VISUALS.md); MPEG-4 part 2 (q 3) when libx264 is missing and always for .avi; VP9 (libvpx-vp9,
// CRF 32) or VP8 for .webm, which admits nothing else. All use yuv420p for compatibility.
fn choose_codec(ext: &str, encoders: &str) -> Result<(&'static str, &'static [&'static str])> {
    const X264: &[&str] = &["-preset", "veryfast", "-crf", "23"];
    const MPEG4: &[&str] = &["-q:v", "3"];
    const VP9: &[&str] = &[
        "-crf",
        "32",
        "-b:v",
        "0",
        "-deadline",
        "realtime",
        "-cpu-used",
        "8",
    ];
    const VP8: &[&str] = &[
        "-crf",
        "10",
        "-b:v",
        "2M",
        "-deadline",
        "realtime",
        "-cpu-used",
        "8",
    ];
    let pick = match ext {
        "mp4" | "mkv" if has_encoder(encoders, "libx264") => Some(("libx264", X264)),
        "mp4" | "mkv" | "avi" if has_encoder(encoders, "mpeg4") => Some(("mpeg4", MPEG4)),
        "webm" if has_encoder(encoders, "libvpx-vp9") => Some(("libvpx-vp9", VP9)),
        "webm" if has_encoder(encoders, "libvpx") => Some(("libvpx", VP8)),
        _ => None,
    };
    pick.ok_or_else(|| Error::External {
        program: "ffmpeg",
        message: format!(
            "has no encoder for .{ext} files (tried libx264/mpeg4 for mp4, mkv, avi and \
             libvpx-vp9/libvpx for webm); write a PNG folder instead or {INSTALL_HINT}"
        ),
    })
}

/// Encodes RGB frames into a video file by piping them into the `ffmpeg` program.
///
/// The video is written to a temporary file next to the destination and renamed over it
/// only when ffmpeg succeeds ([`VideoWriter::finish`]), so an interrupted run never leaves
/// a truncated video under the final name. Dropping a writer without finishing kills
/// ffmpeg and removes the temporary file.
#[derive(Debug)]
pub struct VideoWriter {
    path: PathBuf,
    tmp: Option<TempOutput>,
    ffmpeg: Ffmpeg,
    stdin: Option<ChildStdin>,
    width: u32,
    height: u32,
    frames_written: u32,
    /// The ffmpeg encoder in use (`libx264`, `mpeg4`, `libvpx-vp9` or `libvpx`).
    pub codec: &'static str,
}

impl VideoWriter {
    /// Starts ffmpeg to encode `width × height` frames at `fps` into `path`, whose
    /// extension (`mp4`, `mkv`, `avi`, `webm`) picks the container and the encoder.
    ///
    /// # Errors
    /// ffmpeg is missing or has no suitable encoder; the folder cannot be written; a zero
    /// size or a non-positive rate.
    pub fn create(path: &Path, width: u32, height: u32, fps: f64) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::Invalid(format!(
                "{}: cannot encode {width}×{height} px frames",
                path.display()
            )));
        }
        if !(fps.is_finite() && fps > 0.0) {
            return Err(Error::Invalid(format!(
                "{}: frame rate must be positive, found {fps}",
                path.display()
            )));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let (codec, options) = choose_codec(&ext, ffmpeg_encoders()?)?;
        // The temporary ends in `.partial`, never in the video's extension, so a run killed
        // by SIGKILL cannot leave what looks like a video; the container is named
        // explicitly instead.
        let tmp = TempOutput::create(path, &format!(".{ext}.partial"))?;
        let container = match ext.as_str() {
            "mkv" => "matroska",
            other => other,
        };
        let mut cmd = Command::new("ffmpeg");
        cmd.args(["-hide_banner", "-v", "error", "-y"])
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24"])
            .args(["-s", &format!("{width}x{height}")])
            .args(["-framerate", &format!("{fps}")])
            .args(["-i", "pipe:0", "-an"])
            // yuv420p needs even sizes: pad odd ones by one black row or column.
            .args(["-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2"])
            .args(["-c:v", codec])
            .args(options)
            .args(["-pix_fmt", "yuv420p"])
            // No encoder version or creation time in the file: same frames, same bytes.
            .args([
                "-fflags",
                "+bitexact",
                "-flags:v",
                "+bitexact",
                "-map_metadata",
                "-1",
            ])
            .args(["-f", container])
            .arg(tmp.temp_path())
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        let (ffmpeg, stdin, _) = Ffmpeg::spawn(&mut cmd)?;
        Ok(Self {
            path: path.to_owned(),
            tmp: Some(tmp),
            ffmpeg,
            stdin,
            width,
            height,
            frames_written: 0,
            codec,
        })
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> u32 {
        self.frames_written
    }

    /// Appends `image`, which must have the size given to [`VideoWriter::create`]; `index`
    /// (the frame's number) only names the frame in errors.
    ///
    /// # Errors
    /// A frame of another size; ffmpeg stopped (its message is included); writing after
    /// [`VideoWriter::finish`].
    pub fn write_frame(&mut self, index: u32, image: &RgbImage) -> Result<()> {
        if image.dimensions() != (self.width, self.height) {
            return Err(Error::FrameSize {
                frame: index,
                got: image.dimensions(),
                expected: (self.width, self.height),
            });
        }
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(Error::Invalid(format!(
                "{}: frame {index} written after the video was finished",
                self.path.display()
            )));
        };
        if let Err(e) = stdin.write_all(image.as_raw()) {
            let why = self
                .stop()
                .err()
                .map_or_else(|| e.to_string(), |f| f.to_string());
            return Err(Error::External {
                program: "ffmpeg",
                message: format!(
                    "stopped while encoding {} at frame {index}: {why}",
                    self.path.display()
                ),
            });
        }
        self.frames_written += 1;
        Ok(())
    }

    /// Closes ffmpeg's input, waits for it, and returns its failure with its messages.
    fn stop(&mut self) -> Result<()> {
        self.stdin = None;
        match self.ffmpeg.wait(&self.path)? {
            None => Ok(()),
            Some((status, stderr)) => Err(Error::External {
                program: "ffmpeg",
                message: format!(
                    "failed ({status}) writing {}: {}",
                    self.path.display(),
                    stderr.trim()
                ),
            }),
        }
    }

    /// Ends the stream, waits for ffmpeg and moves the video into place. Calling it again
    /// does nothing.
    ///
    /// # Errors
    /// No frame was written; ffmpeg failed; the rename failed.
    pub fn finish(&mut self) -> Result<()> {
        let Some(tmp) = self.tmp.take() else {
            return Ok(());
        };
        self.stop()?;
        if self.frames_written == 0 {
            return Err(Error::Invalid(format!(
                "{}: no frames to write; the video was not created",
                self.path.display()
            )));
        }
        tmp.commit()?;
        Ok(())
    }
}

impl Drop for VideoWriter {
    fn drop(&mut self) {
        self.stdin = None;
        self.ffmpeg.kill();
        // `self.tmp`, when still set, removes the unfinished file as it drops.
    }
}

impl Drop for VideoReader {
    fn drop(&mut self) {
        self.stdout = None;
        self.ffmpeg.kill();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIST: &str =
        " V....D libx264              libx264 H.264\n V.S... mpeg4                MPEG-4 part 2\n";

    #[test]
    fn codec_follows_the_extension_and_what_ffmpeg_has() -> Result<()> {
        assert_eq!(choose_codec("mp4", LIST)?.0, "libx264");
        assert_eq!(choose_codec("avi", LIST)?.0, "mpeg4");
        assert_eq!(choose_codec("mkv", " V.S... mpeg4   MPEG-4\n")?.0, "mpeg4");
        let e = choose_codec("webm", LIST).expect_err("no vpx");
        assert!(e.to_string().contains("webm"), "{e}");
        Ok(())
    }
}
