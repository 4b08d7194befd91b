//! Offline track extension ([`ExtendStage`]): after the whole sequence is tracked, each
//! track is carried backward from its first point and forward from its last along the
//! detections no track took, while they stay on the line of its motion.
//!
//! Why: a method writes an object only once it has settled on it (the PHD's label weight
//! must pass `report_weight`, the life cycle asks for `confirm_hits` hits) and lets it go
//! some frames before the detections stop. On the aerial crossing (the PHD recipe, seeds
//! 1–3) 7–9 % of the walkers' frames at least half visible had a dot within 1.5 px and no
//! track box, 60–70 % of them before the walker's first tracked frame or after its last
//! (docs/EXPERIMENTS.md "Tracks carried to their detections' ends").
//!
//! For each track (ids in ascending order, backward then forward), starting at its end:
//!
//! - the track's motion is the least-squares line, centre against frame, through its
//!   `fit_frames` points nearest the end (the points added so far included);
//! - in the next frame out, the candidate is the nearest detection within the gate of the
//!   line's position, `max(min_gate_px, gate · longer side of the end's box)`, of a kind
//!   that may be the track's object (same class, or both vehicles, or either unknown),
//!   whose width and height are within `max_size_ratio` of the end's box when it has a
//!   size, and that no track holds: its centre is not within half a box (at least 0.5 px
//!   each way) of another track's box in that frame;
//! - found: a point at the detection's centre with the end's box size, class and score;
//!   not found: a missed frame; after `max_missed` missed frames in a row, or
//!   `max_frames` frames from the end, or at a frame where the track already has a point,
//!   the extension stops. Missed frames between the end and the last point found get boxes
//!   on the straight line between their neighbours, as the life cycle's coasting does.
//!
//! Points added by one track's extension hold their detections against the tracks after
//! it. Ids are never changed; a track is only made longer.
//!
//! The stage sees the detections the tracker was given ([`PointStage::see_detections`]),
//! holds every frame until the end of the run (memory: all points and detections of the
//! sequence) and releases them all at [`PointStage::finish`].

use super::FramePoints;
use super::pipeline::PointStage;
use crate::class::ObjectClass;
use crate::detect::FrameDetections;
use crate::error::{Error, Result};
use crate::geometry::{BBox, Point};
use crate::track_point::TrackPoint;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of [`ExtendStage`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExtendConfig {
    /// Most frames a track is carried past either end. 0 turns the stage off (the
    /// default).
    pub max_frames: u32,
    /// Missed frames in a row that end an extension. Default 5.
    // Choice: 5, 1 px and 12 points below, on the aerial crossing's held-out seeds 4–6
    // (PHD recipe, N = 1 000: HOTA 0.568 against 0.568 / 0.567 at 2 / 10 misses, 0.566 /
    // 0.567 at gates of 0.7 / 1.5 px, 0.566 / 0.569 through 6 / 24 points, 0.553 off; all
    // within the PHD's draws, so 12 points as the recipe's smoothing window;
    // docs/EXPERIMENTS.md "Tracks carried to their detections' ends").
    pub max_missed: u32,
    /// Gate around the line's position, as a fraction of the end box's longer side.
    /// Default 0.5.
    pub gate: f64,
    /// Smallest gate, px. Default 1 (a walker seen from above is a pixel wide).
    pub min_gate_px: f64,
    /// Points of the track's end (and its extension) the line goes through. Default 12.
    pub fit_frames: u32,
    /// Detections whose width or height is more than this ratio from the end box's are
    /// not taken. Default 2.
    pub max_size_ratio: f64,
}

impl Default for ExtendConfig {
    fn default() -> Self {
        Self {
            max_frames: 0,
            max_missed: 5,
            gate: 0.5,
            min_gate_px: 1.0,
            fit_frames: 12,
            max_size_ratio: 2.0,
        }
    }
}

impl ExtendConfig {
    /// Whether the stage is off.
    pub fn is_off(&self) -> bool {
        self.max_frames == 0
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        let bad = |f: &str, m: &str| Err(Error::config("ExtendConfig", f, m));
        if self.max_frames > 10_000 {
            return bad("max_frames", "at most 10000 frames");
        }
        if self.max_missed > 1000 {
            return bad("max_missed", "at most 1000 frames");
        }
        if !(self.gate.is_finite() && self.gate >= 0.0) {
            return bad("gate", "must be finite and ≥ 0");
        }
        if !(self.min_gate_px.is_finite() && self.min_gate_px > 0.0) {
            return bad("min_gate_px", "must be finite and > 0");
        }
        if self.fit_frames == 0 || self.fit_frames > 1000 {
            return bad("fit_frames", "must be 1–1000");
        }
        if !(self.max_size_ratio.is_finite() && self.max_size_ratio >= 1.0) {
            return bad("max_size_ratio", "must be finite and ≥ 1");
        }
        Ok(())
    }
}

/// What the stage keeps of a detection.
#[derive(Debug, Clone)]
struct Candidate {
    centre: Point,
    size: Option<(f64, f64)>,
    class: Option<ObjectClass>,
}

/// Whether a detection of class `det` may be a track of class `track`: the same class,
/// both vehicles, or either unknown.
// Choice: stricter than `may_be_same_object` (which lets a walker take a cyclist's box):
// an extension has no association of its own to correct a wrong kind, and a track's class
// is already its detections' majority.
fn same_kind(track: &ObjectClass, det: Option<&ObjectClass>) -> bool {
    match det {
        None | Some(ObjectClass::Unknown) => true,
        Some(_) if *track == ObjectClass::Unknown => true,
        Some(d) => d == track || d.is_vehicle() && track.is_vehicle(),
    }
}

/// Least-squares line through `(frame, centre)`, evaluated at `frame` (the mean for one
/// point or one distinct frame): the box smoother's line with every weight 1.
fn on_line(points: &[(f64, Point)], frame: f64) -> Point {
    let t: Vec<f64> = points.iter().map(|p| p.0 - frame).collect();
    let w = vec![1.0; points.len()];
    let at = |v: Vec<f64>| super::smooth::weighted_line(&t, &v, &w).0;
    Point::new(
        at(points.iter().map(|p| p.1.x).collect()),
        at(points.iter().map(|p| p.1.y).collect()),
    )
}

/// Whether `c` lies within half of `b` (at least 0.5 px each way) of `b`'s centre.
fn held_by(b: &BBox, c: Point) -> bool {
    let m = b.centre();
    (c.x - m.x).abs() <= (b.width / 2.0).max(0.5) && (c.y - m.y).abs() <= (b.height / 2.0).max(0.5)
}

/// Extends every track of `frames` (consecutive frames in order) along `detections`
/// (by frame number); returns the points added.
///
/// # Errors
/// Frames out of order (an internal error).
fn extend(
    cfg: &ExtendConfig,
    detections: &BTreeMap<u32, Vec<Candidate>>,
    frames: &mut [FramePoints],
) -> Result<usize> {
    if cfg.is_off() || frames.is_empty() {
        return Ok(0);
    }
    let first = frames[0].frame;
    if frames
        .iter()
        .enumerate()
        .any(|(i, f)| f.frame as usize != first as usize + i)
    {
        return Err(Error::Invalid(
            "internal error: the extension stage was given frames out of order".into(),
        ));
    }
    // Each track's frames (indices into `frames`), in order.
    let mut index: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (i, f) in frames.iter().enumerate() {
        for p in &f.points {
            index.entry(p.id).or_default().push(i);
        }
    }
    let empty = Vec::new();
    let mut added = 0;
    for (id, mut own) in index {
        own.dedup();
        for backward in [true, false] {
            // The track's points nearest the end to carry on, that end first.
            let mut near = own.clone();
            if !backward {
                near.reverse();
            }
            let mine: Vec<(usize, TrackPoint)> = near
                .into_iter()
                .take(cfg.fit_frames as usize)
                .filter_map(|i| {
                    let p = frames[i].points.iter().find(|p| p.id == id)?;
                    Some((i, p.clone()))
                })
                .collect();
            let Some((end_i, end)) = mine.first().cloned() else {
                continue;
            };
            let mut fit: Vec<(f64, Point)> = mine
                .iter()
                .map(|(_, p)| (f64::from(p.frame), p.bbox.centre()))
                .collect();
            let side = end.bbox.width.max(end.bbox.height);
            let gate = cfg.min_gate_px.max(cfg.gate * side);
            let mut found: Vec<TrackPoint> = Vec::new();
            let mut missed = 0;
            for step in 1..=cfg.max_frames as usize {
                let Some(i) = (if backward {
                    end_i.checked_sub(step)
                } else {
                    Some(end_i + step).filter(|&i| i < frames.len())
                }) else {
                    break;
                };
                if frames[i].points.iter().any(|p| p.id == id) {
                    break;
                }
                let frame = frames[i].frame;
                let at = on_line(&fit, f64::from(frame));
                let taken = |c: Point| {
                    frames[i]
                        .points
                        .iter()
                        .any(|p| p.id != id && held_by(&p.bbox, c))
                };
                let size_ok = |s: Option<(f64, f64)>| {
                    s.is_none_or(|(w, h)| {
                        let r = |a: f64, b: f64| a.max(b) <= cfg.max_size_ratio * a.min(b);
                        r(w, end.bbox.width) && r(h, end.bbox.height)
                    })
                };
                let best = detections
                    .get(&frame)
                    .unwrap_or(&empty)
                    .iter()
                    .filter(|c| same_kind(&end.class, c.class.as_ref()) && size_ok(c.size))
                    .map(|c| (c.centre.distance(at), c.centre))
                    .filter(|&(d, c)| d <= gate && !taken(c))
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                let Some((_, c)) = best else {
                    missed += 1;
                    if missed > cfg.max_missed {
                        break;
                    }
                    continue;
                };
                missed = 0;
                fit.insert(0, (f64::from(frame), c));
                fit.truncate(cfg.fit_frames as usize);
                // Written now, so that the tracks after this one see the detection held.
                let p = point_at(&end, frame, frames[i].time_s, c);
                frames[i].points.push(p.clone());
                found.push(p);
                own.push(i);
                added += 1;
            }
            // Missed frames between the end and the farthest point found: on the line
            // between the neighbours, as coasting fills them.
            let mut prev = &end;
            for p in &found {
                let (a, b) = if backward { (p, prev) } else { (prev, p) };
                for frame in a.frame + 1..b.frame {
                    let j = (frame - first) as usize;
                    let size = (a.bbox.width, a.bbox.height);
                    let time_s = frames[j].time_s;
                    frames[j]
                        .points
                        .push(super::interpolated_point(a, size, b, frame, time_s, id));
                    own.push(j);
                    added += 1;
                }
                prev = p;
            }
            own.sort_unstable();
        }
    }
    for f in frames.iter_mut() {
        f.points.sort_by_key(|p| p.id);
    }
    Ok(added)
}

/// A point of `end`'s track, box size, class and score at `centre` in `frame`.
fn point_at(end: &TrackPoint, frame: u32, time_s: f64, centre: Point) -> TrackPoint {
    TrackPoint {
        frame,
        time_s,
        bbox: BBox::from_centre(centre, end.bbox.width, end.bbox.height),
        ground: None,
        ..end.clone()
    }
}

/// The offline extension stage (see the module documentation).
#[derive(Debug)]
pub struct ExtendStage {
    config: ExtendConfig,
    held: Vec<FramePoints>,
    detections: BTreeMap<u32, Vec<Candidate>>,
    added: usize,
}

impl ExtendStage {
    /// A stage with nothing held.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn new(config: ExtendConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            held: Vec::new(),
            detections: BTreeMap::new(),
            added: 0,
        })
    }

    /// Points added so far (known after [`PointStage::finish`]).
    pub fn added(&self) -> usize {
        self.added
    }
}

impl PointStage for ExtendStage {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        self.held.push(frame);
        Ok(Vec::new())
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        let mut frames = std::mem::take(&mut self.held);
        let detections = std::mem::take(&mut self.detections);
        self.added += extend(&self.config, &detections, &mut frames)?;
        Ok(frames)
    }

    fn wants_detections(&self) -> bool {
        !self.config.is_off()
    }

    fn see_detections(&mut self, frame: u32, detections: &FrameDetections) {
        self.detections.insert(
            frame,
            detections
                .detections
                .iter()
                .map(|d| Candidate {
                    centre: d.pos_px,
                    size: d.size_px,
                    class: d.class.clone(),
                })
                .collect(),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::frames_of as frames;

    fn point(frame: u32, id: u64, x: f64, class: ObjectClass) -> TrackPoint {
        let bbox = BBox::from_centre(Point::new(x, 50.0), 1.0, 1.0);
        crate::track::point_at(frame, id, class, bbox)
    }

    /// A walker at `x0 + v·f` tracked in `frames` under `id`.
    fn walk(id: u64, frames: std::ops::RangeInclusive<u32>, x0: f64, v: f64) -> Vec<TrackPoint> {
        frames
            .map(|f| point(f, id, x0 + v * f64::from(f), ObjectClass::Pedestrian))
            .collect()
    }

    /// Detections at `(frame, x)` (y = 50), 1 px square, of `class`.
    fn dets(at: &[(u32, f64)], class: Option<ObjectClass>) -> BTreeMap<u32, Vec<Candidate>> {
        let mut m: BTreeMap<u32, Vec<Candidate>> = BTreeMap::new();
        for &(f, x) in at {
            m.entry(f).or_default().push(Candidate {
                centre: Point::new(x, 50.0),
                size: Some((1.0, 1.0)),
                class: class.clone(),
            });
        }
        m
    }

    fn xs(out: &[FramePoints], id: u64) -> Vec<(u32, f64)> {
        out.iter()
            .flat_map(|f| f.points.iter().filter(|p| p.id == id))
            .map(|p| (p.frame, p.bbox.centre().x))
            .collect()
    }

    fn on(max_frames: u32) -> ExtendConfig {
        ExtendConfig {
            max_frames,
            ..ExtendConfig::default()
        }
    }

    /// The walker's detections in every frame, 0.3 px off its line alternately.
    fn along(frames: std::ops::RangeInclusive<u32>, x0: f64, v: f64) -> Vec<(u32, f64)> {
        frames
            .map(|f| {
                (
                    f,
                    x0 + v * f64::from(f) + if f % 2 == 0 { 0.3 } else { -0.3 },
                )
            })
            .collect()
    }

    #[test]
    fn off_changes_nothing() -> Result<()> {
        let pts = walk(1, 8..=12, 10.0, 0.5);
        let mut out = frames(&pts, 20);
        let before = out.clone();
        let d = dets(&along(1..=20, 10.0, 0.5), Some(ObjectClass::Pedestrian));
        assert_eq!(extend(&ExtendConfig::default(), &d, &mut out)?, 0);
        assert_eq!(out, before);
        Ok(())
    }

    /// A track written from frame 8 to 12 whose detections run from frame 3 to 17 is
    /// carried to both ends at the detections' centres, its own points untouched.
    #[test]
    fn a_track_is_carried_to_where_its_detections_end() -> Result<()> {
        let pts = walk(1, 8..=12, 10.0, 0.5);
        let mut out = frames(&pts, 20);
        let seen = along(3..=17, 10.0, 0.5);
        let d = dets(&seen, Some(ObjectClass::Pedestrian));
        assert_eq!(extend(&on(30), &d, &mut out)?, 10);
        let got = xs(&out, 1);
        let want: Vec<(u32, f64)> = seen
            .iter()
            .map(|&(f, x)| {
                if (8..=12).contains(&f) {
                    (f, 10.0 + 0.5 * f64::from(f))
                } else {
                    (f, x)
                }
            })
            .collect();
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(g.0, w.0);
            assert!((g.1 - w.1).abs() < 1e-9, "{g:?} {w:?}");
        }
        // At most `max_frames` each way.
        let mut out = frames(&pts, 20);
        assert_eq!(extend(&on(2), &d, &mut out)?, 4);
        assert_eq!(xs(&out, 1).first().map(|p| p.0), Some(6));
        assert_eq!(xs(&out, 1).last().map(|p| p.0), Some(14));
        Ok(())
    }

    /// Up to `max_missed` frames without a detection are bridged on the straight line
    /// between the points around them; a longer run of misses ends the extension.
    #[test]
    fn short_gaps_are_bridged_and_long_ones_end_it() -> Result<()> {
        let pts = walk(1, 20..=25, 0.0, 1.0);
        // Backward: frames 19, 18, then a gap of 3 (17–15), then 14; beyond a gap of 6
        // (13–8) frame 7 is never reached. Forward: 26, then nothing.
        let d = dets(
            &[(26, 26.0), (19, 19.0), (18, 18.0), (14, 14.0), (7, 7.0)],
            Some(ObjectClass::Pedestrian),
        );
        let mut out = frames(&pts, 30);
        let cfg = ExtendConfig {
            max_missed: 3,
            ..on(30)
        };
        extend(&cfg, &d, &mut out)?;
        let got = xs(&out, 1);
        let frames_got: Vec<u32> = got.iter().map(|p| p.0).collect();
        assert_eq!(frames_got, (14..=26).collect::<Vec<_>>());
        for (f, x) in got {
            assert!((x - f64::from(f)).abs() < 1e-9, "frame {f}: {x}");
        }
        Ok(())
    }

    /// Detections off the track's line, of another kind, of another size, or held by
    /// another track are not taken.
    #[test]
    fn only_free_detections_on_the_line_of_the_same_kind_are_taken() -> Result<()> {
        let pts = walk(1, 10..=14, 0.0, 1.0);
        let mut out = frames(&pts, 14);
        // Frame 9: 1.5 px off the line (gate 1 px); frame 8: a car; frame 7: 5 px wide.
        let mut d = dets(&[(9, 10.5)], Some(ObjectClass::Pedestrian));
        d.extend(dets(&[(8, 8.0)], Some(ObjectClass::Car)));
        d.entry(7).or_default().push(Candidate {
            centre: Point::new(7.0, 50.0),
            size: Some((5.0, 5.0)),
            class: Some(ObjectClass::Pedestrian),
        });
        assert_eq!(extend(&on(30), &d, &mut out)?, 0);
        // On the line, but another walker (id 2) stands on it in frame 9.
        let mut pts2 = pts.clone();
        pts2.push(point(9, 2, 9.2, ObjectClass::Pedestrian));
        let mut out = frames(&pts2, 14);
        let d = dets(&[(9, 9.0)], Some(ObjectClass::Pedestrian));
        assert_eq!(extend(&on(30), &d, &mut out)?, 0);
        // An unclassified detection goes with any track.
        let mut out = frames(&pts, 14);
        let d = dets(&[(9, 9.0)], None);
        assert_eq!(extend(&on(30), &d, &mut out)?, 1);
        Ok(())
    }

    /// Two tracks that could take one detection: the lower id takes it, the other does
    /// not take it too.
    #[test]
    fn a_detection_goes_to_one_track_only() -> Result<()> {
        let mut pts = walk(1, 10..=14, 0.0, 1.0);
        pts.extend(walk(2, 10..=14, 0.6, 1.0));
        let mut out = frames(&pts, 14);
        let d = dets(&[(9, 9.3)], Some(ObjectClass::Pedestrian));
        assert_eq!(extend(&on(30), &d, &mut out)?, 1);
        assert_eq!(out[8].points.len(), 1);
        assert_eq!(out[8].points[0].id, 1);
        Ok(())
    }

    #[test]
    fn on_line_is_least_squares() {
        let pts = [
            (1.0, Point::new(0.0, 0.0)),
            (2.0, Point::new(1.0, 2.0)),
            (3.0, Point::new(2.0, 4.0)),
            (4.0, Point::new(3.5, 6.0)),
        ];
        // x: slope 1.15, intercept −1.25 (normal equations by hand); y = 2f − 2.
        let p = on_line(&pts, 6.0);
        assert!(
            (p.x - 5.65).abs() < 1e-12 && (p.y - 10.0).abs() < 1e-12,
            "{p:?}"
        );
        let one = on_line(&pts[..1], 9.0);
        assert_eq!((one.x, one.y), (0.0, 0.0));
    }

    #[test]
    fn bad_settings_name_the_field() {
        let cases: [(&str, ExtendConfig); 5] = [
            (
                "max_frames",
                ExtendConfig {
                    max_frames: 20_000,
                    ..on(5)
                },
            ),
            (
                "gate",
                ExtendConfig {
                    gate: f64::NAN,
                    ..on(5)
                },
            ),
            (
                "min_gate_px",
                ExtendConfig {
                    min_gate_px: 0.0,
                    ..on(5)
                },
            ),
            (
                "fit_frames",
                ExtendConfig {
                    fit_frames: 0,
                    ..on(5)
                },
            ),
            (
                "max_size_ratio",
                ExtendConfig {
                    max_size_ratio: 0.5,
                    ..on(5)
                },
            ),
        ];
        for (field, cfg) in cases {
            let e = cfg.validate().expect_err(field).to_string();
            assert!(e.contains(field), "{field}: {e}");
            assert!(ExtendStage::new(cfg).is_err());
        }
        assert!(ExtendConfig::default().validate().is_ok());
    }
}
