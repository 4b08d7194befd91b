//! Generates the seeded point scenario, runs the labelled SMC-PHD filter on it and writes
//! `measurements.csv`, `truth.csv` (estimates format, weight 1) and `estimates.csv`.
//!
//! ```text
//! cargo run -p roadtrack --example phd_points -- OUT_DIR [SEED] [--particles N]
//! ```
//!
//! With `OUT_DIR = crates/roadtrack/tests/golden/filter` and seed 7 it regenerates the
//! committed scenario of the Stone Soup comparison (see the README there).

use roadtrack::io::points::{read_measurements, write_estimates, write_measurements};
use roadtrack::track::filter::points::{PointFilterConfig, filter_points};
use roadtrack_sim::points::{PointScenarioConfig, simulate_points};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = PathBuf::from(
        args.first()
            .ok_or("usage: phd_points OUT_DIR [SEED] [--particles N]")?,
    );
    let seed: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(7);
    let particles: usize = args
        .iter()
        .position(|a| a == "--particles")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(70);
    std::fs::create_dir_all(&out)?;
    let sc = PointScenarioConfig::default();
    let scenario = simulate_points(&sc, seed)?;
    write_measurements(&out.join("measurements.csv"), &scenario.measurements)?;
    write_estimates(&out.join("truth.csv"), &scenario.truth)?;
    let cfg = scenario_filter_config(&sc, particles);
    let t0 = Instant::now();
    // Filter the measurements as written (6 decimals), exactly what `roadtrack filter` and
    // scripts/stonesoup_compare.py read.
    let measurements = read_measurements(&out.join("measurements.csv"))?;
    let est = filter_points(&measurements, &cfg, seed)?;
    let secs = t0.elapsed().as_secs_f64();
    write_estimates(&out.join("estimates.csv"), &est)?;
    let mut abs_err = 0.0;
    for step in 1..=sc.steps {
        let n_true = scenario.count_at(step);
        let n_est = est.iter().filter(|e| e.step == step).count();
        abs_err += (n_true as f64 - n_est as f64).abs();
    }
    println!(
        "steps {}, measurements {}, estimates {}, mean |count error| {:.3}, wall {:.3} s",
        sc.steps,
        scenario.measurements.len(),
        est.len(),
        abs_err / sc.steps as f64,
        secs
    );
    Ok(())
}

/// The filter matched to the scenario's true model.
fn scenario_filter_config(sc: &PointScenarioConfig, particles: usize) -> PointFilterConfig {
    PointFilterConfig {
        region: Some(sc.region),
        dt: 1.0,
        detection_prob: sc.detection_prob,
        survival_prob: sc.survival_prob,
        clutter_rate: sc.clutter_rate,
        birth_rate: sc.birth_rate,
        measurement_sigma: sc.measurement_sigma,
        process_sigma: sc.process_sigma,
        particles_per_target: particles,
        birth_speed_sigma: sc.initial_speed_sigma,
        ..PointFilterConfig::default()
    }
}
