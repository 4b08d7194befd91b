//! Trains the detector without the command line (no tract in the build): writes the weights
//! as JSON at every checkpoint; `roadtrack train --detector` does the same and writes ONNX.
//!
//!     cargo run --release -p roadtrack-learn --example train_detector -- STEPS SEED OUT.json [LOG.csv]
//!
//! Environment: `INIT=W.json` starts from those weights, `SIM_SEED_BASE=N` renders episodes
//! from simulator seed N (default 1000), `LEARNING_RATE=X` sets the peak rate, `BOX_WEIGHT=X` the box loss's weight, `CLIP_TO_CROP=1` boxes clipped to the crop, `EDGE_CROP_SHARE=X` that share of crops cutting an object,
//! `BOX_CLASS_WEIGHTS=a,b,c,d` the box loss's weight per class (a second
//! stage of a recipe; `roadtrack train --detector --init --sim-seed-base --learning-rate`).

use std::io::Write as _;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        return Err("usage: train_detector STEPS SEED OUT.json [LOG.csv]".into());
    }
    let mut cfg = roadtrack_learn::TrainConfig {
        steps: args[1].parse()?,
        seed: args[2].parse()?,
        ..Default::default()
    };
    if let Ok(p) = std::env::var("INIT") {
        let text = std::fs::read_to_string(&p)?;
        cfg.init = Some(std::sync::Arc::new(
            roadtrack_learn::arch::CenterNetWeights::from_json(&text)?,
        ));
    }
    if let Ok(v) = std::env::var("SIM_SEED_BASE") {
        cfg.sim_seed_base = v.parse()?;
    }
    if let Ok(v) = std::env::var("LEARNING_RATE") {
        cfg.learning_rate = v.parse()?;
    }
    if let Ok(v) = std::env::var("CLIP_TO_CROP") {
        cfg.data.clip_to_crop = v == "1";
    }
    if let Ok(v) = std::env::var("EDGE_CROP_SHARE") {
        cfg.data.edge_crop_share = v.parse()?;
    }
    if let Ok(v) = std::env::var("BOX_CLASS_WEIGHTS") {
        let w: Vec<f32> = v.split(',').map(str::parse).collect::<Result<_, _>>()?;
        if w.len() != cfg.data.box_class_weights.len() {
            return Err(format!("BOX_CLASS_WEIGHTS: four weights, got {v}").into());
        }
        cfg.data.box_class_weights.copy_from_slice(&w);
    }
    if let Ok(v) = std::env::var("BOX_WEIGHT") {
        cfg.box_weight = v.parse()?;
    }
    let out = std::path::PathBuf::from(&args[3]);
    let mut log = match args.get(4) {
        Some(p) => Some(std::io::BufWriter::new(std::fs::File::create(p)?)),
        None => None,
    };
    let start = std::time::Instant::now();
    roadtrack_learn::train(&cfg, 100, &mut |p| {
        match p {
            roadtrack_learn::Progress::Step(l) => {
                if let Some(w) = &mut log {
                    writeln!(
                        w,
                        "{},{:.1},{},{},{},{}",
                        l.step,
                        start.elapsed().as_secs_f64(),
                        l.learning_rate,
                        l.heat,
                        l.boxes,
                        l.total
                    )
                    .and_then(|_| w.flush())
                    .map_err(|e| roadtrack::Error::io("log", e))?;
                }
            }
            roadtrack_learn::Progress::Checkpoint { weights, .. } => {
                roadtrack::io::atomic::write_bytes_atomic(&out, weights.to_json()?.as_bytes())?;
            }
        }
        Ok(())
    })?;
    Ok(())
}
