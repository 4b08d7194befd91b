//! `roadtrack filter`: the labelled SMC-PHD filter on point measurements.

use crate::common::{Ui, load_config};
use anyhow::Result;
use roadtrack::io::points::{read_measurements, write_estimates};
use roadtrack::track::filter::SurveillanceRegion;
use roadtrack::track::filter::points::{PointFilterConfig, filter_points_with_progress};
use std::path::PathBuf;

/// Run the labelled SMC-PHD filter on point measurements (`step,x,y`) with a Gaussian
/// measurement likelihood and a constant-velocity model; write the labelled estimates
/// (`step,label,x,y,vx,vy,weight`, velocities per step) for every step.
///
/// Every setting comes from the TOML config (a `PointFilterConfig`) or its default; each
/// flag overrides its field. Same input and seed give byte-identical output.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  \
    roadtrack filter crates/roadtrack/tests/golden/filter/measurements.csv -o estimates.csv \\\n    \
    --region 0,0,500,500 --detection-prob 0.9 --survival-prob 0.99 --clutter-rate 10 \\\n    \
    --birth-rate 0.05 --measurement-sigma 2 --process-sigma 0.1 --birth-speed-sigma 2 --seed 7")]
pub struct Args {
    /// Measurements CSV with header `step,x,y`.
    pub measurements: PathBuf,
    /// Output estimates CSV (`-` for standard output).
    #[arg(short, long, default_value = "estimates.csv")]
    pub output: PathBuf,
    /// TOML file with a `PointFilterConfig`; flags override it.
    #[arg(long, value_name = "F.toml")]
    pub config: Option<PathBuf>,
    /// Surveillance region (clutter and births are uniform over it). Default: the
    /// measurements' bounding box grown by 10 % per side.
    #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = parse_region, allow_hyphen_values = true)]
    pub region: Option<SurveillanceRegion>,
    /// Time between steps (default 1).
    #[arg(long, value_name = "S", value_parser = crate::flags::positive)]
    pub dt: Option<f64>,
    /// Detection probability p_D (default 0.88).
    #[arg(long, value_name = "P", value_parser = crate::flags::probability)]
    pub detection_prob: Option<f64>,
    /// Survival probability p_s (default 0.9).
    #[arg(long, value_name = "P", value_parser = crate::flags::probability)]
    pub survival_prob: Option<f64>,
    /// Expected false measurements per step, uniform over the region (default 1).
    #[arg(long, value_name = "N", value_parser = crate::flags::positive)]
    pub clutter_rate: Option<f64>,
    /// Expected births per step, uniform over the region (default 0.1).
    #[arg(long, value_name = "N", value_parser = crate::flags::non_negative)]
    pub birth_rate: Option<f64>,
    /// Measurement noise, standard deviation per axis (default 1).
    #[arg(long, value_name = "S", value_parser = crate::flags::positive)]
    pub measurement_sigma: Option<f64>,
    /// Acceleration noise, standard deviation per axis (default 0.5).
    #[arg(long, value_name = "S", value_parser = crate::flags::non_negative)]
    pub process_sigma: Option<f64>,
    /// Particles per expected target ρ (default 70).
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub particles_per_target: Option<usize>,
    /// Standard deviation of a newborn target's velocity per axis (default 3).
    #[arg(long, value_name = "S", value_parser = crate::flags::non_negative)]
    pub birth_speed_sigma: Option<f64>,
    /// Random seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Parses `X0,Y0,X1,Y1` and checks `X1 > X0`, `Y1 > Y0`.
fn parse_region(s: &str) -> std::result::Result<SurveillanceRegion, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| {
            p.trim()
                .parse::<f64>()
                .map_err(|_| format!("{p:?} is not a number"))
        })
        .collect::<std::result::Result<_, _>>()?;
    let [x0, y0, x1, y1] = v[..] else {
        return Err(format!(
            "expected X0,Y0,X1,Y1 (4 numbers), found {}",
            v.len()
        ));
    };
    let r = SurveillanceRegion::new(x0, y0, x1, y1);
    if !r.is_valid() {
        return Err(format!(
            "X1 > X0 and Y1 > Y0 (finite) are required, found {x0},{y0},{x1},{y1}"
        ));
    }
    Ok(r)
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let mut cfg: PointFilterConfig = load_config(args.config.as_deref())?;
    if let Some(r) = args.region {
        cfg.region = Some(r);
    }
    macro_rules! set {
        ($($field:ident),*) => {$(
            if let Some(v) = args.$field {
                cfg.$field = v;
            }
        )*};
    }
    set!(
        dt,
        detection_prob,
        survival_prob,
        clutter_rate,
        birth_rate,
        measurement_sigma,
        process_sigma,
        particles_per_target,
        birth_speed_sigma
    );
    let given = |f: &str| -> bool {
        match f {
            "--dt" => args.dt.is_some(),
            "--detection-prob" => args.detection_prob.is_some(),
            "--survival-prob" => args.survival_prob.is_some(),
            "--clutter-rate" => args.clutter_rate.is_some(),
            "--birth-rate" => args.birth_rate.is_some(),
            "--measurement-sigma" => args.measurement_sigma.is_some(),
            "--process-sigma" => args.process_sigma.is_some(),
            "--particles-per-target" => args.particles_per_target.is_some(),
            "--birth-speed-sigma" => args.birth_speed_sigma.is_some(),
            "--region" => args.region.is_some(),
            _ => false,
        }
    };
    let fields = [
        ("dt", "--dt"),
        ("detection_prob", "--detection-prob"),
        ("survival_prob", "--survival-prob"),
        ("clutter_rate", "--clutter-rate"),
        ("birth_rate", "--birth-rate"),
        ("measurement_sigma", "--measurement-sigma"),
        ("process_sigma", "--process-sigma"),
        ("particles_per_target", "--particles-per-target"),
        ("birth_speed_sigma", "--birth-speed-sigma"),
        ("region", "--region"),
    ];
    let flags: Vec<(&str, &str, bool)> = fields.iter().map(|&(f, l)| (f, l, given(l))).collect();
    crate::flags::check_overrides(cfg.validate(), &flags, args.config.as_deref())?;
    let measurements = read_measurements(&args.measurements)?;
    let steps = match (measurements.first(), measurements.last()) {
        (Some(a), Some(b)) => b.step - a.step + 1,
        _ => 0,
    };
    let bar = ui.progress(Some(steps), "filter");
    let estimates = filter_points_with_progress(&measurements, &cfg, args.seed, &mut |done, _| {
        bar.set_position(done);
    })?;
    bar.finish_and_clear();
    write_estimates(&args.output, &estimates)?;
    if args.output.as_os_str() != "-" {
        ui.info(format!(
            "{} measurements, {} steps → {} estimates in {}",
            measurements.len(),
            steps,
            estimates.len(),
            args.output.display()
        ));
    }
    Ok(())
}
