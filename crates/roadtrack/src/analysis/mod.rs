//! Traffic analysis of tracks (`roadtrack analyze`): counts across directional lines,
//! turning movements (origin–destination between zones), speed distributions, headways and
//! lane use, per class.
//!
//! Geometry (lines, zones, lanes) is given in a TOML file in ground metres or image pixels
//! (`coordinates = "ground" | "image"`). Objects are the tracks' ids, optionally stitched
//! across id switches (see [`stitch`]).

pub mod ground;
pub mod kinematics;

use crate::class::ObjectClass;
use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::track_point::TrackPoint;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Which coordinates the zones file uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Coordinates {
    /// Ground metres (needs points with `ground` set). Default.
    #[default]
    Ground,
    /// Image pixels (box centres).
    Image,
}

/// A directional counting line from `a` to `b`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CountLine {
    /// Name used in the outputs.
    pub name: String,
    /// First end.
    #[serde(deserialize_with = "crate::config::exact::array")]
    pub a: [f64; 2],
    /// Second end.
    #[serde(deserialize_with = "crate::config::exact::array")]
    pub b: [f64; 2],
}

/// A named polygon (entry/exit zone or lane).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Zone {
    /// Name used in the outputs.
    pub name: String,
    /// Vertices in order (at least 3).
    #[serde(deserialize_with = "crate::config::exact::vec_of_arrays")]
    pub polygon: Vec<[f64; 2]>,
}

/// Joining of track fragments split by an id switch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StitchConfig {
    /// Join a track that ends to one that starts at most this much later, s. Default 1 s;
    /// 0 disables stitching.
    pub max_gap_s: f64,
    /// … and whose start lies within this distance of the first track's end extrapolated at
    /// its final velocity (zone-file units: m or px). Default 3.
    pub max_distance: f64,
    /// Also join a track to one that starts up to this long *before* it ends, s, when the
    /// later one starts within `max_distance` of where the earlier one is at that moment
    /// and outlives it: a tracker that starts a second track on an object and then loses
    /// the first. The earlier track's points from the later one's start on are dropped.
    /// Default 0.5; 0 turns it off.
    // Choice: 0.5 s. On the demo's tracks (seeds 0-2, four methods, learned detector and
    // public detections; demo::tests::turning_error_by_stitch_overlap) 0.5 s lowers the
    // turning error in 8 of 24 runs and raises it in none; 1-5 s lower it more with the
    // learned detector but break a trip of the MRF's on public detections (seed 1).
    pub max_overlap_s: f64,
}

impl Default for StitchConfig {
    fn default() -> Self {
        Self {
            max_gap_s: 1.0,
            max_distance: 3.0,
            max_overlap_s: 0.5,
        }
    }
}

/// Lines, zones and lanes of a site (the `--zones` TOML file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct Site {
    /// Coordinates of every vertex below.
    pub coordinates: Coordinates,
    /// Counting lines (`[[line]]`).
    pub line: Vec<CountLine>,
    /// Entry/exit zones for turning movements (`[[zone]]`).
    pub zone: Vec<Zone>,
    /// Lanes (`[[lane]]`), for lane use.
    pub lane: Vec<Zone>,
    /// Fragment stitching (`[stitch]`).
    pub stitch: StitchConfig,
}

impl crate::config::Validate for Site {
    fn validate(&self) -> crate::error::Result<()> {
        Site::validate(self)
    }
}

impl Site {
    /// Checks the geometry: finite coordinates (NaN would count crossings everywhere), zones
    /// with 3 or more vertices, lines of non-zero length, stitching limits ≥ 0.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the table (`line`, `zone`, `lane`, `stitch`) and the
    /// item by its name.
    pub fn validate(&self) -> Result<()> {
        let finite = |p: &[f64; 2]| p.iter().all(|v| v.is_finite());
        for (table, zones) in [("zone", &self.zone), ("lane", &self.lane)] {
            for z in zones {
                if z.polygon.len() < 3 {
                    return Err(Error::config(
                        "Site",
                        table,
                        format!("`{}` needs at least 3 vertices", z.name),
                    ));
                }
                if let Some(p) = z.polygon.iter().find(|p| !finite(p)) {
                    return Err(Error::config(
                        "Site",
                        table,
                        format!("`{}` has a non-finite vertex {p:?}", z.name),
                    ));
                }
            }
        }
        for l in &self.line {
            if !(finite(&l.a) && finite(&l.b)) {
                return Err(Error::config(
                    "Site",
                    "line",
                    format!(
                        "`{}` has a non-finite end (a = {:?}, b = {:?})",
                        l.name, l.a, l.b
                    ),
                ));
            }
            if l.a == l.b {
                return Err(Error::config(
                    "Site",
                    "line",
                    format!("`{}` has both ends at the same point", l.name),
                ));
            }
        }
        crate::error::check_range("Site", "stitch.max_gap_s", self.stitch.max_gap_s, 0.0..)?;
        crate::error::check_range(
            "Site",
            "stitch.max_distance",
            self.stitch.max_distance,
            0.0..,
        )?;
        crate::error::check_range(
            "Site",
            "stitch.max_overlap_s",
            self.stitch.max_overlap_s,
            0.0..,
        )?;
        Ok(())
    }
}

/// One object: a track, or several stitched together.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// The ids of its fragments, in time order.
    pub ids: Vec<u64>,
    /// Most frequent known class of its points.
    pub class: ObjectClass,
    /// (time s, position in site coordinates, speed m/s when known), in time order.
    pub samples: Vec<(f64, Point, Option<f64>)>,
}

/// Crossings counted at one line in one direction for one class.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LineCount {
    /// Line name.
    pub line: String,
    /// `left_to_right` or `right_to_left`, seen from `a` looking towards `b` with y up
    /// (the mathematical orientation; in image coordinates, where y points down, the sides
    /// appear mirrored).
    pub direction: String,
    /// Class name.
    pub class: String,
    /// Objects that crossed (each object at most once per line and direction).
    pub count: u64,
}

/// Objects per origin and destination zone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OdCount {
    /// First zone the object was in.
    pub origin: String,
    /// Last zone the object was in.
    pub destination: String,
    /// Class name.
    pub class: String,
    /// Objects.
    pub count: u64,
}

/// Distribution of per-object speeds of one class.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SpeedStats {
    /// Class name.
    pub class: String,
    /// Objects with a speed.
    pub objects: u64,
    /// Mean of the per-object median speeds, m/s.
    pub mean_mps: f64,
    /// Median, m/s.
    pub median_mps: f64,
    /// 85th percentile, m/s (linear interpolation).
    pub p85_mps: f64,
    /// Smallest, m/s.
    pub min_mps: f64,
    /// Largest, m/s.
    pub max_mps: f64,
}

/// Time gaps between successive crossings of a line in one direction (all classes).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeadwayStats {
    /// Line name.
    pub line: String,
    /// Direction, as in [`LineCount`].
    pub direction: String,
    /// Number of headways (crossings − 1).
    pub n: u64,
    /// Mean, s.
    pub mean_s: f64,
    /// Median, s.
    pub median_s: f64,
    /// Smallest, s.
    pub min_s: f64,
}

/// Objects per lane (each object assigned to the lane holding most of its samples).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LaneUse {
    /// Lane name.
    pub lane: String,
    /// Class name.
    pub class: String,
    /// Objects.
    pub objects: u64,
    /// Share of all objects of this class that were in some lane.
    pub share: f64,
}

/// Everything `roadtrack analyze` reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    /// Objects after stitching.
    pub objects: u64,
    /// Track ids before stitching.
    pub tracks: u64,
    /// Line counts.
    pub counts: Vec<LineCount>,
    /// Origin–destination counts (turning movements).
    pub od: Vec<OdCount>,
    /// Objects first and last seen in the same zone: not a trip through the junction in
    /// the observed time (or a broken track), reported apart, never as a U-turn
    /// (`origin` = `destination` = that zone).
    pub od_incomplete: Vec<OdCount>,
    /// Objects whose trajectory touched no zone (when zones are given).
    pub od_unassigned: u64,
    /// Speed distributions per class (when points carry ground speeds).
    pub speeds: Vec<SpeedStats>,
    /// Headways per line and direction.
    pub headways: Vec<HeadwayStats>,
    /// Lane use per lane and class.
    pub lanes: Vec<LaneUse>,
}

/// Groups points into objects in site coordinates, stitching fragments per `site.stitch`.
///
/// Choice: stitching is greedy in time order. For each track end, the candidate starts are
/// later tracks of the same class (or unknown class) starting within `max_gap_s`; the one
/// nearest to the end extrapolated at the final velocity is taken if within
/// `max_distance`, and each start is used once. An id switch inside a crossing therefore
/// still counts one object.
pub fn stitch(points: &[TrackPoint], site: &Site) -> Result<Vec<Object>> {
    let mut by_id: BTreeMap<u64, Vec<&TrackPoint>> = BTreeMap::new();
    for p in points {
        by_id.entry(p.id).or_default().push(p);
    }
    let mut tracks: Vec<Object> = Vec::with_capacity(by_id.len());
    for (id, mut pts) in by_id {
        pts.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        let mut classes: BTreeMap<&ObjectClass, usize> = BTreeMap::new();
        let mut samples = Vec::with_capacity(pts.len());
        for p in &pts {
            if p.class != ObjectClass::Unknown {
                *classes.entry(&p.class).or_default() += 1;
            }
            let pos = match site.coordinates {
                Coordinates::Image => p.bbox.centre(),
                Coordinates::Ground => {
                    let g = p.ground.ok_or_else(|| {
                        Error::Invalid(format!(
                            "frame {}, id {}: the zones are in ground coordinates but the track has no ground position (give a calibration)",
                            p.frame, p.id
                        ))
                    })?;
                    Point::new(g.x_m, g.y_m)
                }
            };
            samples.push((p.time_s, pos, p.ground.map(|g| g.speed_mps)));
        }
        let class = classes
            .into_iter()
            .max_by(|a, b| a.1.cmp(&b.1).then_with(|| b.0.cmp(a.0)))
            .map_or(ObjectClass::Unknown, |(c, _)| c.clone());
        tracks.push(Object {
            ids: vec![id],
            class,
            samples,
        });
    }
    if site.stitch.max_gap_s <= 0.0 {
        return Ok(tracks);
    }
    tracks.sort_by(|a, b| {
        a.samples[0]
            .0
            .total_cmp(&b.samples[0].0)
            .then(a.ids[0].cmp(&b.ids[0]))
    });
    let n = tracks.len();
    let mut next: Vec<Option<usize>> = vec![None; n];
    let mut taken = vec![false; n];
    // Ends in time order.
    let mut ends: Vec<usize> = (0..n).collect();
    let end_time = |o: &Object| o.samples.last().map_or(0.0, |s| s.0);
    ends.sort_by(|&a, &b| {
        end_time(&tracks[a])
            .total_cmp(&end_time(&tracks[b]))
            .then(a.cmp(&b))
    });
    let overlap = site.stitch.max_overlap_s;
    for &i in &ends {
        let a = &tracks[i];
        let (te, pe, _) = *a.samples.last().unwrap_or(&(0.0, Point::default(), None));
        let vel = velocity_at_end(&a.samples);
        let mut best: Option<(f64, usize)> = None;
        for (j, b) in tracks.iter().enumerate() {
            if j == i || taken[j] {
                continue;
            }
            let (ts, ps, _) = b.samples[0];
            let gap = ts - te;
            let overlapping = overlap > 0.0 && gap <= 0.0 && gap >= -overlap;
            if !(overlapping || gap > 0.0) || gap > site.stitch.max_gap_s {
                continue;
            }
            // Choice: an overlapping pair must be a hand-over (the later track starts after
            // the earlier one and outlives it), never a track inside another's life.
            if overlapping && (ts <= a.samples[0].0 || end_time(b) <= te) {
                continue;
            }
            if a.class != ObjectClass::Unknown
                && b.class != ObjectClass::Unknown
                && a.class != b.class
            {
                continue;
            }
            let predicted = if overlapping {
                position_at(&a.samples, ts)
            } else {
                Point::new(pe.x + vel.x * gap, pe.y + vel.y * gap)
            };
            let d = predicted.distance(ps);
            if d <= site.stitch.max_distance
                && best.is_none_or(|(bd, bj)| d < bd || (d == bd && j < bj))
            {
                best = Some((d, j));
            }
        }
        if let Some((_, j)) = best {
            next[i] = Some(j);
            taken[j] = true;
        }
    }
    let mut out = Vec::new();
    for start in 0..n {
        if taken[start] {
            continue;
        }
        let mut obj = tracks[start].clone();
        let mut cur = start;
        while let Some(j) = next[cur] {
            obj.ids.extend(&tracks[j].ids);
            // An overlapping hand-over: the earlier track's points from the later one's
            // start on go.
            let ts = tracks[j].samples[0].0;
            obj.samples.retain(|s| s.0 < ts);
            obj.samples.extend(tracks[j].samples.iter().copied());
            if obj.class == ObjectClass::Unknown {
                obj.class = tracks[j].class.clone();
            }
            cur = j;
        }
        out.push(obj);
    }
    out.sort_by_key(|o| o.ids[0]);
    Ok(out)
}

/// Where `samples` (in time order) are at time `t`: linear between the samples around it,
/// the first or last sample outside their span.
fn position_at(samples: &[(f64, Point, Option<f64>)], t: f64) -> Point {
    let k = samples.partition_point(|s| s.0 <= t);
    match (k.checked_sub(1).map(|i| samples[i]), samples.get(k)) {
        (Some((t0, p0, _)), Some(&(t1, p1, _))) if t1 > t0 => {
            let f = (t - t0) / (t1 - t0);
            Point::new(p0.x + f * (p1.x - p0.x), p0.y + f * (p1.y - p0.y))
        }
        (Some((_, p, _)), _) | (None, Some(&(_, p, _))) => p,
        (None, None) => Point::default(),
    }
}

fn velocity_at_end(samples: &[(f64, Point, Option<f64>)]) -> Point {
    let n = samples.len();
    if n < 2 {
        return Point::default();
    }
    let k = n.saturating_sub(5);
    let (t0, p0, _) = samples[k];
    let (t1, p1, _) = samples[n - 1];
    if t1 - t0 <= 0.0 {
        return Point::default();
    }
    Point::new((p1.x - p0.x) / (t1 - t0), (p1.y - p0.y) / (t1 - t0))
}

fn cross(o: Point, a: Point, b: Point) -> f64 {
    (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
}

/// Where and which way the segment `p → q` crosses the line `a → b`: the crossing's
/// fraction along `p → q` and `true` for left-to-right. Touching an end point counts;
/// a segment lying on the line does not.
fn crossing(a: Point, b: Point, p: Point, q: Point) -> Option<(f64, bool)> {
    let sp = cross(a, b, p);
    let sq = cross(a, b, q);
    if sp == sq || (sp > 0.0 && sq > 0.0) || (sp < 0.0 && sq < 0.0) || (sp == 0.0 && sq == 0.0) {
        return None;
    }
    // Point must pass between a and b.
    let s1 = cross(p, q, a);
    let s2 = cross(p, q, b);
    if (s1 > 0.0 && s2 > 0.0) || (s1 < 0.0 && s2 < 0.0) {
        return None;
    }
    // Choice: a sample exactly on the line counts as on the side it goes to, so an object
    // that stops on the line and moves on is counted once.
    if sp == 0.0 {
        return None;
    }
    let frac = sp / (sp - sq);
    Some((frac, sp > 0.0))
}

fn point_in_polygon(p: Point, poly: &[[f64; 2]]) -> bool {
    let mut inside = false;
    let n = poly.len();
    let mut j = n - 1;
    for i in 0..n {
        let (xi, yi) = (poly[i][0], poly[i][1]);
        let (xj, yj) = (poly[j][0], poly[j][1]);
        if (yi > p.y) != (yj > p.y) && p.x < (xj - xi) * (p.y - yi) / (yj - yi) + xi {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// `p`-th percentile (0–100) of sorted values by linear interpolation (NaN when empty).
pub(crate) fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let r = p / 100.0 * (sorted.len() - 1) as f64;
    let lo = r.floor() as usize;
    let hi = r.ceil() as usize;
    sorted[lo] + (sorted[hi] - sorted[lo]) * (r - lo as f64)
}

/// Runs every analysis on `points` for `site`.
pub fn analyze(points: &[TrackPoint], site: &Site) -> Result<Analysis> {
    site.validate()?;
    let tracks = points
        .iter()
        .map(|p| p.id)
        .collect::<std::collections::BTreeSet<_>>()
        .len() as u64;
    let objects = stitch(points, site)?;

    // Counts and crossing times.
    let mut counts: BTreeMap<(String, &'static str, String), u64> = BTreeMap::new();
    let mut crossings: BTreeMap<(String, &'static str), Vec<f64>> = BTreeMap::new();
    for line in &site.line {
        let (a, b) = (
            Point::new(line.a[0], line.a[1]),
            Point::new(line.b[0], line.b[1]),
        );
        for dir in ["left_to_right", "right_to_left"] {
            crossings.entry((line.name.clone(), dir)).or_default();
        }
        for obj in &objects {
            let mut seen = [false, false];
            for w in obj.samples.windows(2) {
                let (t0, p, _) = w[0];
                let (t1, q, _) = w[1];
                if let Some((frac, l2r)) = crossing(a, b, p, q) {
                    let k = usize::from(!l2r);
                    if seen[k] {
                        continue;
                    }
                    seen[k] = true;
                    let dir = if l2r {
                        "left_to_right"
                    } else {
                        "right_to_left"
                    };
                    *counts
                        .entry((line.name.clone(), dir, obj.class.name().to_owned()))
                        .or_default() += 1;
                    crossings
                        .entry((line.name.clone(), dir))
                        .or_default()
                        .push(t0 + frac * (t1 - t0));
                }
            }
        }
    }
    let counts = counts
        .into_iter()
        .map(|((line, direction, class), count)| LineCount {
            line,
            direction: direction.to_owned(),
            class,
            count,
        })
        .collect();
    let mut headways = Vec::new();
    for ((line, dir), mut times) in crossings {
        times.sort_by(f64::total_cmp);
        let mut gaps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
        if gaps.is_empty() {
            continue;
        }
        gaps.sort_by(f64::total_cmp);
        headways.push(HeadwayStats {
            line,
            direction: dir.to_owned(),
            n: gaps.len() as u64,
            mean_s: gaps.iter().sum::<f64>() / gaps.len() as f64,
            median_s: percentile(&gaps, 50.0),
            min_s: gaps[0],
        });
    }

    // Origin–destination.
    let mut od: BTreeMap<(String, String, String), u64> = BTreeMap::new();
    let mut incomplete: BTreeMap<(String, String, String), u64> = BTreeMap::new();
    let mut od_unassigned = 0;
    if !site.zone.is_empty() {
        for obj in &objects {
            let zone_of = |p: Point| {
                site.zone
                    .iter()
                    .find(|z| point_in_polygon(p, &z.polygon))
                    .map(|z| z.name.clone())
            };
            let first = obj.samples.iter().find_map(|s| zone_of(s.1));
            let last = obj.samples.iter().rev().find_map(|s| zone_of(s.1));
            // Choice: a turning movement is a complete trip, first seen in one zone (arm)
            // and last seen in another, so it crossed the junction. An object first and
            // last seen in the same arm (still queued when the video ends, entered and left
            // the view there, or a track broken at the junction) is counted apart in
            // `od_incomplete`; a true U-turn cannot be told from it without a junction zone
            // and is counted there too.
            match (first, last) {
                (Some(o), Some(d)) if o != d => {
                    *od.entry((o, d, obj.class.name().to_owned())).or_default() += 1
                }
                (Some(o), Some(d)) => {
                    *incomplete
                        .entry((o, d, obj.class.name().to_owned()))
                        .or_default() += 1
                }
                _ => od_unassigned += 1,
            }
        }
    }
    let od_rows = |m: BTreeMap<(String, String, String), u64>| -> Vec<OdCount> {
        m.into_iter()
            .map(|((origin, destination, class), count)| OdCount {
                origin,
                destination,
                class,
                count,
            })
            .collect()
    };
    let od = od_rows(od);
    let od_incomplete = od_rows(incomplete);

    // Speeds: per-object median of the points' ground speeds.
    let mut per_class: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for obj in &objects {
        let mut s: Vec<f64> = obj.samples.iter().filter_map(|x| x.2).collect();
        if s.is_empty() {
            continue;
        }
        s.sort_by(f64::total_cmp);
        per_class
            .entry(obj.class.name().to_owned())
            .or_default()
            .push(percentile(&s, 50.0));
    }
    let speeds = per_class
        .into_iter()
        .map(|(class, mut v)| {
            v.sort_by(f64::total_cmp);
            SpeedStats {
                class,
                objects: v.len() as u64,
                mean_mps: v.iter().sum::<f64>() / v.len() as f64,
                median_mps: percentile(&v, 50.0),
                p85_mps: percentile(&v, 85.0),
                min_mps: v[0],
                max_mps: v[v.len() - 1],
            }
        })
        .collect();

    // Lane use.
    let mut lane_counts: BTreeMap<(String, String), u64> = BTreeMap::new();
    let mut class_in_lanes: BTreeMap<String, u64> = BTreeMap::new();
    for obj in &objects {
        let mut hits = vec![0usize; site.lane.len()];
        for s in &obj.samples {
            if let Some(k) = site
                .lane
                .iter()
                .position(|l| point_in_polygon(s.1, &l.polygon))
            {
                hits[k] += 1;
            }
        }
        if let Some((k, _)) = hits
            .iter()
            .enumerate()
            .filter(|(_, h)| **h > 0)
            .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
        {
            *lane_counts
                .entry((site.lane[k].name.clone(), obj.class.name().to_owned()))
                .or_default() += 1;
            *class_in_lanes
                .entry(obj.class.name().to_owned())
                .or_default() += 1;
        }
    }
    let lanes = lane_counts
        .into_iter()
        .map(|((lane, class), objects)| {
            let total = class_in_lanes.get(&class).copied().unwrap_or(1).max(1);
            LaneUse {
                lane,
                share: objects as f64 / total as f64,
                class,
                objects,
            }
        })
        .collect();

    Ok(Analysis {
        objects: objects.len() as u64,
        tracks,
        counts,
        od,
        od_incomplete,
        od_unassigned,
        speeds,
        headways,
        lanes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::BBox;
    use crate::track_point::GroundState;

    /// A straight constant-velocity track starting at `from` in its first frame, 10 fps.
    fn track(
        id: u64,
        class: ObjectClass,
        from: (f64, f64),
        vel: (f64, f64),
        frames: std::ops::RangeInclusive<u32>,
    ) -> Vec<TrackPoint> {
        let first = *frames.start();
        frames
            .map(|f| {
                let t = f64::from(f - 1) / 10.0;
                let dt = f64::from(f - first) / 10.0;
                let c = Point::new(from.0 + vel.0 * dt, from.1 + vel.1 * dt);
                TrackPoint {
                    frame: f,
                    time_s: t,
                    id,
                    class: class.clone(),
                    bbox: BBox::from_centre(c, 4.0, 4.0),
                    score: 1.0,
                    ground: Some(GroundState {
                        x_m: c.x,
                        y_m: c.y,
                        speed_mps: vel.0.hypot(vel.1),
                        heading_deg: 0.0,
                    }),
                }
            })
            .collect()
    }

    fn site() -> Site {
        Site {
            coordinates: Coordinates::Ground,
            line: vec![CountLine {
                name: "x50".into(),
                a: [50.0, -100.0],
                b: [50.0, 100.0],
            }],
            zone: vec![
                Zone {
                    name: "W".into(),
                    polygon: vec![[-10.0, -10.0], [10.0, -10.0], [10.0, 10.0], [-10.0, 10.0]],
                },
                Zone {
                    name: "E".into(),
                    polygon: vec![[90.0, -10.0], [110.0, -10.0], [110.0, 10.0], [90.0, 10.0]],
                },
                Zone {
                    name: "N".into(),
                    polygon: vec![[40.0, 90.0], [60.0, 90.0], [60.0, 110.0], [40.0, 110.0]],
                },
            ],
            lane: vec![
                Zone {
                    name: "upper".into(),
                    polygon: vec![[-20.0, 0.0], [120.0, 0.0], [120.0, 5.0], [-20.0, 5.0]],
                },
                Zone {
                    name: "lower".into(),
                    polygon: vec![[-20.0, -5.0], [120.0, -5.0], [120.0, 0.0], [-20.0, 0.0]],
                },
            ],
            stitch: StitchConfig::default(),
        }
    }

    #[test]
    fn counts_od_speeds_headways_and_lanes_match_the_constructed_traffic() -> Result<()> {
        let mut pts = Vec::new();
        // Three cars W → E at 10 m/s in the upper lane, starting 2 s apart (headway 2 s).
        for k in 0..3u32 {
            pts.extend(track(
                u64::from(k) + 1,
                ObjectClass::Car,
                (0.0, 2.0),
                (10.0, 0.0),
                (1 + 20 * k)..=(101 + 20 * k),
            ));
        }
        // One truck E → W at 5 m/s in the lower lane.
        pts.extend(track(
            10,
            ObjectClass::Truck,
            (100.0, -2.0),
            (-5.0, 0.0),
            1..=201,
        ));
        // One pedestrian walking W → N, ending at (45, 100) short of the line x = 50.
        pts.extend(track(
            20,
            ObjectClass::Pedestrian,
            (0.0, 0.0),
            (0.9, 2.0),
            1..=501,
        ));
        let a = analyze(&pts, &site())?;
        let count = |dir: &str, class: &str| {
            a.counts
                .iter()
                .find(|c| c.direction == dir && c.class == class)
                .map_or(0, |c| c.count)
        };
        // Line from (50,−100) to (50,100) points +y; eastbound traffic crosses from its
        // left... cross((0,200),(p−a)) = −200·(p.x−50): west side positive = left.
        assert_eq!(count("left_to_right", "car"), 3);
        assert_eq!(count("right_to_left", "truck"), 1);
        let od = |o: &str, d: &str, c: &str| {
            a.od.iter()
                .find(|x| x.origin == o && x.destination == d && x.class == c)
                .map_or(0, |x| x.count)
        };
        assert_eq!(od("W", "E", "car"), 3);
        assert_eq!(od("E", "W", "truck"), 1);
        assert_eq!(od("W", "N", "pedestrian"), 1);
        let cars = a
            .speeds
            .iter()
            .find(|s| s.class == "car")
            .expect("car speeds");
        assert!((cars.median_mps - 10.0).abs() < 1e-9 && cars.objects == 3);
        let h = a
            .headways
            .iter()
            .find(|h| h.line == "x50" && h.direction == "left_to_right")
            .expect("headways");
        assert_eq!(h.n, 2);
        assert!((h.mean_s - 2.0).abs() < 1e-9, "{h:?}");
        let lane = |l: &str, c: &str| {
            a.lanes
                .iter()
                .find(|x| x.lane == l && x.class == c)
                .map_or(0, |x| x.objects)
        };
        assert_eq!((lane("upper", "car"), lane("lower", "truck")), (3, 1));
        Ok(())
    }

    /// A car driving along y = 2 at 10 m/s from x = 0: id 1 over `first`, id 2 over
    /// `second` starting at `x2`.
    fn car_in_two_ids(
        first: std::ops::RangeInclusive<u32>,
        x2: f64,
        second: std::ops::RangeInclusive<u32>,
    ) -> Vec<TrackPoint> {
        let mut pts = track(1, ObjectClass::Car, (0.0, 2.0), (10.0, 0.0), first);
        pts.extend(track(2, ObjectClass::Car, (x2, 2.0), (10.0, 0.0), second));
        pts
    }

    #[test]
    fn a_second_track_that_takes_over_an_object_is_joined_with_max_overlap() -> Result<()> {
        // One car at 10 m/s: id 1 over frames 1-60, id 2 started on it at frame 50.
        let pts = car_in_two_ids(1..=60, 49.3, 50..=110);
        let overlap = |s: f64| Site {
            stitch: StitchConfig {
                max_overlap_s: s,
                ..Default::default()
            },
            ..site()
        };
        assert_eq!(stitch(&pts, &overlap(0.0))?.len(), 2, "off at 0");
        let objects = stitch(&pts, &overlap(1.5))?;
        assert_eq!(objects.len(), 1);
        assert_eq!(objects[0].ids, vec![1, 2]);
        // Id 1's points from frame 50 on are dropped: one point per frame, in time order.
        assert_eq!(objects[0].samples.len(), 110);
        assert!(objects[0].samples.windows(2).all(|w| w[0].0 < w[1].0));
        // Too long an overlap (1 s > 0.9 s), and a track inside another's life: not joined.
        assert_eq!(stitch(&pts, &overlap(0.9))?.len(), 2);
        let inside = car_in_two_ids(1..=110, 49.3, 50..=60);
        assert_eq!(stitch(&inside, &overlap(100.0))?.len(), 2);
        Ok(())
    }

    #[test]
    fn an_id_switch_during_a_crossing_still_counts_one_object() -> Result<()> {
        // One car, id 1 up to x = 49, then id 2 from x = 51 (0.2 s later).
        let pts = car_in_two_ids(1..=50, 51.0, 52..=101);
        let a = analyze(&pts, &site())?;
        assert_eq!((a.tracks, a.objects), (2, 1));
        let total: u64 = a.counts.iter().map(|c| c.count).sum();
        assert_eq!(total, 1);
        let no_stitch = Site {
            stitch: StitchConfig {
                max_gap_s: 0.0,
                ..Default::default()
            },
            ..site()
        };
        assert_eq!(analyze(&pts, &no_stitch)?.objects, 2);
        Ok(())
    }

    #[test]
    fn back_and_forth_counts_once_per_direction() -> Result<()> {
        // A pedestrian crosses x = 50 eastwards, comes back, crosses eastwards again.
        let xs = [45.0, 48.0, 52.0, 55.0, 51.0, 49.0, 47.0, 51.0, 53.0];
        let mut pts = track(1, ObjectClass::Pedestrian, (0.0, 0.0), (0.0, 0.0), 1..=9);
        for (p, x) in pts.iter_mut().zip(xs) {
            p.bbox = BBox::from_centre(Point::new(x, 0.0), 1.0, 1.0);
            p.ground = Some(GroundState {
                x_m: x,
                y_m: 0.0,
                speed_mps: 1.0,
                heading_deg: 0.0,
            });
        }
        let a = analyze(
            &pts,
            &Site {
                zone: vec![],
                lane: vec![],
                ..site()
            },
        )?;
        let got: Vec<(&str, u64)> = a
            .counts
            .iter()
            .map(|c| (c.direction.as_str(), c.count))
            .collect();
        assert_eq!(got, [("left_to_right", 1), ("right_to_left", 1)]);
        Ok(())
    }

    #[test]
    fn ground_zones_need_ground_points() {
        let mut pts = track(1, ObjectClass::Car, (0.0, 0.0), (1.0, 0.0), 1..=3);
        pts[1].ground = None;
        let e = analyze(&pts, &site()).expect_err("no ground").to_string();
        assert!(e.contains("frame 2") && e.contains("calibration"), "{e}");
    }

    #[test]
    fn percentile_interpolates() {
        assert_eq!(percentile(&[1.0, 2.0, 3.0, 4.0, 5.0], 50.0), 3.0);
        assert!((percentile(&[0.0, 10.0], 85.0) - 8.5).abs() < 1e-12);
    }
}
