//! Times the simulator's stages (set-up, traffic and rendering, encoding) on one thread
//! (docs/SIMULATOR.md "Speed").
//!
//! ```text
//! cargo bench -p roadtrack-cli --bench simulate -- SCENE VIEW FRAMES
//! ```

use roadtrack_cli::bench::sim::benchmark;
use roadtrack_sim::SimConfig;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = roadtrack_cli::bench::bench_args();
    let config = SimConfig {
        scene: args.first().map_or("road", String::as_str).parse()?,
        view: args.get(1).map_or("aerial", String::as_str).parse()?,
        ..SimConfig::default()
    };
    let frames = args.get(2).map_or(Ok(1000), |s| s.parse())?;
    let b = benchmark(&config, 0, frames)?;
    println!(
        "{:?}/{:?} {} frames {}x{}: setup {:.2} s, simulate+render {:.2} s ({:.2} ms/frame), encode {:.2} s ({:.2} ms/frame), {:.0} KB/frame",
        config.scene,
        config.view,
        b.frames,
        b.size.0,
        b.size.1,
        b.setup_s,
        b.render_s,
        1e3 * b.render_s / f64::from(b.frames),
        b.encode_s,
        1e3 * b.encode_s / f64::from(b.frames),
        b.mean_frame_bytes / 1e3
    );
    Ok(())
}
