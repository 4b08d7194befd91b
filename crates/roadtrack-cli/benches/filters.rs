//! Per-stage timings of the PHD filter (colour likelihood per particle and dense) and the
//! particle filter, 10 targets × 70 particles at 640 × 480 (docs/PERFORMANCE.md "Filters").
//!
//! ```text
//! cargo bench -p roadtrack-cli --bench filters [-- FRAMES [STRIDE_PX]]
//! ```

use roadtrack_cli::bench::filters::{FilterBenchConfig, bench_filters};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = roadtrack_cli::bench::bench_args();
    let mut cfg = FilterBenchConfig::default();
    if let Some(f) = args.first() {
        cfg.frames = f.parse()?;
    }
    if let Some(s) = args.get(1) {
        cfg.dense_stride_px = s.parse()?;
    }
    let reports = bench_filters(&cfg, &mut |_, _| {})?;
    println!(
        "| run | particles | predict | likelihood | update | labels | resample | total ms | frames/s |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for r in reports {
        println!(
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} |",
            r.name,
            r.particles,
            r.predict_ms,
            r.likelihood_ms,
            r.update_ms,
            r.labels_ms,
            r.resample_ms,
            r.total_ms,
            r.fps
        );
    }
    Ok(())
}
