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
//! For each vehicle track (car, lorry, bus, motorcycle, bicycle), with the whole run, its
//! path on the ground is smoothed from its measured boxes and the vehicle model of its
//! class ([`super::ground_path`]: the detections overlapping its boxes at IoU ≥ `min_iou`,
//! a first pass from the boxes' bottom centres, then `passes` passes placing each
//! measurement under the model's box centre, outliers beyond `outlier_sigmas` left out, the
//! likeliest of the `accel_noise` values: a car cruising down a road takes a stiff model,
//! one that turns or brakes a loose one); each of the track's boxes is then the model's box
//! at the smoothed state (centre and size), turned to the smoothed heading.
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

use super::FramePoints;
use super::confirm::ClassVotes;
use super::ground_path::{PathParams, View, tracks};
use super::pipeline::PointStage;
use super::solid::{Block, image_box};
use crate::calibration::Calibration;
use crate::camera::Pinhole;
use crate::class::ObjectClass;
use crate::detect::FrameDetections;
use crate::error::{Result, check_range};
use crate::geometry::BBox;
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

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
        use std::ops::Bound::{Excluded, Included};
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
        self.path_params()
            .validate("VehicleBoxConfig", self.min_iou)
    }

    /// The path's settings.
    fn path_params(&self) -> PathParams<'_> {
        PathParams {
            accel_noise: &self.accel_noise,
            noise_px: self.noise_px,
            noise_per_px: self.noise_per_px,
            outlier_sigmas: self.outlier_sigmas,
            passes: self.passes,
            min_speed_mps: self.min_speed_mps,
        }
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

/// The offline stage (see the module documentation).
#[derive(Debug)]
pub struct VehicleBoxStage {
    config: VehicleBoxConfig,
    view: View,
    held: Vec<FramePoints>,
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
        Ok(Self {
            config,
            view: View::new(calibration, width, height)?,
            held: Vec::new(),
            changed: 0,
        })
    }

    /// Boxes redrawn so far (known after [`PointStage::finish`]).
    pub fn changed(&self) -> usize {
        self.changed
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
            camera: &self.view.camera,
            shape,
            dims,
        };
        let (times, seen) = self.view.measure(frames, at, cfg.min_iou);
        let path = self.view.ground(cfg.path_params());
        let Some((states, heading)) = path.fit(&times, &seen, |g, h| model.centre(g, h)) else {
            return 0;
        };
        let mut changed = 0;
        for (j, &(f, i)) in at.iter().enumerate() {
            if self.view.measurements.at_edge(&frames[f].points[i].bbox) {
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

impl PointStage for VehicleBoxStage {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        self.held.push(frame);
        Ok(Vec::new())
    }

    fn wants_detections(&self) -> bool {
        true
    }

    fn see_detections(&mut self, frame: u32, detections: &FrameDetections) {
        self.view.measurements.see(frame, detections);
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        let mut frames = std::mem::take(&mut self.held);
        frames.sort_by_key(|f| f.frame);
        for at in tracks(&frames, |_| true).values() {
            self.changed += self.redraw(&mut frames, at);
        }
        Ok(frames)
    }
}

#[cfg(test)]
mod tests;
