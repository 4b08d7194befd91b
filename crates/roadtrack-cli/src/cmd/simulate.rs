//! `roadtrack simulate`: synthetic traffic with ground truth (`roadtrack_sim`).

use crate::common::{Ui, load_config};
use anyhow::{Context, Result};
use roadtrack_sim::{ImageFormat, PairsConfig, SceneKind, SimConfig, ViewKind};
use std::path::PathBuf;

/// Simulate traffic and write a MOTChallenge sequence folder with ground truth.
///
/// The folder holds `img1/` (frames), `seqinfo.ini`, `gt/gt.txt` (boxes, MOT17 class,
/// visibility from the render), `det/det.txt` and `det/detections.csv` (noisy detections
/// with colour), `truth.csv` (positions in metres and pixels, speed, heading, size,
/// colour), `calibration.toml` and `simulation.toml` (the full configuration).
///
/// With `--pairs DT` it writes two-frame matching problems instead (`pair_NNNN/frame1.csv`,
/// `frame2.csv`, `truth.csv`, as `roadtrack sweep` reads them). Flags override the values
/// of `--config`; see docs/SIMULATOR.md for the models and every configuration key.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  \
    roadtrack simulate --scene intersection --view oblique --frames 300 -o s/\n  \
    roadtrack simulate --scene road --pairs 1.5 --n-pairs 20 --drop 0.1 -o pairs_1.5/\n  \
    roadtrack simulate --scene crossing --view oblique --from-trajectories traj.csv -o ext/")]
pub struct Args {
    /// Output folder.
    #[arg(short, long, value_name = "DIR", value_parser = crate::common::folder_output)]
    pub output: PathBuf,
    /// Scenario [default: road, or the config's].
    #[arg(long, value_enum)]
    pub scene: Option<SceneKind>,
    /// Camera [default: aerial, or the config's].
    #[arg(long, value_enum)]
    pub view: Option<ViewKind>,
    /// Frames to write [default: 300, or the config's; with --from-trajectories the
    /// file's whole time span].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=i64::from(roadtrack::limits::MAX_FRAME)))]
    pub frames: Option<u32>,
    /// Seed of every random draw (same seed → byte-identical folder).
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub seed: u64,
    /// TOML file with a `SimConfig` (e.g. the `simulation.toml` of an earlier run).
    #[arg(long, value_name = "F.toml")]
    pub config: Option<PathBuf>,
    /// Frame rate, frames/s, at most 1000 [default: 10].
    #[arg(long, value_name = "FPS", value_parser = roadtrack::limits::parse_fps)]
    pub fps: Option<f64>,
    /// Image width, px [default: 640].
    #[arg(long, value_name = "PX")]
    pub width: Option<u32>,
    /// Image height, px [default: 480].
    #[arg(long, value_name = "PX")]
    pub height: Option<u32>,
    /// Format of the frames in img1/ [default: jpeg].
    #[arg(long, value_enum)]
    pub image_format: Option<ImageFormat>,
    /// Render these trajectories (header `time_s,id,class,x_m,y_m,heading_deg,length_m,
    /// width_m`, optional `r,g,b`, `height_m`) instead of simulating traffic.
    #[arg(long, value_name = "F.csv", conflicts_with = "pairs")]
    pub from_trajectories: Option<PathBuf>,
    /// Write two-frame matching problems DT seconds apart instead of a sequence.
    #[arg(long, value_name = "DT", value_parser = crate::flags::positive)]
    pub pairs: Option<f64>,
    /// Number of problems (with --pairs).
    #[arg(long, default_value_t = 20, value_name = "N", requires = "pairs", value_parser = clap::value_parser!(u32).range(1..))]
    pub n_pairs: u32,
    /// Probability that a vehicle is missing from a frame, independently in each frame
    /// (with --pairs; seed 000's "about 10 % not extracted" is 0.1).
    #[arg(long, default_value_t = 0.0, value_name = "F", requires = "pairs", value_parser = crate::flags::unit_fraction)]
    pub drop: f64,
    /// Sd of the noise added to each vehicle centre, px (with --pairs).
    #[arg(long, default_value_t = 0.0, value_name = "PX", requires = "pairs", value_parser = crate::flags::non_negative)]
    pub position_noise: f64,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let mut config: SimConfig = load_config(args.config.as_deref())?;
    if let Some(s) = args.scene {
        config.scene = s;
    }
    if let Some(v) = args.view {
        config.view = v;
    }
    if let Some(n) = args.frames {
        config.frames = n;
    }
    if let Some(f) = args.fps {
        config.fps = f;
    }
    if let Some(w) = args.width {
        config.width = w;
    }
    if let Some(h) = args.height {
        config.height = h;
    }
    if let Some(f) = args.image_format {
        config.image_format = f;
    }
    crate::flags::check_overrides(
        config.validate(),
        &[
            ("frames", "--frames", args.frames.is_some()),
            ("fps", "--fps", args.fps.is_some()),
            ("width", "--width", args.width.is_some()),
            ("width", "--height", args.height.is_some()),
        ],
        args.config.as_deref(),
    )?;
    let out = &args.output;

    if let Some(dt) = args.pairs {
        let pairs = PairsConfig {
            dt_s: dt,
            n_pairs: args.n_pairs,
            drop_fraction: args.drop,
            position_sd_px: args.position_noise,
            ..PairsConfig::default()
        };
        // Every field but the defaults' comes from a flag: a bound it breaks is a usage
        // error naming the flag.
        crate::flags::check_overrides(
            pairs.validate(),
            &[
                ("dt_s", "--pairs", true),
                ("n_pairs", "--n-pairs", true),
                ("drop_fraction", "--drop", true),
                ("position_sd_px", "--position-noise", true),
            ],
            None,
        )?;
        let bar = ui.progress(Some(u64::from(pairs.n_pairs)), "pairs");
        let s = roadtrack_sim::write_pairs(&config, &pairs, args.seed, out, &mut |d, _| {
            bar.set_position(d)
        })
        .with_context(|| format!("writing pairs into {}", out.display()))?;
        bar.finish_and_clear();
        ui.info(format!(
            "{} problems at Δt {dt} s → {} (mean {:.1} → {:.1} vehicles, {:.1} true pairs)",
            s.n_pairs,
            out.display(),
            s.mean_vehicles_frame1,
            s.mean_vehicles_frame2,
            s.mean_true_matches
        ));
        return Ok(());
    }

    let total = args.frames.unwrap_or(config.frames);
    let bar = ui.progress(
        if args.from_trajectories.is_some() && args.frames.is_none() {
            None
        } else {
            Some(u64::from(total))
        },
        "simulate",
    );
    let mut progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let summary = match &args.from_trajectories {
        Some(traj) => roadtrack_sim::simulate_from_trajectories(
            &config,
            args.seed,
            traj,
            args.frames,
            out,
            &mut progress,
        )?,
        None => roadtrack_sim::simulate(&config, args.seed, out, &mut progress)?,
    };
    bar.finish_and_clear();
    ui.info(format!(
        "{} frames, {} objects ({} vehicles, {} pedestrians), {} detections, mean visibility {:.2} → {}",
        summary.frames,
        summary.objects,
        summary.vehicles,
        summary.pedestrians,
        summary.detections,
        summary.mean_visibility,
        out.display()
    ));
    Ok(())
}
