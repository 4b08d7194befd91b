//! Video files through the `ffmpeg` program: frames arrive as raw RGB over a pipe.
//!
//! Size, rate and frame count come from `ffprobe`. This needs no C libraries at build time
//! and decodes every format the installed ffmpeg knows (DEPENDENCY_NOTES.md §1: about
//! 500 frames/s of 768×576 on one core here).

use super::source::SourceOptions;
use crate::error::{Error, Result};
use image::RgbImage;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};

const INSTALL_HINT: &str =
    "install ffmpeg (Debian/Ubuntu: `sudo apt-get install ffmpeg`, or run scripts/setup.sh)";

/// Decodes a video file frame by frame.
#[derive(Debug)]
pub struct VideoReader {
    path: PathBuf,
    child: Option<Child>,
    stdout: Option<ChildStdout>,
    stderr: Option<std::thread::JoinHandle<String>>,
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// Frame rate reported by the container, frames/s.
    pub fps: f64,
    /// Frame count reported by the container, when it has one.
    pub total_frames: Option<u32>,
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
}

fn spawn_error(program: &'static str, e: &std::io::Error) -> Error {
    if e.kind() == std::io::ErrorKind::NotFound {
        Error::External {
            program,
            message: format!("not found on PATH; it is needed to read video files: {INSTALL_HINT}"),
        }
    } else {
        Error::External {
            program,
            message: format!("cannot start: {e}"),
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
        .arg("stream=width,height,r_frame_rate,avg_frame_rate,nb_frames")
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
    if width == 0 || height == 0 {
        return Err(bad("non-zero size"));
    }
    Ok(Probe {
        width,
        height,
        fps,
        total_frames,
    })
}

impl VideoReader {
    /// Probes `path` and starts decoding; stops decoding after `options.end` when set.
    pub fn open(path: &Path, options: &SourceOptions) -> Result<Self> {
        let p = probe(path)?;
        let mut cmd = Command::new("ffmpeg");
        cmd.args(["-v", "error", "-nostdin", "-i"]).arg(path);
        if let Some(end) = options.end {
            cmd.args(["-frames:v", &end.to_string()]);
        }
        cmd.args(["-an", "-sn", "-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = cmd.spawn().map_err(|e| spawn_error("ffmpeg", &e))?;
        let stdout = child.stdout.take();
        let stderr = child.stderr.take().map(|mut s| {
            std::thread::spawn(move || {
                let mut buf = String::new();
                let _ = s.read_to_string(&mut buf);
                buf
            })
        });
        Ok(Self {
            path: path.to_owned(),
            child: Some(child),
            stdout,
            stderr,
            width: p.width,
            height: p.height,
            fps: p.fps,
            total_frames: p.total_frames,
            frames_read: 0,
            done: false,
        })
    }

    fn finish(&mut self) -> Result<()> {
        self.done = true;
        self.stdout = None;
        let status = match self.child.take() {
            Some(mut c) => c.wait().map_err(|e| Error::io(&self.path, e))?,
            None => return Ok(()),
        };
        let stderr = self
            .stderr
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        if status.success() {
            Ok(())
        } else {
            Err(Error::Frame {
                path: self.path.clone(),
                frame: self.frames_read + 1,
                message: format!("ffmpeg failed ({status}): {}", stderr.trim()),
            })
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

impl Drop for VideoReader {
    fn drop(&mut self) {
        self.stdout = None;
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
