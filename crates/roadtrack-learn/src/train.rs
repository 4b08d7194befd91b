//! The training loop: focal loss on the heat map and L1 on box size and offset at object
//! centres (CenterNet), Adam with a cosine learning-rate decay, on batches of random crops
//! of simulator frames rendered by a second thread.
//!
//! Determinism: the weights come from [`TrainConfig::seed`] through roadtrack's own RNG,
//! the frames of episode `e` from simulator seed `sim_seed_base + e` and an RNG seeded from
//! both, and the trainer swaps exactly one new episode into its frame pool every
//! `refresh_every` steps whatever the renderer's speed; burn's `flex` backend computes on
//! one thread. The same config gives the same weights, byte for byte.

use std::sync::mpsc;

use burn::optim::{AdamConfig, GradientsParams};
use burn::prelude::*;
use burn::tensor::activation::{log_sigmoid, sigmoid};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use roadtrack::error::{Error, Result};

use crate::arch::{CenterNetShape, CenterNetWeights, Preprocessing, STRIDE};
use crate::data::{DataConfig, Sample, TrainFrame, make_sample, render_episode};
use crate::net::{CenterNet, Outputs};

/// Everything a training run depends on.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainConfig {
    /// Optimiser steps of the learning-rate schedule.
    pub steps: usize,
    /// Stop after this many steps (default: `steps`), the schedule unchanged: reproduces a
    /// checkpoint of a longer run.
    pub stop_after: Option<usize>,
    /// Crops per step.
    pub batch: usize,
    /// Peak Adam learning rate (cosine decay to a tenth over the run, after a 100-step
    /// warm-up).
    pub learning_rate: f64,
    /// Seed of the weights and the crops.
    pub seed: u64,
    /// Simulator seed of the first episode (then +1 per episode). Choice: 1000 and up,
    /// disjoint from the evaluation seeds 0–3.
    pub sim_seed_base: u64,
    /// Frames kept for cropping (newest episodes).
    pub pool_frames: usize,
    /// A new episode replaces the oldest frames every this many steps.
    pub refresh_every: usize,
    /// Weight of the box L1 loss against the focal loss.
    pub box_weight: f64,
    /// Network widths.
    pub shape: CenterNetShape,
    /// Rendering and cropping.
    pub data: DataConfig,
    /// Start from these weights instead of random ones (a second stage of a recipe, with
    /// its own schedule and `sim_seed_base`); their shape replaces [`TrainConfig::shape`].
    /// The optimiser starts fresh.
    pub init: Option<std::sync::Arc<CenterNetWeights>>,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            steps: 3000,
            stop_after: None,
            batch: 16,
            learning_rate: 2e-3,
            seed: 0,
            sim_seed_base: 1000,
            pool_frames: 48,
            refresh_every: 4,
            box_weight: 1.0,
            shape: CenterNetShape::default(),
            data: DataConfig::default(),
            init: None,
        }
    }
}

impl TrainConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        let bad = |f: &str, m: String| Err(Error::config("TrainConfig", f, m));
        if self.steps == 0 || self.stop_after == Some(0) {
            return bad("steps", "must be at least 1".into());
        }
        if self.batch == 0 || self.batch > 1024 {
            return bad("batch", format!("must be 1–1024, got {}", self.batch));
        }
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            return bad(
                "learning_rate",
                format!("must be > 0, got {}", self.learning_rate),
            );
        }
        let c = self.data.crop;
        if !(32..=1024).contains(&c) || !c.is_multiple_of(16) {
            return bad(
                "crop",
                format!("must be a multiple of 16 in 32–1024, got {c}"),
            );
        }
        if !(32..=4096).contains(&self.data.width) || !(32..=4096).contains(&self.data.height) {
            return bad("width/height", "must be 32–4096 px".into());
        }
        let d = &self.data;
        if d.box_class_weights
            .iter()
            .any(|w| !(w.is_finite() && (0.0..=100.0).contains(w)))
        {
            return bad(
                "box_class_weights",
                format!("each must be in [0, 100], got {:?}", d.box_class_weights),
            );
        }
        if let Some(m) = d.motorcycle_share
            && !(0.0..1.0).contains(&m)
        {
            return bad("motorcycle_share", format!("must be in [0, 1), got {m}"));
        }
        if let Some(h) = d.heavy_share
            && !(0.0..1.0).contains(&h)
        {
            return bad("heavy_share", format!("must be in [0, 1), got {h}"));
        }
        if let (Some(m), Some(h)) = (d.motorcycle_share, d.heavy_share)
            && m + h >= 1.0
        {
            return bad(
                "motorcycle_share/heavy_share",
                format!("must sum to under 1, got {m} + {h}"),
            );
        }
        if !(d.scale_range.0 > 0.0 && d.scale_range.0 < d.scale_range.1) {
            return bad(
                "scale_range",
                format!("must be 0 < min < max, got {:?}", d.scale_range),
            );
        }
        if !(0.0..=1.0).contains(&d.zoom_out_share)
            || (d.zoom_out_share > 0.0
                && !(d.zoom_out_max > d.scale_range.1 && d.zoom_out_max <= 8.0))
        {
            return bad(
                "zoom_out_share/zoom_out_max",
                format!(
                    "share must be in [0, 1] and max in (scale_range.1, 8], got {} and {}",
                    d.zoom_out_share, d.zoom_out_max
                ),
            );
        }
        if !(0.0..=1.0).contains(&d.min_in_crop) {
            return bad(
                "min_in_crop",
                format!("must be in [0, 1], got {}", d.min_in_crop),
            );
        }
        let edge_ok = (0.0..=1.0).contains(&d.edge_crop_share)
            && d.edge_crop_min_px.is_finite()
            && d.edge_crop_min_px > 0.0;
        if !edge_ok {
            return bad(
                "edge_crop_share/edge_crop_min_px",
                format!(
                    "share must be in [0, 1] and the side > 0 px, got {} and {}",
                    d.edge_crop_share, d.edge_crop_min_px
                ),
            );
        }
        if let Some(w) = &self.init {
            w.validate()?;
            if w.preprocessing != training_preprocessing() {
                return bad(
                    "init",
                    format!(
                        "the starting weights expect preprocessing {:?}, the trainer feeds {:?}",
                        w.preprocessing,
                        training_preprocessing()
                    ),
                );
            }
        }
        if self.pool_frames == 0 || self.refresh_every == 0 || self.data.frames_per_episode == 0 {
            return bad(
                "pool_frames/refresh_every/frames_per_episode",
                "must be at least 1".into(),
            );
        }
        Ok(())
    }
}

/// The network input's preprocessing, written into the ONNX metadata.
pub fn training_preprocessing() -> Preprocessing {
    Preprocessing {
        input_scale: 1.0 / 255.0,
        mean: [0.45; 3],
        std: [0.25; 3],
    }
}

/// One step's losses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepLoss {
    /// Step number, from 1.
    pub step: usize,
    /// Learning rate used.
    pub learning_rate: f64,
    /// Focal loss per object centre.
    pub heat: f32,
    /// L1 box loss per object centre.
    pub boxes: f32,
    /// `heat + box_weight · boxes`.
    pub total: f32,
}

/// What the loop reports: a step's losses, and (every `checkpoint_every` steps and at the
/// end) the weights so far.
pub enum Progress<'a> {
    /// A step is done.
    Step(StepLoss),
    /// The weights after `step` steps.
    Checkpoint {
        /// Steps done.
        step: usize,
        /// The weights.
        weights: &'a CenterNetWeights,
    },
}

fn lr_at(cfg: &TrainConfig, step: usize) -> f64 {
    let warm = 100usize.min(cfg.steps / 10).max(1);
    if step < warm {
        return cfg.learning_rate * (step + 1) as f64 / warm as f64;
    }
    let t = (step - warm) as f64 / (cfg.steps - warm).max(1) as f64;
    let floor = 0.1;
    cfg.learning_rate * (floor + (1.0 - floor) * 0.5 * (1.0 + (std::f64::consts::PI * t).cos()))
}

/// The focal and box losses of `out` against a batch's targets.
pub fn losses(out: &Outputs, batch: &Batch, device: &Device) -> (Tensor<1>, Tensor<1>) {
    let dims = batch.target_dims();
    let t = |v: &Vec<f32>| Tensor::<4>::from_data(TensorData::new(v.clone(), dims), device);
    let pos = t(&batch.pos);
    let neg_w = t(&batch.neg_weight);
    let z = out.heat_logits.clone();
    let p = sigmoid(z.clone());
    let one_minus = p.clone().neg().add_scalar(1.0);
    let pos_loss = pos * one_minus.clone() * one_minus * log_sigmoid(z.clone());
    let neg_loss = neg_w * p.clone() * p * log_sigmoid(z.neg());
    let n = batch.n_pos.max(1) as f64;
    let heat = (pos_loss + neg_loss).sum().neg().div_scalar(n);
    let reg = t(&batch.reg);
    let mask = t(&batch.reg_mask);
    let boxes = ((out.boxes.clone() - reg).abs() * mask).sum().div_scalar(n);
    (heat, boxes)
}

/// The value of a one-element tensor (a loss), NaN if it holds none.
pub fn scalar(t: Tensor<1>) -> f32 {
    t.into_data()
        .try_to_vec::<f32>()
        .ok()
        .and_then(|v| v.first().copied())
        .unwrap_or(f32::NAN)
}

/// A batch of samples, stacked.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    /// Samples.
    pub n: usize,
    /// Crop side.
    pub crop: usize,
    /// `n × 3 × S × S`.
    pub input: Vec<f32>,
    /// `n × 4 × G × G` each.
    pub pos: Vec<f32>,
    /// Negatives' weights.
    pub neg_weight: Vec<f32>,
    /// Box targets.
    pub reg: Vec<f32>,
    /// Box target mask.
    pub reg_mask: Vec<f32>,
    /// Object centres in the batch.
    pub n_pos: usize,
}

impl Batch {
    /// Stacks `samples` (all of crop side `crop`).
    pub fn stack(samples: &[Sample], crop: usize) -> Self {
        let mut b = Batch {
            n: samples.len(),
            crop,
            input: Vec::new(),
            pos: Vec::new(),
            neg_weight: Vec::new(),
            reg: Vec::new(),
            reg_mask: Vec::new(),
            n_pos: 0,
        };
        for s in samples {
            b.input.extend_from_slice(&s.input);
            b.pos.extend_from_slice(&s.pos);
            b.neg_weight.extend_from_slice(&s.neg_weight);
            b.reg.extend_from_slice(&s.reg);
            b.reg_mask.extend_from_slice(&s.reg_mask);
            b.n_pos += s.n_pos;
        }
        b
    }

    fn target_dims(&self) -> [usize; 4] {
        let g = self.crop / STRIDE;
        [self.n, 4, g, g]
    }

    /// The input tensor.
    pub fn input_tensor(&self, device: &Device) -> Tensor<4> {
        Tensor::from_data(
            TensorData::new(self.input.clone(), [self.n, 3, self.crop, self.crop]),
            device,
        )
    }
}

/// The random source an episode of simulator seed `sim_seed` is rendered with, under the
/// training seed `seed` (`TrainConfig::seed`); `examples/dump_samples.rs` draws the same.
pub fn episode_rng(seed: u64, sim_seed: u64) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(seed ^ sim_seed.wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// Renders episodes `0, 1, …` on this thread and sends them down `tx` until the receiver
/// hangs up.
fn produce(cfg: &TrainConfig, tx: &mpsc::SyncSender<Result<Vec<TrainFrame>>>) {
    for e in 0u64.. {
        let sim_seed = cfg.sim_seed_base + e;
        let mut rng = episode_rng(cfg.seed, sim_seed);
        let frames = render_episode(sim_seed, &mut rng, &cfg.data);
        if tx.send(frames).is_err() {
            return;
        }
    }
}

/// Trains a network with `cfg`, calling `progress` after every step and at checkpoints
/// (every `checkpoint_every` steps, 0 = only at the end). Returns the trained weights.
///
/// # Errors
/// An invalid config; the simulator or `progress` fails.
pub fn train(
    cfg: &TrainConfig,
    checkpoint_every: usize,
    progress: &mut dyn FnMut(Progress<'_>) -> Result<()>,
) -> Result<CenterNetWeights> {
    cfg.validate()?;
    let device = Device::flex().autodiff();
    let prep = training_preprocessing();
    let mut rng = Pcg64Mcg::seed_from_u64(cfg.seed);
    let mut model = match &cfg.init {
        Some(w) => CenterNet::from_weights(w, &device),
        None => CenterNet::init(&cfg.shape, &mut rng, &device),
    };
    let shape = cfg.init.as_ref().map_or(cfg.shape, |w| w.shape);
    let mut optim = AdamConfig::new().init();

    let (tx, rx) = mpsc::sync_channel::<Result<Vec<TrainFrame>>>(2);
    let producer_cfg = cfg.clone();
    std::thread::scope(|scope| -> Result<CenterNetWeights> {
        scope.spawn(move || produce(&producer_cfg, &tx));
        // The loop owns the receiver: on any return it hangs up, which stops the renderer
        // before the scope joins it.
        let body = move || -> Result<CenterNetWeights> {
            let recv = || -> Result<Vec<TrainFrame>> {
                rx.recv()
                    .map_err(|_| Error::Invalid("the training-data renderer stopped".into()))?
            };
            // Fill the pool.
            let mut pool: Vec<TrainFrame> = Vec::new();
            while pool.len() < cfg.pool_frames {
                pool.extend(recv()?);
            }
            let mut weights = None;
            let stop = cfg.stop_after.unwrap_or(cfg.steps).min(cfg.steps);
            for step in 0..stop {
                if step > 0 && step.is_multiple_of(cfg.refresh_every) {
                    let fresh = recv()?;
                    let n = fresh.len().min(pool.len());
                    pool.drain(..n);
                    pool.extend(fresh);
                }
                let samples: Vec<Sample> = (0..cfg.batch)
                    .map(|_| {
                        let f = &pool[rng.random_range(0..pool.len())];
                        make_sample(f, &mut rng, &cfg.data, &prep)
                    })
                    .collect();
                let batch = Batch::stack(&samples, cfg.data.crop);
                let out = model.forward(batch.input_tensor(&device));
                let (heat, boxes) = losses(&out, &batch, &device);
                let total = heat.clone() + boxes.clone().mul_scalar(cfg.box_weight);
                let grads = total.backward();
                let grads = GradientsParams::from_grads(grads, &model);
                let lr = lr_at(cfg, step);
                model = optim.step(lr, model, grads);
                let loss = StepLoss {
                    step: step + 1,
                    learning_rate: lr,
                    heat: scalar(heat),
                    boxes: scalar(boxes),
                    total: scalar(total),
                };
                if !loss.total.is_finite() {
                    return Err(Error::Invalid(format!(
                        "training diverged at step {} (loss {}); try a lower learning rate",
                        step + 1,
                        loss.total
                    )));
                }
                progress(Progress::Step(loss))?;
                let last = step + 1 == stop;
                if last || (checkpoint_every > 0 && (step + 1).is_multiple_of(checkpoint_every)) {
                    let w = model.weights(&shape, prep);
                    progress(Progress::Checkpoint {
                        step: step + 1,
                        weights: &w,
                    })?;
                    if last {
                        weights = Some(w);
                    }
                }
            }
            weights.ok_or_else(|| Error::Invalid("no training step ran".into()))
        };
        body()
    })
}
