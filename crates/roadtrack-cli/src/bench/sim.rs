//! Timings of the simulator's stages (`roadtrack bench --stages simulate`).

use roadtrack::error::Result;
use roadtrack_sim::{SimConfig, Simulation, encode_frame};
use std::time::Instant;

/// Timings of the simulator's stages (for `roadtrack bench`).
#[derive(Debug, Clone, PartialEq)]
pub struct SimBenchmark {
    /// Frames produced.
    pub frames: u32,
    /// Image size, px.
    pub size: (u32, u32),
    /// Scene set-up: warm-up traffic and background rendering, s.
    pub setup_s: f64,
    /// Traffic, rendering, truth and detections for all frames, one thread, s.
    pub render_s: f64,
    /// Encoding all frames (one thread) in the configured format, s.
    pub encode_s: f64,
    /// Mean encoded frame size, bytes.
    pub mean_frame_bytes: f64,
}

/// Runs `config` for `frames` frames on the calling thread and times each stage (nothing
/// is written to disk).
///
/// # Errors
/// An invalid configuration.
pub fn benchmark(config: &SimConfig, seed: u64, frames: u32) -> Result<SimBenchmark> {
    let cfg = SimConfig {
        frames,
        ..config.clone()
    };
    let t0 = Instant::now();
    let mut sim = Simulation::new(&cfg, seed)?;
    let setup_s = t0.elapsed().as_secs_f64();
    let (mut render_s, mut encode_s, mut bytes) = (0.0, 0.0, 0usize);
    loop {
        let t = Instant::now();
        let Some(step) = sim.next() else { break };
        let step = step?;
        render_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        bytes += encode_frame(&step, &cfg)?.len();
        encode_s += t.elapsed().as_secs_f64();
    }
    Ok(SimBenchmark {
        frames,
        size: (cfg.width, cfg.height),
        setup_s,
        render_s,
        encode_s,
        mean_frame_bytes: bytes as f64 / f64::from(frames.max(1)),
    })
}
