//! Relaxation as a tracker (issue 5 item 3): the two-frame matching of METHODS.md §1 run
//! between every frame and the tracks alive before it, chained into tracks with stable ids.
//!
//! The paper matches two frames only; everything here beyond that is a choice:
//! - Choice: frame 1 of each matching is the set of live tracks, each placed where it is
//!   expected one frame before the current one (last position plus its last per-frame
//!   displacement times the frames it was missing), with its last colour. A vehicle missed
//!   for a few frames then shows the same displacement as its neighbours, which is what the
//!   relaxation rewards.
//! - Choice: a track missing for up to `max_missed_frames` frames stays alive and keeps its
//!   id when it is matched again; after that it ends.
//! - Choice: when the argmax sends two tracks to one detection, the detection goes to the
//!   more probable claim (ties: the older track) and the other track counts as missed.
//! - Choice: tracks and detections the relaxation left unpaired (most often an isolated
//!   vehicle whose real labels lost to the no-match label, see the note below) are paired
//!   by a second, gated minimum-distance assignment between each live track's predicted
//!   position in this frame and the detections ([`RelaxationTrackerConfig::rematch`]; the
//!   cascade of SORT-style trackers). Off, every unpaired detection starts a track.
//! - Choice: a detection no track claimed starts a new track; ids count up from 1.
//! - Choice (options, off by default): `predict` places each track at its prediction for
//!   the current frame instead, so the labels are prediction residuals; `position_alpha`
//!   below 1 smooths each track's centre with an alpha-beta filter, and the state the next
//!   frame is matched against is the filtered one.
//!
//! Note: with the paper's `A = 0.5`, a vehicle without neighbours within `R` loses its real
//! labels to the no-match label (nothing reinforces them, eq. 19), so isolated vehicles
//! start a new track each frame; `own_weight = 1` keeps the colour start's decision for
//! them. The paper's value stays the default.

use super::{RelaxationConfig, match_vehicles};
use crate::class::ObjectClass;
use crate::detection::Detection;
use crate::error::Result;
use crate::geometry::{BBox, Point};
use crate::track_point::TrackPoint;
use serde::{Deserialize, Serialize};

/// Parameters of the relaxation tracker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RelaxationTrackerConfig {
    /// The two-frame matcher (METHODS.md §1; the paper's defaults).
    pub relaxation: RelaxationConfig,
    /// `k`: frames a track may go unmatched and still keep its id. Default 3 (paper
    /// silent; about 2 s at 1.5 s per frame would be 1, at 10 fps 0.3 s).
    pub max_missed_frames: u32,
    /// Side of the box written for detections without a size, px. Default 15 (a car at
    /// 0.3 m/px; paper silent).
    pub fallback_box_px: f64,
    /// Whether tracks and detections the relaxation left unpaired get a second, gated
    /// nearest assignment. Default true (the tracker is ours; `false` chains the paper's
    /// two-frame decisions only).
    pub rematch: bool,
    /// Gate of the second assignment: a detection may take a track predicted within
    /// `max(rematch_gate_px, rematch_box_fraction × the detection box's longer side)`.
    /// Default 10 px.
    pub rematch_gate_px: f64,
    /// See `rematch_gate_px`. Default 0.75.
    pub rematch_box_fraction: f64,
    /// Whether each live track enters the matching at its constant-velocity prediction
    /// for *this* frame rather than one frame before it (ours). The labels are then the
    /// residuals from the prediction: the gate `D` is centred on it, eq. 15 compares
    /// residuals (a queued car and a moving one both have residual ≈ 0 when predicted
    /// well) and `displacement_sd_px` becomes a prior on the prediction error. Default
    /// false.
    pub predict: bool,
    /// Smoothing of each track's centre by an alpha-beta filter with this `α` (ours;
    /// `β = α²/(2 − α)`): the box written is the detection's size at the filtered centre,
    /// and the filtered state is what the next frame is matched against. Default 1: the
    /// detection's own centre (no smoothing).
    pub position_alpha: f64,
    /// Whether the box written is centred on the filtered centre (`position_alpha < 1`) or
    /// on the detection's own centre; the filter's state drives the matching either way.
    /// Default true.
    // Choice: the filter's estimate lags an object that speeds up, slows down or turns.
    // With the offline box fit after the tracker (`--smooth-boxes`, which looks both ways
    // in time) the written boxes are smoothed without that lag, and writing the
    // detection's centre raised relaxation's HOTA on all six simulated video scenes
    // (docs/EXPERIMENTS.md "Writing the detection's centre"); configs/relaxation-video.toml
    // sets it false. True keeps what the filter alone gives when nothing smooths after it.
    pub write_filtered_centre: bool,
    /// Size gate (ours): a track and a detection whose box widths or heights differ by more
    /// than this factor are never paired (by the relaxation or the second assignment).
    /// Default 0: off. Boxes without a size pass.
    // Choice: the relaxation pairs centres only, so a pedestrian's track walking under a
    // passing truck takes the truck's detection; a factor of 2 or more still lets a box
    // grow or shrink as an object turns. A box within 1 px of the image's edge (known when
    // the tracker runs in a pipeline) is cut by it and passes: a vehicle leaving the view
    // shrinks to a sliver in a frame or two.
    pub size_ratio_gate: f64,
    /// Colour of an upright box (ours): a detection whose box is at least `upright_aspect`
    /// times as high as wide takes the mean colour of the central `f × f` part of its box,
    /// read from the frame, instead of its own colour. In `(0, 1]`; default 1: the
    /// detection's colour. Applies where the frame's image is known (in a pipeline).
    // Choice: a pedestrian fills about half of her box's width; the rest is pavement, so
    // the whole box's colour of two pedestrians side by side differs little and the colour
    // start cannot tell a walker from the people she passes. The central part is mostly
    // her. Upright boxes only: a small aerial car's box (14 × 5 px) has too few pixels to
    // shrink, and a vehicle fills its box.
    pub upright_colour_fraction: f64,
    /// See `upright_colour_fraction`: height / width from which a box counts as upright.
    /// Default 1.5.
    pub upright_aspect: f64,
    /// Class gate (ours): a track whose last detection was a pedestrian never takes a car,
    /// lorry or bus detection, nor the other way round ([`ObjectClass::may_be_same_object`];
    /// by the relaxation or the second assignment). Detections without a class pass.
    /// Default true.
    pub keep_classes_apart: bool,
}

impl Default for RelaxationTrackerConfig {
    fn default() -> Self {
        Self {
            relaxation: RelaxationConfig::default(),
            max_missed_frames: 3,
            fallback_box_px: 15.0,
            rematch: true,
            rematch_gate_px: 10.0,
            rematch_box_fraction: 0.75,
            predict: false,
            position_alpha: 1.0,
            write_filtered_centre: true,
            size_ratio_gate: 0.0,
            upright_colour_fraction: 1.0,
            upright_aspect: 1.5,
            keep_classes_apart: true,
        }
    }
}

impl crate::config::Validate for RelaxationTrackerConfig {
    fn validate(&self) -> crate::error::Result<()> {
        RelaxationTrackerConfig::validate(self)
    }
}

impl RelaxationTrackerConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`crate::Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        self.relaxation
            .validate()
            .map_err(|e| e.in_table("relaxation"))?;
        for (name, v) in [
            ("rematch_gate_px", self.rematch_gate_px),
            ("rematch_box_fraction", self.rematch_box_fraction),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::Error::config(
                    "RelaxationTrackerConfig",
                    name,
                    "must be finite and non-negative",
                ));
            }
        }
        if !(self.position_alpha > 0.0 && self.position_alpha <= 1.0) {
            return Err(crate::Error::config(
                "RelaxationTrackerConfig",
                "position_alpha",
                "must be in (0, 1]",
            ));
        }
        if !(self.size_ratio_gate == 0.0
            || (self.size_ratio_gate.is_finite() && self.size_ratio_gate >= 1.0))
        {
            return Err(crate::Error::config(
                "RelaxationTrackerConfig",
                "size_ratio_gate",
                "must be 0 (off) or a finite factor of at least 1",
            ));
        }
        if !(self.upright_colour_fraction > 0.0 && self.upright_colour_fraction <= 1.0) {
            return Err(crate::Error::config(
                "RelaxationTrackerConfig",
                "upright_colour_fraction",
                "must be in (0, 1]",
            ));
        }
        if !(self.upright_aspect.is_finite() && self.upright_aspect > 0.0) {
            return Err(crate::Error::config(
                "RelaxationTrackerConfig",
                "upright_aspect",
                "must be finite and positive",
            ));
        }
        if !(self.fallback_box_px.is_finite() && self.fallback_box_px >= 0.0) {
            return Err(crate::Error::config(
                "RelaxationTrackerConfig",
                "fallback_box_px",
                "must be finite and non-negative",
            ));
        }
        Ok(())
    }
}

#[derive(Debug, Clone)]
struct Track {
    id: u64,
    pos: Point,
    /// Displacement per frame at the last match.
    velocity: [f64; 2],
    colour: Option<[f64; 3]>,
    /// The last detection's box size, px, unless that box touched the image's edge.
    size: Option<(f64, f64)>,
    /// The last detection's class, where it had one.
    class: Option<ObjectClass>,
    last_frame: u32,
}

/// Chains relaxation matchings of consecutive frames into tracks.
#[derive(Debug, Clone)]
pub struct RelaxationTracker {
    // Boxed: the config is most of the tracker's size, and `BuiltTracker` holds it inline.
    config: Box<RelaxationTrackerConfig>,
    tracks: Vec<Track>,
    next_id: u64,
    /// Width and height of the current frame's image, px, when known (boxes at its edge
    /// pass the size gate).
    image_size: Option<(f64, f64)>,
}

impl RelaxationTracker {
    /// A tracker with no tracks yet.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn new(config: RelaxationTrackerConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config: Box::new(config),
            tracks: Vec::new(),
            next_id: 1,
            image_size: None,
        })
    }

    /// Number of live tracks (matched recently enough to be matched again).
    pub fn live_tracks(&self) -> usize {
        self.tracks.len()
    }

    /// Processes the detections of frame `frame` (1-based, increasing) taken at `time_s`;
    /// returns one track point per detection, in input order.
    ///
    /// # Errors
    /// Frames out of order, or detections the matcher rejects (duplicate ids, missing
    /// colour under a colour variant, non-finite values).
    pub fn step(
        &mut self,
        frame: u32,
        time_s: f64,
        detections: &[Detection],
    ) -> Result<Vec<TrackPoint>> {
        if let Some(t) = self.tracks.iter().find(|t| t.last_frame >= frame) {
            return Err(crate::Error::Invalid(format!(
                "frame {frame} after frame {}: frames must increase",
                t.last_frame
            )));
        }
        let previous: Vec<Detection> = self
            .tracks
            .iter()
            .enumerate()
            .map(|(n, t)| {
                // Choice: with `predict`, the prediction for this frame; otherwise one
                // frame before it (the label is then the last per-frame displacement).
                let ahead = frame - t.last_frame - u32::from(!self.config.predict);
                let missed = f64::from(ahead);
                let pos = Point::new(
                    t.pos.x + t.velocity[0] * missed,
                    t.pos.y + t.velocity[1] * missed,
                );
                Detection {
                    colour_rgb: t.colour,
                    ..Detection::at(frame.saturating_sub(1).max(1), n as u64, pos)
                }
            })
            .collect();
        let matching = match_vehicles(&previous, detections, &self.config.relaxation)
            .map_err(|e| crate::Error::Invalid(format!("frame {frame}: {e}")))?;
        // Resolve many-to-one claims: best probability, then older track.
        let mut owner: Vec<Option<usize>> = vec![None; detections.len()];
        for (n, k) in matching.partner.iter().enumerate() {
            if let Some(k) = *k
                && self.may_continue(&self.tracks[n], &detections[k])
            {
                let better = match owner[k] {
                    None => true,
                    Some(o) => matching.probability[n] > matching.probability[o],
                };
                if better {
                    owner[k] = Some(n);
                }
            }
        }
        if self.config.rematch {
            self.rematch(frame, detections, &mut owner)?;
        }
        let mut points = Vec::with_capacity(detections.len());
        let alpha = self.config.position_alpha;
        for (k, d) in detections.iter().enumerate() {
            let mut centre = d.pos_px;
            let size = self.unclipped_size(d);
            let id = match owner[k] {
                Some(n) => {
                    let t = &mut self.tracks[n];
                    let gap = f64::from(frame - t.last_frame);
                    if alpha < 1.0 {
                        // Alpha-beta filter (β = α² / (2 − α), Benedict–Bordner).
                        let beta = alpha * alpha / (2.0 - alpha);
                        let pred = [t.pos.x + t.velocity[0] * gap, t.pos.y + t.velocity[1] * gap];
                        let r = [d.pos_px.x - pred[0], d.pos_px.y - pred[1]];
                        t.pos = Point::new(pred[0] + alpha * r[0], pred[1] + alpha * r[1]);
                        t.velocity = [
                            t.velocity[0] + beta * r[0] / gap,
                            t.velocity[1] + beta * r[1] / gap,
                        ];
                        centre = t.pos;
                    } else {
                        t.velocity = [(d.pos_px.x - t.pos.x) / gap, (d.pos_px.y - t.pos.y) / gap];
                        t.pos = d.pos_px;
                    }
                    t.colour = d.colour_rgb.or(t.colour);
                    t.size = size;
                    t.class = d.class.clone().or(t.class.take());
                    t.last_frame = frame;
                    t.id
                }
                None => {
                    let id = self.next_id;
                    self.next_id += 1;
                    self.tracks.push(Track {
                        id,
                        pos: d.pos_px,
                        velocity: [0.0, 0.0],
                        colour: d.colour_rgb,
                        size,
                        class: d.class.clone(),
                        last_frame: frame,
                    });
                    id
                }
            };
            let bbox = match d.size_px {
                Some((w, h)) if alpha < 1.0 && self.config.write_filtered_centre => {
                    BBox::from_centre(centre, w, h)
                }
                _ => d.bbox().unwrap_or_else(|| {
                    let s = self.config.fallback_box_px;
                    BBox::from_centre(d.pos_px, s, s)
                }),
            };
            points.push(TrackPoint {
                frame,
                time_s,
                id,
                class: d.class.clone().unwrap_or(ObjectClass::Unknown),
                bbox,
                score: d.score.unwrap_or(1.0),
                ground: None,
            });
        }
        let k = self.config.max_missed_frames;
        self.tracks.retain(|t| frame - t.last_frame <= k);
        Ok(points)
    }
}

impl RelaxationTracker {
    /// Whether `d` may continue `track`: the size gate
    /// ([`RelaxationTrackerConfig::size_ratio_gate`]) and the class gate
    /// ([`RelaxationTrackerConfig::keep_classes_apart`]).
    fn may_continue(&self, track: &Track, d: &Detection) -> bool {
        let classes = !self.config.keep_classes_apart
            || ObjectClass::may_be_same_object_if_known(track.class.as_ref(), d.class.as_ref());
        classes && self.sizes_match(track, d)
    }

    /// Whether `track` and `d` pass the size gate ([`RelaxationTrackerConfig::size_ratio_gate`]).
    fn sizes_match(&self, track: &Track, d: &Detection) -> bool {
        let r = self.config.size_ratio_gate;
        match (track.size, self.unclipped_size(d)) {
            (Some((w0, h0)), Some((w1, h1))) if r > 0.0 => {
                let within = |a: f64, b: f64| a <= r * b && b <= r * a;
                within(w0, w1) && within(h0, h1)
            }
            _ => true,
        }
    }

    /// `d`'s box size, or `None` when the box lies within 1 px of the image's edge.
    fn unclipped_size(&self, d: &Detection) -> Option<(f64, f64)> {
        let (w, h) = d.size_px?;
        let b = d.bbox()?;
        let at_edge = b.left <= 1.0
            || b.top <= 1.0
            || self
                .image_size
                .is_some_and(|(iw, ih)| b.left + w >= iw - 1.0 || b.top + h >= ih - 1.0);
        (!at_edge).then_some((w, h))
    }

    /// `d` with the colour of the central part of its box when the box is upright
    /// ([`RelaxationTrackerConfig::upright_colour_fraction`]); `d` itself otherwise or when
    /// that part misses the image.
    pub fn upright_colour(&self, d: &Detection, image: &image::RgbImage) -> Detection {
        let f = self.config.upright_colour_fraction;
        let mut out = d.clone();
        if let Some((w, h)) = d.size_px
            && f < 1.0
            && h >= self.config.upright_aspect * w
        {
            let centre = BBox::from_centre(d.pos_px, f * w, f * h);
            if let Some(c) = crate::detect::file::mean_colour(image, &centre) {
                out.colour_rgb = Some(c);
            }
        }
        out
    }

    /// The second assignment: unpaired live tracks, predicted to `frame`, against unclaimed
    /// detections, minimum total distance within the gate.
    fn rematch(
        &self,
        frame: u32,
        detections: &[Detection],
        owner: &mut [Option<usize>],
    ) -> Result<()> {
        let mut claimed = vec![false; self.tracks.len()];
        for n in owner.iter().flatten() {
            claimed[*n] = true;
        }
        let rows: Vec<usize> = (0..self.tracks.len()).filter(|&n| !claimed[n]).collect();
        let cols: Vec<usize> = (0..detections.len())
            .filter(|&k| owner[k].is_none())
            .collect();
        if rows.is_empty() || cols.is_empty() {
            return Ok(());
        }
        let gate = |d: &Detection| {
            let side = d.size_px.map_or(0.0, |(w, h)| w.max(h));
            self.config
                .rematch_gate_px
                .max(self.config.rematch_box_fraction * side)
        };
        // Pairs beyond the gate cost more than any allowed set of pairs can save.
        let forbidden = 1e9;
        let mut cost = Vec::with_capacity(rows.len() * cols.len());
        for &n in &rows {
            let t = &self.tracks[n];
            let ahead = f64::from(frame - t.last_frame);
            let p = Point::new(
                t.pos.x + t.velocity[0] * ahead,
                t.pos.y + t.velocity[1] * ahead,
            );
            for &k in &cols {
                let d = p.distance(detections[k].pos_px);
                cost.push(
                    if d <= gate(&detections[k]) && self.may_continue(t, &detections[k]) {
                        d
                    } else {
                        forbidden
                    },
                );
            }
        }
        let pairs = crate::assignment::linear_sum_assignment(&cost, rows.len(), cols.len())?;
        for (r, c) in pairs {
            if cost[r * cols.len() + c] < forbidden {
                owner[cols[c]] = Some(rows[r]);
            }
        }
        Ok(())
    }
}

impl crate::track::Tracker for RelaxationTracker {
    fn step(
        &mut self,
        frame: &crate::frame::Frame,
        detections: &crate::detect::FrameDetections,
    ) -> Result<Vec<crate::track::FramePoints>> {
        let (w, h) = frame.image.dimensions();
        self.image_size = Some((f64::from(w), f64::from(h)));
        let points = if self.config.upright_colour_fraction < 1.0 {
            let own: Vec<Detection> = detections
                .detections
                .iter()
                .map(|d| self.upright_colour(d, &frame.image))
                .collect();
            RelaxationTracker::step(self, frame.index, frame.time_s, &own)?
        } else {
            RelaxationTracker::step(self, frame.index, frame.time_s, &detections.detections)?
        };
        Ok(vec![crate::track::FramePoints::new(frame, points)])
    }

    fn finish(&mut self) -> Result<Vec<crate::track::FramePoints>> {
        Ok(Vec::new())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A platoon of `n` cars 60 px apart moving 25 px per frame, distinct colours.
    fn platoon(frame: u32, n: u64, skip: &[u64]) -> Vec<Detection> {
        (0..n)
            .filter(|i| !skip.contains(i))
            .map(|i| Detection {
                colour_rgb: Some([(i * 40 % 256) as f64, 100.0, (255 - i * 30 % 256) as f64]),
                ..Detection::at(
                    frame,
                    100 + i,
                    Point::new(
                        i as f64 * 60.0 + 25.0 * f64::from(frame),
                        50.0 + (i % 2) as f64 * 12.0,
                    ),
                )
            })
            .collect()
    }

    fn ids_by_detection(points: &[TrackPoint]) -> Vec<u64> {
        points.iter().map(|p| p.id).collect()
    }

    #[test]
    fn tracks_keep_their_ids_and_survive_short_gaps() -> Result<()> {
        let mut t = RelaxationTracker::new(RelaxationTrackerConfig::default())?;
        let first = ids_by_detection(&t.step(1, 0.0, &platoon(1, 6, &[]))?);
        assert_eq!(first, vec![1, 2, 3, 4, 5, 6]);
        assert_eq!(
            ids_by_detection(&t.step(2, 0.1, &platoon(2, 6, &[]))?),
            first
        );
        // Car 3 (id 4) is missing for two frames (k = 3 allows it), then returns where its
        // last displacement (25 px per frame) predicts.
        let gap = ids_by_detection(&t.step(3, 0.2, &platoon(3, 6, &[3]))?);
        assert_eq!(gap, vec![1, 2, 3, 5, 6]);
        t.step(4, 0.3, &platoon(4, 6, &[3]))?;
        let back = ids_by_detection(&t.step(5, 0.4, &platoon(5, 6, &[]))?);
        assert_eq!(back, vec![1, 2, 3, 4, 5, 6]);
        Ok(())
    }

    #[test]
    fn a_track_missing_longer_than_k_frames_gets_a_new_id() -> Result<()> {
        let cfg = RelaxationTrackerConfig {
            max_missed_frames: 1,
            ..Default::default()
        };
        let mut t = RelaxationTracker::new(cfg)?;
        t.step(1, 0.0, &platoon(1, 6, &[]))?;
        t.step(2, 0.1, &platoon(2, 6, &[]))?;
        t.step(3, 0.2, &platoon(3, 6, &[3]))?;
        t.step(4, 0.3, &platoon(4, 6, &[3]))?;
        let back = ids_by_detection(&t.step(5, 0.4, &platoon(5, 6, &[]))?);
        assert_eq!(back, vec![1, 2, 3, 7, 5, 6]);
        Ok(())
    }

    #[test]
    fn boxes_fall_back_to_a_square_and_frames_must_increase() -> Result<()> {
        let mut t = RelaxationTracker::new(RelaxationTrackerConfig::default())?;
        let p = t.step(1, 0.0, &platoon(1, 2, &[]))?;
        assert_eq!(
            p[0].bbox,
            BBox::from_centre(Point::new(25.0, 50.0), 15.0, 15.0)
        );
        assert_eq!(p[0].class, ObjectClass::Unknown);
        let m = t
            .step(1, 0.0, &platoon(1, 2, &[]))
            .expect_err("same frame")
            .to_string();
        assert!(m.contains("frames must increase"), "{m}");
        // An empty frame is fine: every track is missed.
        assert!(t.step(2, 0.1, &[])?.is_empty());
        assert_eq!(t.live_tracks(), 2);
        Ok(())
    }

    #[test]
    fn pairs_the_relaxation_leaves_are_made_by_the_second_assignment_within_its_gate() -> Result<()>
    {
        // Two cars moving 8 px a frame, beyond a 5 px relaxation gate: the relaxation pairs
        // nothing, so without the second assignment every frame starts new tracks.
        let cars = |frame: u32| -> Vec<Detection> {
            (0..2u64)
                .map(|i| Detection {
                    colour_rgb: Some([200.0, 50.0 + 100.0 * i as f64, 50.0]),
                    size_px: Some((20.0, 10.0)),
                    ..Detection::at(
                        frame,
                        i + 1,
                        Point::new(100.0 + 300.0 * i as f64 + 8.0 * f64::from(frame), 80.0),
                    )
                })
                .collect()
        };
        let ids = |rematch: bool, gate_px: f64, fraction: f64| -> Result<Vec<Vec<u64>>> {
            let mut cfg = RelaxationTrackerConfig {
                rematch,
                rematch_gate_px: gate_px,
                rematch_box_fraction: fraction,
                ..Default::default()
            };
            cfg.relaxation.gate_half_width_px = 5.0;
            let mut t = RelaxationTracker::new(cfg)?;
            (1..=5)
                .map(|f| Ok(ids_by_detection(&t.step(f, 0.0, &cars(f))?)))
                .collect()
        };
        let paper = ids(false, 10.0, 0.75)?;
        assert_eq!(paper[4], vec![9, 10], "{paper:?}");
        // Frame 2 is predicted where frame 1 was (8 px off, inside max(10, 0.75 × 20) px);
        // later frames where the last displacement leads.
        assert_eq!(ids(true, 10.0, 0.75)?, vec![vec![1, 2]; 5]);
        // A 6 px gate never reaches a new track (no displacement yet) 8 px away.
        assert_eq!(ids(true, 6.0, 0.0)?, paper);
        Ok(())
    }

    /// One car moving 15 px a frame along x with a jitter of ±2 px, 30 × 12 px boxes.
    fn jittery(frame: u32) -> Vec<Detection> {
        let j = if frame.is_multiple_of(2) { 2.0 } else { -2.0 };
        vec![Detection {
            colour_rgb: Some([200.0, 30.0, 30.0]),
            size_px: Some((30.0, 12.0)),
            ..Detection::at(
                frame,
                1,
                Point::new(100.0 + 15.0 * f64::from(frame) + j, 50.0),
            )
        }]
    }

    #[test]
    fn predicted_tracks_centre_the_gate_on_the_prediction() -> Result<()> {
        // A car moving 4 px, then 8 px a frame; gate D = 6 px, no second assignment. One
        // frame back, the label is the whole motion (8 px: outside the gate from frame 3);
        // predicted to the frame, it is the change of motion (4 px once, then 0).
        let car = |f: u32| {
            let x = if f == 1 {
                100.0
            } else {
                104.0 + 8.0 * f64::from(f - 2)
            };
            vec![Detection {
                colour_rgb: Some([200.0, 30.0, 30.0]),
                ..Detection::at(f, 1, Point::new(x, 50.0))
            }]
        };
        let ids = |predict: bool| -> Result<Vec<u64>> {
            let mut cfg = RelaxationTrackerConfig {
                rematch: false,
                predict,
                ..Default::default()
            };
            cfg.relaxation.gate_half_width_px = 6.0;
            let mut t = RelaxationTracker::new(cfg)?;
            (1..=6)
                .map(|f| Ok(t.step(f, 0.0, &car(f))?[0].id))
                .collect()
        };
        assert_eq!(ids(false)?, vec![1, 1, 2, 3, 4, 5]);
        assert_eq!(ids(true)?, vec![1; 6]);
        Ok(())
    }

    #[test]
    fn position_smoothing_takes_the_jitter_out_of_the_boxes() -> Result<()> {
        let err = |alpha: f64| -> Result<f64> {
            let cfg = RelaxationTrackerConfig {
                position_alpha: alpha,
                ..Default::default()
            };
            let mut t = RelaxationTracker::new(cfg)?;
            let mut e = 0.0;
            for f in 1..=30 {
                let p = &t.step(f, 0.0, &jittery(f))?[0];
                assert_eq!(p.id, 1);
                assert!((p.bbox.width - 30.0).abs() < 1e-9, "{:?}", p.bbox);
                if f > 10 {
                    e += (p.bbox.centre().x - (100.0 + 15.0 * f64::from(f))).abs();
                }
            }
            Ok(e / 20.0)
        };
        let raw = err(1.0)?;
        assert!((raw - 2.0).abs() < 1e-9, "{raw}");
        let smooth = err(0.35)?;
        assert!(smooth < 0.7 * raw, "{smooth} vs {raw}");
        for bad in [0.0, 1.5, f64::NAN] {
            let cfg = RelaxationTrackerConfig {
                position_alpha: bad,
                ..Default::default()
            };
            let m = RelaxationTracker::new(cfg).expect_err("alpha").to_string();
            assert!(m.contains("position_alpha"), "{m}");
        }
        Ok(())
    }

    /// With `write_filtered_centre = false` the filter still drives the matching (the same
    /// ids as with it written) but every box written is the detection's own.
    #[test]
    fn the_detections_boxes_are_written_when_the_filtered_centre_is_not() -> Result<()> {
        let run = |write: bool| -> Result<Vec<TrackPoint>> {
            let cfg = RelaxationTrackerConfig {
                position_alpha: 0.35,
                write_filtered_centre: write,
                ..Default::default()
            };
            let mut t = RelaxationTracker::new(cfg)?;
            let mut out = Vec::new();
            for f in 1..=30 {
                out.extend(t.step(f, 0.0, &jittery(f))?);
            }
            Ok(out)
        };
        let (filtered, own) = (run(true)?, run(false)?);
        assert_eq!(
            filtered.iter().map(|p| p.id).collect::<Vec<_>>(),
            own.iter().map(|p| p.id).collect::<Vec<_>>()
        );
        let mut moved = 0;
        for (f, (a, b)) in (1..=30).zip(filtered.iter().zip(&own)) {
            let d = &jittery(f)[0];
            assert_eq!(Some(b.bbox), d.bbox(), "frame {f}");
            moved += usize::from(a.bbox != b.bbox);
        }
        assert!(moved > 20, "the filter moved {moved} boxes");
        Ok(())
    }

    fn boxed(frame: u32, id: u64, x: f64, size: (f64, f64)) -> Detection {
        Detection {
            colour_rgb: Some([120.0, 120.0, 120.0]),
            size_px: Some(size),
            ..Detection::at(frame, id, Point::new(x, 100.0))
        }
    }

    /// The track id of each detection, frame by frame (frames numbered from 1).
    fn ids_per_frame(
        config: RelaxationTrackerConfig,
        frames: &[Vec<Detection>],
    ) -> Result<Vec<Vec<u64>>> {
        let mut t = RelaxationTracker::new(config)?;
        frames
            .iter()
            .zip(1..)
            .map(|(d, f)| Ok(ids_by_detection(&t.step(f, 0.0, d)?)))
            .collect()
    }

    #[test]
    fn the_size_gate_keeps_a_pedestrian_track_off_a_truck() -> Result<()> {
        // A pedestrian (10 × 30 px) is hidden by a truck (90 × 50 px) whose centre passes
        // 4 px from it; then both are seen.
        let frames = [
            vec![boxed(1, 1, 100.0, (10.0, 30.0))],
            vec![boxed(2, 1, 104.0, (90.0, 50.0))],
            vec![
                boxed(3, 1, 100.0, (10.0, 30.0)),
                boxed(3, 2, 114.0, (90.0, 50.0)),
            ],
        ];
        let ids = |gate: f64| {
            ids_per_frame(
                RelaxationTrackerConfig {
                    size_ratio_gate: gate,
                    ..Default::default()
                },
                &frames,
            )
        };
        // Without the gate the pedestrian's track takes the truck.
        assert_eq!(ids(0.0)?[1], vec![1]);
        // With it the truck starts its own track and the pedestrian keeps hers.
        assert_eq!(ids(2.0)?, vec![vec![1], vec![2], vec![1, 2]]);
        for bad in [0.5, f64::INFINITY, f64::NAN, -1.0] {
            let cfg = RelaxationTrackerConfig {
                size_ratio_gate: bad,
                ..Default::default()
            };
            let m = RelaxationTracker::new(cfg).expect_err("gate").to_string();
            assert!(m.contains("size_ratio_gate"), "{m}");
        }
        Ok(())
    }

    #[test]
    fn the_class_gate_keeps_a_pedestrian_track_off_a_car() -> Result<()> {
        // A pedestrian's track; in frame 2 only a car is detected 3 px away (the walker
        // hidden), in frame 3 both. Sizes equal, so only the classes tell them apart.
        let with = |d: Detection, c: ObjectClass| Detection {
            class: Some(c),
            ..d
        };
        let frames = [
            vec![with(
                boxed(1, 1, 100.0, (12.0, 30.0)),
                ObjectClass::Pedestrian,
            )],
            vec![with(boxed(2, 1, 103.0, (12.0, 30.0)), ObjectClass::Car)],
            vec![
                with(boxed(3, 1, 100.0, (12.0, 30.0)), ObjectClass::Pedestrian),
                with(boxed(3, 2, 106.0, (12.0, 30.0)), ObjectClass::Car),
            ],
        ];
        let ids = |gate: bool| {
            ids_per_frame(
                RelaxationTrackerConfig {
                    keep_classes_apart: gate,
                    ..Default::default()
                },
                &frames,
            )
        };
        // Without the gate the pedestrian's track takes the car.
        assert_eq!(ids(false)?[1], vec![1]);
        // With it the car starts its own track and the pedestrian keeps hers.
        assert_eq!(ids(true)?, vec![vec![1], vec![2], vec![1, 2]]);
        Ok(())
    }

    #[test]
    fn a_box_cut_by_the_image_edge_passes_the_size_gate() -> Result<()> {
        // A car (40 × 20 px) leaves the view on the left: its box shrinks to 16 px. Away
        // from the edge the same change of size is another object.
        let ids = |x0: f64| -> Result<Vec<u64>> {
            let mut t = RelaxationTracker::new(RelaxationTrackerConfig {
                size_ratio_gate: 2.0,
                ..Default::default()
            })?;
            let a = t.step(1, 0.0, &[boxed(1, 1, x0 + 22.0, (40.0, 20.0))])?[0].id;
            let b = t.step(2, 0.1, &[boxed(2, 1, x0 + 8.0, (16.0, 20.0))])?[0].id;
            Ok(vec![a, b])
        };
        assert_eq!(ids(0.0)?, vec![1, 1]);
        assert_eq!(ids(100.0)?, vec![1, 2]);
        Ok(())
    }

    #[test]
    fn upright_boxes_take_the_colour_of_their_centre() -> Result<()> {
        use image::{Rgb, RgbImage};
        // Grey pavement; a red pedestrian 4 px wide in the middle of a 10 × 30 px box, and
        // a car filling a 30 × 10 px box.
        let mut image = RgbImage::from_pixel(100, 100, Rgb([100, 100, 100]));
        for y in 10..40 {
            for x in 13..17 {
                image.put_pixel(x, y, Rgb([200, 0, 0]));
            }
        }
        let walker = Detection {
            colour_rgb: Some([1.0, 2.0, 3.0]),
            size_px: Some((10.0, 30.0)),
            ..Detection::at(1, 1, Point::new(15.0, 25.0))
        };
        let car = Detection {
            size_px: Some((30.0, 10.0)),
            ..walker.clone()
        };
        let tracker = |f: f64| {
            RelaxationTracker::new(RelaxationTrackerConfig {
                upright_colour_fraction: f,
                ..Default::default()
            })
        };
        let t = tracker(0.4)?;
        // The central 4 × 12 px are all the pedestrian.
        assert_eq!(
            t.upright_colour(&walker, &image).colour_rgb,
            Some([200.0, 0.0, 0.0])
        );
        // A wide box keeps the detection's colour, and so does every box by default.
        assert_eq!(t.upright_colour(&car, &image).colour_rgb, car.colour_rgb);
        assert_eq!(
            tracker(1.0)?.upright_colour(&walker, &image).colour_rgb,
            walker.colour_rgb
        );
        for (field, cfg) in [
            (
                "upright_colour_fraction",
                RelaxationTrackerConfig {
                    upright_colour_fraction: 0.0,
                    ..Default::default()
                },
            ),
            (
                "upright_aspect",
                RelaxationTrackerConfig {
                    upright_aspect: f64::NAN,
                    ..Default::default()
                },
            ),
        ] {
            let m = RelaxationTracker::new(cfg).expect_err(field).to_string();
            assert!(m.contains(field), "{m}");
        }
        Ok(())
    }
}
