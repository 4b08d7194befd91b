//! Offline gap closing ([`GapLinkStage`]): after the whole sequence is tracked, a track that
//! ends and a track that starts soon after (or a few frames before, while the first one
//! coasts) where the first one's motion says it would be are joined under the first one's
//! id, and the frames between are filled with interpolated boxes. This is the life cycle's
//! "re-link fragments" step (issue 14 item 1), in the spirit of u-track's and trackpy's gap
//! closing: each method keeps its own association; the stage only joins what it left
//! broken.
//!
//! For a track `a` ending and a track `b` starting (`a` cut to its frames before `b`'s
//! first, gap `g` frames between `a`'s last kept point and `b`'s first):
//!
//! - `a`'s velocity `v_a` from its last `velocity_frames + 1` points, `b`'s `v_b` from its
//!   first (constant velocity; 0 for a one-point track);
//! - error `d = (|p_a + g·v_a − p_b| + |p_b − g·v_b − p_a|) / 2`, px (both ways, so neither
//!   track's velocity alone decides);
//! - gate `s · (gate + gate_growth · g)`, `s` = the mean of the two boxes' longer sides;
//!   boxes more than `max_size_ratio` apart in width or height never join;
//! - cost `d / gate`; the joins are the minimum-cost one-to-one assignment of ends to starts
//!   ([`crate::assignment::linear_sum_assignment`], per connected group of candidates), so
//!   each track gets at most one predecessor and one successor and chains form.
//!
//! Colour (when `colour_gate` > 0 and the run has images): the stage takes each point's
//! mean colour from the frame, over the central half of its box (width and height halved,
//! so that little of the road around the object counts), as the frame passes
//! ([`PointStage::see_image`]). A track's end colour is the mean over its last
//! `velocity_frames + 1` points, its start colour over its first; pairs whose colours are
//! more than `colour_gate` apart (Euclidean RGB, 0–255 per channel) never join, and the
//! others add `colour_weight · distance / colour_gate` to their cost. Choice: the box's
//! centre rather than a mask (points carry boxes only) and the mean rather than a histogram
//! (a few pixels for far objects).
//!
//! The stage holds every frame until the end of the run (memory: all points of the
//! sequence) and releases them all at [`PointStage::finish`].

use super::FramePoints;
use super::pipeline::PointStage;
use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::track_point::TrackPoint;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of [`GapLinkStage`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LinkConfig {
    /// Most frames between a track's end and the next one's start, frames. 0 turns gap
    /// closing off (the default).
    pub max_gap_frames: u32,
    /// Most frames a new track may start before the old one ends (the old one's last
    /// points, usually coasted, are dropped). Default 4.
    pub max_overlap_frames: u32,
    /// Gate at a one-frame gap, as a fraction of the box's longer side. Default 0.5.
    pub gate: f64,
    /// Growth of the gate per frame of gap, fraction of the box side. Default 0.05.
    pub gate_growth: f64,
    /// Widths or heights more than this ratio apart never join. Default 2.
    pub max_size_ratio: f64,
    /// Frames over which a track's end (start) velocity, and colour, is measured.
    /// Default 5.
    pub velocity_frames: u32,
    /// Colours of an end and a start further apart than this (Euclidean RGB distance,
    /// 0–255 per channel) never join. 0 (the default) leaves colour out.
    pub colour_gate: f64,
    /// Weight of the colour distance (as a fraction of `colour_gate`) in the join cost,
    /// against the motion error's (a fraction of its gate). Default 1.
    pub colour_weight: f64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            max_gap_frames: 0,
            max_overlap_frames: 4,
            gate: 0.5,
            gate_growth: 0.05,
            max_size_ratio: 2.0,
            velocity_frames: 5,
            colour_gate: 0.0,
            colour_weight: 1.0,
        }
    }
}

impl LinkConfig {
    /// The recommended settings with gap closing on (gaps up to 10 frames): the values
    /// measured on the crossing in docs/TRACKING.md "Gap closing".
    pub fn recommended() -> Self {
        Self {
            max_gap_frames: 10,
            ..Self::default()
        }
    }

    /// Whether the stage is off.
    pub fn is_off(&self) -> bool {
        self.max_gap_frames == 0
    }

    /// Whether joins look at colour.
    pub fn uses_colour(&self) -> bool {
        !self.is_off() && self.colour_gate > 0.0
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        let bad = |f: &str, m: &str| Err(Error::config("LinkConfig", f, m));
        if self.max_gap_frames > 10_000 || self.max_overlap_frames > 10_000 {
            return bad("max_gap_frames/max_overlap_frames", "at most 10000 frames");
        }
        if !(self.gate.is_finite() && self.gate > 0.0) {
            return bad("gate", "must be finite and > 0");
        }
        if !(self.gate_growth.is_finite() && self.gate_growth >= 0.0) {
            return bad("gate_growth", "must be finite and ≥ 0");
        }
        if !(self.max_size_ratio.is_finite() && self.max_size_ratio >= 1.0) {
            return bad("max_size_ratio", "must be finite and ≥ 1");
        }
        if self.velocity_frames == 0 || self.velocity_frames > 1000 {
            return bad("velocity_frames", "must be 1–1000");
        }
        if !(self.colour_gate.is_finite() && self.colour_gate >= 0.0) {
            return bad("colour_gate", "must be finite and ≥ 0");
        }
        if !(0.0..=100.0).contains(&self.colour_weight) {
            return bad("colour_weight", "must be 0–100");
        }
        Ok(())
    }
}

/// One track's points in frame order.
type Track = Vec<TrackPoint>;

/// Constant velocity, px per frame, from the first (`from_start`) or last `n + 1` points.
fn velocity(points: &[TrackPoint], n: usize, from_start: bool) -> (f64, f64) {
    let k = n.min(points.len().saturating_sub(1));
    if k == 0 {
        return (0.0, 0.0);
    }
    let (a, b) = if from_start {
        (&points[0], &points[k])
    } else {
        (&points[points.len() - 1 - k], &points[points.len() - 1])
    };
    let df = f64::from(b.frame - a.frame);
    let (ca, cb) = (a.bbox.centre(), b.bbox.centre());
    ((cb.x - ca.x) / df, (cb.y - ca.y) / df)
}

/// Mean colour of each point, by (id, frame); points without one are absent.
pub type Colours = BTreeMap<(u64, u32), [f64; 3]>;

/// Mean colour of `image` over the central half of `bbox` (width and height halved, at
/// least one pixel; clipped to the image), or `None` when that is empty.
pub fn centre_colour(image: &image::RgbImage, bbox: &crate::geometry::BBox) -> Option<[f64; 3]> {
    let half = crate::geometry::BBox::from_centre(
        bbox.centre(),
        (bbox.width / 2.0).max(1.0),
        (bbox.height / 2.0).max(1.0),
    );
    crate::detect::file::mean_colour(image, &half)
}

/// Mean of the known colours of `points` (`None` when none is known).
fn mean_colour(colours: &Colours, points: &[TrackPoint]) -> Option<[f64; 3]> {
    let mut sum = [0.0; 3];
    let mut n = 0.0;
    for p in points {
        if let Some(c) = colours.get(&(p.id, p.frame)) {
            for (s, v) in sum.iter_mut().zip(c) {
                *s += v;
            }
            n += 1.0;
        }
    }
    (n > 0.0).then(|| sum.map(|s| s / n))
}

/// A candidate join of track `a` (its points before `cut`) to track `b`.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    a: u64,
    b: u64,
    cost: f64,
}

/// The join cost of `a` into `b` (`None` outside the gates).
fn join_cost(cfg: &LinkConfig, colours: &Colours, a: &Track, b: &Track) -> Option<f64> {
    let (a0, a1) = (a.first()?, a.last()?);
    let (b0, b1) = (b.first()?, b.last()?);
    // `b` must start after `a` starts and end after `a` ends.
    if b0.frame <= a0.frame || b1.frame <= a1.frame {
        return None;
    }
    // Overlap: `b` starts while `a` still has points.
    if a1.frame >= b0.frame && a1.frame - b0.frame + 1 > cfg.max_overlap_frames {
        return None;
    }
    let kept = a.partition_point(|p| p.frame < b0.frame);
    let a = &a[..kept];
    let pa = a.last()?;
    let g = b0.frame - pa.frame;
    if g - 1 > cfg.max_gap_frames {
        return None;
    }
    // Choice: a walker's fragment never joins a car's, lorry's or bus's
    // (`ObjectClass::may_be_same_object`), as the trackers' own class gates decide.
    if !pa.class.may_be_same_object(&b0.class) {
        return None;
    }
    let ratio = |x: f64, y: f64| (x / y).max(y / x);
    if ratio(pa.bbox.width, b0.bbox.width) > cfg.max_size_ratio
        || ratio(pa.bbox.height, b0.bbox.height) > cfg.max_size_ratio
    {
        return None;
    }
    let n = cfg.velocity_frames as usize;
    let (va, vb) = (velocity(a, n, false), velocity(b, n, true));
    let gf = f64::from(g);
    let (ca, cb) = (pa.bbox.centre(), b0.bbox.centre());
    let forward = Point::new(ca.x + gf * va.0, ca.y + gf * va.1).distance(cb);
    let backward = Point::new(cb.x - gf * vb.0, cb.y - gf * vb.1).distance(ca);
    let d = 0.5 * (forward + backward);
    let side =
        0.5 * (pa.bbox.width.max(pa.bbox.height) + b0.bbox.width.max(b0.bbox.height)).max(1e-9);
    let gate = side * (cfg.gate + cfg.gate_growth * gf);
    if d > gate {
        return None;
    }
    let mut cost = d / gate;
    if cfg.colour_gate > 0.0 {
        let end = &a[a.len().saturating_sub(n + 1)..];
        let start = &b[..b.len().min(n + 1)];
        // Choice: a pair whose colour is unknown at either side is judged on motion alone.
        if let (Some(ca), Some(cb)) = (mean_colour(colours, end), mean_colour(colours, start)) {
            let dc = ((ca[0] - cb[0]).powi(2) + (ca[1] - cb[1]).powi(2) + (ca[2] - cb[2]).powi(2))
                .sqrt();
            if dc > cfg.colour_gate {
                return None;
            }
            cost += cfg.colour_weight * dc / cfg.colour_gate;
        }
    }
    Some(cost)
}

/// The joins `a → b`: a minimum-cost one-to-one assignment of ends to starts, solved per
/// connected group of candidates.
fn choose(candidates: &[Candidate]) -> Result<Vec<(u64, u64)>> {
    // Union-find over ends (even) and starts (odd) to split the problem into groups.
    let mut nodes: BTreeMap<(u64, bool), usize> = BTreeMap::new();
    for c in candidates {
        let n = nodes.len();
        nodes.entry((c.a, false)).or_insert(n);
        let n = nodes.len();
        nodes.entry((c.b, true)).or_insert(n);
    }
    let mut parent: Vec<usize> = (0..nodes.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for c in candidates {
        let (x, y) = (nodes[&(c.a, false)], nodes[&(c.b, true)]);
        let (rx, ry) = (root(&mut parent, x), root(&mut parent, y));
        if rx != ry {
            parent[rx.max(ry)] = rx.min(ry);
        }
    }
    let mut groups: BTreeMap<usize, Vec<Candidate>> = BTreeMap::new();
    for c in candidates {
        let r = root(&mut parent, nodes[&(c.a, false)]);
        groups.entry(r).or_default().push(*c);
    }
    let mut joins = Vec::new();
    for group in groups.values() {
        let ends: Vec<u64> = unique(group.iter().map(|c| c.a));
        let starts: Vec<u64> = unique(group.iter().map(|c| c.b));
        // Choice: an infeasible pair costs more than any feasible one (costs are ≤ 1 plus
        // the colour weight), so
        // the assignment never trades a feasible join for it; such pairs are dropped.
        const INFEASIBLE: f64 = 1e6;
        let mut cost = vec![INFEASIBLE; ends.len() * starts.len()];
        for c in group {
            let (Ok(i), Ok(j)) = (ends.binary_search(&c.a), starts.binary_search(&c.b)) else {
                continue;
            };
            cost[i * starts.len() + j] = c.cost;
        }
        for (i, j) in crate::assignment::linear_sum_assignment(&cost, ends.len(), starts.len())? {
            if cost[i * starts.len() + j] < INFEASIBLE {
                joins.push((ends[i], starts[j]));
            }
        }
    }
    joins.sort_unstable();
    Ok(joins)
}

fn unique(it: impl Iterator<Item = u64>) -> Vec<u64> {
    let mut v: Vec<u64> = it.collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// Joins fragments of `frames` (all frames of a run, in order) per `cfg`; returns how many
/// joins were made. Points keep their fields except the id (the chain's first track's), and
/// the dropped overlap; gap frames get interpolated boxes.
///
/// # Errors
/// The assignment solver failed (it does not on finite costs).
pub fn link(cfg: &LinkConfig, colours: &Colours, frames: &mut [FramePoints]) -> Result<usize> {
    if cfg.is_off() {
        return Ok(0);
    }
    let mut tracks: BTreeMap<u64, Track> = BTreeMap::new();
    for f in frames.iter() {
        for p in &f.points {
            tracks.entry(p.id).or_default().push(p.clone());
        }
    }
    // Candidates: for each start, the ends within the window before it.
    let mut by_end: BTreeMap<u32, Vec<u64>> = BTreeMap::new();
    for (id, t) in &tracks {
        if let Some(p) = t.last() {
            by_end.entry(p.frame).or_default().push(*id);
        }
    }
    let mut candidates = Vec::new();
    for (b, tb) in &tracks {
        let Some(b0) = tb.first() else { continue };
        let lo = b0.frame.saturating_sub(cfg.max_gap_frames + 1);
        let hi = b0.frame + cfg.max_overlap_frames.saturating_sub(1);
        for ids in by_end.range(lo..=hi).map(|(_, v)| v) {
            for a in ids {
                if a == b {
                    continue;
                }
                if let Some(cost) = join_cost(cfg, colours, &tracks[a], tb) {
                    candidates.push(Candidate { a: *a, b: *b, cost });
                }
            }
        }
    }
    let joins = choose(&candidates)?;
    if joins.is_empty() {
        return Ok(0);
    }
    let next: BTreeMap<u64, u64> = joins.iter().copied().collect();
    let prev: BTreeMap<u64, u64> = joins.iter().map(|&(a, b)| (b, a)).collect();
    // The new id of every track in a chain: the chain's first track's id.
    let mut new_id: BTreeMap<u64, u64> = BTreeMap::new();
    for id in tracks.keys() {
        if prev.contains_key(id) {
            continue;
        }
        let mut cur = *id;
        loop {
            new_id.insert(cur, *id);
            match next.get(&cur) {
                Some(n) => cur = *n,
                None => break,
            }
        }
    }
    // Where each joined track's points stop (the successor's first frame).
    let cut: BTreeMap<u64, u32> = next
        .iter()
        .filter_map(|(a, b)| Some((*a, tracks[b].first()?.frame)))
        .collect();
    let index: BTreeMap<u32, usize> = frames
        .iter()
        .enumerate()
        .map(|(i, f)| (f.frame, i))
        .collect();
    // Gap fills, computed before the points change.
    let mut fills: Vec<TrackPoint> = Vec::new();
    for (a, b) in &next {
        let stop = cut[a];
        let ta = &tracks[a];
        let Some(pa) = ta[..ta.partition_point(|p| p.frame < stop)].last() else {
            continue;
        };
        let pb = &tracks[b][0];
        let size = (pa.bbox.width, pa.bbox.height);
        for frame in pa.frame + 1..pb.frame {
            let Some(&i) = index.get(&frame) else {
                continue;
            };
            fills.push(super::interpolated_point(
                pa,
                size,
                pb,
                frame,
                frames[i].time_s,
                new_id[a],
            ));
        }
    }
    for f in frames.iter_mut() {
        let frame = f.frame;
        f.points
            .retain(|p| cut.get(&p.id).is_none_or(|&stop| frame < stop));
        for p in &mut f.points {
            p.id = new_id.get(&p.id).copied().unwrap_or(p.id);
        }
    }
    for p in fills {
        frames[index[&p.frame]].points.push(p);
    }
    for f in frames.iter_mut() {
        f.points.sort_by_key(|p| p.id);
    }
    Ok(joins.len())
}

/// The offline gap-closing stage (see the module documentation).
#[derive(Debug)]
pub struct GapLinkStage {
    config: LinkConfig,
    held: Vec<FramePoints>,
    colours: Colours,
    joins: usize,
}

impl GapLinkStage {
    /// A stage with nothing held.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn new(config: LinkConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            held: Vec::new(),
            colours: Colours::new(),
            joins: 0,
        })
    }

    /// Joins made so far (known after [`PointStage::finish`]).
    pub fn joins(&self) -> usize {
        self.joins
    }
}

impl PointStage for GapLinkStage {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        self.held.push(frame);
        Ok(Vec::new())
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        let mut frames = std::mem::take(&mut self.held);
        let colours = std::mem::take(&mut self.colours);
        self.joins += link(&self.config, &colours, &mut frames)?;
        Ok(frames)
    }

    fn wants_images(&self) -> bool {
        self.config.uses_colour()
    }

    fn see_image(&mut self, points: &FramePoints, image: &crate::frame::Frame) {
        for p in &points.points {
            if let Some(c) = centre_colour(&image.image, &p.bbox) {
                self.colours.insert((p.id, p.frame), c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::class::ObjectClass;
    use crate::geometry::BBox;
    use rand::RngExt;

    fn point(frame: u32, id: u64, x: f64, y: f64, w: f64) -> TrackPoint {
        TrackPoint {
            frame,
            time_s: f64::from(frame - 1) / 10.0,
            id,
            class: ObjectClass::Pedestrian,
            bbox: BBox::from_centre(Point::new(x, y), w, 2.0 * w),
            score: 0.9,
            ground: None,
        }
    }

    use crate::track::frames_of as frames;

    /// Points of an object moving at `v` px/frame from `x0`, in `frames`, under `id`.
    fn walk(id: u64, frames: std::ops::RangeInclusive<u32>, x0: f64, v: f64) -> Vec<TrackPoint> {
        frames
            .map(|f| point(f, id, x0 + v * f64::from(f), 100.0, 10.0))
            .collect()
    }

    fn ids_at(out: &[FramePoints], frame: u32) -> Vec<u64> {
        out[frame as usize - 1]
            .points
            .iter()
            .map(|p| p.id)
            .collect()
    }

    #[test]
    fn off_changes_nothing() -> Result<()> {
        let mut pts = walk(1, 1..=10, 0.0, 3.0);
        pts.extend(walk(2, 14..=20, 0.0, 3.0));
        let input = frames(&pts, 20);
        let mut out = input.clone();
        assert_eq!(link(&LinkConfig::default(), &Colours::new(), &mut out)?, 0);
        assert_eq!(out, input);
        Ok(())
    }

    #[test]
    fn a_broken_track_is_joined_and_its_gap_filled_on_the_line() -> Result<()> {
        let mut pts = walk(1, 1..=10, 0.0, 3.0);
        pts.extend(walk(2, 14..=20, 0.0, 3.0));
        let mut out = frames(&pts, 20);
        assert_eq!(
            link(&LinkConfig::recommended(), &Colours::new(), &mut out)?,
            1
        );
        for f in 1..=20 {
            assert_eq!(ids_at(&out, f), vec![1], "frame {f}");
            let c = out[f as usize - 1].points[0].bbox.centre();
            assert!(
                (c.x - 3.0 * f64::from(f)).abs() < 1e-9,
                "frame {f}: x {}",
                c.x
            );
        }
        Ok(())
    }

    #[test]
    fn a_gap_beyond_the_limit_or_a_start_off_the_path_is_not_joined() -> Result<()> {
        let cfg = LinkConfig {
            max_gap_frames: 5,
            ..LinkConfig::recommended()
        };
        // Six missing frames.
        let mut pts = walk(1, 1..=10, 0.0, 3.0);
        pts.extend(walk(2, 17..=25, 0.0, 3.0));
        let mut out = frames(&pts, 25);
        assert_eq!(link(&cfg, &Colours::new(), &mut out)?, 0);
        // On time, but 15 px (1.5 box sides) off the predicted position.
        let mut pts = walk(1, 1..=10, 0.0, 3.0);
        pts.extend(walk(2, 13..=25, 15.0, 3.0));
        let mut out = frames(&pts, 25);
        assert_eq!(link(&cfg, &Colours::new(), &mut out)?, 0);
        // On the path, but three times as large.
        let mut pts = walk(1, 1..=10, 0.0, 3.0);
        pts.extend((13..=25).map(|f| point(f, 2, 3.0 * f64::from(f), 100.0, 30.0)));
        let mut out = frames(&pts, 25);
        assert_eq!(link(&cfg, &Colours::new(), &mut out)?, 0);
        // On the path and the same size, but a car after a walker; a motorcycle may join.
        for (class, joins) in [(ObjectClass::Car, 0), (ObjectClass::Motorcycle, 1)] {
            let mut pts = walk(1, 1..=10, 0.0, 3.0);
            pts.extend(walk(2, 13..=25, 0.0, 3.0).into_iter().map(|p| TrackPoint {
                class: class.clone(),
                ..p
            }));
            let mut out = frames(&pts, 25);
            assert_eq!(link(&cfg, &Colours::new(), &mut out)?, joins, "{class:?}");
        }
        Ok(())
    }

    #[test]
    fn crossing_objects_are_joined_by_their_motion() -> Result<()> {
        // Two people pass each other at x = 60 around frame 10; both tracks break there and
        // restart under new ids. Nearest-position joining could swap them; motion does not.
        let mut pts = walk(1, 1..=9, 30.0, 3.0);
        pts.extend(walk(2, 1..=9, 90.0, -3.0));
        pts.extend(walk(3, 12..=20, 30.0, 3.0));
        pts.extend(walk(4, 12..=20, 90.0, -3.0));
        let mut out = frames(&pts, 20);
        assert_eq!(
            link(&LinkConfig::recommended(), &Colours::new(), &mut out)?,
            2
        );
        for f in 12..=20 {
            let ps = &out[f as usize - 1].points;
            let right = ps.iter().find(|p| p.id == 1).expect("track 1 goes on");
            let left = ps.iter().find(|p| p.id == 2).expect("track 2 goes on");
            assert!(right.bbox.centre().x > 30.0 + 3.0 * f64::from(f) - 1e-9);
            assert!(left.bbox.centre().x < 90.0 - 3.0 * f64::from(f) + 1e-9);
        }
        Ok(())
    }

    #[test]
    fn an_overlap_drops_the_old_tracks_last_points_and_a_chain_keeps_the_first_id() -> Result<()> {
        let mut pts = walk(5, 1..=10, 0.0, 2.0);
        pts.extend(walk(9, 9..=20, 0.5, 2.0)); // starts two frames before 5 ends
        pts.extend(walk(7, 24..=30, 0.0, 2.0)); // then a 3-frame gap
        let mut out = frames(&pts, 30);
        assert_eq!(
            link(&LinkConfig::recommended(), &Colours::new(), &mut out)?,
            2
        );
        for f in 1..=30 {
            assert_eq!(ids_at(&out, f), vec![5], "frame {f}");
        }
        // Frames 9 and 10 hold the new track's points, not the old one's.
        assert_eq!(out[8].points[0].bbox.centre().x, 18.5);
        Ok(())
    }

    #[test]
    fn colour_joins_what_motion_alone_would_swap() -> Result<()> {
        // Two people stand 4 px apart (1 red, 2 blue); both tracks break and restart on
        // the other's side (3 red at 54, 4 blue at 50). Motion alone joins each to the
        // nearer start (1 → 4, 2 → 3); colour joins red to red and blue to blue.
        let still = |id, frames: std::ops::RangeInclusive<u32>, x| walk(id, frames, x, 0.0);
        let mut pts = still(1, 1..=10, 50.0);
        pts.extend(still(2, 1..=10, 54.0));
        pts.extend(still(3, 13..=20, 54.0));
        pts.extend(still(4, 13..=20, 50.0));
        let red = [200.0, 30.0, 30.0];
        let blue = [30.0, 30.0, 200.0];
        let colours: Colours = pts
            .iter()
            .map(|p| ((p.id, p.frame), if p.id % 2 == 1 { red } else { blue }))
            .collect();
        let by_motion = |out: &[FramePoints]| -> Vec<(u64, f64)> {
            out[14]
                .points
                .iter()
                .map(|p| (p.id, p.bbox.centre().x))
                .collect()
        };
        let mut out = frames(&pts, 20);
        assert_eq!(link(&LinkConfig::recommended(), &colours, &mut out)?, 2);
        assert_eq!(by_motion(&out), vec![(1, 50.0), (2, 54.0)]);
        let cfg = LinkConfig {
            colour_gate: 60.0,
            ..LinkConfig::recommended()
        };
        let mut out = frames(&pts, 20);
        assert_eq!(link(&cfg, &colours, &mut out)?, 2);
        assert_eq!(by_motion(&out), vec![(1, 54.0), (2, 50.0)]);
        // A colour change beyond the gate is never joined, however good the motion.
        let mut pts = walk(1, 1..=10, 0.0, 3.0);
        pts.extend(walk(2, 14..=20, 0.0, 3.0));
        let colours: Colours = pts
            .iter()
            .map(|p| ((p.id, p.frame), if p.id == 1 { red } else { blue }))
            .collect();
        let mut out = frames(&pts, 20);
        assert_eq!(link(&cfg, &colours, &mut out)?, 0);
        // Unknown colours leave the join to motion.
        let mut out = frames(&pts, 20);
        assert_eq!(link(&cfg, &Colours::new(), &mut out)?, 1);
        Ok(())
    }

    #[test]
    fn centre_colour_is_the_mean_over_the_boxs_central_half_inside_the_image() {
        // A 20 × 20 red square on grey; its box's central half is red only.
        let mut img = image::RgbImage::from_pixel(40, 30, image::Rgb([100, 100, 100]));
        for y in 5..25 {
            for x in 10..30 {
                img.put_pixel(x, y, image::Rgb([200, 10, 20]));
            }
        }
        let sq = BBox::new(10.0, 5.0, 20.0, 20.0);
        assert_eq!(centre_colour(&img, &sq), Some([200.0, 10.0, 20.0]));
        // Half outside the image: the part inside counts (here the right-most 5 columns of
        // the central half: x 35–39, grey).
        let edge = BBox::new(30.0, 5.0, 20.0, 20.0);
        assert_eq!(centre_colour(&img, &edge), Some([100.0, 100.0, 100.0]));
        assert_eq!(centre_colour(&img, &BBox::new(50.0, 5.0, 20.0, 20.0)), None);
    }

    /// The best joins by brute force: most joins, then least total cost.
    fn brute_force(c: &[Candidate]) -> (usize, f64) {
        fn go(c: &[Candidate], i: usize, used: &mut Vec<u64>, n: usize, cost: f64) -> (usize, f64) {
            if i == c.len() {
                return (n, cost);
            }
            let mut best = go(c, i + 1, used, n, cost);
            let (a, b) = (c[i].a, c[i].b + 1_000_000);
            if !used.contains(&a) && !used.contains(&b) {
                used.push(a);
                used.push(b);
                let r = go(c, i + 1, used, n + 1, cost + c[i].cost);
                used.truncate(used.len() - 2);
                if r.0 > best.0 || (r.0 == best.0 && r.1 < best.1 - 1e-12) {
                    best = r;
                }
            }
            best
        }
        go(c, 0, &mut Vec::new(), 0, 0.0)
    }

    #[test]
    fn the_joins_are_the_best_one_to_one_assignment() -> Result<()> {
        let mut rng = crate::rng::rng_for(7, crate::rng::Stream::Synthetic, 0);
        for _ in 0..200 {
            let n = rng.random_range(1..=9);
            let mut c: Vec<Candidate> = Vec::new();
            for _ in 0..n {
                let (a, b) = (rng.random_range(0..5u64), rng.random_range(0..5u64));
                if c.iter().any(|x| x.a == a && x.b == b) {
                    continue;
                }
                c.push(Candidate {
                    a,
                    b,
                    cost: rng.random_range(0.0..1.0),
                });
            }
            let joins = choose(&c)?;
            let cost: f64 = joins
                .iter()
                .map(|(a, b)| {
                    c.iter()
                        .find(|x| x.a == *a && x.b == *b)
                        .map_or(f64::NAN, |x| x.cost)
                })
                .sum();
            let (n_best, cost_best) = brute_force(&c);
            assert_eq!(joins.len(), n_best, "{c:?}");
            assert!(
                (cost - cost_best).abs() < 1e-9,
                "{c:?}: {cost} vs {cost_best}"
            );
        }
        Ok(())
    }

    #[test]
    fn bad_settings_name_the_field() {
        for (cfg, field) in [
            (
                LinkConfig {
                    gate: 0.0,
                    ..LinkConfig::recommended()
                },
                "gate",
            ),
            (
                LinkConfig {
                    gate_growth: f64::NAN,
                    ..LinkConfig::recommended()
                },
                "gate_growth",
            ),
            (
                LinkConfig {
                    max_size_ratio: 0.5,
                    ..LinkConfig::recommended()
                },
                "max_size_ratio",
            ),
            (
                LinkConfig {
                    velocity_frames: 0,
                    ..LinkConfig::recommended()
                },
                "velocity_frames",
            ),
            (
                LinkConfig {
                    colour_gate: -1.0,
                    ..LinkConfig::recommended()
                },
                "colour_gate",
            ),
            (
                LinkConfig {
                    colour_weight: f64::INFINITY,
                    ..LinkConfig::recommended()
                },
                "colour_weight",
            ),
        ] {
            let e = GapLinkStage::new(cfg).expect_err("invalid").to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
