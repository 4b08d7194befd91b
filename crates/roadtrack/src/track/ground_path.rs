//! One object's path on the ground from its measured boxes and a model of how it looks
//! ([`GroundPath::fit`]): what [`super::vehicle_box`] and [`super::walker_box`] smooth
//! their tracks with.
//!
//! - A track's measurements are the detections the tracker was given that overlap its
//!   boxes (the best one per frame at IoU ≥ a least IoU; none touching the frame's edge,
//!   which cuts them; [`Measurements`]); a run without detections measures the track's own
//!   boxes.
//! - A first pass puts each measured box's bottom centre on the ground, its covariance the
//!   image noise `noise_px + noise_per_px · size` carried through the calibration, and
//!   smooths the positions (`ground_path/rts.rs`: constant velocity, white acceleration
//!   noise).
//! - The heading at each point is that of the smoothed velocity where the speed is at
//!   least `min_speed_mps`, else the last one before (or the first one after); an object
//!   never that fast has no path.
//! - Then `passes` times: each measurement is put where the model's box, turned to the
//!   heading, has its centre at the measured box's centre (Newton's method), with the
//!   covariance of that mapping; from the second pass on, a measurement whose centre lies
//!   more than `outlier_sigmas` noise units from the model's box at the smoothed state is
//!   left out of that pass; the positions are smoothed again.
//! - Each smoothing is done with every acceleration noise of `accel_noise` and keeps the
//!   likeliest (the innovations' density).

mod rts;

use super::FramePoints;
use super::solid::hold_headings;
use crate::calibration::Calibration;
use crate::camera::Pinhole;
use crate::detect::FrameDetections;
use crate::error::{Error, Result, check_range};
use crate::geometry::{BBox, Point};
use nalgebra::{Matrix2, Vector2, Vector4};
use rts::Fix;
use std::collections::BTreeMap;

/// Newton steps that put a measurement on the ground under the model's box centre.
const NEWTON_STEPS: usize = 3;
/// Ground step of the model's numerical Jacobian, m.
const JACOBIAN_STEP_M: f64 = 0.05;
/// Image step of the calibration's numerical Jacobian, px.
const JACOBIAN_STEP_PX: f64 = 0.5;
/// Added to each measurement's covariance, m²: keeps it invertible where the calibration
/// squeezes a pixel to nothing.
const COVARIANCE_FLOOR_M2: f64 = 1e-4;

/// The settings of one smoothing (see the module documentation).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PathParams<'a> {
    pub accel_noise: &'a [f64],
    pub noise_px: f64,
    pub noise_per_px: f64,
    pub outlier_sigmas: f64,
    pub passes: u32,
    pub min_speed_mps: f64,
}

impl PathParams<'_> {
    /// Checks every setting and `min_iou`, naming `owner`'s field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub(crate) fn validate(&self, owner: &'static str, min_iou: f64) -> Result<()> {
        use std::ops::Bound::{Excluded, Included, Unbounded};
        if self.accel_noise.is_empty() {
            return Err(Error::config(
                owner,
                "accel_noise",
                "needs at least one value",
            ));
        }
        for &q in self.accel_noise {
            check_range(owner, "accel_noise", q, (Excluded(0.0), Unbounded))?;
        }
        check_range(owner, "noise_px", self.noise_px, (Excluded(0.0), Unbounded))?;
        check_range(
            owner,
            "noise_per_px",
            self.noise_per_px,
            (Included(0.0), Unbounded),
        )?;
        check_range(owner, "min_iou", min_iou, (Excluded(0.0), Included(1.0)))?;
        check_range(
            owner,
            "outlier_sigmas",
            self.outlier_sigmas,
            (Excluded(0.0), Unbounded),
        )?;
        if self.passes > 100 {
            return Err(Error::config(owner, "passes", "must be 0–100"));
        }
        check_range(
            owner,
            "min_speed_mps",
            self.min_speed_mps,
            (Excluded(0.0), Unbounded),
        )
    }
}

/// The detections of a run, by frame, that measure tracks' boxes.
#[derive(Debug, Default)]
pub(crate) struct Measurements {
    detections: BTreeMap<u32, Vec<BBox>>,
    size: (f64, f64),
}

impl Measurements {
    /// None yet, for `width × height` px frames.
    pub(crate) fn new(width: f64, height: f64) -> Self {
        Self {
            detections: BTreeMap::new(),
            size: (width, height),
        }
    }

    /// Keeps `frame`'s detections' boxes.
    pub(crate) fn see(&mut self, frame: u32, detections: &FrameDetections) {
        let boxes: Vec<BBox> = detections
            .detections
            .iter()
            .filter_map(|d| d.bbox())
            .collect();
        if !boxes.is_empty() {
            self.detections.insert(frame, boxes);
        }
    }

    /// Whether `b` touches the frame's edge (within 1 px).
    pub(crate) fn at_edge(&self, b: &BBox) -> bool {
        let (w, h) = self.size;
        b.left < 1.0 || b.top < 1.0 || b.right() > w - 1.0 || b.bottom() > h - 1.0
    }

    /// The measured box of a track's box `b` in `frame`: the best-overlapping detection at
    /// IoU ≥ `min_iou` (the box itself when the run had none), or `None`; never one at the
    /// frame's edge.
    pub(crate) fn measured(&self, frame: u32, b: &BBox, min_iou: f64) -> Option<BBox> {
        let m = if self.detections.is_empty() {
            *b
        } else {
            let (iou, d) = self
                .detections
                .get(&frame)?
                .iter()
                .map(|d| (d.iou(b), *d))
                .max_by(|x, y| x.0.total_cmp(&y.0))?;
            if iou < min_iou {
                return None;
            }
            d
        };
        (!self.at_edge(&m)).then_some(m)
    }
}

/// What a box stage sees through: the calibration, the camera recovered from it, and the
/// run's detections.
#[derive(Debug)]
pub(crate) struct View {
    pub calibration: Calibration,
    pub camera: Pinhole,
    pub measurements: Measurements,
}

impl View {
    /// The view of `width × height` px frames through `calibration`.
    ///
    /// # Errors
    /// A calibration no pinhole camera can be recovered from ([`Pinhole::from_calibration`]).
    pub(crate) fn new(calibration: &Calibration, width: u32, height: u32) -> Result<Self> {
        Ok(Self {
            calibration: calibration.clone(),
            camera: Pinhole::from_calibration(calibration, width, height)?,
            measurements: Measurements::new(f64::from(width), f64::from(height)),
        })
    }

    /// The times of one track's points (`at`: `(frame index, point index)` in frame order)
    /// and their measured boxes ([`Measurements::measured`]).
    pub(crate) fn measure(
        &self,
        frames: &[FramePoints],
        at: &[(usize, usize)],
        min_iou: f64,
    ) -> (Vec<f64>, Vec<Option<BBox>>) {
        at.iter()
            .map(|&(f, i)| {
                let p = &frames[f].points[i];
                let seen = self.measurements.measured(p.frame, &p.bbox, min_iou);
                (p.time_s, seen)
            })
            .unzip()
    }

    /// The smoother of `params` on this view's ground.
    pub(crate) fn ground<'a>(&'a self, params: PathParams<'a>) -> GroundPath<'a> {
        GroundPath {
            calibration: &self.calibration,
            params,
        }
    }
}

/// The points of `frames` that `keep` takes, by track id: `(frame index, point index)` in
/// frame order (`frames` sorted by frame).
pub(crate) fn tracks(
    frames: &[FramePoints],
    keep: impl Fn(&crate::track_point::TrackPoint) -> bool,
) -> BTreeMap<u64, Vec<(usize, usize)>> {
    let mut tracks: BTreeMap<u64, Vec<(usize, usize)>> = BTreeMap::new();
    for (f, frame) in frames.iter().enumerate() {
        for (i, p) in frame.points.iter().enumerate() {
            if keep(p) {
                tracks.entry(p.id).or_default().push((f, i));
            }
        }
    }
    tracks
}

/// Smooths paths on the ground seen through one calibration.
pub(crate) struct GroundPath<'a> {
    pub calibration: &'a Calibration,
    pub params: PathParams<'a>,
}

impl GroundPath<'_> {
    /// The measurement noise of box `b`, px.
    fn noise(&self, b: &BBox) -> f64 {
        self.params.noise_px + self.params.noise_per_px * b.width.max(b.height)
    }

    /// A ground fix of image point `p` (the bottom centre of a box) with noise `sigma` px.
    fn ground_fix(&self, p: Point, sigma: f64) -> Option<Fix> {
        let g = |x: f64, y: f64| -> Option<Vector2<f64>> {
            let (gx, gy) = self.calibration.ground_from_image(Point::new(x, y))?;
            Some(Vector2::new(gx, gy))
        };
        let e = JACOBIAN_STEP_PX;
        let mut j = Matrix2::zeros();
        j.set_column(0, &((g(p.x + e, p.y)? - g(p.x - e, p.y)?) / (2.0 * e)));
        j.set_column(1, &((g(p.x, p.y + e)? - g(p.x, p.y - e)?) / (2.0 * e)));
        Some((g(p.x, p.y)?, covariance(&j, sigma)))
    }

    /// The smoothed states under the likeliest of the configured acceleration noises.
    fn smooth(&self, times: &[f64], fixes: &[Option<Fix>]) -> Option<Vec<Vector4<f64>>> {
        self.params
            .accel_noise
            .iter()
            .filter_map(|&q| rts::smooth(times, fixes, q))
            .fold(
                None,
                |best: Option<(Vec<Vector4<f64>>, f64)>, (s, ll)| match best {
                    Some((_, b)) if b >= ll => best,
                    _ => Some((s, ll)),
                },
            )
            .map(|(s, _)| s)
    }

    /// The smoothed states (`[x, y, vx, vy]`, m and m/s) and headings (rad) at `times` of a
    /// track whose boxes measured `seen` (`None` where nothing was), the model's box centre
    /// at a ground point and heading given by `centre`; `None` when fewer than three boxes
    /// were measured, the object never moved at `min_speed_mps`, or a smoothing failed.
    pub(crate) fn fit(
        &self,
        times: &[f64],
        seen: &[Option<BBox>],
        centre: impl Fn(Vector2<f64>, f64) -> Option<Vector2<f64>>,
    ) -> Option<(Vec<Vector4<f64>>, Vec<f64>)> {
        let p = &self.params;
        if seen.iter().flatten().count() < 3 {
            return None;
        }
        // First pass: the boxes' bottom centres on the ground.
        let fixes: Vec<Option<Fix>> = seen
            .iter()
            .map(|m| {
                let m = m.as_ref()?;
                self.ground_fix(Point::new(m.centre().x, m.bottom()), self.noise(m))
            })
            .collect();
        let mut states = self.smooth(times, &fixes)?;
        for pass in 0..p.passes {
            let heading = headings(&states, p.min_speed_mps)?;
            let fixes: Vec<Option<Fix>> = seen
                .iter()
                .enumerate()
                .map(|(j, m)| {
                    let m = m.as_ref()?;
                    let c = Vector2::new(m.centre().x, m.centre().y);
                    let sigma = self.noise(m);
                    let at = states[j].xy();
                    if pass > 0 {
                        let r = (centre(at, heading[j])? - c).norm();
                        if r > p.outlier_sigmas * sigma {
                            return None;
                        }
                    }
                    let (g, inverse) = place(&centre, c, at, heading[j])?;
                    Some((g, covariance(&inverse, sigma)))
                })
                .collect();
            states = self.smooth(times, &fixes)?;
        }
        let heading = headings(&states, p.min_speed_mps)?;
        Some((states, heading))
    }
}

/// The ground point whose model box (`centre`) has its centre at `seen` (px), from `start`,
/// and the inverse of the centre's Jacobian there (m per px).
fn place(
    centre: &impl Fn(Vector2<f64>, f64) -> Option<Vector2<f64>>,
    seen: Vector2<f64>,
    start: Vector2<f64>,
    heading: f64,
) -> Option<(Vector2<f64>, Matrix2<f64>)> {
    let mut g = start;
    let mut inverse = Matrix2::zeros();
    for _ in 0..NEWTON_STEPS {
        let c = centre(g, heading)?;
        let mut j = Matrix2::zeros();
        for k in 0..2 {
            let mut d = Vector2::zeros();
            d[k] = JACOBIAN_STEP_M;
            let col = (centre(g + d, heading)? - centre(g - d, heading)?) / (2.0 * JACOBIAN_STEP_M);
            j.set_column(k, &col);
        }
        inverse = j.try_inverse()?;
        g += inverse * (seen - c);
    }
    g.iter().all(|v| v.is_finite()).then_some((g, inverse))
}

/// `J · Jᵀ · σ²`, plus the floor.
fn covariance(j: &Matrix2<f64>, sigma: f64) -> Matrix2<f64> {
    j * j.transpose() * (sigma * sigma) + Matrix2::identity() * COVARIANCE_FLOOR_M2
}

/// The heading of each state's velocity where its speed is at least `min_speed`, else the
/// last such before, else the first after; `None` when the object never moves that fast.
fn headings(states: &[Vector4<f64>], min_speed: f64) -> Option<Vec<f64>> {
    let moving: Vec<Option<f64>> = states
        .iter()
        .map(|s| (s[2].hypot(s[3]) >= min_speed).then(|| s[3].atan2(s[2])))
        .collect();
    hold_headings(&moving)
}
