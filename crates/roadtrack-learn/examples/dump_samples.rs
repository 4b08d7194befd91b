//! Writes training samples (the trainer's own crops and targets) to stdout, for a trainer
//! outside this crate (`scripts/train_gpu.py`, a GPU stage of the detector's recipe).
//!
//!     cargo run --release -p roadtrack-learn --example dump_samples -- \
//!         SIM_SEED_FIRST SIM_SEED_STEP SEED SAMPLES_PER_EPISODE [EPISODES]
//!
//! Episodes use simulator seeds `SIM_SEED_FIRST`, `+ SIM_SEED_STEP`, … (one worker per
//! residue, so that workers never render the same episode), rendered and corrupted as
//! `roadtrack_learn::train` renders them (`render_episode`, `DataConfig::default()`). Each
//! episode's frames join a pool of the last 48 frames, as in the trainer, and
//! `SAMPLES_PER_EPISODE` crops are drawn from the pool (`make_sample`). Runs until
//! `EPISODES` episodes (default: until stdout closes).
//!
//! Record, little-endian: `b"RTS1"`, `u32` crop side S, `u32` P (positives), `u32` R (box
//! cells), `u32` n_pos; the input as `3 × S × S` `u8` (the crop's 0–255 values, undoing the
//! preprocessing); the negatives' weights `4 × G × G` `f32` (G = S / 4); P `u32` indices
//! into `4 × G × G` where `pos` is 1; R entries of `u32` cell index into `G × G` and 4 `f32`
//! (`ln(w/4)`, `ln(h/4)`, `dx`, `dy`).

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
    let data = DataConfig::default();
    let prep = training_preprocessing();
    let mut crop_rng = Pcg64Mcg::seed_from_u64(seed ^ first.wrapping_mul(0xD1B5_4A32_D192_ED03));
    let mut pool: Vec<TrainFrame> = Vec::new();
    let mut out = std::io::BufWriter::with_capacity(1 << 20, std::io::stdout().lock());
    let s = data.crop;
    let g = s / roadtrack_learn::arch::STRIDE;
    for e in 0..episodes {
        let sim_seed = first + e * step;
        // The trainer's per-episode RNG (`train::produce`).
        let mut rng = Pcg64Mcg::seed_from_u64(seed ^ sim_seed.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let frames = render_episode(sim_seed, &mut rng, &data)?;
        pool.extend(frames);
        if pool.len() > 48 {
            pool.drain(..pool.len() - 48);
        }
        for _ in 0..per_episode {
            let f = &pool[crop_rng.random_range(0..pool.len())];
            let sm = make_sample(f, &mut crop_rng, &data, &prep);
            let pos: Vec<u32> = (0..sm.pos.len())
                .filter(|&i| sm.pos[i] != 0.0)
                .map(|i| i as u32)
                .collect();
            let cells: Vec<u32> = (0..g * g)
                .filter(|&i| sm.reg_mask[i] != 0.0)
                .map(|i| i as u32)
                .collect();
            let mut rec = Vec::with_capacity(20 + 3 * s * s + 16 * g * g + 4 * pos.len());
            rec.extend_from_slice(b"RTS1");
            for v in [
                s as u32,
                pos.len() as u32,
                cells.len() as u32,
                sm.n_pos as u32,
            ] {
                rec.extend_from_slice(&v.to_le_bytes());
            }
            for (i, &x) in sm.input.iter().enumerate() {
                let c = i / (s * s);
                let px = (x * prep.std[c] + prep.mean[c]) / prep.input_scale;
                rec.push(px.round().clamp(0.0, 255.0) as u8);
            }
            for &w in &sm.neg_weight {
                rec.extend_from_slice(&w.to_le_bytes());
            }
            for &p in &pos {
                rec.extend_from_slice(&p.to_le_bytes());
            }
            for &c in &cells {
                rec.extend_from_slice(&c.to_le_bytes());
                for k in 0..4 {
                    rec.extend_from_slice(&sm.reg[k * g * g + c as usize].to_le_bytes());
                }
            }
            if out.write_all(&rec).is_err() {
                return Ok(()); // the reader hung up
            }
        }
        if out.flush().is_err() {
            return Ok(());
        }
    }
    Ok(())
}
