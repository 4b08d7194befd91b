//! Training the small person-vs-background or vehicle-vs-background classifier
//! (`roadtrack train`; METHODS.md §3 "Classifier training").
//!
//! Data come from two patch folders (positives, negatives) or from a MOTChallenge
//! sequence's ground truth (positives cut around the boxes, negatives sampled away from
//! them). The data are shuffled and split 0.8 / 0.2 into training and test sets with the
//! run's seed; training is mini-batch Adam on the cross-entropy loss. Everything random
//! draws from [`Stream::Training`], and per-sample gradients are summed in sample order,
//! so a seed gives the same network at any thread count.

use std::path::Path;

use image::RgbImage;
use rand::RngExt as _;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::net::{Adam, Cache, Shape, TinyCnn};
use super::window::{Preprocessing, sample_grid_xy};
use roadtrack::error::{Error, Result};
use roadtrack::geometry::{BBox, Point};
use roadtrack::rng::{Stream, rng, rng_for};

/// Which classifier to train; picks the paper's hyper-parameters (METHODS.md §3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// Person vs background: 30 epochs, batch 64, lr 1e-3.
    #[cfg_attr(feature = "clap", value(help = "Person vs background"))]
    Person,
    /// Vehicle vs background: 20 epochs, batch 32, lr 1e-4.
    #[cfg_attr(feature = "clap", value(help = "Vehicle vs background"))]
    Vehicle,
}

impl Preset {
    /// Whether a MOT17 ground-truth class id is this preset's target.
    pub fn is_target(self, mot17_class: u32) -> bool {
        match self {
            // Pedestrian (1) and static person (7).
            Preset::Person => matches!(mot17_class, 1 | 7),
            // Car (3), motorbike (5), non-MOT vehicle (6: trucks, buses).
            Preset::Vehicle => matches!(mot17_class, 3 | 5 | 6),
        }
    }
}

/// Training parameters. `Default` is the person preset ([`TrainConfig::preset`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// The target class.
    pub preset: Preset,
    /// Passes over the training set. Paper: person 30, vehicle 20.
    pub epochs: u32,
    /// Samples per Adam step. Paper: person 64, vehicle 32.
    pub batch_size: usize,
    /// Adam learning rate. Paper: person 1e-3, vehicle 1e-4.
    pub learning_rate: f64,
    /// Fraction of the data used for training; the rest is the test set. Paper: 0.8.
    pub train_fraction: f64,
    /// Network input height, px. Choice: person 64, vehicle 32 (paper: Inception's 299).
    pub input_height: usize,
    /// Network input width, px. Choice: person 32, vehicle 48.
    pub input_width: usize,
    /// Channels of the first convolution. Choice: 8.
    pub conv1_channels: usize,
    /// Channels of the second convolution. Choice: 16.
    pub conv2_channels: usize,
    /// Negatives sampled per positive from a sequence. Paper ratios: person 2 (900 /
    /// 1800), vehicle 1 (5000 / 5000).
    pub negatives_per_positive: f64,
    /// At most this many positives are drawn from a sequence (seeded subset).
    /// Choice: person 900, vehicle 5000 (the paper's data-set sizes).
    pub max_positives: usize,
    /// Ground-truth boxes less visible than this are not used as positives. Choice: 0.5.
    pub min_visibility: f64,
    /// A negative window may overlap any ground-truth box by at most this IoU. Choice: 0.1.
    pub max_negative_iou: f64,
    /// Random seed (weights, shuffling, split, negative sampling).
    pub seed: u64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self::preset(Preset::Person)
    }
}

impl TrainConfig {
    /// The paper's hyper-parameters for `preset` (METHODS.md §3).
    pub fn preset(preset: Preset) -> Self {
        let person = preset == Preset::Person;
        Self {
            preset,
            epochs: if person { 30 } else { 20 },
            batch_size: if person { 64 } else { 32 },
            learning_rate: if person { 1e-3 } else { 1e-4 },
            train_fraction: 0.8,
            input_height: if person { 64 } else { 32 },
            input_width: if person { 32 } else { 48 },
            conv1_channels: 8,
            conv2_channels: 16,
            negatives_per_positive: if person { 2.0 } else { 1.0 },
            max_positives: if person { 900 } else { 5000 },
            min_visibility: 0.5,
            max_negative_iou: 0.1,
            seed: 0,
        }
    }

    /// The network shape.
    pub fn shape(&self) -> Shape {
        Shape {
            height: self.input_height,
            width: self.input_width,
            c1: self.conv1_channels,
            c2: self.conv2_channels,
        }
    }

    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        let bad = |field, reason: String| Err(Error::config("TrainConfig", field, reason));
        if self.epochs == 0 {
            return bad("epochs", "must be at least 1".into());
        }
        if self.batch_size == 0 {
            return bad("batch_size", "must be at least 1".into());
        }
        if !(self.learning_rate > 0.0 && self.learning_rate.is_finite()) {
            return bad(
                "learning_rate",
                format!("must be positive, got {}", self.learning_rate),
            );
        }
        if !(self.train_fraction > 0.0 && self.train_fraction < 1.0) {
            return bad(
                "train_fraction",
                format!("must be in (0, 1), got {}", self.train_fraction),
            );
        }
        if !self.shape().is_valid() {
            return bad(
                "input_height",
                "input must be at least 10×10 px and channels positive".into(),
            );
        }
        for (v, f) in [
            (self.min_visibility, "min_visibility"),
            (self.max_negative_iou, "max_negative_iou"),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return bad(f, format!("must be in [0, 1], got {v}"));
            }
        }
        if !(self.negatives_per_positive >= 0.0 && self.negatives_per_positive.is_finite()) {
            return bad("negatives_per_positive", "must be non-negative".into());
        }
        // Sizes are bounded before anything is allocated (docs/FORMATS.md, Limits).
        use roadtrack::limits as l;
        l::at_most(self.epochs, l::MAX_ITERATIONS, "epochs")
            .map_err(|m| Error::config("TrainConfig", "epochs", m))?;
        for (v, max, f) in [
            (self.input_height, l::MAX_CNN_INPUT_SIDE, "input_height"),
            (self.input_width, l::MAX_CNN_INPUT_SIDE, "input_width"),
            (self.batch_size, l::MAX_BATCH_SIZE, "batch_size"),
            (self.conv1_channels, l::MAX_CNN_CHANNELS, "conv1_channels"),
            (self.conv2_channels, l::MAX_CNN_CHANNELS, "conv2_channels"),
            (self.max_positives, l::MAX_PATCHES, "max_positives"),
        ] {
            l::at_most(v, max, f).map_err(|m| Error::config("TrainConfig", f, m))?;
        }
        l::at_most(
            self.batch_size * self.input_height * self.input_width,
            l::MAX_BATCH_PIXELS,
            "batch_size × input_height × input_width",
        )
        .map_err(|m| Error::config("TrainConfig", "batch_size", m))?;
        l::at_most(
            self.negatives_per_positive,
            l::MAX_NEGATIVES_PER_POSITIVE,
            "negatives_per_positive",
        )
        .map_err(|m| Error::config("TrainConfig", "negatives_per_positive", m))?;
        Ok(())
    }
}

/// Labelled patches, preprocessed, at the network's input size.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Patches {
    /// Patch height, px.
    pub height: usize,
    /// Patch width, px.
    pub width: usize,
    /// `len · 3 · height · width` values, planar CHW per patch.
    pub data: Vec<f32>,
    /// 1 = target, 0 = background, one per patch.
    pub labels: Vec<u8>,
    /// Median image px per model px of the positives cut from a sequence (the tracker's
    /// window scale), when known.
    pub window_scale: Option<f64>,
}

impl Patches {
    /// Number of patches.
    pub fn len(&self) -> usize {
        self.labels.len()
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }
    /// Patch `i`.
    pub fn patch(&self, i: usize) -> &[f32] {
        let n = 3 * self.height * self.width;
        &self.data[i * n..(i + 1) * n]
    }
    /// Appends the `rect` of `image` stretched to the patch size, preprocessed, as `label`.
    pub fn push_stretched(
        &mut self,
        image: &RgbImage,
        rect: BBox,
        label: u8,
        prep: &Preprocessing,
    ) {
        let n = 3 * self.height * self.width;
        let start = self.data.len();
        self.data.resize(start + n, 0.0);
        let (sx, sy) = (
            rect.width / self.width as f64,
            rect.height / self.height as f64,
        );
        sample_grid_xy(
            image,
            (rect.left + 0.5 * sx - 0.5, rect.top + 0.5 * sy - 0.5),
            (sx, sy),
            (self.width, self.height),
            prep,
            &mut self.data[start..],
        );
        self.labels.push(label);
    }
}

/// The preprocessing of networks trained here (written into their ONNX metadata).
/// Choice: `(pixel/255 − 0.5) / 0.25`, inputs in `[−2, 2]`, for well-scaled gradients.
pub fn training_preprocessing() -> Preprocessing {
    Preprocessing {
        input_scale: 1.0 / 255.0,
        mean: [0.5; 3],
        std: [0.25; 3],
    }
}

fn load_image(path: &Path) -> Result<RgbImage> {
    image::open(path)
        .map(|i| i.to_rgb8())
        .map_err(|source| Error::Image {
            source,
            path: path.to_path_buf(),
        })
}

/// Reads every image in `positives` (label 1) and `negatives` (label 0), each stretched to
/// `height × width`.
pub fn patches_from_folders(
    positives: &Path,
    negatives: &Path,
    height: usize,
    width: usize,
) -> Result<Patches> {
    let prep = training_preprocessing();
    let mut patches = Patches {
        height,
        width,
        ..Default::default()
    };
    for (dir, label) in [(positives, 1u8), (negatives, 0u8)] {
        let files = roadtrack::io::source::list_images(dir)?;
        if files.is_empty() {
            return Err(Error::format(dir, "no .png/.jpg images in this folder"));
        }
        for f in files {
            let img = load_image(&f)?;
            let rect = BBox::new(0.0, 0.0, f64::from(img.width()), f64::from(img.height()));
            patches.push_stretched(&img, rect, label, &prep);
        }
    }
    Ok(patches)
}

/// Cuts positives around a MOTChallenge sequence's ground-truth boxes of the preset's class
/// and samples negatives away from every ground-truth box (seeded).
///
/// A positive is the window of the network's aspect centred on the box centre and just
/// covering the box (the tracker's window at that object's scale); a negative is a window
/// of a random positive's size at a uniform position whose IoU with every box of its frame
/// is at most `max_negative_iou`.
pub fn patches_from_sequence(sequence: &Path, config: &TrainConfig) -> Result<Patches> {
    config.validate()?;
    let gt_path = sequence.join("gt").join("gt.txt");
    let gt = roadtrack::io::mot::read_gt(&gt_path)?;
    let (h, w) = (config.input_height as f64, config.input_width as f64);
    let mut candidates: Vec<usize> = (0..gt.len())
        .filter(|&i| {
            let r = &gt[i];
            r.consider
                && config.preset.is_target(r.class)
                && r.visibility >= config.min_visibility
                && r.bbox.width >= 4.0
                && r.bbox.height >= 4.0
        })
        .collect();
    if candidates.is_empty() {
        return Err(Error::format(
            &gt_path,
            format!(
                "no ground-truth boxes of the {:?} class to train on",
                config.preset
            ),
        ));
    }
    let mut r = rng(config.seed, Stream::Training);
    // Seeded subset (partial Fisher–Yates), then back in file order.
    let keep = candidates.len().min(config.max_positives);
    for i in 0..keep {
        let j = r.random_range(i..candidates.len());
        candidates.swap(i, j);
    }
    candidates.truncate(keep);
    candidates.sort_unstable();
    let mut wanted: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
    for &i in &candidates {
        wanted.entry(gt[i].frame).or_default().push(i);
    }
    let boxes_of = |frame: u32| gt.iter().filter(move |r| r.frame == frame).map(|r| r.bbox);

    let prep = training_preprocessing();
    let mut patches = Patches {
        height: config.input_height,
        width: config.input_width,
        ..Default::default()
    };
    let mut scales = Vec::new();
    let mut negatives_due = 0.0;
    let source = roadtrack::io::source::open(sequence, &Default::default())?;
    for frame in source {
        let frame = frame?;
        let Some(rows) = wanted.get(&frame.index) else {
            continue;
        };
        let (iw, ih) = (
            f64::from(frame.image.width()),
            f64::from(frame.image.height()),
        );
        let mut sizes = Vec::new();
        for &i in rows {
            let b = gt[i].bbox;
            let scale = (b.height / h).max(b.width / w);
            let window = BBox::from_centre(b.centre(), w * scale, h * scale);
            patches.push_stretched(&frame.image, window, 1, &prep);
            scales.push(scale);
            sizes.push((w * scale, h * scale));
        }
        let all: Vec<BBox> = boxes_of(frame.index).collect();
        let mut fr = rng_for(config.seed, Stream::Training, u64::from(frame.index));
        negatives_due += config.negatives_per_positive * rows.len() as f64;
        while negatives_due >= 1.0 {
            negatives_due -= 1.0;
            let (ww, wh) = sizes[fr.random_range(0..sizes.len())];
            // Choice: up to 50 tries per negative; a crowded frame may yield fewer.
            for _ in 0..50 {
                let c = Point::new(
                    fr.random_range(0.0..iw.max(1.0)),
                    fr.random_range(0.0..ih.max(1.0)),
                );
                let window = BBox::from_centre(c, ww, wh);
                if all
                    .iter()
                    .all(|b| b.iou(&window) <= config.max_negative_iou)
                {
                    patches.push_stretched(&frame.image, window, 0, &prep);
                    break;
                }
            }
        }
    }
    scales.sort_by(f64::total_cmp);
    patches.window_scale = scales.get(scales.len() / 2).copied();
    Ok(patches)
}

/// Progress of a training run, reported after every batch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainProgress {
    /// 1-based epoch.
    pub epoch: u32,
    /// Batches done so far over the whole run.
    pub batches_done: u64,
    /// Batches in the whole run.
    pub batches_total: u64,
    /// Mean loss of the last batch.
    pub batch_loss: f64,
}

/// Statistics of one epoch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EpochStats {
    /// 1-based epoch.
    pub epoch: u32,
    /// Mean cross-entropy over the training set during the epoch.
    pub train_loss: f64,
    /// Accuracy on the test set after the epoch (threshold 0.5).
    pub test_accuracy: f64,
}

/// What a training run produced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrainReport {
    /// Training patches (positives + negatives).
    pub n_train: usize,
    /// Test patches.
    pub n_test: usize,
    /// Positive patches in all.
    pub n_positive: usize,
    /// Negative patches in all.
    pub n_negative: usize,
    /// One row per epoch.
    pub epochs: Vec<EpochStats>,
    /// Final test accuracy (the paper reports 0.972 person, 0.997 vehicle with Inception).
    pub test_accuracy: f64,
}

/// Accuracy of `net` on the patches `indices` (class 1 when p ≥ 0.5).
pub fn accuracy(net: &TinyCnn, patches: &Patches, indices: &[usize]) -> f64 {
    if indices.is_empty() {
        return 0.0;
    }
    let correct: usize = indices
        .par_iter()
        .map_init(Cache::default, |cache, &i| {
            net.forward(patches.patch(i), cache);
            usize::from(u8::from(cache.probs[1] >= 0.5) == patches.labels[i])
        })
        .sum();
    correct as f64 / indices.len() as f64
}

/// Trains a [`TinyCnn`] on `patches` (see the module docs) and reports test accuracy.
///
/// # Errors
/// Invalid config, patches of another size, or fewer than 2 patches of either class.
pub fn train(
    patches: &Patches,
    config: &TrainConfig,
    progress: &mut dyn FnMut(TrainProgress),
) -> Result<(TinyCnn, TrainReport)> {
    config.validate()?;
    if (patches.height, patches.width) != (config.input_height, config.input_width) {
        return Err(Error::Invalid(format!(
            "patches are {}×{} px but the network input is {}×{}",
            patches.height, patches.width, config.input_height, config.input_width
        )));
    }
    let n_positive = patches.labels.iter().filter(|&&l| l == 1).count();
    let n_negative = patches.len() - n_positive;
    if n_positive < 2 || n_negative < 2 {
        return Err(Error::Invalid(format!(
            "need at least 2 positive and 2 negative patches, got {n_positive} and {n_negative}"
        )));
    }
    let mut r = rng(config.seed, Stream::Training);
    let mut order: Vec<usize> = (0..patches.len()).collect();
    for i in (1..order.len()).rev() {
        let j = r.random_range(0..=i);
        order.swap(i, j);
    }
    let n_train = ((patches.len() as f64 * config.train_fraction).round() as usize)
        .clamp(1, patches.len() - 1);
    let (train_idx, test_idx) = order.split_at(n_train);
    let mut train_idx = train_idx.to_vec();
    let test_idx = test_idx.to_vec();

    let mut net = TinyCnn::new(config.shape(), &mut r);
    let mut adam = Adam::new(net.params.len(), config.learning_rate);
    let n_params = net.params.len();
    let batches_per_epoch = train_idx.len().div_ceil(config.batch_size) as u64;
    let batches_total = batches_per_epoch * u64::from(config.epochs);
    let mut batches_done = 0;
    let mut epochs = Vec::new();
    for epoch in 1..=config.epochs {
        let mut er = rng_for(config.seed, Stream::Training, u64::from(epoch));
        for i in (1..train_idx.len()).rev() {
            let j = er.random_range(0..=i);
            train_idx.swap(i, j);
        }
        let mut epoch_loss = 0.0;
        for batch in train_idx.chunks(config.batch_size) {
            // Per-sample gradients in parallel, summed in sample order: deterministic.
            let per_sample: Vec<(f64, Vec<f32>)> = batch
                .par_iter()
                .map_init(Cache::default, |cache, &i| {
                    let mut g = vec![0.0f32; n_params];
                    let loss = net.accumulate_gradient(
                        patches.patch(i),
                        usize::from(patches.labels[i]),
                        cache,
                        &mut g,
                    );
                    (loss, g)
                })
                .collect();
            let mut grad = vec![0.0f32; n_params];
            let mut loss = 0.0;
            for (l, g) in &per_sample {
                loss += l;
                for (a, b) in grad.iter_mut().zip(g) {
                    *a += b;
                }
            }
            let scale = 1.0 / batch.len() as f32;
            grad.iter_mut().for_each(|g| *g *= scale);
            adam.step(&mut net.params, &grad);
            epoch_loss += loss;
            batches_done += 1;
            progress(TrainProgress {
                epoch,
                batches_done,
                batches_total,
                batch_loss: loss / batch.len() as f64,
            });
        }
        epochs.push(EpochStats {
            epoch,
            train_loss: epoch_loss / train_idx.len() as f64,
            test_accuracy: accuracy(&net, patches, &test_idx),
        });
    }
    let test_accuracy = epochs.last().map_or(0.0, |e| e.test_accuracy);
    Ok((
        net,
        TrainReport {
            n_train: train_idx.len(),
            n_test: test_idx.len(),
            n_positive,
            n_negative,
            epochs,
            test_accuracy,
        },
    ))
}

/// A learnable synthetic data set for tests and benchmarks: positives hold a bright
/// upright bar (a "person") on noise, negatives only noise. Seeded.
pub fn synthetic_patches(n_each: usize, height: usize, width: usize, seed: u64) -> Patches {
    let mut r = rng(seed, Stream::Synthetic);
    let prep = training_preprocessing();
    let mut patches = Patches {
        height,
        width,
        ..Default::default()
    };
    for k in 0..2 * n_each {
        let label = u8::from(k % 2 == 0);
        let img = RgbImage::from_fn(width as u32, height as u32, |x, y| {
            let noise: u8 = r.random_range(40..120);
            let bar = label == 1
                && (x as usize) >= width / 3
                && (x as usize) < width - width / 3
                && (y as usize) >= height / 8
                && (y as usize) < height - height / 8;
            if bar {
                image::Rgb([220, 200 + noise / 4, 180])
            } else {
                image::Rgb([noise, noise / 2 + 30, noise])
            }
        });
        let rect = BBox::new(0.0, 0.0, width as f64, height as f64);
        patches.push_stretched(&img, rect, label, &prep);
    }
    patches
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_rejects_every_non_finite_float() {
        type Field = fn(&mut TrainConfig) -> &mut f64;
        let fields: [(&str, Field); 5] = [
            ("learning_rate", |c| &mut c.learning_rate),
            ("train_fraction", |c| &mut c.train_fraction),
            ("negatives_per_positive", |c| &mut c.negatives_per_positive),
            ("min_visibility", |c| &mut c.min_visibility),
            ("max_negative_iou", |c| &mut c.max_negative_iou),
        ];
        for (name, field) in fields {
            for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut c = TrainConfig::default();
                *field(&mut c) = x;
                match c.validate() {
                    Err(Error::InvalidConfig { field: f, .. }) => assert_eq!(f, name),
                    other => panic!("{name} = {x}: {other:?}"),
                }
            }
        }
    }

    fn quick() -> TrainConfig {
        TrainConfig {
            epochs: 3,
            batch_size: 8,
            learning_rate: 1e-2,
            input_height: 16,
            input_width: 12,
            conv1_channels: 4,
            conv2_channels: 6,
            seed: 5,
            ..TrainConfig::default()
        }
    }

    #[test]
    fn defaults_are_the_papers() {
        let p = TrainConfig::preset(Preset::Person);
        assert_eq!(
            (p.epochs, p.batch_size, p.learning_rate, p.train_fraction),
            (30, 64, 1e-3, 0.8)
        );
        let v = TrainConfig::preset(Preset::Vehicle);
        assert_eq!(
            (v.epochs, v.batch_size, v.learning_rate, v.train_fraction),
            (20, 32, 1e-4, 0.8)
        );
        assert_eq!(TrainConfig::default(), p);
    }

    #[test]
    fn training_learns_a_separable_task() -> Result<()> {
        let cfg = quick();
        let data = synthetic_patches(40, 16, 12, 1);
        let mut calls = 0;
        let (_, report) = train(&data, &cfg, &mut |_| calls += 1)?;
        assert_eq!(report.n_train + report.n_test, 80);
        assert_eq!(report.n_test, 16);
        assert_eq!(calls, 3 * 64usize.div_ceil(8));
        assert!(report.test_accuracy >= 0.9, "{report:?}");
        Ok(())
    }

    #[test]
    fn training_is_deterministic_at_any_thread_count() -> Result<()> {
        let cfg = TrainConfig {
            epochs: 1,
            ..quick()
        };
        let data = synthetic_patches(12, 16, 12, 2);
        let (a, _) = train(&data, &cfg, &mut |_| {})?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool");
        let (b, _) = pool.install(|| train(&data, &cfg, &mut |_| {}))?;
        assert_eq!(a.params, b.params);
        let (c, _) = train(&data, &TrainConfig { seed: 6, ..cfg }, &mut |_| {})?;
        assert_ne!(a.params, c.params);
        Ok(())
    }

    #[test]
    fn one_class_data_is_rejected() {
        let mut data = synthetic_patches(4, 16, 12, 3);
        data.labels.iter_mut().for_each(|l| *l = 1);
        assert!(train(&data, &quick(), &mut |_| {}).is_err());
    }
}
