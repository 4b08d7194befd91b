//! Running a tracking method over a frame source, and putting its output on the ground.
//!
//! The MRF tracker has its own entry point (`mrf::track_source`), the filters theirs; this
//! module holds the relaxation tracker's (extraction in every frame, relaxation between
//! consecutive frames) and the calibration step shared by all methods.

use crate::analysis::kinematics::{GroundPoint, KinematicsConfig, attach_ground};
use crate::calibration::Calibration;
use crate::detect::background::{Detector, DetectorConfig};
use crate::error::Result;
use crate::geometry::Point;
use crate::io::{SourceOptions, source};
use crate::track::relaxation::tracker::{RelaxationTracker, TrackerConfig};
use crate::track_point::TrackPoint;
use std::path::Path;

/// `roadtrack track --method relaxation`: foreground extraction (the spine's detector,
/// bootstrapped by a first pass over `input`) in every frame, then
/// [`RelaxationTracker`] between consecutive frames. Returns the track points in frame order.
pub fn relaxation_track_source(
    config: &TrackerConfig,
    detector: &DetectorConfig,
    input: &Path,
    options: &SourceOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<TrackPoint>> {
    config.validate()?;
    let mut det = Detector::bootstrap_source(detector.clone(), input, options)?;
    let frames = source::open(input, options)?;
    let total = u64::from(frames.info.selected_frames.unwrap_or(0));
    let mut tracker = RelaxationTracker::new(config.clone())?;
    let mut points = Vec::new();
    for (done, frame) in frames.enumerate() {
        let frame = frame?;
        let detections = det.detect(&frame)?;
        points.extend(tracker.step(frame.index, frame.time_s, &detections)?);
        progress(done as u64 + 1, total);
    }
    Ok(points)
}

/// Sets ground position, speed and heading on every point through `calibration`.
///
/// Choice: the ground point of a box is its centre for a nadir calibration (the whole
/// object is seen from above) and the middle of its bottom edge otherwise (where an object
/// stands on the road in an oblique view), unless `ground_point` says otherwise. Speeds come
/// from the local line-fit smoother of [`crate::analysis::kinematics`].
pub fn attach_calibration(
    points: &mut [TrackPoint],
    calibration: &Calibration,
    ground_point: Option<GroundPoint>,
    half_window_s: f64,
) -> Result<()> {
    let gp = ground_point.unwrap_or(if calibration.metres_per_pixel().is_some() {
        GroundPoint::Centre
    } else {
        GroundPoint::BottomCentre
    });
    let cfg = KinematicsConfig {
        half_window_s,
        ground_point: gp,
    };
    attach_ground(
        points,
        &|p| {
            calibration
                .ground_from_image(p)
                .map(|(x, y)| Point::new(x, y))
        },
        &cfg,
    )
}
