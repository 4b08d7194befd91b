//! Tracks read from a file, replayed frame by frame as a [`Tracker`] (`roadtrack render`
//! draws them through the same pipeline as `roadtrack track`).

use super::{FramePoints, Tracker};
use crate::detect::FrameDetections;
use crate::error::Result;
use crate::frame::Frame;
use crate::track_point::TrackPoint;
use std::collections::BTreeMap;

/// Gives each frame the points recorded for it.
#[derive(Debug, Clone, Default)]
pub struct ReplayTracker {
    by_frame: BTreeMap<u32, Vec<TrackPoint>>,
}

impl ReplayTracker {
    /// Replays `points` (any order).
    pub fn new(points: Vec<TrackPoint>) -> Self {
        let mut by_frame: BTreeMap<u32, Vec<TrackPoint>> = BTreeMap::new();
        for p in points {
            by_frame.entry(p.frame).or_default().push(p);
        }
        Self { by_frame }
    }
}

impl Tracker for ReplayTracker {
    fn step(&mut self, frame: &Frame, _detections: &FrameDetections) -> Result<Vec<FramePoints>> {
        let points = self.by_frame.remove(&frame.index).unwrap_or_default();
        Ok(vec![FramePoints::new(frame, points)])
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        Ok(Vec::new())
    }
}
