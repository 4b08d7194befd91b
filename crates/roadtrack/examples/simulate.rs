//! Simulates a scene and writes a MOTChallenge folder, or times the simulator.
//!
//! ```text
//! cargo run --example simulate -- SCENE VIEW FRAMES OUT_DIR [SEED]
//! cargo run --example simulate -- bench SCENE VIEW FRAMES
//! ```

use roadtrack_sim::{SimConfig, benchmark, simulate};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("bench") {
        let config = SimConfig {
            scene: args.get(1).map_or("road", String::as_str).parse()?,
            view: args.get(2).map_or("aerial", String::as_str).parse()?,
            ..SimConfig::default()
        };
        let frames = args.get(3).map_or(Ok(1000), |s| s.parse())?;
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
        return Ok(());
    }
    if args.first().map(String::as_str) == Some("pairs") {
        let mut config = SimConfig::default();
        if let Some(q) = args.get(3) {
            config.road.inflow_veh_per_h = q.parse()?;
        }
        if let Some(v) = args.get(4) {
            config.road.speed_limit_mps = v.parse()?;
        }
        let pairs = roadtrack_sim::PairsConfig {
            dt_s: args.get(1).map_or(Ok(1.5), |s| s.parse())?,
            ..Default::default()
        };
        let out = std::path::PathBuf::from(args.get(2).map_or("pairs_out", String::as_str));
        let s = roadtrack_sim::write_pairs(&config, &pairs, 0, &out, &mut |_, _| {})?;
        println!("{s:?}");
        return Ok(());
    }
    let config = SimConfig {
        scene: args.first().map_or("road", String::as_str).parse()?,
        view: args.get(1).map_or("aerial", String::as_str).parse()?,
        frames: args.get(2).map_or(Ok(100), |s| s.parse())?,
        image_format: if std::env::var_os("SIM_PNG").is_some() {
            roadtrack_sim::ImageFormat::Png
        } else {
            roadtrack_sim::ImageFormat::Jpeg
        },
        ..SimConfig::default()
    };
    let out = std::path::PathBuf::from(args.get(3).map_or("sim_out", String::as_str));
    let seed = args.get(4).map_or(Ok(0), |s| s.parse())?;
    let summary = simulate(&config, seed, &out, &mut |_, _| {})?;
    println!("{summary:?}");
    Ok(())
}
