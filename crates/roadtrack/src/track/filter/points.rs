//! The labelled SMC-PHD filter on point measurements (`roadtrack filter`, INTERFACES.md):
//! measurements `step,x,y` → estimates `step,label,x,y,vx,vy,weight`, with a Gaussian
//! measurement likelihood and a constant-velocity (white-noise acceleration) model.
//!
//! It runs the same [`LabelledPhd`] core as the image tracker, with the standard SMC-PHD
//! update over all measurements ([`LabelledPhd::update_points`]) and births proposed around
//! the previous step's measurements ([`LabelledPhd::add_measurement_births`]).

use super::SurveillanceRegion;
use super::motion::ConstantVelocity;
use super::phd::{LabelUpdate, LabelledPhd, PhdConfig};
use super::resample::ResamplingScheme;
use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::io::points::{Measurement, PointEstimate};
use crate::limits::{MAX_MEASUREMENTS_PER_STEP, MAX_PARTICLES_PER_OBJECT, MAX_STEP, at_most};
use serde::{Deserialize, Serialize};

/// Where the birth particles of a step are proposed ([`PointFilterConfig::birth_proposal`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BirthProposal {
    /// Around the step's own measurements (Vo, Singh & Doucet 2005 allow a proposal that
    /// depends on the current measurements): a target is born with the weight Bayes gives
    /// it at its first detection.
    #[default]
    Current,
    /// Around the previous step's measurements, moved by the system model over `dt` (the
    /// form before issue 14): a target's first detection finds no birth particle, so it is
    /// confirmed one step later.
    Previous,
}

/// The scenario model and filter settings of `roadtrack filter`. Probabilities default to
/// the paper's (`p_D = 0.88`, `p_s = 0.9`, `ρ = 70`; METHODS.md §3); the rest have no
/// counterpart in the paper (its observations are images) and are marked `Choice:`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PointFilterConfig {
    /// Surveillance region `X0,Y0,X1,Y1`; `None` takes the measurements' bounding box grown
    /// by 10 % on each side.
    pub region: Option<SurveillanceRegion>,
    /// Time between steps (velocities are in units per unit time inside the filter; the
    /// estimates CSV gives them per step). Default 1.
    pub dt: f64,
    /// `p_D`. Default 0.88.
    pub detection_prob: f64,
    /// `p_s`. Default 0.9.
    pub survival_prob: f64,
    /// Expected false measurements per step, uniform over the region. Default 1.
    pub clutter_rate: f64,
    /// Expected births per step, uniform over the region (`μ_Γ`). Default 0.1.
    // Choice: the paper's μ_Γ = 2 births per frame is for a 640 × 480 image searched by a
    // classifier; for point data a low rate keeps clutter from being confirmed.
    pub birth_rate: f64,
    /// Measurement noise, standard deviation per axis. Default 1.
    pub measurement_sigma: f64,
    /// Acceleration noise, standard deviation per axis (units per unit time²). Default 0.5.
    pub process_sigma: f64,
    /// `ρ`: particles per expected target. Default 70.
    pub particles_per_target: usize,
    /// Birth particles drawn around each measurement ([`BirthProposal`]). Default 50.
    pub birth_particles_per_measurement: usize,
    /// Standard deviation of a birth's velocity per axis (units per unit time). Default 3.
    pub birth_speed_sigma: f64,
    /// `β_likelihood` on the unit-peak Gaussian kernel `exp(−d²/2σ²)`. Default 0.05.
    pub likelihood_threshold: f64,
    /// `α_mesh`. Default 0.08.
    pub mesh_likelihood_threshold: f64,
    /// Mesh cell side, in measurement sigmas. Default 4.
    pub mesh_cell_sigmas: f64,
    /// `β_center`: labels closer than this merge, in measurement sigmas. Default 4.
    pub merge_distance_sigmas: f64,
    /// `α_spawned`: a label splits when its 2-means centres are farther apart, in
    /// measurement sigmas. Default 10.
    pub split_distance_sigmas: f64,
    /// A label is written when its weight reaches this. Default 0.5.
    pub report_weight: f64,
    /// Step d) for labelled particles ([`LabelUpdate`]). Default `bernoulli`; `phd` is
    /// Vo et al.'s update for every particle (the form before issue 14).
    // Choice: the point update is not the paper's (its observations are images), so its
    // default is the form whose expected count follows the number of targets: with the
    // PHD form every missed detection (10 % of steps at p_D = 0.9) takes 0.9 of a target
    // off Σw (docs/FILTERS.md "Expected count").
    pub label_update: LabelUpdate,
    /// Where births are proposed. Default `current`.
    // Choice: proposing births around the previous step's measurements costs every new
    // target one step of Σw (docs/FILTERS.md "Expected count").
    pub birth_proposal: BirthProposal,
    /// Roughening constant after resampling ([`PhdConfig::roughening`]). Default 0.3
    /// (Gordon, Salmond & Smith 1993).
    // Choice: 0.3 rather than 0.2: with the scenario's small process noise (0.1) the
    // copies of a label's particles collapse onto one velocity, the label lags its target
    // and its detections count as clutter; 0.3 lowered the mean OSPA over seeds 1, 2, 3, 7
    // and 11 from 4.05 to 3.60 (docs/FILTERS.md "Expected count").
    pub roughening: f64,
}

impl Default for PointFilterConfig {
    fn default() -> Self {
        Self {
            region: None,
            dt: 1.0,
            detection_prob: 0.88,
            survival_prob: 0.9,
            clutter_rate: 1.0,
            birth_rate: 0.1,
            measurement_sigma: 1.0,
            process_sigma: 0.5,
            particles_per_target: 70,
            birth_particles_per_measurement: 50,
            birth_speed_sigma: 3.0,
            likelihood_threshold: 0.05,
            mesh_likelihood_threshold: 0.08,
            mesh_cell_sigmas: 4.0,
            merge_distance_sigmas: 4.0,
            split_distance_sigmas: 10.0,
            report_weight: 0.5,
            label_update: LabelUpdate::Bernoulli,
            birth_proposal: BirthProposal::Current,
            roughening: 0.3,
        }
    }
}

impl crate::config::Validate for PointFilterConfig {
    fn validate(&self) -> crate::error::Result<()> {
        PointFilterConfig::validate(self)
    }
}

impl PointFilterConfig {
    /// Checks every range (the PHD core checks the rest).
    pub fn validate(&self) -> Result<()> {
        let c = "PointFilterConfig";
        let positive = |v: f64, f: &'static str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error::config(
                    c,
                    f,
                    format!("must be finite and > 0, got {v}"),
                ))
            }
        };
        positive(self.dt, "dt")?;
        positive(self.measurement_sigma, "measurement_sigma")?;
        positive(self.clutter_rate, "clutter_rate")?;
        positive(self.mesh_cell_sigmas, "mesh_cell_sigmas")?;
        positive(self.split_distance_sigmas, "split_distance_sigmas")?;
        if let Some(r) = self.region
            && !r.is_valid()
        {
            return Err(Error::config(
                c,
                "region",
                "X1 > X0 and Y1 > Y0 are required",
            ));
        }
        if self.birth_particles_per_measurement == 0 {
            return Err(Error::config(
                c,
                "birth_particles_per_measurement",
                "must be ≥ 1",
            ));
        }
        for (v, f) in [
            (self.particles_per_target, "particles_per_target"),
            (
                self.birth_particles_per_measurement,
                "birth_particles_per_measurement",
            ),
        ] {
            at_most(v, MAX_PARTICLES_PER_OBJECT, "particles per object")
                .map_err(|m| Error::config(c, f, m))?;
        }
        // The PHD filter's fields derive from these: name the one the file spells.
        self.phd_config().validate().map_err(|e| match e {
            Error::InvalidConfig { field, reason, .. } => {
                let field = match field.as_str() {
                    "particles_per_object" | "max_particles" => "particles_per_target",
                    "motion" => "process_sigma",
                    "merge_distance" => "merge_distance_sigmas",
                    "split_distance" => "split_distance_sigmas",
                    "mesh_cell" => "mesh_cell_sigmas",
                    other => other,
                };
                Error::config(c, field.to_owned(), reason)
            }
            other => other,
        })
    }

    /// The PHD core's configuration for these settings.
    pub fn phd_config(&self) -> PhdConfig {
        let s = self.measurement_sigma;
        PhdConfig {
            particles_per_object: self.particles_per_target,
            survival_prob: self.survival_prob,
            detection_prob: self.detection_prob,
            motion: ConstantVelocity::acceleration(self.process_sigma),
            birth_rate: self.birth_rate,
            birth_grid_points: 140,
            birth_speed_sigma: self.birth_speed_sigma,
            // Unused by the point update (κ = clutter_rate / area there).
            clutter_intensity: 1.0,
            likelihood_threshold: self.likelihood_threshold,
            // Choice: with p_D < 1 a step without the target's measurement is expected; it
            // must not erase the label (its weight already drops by 1 − p_D).
            keep_unsupported_labels: true,
            border_margin: 0.0,
            // Choice: no border-exit rule for points: an object that leaves stops producing
            // measurements and its weight decays; the rule exists for image windows.
            exit_speed: f64::INFINITY,
            split_distance: self.split_distance_sigmas * s,
            mesh_likelihood_threshold: self.mesh_likelihood_threshold,
            mesh_cell: self.mesh_cell_sigmas * s,
            merge_distance: self.merge_distance_sigmas * s,
            report_weight: self.report_weight,
            label_update: self.label_update,
            resampling: ResamplingScheme::Stratified,
            max_particles: 200_000,
            roughening: self.roughening,
            ..PhdConfig::default()
        }
    }
}

/// Runs the labelled SMC-PHD filter over `measurements` (any order; steps need not be
/// contiguous: every step from the first to the last is filtered) and returns the
/// estimates of every step, sorted by step then label. Velocities are in units per step.
///
/// # Errors
/// When the config is invalid or a measurement is not finite.
pub fn filter_points(
    measurements: &[Measurement],
    config: &PointFilterConfig,
    seed: u64,
) -> Result<Vec<PointEstimate>> {
    filter_points_with_progress(measurements, config, seed, &mut |_, _| {})
}

/// [`filter_points`] with a progress callback `(steps done, steps in all)`.
///
/// # Errors
/// As [`filter_points`].
pub fn filter_points_with_progress(
    measurements: &[Measurement],
    config: &PointFilterConfig,
    seed: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<PointEstimate>> {
    Ok(filter_points_run(measurements, config, seed, progress)?.estimates)
}

/// What one run of the point filter produced.
#[derive(Debug, Clone, PartialEq)]
pub struct PointFilterRun {
    /// The estimates of every step, sorted by step then label (as [`filter_points`]).
    pub estimates: Vec<PointEstimate>,
    /// `(step, Σw)`: the expected number of targets after each step's update, every step
    /// from the first to the last.
    pub expected_counts: Vec<(u64, f64)>,
}

/// [`filter_points_with_progress`] that also returns the expected count `Σw` per step.
///
/// # Errors
/// As [`filter_points`].
pub fn filter_points_run(
    measurements: &[Measurement],
    config: &PointFilterConfig,
    seed: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<PointFilterRun> {
    config.validate()?;
    if let Some(m) = measurements
        .iter()
        .find(|m| !(m.pos.x.is_finite() && m.pos.y.is_finite()))
    {
        return Err(Error::Invalid(format!(
            "measurement at step {} is not finite: ({}, {})",
            m.step, m.pos.x, m.pos.y
        )));
    }
    let mut sorted = measurements.to_vec();
    sorted.sort_by_key(|m| m.step);
    let (Some(first), Some(last)) = (sorted.first(), sorted.last()) else {
        return Ok(PointFilterRun {
            estimates: Vec::new(),
            expected_counts: Vec::new(),
        });
    };
    let (first, last) = (first.step, last.step);
    // Every step from the first to the last is filtered, and one step costs (birth
    // particles per measurement) × measurements²: both are bounded before the loop (the
    // CSV reader names the line; measurements built in code are checked here).
    at_most(
        last - first,
        MAX_STEP,
        "steps from the first to the last measurement",
    )
    .map_err(|m| Error::Invalid(format!("measurements: {m}")))?;
    if let Some(w) = sorted
        .chunk_by(|a, b| a.step == b.step)
        .find(|w| w.len() > MAX_MEASUREMENTS_PER_STEP)
    {
        return Err(Error::Invalid(format!(
            "measurements: step {}: {}",
            w[0].step,
            at_most(
                w.len(),
                MAX_MEASUREMENTS_PER_STEP,
                "measurements in one step"
            )
            .unwrap_err()
        )));
    }
    let region = config.region.unwrap_or_else(|| bounding_region(&sorted));
    let mut phd = LabelledPhd::new(config.phd_config(), region, seed)?;
    let sigma = config.measurement_sigma;
    let total = last - first + 1;
    let mut out = Vec::new();
    let mut counts = Vec::with_capacity(usize::try_from(total).unwrap_or(0));
    let mut prev: Vec<Point> = Vec::new();
    let mut k = 0;
    for step in first..=last {
        let start = k;
        while k < sorted.len() && sorted[k].step == step {
            k += 1;
        }
        let z: Vec<Point> = sorted[start..k].iter().map(|m| m.pos).collect();
        if step > first {
            phd.predict(config.dt);
        }
        // Births: proposed around this step's measurements (or the previous step's, moved
        // to this step).
        // Choice: measurement-driven birth proposals (Ristic, Clark & Vo 2010, the paper's
        // ref. 10) instead of the paper's 140-point grid, which cannot resolve point
        // targets; the importance weights keep the birth intensity uniform (μ_Γ / area).
        let previous = step > first && config.birth_proposal == BirthProposal::Previous;
        let advance = if previous { config.dt } else { 0.0 };
        let birth_points = if previous { &prev[..] } else { &z[..] };
        phd.add_measurement_births(
            birth_points,
            config.birth_particles_per_measurement,
            sigma,
            advance,
        );
        phd.update_points(&z, sigma, config.clutter_rate);
        counts.push((step, phd.expected_count()));
        phd.update_labels();
        out.extend(phd.estimates().into_iter().map(|e| PointEstimate {
            step,
            label: u64::from(e.label),
            pos: e.pos,
            vel: Point::new(e.vel.x * config.dt, e.vel.y * config.dt),
            weight: e.weight,
        }));
        phd.resample();
        prev = z;
        progress(step - first + 1, total);
    }
    Ok(PointFilterRun {
        estimates: out,
        expected_counts: counts,
    })
}

/// The bounding box of the measurements grown by 10 % of its size (at least 1 unit) per side.
fn bounding_region(ms: &[Measurement]) -> SurveillanceRegion {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for m in ms {
        x0 = x0.min(m.pos.x);
        y0 = y0.min(m.pos.y);
        x1 = x1.max(m.pos.x);
        y1 = y1.max(m.pos.y);
    }
    let px = (0.1 * (x1 - x0)).max(1.0);
    let py = (0.1 * (y1 - y0)).max(1.0);
    SurveillanceRegion::new(x0 - px, y0 - py, x1 + px, y1 + py)
}

#[cfg(test)]
mod tests {
    use super::*;
    use roadtrack_sim::points::{PointScenarioConfig, simulate_points};

    /// OSPA distance (Schuhmacher et al. 2008) of order 1 with cut-off `c`, by brute-force
    /// assignment over permutations of the smaller set (sets here have ≤ 8 points).
    // Test-only helper; the metrics module owns the library OSPA.
    fn ospa(a: &[Point], b: &[Point], c: f64) -> f64 {
        let (small, large) = if a.len() <= b.len() { (a, b) } else { (b, a) };
        if large.is_empty() {
            return 0.0;
        }
        fn best(small: &[Point], large: &[Point], used: &mut Vec<bool>, k: usize, c: f64) -> f64 {
            if k == small.len() {
                return 0.0;
            }
            let mut m = f64::INFINITY;
            for j in 0..large.len() {
                if !used[j] {
                    used[j] = true;
                    let d = small[k].distance(large[j]).min(c);
                    m = m.min(d + best(small, large, used, k + 1, c));
                    used[j] = false;
                }
            }
            m
        }
        let mut used = vec![false; large.len()];
        let cost = best(small, large, &mut used, 0, c);
        (cost + c * (large.len() - small.len()) as f64) / large.len() as f64
    }

    fn matched(sc: &PointScenarioConfig) -> PointFilterConfig {
        PointFilterConfig {
            region: Some(sc.region),
            detection_prob: sc.detection_prob,
            survival_prob: sc.survival_prob,
            clutter_rate: sc.clutter_rate,
            birth_rate: sc.birth_rate,
            measurement_sigma: sc.measurement_sigma,
            process_sigma: sc.process_sigma,
            birth_speed_sigma: sc.initial_speed_sigma,
            ..PointFilterConfig::default()
        }
    }

    #[test]
    fn phd_count_and_positions_track_the_truth_of_a_simulated_scenario() -> Result<()> {
        let sc = PointScenarioConfig {
            steps: 60,
            ..Default::default()
        };
        let scenario = simulate_points(&sc, 11)?;
        let est = filter_points(&scenario.measurements, &matched(&sc), 11)?;
        let (mut count_err, mut ospa_sum) = (0.0, 0.0);
        for step in 1..=sc.steps {
            let truth: Vec<Point> = scenario
                .truth
                .iter()
                .filter(|t| t.step == step)
                .map(|t| t.pos)
                .collect();
            let mine: Vec<Point> = est
                .iter()
                .filter(|e| e.step == step)
                .map(|e| e.pos)
                .collect();
            count_err += (truth.len() as f64 - mine.len() as f64).abs();
            ospa_sum += ospa(&truth, &mine, 20.0);
        }
        let (count_err, mean_ospa) = (count_err / sc.steps as f64, ospa_sum / sc.steps as f64);
        // Missed detections (10 %) alone drop a target below the report weight on ~10 % of
        // steps, and new targets take 2–3 steps to confirm.
        assert!(count_err < 1.3, "mean |count error| {count_err:.2}");
        assert!(mean_ospa < 8.0, "mean OSPA(c = 20, p = 1) {mean_ospa:.2}");
        Ok(())
    }

    /// Mean |Σw − true count| over steps 11–100 of the default point scenario (the Stone
    /// Soup comparison's) under `seed`.
    fn count_mae(cfg: &PointFilterConfig, seed: u64) -> Result<f64> {
        let sc = PointScenarioConfig::default();
        let scenario = simulate_points(&sc, seed)?;
        let run = filter_points_run(&scenario.measurements, cfg, seed, &mut |_, _| {})?;
        assert_eq!(run.expected_counts.len() as u64, sc.steps);
        let burn_in = 10;
        let errors: Vec<f64> = run
            .expected_counts
            .iter()
            .filter(|(step, _)| *step > burn_in)
            .map(|&(step, sum_w)| (sum_w - scenario.count_at(step) as f64).abs())
            .collect();
        Ok(errors.iter().sum::<f64>() / errors.len() as f64)
    }

    #[test]
    fn expected_count_follows_the_true_count_on_the_point_scenario() -> Result<()> {
        // Issue 14: Σw ran 0.7 targets below the truth on average (5.1 of 7.2 at worst)
        // with the PHD update of labelled particles and births one step late.
        let cfg = matched(&PointScenarioConfig::default());
        let seeds = [7, 1, 2, 3, 11];
        let mut maes = Vec::new();
        for seed in seeds {
            maes.push(count_mae(&cfg, seed)?);
        }
        let mean = maes.iter().sum::<f64>() / maes.len() as f64;
        assert!(
            maes[0] <= 0.5,
            "count MAE {:.3} on the comparison scenario",
            maes[0]
        );
        assert!(mean <= 0.5, "count MAE over seeds {seeds:?}: {maes:.3?}");
        // The form before the fix, kept selectable, fails the same bound.
        let before = PointFilterConfig {
            label_update: LabelUpdate::Phd,
            birth_proposal: BirthProposal::Previous,
            roughening: 0.2,
            ..cfg
        };
        let old = count_mae(&before, 7)?;
        assert!(old > 0.6, "count MAE {old:.3} before the fix");
        Ok(())
    }

    /// The committed estimates behind the Stone Soup comparison table are what the code
    /// produces now (regenerate with the command in tests/golden/filter/README.md).
    #[test]
    fn committed_comparison_estimates_match_the_filter() -> Result<()> {
        let dir = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/filter"));
        let ms = crate::io::points::read_measurements(&dir.join("measurements.csv"))?;
        let est = filter_points(&ms, &matched(&PointScenarioConfig::default()), 7)?;
        let tmp = tempfile::tempdir().map_err(|e| Error::io("tempdir", e))?;
        let mine = tmp.path().join("e.csv");
        crate::io::points::write_estimates(&mine, &est)?;
        let a = std::fs::read_to_string(&mine).map_err(|e| Error::io(&mine, e))?;
        let golden = dir.join("estimates.csv");
        let b = std::fs::read_to_string(&golden).map_err(|e| Error::io(&golden, e))?;
        assert!(
            a == b,
            "estimates.csv differs; see tests/golden/filter/README.md"
        );
        Ok(())
    }

    #[test]
    fn point_filter_is_deterministic_at_any_thread_count() -> Result<()> {
        let sc = PointScenarioConfig {
            steps: 25,
            ..Default::default()
        };
        let scenario = simulate_points(&sc, 3)?;
        let run = |threads: usize| -> Result<Vec<PointEstimate>> {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| Error::Invalid(e.to_string()))?;
            pool.install(|| filter_points(&scenario.measurements, &matched(&sc), 3))
        };
        let one = run(1)?;
        assert!(!one.is_empty());
        assert_eq!(one, run(4)?);
        assert_ne!(
            one,
            filter_points(&scenario.measurements, &matched(&sc), 4)?
        );
        Ok(())
    }

    #[test]
    fn progress_is_reported_for_every_step_and_bad_input_is_rejected() -> Result<()> {
        let ms = [
            Measurement {
                step: 3,
                pos: Point::new(1.0, 1.0),
            },
            Measurement {
                step: 6,
                pos: Point::new(2.0, 1.0),
            },
        ];
        let mut calls = Vec::new();
        filter_points_with_progress(&ms, &PointFilterConfig::default(), 0, &mut |d, t| {
            calls.push((d, t))
        })?;
        assert_eq!(calls, vec![(1, 4), (2, 4), (3, 4), (4, 4)]);
        let bad = [Measurement {
            step: 1,
            pos: Point::new(f64::NAN, 0.0),
        }];
        assert!(filter_points(&bad, &PointFilterConfig::default(), 0).is_err());
        let cfg = PointFilterConfig {
            measurement_sigma: 0.0,
            ..Default::default()
        };
        assert!(filter_points(&ms, &cfg, 0).is_err());
        assert!(filter_points(&[], &PointFilterConfig::default(), 0)?.is_empty());
        Ok(())
    }

    #[test]
    fn ospa_helper_is_zero_for_equal_sets_and_c_for_a_missing_point() {
        let a = [Point::new(0.0, 0.0), Point::new(5.0, 5.0)];
        assert_eq!(ospa(&a, &a, 10.0), 0.0);
        assert_eq!(ospa(&a[..1], &a, 10.0), 5.0);
        assert_eq!(ospa(&[], &[], 10.0), 0.0);
    }
}
