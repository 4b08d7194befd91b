//! Writes training samples (the trainer's own crops and targets) to stdout, for a trainer
//! outside this crate (`scripts/train_gpu.py`, a GPU stage of the detector's recipe).
//!
//!     cargo run --release -p roadtrack-learn --example dump_samples -- \
//!         SIM_SEED_FIRST SIM_SEED_STEP SEED SAMPLES_PER_EPISODE [EPISODES]
//!
//! Episodes use simulator seeds `SIM_SEED_FIRST`, `+ SIM_SEED_STEP`, … (one worker per
//! residue, so that workers never render the same episode), rendered and corrupted as
//! `roadtrack_learn::train` renders them (`render_episode`, `DataConfig::default()`,
//! `train::episode_rng`). Each episode's frames join a pool of the last
//! `TrainConfig::pool_frames` (48) frames, as in the trainer, and `SAMPLES_PER_EPISODE`
//! crops are drawn from the pool (`make_sample`). Runs until `EPISODES` episodes (default:
//! until stdout closes).
//!
//! Records as `roadtrack_learn::record` writes them.
//!
//! `MOTORCYCLE_SHARE=S`, `HEAVY_SHARE=S`: the simulated vehicles' mix, as `roadtrack train
//! --detector --motorcycle-share S --heavy-share S` sets it (`DataConfig::with_mix_from`);
//! checked as the trainer checks them.
//!
//! `LOSS_OF=W.json` (or a learned detector's weights from `--weights-out`): also prints to
//! stderr burn's losses of those weights on the samples written, per object centre, as
//! `roadtrack_learn::train` computes them, to check an outside trainer's loss against
//! (`python3 scripts/train_gpu.py --check-loss DUMP --model x:W.json:0`).

use std::io::Write as _;

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use roadtrack_learn::data::{DataConfig, TrainFrame, make_sample, render_episode};
use roadtrack_learn::training_preprocessing;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 5 {
        return Err(
            "usage: dump_samples SIM_SEED_FIRST SIM_SEED_STEP SEED SAMPLES_PER_EPISODE [EPISODES]"
                .into(),
        );
    }
    let first: u64 = args[1].parse()?;
    let step: u64 = args[2].parse()?;
    let seed: u64 = args[3].parse()?;
    let per_episode: usize = args[4].parse()?;
    let episodes: u64 = match args.get(5) {
        Some(v) => v.parse()?,
        None => u64::MAX,
    };
    let data = match DataConfig::with_mix_from(|v| std::env::var(v).ok()) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("dump_samples: {e}");
            std::process::exit(1);
        }
    };
    let pool_frames = roadtrack_learn::train::TrainConfig::default().pool_frames;
    let prep = training_preprocessing();
    let mut crop_rng = Pcg64Mcg::seed_from_u64(seed ^ first.wrapping_mul(0xD1B5_4A32_D192_ED03));
    let mut pool: Vec<TrainFrame> = Vec::new();
    let loss_of = match std::env::var("LOSS_OF") {
        Ok(p) => Some(roadtrack_learn::arch::CenterNetWeights::from_json(
            &std::fs::read_to_string(&p)?,
        )?),
        Err(_) => None,
    };
    let mut kept = Vec::new();
    let mut out = std::io::BufWriter::with_capacity(1 << 20, std::io::stdout().lock());
    let s = data.crop;
    for e in 0..episodes {
        let sim_seed = first + e * step;
        let mut rng = roadtrack_learn::train::episode_rng(seed, sim_seed);
        let frames = render_episode(sim_seed, &mut rng, &data)?;
        pool.extend(frames);
        if pool.len() > pool_frames {
            pool.drain(..pool.len() - pool_frames);
        }
        for _ in 0..per_episode {
            let f = &pool[crop_rng.random_range(0..pool.len())];
            let sm = make_sample(f, &mut crop_rng, &data, &prep);
            let rec = roadtrack_learn::record::encode(&sm, s, &prep);
            if out.write_all(&rec).is_err() {
                return Ok(()); // the reader hung up
            }
            if loss_of.is_some() {
                kept.push(sm);
            }
        }
        if out.flush().is_err() {
            return Ok(());
        }
    }
    if let Some(w) = &loss_of {
        use roadtrack_learn::burn::prelude::Device;
        let device = Device::flex();
        let net = roadtrack_learn::net::CenterNet::from_weights(w, &device);
        let (mut heat, mut boxes, mut n) = (0.0f64, 0.0f64, 0usize);
        for chunk in kept.chunks(64) {
            let batch = roadtrack_learn::train::Batch::stack(chunk, s);
            let outputs = net.forward(batch.input_tensor(&device));
            let (h, b) = roadtrack_learn::train::losses(&outputs, &batch, &device);
            // `losses` divides by the batch's centres: weigh each batch back by them.
            let k = batch.n_pos.max(1);
            heat += f64::from(roadtrack_learn::train::scalar(h)) * k as f64;
            boxes += f64::from(roadtrack_learn::train::scalar(b)) * k as f64;
            n += batch.n_pos;
        }
        let n = n.max(1) as f64;
        eprintln!(
            "burn losses per object centre: heat {:.6} box {:.6} ({} samples)",
            heat / n,
            boxes / n,
            kept.len()
        );
    }
    Ok(())
}
