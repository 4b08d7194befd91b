//! Throughput of the MRF tracker (`roadtrack bench --stages mrf`, `benches/mrf.rs`).

use roadtrack::detect::background_model::bootstrap_from_frames;
use roadtrack::error::{Error, Result};
use roadtrack::frame::Frame;
use roadtrack::track::mrf::{MrfConfig, MrfStageTimes, MrfTracker};
use serde::Serialize;

/// Throughput of the MRF tracker on some frames (for `roadtrack bench`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MrfBench {
    /// Frames tracked.
    pub frames: u32,
    /// Frame size, px.
    pub width: u32,
    /// Frame size, px.
    pub height: u32,
    /// Rayon threads used.
    pub threads: usize,
    /// Wall time of all `step` calls (luminance, background subtraction, block matching,
    /// propagation, Gibbs sampler, births, output), s.
    pub seconds: f64,
    /// Frames per second end to end.
    pub fps: f64,
    /// Mean blocks block-matched per frame.
    pub mean_matched_blocks: f64,
    /// Mean contested blocks per frame.
    pub mean_sites: f64,
    /// Mean sweeps per frame with sites.
    pub mean_sweeps: f64,
    /// Wall time per stage over all frames, s.
    pub stages: MrfStageTimes,
}

/// Tracks `frames` (already decoded, so decoding is not timed) with `threads` rayon threads
/// and reports the throughput. The background starts as the median of up to 25 frames.
pub fn bench_mrf(
    config: &MrfConfig,
    frames: &[Frame],
    threads: usize,
    seed: u64,
) -> Result<MrfBench> {
    let first = frames
        .first()
        .ok_or_else(|| Error::Invalid("bench_mrf needs at least one frame".into()))?;
    let (w, h) = first.size();
    let mut tracker = MrfTracker::new(config.clone(), w, h, seed)?;
    tracker.set_background(bootstrap_from_frames(frames, config.background.clone())?)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| Error::Invalid(format!("cannot build a thread pool: {e}")))?;
    let (mut matched, mut sites, mut sweeps, mut with_sites) = (0u64, 0u64, 0u64, 0u64);
    let start = std::time::Instant::now();
    pool.install(|| -> Result<()> {
        for f in frames {
            tracker.step(f)?;
            let s = tracker.stats();
            matched += u64::from(s.matched_blocks);
            sites += u64::from(s.sites);
            if s.sites > 0 {
                with_sites += 1;
                sweeps += u64::from(s.gibbs.iterations);
            }
        }
        Ok(())
    })?;
    let seconds = start.elapsed().as_secs_f64();
    let stages = tracker.stage_times();
    let n = frames.len() as f64;
    Ok(MrfBench {
        frames: frames.len() as u32,
        width: w,
        height: h,
        threads: threads.max(1),
        seconds,
        fps: n / seconds.max(1e-12),
        mean_matched_blocks: matched as f64 / n,
        mean_sites: sites as f64 / n,
        mean_sweeps: if with_sites > 0 {
            sweeps as f64 / with_sites as f64
        } else {
            0.0
        },
        stages,
    })
}
