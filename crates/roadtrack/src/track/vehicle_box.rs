//! Vehicles' boxes from their smoothed path on the ground and a vehicle model seen through
//! the calibration ([`VehicleBoxStage`], `track --vehicle-boxes`), for cameras that look
//! along a road from the side.
//!
//! Why: far down an oblique road a car is a few pixels, and a detector's box there is off
//! by half a pixel and 10 % in width, a third of its IoU. On the oblique road (the MRF on
//! the learned detector's boxes, seed 1) exact boxes in place of the tracks' raised HOTA
//! from 0.533 to 0.721, exact centres alone to 0.598, exact sizes alone to 0.566
//! (docs/EXPERIMENTS.md "Vehicles' boxes from the ground"). A vehicle's path is smooth on
//! the ground, where its near, large boxes place it to centimetres; the calibration says
//! how it looks at each point.
//!
//! For each vehicle track (car, lorry, bus, motorcycle, bicycle), with the whole run:
//!
//! - its measurements are the detections the tracker was given that overlap its boxes
//!   (the best one per frame at IoU ≥ `min_iou`; none touching the frame's edge, which
//!   cuts them); a run without detections measures the track's own boxes;
//! - a first pass puts each measured box's bottom centre on the ground, its covariance the
//!   image noise `noise_px + noise_per_px · size` carried through the calibration, and
//!   smooths the positions (`vehicle_box/rts.rs`: constant velocity, white acceleration
//!   noise);
//! - the heading at each point is that of the smoothed velocity where the speed is at
//!   least `min_speed_mps`, else the last one before (or the first one after); a vehicle
//!   never that fast is left as it is;
//! - then `passes` times: each measurement is put where the model's box, turned to the
//!   heading, has its centre at the measured box's centre (Newton's method), with the
//!   covariance of that mapping; from the second pass on, a measurement whose centre lies
//!   more than `outlier_sigmas` noise units from the model's box at the smoothed state is
//!   left out of that pass; the positions are smoothed again;
//! - each smoothing is done with every acceleration noise of `accel_noise` and keeps the
//!   likeliest (the innovations' density): a car cruising down a road takes a stiff model,
//!   one that turns or brakes a loose one;
//! - each of the track's boxes is the model's box at the smoothed state (centre and size).
//!
//! The vehicles are the simulator's (`roadtrack simulate`, docs/SIMULATOR.md): a car is an
//! under-body, a body to 0.58 of its height and a cabin; a lorry a chassis, a cab and a
//! cargo box; a bus a box on an under-body; a motorcycle (and a bicycle) a frame, a rider's
//! torso and head. Their image is the box of their corners' projections through the camera
//! recovered from the calibration ([`Pinhole`]); at a simulated vehicle's true place,
//! heading and size it is its `gt.txt` box to 0.05 px (a test). The sizes are the classes'
//! means (the simulator's, which are those of European fleets).
//!
//! Choice: the whole box comes from the model, centre included. In the Python prototype
//! (seed 1, the tracks' own boxes measured) the model's centres alone gave 0.540, its sizes
//! alone 0.554, both 0.564, from 0.533.
//! Choice: the detections are measured, not the tracks' boxes (the tracker's boxes are
//! smoothed and carried between detections already): 0.595 against 0.567 on seed 1.
//! Choice: `min_iou` 0.7 and the outlier test at 2 noise units: a detection that the
//! tracker's box does not agree with is a neighbour's or a part (held-out seeds 4–6, with
//! one acceleration noise of 0.01: `min_iou` 0.5 / 0.6 / 0.7 0.682 / 0.687 / 0.689; at
//! 0.5, the outlier test at 1.5 / 2 / 3 units 0.683 / 0.682 / 0.671, none in the prototype
//! 0.654).
//! Choice: the likeliest of four acceleration noises rather than one: one noise of 0.003 /
//! 0.01 / 0.1 gives 0.695 / 0.689 / 0.675 on the oblique road (held-out seeds 4–6) but
//! 0.644 / 0.667 / 0.706 on the oblique intersection, where the tracks score 0.715 without
//! the stage; the four give 0.683 and 0.713. The stage is for roads; at junctions the
//! refined boxes are as good already.
//! Choice: the tracks' boxes touching the frame's edge are left as they are: the truth,
//! like the detector, boxes only what is inside the frame.
//! Choice: one size per class, not fitted per track. Fitting a lorry's length and height to
//! its boxes of 12 px or more changed held-out HOTA by +0.0001 in the prototype.

mod rts;

use super::FramePoints;
use super::confirm::ClassVotes;
use super::pipeline::PointStage;
use super::solid::{Block, hold_headings, image_box};
use crate::calibration::Calibration;
use crate::camera::Pinhole;
use crate::class::ObjectClass;
use crate::detect::FrameDetections;
use crate::error::{Error, Result, check_range};
use crate::geometry::{BBox, Point};
use nalgebra::{Matrix2, Vector2, Vector4};
use rts::Fix;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of [`VehicleBoxStage`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleBoxConfig {
    /// A car's length, width and height, m. Default 4.5, 1.78, 1.45.
    pub car_m: [f64; 3],
    /// A lorry's. Default 9.0, 2.45, 3.3.
    pub truck_m: [f64; 3],
    /// A bus's. Default 11.0, 2.5, 3.1.
    pub bus_m: [f64; 3],
    /// A motorcycle's with its rider. Default 2.1, 0.8, 1.5.
    pub motorcycle_m: [f64; 3],
    /// A bicycle's with its rider. Default 1.8, 0.6, 1.7.
    pub bicycle_m: [f64; 3],
    /// Spectral densities of the white acceleration noise, m²/s³: each track is smoothed
    /// with the one under which its measurements are likeliest. Default 0.003, 0.01, 0.1,
    /// 1: a car cruising down a road, one that brakes, one that turns.
    pub accel_noise: Vec<f64>,
    /// Image noise of a measured box's centre: this, px, plus `noise_per_px` times the
    /// box's longer side. Default 0.5.
    pub noise_px: f64,
    /// Default 0.05.
    pub noise_per_px: f64,
    /// Least IoU of a detection with a track's box for it to measure the track. Default 0.7.
    pub min_iou: f64,
    /// A measurement further than this many noise units from the smoothed model's box is
    /// left out of the next pass. Default 2.
    pub outlier_sigmas: f64,
    /// Passes with the model after the first from the boxes' bottoms. Default 3.
    pub passes: u32,
    /// Slowest speed that has a heading, m/s. Default 1.
    pub min_speed_mps: f64,
}

impl Default for VehicleBoxConfig {
    fn default() -> Self {
        Self {
            car_m: [4.5, 1.78, 1.45],
            truck_m: [9.0, 2.45, 3.3],
            bus_m: [11.0, 2.5, 3.1],
            motorcycle_m: [2.1, 0.8, 1.5],
            bicycle_m: [1.8, 0.6, 1.7],
            accel_noise: vec![0.003, 0.01, 0.1, 1.0],
            noise_px: 0.5,
            noise_per_px: 0.05,
            min_iou: 0.7,
            outlier_sigmas: 2.0,
            passes: 3,
            min_speed_mps: 1.0,
        }
    }
}

impl VehicleBoxConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        use std::ops::Bound::{Excluded, Included, Unbounded};
        for (name, dims) in [
            ("car_m", self.car_m),
            ("truck_m", self.truck_m),
            ("bus_m", self.bus_m),
            ("motorcycle_m", self.motorcycle_m),
            ("bicycle_m", self.bicycle_m),
        ] {
            for v in dims {
                check_range("VehicleBoxConfig", name, v, (Excluded(0.0), Included(30.0)))?;
            }
        }
        if self.accel_noise.is_empty() {
            return Err(Error::config(
                "VehicleBoxConfig",
                "accel_noise",
                "needs at least one value",
            ));
        }
        for &q in &self.accel_noise {
            check_range(
                "VehicleBoxConfig",
                "accel_noise",
                q,
                (Excluded(0.0), Unbounded),
            )?;
        }
        check_range(
            "VehicleBoxConfig",
            "noise_px",
            self.noise_px,
            (Excluded(0.0), Unbounded),
        )?;
        check_range(
            "VehicleBoxConfig",
            "noise_per_px",
            self.noise_per_px,
            (Included(0.0), Unbounded),
        )?;
        check_range(
            "VehicleBoxConfig",
            "min_iou",
            self.min_iou,
            (Excluded(0.0), Included(1.0)),
        )?;
        check_range(
            "VehicleBoxConfig",
            "outlier_sigmas",
            self.outlier_sigmas,
            (Excluded(0.0), Unbounded),
        )?;
        if self.passes > 100 {
            return Err(Error::config("VehicleBoxConfig", "passes", "must be 0–100"));
        }
        check_range(
            "VehicleBoxConfig",
            "min_speed_mps",
            self.min_speed_mps,
            (Excluded(0.0), Unbounded),
        )
    }

    /// The shape and size of `class`, or `None` for a class that is not a vehicle.
    fn vehicle(&self, class: &ObjectClass) -> Option<(Shape, [f64; 3])> {
        Some(match class {
            ObjectClass::Car => (Shape::Car, self.car_m),
            ObjectClass::Truck => (Shape::Lorry, self.truck_m),
            ObjectClass::Bus => (Shape::Bus, self.bus_m),
            ObjectClass::Motorcycle => (Shape::TwoWheeler, self.motorcycle_m),
            ObjectClass::Bicycle => (Shape::TwoWheeler, self.bicycle_m),
            _ => return None,
        })
    }
}

impl crate::config::Validate for VehicleBoxConfig {
    fn validate(&self) -> Result<()> {
        VehicleBoxConfig::validate(self)
    }
}

/// A vehicle's build (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// Under-body, body, cabin.
    Car,
    /// Chassis, cab, cargo box.
    Lorry,
    /// Under-body, body, roof.
    Bus,
    /// Frame, rider's torso, head.
    TwoWheeler,
}

/// The blocks of a vehicle of `shape`, `[length, width, height]` m: the simulator's
/// (crates/roadtrack-sim/src/render.rs).
fn blocks(shape: Shape, [l, w, h]: [f64; 3]) -> Vec<Block> {
    let (hl, hw) = (l / 2.0, w / 2.0);
    match shape {
        Shape::Car => {
            let top = 0.58 * h;
            vec![
                Block::new(
                    [-hl * 0.86, hl * 0.86, hw * 0.9],
                    [-hl * 0.86, hl * 0.86, hw * 0.9],
                    [0.0, 0.32],
                ),
                Block::new(
                    [-hl, hl, hw],
                    [-hl * 0.97, hl * 0.96, hw * 0.97],
                    [0.32, top],
                ),
                Block::new(
                    [-0.34 * l, 0.2 * l, hw * 0.94],
                    [-0.24 * l, 0.02 * l, hw * 0.8],
                    [top, h],
                ),
            ]
        }
        Shape::Lorry => {
            let cab = (0.35 * l).min(2.2);
            vec![
                Block::new(
                    [-hl * 0.95, hl * 0.95, hw * 0.9],
                    [-hl * 0.95, hl * 0.95, hw * 0.9],
                    [0.25, 0.95],
                ),
                Block::new([hl - cab, hl, hw], [hl - cab, hl, hw], [0.5, 1.7]),
                Block::new(
                    [hl - cab, hl, hw],
                    [hl - cab, hl - 0.25, hw * 0.96],
                    [1.7, 0.85 * h],
                ),
                Block::new(
                    [-hl, hl - cab - 0.2, hw],
                    [-hl, hl - cab - 0.2, hw],
                    [0.95, h],
                ),
            ]
        }
        Shape::Bus => vec![
            Block::new(
                [-hl * 0.96, hl * 0.96, hw * 0.92],
                [-hl * 0.96, hl * 0.96, hw * 0.92],
                [0.2, 0.5],
            ),
            Block::new([-hl, hl, hw], [-hl, hl, hw], [0.5, h - 0.45]),
            Block::new(
                [-hl, hl, hw],
                [-hl + 0.1, hl - 0.1, hw * 0.97],
                [h - 0.45, h],
            ),
        ],
        Shape::TwoWheeler => vec![
            Block::new(
                [-hl, hl, hw * 0.45],
                [-hl * 0.9, hl * 0.9, hw * 0.4],
                [0.25, 0.9],
            ),
            Block::new(
                [-0.45, 0.05, hw * 0.6],
                [-0.4, 0.0, hw * 0.55],
                [0.9, 0.78 * h],
            ),
            Block::new([-0.3, -0.02, 0.15], [-0.28, -0.04, 0.13], [0.78 * h, h]),
        ],
    }
}

/// The image box of a vehicle of `shape` and size `dims` (length, width, height, m) whose
/// centre stands at ground point `(x, y)`, facing `heading` (rad, counter-clockwise from
/// ground `+x`), or `None` when part of it is behind the camera.
pub fn vehicle_box(
    camera: &Pinhole,
    shape: Shape,
    dims: [f64; 3],
    (x, y): (f64, f64),
    heading: f64,
) -> Option<BBox> {
    image_box(camera, &blocks(shape, dims), (x, y), heading)
}

/// Newton steps that put a measurement on the ground under the model's box centre.
const NEWTON_STEPS: usize = 3;
/// Ground step of the model's numerical Jacobian, m.
const JACOBIAN_STEP_M: f64 = 0.05;
/// Image step of the calibration's numerical Jacobian, px.
const JACOBIAN_STEP_PX: f64 = 0.5;
/// Added to each measurement's covariance, m²: keeps it invertible where the calibration
/// squeezes a pixel to nothing.
const COVARIANCE_FLOOR_M2: f64 = 1e-4;

/// The offline stage (see the module documentation).
#[derive(Debug)]
pub struct VehicleBoxStage {
    config: VehicleBoxConfig,
    calibration: Calibration,
    camera: Pinhole,
    size: (f64, f64),
    held: Vec<FramePoints>,
    detections: BTreeMap<u32, Vec<BBox>>,
    changed: usize,
}

/// What one vehicle track is: its shape and size.
struct Model<'a> {
    camera: &'a Pinhole,
    shape: Shape,
    dims: [f64; 3],
}

impl Model<'_> {
    fn bbox(&self, g: Vector2<f64>, heading: f64) -> Option<BBox> {
        let b = vehicle_box(self.camera, self.shape, self.dims, (g.x, g.y), heading)?;
        (b.width.is_finite() && b.height.is_finite() && b.width > 0.0 && b.height > 0.0)
            .then_some(b)
    }

    fn centre(&self, g: Vector2<f64>, heading: f64) -> Option<Vector2<f64>> {
        let c = self.bbox(g, heading)?.centre();
        Some(Vector2::new(c.x, c.y))
    }

    /// The ground point whose box has its centre at `seen` (px), from `start`, and the
    /// inverse of the centre's Jacobian there (m per px).
    fn place(
        &self,
        seen: Vector2<f64>,
        start: Vector2<f64>,
        heading: f64,
    ) -> Option<(Vector2<f64>, Matrix2<f64>)> {
        let mut g = start;
        let mut inverse = Matrix2::zeros();
        for _ in 0..NEWTON_STEPS {
            let c = self.centre(g, heading)?;
            let mut j = Matrix2::zeros();
            for k in 0..2 {
                let mut d = Vector2::zeros();
                d[k] = JACOBIAN_STEP_M;
                let col = (self.centre(g + d, heading)? - self.centre(g - d, heading)?)
                    / (2.0 * JACOBIAN_STEP_M);
                j.set_column(k, &col);
            }
            inverse = j.try_inverse()?;
            g += inverse * (seen - c);
        }
        g.iter().all(|v| v.is_finite()).then_some((g, inverse))
    }
}

impl VehicleBoxStage {
    /// A stage for `width × height` px frames seen through `calibration`.
    ///
    /// # Errors
    /// An invalid configuration, or a calibration no pinhole camera can be recovered from
    /// ([`Pinhole::from_calibration`]).
    pub fn new(
        config: VehicleBoxConfig,
        calibration: &Calibration,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        config.validate()?;
        let camera = Pinhole::from_calibration(calibration, width, height)?;
        Ok(Self {
            config,
            calibration: calibration.clone(),
            camera,
            size: (f64::from(width), f64::from(height)),
            held: Vec::new(),
            detections: BTreeMap::new(),
            changed: 0,
        })
    }

    /// Boxes redrawn so far (known after [`PointStage::finish`]).
    pub fn changed(&self) -> usize {
        self.changed
    }

    /// Whether `b` touches the frame's edge (within 1 px).
    fn at_edge(&self, b: &BBox) -> bool {
        let (w, h) = self.size;
        b.left < 1.0 || b.top < 1.0 || b.right() > w - 1.0 || b.bottom() > h - 1.0
    }

    /// The measured box of a track's box `b` in `frame`: the best-overlapping detection
    /// (the box itself when the run had none), or `None`.
    fn measured(&self, frame: u32, b: &BBox) -> Option<BBox> {
        let m = if self.detections.is_empty() {
            *b
        } else {
            let (iou, d) = self
                .detections
                .get(&frame)?
                .iter()
                .map(|d| (d.iou(b), *d))
                .max_by(|x, y| x.0.total_cmp(&y.0))?;
            if iou < self.config.min_iou {
                return None;
            }
            d
        };
        (!self.at_edge(&m)).then_some(m)
    }

    /// The measurement noise of box `b`, px.
    fn noise(&self, b: &BBox) -> f64 {
        self.config.noise_px + self.config.noise_per_px * b.width.max(b.height)
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
        self.config
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

    /// Redraws the boxes of one track: `at` holds `(frame index, point index)` in frame
    /// order.
    fn redraw(&self, frames: &mut [FramePoints], at: &[(usize, usize)]) -> usize {
        let cfg = &self.config;
        let point = |&(f, i): &(usize, usize)| &frames[f].points[i];
        // The track's class: the most frequent among its points (the life cycle gives them
        // one already; without it they may differ).
        let mut votes = ClassVotes::default();
        for a in at {
            votes.add(&point(a).class);
        }
        let class = votes.majority().unwrap_or_default();
        let Some((shape, dims)) = cfg.vehicle(&class) else {
            return 0;
        };
        let model = Model {
            camera: &self.camera,
            shape,
            dims,
        };
        let times: Vec<f64> = at.iter().map(|a| point(a).time_s).collect();
        let seen: Vec<Option<BBox>> = at
            .iter()
            .map(|a| self.measured(point(a).frame, &point(a).bbox))
            .collect();
        if seen.iter().flatten().count() < 3 {
            return 0;
        }
        // First pass: the boxes' bottom centres on the ground.
        let fixes: Vec<Option<Fix>> = seen
            .iter()
            .map(|m| {
                let m = m.as_ref()?;
                self.ground_fix(Point::new(m.centre().x, m.bottom()), self.noise(m))
            })
            .collect();
        let Some(mut states) = self.smooth(&times, &fixes) else {
            return 0;
        };
        for pass in 0..cfg.passes {
            let Some(heading) = headings(&states, cfg.min_speed_mps) else {
                return 0;
            };
            let fixes: Vec<Option<Fix>> = seen
                .iter()
                .enumerate()
                .map(|(j, m)| {
                    let m = m.as_ref()?;
                    let c = Vector2::new(m.centre().x, m.centre().y);
                    let sigma = self.noise(m);
                    let at = states[j].xy();
                    if pass > 0 {
                        let r = (model.centre(at, heading[j])? - c).norm();
                        if r > cfg.outlier_sigmas * sigma {
                            return None;
                        }
                    }
                    let (g, inverse) = model.place(c, at, heading[j])?;
                    Some((g, covariance(&inverse, sigma)))
                })
                .collect();
            match self.smooth(&times, &fixes) {
                Some(s) => states = s,
                None => return 0,
            }
        }
        let Some(heading) = headings(&states, cfg.min_speed_mps) else {
            return 0;
        };
        let mut changed = 0;
        for (j, &(f, i)) in at.iter().enumerate() {
            if self.at_edge(&frames[f].points[i].bbox) {
                continue;
            }
            if let Some(b) = model.bbox(states[j].xy(), heading[j]) {
                frames[f].points[i].bbox = b;
                changed += 1;
            }
        }
        changed
    }
}

/// `J · Jᵀ · σ²`, plus the floor.
fn covariance(j: &Matrix2<f64>, sigma: f64) -> Matrix2<f64> {
    j * j.transpose() * (sigma * sigma) + Matrix2::identity() * COVARIANCE_FLOOR_M2
}

/// The heading of each state's velocity where its speed is at least `min_speed`, else the
/// last such before, else the first after; `None` when the vehicle never moves that fast.
fn headings(states: &[Vector4<f64>], min_speed: f64) -> Option<Vec<f64>> {
    let moving: Vec<Option<f64>> = states
        .iter()
        .map(|s| (s[2].hypot(s[3]) >= min_speed).then(|| s[3].atan2(s[2])))
        .collect();
    hold_headings(&moving)
}

impl PointStage for VehicleBoxStage {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        self.held.push(frame);
        Ok(Vec::new())
    }

    fn wants_detections(&self) -> bool {
        true
    }

    fn see_detections(&mut self, frame: u32, detections: &FrameDetections) {
        let boxes: Vec<BBox> = detections
            .detections
            .iter()
            .filter_map(|d| d.bbox())
            .collect();
        if !boxes.is_empty() {
            self.detections.insert(frame, boxes);
        }
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        let mut frames = std::mem::take(&mut self.held);
        frames.sort_by_key(|f| f.frame);
        let mut tracks: BTreeMap<u64, Vec<(usize, usize)>> = BTreeMap::new();
        for (f, frame) in frames.iter().enumerate() {
            for (i, p) in frame.points.iter().enumerate() {
                tracks.entry(p.id).or_default().push((f, i));
            }
        }
        for at in tracks.values() {
            self.changed += self.redraw(&mut frames, at);
        }
        Ok(frames)
    }
}

#[cfg(test)]
mod tests;
