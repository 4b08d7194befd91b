//! Tracking: the [`Tracker`] trait, the methods that implement it, the shared track life
//! cycle, and the one loop that runs them ([`pipeline`]).
//!
//! ```text
//! frames ─▶ Detector ─▶ Tracker ─▶ point stages (e.g. ground) ─▶ sinks (MOT, CSV, GeoJSON, overlay)
//! ```
//!
//! Methods (METHODS.md): [`relaxation`] (seed 000), [`mrf`] (seed 002), [`filter`] (PF and
//! labelled SMC-PHD, seed 004). [`method`] is the one place that turns a [`Method`] and its
//! config into a detector and a tracker. [`confirm`] is the life cycle every method shares
//! (confirmation, coasting, box smoothing, a class per track) as a point stage.

pub mod confirm;
pub mod extend;
pub mod filter;
mod ground_path;
pub mod lifecycle;
pub mod link;
pub mod method;
pub mod mrf;
pub mod pipeline;
pub mod relaxation;
pub mod replay;
pub mod smooth;
mod solid;
pub mod vehicle_box;
pub mod walker_box;

pub use method::{Method, MethodConfig, track_frames, track_source};
pub use pipeline::{Pipeline, PointSink, PointStage, RunSummary};

use crate::detect::FrameDetections;
use crate::error::Result;
use crate::frame::Frame;
use crate::track_point::TrackPoint;

/// The final track points of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePoints {
    /// 1-based frame number.
    pub frame: u32,
    /// Time of the frame, s.
    pub time_s: f64,
    /// The points (the pipeline sorts them by id before the sinks see them).
    pub points: Vec<TrackPoint>,
}

impl FramePoints {
    /// `points` as the final output of `frame`.
    pub fn new(frame: &Frame, points: Vec<TrackPoint>) -> Self {
        Self {
            frame: frame.index,
            time_s: frame.time_s,
            points,
        }
    }
}

/// A point of track `id` in `frame` (at `time_s`) between `before` (box size
/// `size_before`) and `after`: centre and size linear in the frame number, `before`'s class,
/// the lower score, no ground state. Coasting ([`confirm`]) and gap closing ([`link`]) fill
/// a track's missing frames with it.
pub(crate) fn interpolated_point(
    before: &TrackPoint,
    size_before: (f64, f64),
    after: &TrackPoint,
    frame: u32,
    time_s: f64,
    id: u64,
) -> TrackPoint {
    let s = f64::from(frame - before.frame) / f64::from(after.frame - before.frame);
    let lerp = |a: f64, b: f64| a + s * (b - a);
    let (ca, cb) = (before.bbox.centre(), after.bbox.centre());
    TrackPoint {
        frame,
        time_s,
        id,
        class: before.class.clone(),
        bbox: crate::geometry::BBox::from_centre(
            crate::geometry::Point::new(lerp(ca.x, cb.x), lerp(ca.y, cb.y)),
            lerp(size_before.0, after.bbox.width),
            lerp(size_before.1, after.bbox.height),
        ),
        score: before.score.min(after.score),
        ground: None,
    }
}

/// Test input: a point of track `id` in `frame` (10 frames/s), score 1, not on the ground.
#[cfg(test)]
pub(crate) fn point_at(
    frame: u32,
    id: u64,
    class: crate::class::ObjectClass,
    bbox: crate::geometry::BBox,
) -> TrackPoint {
    TrackPoint {
        frame,
        time_s: f64::from(frame - 1) / 10.0,
        id,
        class,
        bbox,
        score: 1.0,
        ground: None,
    }
}

/// Test input: frames `1..=n` at 10 frames/s holding `points` by frame, sorted by id.
#[cfg(test)]
pub(crate) fn frames_of(points: &[TrackPoint], n: u32) -> Vec<FramePoints> {
    (1..=n)
        .map(|f| FramePoints {
            frame: f,
            time_s: f64::from(f - 1) / 10.0,
            points: {
                let mut v: Vec<TrackPoint> =
                    points.iter().filter(|p| p.frame == f).cloned().collect();
                v.sort_by_key(|p| p.id);
                v
            },
        })
        .collect()
}

/// Test input: a frame's detections with `boxes` (ids from 1, no class or score).
#[cfg(test)]
pub(crate) fn detections_of(
    boxes: &[crate::geometry::BBox],
    frame: u32,
) -> crate::detect::FrameDetections {
    crate::detect::FrameDetections {
        detections: boxes
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let mut d = crate::detection::Detection::at(frame, i as u64 + 1, b.centre());
                d.size_px = Some((b.width, b.height));
                d
            })
            .collect(),
        foreground: None,
    }
}

/// Test run of an offline box stage: `points` over frames `1..=n`, the detector having
/// found `dets(frame)` in each (given to the stage when it asks for detections; a stage
/// that does not ask must be given none); the frames out and the boxes the stage changed.
#[cfg(test)]
pub(crate) fn run_box_stage<S: pipeline::PointStage>(
    stage: &mut S,
    points: &[TrackPoint],
    n: u32,
    dets: impl Fn(u32) -> Vec<crate::geometry::BBox>,
) -> crate::error::Result<Vec<FramePoints>> {
    for f in frames_of(points, n) {
        let boxes = dets(f.frame);
        assert!(stage.wants_detections() || boxes.is_empty());
        stage.see_detections(f.frame, &detections_of(&boxes, f.frame));
        assert!(stage.push(f)?.is_empty(), "the stage holds every frame");
    }
    stage.finish()
}

/// Test output: the boxes of track `id` in `out`, in frame order.
#[cfg(test)]
pub(crate) fn boxes_of(out: &[FramePoints], id: u64) -> Vec<crate::geometry::BBox> {
    out.iter()
        .flat_map(|f| f.points.iter().filter(|p| p.id == id))
        .map(|p| p.bbox)
        .collect()
}

/// A multi-object tracker that consumes frames in order.
///
/// Implemented by [`relaxation::tracker::RelaxationTracker`] (seed 000 chained frame to
/// frame), [`mrf::MrfTracker`] (seed 002), [`filter::FilterTracker`] (seed 004's PF and
/// PHD) and [`replay::ReplayTracker`] (tracks read from a file).
///
/// Contract: every frame given to [`Tracker::step`] comes back exactly once, as one
/// [`FramePoints`] (empty when nothing is tracked in it), in the order the frames came,
/// from `step` or from [`Tracker::finish`]. A tracker may hold frames back while their
/// points can still change (a filter waiting for its colour reference) and return them
/// later, together.
pub trait Tracker {
    /// Consumes one frame and what was detected in it; returns the frames whose points are
    /// now final.
    ///
    /// # Errors
    /// A frame the tracker cannot process (another size, out of order), bad detections, a
    /// likelihood that fails.
    fn step(&mut self, frame: &Frame, detections: &FrameDetections) -> Result<Vec<FramePoints>>;

    /// Ends the run: the frames still held back.
    ///
    /// # Errors
    /// As [`Tracker::step`].
    fn finish(&mut self) -> Result<Vec<FramePoints>>;
}

impl<T: Tracker + ?Sized> Tracker for &mut T {
    fn step(&mut self, frame: &Frame, detections: &FrameDetections) -> Result<Vec<FramePoints>> {
        (**self).step(frame, detections)
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        (**self).finish()
    }
}

impl<T: Tracker + ?Sized> Tracker for Box<T> {
    fn step(&mut self, frame: &Frame, detections: &FrameDetections) -> Result<Vec<FramePoints>> {
        (**self).step(frame, detections)
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        (**self).finish()
    }
}
