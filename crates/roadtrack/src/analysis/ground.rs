//! Putting tracks on the ground through a calibration: positions in metres, speeds and
//! headings, for a whole set of points ([`attach_calibration`]) or frame by frame in the
//! tracking pipeline ([`GroundStage`]).

use crate::analysis::kinematics::{GroundPoint, GroundSmoother, KinematicsConfig, attach_ground};
use crate::calibration::Calibration;
use crate::error::Result;
use crate::geometry::Point;
use crate::track::{FramePoints, PointStage};
use crate::track_point::TrackPoint;

/// The smoother's settings for `calibration`.
///
/// Choice: the ground point of a box is its centre for a nadir calibration (the whole
/// object is seen from above) and the middle of its bottom edge otherwise (where an object
/// stands on the road in an oblique view), unless `ground_point` says otherwise. Speeds come
/// from the local line-fit smoother of [`crate::analysis::kinematics`].
fn kinematics(
    calibration: &Calibration,
    ground_point: Option<GroundPoint>,
    half_window_s: f64,
) -> KinematicsConfig {
    let gp = ground_point.unwrap_or(if calibration.metres_per_pixel().is_some() {
        GroundPoint::Centre
    } else {
        GroundPoint::BottomCentre
    });
    KinematicsConfig {
        half_window_s,
        ground_point: gp,
    }
}

/// Sets ground position, speed and heading on every point through `calibration` (see
/// [`GroundStage`] for the rules).
///
/// # Errors
/// A point whose ground point has no ground position; a bad window.
pub fn attach_calibration(
    points: &mut [TrackPoint],
    calibration: &Calibration,
    ground_point: Option<GroundPoint>,
    half_window_s: f64,
) -> Result<()> {
    let cfg = kinematics(calibration, ground_point, half_window_s);
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

/// [`attach_calibration`] as a pipeline stage: frames leave half a smoothing window late,
/// with the same values as the whole-run computation.
#[derive(Debug)]
pub struct GroundStage<'a>(GroundSmoother<'a>);

impl<'a> GroundStage<'a> {
    /// A stage mapping through `calibration`; the ground point as in
    /// [`attach_calibration`].
    ///
    /// # Errors
    /// A bad window.
    pub fn new(
        calibration: &'a Calibration,
        ground_point: Option<GroundPoint>,
        half_window_s: f64,
    ) -> Result<Self> {
        let cfg = kinematics(calibration, ground_point, half_window_s);
        Ok(Self(GroundSmoother::new(
            Box::new(move |p| {
                calibration
                    .ground_from_image(p)
                    .map(|(x, y)| Point::new(x, y))
            }),
            cfg,
        )?))
    }
}

impl PointStage for GroundStage<'_> {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        self.0.push(frame)
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        self.0.finish()
    }
}
