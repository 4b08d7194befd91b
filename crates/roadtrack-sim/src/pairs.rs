//! Two-frame vehicle matching problems for seed 000's experiment (METHODS.md §1):
//! `roadtrack simulate --pairs DT`, read by `roadtrack sweep`.
//!
//! ```text
//! OUT/
//!   pair_0001/frame1.csv   detections CSV: frame,id,x,y,w,h,r,g,b,class  (frame 1)
//!   pair_0001/frame2.csv   the same, Δt later (frame 2)
//!   pair_0001/truth.csv    id1,id2,probability: one row per frame-1 vehicle, id2 empty
//!                          when it has no partner; then one row per frame-2 vehicle
//!                          with no predecessor, id1 empty (the matches CSV layout)
//!   …
//!   calibration.toml       the whole-scene nadir calibration the pixels use
//!   pairs.toml             seed and configurations
//! ```
//!
//! Pixels are those of a nadir view of the *whole* scene at `aerial.metres_per_pixel`
//! (0.33 m/px: the 700 m road spans 2 121 px), whatever the image size: the paper's
//! helicopter HDTV frames covered the whole 700 m. Positions are the vehicles' footprint
//! centres, `w,h` the footprint's axis-aligned box, and `r,g,b` the colour a nadir camera
//! sees on the roof (paint × the renderer's top-face shading), optionally with noise.
//! Ids are shuffled within each frame so that id order says nothing about identity.

use super::config::SimConfig;
use super::scene::Scene;
use super::traffic::Traffic;
use rand::RngExt;
use rand_distr::StandardNormal;
use roadtrack_core::calibration::Calibration;
use roadtrack_core::detection::Detection;
use roadtrack_core::error::{Error, Result};
use roadtrack_core::geometry::Point;
use roadtrack_core::io::matches::MatchRow;
use roadtrack_core::rng::{Rng, Stream, rng, rng_for};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Parameters of `--pairs`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PairsConfig {
    /// Time between the two frames of a pair, s. Default 1.5 (seed 000's HDTV interval;
    /// its Table 2 also uses 0.5, 2.5 and 4).
    pub dt_s: f64,
    /// Number of pairs. Default 20.
    pub n_pairs: u32,
    /// Probability that a vehicle is missing from a frame (independently in each frame).
    /// Default 0 (seed 000 also ran "about 10 % not extracted": 0.1).
    pub drop_fraction: f64,
    /// Sd of position noise added to each centre, px. Default 0 (the paper extracted
    /// vehicles by hand).
    pub position_sd_px: f64,
    /// Sd of colour noise added to each channel, 8-bit levels. Default 4.
    pub colour_sd: f64,
    /// Time between the first frames of consecutive pairs, s. Default 20.
    pub spacing_s: f64,
    /// Traffic simulated before the first pair, s. Default 90 (the 700 m fill up).
    pub warmup_s: f64,
}

impl Default for PairsConfig {
    fn default() -> Self {
        Self {
            dt_s: 1.5,
            n_pairs: 20,
            drop_fraction: 0.0,
            position_sd_px: 0.0,
            colour_sd: 4.0,
            spacing_s: 20.0,
            warmup_s: 90.0,
        }
    }
}

impl PairsConfig {
    /// Checks every value is in range.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the bad field.
    pub fn validate(&self) -> Result<()> {
        let bad = |f: &'static str, r: &str| Err(Error::config("PairsConfig", f, r));
        if !(self.dt_s.is_finite() && self.dt_s > 0.0) {
            return bad("dt_s", "must be positive");
        }
        if self.n_pairs == 0 {
            return bad("n_pairs", "must be at least 1");
        }
        if !(0.0..1.0).contains(&self.drop_fraction) {
            return bad("drop_fraction", "must be in [0, 1)");
        }
        use roadtrack_core::error::check_range;
        check_range("PairsConfig", "position_sd_px", self.position_sd_px, 0.0..)?;
        check_range("PairsConfig", "colour_sd", self.colour_sd, 0.0..)?;
        if !(self.spacing_s.is_finite() && self.spacing_s > 0.0) {
            return bad("spacing_s", "must be finite and positive");
        }
        check_range("PairsConfig", "warmup_s", self.warmup_s, 0.0..)?;
        // Bounds (docs/FORMATS.md, Limits): the simulated time is warm-up plus a spacing
        // and a Δt per problem.
        use roadtrack_core::limits::{MAX_DURATION_S, MAX_PAIRS, at_most};
        let limit = |r: std::result::Result<(), String>, f: &'static str| {
            r.map_err(|m| Error::config("PairsConfig", f, m))
        };
        limit(at_most(self.n_pairs, MAX_PAIRS, "problems"), "n_pairs")?;
        let span = self.warmup_s + f64::from(self.n_pairs) * (self.spacing_s + self.dt_s);
        for (v, f) in [
            (self.dt_s, "dt_s"),
            (self.spacing_s, "spacing_s"),
            (self.warmup_s, "warmup_s"),
            (span, "n_pairs"),
        ] {
            limit(
                at_most(
                    v,
                    MAX_DURATION_S,
                    "simulated s: warmup_s + n_pairs × (spacing_s + dt_s)",
                ),
                f,
            )?;
        }
        Ok(())
    }
}

/// What [`write_pairs`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct PairsSummary {
    /// Pairs written.
    pub n_pairs: u32,
    /// Mean vehicles in frame 1.
    pub mean_vehicles_frame1: f64,
    /// Mean vehicles in frame 2.
    pub mean_vehicles_frame2: f64,
    /// Mean frame-1 vehicles whose partner is in frame 2.
    pub mean_true_matches: f64,
}

/// One vehicle in one frame of a pair.
struct Seen {
    id: u64,
    det: Detection,
}

/// Writes `pairs.n_pairs` matching problems into `out_dir` (module doc) from the traffic
/// of `config.scene` under `seed`. `progress(done, total)` counts pairs.
///
/// # Errors
/// Invalid configurations; files that cannot be written.
pub fn write_pairs(
    config: &SimConfig,
    pairs: &PairsConfig,
    seed: u64,
    out_dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<PairsSummary> {
    config.validate()?;
    pairs.validate()?;
    let scene = Scene::build(config, rng(seed, Stream::Scenario).random::<f64>());
    let step_s = config.max_step_s.min(pairs.dt_s);
    let n_dt = (pairs.dt_s / step_s).round() as u64;
    let step_s = pairs.dt_s / n_dt as f64;
    let ext = scene.extent_m;
    let k = config.aerial.metres_per_pixel;
    let cal = Calibration::from_nadir(k, [ext[0], ext[3]], 0.0)?;
    // Times, in steps, of every frame needed.
    let mut wanted: BTreeMap<u64, Vec<(usize, usize)>> = BTreeMap::new();
    for p in 0..pairs.n_pairs as usize {
        let t1 = pairs.warmup_s + p as f64 * pairs.spacing_s;
        let s1 = (t1 / step_s).round() as u64;
        wanted.entry(s1).or_default().push((p, 0));
        wanted.entry(s1 + n_dt).or_default().push((p, 1));
    }
    let mut traffic = Traffic::new(scene.clone(), config, seed);
    let mut frames: Vec<[Vec<Seen>; 2]> = (0..pairs.n_pairs)
        .map(|_| [Vec::new(), Vec::new()])
        .collect();
    let mut step = 0u64;
    let roof_light = 0.52 + 0.48 * config.render.sun_elevation_deg.to_radians().sin();
    for (&at, uses) in &wanted {
        while step < at {
            traffic.step(step_s);
            step += 1;
        }
        let states = traffic.states();
        for &(p, f) in uses {
            let mut r = rng_for(seed, Stream::Synthetic, ((p as u64) << 1) | f as u64);
            for a in states.iter().filter(|a| a.class.is_vehicle()) {
                if a.pos_m[0] < ext[0]
                    || a.pos_m[0] > ext[2]
                    || r.random::<f64>() < pairs.drop_fraction
                {
                    continue;
                }
                let Some(c) = cal.image_from_ground(a.pos_m[0], a.pos_m[1]) else {
                    continue;
                };
                let n = |r: &mut Rng, sd: f64| sd * r.sample::<f64, _>(StandardNormal);
                let (s, co) = a.heading_rad.sin_cos();
                let w_px = (a.length_m * co.abs() + a.width_m * s.abs()) / k;
                let h_px = (a.length_m * s.abs() + a.width_m * co.abs()) / k;
                let rgb = a.colour.map(|v| f64::from(v) * roof_light);
                let rgb =
                    [0, 1, 2].map(|i| (rgb[i] + n(&mut r, pairs.colour_sd)).clamp(0.0, 255.0));
                let pos = Point::new(
                    c.x + n(&mut r, pairs.position_sd_px),
                    c.y + n(&mut r, pairs.position_sd_px),
                );
                frames[p][f].push(Seen {
                    id: a.id,
                    det: Detection {
                        frame: f as u32 + 1,
                        id: 0,
                        pos_px: pos,
                        size_px: Some((w_px, h_px)),
                        colour_rgb: Some(rgb.map(|v| (v * 100.0).round() / 100.0)),
                        class: Some(a.class.clone()),
                        score: None,
                        area_px: None,
                    },
                });
            }
            // Shuffle, then number 1..n.
            let list = &mut frames[p][f];
            for i in (1..list.len()).rev() {
                let j = r.random_range(0..=i);
                list.swap(i, j);
            }
            for (i, s) in list.iter_mut().enumerate() {
                s.det.id = i as u64 + 1;
            }
        }
    }
    let dest = roadtrack_core::io::atomic::AtomicDir::create(out_dir)?;
    let tmp = dest.temp_path().to_owned();
    let (mut n1, mut n2, mut nm) = (0usize, 0usize, 0usize);
    for (p, [f1, f2]) in frames.iter().enumerate() {
        let dir = tmp.join(format!("pair_{:04}", p + 1));
        let d1: Vec<Detection> = f1.iter().map(|s| s.det.clone()).collect();
        let d2: Vec<Detection> = f2.iter().map(|s| s.det.clone()).collect();
        roadtrack_core::io::detections::write_detections(&dir.join("frame1.csv"), &d1)?;
        roadtrack_core::io::detections::write_detections(&dir.join("frame2.csv"), &d2)?;
        let in2: BTreeMap<u64, u64> = f2.iter().map(|s| (s.id, s.det.id)).collect();
        let in1: std::collections::HashSet<u64> = f1.iter().map(|s| s.id).collect();
        let mut rows: Vec<MatchRow> = f1
            .iter()
            .map(|s| MatchRow {
                id1: Some(s.det.id),
                id2: in2.get(&s.id).copied(),
                probability: None,
            })
            .collect();
        nm += rows.iter().filter(|r| r.id2.is_some()).count();
        let mut appeared: Vec<MatchRow> = f2
            .iter()
            .filter(|s| !in1.contains(&s.id))
            .map(|s| MatchRow {
                id1: None,
                id2: Some(s.det.id),
                probability: None,
            })
            .collect();
        appeared.sort_by_key(|r| r.id2);
        rows.extend(appeared);
        roadtrack_core::io::matches::write_matches(&dir.join("truth.csv"), &rows)?;
        n1 += f1.len();
        n2 += f2.len();
        progress(p as u64 + 1, u64::from(pairs.n_pairs));
    }
    cal.save(&tmp.join("calibration.toml"))?;
    #[derive(Serialize)]
    struct Provenance<'a> {
        seed: u64,
        pairs: &'a PairsConfig,
        simulation: &'a SimConfig,
    }
    let provenance = format!(
        "# roadtrack simulate --pairs: seed and configurations.\n{}",
        toml::to_string(&Provenance {
            seed,
            pairs,
            simulation: config
        })
        .unwrap_or_default()
    );
    roadtrack_core::io::atomic::write_bytes_atomic(&tmp.join("pairs.toml"), provenance.as_bytes())?;
    dest.commit()?;
    let n = f64::from(pairs.n_pairs);
    Ok(PairsSummary {
        n_pairs: pairs.n_pairs,
        mean_vehicles_frame1: n1 as f64 / n,
        mean_vehicles_frame2: n2 as f64 / n,
        mean_true_matches: nm as f64 / n,
    })
}
