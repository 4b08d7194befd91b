//! Throughput of the MRF tracker (`roadtrack_cli::bench::mrf::bench_mrf`), frames decoded/rendered beforehand.
//!
//! ```text
//! cargo bench -p roadtrack-cli --bench mrf -- sim SCENE FRAMES [THREADS]   # 640×480 oblique
//! cargo bench -p roadtrack-cli --bench mrf -- video PATH FRAMES [THREADS]
//! cargo bench -p roadtrack-cli --bench mrf -- kernel   # block-matching paths, one thread
//! ```
//!
//! Prints one line per variant (improved, legacy): frames/s by wall clock and per CPU
//! second of the process (user + system from `/proc/self/stat`, 10 ms ticks, minus the
//! background bootstrap; robust to a shared machine), and wall time per stage.

use roadtrack::detect::background_model::{BackgroundModel, bootstrap_positions};
use roadtrack::frame::Frame;
use roadtrack::track::mrf::{MrfConfig, MrfVariant};
use roadtrack_cli::bench::cpu_seconds as process_cpu_s;
use roadtrack_cli::bench::mrf::bench_mrf;
use roadtrack_sim::{SimConfig, ViewKind, simulate_in_memory};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = roadtrack_cli::bench::bench_args();
    let kind = args.first().map_or("sim", String::as_str);
    let what = args.get(1).map_or("crossing", String::as_str);
    let n: u32 = args.get(2).map_or(Ok(200), |s| s.parse())?;
    let threads: usize = args.get(3).map_or(Ok(1), |s| s.parse())?;
    if kind == "kernel" {
        return kernel();
    }
    let frames: Vec<Frame> = if kind == "video" {
        let opts = roadtrack::io::SourceOptions {
            end: Some(n),
            ..Default::default()
        };
        roadtrack::io::source::open(std::path::Path::new(what), &opts)?
            .collect::<roadtrack::Result<_>>()?
    } else {
        let config = SimConfig {
            scene: what.parse()?,
            view: ViewKind::Oblique,
            frames: n,
            ..SimConfig::default()
        };
        simulate_in_memory(&config, 0)?.frames
    };
    for variant in [MrfVariant::Improved, MrfVariant::Legacy] {
        let cfg = MrfConfig {
            variant,
            ..MrfConfig::default()
        };
        let cpu0 = process_cpu_s();
        let b = bench_mrf(&cfg, &frames, threads, 0)?;
        // The CPU time of the background bootstrap inside `bench_mrf` (not part of tracking)
        // is measured separately and subtracted.
        let cpu1 = process_cpu_s();
        let pos = bootstrap_positions(Some(frames.len() as u32), cfg.background.bootstrap_frames);
        let samples: Vec<_> = pos
            .iter()
            .map(|&p| frames[p as usize].image.clone())
            .collect();
        BackgroundModel::from_samples(&samples, cfg.background.clone())?;
        let cpu = (cpu1 - cpu0) - (process_cpu_s() - cpu1);
        let ms = |s: f64| 1e3 * s / f64::from(b.frames);
        println!(
            "{kind} {what} {}x{} {} frames {variant:?} threads={}: {:.1} frames/s wall, \
             {:.1} frames/s per CPU second \
             ({:.2} ms/frame: luminance {:.2}, background {:.2}, matching {:.2}, \
             propagation {:.2}, gibbs {:.2}, output {:.2}); {:.0} matched blocks/frame, \
             {:.1} sites/frame, {:.2} sweeps",
            b.width,
            b.height,
            b.frames,
            b.threads,
            b.fps,
            f64::from(b.frames) / cpu,
            ms(b.seconds),
            ms(b.stages.luminance_s),
            ms(b.stages.background_s),
            ms(b.stages.matching_s),
            ms(b.stages.propagation_s),
            ms(b.stages.gibbs_s),
            ms(b.stages.output_s),
            b.mean_matched_blocks,
            b.mean_sites,
            b.mean_sweeps
        );
    }
    Ok(())
}

/// CPU time per block of each block-matching path on one 640×480 pair of the simulated
/// crossing (±24 px, 1 000 blocks spread over the frame, guess (0, 0)).
fn kernel() -> Result<(), Box<dyn std::error::Error>> {
    use roadtrack::track::mrf::block_matching::{
        gray_from_rgb, match_block_reference, match_block_simd, match_block_with,
    };
    let config = SimConfig {
        scene: "crossing".parse()?,
        view: ViewKind::Oblique,
        frames: 2,
        ..SimConfig::default()
    };
    let run = simulate_in_memory(&config, 0)?;
    let (a, b) = (
        gray_from_rgb(&run.frames[0].image),
        gray_from_rgb(&run.frames[1].image),
    );
    let blocks: Vec<(u32, u32)> = (0..1000u32)
        .map(|k| (3 + k % 74, 3 + (k * 7) % 54))
        .collect();
    type Path = (
        &'static str,
        fn(&image::GrayImage, &image::GrayImage, u32, u32) -> u32,
    );
    let paths: [Path; 5] = [
        ("brute force (reference)", |a, b, x, y| {
            match_block_reference(a, b, x, y, 24).sad
        }),
        ("scalar rows, early termination", |a, b, x, y| {
            match_block_with::<false>(a, b, x, y, 24, [0, 0]).sad
        }),
        ("SSE2 psadbw, early termination (before)", |a, b, x, y| {
            match_block_with::<true>(a, b, x, y, 24, [0, 0]).sad
        }),
        ("SSE4.1 mpsadbw, exhaustive", |a, b, x, y| {
            match_block_simd(a, b, x, y, 24, false).sad
        }),
        ("AVX2 vmpsadbw, exhaustive (now)", |a, b, x, y| {
            match_block_simd(a, b, x, y, 24, true).sad
        }),
    ];
    for (name, f) in paths {
        // Repeat the block list until at least 1 s of CPU (the clock ticks at 10 ms).
        let c0 = process_cpu_s();
        let (mut n, mut acc) = (0usize, 0u64);
        while process_cpu_s() - c0 < 1.0 {
            for &(x, y) in &blocks {
                acc += u64::from(f(&a, &b, x, y));
            }
            n += blocks.len();
        }
        let cpu = process_cpu_s() - c0;
        println!(
            "{name}: {:.2} µs/block of CPU ({n} blocks, mean SAD {:.1})",
            1e6 * cpu / n as f64,
            acc as f64 / n as f64
        );
    }
    Ok(())
}
