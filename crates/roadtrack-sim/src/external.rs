//! Trajectories made elsewhere (e.g. by SUMO), rendered with the simulator's cameras:
//! `roadtrack simulate --from-trajectories F.csv`.
//!
//! Header `time_s,id,class,x_m,y_m,heading_deg,length_m,width_m`, optionally `r,g,b`
//! (paint colour; drawn from the fleet distribution when absent) and `height_m` (class
//! default when absent). Positions are the footprint centre on the ground plane in the
//! scene's frame, metres; headings in degrees counter-clockwise from `+x`. Each object is
//! shown from its first to its last sample, linearly interpolated between samples (the
//! heading along the shorter arc); at a sample time the sample itself is shown exactly.

use super::config::SimConfig;
use super::traffic::AgentState;
use rand::RngExt;
use roadtrack_core::class::ObjectClass;
use roadtrack_core::error::{Error, Result};
use roadtrack_core::io::table::Table;
use roadtrack_core::limits::{MAX_DURATION_S, at_most};
use roadtrack_core::rng::{Stream, rng_for};
use std::collections::BTreeMap;
use std::path::Path;

/// One row of a trajectories file.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectorySample {
    /// Time, s.
    pub time_s: f64,
    /// Class.
    pub class: ObjectClass,
    /// Ground x, m.
    pub x_m: f64,
    /// Ground y, m.
    pub y_m: f64,
    /// Heading, degrees ccw from `+x`.
    pub heading_deg: f64,
    /// Length, m.
    pub length_m: f64,
    /// Width, m.
    pub width_m: f64,
    /// Height, m, when given.
    pub height_m: Option<f64>,
    /// Colour, when given.
    pub rgb: Option<[u8; 3]>,
}

/// Trajectories by object id, each sorted by time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ExternalTrajectories {
    tracks: BTreeMap<u64, Vec<TrajectorySample>>,
    t_first_s: f64,
    t_last_s: f64,
}

impl ExternalTrajectories {
    /// Builds from samples (any order).
    ///
    /// # Errors
    /// No samples, or two samples of one id at the same time.
    pub fn new(samples: Vec<(u64, TrajectorySample)>) -> Result<Self> {
        if samples.is_empty() {
            return Err(Error::Invalid("no trajectory samples".into()));
        }
        let mut tracks: BTreeMap<u64, Vec<TrajectorySample>> = BTreeMap::new();
        let (mut t0, mut t1) = (f64::INFINITY, f64::NEG_INFINITY);
        for (id, s) in samples {
            t0 = t0.min(s.time_s);
            t1 = t1.max(s.time_s);
            tracks.entry(id).or_default().push(s);
        }
        for (id, v) in tracks.iter_mut() {
            v.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
            if v.windows(2).any(|w| w[0].time_s == w[1].time_s) {
                return Err(Error::Invalid(format!(
                    "id {id} has two samples at the same time"
                )));
            }
        }
        Ok(Self {
            tracks,
            t_first_s: t0,
            t_last_s: t1,
        })
    }

    /// Reads a trajectories CSV (module doc).
    ///
    /// # Errors
    /// Missing columns, bad numbers, non-positive sizes, colours outside 0–255, duplicate
    /// `(id, time)`, an empty file.
    pub fn read(path: &Path) -> Result<Self> {
        let table = Table::open(path)?;
        table.require(&[
            "time_s",
            "id",
            "class",
            "x_m",
            "y_m",
            "heading_deg",
            "length_m",
            "width_m",
        ])?;
        let mut samples = Vec::new();
        let mut seen = std::collections::HashSet::new();
        table.for_each(|row| {
            let id = row
                .opt_u64("id")?
                .ok_or_else(|| row.error("id", "empty id"))?;
            let time_s = row.f64("time_s")?;
            // Choice: times lie within a day either side of 0 (docs/FORMATS.md, Limits):
            // the frames written span the file's times.
            at_most(time_s.abs(), MAX_DURATION_S, "|time_s|, s")
                .map_err(|m| row.error("time_s", m))?;
            if !seen.insert((id, time_s.to_bits())) {
                return Err(row.error(
                    "time_s",
                    format!("id {id} already has a sample at {time_s} s"),
                ));
            }
            let length_m = row.f64("length_m")?;
            let width_m = row.f64("width_m")?;
            if length_m <= 0.0 || width_m <= 0.0 {
                return Err(row.error("length_m", "sizes must be positive"));
            }
            let height_m = row.opt_f64("height_m")?;
            if height_m.is_some_and(|h| h <= 0.0) {
                return Err(row.error("height_m", "must be positive"));
            }
            let mut rgb = [0u8; 3];
            let mut n_rgb = 0;
            for (k, c) in ["r", "g", "b"].into_iter().enumerate() {
                if let Some(v) = row.opt_f64(c)? {
                    if !(0.0..=255.0).contains(&v) {
                        return Err(row.error(c, format!("colour {v} outside 0–255")));
                    }
                    rgb[k] = v.round() as u8;
                    n_rgb += 1;
                }
            }
            if n_rgb != 0 && n_rgb != 3 {
                return Err(row.error("r", "give all of r,g,b or none"));
            }
            samples.push((
                id,
                TrajectorySample {
                    time_s,
                    class: ObjectClass::from(row.opt_str("class").unwrap_or("unknown").to_owned()),
                    x_m: row.f64("x_m")?,
                    y_m: row.f64("y_m")?,
                    heading_deg: row.f64("heading_deg")?,
                    length_m,
                    width_m,
                    height_m,
                    rgb: (n_rgb == 3).then_some(rgb),
                },
            ));
            Ok(())
        })?;
        let t = Self::new(samples).map_err(|e| Error::format(path, e.to_string()))?;
        at_most(t.t_last_s - t.t_first_s, MAX_DURATION_S, "time span, s")
            .map_err(|m| Error::format(path, format!("the samples' times: {m}")))?;
        Ok(t)
    }

    /// Time of the first sample, s.
    pub fn first_time_s(&self) -> f64 {
        self.t_first_s
    }

    /// Frames at `fps` from the first to the last sample, both included.
    pub fn frames_spanned(&self, fps: f64) -> u32 {
        (((self.t_last_s - self.t_first_s) * fps + 1e-6).floor() as u32).saturating_add(1)
    }

    /// The objects at `t_s` seconds after the first sample.
    pub fn states_at(&self, t_s: f64, config: &SimConfig, seed: u64) -> Vec<AgentState> {
        let t = self.t_first_s + t_s;
        let mut out = Vec::new();
        for (&id, v) in &self.tracks {
            let (Some(first), Some(last)) = (v.first(), v.last()) else {
                continue;
            };
            if t < first.time_s || t > last.time_s {
                continue;
            }
            let i = v.partition_point(|s| s.time_s <= t).saturating_sub(1);
            let a = &v[i];
            let (x, y, heading_deg, speed) = if a.time_s == t || i + 1 >= v.len() {
                let speed = if i + 1 < v.len() {
                    seg_speed(a, &v[i + 1])
                } else if i > 0 {
                    seg_speed(&v[i - 1], a)
                } else {
                    0.0
                };
                (a.x_m, a.y_m, a.heading_deg, speed)
            } else {
                let b = &v[i + 1];
                let u = (t - a.time_s) / (b.time_s - a.time_s);
                let dh = (b.heading_deg - a.heading_deg + 180.0).rem_euclid(360.0) - 180.0;
                (
                    a.x_m + (b.x_m - a.x_m) * u,
                    a.y_m + (b.y_m - a.y_m) * u,
                    a.heading_deg + dh * u,
                    seg_speed(a, b),
                )
            };
            let mut r = rng_for(seed, Stream::Scenario, id);
            let vc = &config.vehicles;
            let default_height = match a.class {
                ObjectClass::Pedestrian => config.pedestrians.height_m[0],
                ObjectClass::Truck => vc.truck.height_m,
                ObjectClass::Bus => vc.bus.height_m,
                ObjectClass::Motorcycle | ObjectClass::Bicycle => vc.motorcycle.height_m,
                _ => vc.car.height_m,
            };
            let colour = a.rgb.unwrap_or_else(|| {
                let total: f64 = vc.colours.iter().map(|c| c.share).sum();
                let mut u = r.random::<f64>() * total;
                let mut pick = vc.colours.last().map_or([128; 3], |c| c.rgb);
                for c in &vc.colours {
                    if u < c.share {
                        pick = c.rgb;
                        break;
                    }
                    u -= c.share;
                }
                pick
            });
            out.push(AgentState {
                id,
                class: a.class.clone(),
                pos_m: [x, y],
                heading_rad: heading_deg.to_radians(),
                speed_mps: speed,
                length_m: a.length_m,
                width_m: a.width_m,
                height_m: a.height_m.unwrap_or(default_height),
                colour,
                secondary: [40, 42, 50],
            });
        }
        out
    }
}

fn seg_speed(a: &TrajectorySample, b: &TrajectorySample) -> f64 {
    (b.x_m - a.x_m).hypot(b.y_m - a.y_m) / (b.time_s - a.time_s)
}
