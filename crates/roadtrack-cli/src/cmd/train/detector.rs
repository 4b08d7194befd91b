//! `roadtrack train --detector`: train the learned detector (`--detector cnn`) on simulator
//! renders with burn (crate roadtrack-learn) and write it as ONNX.

use crate::common::Ui;
use anyhow::Result;
use std::path::PathBuf;

/// The flags of `train --detector` (with `--seed`, `--batch-size`, `--learning-rate`, `-o`).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct DetectorTrainArgs {
    /// --detector: optimiser steps of the learning-rate schedule [default: 3000].
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000_000))]
    pub steps: Option<usize>,
    /// --detector: stop after N steps, the schedule of --steps unchanged (reproduces a
    /// checkpoint of a longer run) [default: --steps].
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000_000))]
    pub stop_after: Option<usize>,
    /// --detector: crop side in px, a multiple of 16 [default: 128].
    #[arg(long, value_name = "PX", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(32..=1024))]
    pub crop: Option<usize>,
    /// --detector: write the weights so far to the output every N steps (0: only at the
    /// end) [default: 250].
    #[arg(long, value_name = "N")]
    pub checkpoint_every: Option<usize>,
    /// --detector: no training; write the weights saved as JSON by roadtrack-learn's
    /// `train_detector` example as ONNX (-o).
    #[arg(long, value_name = "W.json")]
    pub from_weights: Option<PathBuf>,
    /// --detector: no training; write the element-wise mean of these networks (JSON or a
    /// learned detector's .onnx, all of one shape) as ONNX (-o), and as JSON with
    /// --weights-out: a soup of fine-tunes started from the same weights.
    #[arg(long, value_name = "W", num_args = 2.., conflicts_with_all = ["from_weights", "init"])]
    pub average: Vec<PathBuf>,
    /// --detector: start from these weights (JSON, as `train_detector` writes, the
    /// checkpoint of an earlier run, or a learned detector's .onnx such as the shipped
    /// models/detector.onnx) instead of random ones; the optimiser and the schedule of
    /// --steps start fresh (a second stage of a recipe).
    #[arg(long, value_name = "W.json|W.onnx", conflicts_with = "from_weights")]
    pub init: Option<PathBuf>,
    /// --detector: also write the weights as JSON here, at every checkpoint and at the
    /// end (what --init of a next stage reads).
    #[arg(long, value_name = "W.json", conflicts_with = "from_weights")]
    pub weights_out: Option<PathBuf>,
    /// --detector: simulator seed of the first training episode [default: 1000]; a second
    /// stage takes seeds the first did not use.
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedU64ValueParser::<u64>::new().range(4..))]
    pub sim_seed_base: Option<u64>,
    /// --detector: clip each object's box to the crop, as the ground truth clips boxes to
    /// the frame (by default a box is whole, and an object whose centre falls outside the
    /// crop is left out). Tried as a fifth stage and not kept (docs/EXPERIMENTS.md).
    #[arg(long)]
    pub clip_to_crop: bool,
    /// --detector: this share of the crops (0–1) has an edge cutting an object 16 crop px
    /// or more across, 40–90 % of it inside: vehicles leaving the frame. With
    /// --clip-to-crop. Tried as a stage and not kept (docs/EXPERIMENTS.md "Edge crops")
    /// [default: 0].
    #[arg(long, value_name = "SHARE", requires = "clip_to_crop")]
    pub edge_crops: Option<f64>,
    /// --detector: weight of each class's box targets in the box loss, four numbers for
    /// car, bus/truck, bicycle/motorcycle and pedestrian [default: 1,1,1,1].
    #[arg(long, value_name = "W,W,W,W", value_delimiter = ',')]
    pub box_class_weights: Option<Vec<f32>>,
    /// --detector: share of the simulated vehicles that are motorcycles, in [0, 1)
    /// [default: the simulator's 0.08]. Tried at 0.3 and not kept (docs/EXPERIMENTS.md
    /// "More motorcycles in training").
    #[arg(long, value_name = "SHARE")]
    pub motorcycle_share: Option<f64>,
    /// --detector: share of the simulated vehicles that are lorries or buses, in [0, 1),
    /// their own ratio kept [default: the simulator's 0.12].
    #[arg(long, value_name = "SHARE")]
    pub heavy_share: Option<f64>,
    /// --detector: no training; copy the learned detector given as --init (.onnx) to -o with
    /// this box gain in its metadata: a_w, b_w, a_h, b_h for car, bus/truck,
    /// bicycle/motorcycle and pedestrian (16 numbers; each side's factor is e^(a + b
    /// ln(√(w h) / 32))), as scripts/box_gain.py measures them (docs/DETECTION.md "Box
    /// gain"). A list starting with a minus sign goes as `--box-gain=-0.1,…`.
    #[arg(long, value_name = "A,B,…", value_delimiter = ',', allow_negative_numbers = true,
          requires = "init",
          conflicts_with_all = ["from_weights", "average", "weights_out"])]
    pub box_gain: Option<Vec<f64>>,
    /// --detector: write every step's losses to this CSV (step, learning_rate, heat, boxes,
    /// total).
    #[arg(long, value_name = "F.csv")]
    pub loss_log: Option<PathBuf>,
}

/// The `--detector` flags are usage errors when training a classifier.
pub fn reject_detector_flags(a: &DetectorTrainArgs) -> Result<()> {
    crate::flags::reject_given(
        &[
            ("--steps", a.steps.is_some()),
            ("--stop-after", a.stop_after.is_some()),
            ("--crop", a.crop.is_some()),
            ("--checkpoint-every", a.checkpoint_every.is_some()),
            ("--loss-log", a.loss_log.is_some()),
            ("--from-weights", a.from_weights.is_some()),
            ("--init", a.init.is_some()),
            ("--average", !a.average.is_empty()),
            ("--weights-out", a.weights_out.is_some()),
            ("--sim-seed-base", a.sim_seed_base.is_some()),
            ("--clip-to-crop", a.clip_to_crop),
            ("--edge-crops", a.edge_crops.is_some()),
            ("--box-class-weights", a.box_class_weights.is_some()),
            ("--motorcycle-share", a.motorcycle_share.is_some()),
            ("--heavy-share", a.heavy_share.is_some()),
            ("--box-gain", a.box_gain.is_some()),
        ],
        "only with --detector",
    )
}

/// `--from-weights W.json`: a JSON checkpoint of the trainer written as the ONNX model.
#[cfg(feature = "cnn")]
fn convert_weights(weights: &std::path::Path, output: &std::path::Path, ui: &Ui) -> Result<()> {
    use anyhow::Context as _;
    let text = std::fs::read_to_string(weights).map_err(|e| roadtrack::Error::io(weights, e))?;
    let w = roadtrack_cnn::centernet::CenterNetWeights::from_json(&text)
        .with_context(|| format!("reading {}", weights.display()))?;
    roadtrack_cnn::centernet::write_onnx(output, &w)
        .with_context(|| format!("writing {}", output.display()))?;
    ui.info(format!("wrote {}", output.display()));
    Ok(())
}

/// `--average W...`: the mean of the networks, written as ONNX (and as JSON with
/// `--weights-out`).
#[cfg(feature = "cnn")]
fn average_weights(
    inputs: &[PathBuf],
    output: &std::path::Path,
    weights_out: Option<&std::path::Path>,
    ui: &Ui,
) -> Result<()> {
    use anyhow::Context as _;
    use roadtrack_cnn::centernet::{CenterNetWeights, read_weights_any, write_onnx};
    let nets = inputs
        .iter()
        .map(|p| read_weights_any(p))
        .collect::<roadtrack::Result<Vec<_>>>()?;
    let mean = CenterNetWeights::average(&nets).with_context(|| {
        let names: Vec<String> = inputs.iter().map(|p| p.display().to_string()).collect();
        format!("averaging {} (in this order)", names.join(", "))
    })?;
    write_onnx(output, &mean).with_context(|| format!("writing {}", output.display()))?;
    if let Some(p) = weights_out {
        roadtrack::io::atomic::write_bytes_atomic(p, mean.to_json()?.as_bytes())?;
    }
    ui.info(format!(
        "wrote {}: the mean of {} networks",
        output.display(),
        nets.len()
    ));
    Ok(())
}

/// `--box-gain A,B,…`: the model of `--init` written to `output` with the gain in its
/// metadata.
#[cfg(feature = "cnn")]
fn set_box_gain(
    init: Option<&std::path::Path>,
    gain: &[f64],
    output: &std::path::Path,
    ui: &Ui,
) -> Result<()> {
    use anyhow::Context as _;
    let Some(init) = init else {
        return Err(crate::flags::invalid(
            "--box-gain needs the model to copy: --init F.onnx",
        ));
    };
    let terms = roadtrack_cnn::centernet::box_gain_terms(gain)
        .map_err(|e| crate::flags::invalid(format!("--box-gain: {e}")))?;
    roadtrack_cnn::centernet::write_box_gain(init, output, &terms)
        .with_context(|| format!("writing {}", output.display()))?;
    let text: Vec<String> = gain.iter().map(f64::to_string).collect();
    ui.info(format!(
        "wrote {}: {} with box gain {}",
        output.display(),
        init.display(),
        text.join(",")
    ));
    Ok(())
}

/// Without the `learn` feature there is no trainer (`--from-weights` still converts when
/// the `cnn` feature is on).
#[cfg(not(feature = "learn"))]
pub fn run(args: &super::Args, ui: &Ui) -> Result<()> {
    #[cfg(feature = "cnn")]
    if let Some(gain) = &args.detector_args.box_gain {
        return set_box_gain(args.detector_args.init.as_deref(), gain, &args.output, ui);
    }
    #[cfg(feature = "cnn")]
    if let Some(path) = &args.detector_args.from_weights {
        return convert_weights(path, &args.output, ui);
    }
    #[cfg(feature = "cnn")]
    if !args.detector_args.average.is_empty() {
        let d = &args.detector_args;
        return average_weights(&d.average, &args.output, d.weights_out.as_deref(), ui);
    }
    let _ = (args, ui);
    anyhow::bail!(
        "roadtrack was built without the `learn` feature, which trains the detector \
         (cargo build -p roadtrack-cli --features learn)"
    )
}

/// Trains and writes the detector.
#[cfg(feature = "learn")]
pub fn run(args: &super::Args, ui: &Ui) -> Result<()> {
    use anyhow::Context as _;
    use roadtrack_learn::{Progress, TrainConfig, train};
    use std::io::Write as _;

    let d = &args.detector_args;
    if let Some(gain) = &d.box_gain {
        return set_box_gain(d.init.as_deref(), gain, &args.output, ui);
    }
    if let Some(path) = &d.from_weights {
        return convert_weights(path, &args.output, ui);
    }
    if !d.average.is_empty() {
        return average_weights(&d.average, &args.output, d.weights_out.as_deref(), ui);
    }
    let mut config = TrainConfig {
        seed: args.seed,
        ..TrainConfig::default()
    };
    if let Some(v) = d.steps {
        config.steps = v;
    }
    config.stop_after = d.stop_after;
    if let Some(p) = &d.init {
        // roadtrack_learn::arch is roadtrack's own centernet module: the same type.
        let w = roadtrack_cnn::centernet::read_weights_any(p)
            .with_context(|| format!("reading the starting weights {}", p.display()))?;
        config.init = Some(std::sync::Arc::new(w));
    }
    if let Some(v) = d.sim_seed_base {
        config.sim_seed_base = v;
    }
    if let Some(v) = d.crop {
        config.data.crop = v;
    }
    config.data.clip_to_crop = d.clip_to_crop;
    if let Some(v) = d.edge_crops {
        config.data.edge_crop_share = v;
    }
    if let Some(v) = &d.box_class_weights {
        if v.len() != config.data.box_class_weights.len() {
            anyhow::bail!(
                "--box-class-weights: four weights (car, bus/truck, bicycle/motorcycle, \
                 pedestrian), got {}",
                v.len()
            );
        }
        config.data.box_class_weights.copy_from_slice(v);
    }
    config.data.motorcycle_share = d.motorcycle_share;
    config.data.heavy_share = d.heavy_share;
    if let Some(v) = args.batch_size {
        config.batch = v;
    }
    if let Some(v) = args.learning_rate {
        config.learning_rate = v;
    }
    crate::flags::check_overrides(
        config.validate(),
        &[
            ("crop", "--crop", d.crop.is_some()),
            (
                "edge_crop_share/edge_crop_min_px",
                "--edge-crops",
                d.edge_crops.is_some(),
            ),
            ("init", "--init", d.init.is_some()),
            (
                "box_class_weights",
                "--box-class-weights",
                d.box_class_weights.is_some(),
            ),
            (
                "motorcycle_share",
                "--motorcycle-share",
                d.motorcycle_share.is_some(),
            ),
            ("heavy_share", "--heavy-share", d.heavy_share.is_some()),
            (
                "motorcycle_share/heavy_share",
                "--motorcycle-share/--heavy-share",
                d.motorcycle_share.is_some() && d.heavy_share.is_some(),
            ),
            ("batch", "--batch-size", args.batch_size.is_some()),
            (
                "learning_rate",
                "--learning-rate",
                args.learning_rate.is_some(),
            ),
        ],
        None,
    )?;
    let checkpoint_every = d.checkpoint_every.unwrap_or(250);
    let mut log = match &d.loss_log {
        Some(p) => {
            let f = std::fs::File::create(p)
                .with_context(|| format!("creating the loss log {}", p.display()))?;
            let mut w = std::io::BufWriter::new(f);
            writeln!(w, "step,learning_rate,heat,boxes,total")
                .with_context(|| format!("writing {}", p.display()))?;
            Some((p.clone(), w))
        }
        None => None,
    };
    ui.info(format!(
        "training the detector: {} steps of {} crops of {} px, lr {}, seed {}; simulator \
         seeds from {}",
        config.steps,
        config.batch,
        config.data.crop,
        config.learning_rate,
        config.seed,
        config.sim_seed_base
    ));
    let stop = config.stop_after.unwrap_or(config.steps).min(config.steps);
    let bar = ui.progress(Some(stop as u64), "train");
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{msg:>24} [{bar:30}] {pos}/{len} steps, eta {eta}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    let output = args.output.clone();
    let mut smooth: Option<f64> = None;
    let weights = train(&config, checkpoint_every, &mut |p| {
        match p {
            Progress::Step(l) => {
                let s = smooth.map_or(f64::from(l.total), |s| 0.98 * s + 0.02 * f64::from(l.total));
                smooth = Some(s);
                bar.set_position(l.step as u64);
                bar.set_message(format!("loss {s:.4}"));
                if let Some((path, w)) = &mut log {
                    writeln!(
                        w,
                        "{},{},{},{},{}",
                        l.step, l.learning_rate, l.heat, l.boxes, l.total
                    )
                    .and_then(|_| w.flush())
                    .map_err(|e| roadtrack::Error::io(path.as_path(), e))?;
                }
                bar.suspend(|| {
                    ui.detail(format!(
                        "step {:>6}: loss {:.4} (heat {:.4}, boxes {:.4}), lr {:.2e}",
                        l.step, l.total, l.heat, l.boxes, l.learning_rate
                    ))
                });
            }
            Progress::Checkpoint { step, weights } => {
                roadtrack_cnn::centernet::write_onnx(&output, weights)?;
                if let Some(p) = &d.weights_out {
                    roadtrack::io::atomic::write_bytes_atomic(p, weights.to_json()?.as_bytes())?;
                }
                bar.suspend(|| {
                    if step < stop {
                        eprintln!("checkpoint after {step} steps: {}", output.display());
                    }
                });
            }
        }
        Ok(())
    })
    .context("training the detector")?;
    bar.finish_and_clear();
    roadtrack_cnn::centernet::write_onnx(&args.output, &weights)
        .with_context(|| format!("writing {}", args.output.display()))?;
    ui.info(format!(
        "wrote {} ({} steps{})",
        args.output.display(),
        stop,
        smooth.map_or(String::new(), |s| format!(", final loss {s:.4}"))
    ));
    Ok(())
}
