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
pub mod filter;
pub mod lifecycle;
pub mod link;
pub mod method;
pub mod mrf;
pub mod pipeline;
pub mod relaxation;
pub mod replay;

pub use method::{Method, MethodConfig, track_source};
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
