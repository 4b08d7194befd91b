//! Throughput measurements behind `roadtrack bench` and the benchmarks in `benches/`.
//!
//! Each stage runs on a named input and reports frames (or items) per second of wall time.
//! Timings are measurements, never test assertions.

#[cfg(feature = "cnn")]
pub mod cnn;
pub mod filters;
pub mod mrf;
pub mod sim;

use roadtrack::detect::background::{BackgroundDetector, BackgroundDetectorConfig};
use roadtrack::error::Result;
use roadtrack::frame::Frame;
use roadtrack::io::{OnBadFrame, SkipLog, SourceOptions, source};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// One measured stage.
#[derive(Debug, Clone, Serialize)]
pub struct StageResult {
    /// Stage name, e.g. `decode`.
    pub stage: String,
    /// What it ran on, e.g. `vtest.avi 768×576`.
    pub input: String,
    /// Items processed (frames unless `unit` says otherwise).
    pub items: u64,
    /// What an item is (`frames`, `vehicles`, …).
    pub unit: String,
    /// Wall time, s.
    pub seconds: f64,
    /// Items per second.
    pub per_second: f64,
}

impl StageResult {
    /// A result from a count and a duration.
    pub fn new(stage: &str, input: &str, items: u64, unit: &str, seconds: f64) -> Self {
        Self {
            stage: stage.to_owned(),
            input: input.to_owned(),
            items,
            unit: unit.to_owned(),
            seconds,
            per_second: if seconds > 0.0 {
                items as f64 / seconds
            } else {
                f64::INFINITY
            },
        }
    }
}

/// The machine the figures were taken on.
#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    /// CPU model from `/proc/cpuinfo` (or `unknown`).
    pub cpu: String,
    /// Logical cores available to this process.
    pub cores: usize,
    /// Threads rayon uses.
    pub rayon_threads: usize,
}

/// Describes this machine.
pub fn machine() -> Machine {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into());
    Machine {
        cpu,
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        rayon_threads: rayon::current_num_threads(),
    }
}

/// Decodes `path` (any frame source) and returns the stage result, with the frames
/// skipped under `--on-bad-frame skip`.
pub fn decode(path: &Path, options: &SourceOptions) -> Result<(StageResult, SkipLog)> {
    let start = Instant::now();
    let src = source::open(path, options)?;
    let skipped = src.skip_log();
    let label = input_label(path, src.info.width, src.info.height);
    let mut n = 0u64;
    let mut checksum = 0u64;
    for f in src {
        let f = f?;
        // Touch the pixels so no work can be skipped.
        checksum = checksum.wrapping_add(
            f.image
                .as_raw()
                .iter()
                .step_by(97)
                .map(|&v| u64::from(v))
                .sum::<u64>(),
        );
        n += 1;
    }
    std::hint::black_box(checksum);
    let result = StageResult::new("decode", &label, n, "frames", start.elapsed().as_secs_f64());
    Ok((result, skipped))
}

/// A bench program's own arguments: those after the program's name, without the flags
/// `cargo bench` appends (`--bench`).
pub fn bench_args() -> Vec<String> {
    std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect()
}

/// Runs foreground extraction over frames already in memory (decode excluded).
pub fn detect_frames(
    label: &str,
    frames: &[Frame],
    config: &BackgroundDetectorConfig,
) -> Result<StageResult> {
    let total = Some(frames.len() as u32);
    let mut det =
        BackgroundDetector::bootstrap(config.clone(), frames.iter().cloned().map(Ok), total)?;
    let start = Instant::now();
    let mut regions = 0usize;
    for f in frames {
        regions += det.detect(f)?.len();
    }
    std::hint::black_box(regions);
    Ok(StageResult::new(
        "detect",
        label,
        frames.len() as u64,
        "frames",
        start.elapsed().as_secs_f64(),
    ))
}

/// Frames per second of any detector over `frames` (stage name `stage`).
pub fn detect_with(
    stage: &str,
    label: &str,
    frames: &[Frame],
    det: &mut dyn roadtrack::detect::Detector,
) -> Result<StageResult> {
    let start = Instant::now();
    let mut n = 0usize;
    // In batches, as `detect` and `track` run it.
    for chunk in frames.chunks(det.batch_len().max(1)) {
        n += roadtrack::detect::detect_checked(det, chunk)?
            .iter()
            .map(|f| f.detections.len())
            .sum::<usize>();
    }
    std::hint::black_box(n);
    Ok(StageResult::new(
        stage,
        label,
        frames.len() as u64,
        "frames",
        start.elapsed().as_secs_f64(),
    ))
}

/// Reads up to `max_frames` frames of `path` into memory (bad frames as `on_bad_frame`
/// says).
pub fn load_frames(
    path: &Path,
    max_frames: u32,
    on_bad_frame: OnBadFrame,
) -> Result<(String, Vec<Frame>)> {
    let opts = SourceOptions {
        end: Some(max_frames),
        on_bad_frame,
        ..Default::default()
    };
    let src = source::open(path, &opts)?;
    let label = input_label(path, src.info.width, src.info.height);
    Ok((label, src.collect::<Result<Vec<_>>>()?))
}

fn input_label(path: &Path, w: u32, h: u32) -> String {
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    format!("{name} {w}×{h}")
}

/// The whole pipeline of `roadtrack track` (decode, detect, track, life cycle, write MOT tracks) for
/// each method with its defaults, on the MOT sequence folder `seq`: frames per second of
/// wall time, as a user sees it.
///
/// # Errors
/// The sequence cannot be read or a method fails.
pub fn pipeline(seq: &Path, label: &str, seed: u64) -> Result<Vec<StageResult>> {
    use roadtrack::track::pipeline::MotSink;
    use roadtrack::track::{Method, MethodConfig, PointSink, track_source};
    let out = tempfile::tempdir().map_err(|e| roadtrack::Error::io("temporary folder", e))?;
    Method::ALL
        .iter()
        .map(|&method| {
            let path = out.path().join(format!("{}.txt", method.name()));
            let sink: Box<dyn PointSink> = Box::new(MotSink::create(&path)?);
            let start = Instant::now();
            let lifecycle = roadtrack::track::confirm::LifecycleStage::new(Default::default())?;
            let smooth = roadtrack::track::smooth::SmoothStage::new(
                roadtrack::track::smooth::SmoothConfig::recommended(),
            )?;
            let summary = track_source(
                seq,
                &SourceOptions::default(),
                MethodConfig::defaults(method, seed),
                None,
                vec![Box::new(lifecycle), Box::new(smooth)],
                vec![sink],
                &mut |_, _| {},
            )?;
            Ok(StageResult::new(
                &format!("pipeline {}", method.name()),
                label,
                summary.frames,
                "frames",
                start.elapsed().as_secs_f64(),
            ))
        })
        .collect()
}

/// CPU seconds (user + system) this process has used so far, from `/proc/self/stat`
/// (Linux, 100 clock ticks a second; 0 elsewhere). On a shared machine, items per CPU
/// second estimate quiet single-core throughput better than items per wall second.
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesised command name: state (field 3) onwards; utime and
    // stime are fields 14 and 15.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let field = |n: usize| f.get(n - 3).and_then(|x| x.parse::<f64>().ok());
    match (field(14), field(15)) {
        (Some(u), Some(s)) => (u + s) / 100.0,
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use roadtrack_sim::testkit::moving_boxes;

    #[test]
    fn generated_sequence_has_the_objects_the_detector_finds() -> Result<()> {
        let frames = moving_boxes(320, 240, 30, 4);
        let mut det = BackgroundDetector::bootstrap(
            BackgroundDetectorConfig::default(),
            frames.iter().cloned().map(Ok),
            Some(30),
        )?;
        let counts: Vec<usize> = frames
            .iter()
            .map(|f| det.detect(f).map(|d| d.len()))
            .collect::<Result<_>>()?;
        // Objects may touch the border or overlap each other, so allow fewer, never more.
        assert!(counts.iter().all(|&c| c <= 4), "{counts:?}");
        assert!(
            counts.iter().filter(|&&c| c >= 3).count() > 20,
            "{counts:?}"
        );
        Ok(())
    }

    #[test]
    fn stage_rate_is_items_over_seconds() {
        let r = StageResult::new("x", "y", 50, "frames", 2.0);
        assert_eq!(r.per_second, 25.0);
    }
}
