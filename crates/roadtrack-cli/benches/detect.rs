//! Throughput of the background detector with and without the age cut
//! (`[regions] age_gap_s`), the same frames, runs alternating.
//!
//! ```text
//! cargo bench -p roadtrack-cli --bench detect -- generated FRAMES [THREADS] [ROUNDS]
//! cargo bench -p roadtrack-cli --bench detect -- sim SCENE FRAMES [THREADS] [ROUNDS]   # 640×480 oblique
//! ```
//!
//! Prints one line per run: frames/s by wall clock and per CPU second of the process
//! (user + system from `/proc/self/stat`, 10 ms ticks, bootstrap excluded; robust to a
//! shared machine). `bench --stages detect` runs the default only.

use std::time::Instant;

use roadtrack::detect::background::{BackgroundDetector, BackgroundDetectorConfig};
use roadtrack::frame::Frame;
use roadtrack_cli::bench::cpu_seconds;
use roadtrack_sim::{SimConfig, ViewKind, simulate_in_memory};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = roadtrack_cli::bench::bench_args();
    let kind = args.first().map_or("generated", String::as_str);
    let (frames, label, rest): (Vec<Frame>, String, &[String]) = if kind == "sim" {
        let scene = args.get(1).map_or("intersection", String::as_str);
        let n: u32 = args.get(2).map_or(Ok(300), |s| s.parse())?;
        let config = SimConfig {
            scene: scene.parse()?,
            view: ViewKind::Oblique,
            frames: n,
            ..SimConfig::default()
        };
        let run = simulate_in_memory(&config, 0)?;
        (
            run.frames,
            format!("{scene} oblique, {n} frames"),
            args.get(3..).unwrap_or(&[]),
        )
    } else {
        let n: u32 = args.get(1).map_or(Ok(300), |s| s.parse())?;
        (
            roadtrack_sim::testkit::moving_boxes(640, 480, n, 12),
            format!("generated 640×480, 12 boxes, {n} frames"),
            args.get(2..).unwrap_or(&[]),
        )
    };
    let threads: usize = rest.first().map_or(Ok(0), |s| s.parse())?;
    let rounds: usize = rest.get(1).map_or(Ok(3), |s| s.parse())?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let with_cut = BackgroundDetectorConfig::default();
    let mut without = with_cut.clone();
    without.regions.age_gap_s = 0.0;
    for round in 0..rounds {
        for (name, cfg) in [("age cut off", &without), ("age cut on", &with_cut)] {
            let total = Some(frames.len() as u32);
            let (wall, cpu) = pool.install(|| -> roadtrack::Result<(f64, f64)> {
                let mut det = BackgroundDetector::bootstrap(
                    cfg.clone(),
                    frames.iter().cloned().map(Ok),
                    total,
                )?;
                let (c0, t0) = (cpu_seconds(), Instant::now());
                let mut n = 0usize;
                for f in &frames {
                    n += det.detect(f)?.len();
                }
                std::hint::black_box(n);
                Ok((t0.elapsed().as_secs_f64(), cpu_seconds() - c0))
            })?;
            let nf = frames.len() as f64;
            println!(
                "{label}, threads={}, round {round}, {name}: {:.1} frames/s wall, \
                 {:.1} frames/s per CPU second",
                pool.current_num_threads(),
                nf / wall,
                nf / cpu
            );
        }
    }
    Ok(())
}
