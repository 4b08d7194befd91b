//! The three papers' own measures (METHODS.md §1–§3):
//!
//! - [`correct_match_rate`]: seed 000's correct-match rate of a matches file against truth;
//! - [`trajectory_rmse`]: seed 004's position RMSE in x and y and speed RMSE, in px and,
//!   through a ground mapping, in m and km/h;
//! - [`detection_table`]: seed 004's TP / FP / FN table with a distance gate;
//! - [`separation_success`] and [`separation_outcomes`]: seed 002's occlusion separation
//!   success against visible area (Fig. 10), the one implementation of that curve (the MRF
//!   experiments reach it through `track::mrf::separation`).

use crate::assignment::linear_sum_assignment;
use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::io::matches::MatchRow;
use crate::io::mot::{MotGtRow, MotTrackRow};
use crate::io::occlusion::OcclusionRow;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};

// ---------------------------------------------------------------------------------------
// Correct-match rate (seed 000)

/// Correct-match rate of two-frame matching decisions.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MatchRate {
    /// Frame-1 vehicles in the truth.
    pub n_vehicles: usize,
    /// Vehicles whose decision (partner or "none") equals the truth.
    pub n_correct: usize,
    /// `n_correct / n_vehicles` (0 when there is no vehicle).
    pub rate: f64,
    /// Decided a partner, but a different one from the truth's.
    pub wrong_partner: usize,
    /// Decided "no partner" although the truth has one.
    pub missed_partner: usize,
    /// Decided a partner although the truth has none.
    pub false_partner: usize,
    /// Truth vehicles with no row in the matches file (counted wrong).
    pub undecided: usize,
}

/// Seed 000's correct-match rate (METHODS.md §1 "Measure"): the fraction of frame-1
/// vehicles whose decision equals the truth, "no partner" included.
///
/// Both inputs have the matches-CSV layout (`id1,id2[,probability]`, empty `id2` = none),
/// so `truth.csv` of `roadtrack sweep` reads with [`crate::io::matches::read_matches`].
/// Rows with an empty `id1` (appeared in frame 2) are ignored in both.
///
/// # Errors
/// An `id1` listed twice in either input.
pub fn correct_match_rate(decisions: &[MatchRow], truth: &[MatchRow]) -> Result<MatchRate> {
    let mut decided = HashMap::new();
    for d in decisions {
        if let Some(i) = d.id1
            && decided.insert(i, d.id2).is_some()
        {
            return Err(Error::Invalid(format!("matches: id1 {i} listed twice")));
        }
    }
    let mut r = MatchRate::default();
    let mut seen = std::collections::HashSet::new();
    for t in truth {
        let Some(i) = t.id1 else { continue };
        if !seen.insert(i) {
            return Err(Error::Invalid(format!("truth: id1 {i} listed twice")));
        }
        r.n_vehicles += 1;
        match (decided.get(&i).copied(), t.id2) {
            (None, _) => r.undecided += 1,
            (Some(d), t2) if d == t2 => r.n_correct += 1,
            (Some(None), _) => r.missed_partner += 1,
            (Some(Some(_)), None) => r.false_partner += 1,
            (Some(Some(_)), Some(_)) => r.wrong_partner += 1,
        }
    }
    r.rate = if r.n_vehicles == 0 {
        0.0
    } else {
        r.n_correct as f64 / r.n_vehicles as f64
    };
    Ok(r)
}

// ---------------------------------------------------------------------------------------
// Points with ids

/// An object's position in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelledPoint {
    /// 1-based frame number.
    pub frame: u32,
    /// Object or track id.
    pub id: u64,
    /// Position, px.
    pub pos_px: Point,
}

/// Box centres of the ground-truth rows with `consider = 1`.
pub fn points_from_gt(rows: &[MotGtRow]) -> Vec<LabelledPoint> {
    rows.iter()
        .filter(|r| r.consider)
        .map(|r| LabelledPoint {
            frame: r.frame,
            id: r.id,
            pos_px: r.bbox.centre(),
        })
        .collect()
}

/// Box centres of tracker rows.
pub fn points_from_tracks(rows: &[MotTrackRow]) -> Vec<LabelledPoint> {
    rows.iter()
        .map(|r| LabelledPoint {
            frame: r.frame,
            id: r.id,
            pos_px: r.bbox.centre(),
        })
        .collect()
}

fn by_frame(points: &[LabelledPoint]) -> BTreeMap<u32, Vec<&LabelledPoint>> {
    let mut m: BTreeMap<u32, Vec<&LabelledPoint>> = BTreeMap::new();
    for p in points {
        m.entry(p.frame).or_default().push(p);
    }
    m
}

/// Per-frame gated assignment: most pairs within `gate_px` first, then least total distance.
/// Returns index pairs into `a` and `b`.
fn gated_pairs(
    a: &[&LabelledPoint],
    b: &[&LabelledPoint],
    gate_px: f64,
) -> Result<Vec<(usize, usize)>> {
    // A pair beyond the gate costs more than all gated pairs together, so cardinality comes
    // first; such pairs are dropped afterwards.
    let big = gate_px * (a.len().min(b.len()) as f64 + 1.0) + 1.0;
    let cost: Vec<f64> = a
        .iter()
        .flat_map(|p| {
            b.iter().map(move |q| {
                let d = p.pos_px.distance(q.pos_px);
                if d <= gate_px { d } else { big }
            })
        })
        .collect();
    Ok(linear_sum_assignment(&cost, a.len(), b.len())?
        .into_iter()
        .filter(|&(i, j)| cost[i * b.len() + j] < big)
        .collect())
}

// ---------------------------------------------------------------------------------------
// Detection table (seed 004)

/// Detection counts with a distance gate.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct DetectionTable {
    /// Detections matched to a truth object within the gate (summed over frames).
    pub tp: u64,
    /// Detections not matched.
    pub fp: u64,
    /// Truth objects not matched (`fn` in JSON).
    #[serde(rename = "fn")]
    pub fn_: u64,
    /// `tp / (tp + fp)`.
    pub precision: f64,
    /// `tp / (tp + fn)`.
    pub recall: f64,
    /// Truth objects (ids) matched in at least one frame.
    pub objects_detected: u64,
    /// Truth objects (ids).
    pub objects: u64,
}

/// Seed 004's detection table: per frame, detections are assigned one-to-one to truth
/// positions (most pairs within `gate_px`, then least total distance); matched pairs are
/// TP, leftover detections FP, leftover truth FN. The paper's object-level count
/// ("197 of 211 vehicles") is `objects_detected` of `objects`.
///
/// # Errors
/// A gate that is not positive and finite.
pub fn detection_table(
    truth: &[LabelledPoint],
    detections: &[LabelledPoint],
    gate_px: f64,
) -> Result<DetectionTable> {
    if !(gate_px > 0.0 && gate_px.is_finite()) {
        return Err(Error::config(
            "detection_table",
            "gate_px",
            format!("{gate_px} must be > 0"),
        ));
    }
    let (t, d) = (by_frame(truth), by_frame(detections));
    let mut r = DetectionTable::default();
    let mut detected = std::collections::HashSet::new();
    let all: std::collections::BTreeSet<u32> = t.keys().chain(d.keys()).copied().collect();
    for f in all {
        let a = t.get(&f).map(Vec::as_slice).unwrap_or(&[]);
        let b = d.get(&f).map(Vec::as_slice).unwrap_or(&[]);
        let pairs = gated_pairs(a, b, gate_px)?;
        for &(i, _) in &pairs {
            detected.insert(a[i].id);
        }
        r.tp += pairs.len() as u64;
        r.fn_ += (a.len() - pairs.len()) as u64;
        r.fp += (b.len() - pairs.len()) as u64;
    }
    let ratio = |x: u64, y: u64| {
        if x + y == 0 {
            0.0
        } else {
            x as f64 / (x + y) as f64
        }
    };
    r.precision = ratio(r.tp, r.fp);
    r.recall = ratio(r.tp, r.fn_);
    r.objects_detected = detected.len() as u64;
    r.objects = truth
        .iter()
        .map(|p| p.id)
        .collect::<std::collections::HashSet<_>>()
        .len() as u64;
    Ok(r)
}

// ---------------------------------------------------------------------------------------
// Position and speed RMSE (seed 004)

/// Parameters of [`trajectory_rmse`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RmseConfig {
    /// Frames per second, for speeds. Default 10 (the paper's videos, METHODS.md §3).
    pub fps: f64,
    /// Distance within which a track and a truth object count as together in a frame, for
    /// associating track ids with truth ids. Default 100 px.
    // Choice: the paper does not say how tracks were tied to truth; its vehicle y RMSE of
    // 86.5 px shows errors of that size were kept, so the gate only associates ids and every
    // frame of an associated pair enters the RMSE.
    pub gate_px: f64,
}

impl Default for RmseConfig {
    fn default() -> Self {
        Self {
            fps: 10.0,
            gate_px: 100.0,
        }
    }
}

/// RMSE in one set of units.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Rmse {
    /// RMSE of x.
    pub x: f64,
    /// RMSE of y.
    pub y: f64,
    /// RMSE of the Euclidean position error.
    pub position: f64,
    /// RMSE of the speed (units per second; km/h for ground units).
    pub speed: f64,
}

/// Position and speed RMSE of associated track / truth pairs.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RmseReport {
    /// (truth id, track id) pairs associated.
    pub pairs: Vec<(u64, u64)>,
    /// Frames with a position error.
    pub position_samples: usize,
    /// Frames with a speed error.
    pub speed_samples: usize,
    /// In px and px/s.
    pub px: Rmse,
    /// In m and km/h, when a ground mapping was given.
    pub ground: Option<Rmse>,
}

/// Seed 004's RMSE (METHODS.md §3 "Measures"): position RMSE in x and y and speed RMSE.
///
/// Track ids are tied to truth ids once for the sequence, by the one-to-one assignment that
/// maximises the number of frames in which the pair is within `gate_px` (the identity
/// metrics' rule with a distance gate). Every frame where both ids of a pair exist gives a
/// position error; speeds are finite differences between consecutive frames (`(p_f −
/// p_{f−1}) · fps`) where both have them. `ground_from_image` maps a pixel position to
/// ground metres (a calibration; the calibration module provides one): when given, the same
/// errors are computed on mapped positions, speeds in km/h.
///
/// # Errors
/// An invalid config.
pub fn trajectory_rmse(
    truth: &[LabelledPoint],
    tracks: &[LabelledPoint],
    cfg: &RmseConfig,
    ground_from_image: Option<&dyn Fn(Point) -> Point>,
) -> Result<RmseReport> {
    if !(cfg.fps > 0.0 && cfg.fps.is_finite()) {
        return Err(Error::config(
            "RmseConfig",
            "fps",
            format!("{} must be > 0", cfg.fps),
        ));
    }
    if !(cfg.gate_px > 0.0 && cfg.gate_px.is_finite()) {
        return Err(Error::config(
            "RmseConfig",
            "gate_px",
            format!("{} must be > 0", cfg.gate_px),
        ));
    }
    // Association: frames together within the gate, per (truth id, track id).
    let (t, d) = (by_frame(truth), by_frame(tracks));
    let mut together: BTreeMap<(u64, u64), f64> = BTreeMap::new();
    for (f, a) in &t {
        let Some(b) = d.get(f) else { continue };
        for p in a {
            for q in b {
                if p.pos_px.distance(q.pos_px) <= cfg.gate_px {
                    *together.entry((p.id, q.id)).or_insert(0.0) += 1.0;
                }
            }
        }
    }
    let t_ids: Vec<u64> = together
        .keys()
        .map(|k| k.0)
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let k_ids: Vec<u64> = together
        .keys()
        .map(|k| k.1)
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let mut score = vec![0.0; t_ids.len() * k_ids.len()];
    for (i, ti) in t_ids.iter().enumerate() {
        for (j, kj) in k_ids.iter().enumerate() {
            score[i * k_ids.len() + j] = together.get(&(*ti, *kj)).copied().unwrap_or(0.0);
        }
    }
    let pairs: Vec<(u64, u64)> =
        crate::assignment::max_score_assignment(&score, t_ids.len(), k_ids.len())?
            .into_iter()
            .filter(|&(i, j)| score[i * k_ids.len() + j] > 0.0)
            .map(|(i, j)| (t_ids[i], k_ids[j]))
            .collect();
    let series = |pts: &[LabelledPoint]| -> HashMap<u64, BTreeMap<u32, Point>> {
        let mut m: HashMap<u64, BTreeMap<u32, Point>> = HashMap::new();
        for p in pts {
            m.entry(p.id).or_default().insert(p.frame, p.pos_px);
        }
        m
    };
    let (ts, ks) = (series(truth), series(tracks));
    let empty = BTreeMap::new();
    let errors = |map: &dyn Fn(Point) -> Point, speed_scale: f64| -> (Rmse, usize, usize) {
        let (mut sx, mut sy, mut n, mut sv, mut nv) = (0.0, 0.0, 0usize, 0.0, 0usize);
        for (tid, kid) in &pairs {
            let (a, b) = (ts.get(tid).unwrap_or(&empty), ks.get(kid).unwrap_or(&empty));
            for (f, pa) in a {
                let Some(pb) = b.get(f) else { continue };
                let (ga, gb) = (map(*pa), map(*pb));
                sx += (ga.x - gb.x).powi(2);
                sy += (ga.y - gb.y).powi(2);
                n += 1;
                let prev = f
                    .checked_sub(1)
                    .and_then(|p| Some((a.get(&p)?, b.get(&p)?)));
                if let Some((qa, qb)) = prev {
                    let va = map(*qa).distance(ga) * cfg.fps * speed_scale;
                    let vb = map(*qb).distance(gb) * cfg.fps * speed_scale;
                    sv += (va - vb).powi(2);
                    nv += 1;
                }
            }
        }
        let rms = |s: f64, k: usize| if k == 0 { 0.0 } else { (s / k as f64).sqrt() };
        (
            Rmse {
                x: rms(sx, n),
                y: rms(sy, n),
                position: rms(sx + sy, n),
                speed: rms(sv, nv),
            },
            n,
            nv,
        )
    };
    let (px, n, nv) = errors(&|p| p, 1.0);
    // m/s → km/h.
    let ground = ground_from_image.map(|g| errors(g, 3.6).0);
    Ok(RmseReport {
        pairs,
        position_samples: n,
        speed_samples: nv,
        px,
        ground,
    })
}

// ---------------------------------------------------------------------------------------
// Occlusion separation success (seed 002)

/// Success rate of separation at one visible area: one point of the Fig. 10 curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SeparationBin {
    /// Visible area, blocks (with a `max_bin`, the last bin holds every area at or above it).
    pub visible_blocks: u32,
    /// Occluded object-frames with this visible area.
    pub n: u64,
    /// Of which separated.
    pub separated: u64,
    /// `separated / n` (0 when there was no case).
    pub success_rate: f64,
}

/// Seed 002 Fig. 10: success rate of separation against visible area.
///
/// Without `max_bin`, one bin per visible area found in `rows` (increasing). With
/// `Some(max_bin)`, the bins `1..=max_bin` whether or not they hold a case, the last one
/// holding every area at or above `max_bin`; rows with no visible block are then left out.
pub fn separation_success(rows: &[OcclusionRow], max_bin: Option<u32>) -> Vec<SeparationBin> {
    let mut bins: BTreeMap<u32, (u64, u64)> = BTreeMap::new();
    if let Some(max_bin) = max_bin {
        for v in 1..=max_bin.max(1) {
            bins.insert(v, (0, 0));
        }
    }
    for r in rows {
        let v = match max_bin {
            None => r.visible_blocks,
            Some(_) if r.visible_blocks == 0 => continue,
            Some(m) => r.visible_blocks.min(m.max(1)),
        };
        let e = bins.entry(v).or_default();
        e.0 += 1;
        e.1 += u64::from(r.separated);
    }
    bins.into_iter()
        .map(|(v, (n, s))| SeparationBin {
            visible_blocks: v,
            n,
            separated: s,
            success_rate: if n > 0 { s as f64 / n as f64 } else { 0.0 },
        })
        .collect()
}

/// When a truth object counts as separated from the others.
///
/// Both rules first give every tracker id to the truth object whose visible blocks it
/// covers most (ties: the smaller truth id), and ask for an id given to the object itself
/// among those on its visible blocks; an object whose visible blocks carry only ids given to
/// other objects was absorbed by a neighbour, one with no labelled block was lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeparationRule {
    /// The paper's criterion: the object's own region exists in the output, however small.
    OwnRegion,
    /// Stricter: the object's own id also covers more than half of its visible blocks.
    OwnMajority,
}

/// Whether each truth object is separated under `rule`: `objects[i]` holds the truth id and
/// the visible blocks of object `i`, `tracker_id(block)` the tracker's id on a block (`None`
/// for background). One answer per object, in order; an object with no visible block is
/// not separated.
pub fn separated_objects(
    objects: &[(u64, &[usize])],
    tracker_id: &dyn Fn(usize) -> Option<u64>,
    rule: SeparationRule,
) -> Vec<bool> {
    // overlap[(tracker id, object index)] = visible blocks of the object carrying the id.
    let mut overlap: BTreeMap<(u64, usize), u32> = BTreeMap::new();
    for (t, (_, blocks)) in objects.iter().enumerate() {
        for &b in *blocks {
            if let Some(k) = tracker_id(b) {
                *overlap.entry((k, t)).or_insert(0) += 1;
            }
        }
    }
    // For each tracker id: (overlap, truth id, object index) of the object it covers most.
    let mut owner: BTreeMap<u64, (u32, u64, usize)> = BTreeMap::new();
    for (&(k, t), &n) in &overlap {
        let tid = objects[t].0;
        let better = match owner.get(&k) {
            None => true,
            Some(&(bn, btid, _)) => n > bn || (n == bn && tid < btid),
        };
        if better {
            owner.insert(k, (n, tid, t));
        }
    }
    let mut out = vec![false; objects.len()];
    for (&(k, t), &n) in &overlap {
        let visible = objects[t].1.len();
        let enough = match rule {
            SeparationRule::OwnRegion => true,
            SeparationRule::OwnMajority => 2 * n as usize > visible,
        };
        if enough && owner.get(&k).is_some_and(|o| o.2 == t) {
            out[t] = true;
        }
    }
    out
}

/// Occlusion outcomes of one frame from block maps (row-major grids of the same size; `None`
/// = background): `truth_map` holds the visible truth object of each block, `tracker_map`
/// the tracker's id. `occluded(id)` says which truth objects are occluded in this frame
/// (for example: visible area smaller than the object's full area). Whether an object is
/// separated follows `rule` ([`separated_objects`]). Rows in increasing truth id.
///
/// # Errors
/// Maps of different sizes.
pub fn separation_outcomes(
    frame: u32,
    truth_map: &[Option<u64>],
    tracker_map: &[Option<u64>],
    occluded: &dyn Fn(u64) -> bool,
    rule: SeparationRule,
) -> Result<Vec<OcclusionRow>> {
    if truth_map.len() != tracker_map.len() {
        return Err(Error::Invalid(format!(
            "separation: truth map has {} blocks, tracker map {}",
            truth_map.len(),
            tracker_map.len()
        )));
    }
    let mut visible: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (b, t) in truth_map.iter().enumerate() {
        if let Some(t) = t {
            visible.entry(*t).or_default().push(b);
        }
    }
    let objects: Vec<(u64, &[usize])> = visible.iter().map(|(&id, b)| (id, &b[..])).collect();
    let separated = separated_objects(&objects, &|b| tracker_map[b], rule);
    Ok(objects
        .iter()
        .zip(separated)
        .filter(|((id, _), _)| occluded(*id))
        .map(|(&(id, blocks), separated)| OcclusionRow {
            frame,
            id,
            visible_blocks: blocks.len() as u32,
            separated,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lp(frame: u32, id: u64, x: f64, y: f64) -> LabelledPoint {
        LabelledPoint {
            frame,
            id,
            pos_px: Point::new(x, y),
        }
    }

    fn m(id1: Option<u64>, id2: Option<u64>) -> MatchRow {
        MatchRow {
            id1,
            id2,
            probability: None,
        }
    }

    #[test]
    fn correct_match_rate_counts_each_kind_of_error() -> Result<()> {
        let truth = [
            m(Some(1), Some(10)),
            m(Some(2), None),
            m(Some(3), Some(30)),
            m(Some(4), Some(40)),
            m(Some(5), Some(50)),
            m(None, Some(60)),
        ];
        let got = [
            m(Some(1), Some(10)),
            m(Some(2), None),
            m(Some(3), Some(40)),
            m(Some(4), None),
            m(None, Some(60)),
        ];
        let r = correct_match_rate(&got, &truth)?;
        assert_eq!(
            (
                r.n_vehicles,
                r.n_correct,
                r.wrong_partner,
                r.missed_partner,
                r.undecided
            ),
            (5, 2, 1, 1, 1)
        );
        assert_eq!(r.rate, 0.4);
        let r = correct_match_rate(&[m(Some(2), Some(9))], &[m(Some(2), None)])?;
        assert_eq!(r.false_partner, 1);
        assert!(correct_match_rate(&[m(Some(1), None), m(Some(1), None)], &truth).is_err());
        Ok(())
    }

    #[test]
    fn detection_table_gates_by_distance_and_prefers_more_matches() -> Result<()> {
        let truth = [lp(1, 1, 0.0, 0.0), lp(1, 2, 10.0, 0.0), lp(2, 1, 0.0, 0.0)];
        // Frame 1: the detection at 6 could take truth 2 (4 away) or truth 1 (6 away); taking
        // truth 1 lets the one at -5 match too: 2 TP, not 1.
        let det = [
            lp(1, 1, 6.0, 0.0),
            lp(1, 2, -5.0, 100.0),
            lp(1, 3, -5.0, 0.0),
            lp(2, 1, 50.0, 0.0),
        ];
        let r = detection_table(&truth, &det, 8.0)?;
        assert_eq!((r.tp, r.fp, r.fn_), (2, 2, 1));
        assert_eq!((r.objects_detected, r.objects), (2, 2));
        assert!(detection_table(&truth, &det, 0.0).is_err());
        Ok(())
    }

    #[test]
    fn rmse_of_a_known_offset_and_speed_in_ground_units() -> Result<()> {
        // Truth moves 2 px/frame in x; the track moves 3 px/frame from the same start and
        // is 4 px lower: x errors 1..5 px, y error 4 px, speeds 20 and 30 px/s.
        let truth: Vec<_> = (1..=5).map(|f| lp(f, 1, 2.0 * f64::from(f), 0.0)).collect();
        let track: Vec<_> = (1..=5).map(|f| lp(f, 9, 3.0 * f64::from(f), 4.0)).collect();
        let cfg = RmseConfig {
            fps: 10.0,
            gate_px: 50.0,
        };
        let half = |p: Point| Point::new(p.x * 0.5, p.y * 0.5); // 0.5 m per px
        let r = trajectory_rmse(&truth, &track, &cfg, Some(&half))?;
        assert_eq!(r.pairs, [(1, 9)]);
        assert_eq!((r.position_samples, r.speed_samples), (5, 4));
        assert!((r.px.x - 11.0f64.sqrt()).abs() < 1e-12 && (r.px.y - 4.0).abs() < 1e-12);
        assert!((r.px.position - 27.0f64.sqrt()).abs() < 1e-12);
        assert!((r.px.speed - 10.0).abs() < 1e-9, "30 vs 20 px/s");
        let g = r.ground.unwrap_or_default();
        assert!((g.position - 27.0f64.sqrt() / 2.0).abs() < 1e-12);
        assert!((g.speed - 18.0).abs() < 1e-9, "5 m/s = 18 km/h");
        Ok(())
    }

    #[test]
    fn rmse_associates_ids_by_frames_together() -> Result<()> {
        // Track 7 follows truth 1 for 3 frames, then truth 2 for 1 frame: it is tied to 1.
        let truth = [
            lp(1, 1, 0.0, 0.0),
            lp(2, 1, 0.0, 0.0),
            lp(3, 1, 0.0, 0.0),
            lp(4, 1, 0.0, 0.0),
            lp(4, 2, 500.0, 0.0),
        ];
        let track = [
            lp(1, 7, 1.0, 0.0),
            lp(2, 7, 1.0, 0.0),
            lp(3, 7, 1.0, 0.0),
            lp(4, 7, 500.0, 0.0),
        ];
        let r = trajectory_rmse(&truth, &track, &RmseConfig::default(), None)?;
        assert_eq!(r.pairs, [(1, 7)]);
        assert_eq!(r.position_samples, 4);
        assert!((r.px.x - ((3.0 + 500.0f64 * 500.0) / 4.0).sqrt()).abs() < 1e-9);
        Ok(())
    }

    #[test]
    fn separation_is_judged_from_block_maps_and_binned_by_visible_area() -> Result<()> {
        // Truth: object 1 has 4 visible blocks, object 2 has 2. Tracker id 5 covers all of 1
        // and one block of 2; id 6 covers the other block of 2 — not more than half: absorbed.
        let truth = [Some(1), Some(1), Some(1), Some(1), Some(2), Some(2), None];
        let track = [Some(5), Some(5), Some(5), Some(5), Some(5), Some(6), None];
        let rows = separation_outcomes(3, &truth, &track, &|_| true, SeparationRule::OwnMajority)?;
        assert_eq!(
            rows,
            [
                OcclusionRow {
                    frame: 3,
                    id: 1,
                    visible_blocks: 4,
                    separated: true
                },
                OcclusionRow {
                    frame: 3,
                    id: 2,
                    visible_blocks: 2,
                    separated: false
                },
            ]
        );
        let mut all = rows.clone();
        all.push(OcclusionRow {
            frame: 4,
            id: 2,
            visible_blocks: 2,
            separated: true,
        });
        let bins = separation_success(&all, None);
        assert_eq!(bins.len(), 2);
        assert_eq!(
            (bins[0].visible_blocks, bins[0].n, bins[0].success_rate),
            (2, 2, 0.5)
        );
        // With bins 1..=3, "≥ 3" holds object 1's 4 blocks; bin 1 is empty.
        let fixed = separation_success(&all, Some(3));
        assert_eq!(
            fixed
                .iter()
                .map(|b| (b.visible_blocks, b.n, b.separated))
                .collect::<Vec<_>>(),
            [(1, 0, 0), (2, 2, 1), (3, 1, 1)]
        );
        assert_eq!(fixed[0].success_rate, 0.0);
        // The paper's rule: id 6 is object 2's own region, however small.
        let own = separation_outcomes(3, &truth, &track, &|_| true, SeparationRule::OwnRegion)?;
        assert_eq!(
            own.iter().map(|r| r.separated).collect::<Vec<_>>(),
            [true, true]
        );
        assert!(
            separation_outcomes(1, &truth, &track[..3], &|_| true, SeparationRule::OwnRegion)
                .is_err()
        );
        Ok(())
    }
}
