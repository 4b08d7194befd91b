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

/// A pipeline stage that drops the points whose ground point (as [`GroundStage`] chooses
/// it) is on or above the horizon under `calibration`: they cannot stand on the road, and
/// [`GroundStage`] would fail on them. A box of a far object near the horizon, widened by
/// detector noise or a tracker's prediction, can end there.
// Choice: dropped rather than failing the run or kept without a ground position (the
// trajectories writer wants a ground state on every point); `roadtrack demo` puts this
// stage before its [`GroundStage`].
#[derive(Debug)]
pub struct OffGroundFilter<'a> {
    calibration: &'a Calibration,
    ground_point: GroundPoint,
}

impl<'a> OffGroundFilter<'a> {
    /// A filter for `calibration`; the ground point as in [`attach_calibration`].
    pub fn new(calibration: &'a Calibration, ground_point: Option<GroundPoint>) -> Self {
        Self {
            calibration,
            ground_point: kinematics(calibration, ground_point, 0.0).ground_point,
        }
    }
}

impl PointStage for OffGroundFilter<'_> {
    fn push(&mut self, mut frame: FramePoints) -> Result<Vec<FramePoints>> {
        frame.points.retain(|p| {
            let img = match self.ground_point {
                GroundPoint::BottomCentre => Point::new(p.bbox.centre().x, p.bbox.bottom()),
                GroundPoint::Centre => p.bbox.centre(),
            };
            self.calibration.ground_from_image(img).is_some()
        });
        Ok(vec![frame])
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        Ok(Vec::new())
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::class::ObjectClass;
    use crate::frame::Frame;
    use crate::geometry::BBox;
    use roadtrack_sim::{SceneKind, SimConfig, Simulation, ViewKind};

    /// Under the oblique intersection camera a box standing in the sky is dropped, one on
    /// the road kept, and the ground stage then maps every point left.
    #[test]
    fn off_ground_filter_drops_boxes_above_the_horizon() -> Result<()> {
        let cfg = SimConfig {
            scene: SceneKind::Intersection,
            view: ViewKind::Oblique,
            frames: 1,
            ..Default::default()
        };
        let calibration = Simulation::new(&cfg, 0)?.calibration().clone();
        let frame = Frame {
            index: 1,
            time_s: 0.0,
            image: image::RgbImage::new(4, 4),
        };
        let point = |id: u64, top: f64| TrackPoint {
            frame: 1,
            time_s: 0.0,
            id,
            class: ObjectClass::Unknown,
            bbox: BBox::new(300.0, top, 20.0, 10.0),
            score: 1.0,
            ground: None,
        };
        let pts = vec![point(1, 5.0), point(2, 400.0)];
        let out = OffGroundFilter::new(&calibration, None).push(FramePoints::new(&frame, pts))?;
        assert_eq!(out.len(), 1);
        let ids: Vec<u64> = out[0].points.iter().map(|p| p.id).collect();
        assert_eq!(ids, [2]);
        let mut ground = GroundStage::new(&calibration, None, 0.5)?;
        let mut done = ground.push(out[0].clone())?;
        done.extend(ground.finish()?);
        assert!(done[0].points[0].ground.is_some());
        // Without the filter the point in the sky fails the ground stage.
        let mut ground = GroundStage::new(&calibration, None, 0.5)?;
        assert!(
            ground
                .push(FramePoints::new(&frame, vec![point(1, 5.0)]))
                .is_err()
        );
        Ok(())
    }
}
