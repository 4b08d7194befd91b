//! A tiny training run learns and is reproducible (the burn/tract parity test is in
//! roadtrack-cli's tests/cnn_detector.rs, which has both crates).

use roadtrack::error::Result;

use crate::arch::CenterNetShape;
use crate::data::DataConfig;
use crate::train::{Progress, TrainConfig, train};

fn tiny_shape() -> CenterNetShape {
    crate::parity::tiny_shape()
}

fn tiny_config(steps: usize) -> TrainConfig {
    TrainConfig {
        steps,
        batch: 4,
        learning_rate: 5e-3,
        seed: 3,
        pool_frames: 4,
        refresh_every: 8,
        shape: tiny_shape(),
        data: DataConfig {
            width: 192,
            height: 144,
            frames_per_episode: 2,
            crop: 48,
            ..DataConfig::default()
        },
        ..TrainConfig::default()
    }
}

#[test]
fn tiny_training_run_lowers_the_loss_and_is_reproducible() -> Result<()> {
    let cfg = tiny_config(40);
    let mut losses = Vec::new();
    let mut checkpoints = Vec::new();
    let a = train(&cfg, 20, &mut |p| {
        match p {
            Progress::Step(l) => losses.push(l.total),
            Progress::Checkpoint { step, .. } => checkpoints.push(step),
        }
        Ok(())
    })?;
    assert_eq!(losses.len(), 40);
    assert_eq!(checkpoints, vec![20, 40]);
    let first: f32 = losses[..5].iter().sum::<f32>() / 5.0;
    let last: f32 = losses[30..].iter().sum::<f32>() / 10.0;
    assert!(
        last < 0.85 * first,
        "loss did not fall: first steps {first}, last steps {last} ({losses:?})"
    );
    let b = train(&cfg, 0, &mut |_| Ok(()))?;
    assert_eq!(a.to_json()?, b.to_json()?, "same seed, different model");
    let c = train(&TrainConfig { seed: 4, ..cfg }, 0, &mut |_| Ok(()))?;
    assert_ne!(a.to_json()?, c.to_json()?, "the seed changes nothing");
    Ok(())
}

#[test]
fn burn_still_computes_the_parity_fixture() -> Result<()> {
    // The fixture's outputs are burn's; roadtrack-cnn's test checks tract against them.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../roadtrack-cnn/tests/fixtures/centernet_parity.json");
    let text = std::fs::read_to_string(&path).map_err(|e| roadtrack::Error::io(&path, e))?;
    let f: crate::parity::ParityFixture = serde_json::from_str(&text)
        .map_err(|e| roadtrack::Error::Invalid(format!("{}: {e}", path.display())))?;
    assert_eq!(
        f,
        crate::parity::make_fixture(11),
        "the fixture is stale: regenerate it"
    );
    let (heat, boxes) = crate::parity::burn_forward(&f.weights, &f.input, f.h, f.w);
    assert_eq!(heat, f.heatmap);
    assert_eq!(boxes, f.boxes);
    Ok(())
}
