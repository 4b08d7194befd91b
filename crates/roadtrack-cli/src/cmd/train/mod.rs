//! `roadtrack train`: train the small CNN classifier used as a likelihood (METHODS.md §3).

/// `roadtrack train --detector`: the learned detector (crate roadtrack-learn).
pub mod detector;

use crate::common::Ui;
#[cfg(feature = "cnn")]
use anyhow::Context;
use anyhow::{Result, bail};
use roadtrack::limits::MAX_CNN_INPUT_SIDE;
#[cfg(feature = "cnn")]
use roadtrack_cnn::train::{
    Preset, TrainConfig, patches_from_folders, patches_from_sequence, train,
};
use std::path::PathBuf;

/// Train a person-vs-background or vehicle-vs-background CNN and write it as ONNX.
///
/// Data come from two folders of patches (`--positives`, `--negatives`) or from a
/// MOTChallenge sequence's ground truth (`--sequence`: positives around the boxes, negatives
/// sampled away from them). 80 % trains, 20 % tests; the paper's epochs, batch size and
/// learning rate are the defaults of each `--preset`. The written model loads in the tracker
/// like any ONNX classifier (its preprocessing and window scale are in its metadata).
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack train --positives patches/person --negatives patches/background -o person.onnx\n  roadtrack train --sequence MOT17-09 --preset person --seed 1 -o person.onnx"
)]
pub struct Args {
    /// Folder of target-class patch images (.png/.jpg, any size; stretched to the input).
    #[arg(
        long,
        value_name = "DIR",
        requires = "negatives",
        conflicts_with = "sequence"
    )]
    pub positives: Option<PathBuf>,
    /// Folder of background patch images.
    #[arg(long, value_name = "DIR", requires = "positives")]
    pub negatives: Option<PathBuf>,
    /// MOTChallenge sequence folder with gt/gt.txt to cut patches from.
    #[arg(long, value_name = "SEQ", required_unless_present_any = ["positives", "detector"])]
    pub sequence: Option<PathBuf>,
    /// Train the learned object detector (`--detector cnn`) on simulator renders instead
    /// of a classifier (docs/DETECTION.md "Learned detector").
    #[arg(long, conflicts_with_all = ["positives", "negatives", "sequence", "epochs", "train_fraction", "input_size", "max_positives", "report"])]
    pub detector: bool,
    #[command(flatten)]
    pub detector_args: detector::DetectorTrainArgs,
    /// Output ONNX model (--detector: written at every checkpoint too).
    #[arg(short, long, default_value = "model.onnx")]
    pub output: PathBuf,
    /// Target class and the paper's hyper-parameters for it.
    #[arg(long, value_enum, default_value_t = Preset::Person)]
    pub preset: Preset,
    /// Epochs (preset: person 30, vehicle 20).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub epochs: Option<u32>,
    /// Batch size (preset: person 64, vehicle 32).
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub batch_size: Option<usize>,
    /// Adam learning rate (preset: person 1e-3, vehicle 1e-4).
    #[arg(long, value_name = "R", value_parser = crate::flags::positive)]
    pub learning_rate: Option<f64>,
    /// Fraction of patches used for training; the rest tests (default 0.8).
    #[arg(long, value_name = "F", value_parser = crate::flags::open_fraction)]
    pub train_fraction: Option<f64>,
    /// Network input HEIGHTxWIDTH in px, each side 10–1024 (preset: person 64x32,
    /// vehicle 32x48).
    #[arg(long, value_name = "HxW", value_parser = parse_size)]
    pub input_size: Option<(usize, usize)>,
    /// Most positives drawn from a sequence (preset: person 900, vehicle 5000).
    #[arg(long, value_name = "N", requires = "sequence", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub max_positives: Option<usize>,
    /// Random seed (weights, shuffling, split, negatives).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also write the training report (per-epoch loss and test accuracy) as JSON.
    #[arg(long, value_name = "F.json")]
    pub report: Option<PathBuf>,
}

/// `--preset` values without the `cnn` feature: there is no trainer then, nor
/// `roadtrack_cnn::train::Preset`, but the command line stays the same.
#[cfg(not(feature = "cnn"))]
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Preset {
    /// Person vs background.
    Person,
    /// Vehicle vs background.
    Vehicle,
}

/// Parses `HEIGHTxWIDTH` with each side in `10..=`[`MAX_CNN_INPUT_SIDE`] (a usage error
/// otherwise, before anything is allocated).
fn parse_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (h, w) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected HEIGHTxWIDTH, e.g. 64x32, found {s:?}"))?;
    let side = |v: &str| -> std::result::Result<usize, String> {
        let n: usize = v
            .trim()
            .parse()
            .map_err(|_| format!("{v:?} is not a whole number of pixels"))?;
        if (10..=MAX_CNN_INPUT_SIDE).contains(&n) {
            Ok(n)
        } else {
            Err(format!(
                "each side must be 10–{MAX_CNN_INPUT_SIDE} px (docs/FORMATS.md, Limits), found {n}"
            ))
        }
    };
    Ok((side(h)?, side(w)?))
}

/// Without the `cnn` feature there is no trainer: fail before reading any data.
#[cfg(not(feature = "cnn"))]
pub fn run(args: Args, ui: &Ui) -> Result<()> {
    if args.detector {
        return detector::run(&args, ui);
    }
    detector::reject_detector_flags(&args.detector_args)?;
    bail!(NO_CNN)
}

#[cfg(feature = "cnn")]
pub fn run(args: Args, ui: &Ui) -> Result<()> {
    if args.detector {
        return detector::run(&args, ui);
    }
    detector::reject_detector_flags(&args.detector_args)?;
    let mut config = TrainConfig::preset(args.preset);
    config.seed = args.seed;
    if let Some(v) = args.epochs {
        config.epochs = v;
    }
    if let Some(v) = args.batch_size {
        config.batch_size = v;
    }
    if let Some(v) = args.learning_rate {
        config.learning_rate = v;
    }
    if let Some(v) = args.train_fraction {
        config.train_fraction = v;
    }
    if let Some(v) = args.max_positives {
        config.max_positives = v;
    }
    if let Some((h, w)) = args.input_size {
        config.input_height = h;
        config.input_width = w;
    }
    crate::flags::check_overrides(
        config.validate(),
        &[
            ("epochs", "--epochs", args.epochs.is_some()),
            ("batch_size", "--batch-size", args.batch_size.is_some()),
            (
                "learning_rate",
                "--learning-rate",
                args.learning_rate.is_some(),
            ),
            (
                "train_fraction",
                "--train-fraction",
                args.train_fraction.is_some(),
            ),
            ("input_height", "--input-size", args.input_size.is_some()),
        ],
        None,
    )?;

    let patches = match (&args.positives, &args.negatives, &args.sequence) {
        (Some(p), Some(n), None) => {
            patches_from_folders(p, n, config.input_height, config.input_width)?
        }
        (None, None, Some(seq)) => {
            ui.info(format!("cutting patches from {}…", seq.display()));
            patches_from_sequence(seq, &config)?
        }
        _ => bail!("give --positives and --negatives, or --sequence"),
    };
    let n_pos = patches.labels.iter().filter(|&&l| l == 1).count();
    ui.info(format!(
        "{} patches ({} positive, {} negative), {}×{} px; {} epochs, batch {}, lr {}",
        patches.len(),
        n_pos,
        patches.len() - n_pos,
        config.input_height,
        config.input_width,
        config.epochs,
        config.batch_size,
        config.learning_rate
    ));
    let bar = ui.progress(None, "train");
    let (net, report) = train(&patches, &config, &mut |p| {
        if bar.length().is_none() {
            bar.set_length(p.batches_total);
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{msg:>10} [{bar:30}] {pos}/{len} batches, eta {eta}",
            ) {
                bar.set_style(style.progress_chars("=> "));
            }
        }
        bar.set_position(p.batches_done);
        bar.set_message(format!("epoch {}", p.epoch));
    })?;
    bar.finish_and_clear();
    for e in &report.epochs {
        ui.detail(format!(
            "epoch {:>3}: train loss {:.4}, test accuracy {:.4}",
            e.epoch, e.train_loss, e.test_accuracy
        ));
    }
    write_model(&args.output, &net, patches.window_scale)
        .with_context(|| format!("writing {}", args.output.display()))?;
    if let Some(path) = &args.report {
        let json = serde_json::to_string_pretty(&report)? + "\n";
        roadtrack::io::atomic::write_bytes_atomic(path, json.as_bytes())?;
    }
    ui.info(format!(
        "test accuracy {:.4} on {} patches (trained on {}); wrote {}",
        report.test_accuracy,
        report.n_test,
        report.n_train,
        args.output.display()
    ));
    Ok(())
}

/// The error of a build without the `cnn` feature.
#[cfg(not(feature = "cnn"))]
const NO_CNN: &str = "roadtrack was built without the `cnn` feature, which writes ONNX models \
                      (cargo build -p roadtrack-cli --features cnn)";

/// Writes the trained network as ONNX.
#[cfg(feature = "cnn")]
fn write_model(
    path: &std::path::Path,
    net: &roadtrack_cnn::net::TinyCnn,
    window_scale: Option<f64>,
) -> Result<()> {
    roadtrack_cnn::export::write_onnx(
        path,
        net,
        &roadtrack_cnn::train::training_preprocessing(),
        window_scale,
    )?;
    Ok(())
}
