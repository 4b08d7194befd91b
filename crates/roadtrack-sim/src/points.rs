//! Point measurements with known truth, for `roadtrack filter`: constant-velocity targets
//! (white-noise acceleration) that are born (Poisson), survive with `p_s` or leave the
//! region, are detected with `p_D` with Gaussian position noise, among Poisson clutter
//! uniform over the region. Used by the PHD tests, the `phd_points` example and the Stone
//! Soup comparison (`crates/roadtrack/tests/golden/filter/`).

use rand::RngExt as _;
use rand_distr::{Distribution, Normal, Poisson, StandardNormal};
use roadtrack_core::error::{Error, Result};
use roadtrack_core::geometry::{Point, SurveillanceRegion};
use roadtrack_core::io::points::{Measurement, PointEstimate};
use roadtrack_core::rng::{Rng, Stream, rng_for};
use serde::{Deserialize, Serialize};

/// Parameters of a point scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PointScenarioConfig {
    /// Surveillance region; targets leaving it die; clutter is uniform over it.
    pub region: SurveillanceRegion,
    /// Number of steps (numbered from 1).
    pub steps: u64,
    /// Targets alive at step 1.
    pub initial_targets: usize,
    /// Expected new targets per step (Poisson), uniform over the region.
    pub birth_rate: f64,
    /// Probability a target survives a step.
    pub survival_prob: f64,
    /// Probability a target is detected at a step.
    pub detection_prob: f64,
    /// Expected false measurements per step (Poisson), uniform over the region.
    pub clutter_rate: f64,
    /// Standard deviation of the measurement noise per axis.
    pub measurement_sigma: f64,
    /// Standard deviation of the acceleration per axis (units per step²).
    pub process_sigma: f64,
    /// Standard deviation of a new target's velocity per axis (units per step).
    pub initial_speed_sigma: f64,
}

impl Default for PointScenarioConfig {
    fn default() -> Self {
        Self {
            region: SurveillanceRegion::new(0.0, 0.0, 500.0, 500.0),
            steps: 100,
            initial_targets: 4,
            birth_rate: 0.05,
            survival_prob: 0.99,
            detection_prob: 0.9,
            clutter_rate: 10.0,
            measurement_sigma: 2.0,
            process_sigma: 0.1,
            initial_speed_sigma: 2.0,
        }
    }
}

/// A generated scenario: truth (as estimates with weight 1, label = target id) and
/// measurements, both sorted by step.
#[derive(Debug, Clone, PartialEq)]
pub struct PointScenario {
    /// True target states per step (velocity in units per step).
    pub truth: Vec<PointEstimate>,
    /// Measurements per step (targets and clutter, sorted by x within a step).
    pub measurements: Vec<Measurement>,
}

impl PointScenario {
    /// Number of true targets at `step`.
    pub fn count_at(&self, step: u64) -> usize {
        self.truth.iter().filter(|t| t.step == step).count()
    }
}

/// Generates the scenario of `config` under `seed`.
///
/// # Errors
/// When a rate or probability is out of range.
pub fn simulate_points(config: &PointScenarioConfig, seed: u64) -> Result<PointScenario> {
    let c = "PointScenarioConfig";
    if !config.region.is_valid() {
        return Err(Error::config(c, "region", "must have positive size"));
    }
    for (v, f) in [
        (config.survival_prob, "survival_prob"),
        (config.detection_prob, "detection_prob"),
    ] {
        if !(0.0..=1.0).contains(&v) {
            return Err(Error::config(c, f, "must be in [0, 1]"));
        }
    }
    let pos_or_zero = |v: f64| v.is_finite() && v >= 0.0;
    if ![
        config.birth_rate,
        config.clutter_rate,
        config.measurement_sigma,
        config.process_sigma,
        config.initial_speed_sigma,
    ]
    .into_iter()
    .all(pos_or_zero)
    {
        return Err(Error::config(
            c,
            "rates",
            "rates and sigmas must be finite and ≥ 0",
        ));
    }
    let mut rng = rng_for(seed, Stream::Scenario, 0x0050_4F49_4E54);
    let r = config.region;
    let poisson = |rate: f64, rng: &mut Rng| -> u64 {
        if rate <= 0.0 {
            return 0;
        }
        Poisson::new(rate).map_or(0, |p: Poisson<f64>| p.sample(rng) as u64)
    };
    let speed = Normal::new(0.0, config.initial_speed_sigma.max(1e-12))
        .map_err(|e| Error::config(c, "initial_speed_sigma", e.to_string()))?;
    let mut alive: Vec<(u64, [f64; 4])> = Vec::new();
    let mut next_id = 1;
    let mut truth = Vec::new();
    let mut measurements = Vec::new();
    for step in 1..=config.steps {
        if step > 1 {
            alive.retain_mut(|(_, s)| {
                white_noise_acceleration(s, config.process_sigma, &mut rng);
                let survives = rng.random::<f64>() < config.survival_prob;
                survives && r.contains(Point::new(s[0], s[1]))
            });
        }
        let births = if step == 1 {
            config.initial_targets as u64
        } else {
            poisson(config.birth_rate, &mut rng)
        };
        for _ in 0..births {
            // New targets start inside the central 80 % so they live a while.
            let s = [
                r.x0 + r.width() * (0.1 + 0.8 * rng.random::<f64>()),
                r.y0 + r.height() * (0.1 + 0.8 * rng.random::<f64>()),
                speed.sample(&mut rng),
                speed.sample(&mut rng),
            ];
            alive.push((next_id, s));
            next_id += 1;
        }
        let mut zs = Vec::new();
        for (id, s) in &alive {
            truth.push(PointEstimate {
                step,
                label: *id,
                pos: Point::new(s[0], s[1]),
                vel: Point::new(s[2], s[3]),
                weight: 1.0,
            });
            if rng.random::<f64>() < config.detection_prob {
                let n1: f64 = StandardNormal.sample(&mut rng);
                let n2: f64 = StandardNormal.sample(&mut rng);
                zs.push(Point::new(
                    s[0] + config.measurement_sigma * n1,
                    s[1] + config.measurement_sigma * n2,
                ));
            }
        }
        for _ in 0..poisson(config.clutter_rate, &mut rng) {
            zs.push(Point::new(
                r.x0 + r.width() * rng.random::<f64>(),
                r.y0 + r.height() * rng.random::<f64>(),
            ));
        }
        zs.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        measurements.extend(zs.into_iter().map(|pos| Measurement { step, pos }));
    }
    Ok(PointScenario {
        truth,
        measurements,
    })
}

/// One step (`dt = 1`) of the constant-velocity model with white-noise acceleration `σ`
/// per axis on `s = (x, y, v_x, v_y)`: the truth model of the scenario, the same as the
/// filters' `ConstantVelocity::acceleration(σ)` (`roadtrack::track::filter::motion`).
fn white_noise_acceleration(s: &mut [f64; 4], sigma: f64, rng: &mut Rng) {
    let dt = 1.0;
    let n1: f64 = StandardNormal.sample(rng);
    let n2: f64 = StandardNormal.sample(rng);
    let (ax, ay) = (sigma * n1, sigma * n2);
    s[0] += s[2] * dt + 0.5 * ax * dt * dt;
    s[1] += s[3] * dt + 0.5 * ay * dt * dt;
    s[2] += ax * dt;
    s[3] += ay * dt;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenario_is_reproducible_and_has_the_configured_statistics() -> Result<()> {
        let cfg = PointScenarioConfig::default();
        let a = simulate_points(&cfg, 1)?;
        assert_eq!(a, simulate_points(&cfg, 1)?);
        assert_ne!(a, simulate_points(&cfg, 2)?);
        assert_eq!(a.count_at(1), cfg.initial_targets);
        let detections_and_clutter = a.measurements.len() as f64 / cfg.steps as f64;
        let mean_targets = a.truth.len() as f64 / cfg.steps as f64;
        let expected = cfg.clutter_rate + cfg.detection_prob * mean_targets;
        assert!(
            (detections_and_clutter - expected).abs() < 1.5,
            "{detections_and_clutter} measurements per step, expected about {expected}"
        );
        Ok(())
    }
}

#[cfg(test)]
mod golden {
    use super::*;
    use roadtrack_core::io::points::{write_estimates, write_measurements};

    /// The committed Stone Soup comparison scenario is exactly the generator's output
    /// (`cargo run -p roadtrack --example phd_points -- crates/roadtrack/tests/golden/filter 7`).
    #[test]
    fn committed_comparison_scenario_matches_the_generator() -> Result<()> {
        let dir = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../roadtrack/tests/golden/filter"
        );
        let s = simulate_points(&PointScenarioConfig::default(), 7)?;
        let tmp = tempfile::tempdir().map_err(|e| Error::io("tempdir", e))?;
        let (m, t) = (tmp.path().join("m.csv"), tmp.path().join("t.csv"));
        write_measurements(&m, &s.measurements)?;
        write_estimates(&t, &s.truth)?;
        for (mine, name) in [(m, "measurements.csv"), (t, "truth.csv")] {
            let golden = std::path::Path::new(dir).join(name);
            let a = std::fs::read_to_string(&mine).map_err(|e| Error::io(&mine, e))?;
            let b = std::fs::read_to_string(&golden).map_err(|e| Error::io(&golden, e))?;
            assert!(
                a == b,
                "{name} differs from the generator; see tests/golden/filter/README.md"
            );
        }
        Ok(())
    }
}
