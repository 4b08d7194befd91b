//! Fuzz tests of every configuration loaded from TOML (issue 15, part 5): seeded mutations
//! of the default config (and of the committed `configs/*.toml`) plus raw bytes (see
//! `fuzzkit`).
//!
//! Parsing with [`parse_toml`] must not panic and must return the config or an error naming
//! the file ([`Error::Toml`], or [`Error::Parse`] for text that is not UTF-8); `validate()`
//! must not panic, may only fail with [`Error::InvalidConfig`], and must reject NaN and ±∞
//! in every float field (except [`PHD_EXIT_SPEED`], where ∞ is a documented value).
//!
//! `cargo test -p roadtrack --test fuzz_configs -- --ignored` runs the deep variant.

#[path = "../../roadtrack-core/tests/fuzzkit/mod.rs"]
mod fuzzkit;

use fuzzkit::{DEEP, Syntax, run};
use roadtrack::analysis::Site;
use roadtrack::config::{parse_toml, to_toml};
use roadtrack::detect::background::BackgroundDetectorConfig;
use roadtrack::eval::EvalConfig;
use roadtrack::track::filter::{
    ConstantVelocity, FilterTrackConfig, ParticleFilterConfig, PhdConfig, PointFilterConfig,
};
use roadtrack::track::mrf::MrfConfig;
use roadtrack::track::relaxation::{RelaxationConfig, RelaxationTrackerConfig};
use roadtrack::{Error, Result};
use roadtrack_sim::SimConfig;
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::fmt::Debug;
use std::path::Path;

/// The dotted paths (`line.0.a.1`) of the non-finite floats in `value`.
fn non_finite(value: &toml::Value, at: &str, out: &mut Vec<String>) {
    let join = |k: &str| {
        if at.is_empty() {
            k.to_owned()
        } else {
            format!("{at}.{k}")
        }
    };
    match value {
        toml::Value::Float(x) if !x.is_finite() => out.push(format!("{at} = {x}")),
        toml::Value::Array(a) => a
            .iter()
            .enumerate()
            .for_each(|(i, v)| non_finite(v, &join(&i.to_string()), out)),
        toml::Value::Table(t) => t.iter().for_each(|(k, v)| non_finite(v, &join(k), out)),
        _ => {}
    }
}

/// Fuzzes config `T` from `seeds` (the default config's TOML is added): load, validate,
/// and check an accepted config has no NaN/∞, except where `path = value` starts with one
/// of `accepted_ok` (fields where +∞ is a documented value, known exceptions).
fn fuzz_config<T: DeserializeOwned + Serialize + Default + Debug>(
    name: &str,
    cases: u32,
    seeds: &[&str],
    validate: fn(&T) -> Result<()>,
    accepted_ok: &[&str],
) {
    let default = to_toml(&T::default()).expect("default config as TOML");
    let mut all: Vec<&str> = seeds.to_vec();
    all.push(&default);
    let dir = tempfile::tempdir().expect("temporary folder");
    let path = dir.path().join("config.toml");
    run(name, cases, &all, Syntax::Toml, |bytes| {
        fuzzkit::write_case(&path, bytes)?;
        let config: T = match parse_toml(&path) {
            Ok(c) => c,
            Err(Error::Toml { path: p, .. }) if p == path => return Ok(()),
            Err(Error::Parse { path: p, line, .. }) if p == path && line >= 1 => return Ok(()),
            Err(e) => return Err(format!("unexpected load error kind: {e:?}")),
        };
        match validate(&config) {
            Ok(()) => {}
            Err(Error::InvalidConfig { .. }) => return Ok(()),
            Err(e) => return Err(format!("unexpected validate error kind: {e:?}")),
        }
        let value = toml::Value::try_from(&config)
            .map_err(|e| format!("accepted config does not serialise: {e}"))?;
        let mut bad = Vec::new();
        non_finite(&value, "", &mut bad);
        bad.retain(|b| !accepted_ok.iter().any(|f| b.starts_with(f)));
        if bad.is_empty() {
            Ok(())
        } else {
            Err(format!("validate() accepted {}", bad.join(", ")))
        }
    });
}

/// Every float leaf of `value` (table keys and array positions from the root).
fn float_leaves(value: &toml::Value, at: Vec<String>, out: &mut Vec<Vec<String>>) {
    match value {
        toml::Value::Float(_) => out.push(at),
        toml::Value::Array(a) => a.iter().enumerate().for_each(|(i, v)| {
            let mut p = at.clone();
            p.push(i.to_string());
            float_leaves(v, p, out)
        }),
        toml::Value::Table(t) => t.iter().for_each(|(k, v)| {
            let mut p = at.clone();
            p.push(k.clone());
            float_leaves(v, p, out)
        }),
        _ => {}
    }
}

fn leaf_mut<'v>(value: &'v mut toml::Value, at: &[String]) -> &'v mut toml::Value {
    at.iter().fold(value, |v, k| match v {
        toml::Value::Array(a) => &mut a[k.parse::<usize>().expect("index")],
        toml::Value::Table(t) => t.get_mut(k).expect("key"),
        _ => unreachable!("a leaf has no children"),
    })
}

/// The float fields of `T`'s default config (as written by `to_toml`) that `validate`
/// accepts as NaN, +∞ or −∞, as `path = value`.
fn non_finite_accepted<T: DeserializeOwned + Serialize + Default>(
    validate: fn(&T) -> Result<()>,
) -> Vec<String> {
    let base = toml::Value::try_from(T::default()).expect("default config as TOML");
    non_finite_accepted_from(base, validate)
}

/// As [`non_finite_accepted`], from the config `base` (as TOML).
fn non_finite_accepted_from<T: DeserializeOwned>(
    base: toml::Value,
    validate: fn(&T) -> Result<()>,
) -> Vec<String> {
    let mut leaves = Vec::new();
    float_leaves(&base, Vec::new(), &mut leaves);
    let mut out = Vec::new();
    for at in leaves {
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut v = base.clone();
            *leaf_mut(&mut v, &at) = toml::Value::Float(x);
            let config: T = v.try_into().expect("a float where a float was");
            if validate(&config).is_ok() {
                out.push(format!("{} = {x}", at.join(".")));
            }
        }
    }
    out
}

/// Every float field of every config, set to NaN, +∞ and −∞ in turn (deterministic,
/// complements the fuzzing): `validate()` rejects all but the documented exceptions.
#[test]
fn every_float_field_rejects_non_finite_values() {
    let mut report = Vec::new();
    let mut check = |name: &str, accepted: Vec<String>, ok: &[&str]| {
        for a in accepted {
            if !ok.iter().any(|f| a.starts_with(f)) {
                report.push(format!("{name}.{a}"));
            }
        }
    };
    check(
        "RelaxationConfig",
        non_finite_accepted::<RelaxationConfig>(|c| c.validate()),
        &[],
    );
    check(
        "RelaxationTrackerConfig",
        non_finite_accepted::<RelaxationTrackerConfig>(|c| c.validate()),
        &[],
    );
    check(
        "MrfConfig",
        non_finite_accepted::<MrfConfig>(|c| c.validate()),
        &[],
    );
    check(
        "FilterTrackConfig",
        non_finite_accepted::<FilterTrackConfig>(|c| c.validate()),
        &[&format!("phd.{PHD_EXIT_SPEED}")],
    );
    check(
        "PhdConfig",
        non_finite_accepted::<PhdConfig>(|c| c.validate()),
        &[PHD_EXIT_SPEED],
    );
    check(
        "ParticleFilterConfig",
        non_finite_accepted::<ParticleFilterConfig>(|c| c.validate()),
        &[],
    );
    check(
        "PointFilterConfig",
        non_finite_accepted::<PointFilterConfig>(|c| c.validate()),
        &[],
    );
    check(
        "BackgroundDetectorConfig",
        non_finite_accepted::<BackgroundDetectorConfig>(|c| c.validate()),
        &[],
    );
    check(
        "EvalConfig",
        non_finite_accepted::<EvalConfig>(|c| c.validate()),
        &[],
    );
    check(
        "SimConfig",
        non_finite_accepted::<SimConfig>(|c| c.validate()),
        &[],
    );
    check(
        "Site",
        non_finite_accepted_from::<Site>(toml::from_str(SITE).expect("site"), |c| c.validate()),
        &[],
    );
    assert!(
        report.is_empty(),
        "validate() accepts:\n{}",
        report.join("\n")
    );
}

/// `PhdConfig.exit_speed = inf` disables the exit test (documented).
const PHD_EXIT_SPEED: &str = "exit_speed = inf";

fn committed(name: &str) -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../configs")
        .join(name);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// `configs/NAME`, parsed and validated; a panic naming the file otherwise.
fn load_committed<T: DeserializeOwned>(name: &str, validate: impl Fn(&T) -> Result<()>) -> T {
    let c: T = toml::from_str(&committed(name)).unwrap_or_else(|e| panic!("configs/{name}: {e}"));
    validate(&c).unwrap_or_else(|e| panic!("configs/{name}: {e}"));
    c
}

fn relaxation(cases: u32) {
    let a = committed("relaxation.toml");
    let b = committed("relaxation-intersection.toml");
    fuzz_config::<RelaxationConfig>("relaxation", cases, &[&a, &b], |c| c.validate(), &[]);
}

/// 2 000 cases.
#[test]
fn fuzz_relaxation_config() {
    relaxation(2000);
}

fn relaxation_tracker(cases: u32) {
    let video = committed("relaxation-video.toml");
    fuzz_config::<RelaxationTrackerConfig>(
        "relaxation_tracker",
        cases,
        &[&video],
        |c| c.validate(),
        &[],
    );
}

/// 2 000 cases.
#[test]
fn fuzz_relaxation_tracker_config() {
    relaxation_tracker(2000);
}

fn mrf(cases: u32) {
    let junction = committed("mrf-intersection.toml");
    let aerial = committed("mrf-aerial.toml");
    fuzz_config::<MrfConfig>("mrf", cases, &[&junction, &aerial], |c| c.validate(), &[]);
}

/// The committed MRF configs load, validate and differ from the default in the fields
/// their comments name, and only there: the aerial file is the junction file as it was
/// before 2026-11-30 (25 frames, unmatched objects written, no lowest match score) with a
/// 2 px distance gate.
#[test]
fn committed_mrf_configs_load() {
    let load = |name| load_committed(name, MrfConfig::validate);
    let (junction, aerial) = (load("mrf-intersection.toml"), load("mrf-aerial.toml"));
    let default = MrfConfig::default();
    assert_eq!(
        (
            junction.max_missed_frames,
            junction.appearance_scale,
            junction.write_unmatched,
            junction.min_match_score
        ),
        (40, 20.0, false, 1.0)
    );
    assert!(default.write_unmatched);
    assert_eq!(default.min_match_score, 0.0);
    assert_eq!(
        MrfConfig {
            max_missed_frames: default.max_missed_frames,
            appearance_scale: default.appearance_scale,
            write_unmatched: default.write_unmatched,
            min_match_score: default.min_match_score,
            ..junction.clone()
        },
        default
    );
    assert_eq!(aerial.gate_px, 2.0);
    assert_ne!(default.gate_px, 2.0);
    assert_eq!(
        (aerial.max_missed_frames, aerial.write_unmatched),
        (25, true)
    );
    assert_eq!(
        MrfConfig {
            gate_px: junction.gate_px,
            max_missed_frames: junction.max_missed_frames,
            write_unmatched: junction.write_unmatched,
            min_match_score: junction.min_match_score,
            ..aerial
        },
        junction
    );
}

/// 2 000 cases.
#[test]
fn fuzz_mrf_config() {
    mrf(2000);
}

fn filter_track(cases: u32) {
    let people = committed("filters-pedestrians.toml");
    let aerial = committed("phd-aerial.toml");
    let road = committed("phd-road.toml");
    let public = committed("phd-aerial-public.toml");
    fuzz_config::<FilterTrackConfig>(
        "filter_track",
        cases,
        &[&people, &aerial, &road, &public],
        |c| c.validate(),
        &[&format!("phd.{PHD_EXIT_SPEED}")],
    );
}

/// configs/phd-aerial.toml loads, validates and differs from the default in the fields its
/// comments name, and only there.
#[test]
fn committed_aerial_phd_config_loads() {
    let aerial = load_committed("phd-aerial.toml", FilterTrackConfig::validate);
    let mut want = FilterTrackConfig::default();
    want.phd.motion = ConstantVelocity::proportional(0.2, 0.05);
    want.phd.birth_speed_sigma = 0.4;
    want.phd.birth_speed_box_fraction = 0.22;
    want.phd.survival_prob = 0.99;
    want.phd.birth_rate = 0.5;
    want.phd.report_weight = 0.95;
    want.detections.phd_write_detection_centre = true;
    want.detections.min_sigma_px = 0.2;
    want.detections.sigma_box_fraction = 0.1;
    want.detections.clutter_per_frame = 5.0;
    assert_ne!(want, FilterTrackConfig::default());
    assert_eq!(aerial, want);
}

/// configs/phd-aerial-public.toml is phd-aerial.toml's motion and births with the
/// detection model of det.txt-like detections, the longer look-ahead of the count and the
/// default report weight, and nothing else.
#[test]
fn committed_aerial_public_phd_config_loads() {
    let public = load_committed("phd-aerial-public.toml", FilterTrackConfig::validate);
    let aerial = load_committed("phd-aerial.toml", FilterTrackConfig::validate);
    let default = FilterTrackConfig::default();
    let mut want = FilterTrackConfig {
        count_lag_frames: 2,
        ..aerial
    };
    want.phd.survival_prob = 0.995;
    want.phd.report_weight = default.phd.report_weight;
    want.detections.min_sigma_px = 1.0;
    want.detections.sigma_box_fraction = default.detections.sigma_box_fraction;
    want.detections.detection_prob = 0.95;
    want.detections.clutter_per_frame = 0.5;
    assert_eq!(public, want);
}

/// configs/phd-road.toml is the PHD part of filters-pedestrians.toml with the two fields of
/// the detection likelihood its comments name changed, and nothing else.
#[test]
fn committed_road_phd_config_loads() {
    let road = load_committed("phd-road.toml", FilterTrackConfig::validate);
    let people = load_committed("filters-pedestrians.toml", FilterTrackConfig::validate);
    let default = FilterTrackConfig::default();
    assert_ne!(
        (
            default.detections.detection_prob,
            default.detections.min_sigma_px
        ),
        (0.95, 1.0)
    );
    let mut want = people;
    want.pf = default.pf.clone();
    want.detections.pf_write_detection_centre = default.detections.pf_write_detection_centre;
    want.detections.detection_prob = 0.95;
    want.detections.min_sigma_px = 1.0;
    assert_eq!(road, want);
}

/// 3 000 cases (the largest config: detector, PF, PHD and likelihood tables).
#[test]
fn fuzz_filter_track_config() {
    filter_track(3000);
}

fn phd(cases: u32) {
    let a = committed("phd.toml");
    fuzz_config::<PhdConfig>("phd", cases, &[&a], |c| c.validate(), &[PHD_EXIT_SPEED]);
}

/// 2 000 cases.
#[test]
fn fuzz_phd_config() {
    phd(2000);
}

fn particle(cases: u32) {
    fuzz_config::<ParticleFilterConfig>("particle", cases, &[], |c| c.validate(), &[]);
}

/// 2 000 cases.
#[test]
fn fuzz_particle_filter_config() {
    particle(2000);
}

fn point_filter(cases: u32) {
    fuzz_config::<PointFilterConfig>("point_filter", cases, &[], |c| c.validate(), &[]);
}

/// 2 000 cases.
#[test]
fn fuzz_point_filter_config() {
    point_filter(2000);
}

fn background(cases: u32) {
    let people = committed("detect-pedestrians.toml");
    let mixed = committed("detect-intersection.toml");
    fuzz_config::<BackgroundDetectorConfig>(
        "background",
        cases,
        &[&people, &mixed],
        |c| c.validate(),
        &[],
    );
}

/// The committed detector configs load, validate and differ from the default where they
/// say they do.
#[test]
fn committed_detector_configs_load() {
    let load = |name| load_committed(name, BackgroundDetectorConfig::validate);
    let (people, mixed) = (
        load("detect-pedestrians.toml"),
        load("detect-intersection.toml"),
    );
    let default = BackgroundDetectorConfig::default();
    assert!(people.split.columns && people.regions.age_gap_s == 0.0);
    assert_eq!(mixed.regions.min_person_share, 0.4);
    assert_eq!(people.regions.person_min_area_px, 20);
    // Everything else of the intersection config is the default's.
    let mut rest = mixed.clone();
    rest.regions.person_min_area_px = default.regions.person_min_area_px;
    assert_ne!(rest.regions.person_min_area_px, 20);
    assert_eq!(rest, default);
}

/// 2 000 cases.
#[test]
fn fuzz_background_detector_config() {
    background(2000);
}

fn eval(cases: u32) {
    fuzz_config::<EvalConfig>("eval", cases, &[], |c| c.validate(), &[]);
}

/// 2 000 cases.
#[test]
fn fuzz_eval_config() {
    eval(2000);
}

/// The zones example of `roadtrack analyze --help`.
const SITE: &str = "coordinates = \"ground\"\n[[line]]\nname = \"stop line N\"\na = [-6.0, 10.0]\nb = [6.0, 10.0]\n[[zone]]\nname = \"N\"\npolygon = [[-6, 10], [6, 10], [6, 30], [-6, 30]]\n[[lane]]\nname = \"lane 1\"\npolygon = [[0, 0], [700, 0], [700, 3.5], [0, 3.5]]\n[stitch]\nmax_gap_s = 1.0\nmax_distance = 3.0\n";

fn site(cases: u32) {
    fuzz_config::<Site>("site", cases, &[SITE], |c| c.validate(), &[]);
}

/// 2 000 cases.
#[test]
fn fuzz_site_zones() {
    site(2000);
}

fn sim(cases: u32) {
    fuzz_config::<SimConfig>("sim", cases, &[], |c| c.validate(), &[]);
}

/// 2 000 cases (the largest file: about 1.6 s for 3 000 in the dev profile).
#[test]
fn fuzz_sim_config() {
    sim(2000);
}

/// The deep runs: 100 × the cases of each config above, one `#[ignore]`d test per config
/// (so they run in parallel and one at a time).
macro_rules! deep {
    ($($test:ident: $fuzz:ident($cases:expr)),* $(,)?) => {$(
        #[test]
        #[ignore = "deep fuzzing, minutes; run with --ignored"]
        fn $test() {
            $fuzz($cases * DEEP);
        }
    )*};
}

deep! {
    deep_relaxation_config: relaxation(2000),
    deep_relaxation_tracker_config: relaxation_tracker(2000),
    deep_mrf_config: mrf(2000),
    deep_filter_track_config: filter_track(3000),
    deep_phd_config: phd(2000),
    deep_particle_filter_config: particle(2000),
    deep_point_filter_config: point_filter(2000),
    deep_background_detector_config: background(2000),
    deep_eval_config: eval(2000),
    deep_site_zones: site(2000),
    deep_sim_config: sim(2000),
}

/// The configs the fuzz tests above found wrongly accepted (each the smallest file with
/// the value the fuzzer put into the default config), now rejected naming the field.
#[test]
fn regressions() {
    fn rejected<T: DeserializeOwned>(text: &str, validate: fn(&T) -> Result<()>) -> String {
        let config: T = toml::from_str(text).expect("valid TOML");
        match validate(&config) {
            Err(Error::InvalidConfig { field, .. }) => field.to_owned(),
            other => panic!("{text}: expected an invalid config, got {other:?}"),
        }
    }
    let sim = |c: &SimConfig| c.validate();
    assert_eq!(
        rejected("[render]\nsun_azimuth_deg = nan\n", sim),
        "render.sun_azimuth_deg"
    );
    assert_eq!(
        rejected("[intersection]\narm_length_m = inf\n", sim),
        "intersection.arm_length_m"
    );
    assert_eq!(
        rejected("[crossing]\nhalf_length_m = inf\n", sim),
        "crossing.half_length_m"
    );
    assert_eq!(
        rejected("[vehicles]\nmax_decel_mps2 = inf\n", sim),
        "vehicles.time_headway_s"
    );
    let mrf = |c: &MrfConfig| c.validate();
    assert_eq!(
        rejected("[background]\nthreshold_sigma = inf\n", mrf),
        "background.threshold_sigma"
    );
    let detector = |c: &BackgroundDetectorConfig| c.validate();
    assert_eq!(
        rejected("[background]\nmax_sigma = inf\n", detector),
        "background.max_sigma"
    );
}
