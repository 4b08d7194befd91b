//! Tracker output: one row per object per frame.

use crate::class::ObjectClass;
use crate::geometry::BBox;

/// Position and motion on the ground, from a calibration (INTERFACES.md trajectories CSV).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundState {
    /// Ground x, m.
    pub x_m: f64,
    /// Ground y, m.
    pub y_m: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Heading, degrees (0 = +x, counter-clockwise towards +y).
    pub heading_deg: f64,
}

/// Where one tracked object is in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackPoint {
    /// 1-based frame number.
    pub frame: u32,
    /// Time of the frame, s.
    pub time_s: f64,
    /// Track identifier, stable over the object's life.
    pub id: u64,
    /// Class, [`ObjectClass::Unknown`] when the tracker does not classify.
    pub class: ObjectClass,
    /// Box, px.
    pub bbox: BBox,
    /// Confidence in `[0, 1]` (1 when the tracker has none).
    pub score: f64,
    /// Ground position and motion, when a calibration was given.
    pub ground: Option<GroundState>,
}
