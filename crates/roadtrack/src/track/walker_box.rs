//! Walkers' boxes from a body model seen through the calibration ([`WalkerBoxStage`],
//! `track --walker-boxes`), for cameras that look at people from the side.
//!
//! Why: a walker's box is the image of a body, and its width depends on which way they
//! face and where they stand, which a detector reading one frame's pixels can only guess.
//! On the oblique crossing (the MRF's tracks from the learned detector's boxes, held-out
//! seed 4) walkers' box widths were off by 13 % (sd of `ln(w / w_true)`), standing walkers'
//! 11–19 % too wide on average; with the truth's size in place of each box's, HOTA rose by
//! 0.04 (docs/EXPERIMENTS.md "Walkers' boxes from a body model"). The track knows where the
//! walker stands and which way they walk; the calibration says how a body there looks.
//!
//! For each pedestrian track (after the box smoothing, with the whole run's points):
//!
//! - each box's bottom centre is put on the ground through the calibration;
//! - the walk's direction at each point is the slope of a least-squares line, ground
//!   position against time, through the track's points within `half_window_frames` of it,
//!   where that speed is at least `min_speed_mps`; a walker standing still keeps the
//!   direction of their last steps before, or failing those their first steps after; a
//!   track never seen walking is left as it is;
//! - the body's centre is the ground point whose body box, turned to the walk, has its
//!   bottom centre where the track's box has it (a box's bottom is the image of the
//!   nearest corner of the feet, 0.1–0.2 m nearer the camera than the body's centre);
//! - the track's height is the prior `height_m` times the median, over its points, of the
//!   box's height divided by the body's image height there at the prior (clamped to
//!   0.6–1.4 times the prior);
//! - each box takes the width and height of the body's image there, at the track's
//!   height;
//! - with `smooth_centres`, each box's centre is that of the body's image at the track's
//!   path on the ground, smoothed from the detections that overlap its boxes
//!   ([`super::ground_path`]: IoU ≥ `min_iou`, the body of the track's height placed under
//!   each, outliers beyond `outlier_sigmas` left out, the likeliest of `accel_noise`); a
//!   track with fewer than three such detections keeps its centres, as does every track
//!   without `smooth_centres`.
//!
//! The body is the simulator's walker (`roadtrack simulate`, docs/SIMULATOR.md): legs
//! `0.8·depth × 0.6·width` from the ground to 0.47 of the height, a torso `depth × width`
//! narrowing to 0.9 of both at 0.83 of the height, a head 0.2 × 0.17 m to the top. Its
//! image is the box of its corners' projections through the camera recovered from the
//! calibration ([`Pinhole`]); for the simulator's walkers at their true place, heading and
//! size this is their `gt.txt` box to 0.01 px (a test).
//!
//! Choice: `accel_noise` 0.3 and 3 m²/s³. One noise of 0.3 was the best of 0.03–1 in a
//! prototype (the oblique crossing, held-out seeds 4–6); a track whose boxes pass from one
//! walker to another (a swap in a group) is then forced onto one smooth path between them,
//! and its centres move away from both (a simulated crossing: 0.0166 → 0.0193 of the
//! walkers' heights, mean distance from the truth's centres, against 0.0160 with the two,
//! docs/EXPERIMENTS.md "Walkers' centres from their path"). The likelier of the two lets
//! such a track follow its boxes; the pipelines score the same (±0.0004).
//! Choice: without `smooth_centres` the centre is kept. Anchoring the body's box at the
//! track box's bottom centre instead scored 0.609 against 0.615 on the crossing's held-out
//! seeds, and placing it whole at the ground point lost 0.1 in a prototype.
//! Choice: boxes within 1 px of the frame's edge are left as they are: the truth, like
//! the detector, boxes only what is inside the frame.

use super::FramePoints;
use super::ground_path::{PathParams, View, tracks};
use super::pipeline::PointStage;
use super::solid::{Block, hold_headings, image_box};
use crate::calibration::Calibration;
use crate::camera::Pinhole;
use crate::class::ObjectClass;
use crate::detect::FrameDetections;
use crate::error::{Error, Result, check_range};
use crate::geometry::{BBox, Point};
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

/// Parameters of [`WalkerBoxStage`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WalkerBoxConfig {
    /// The body's depth (chest to back), m. Default 0.30 (the simulator's walkers).
    pub depth_m: f64,
    /// The body's width (shoulders), m. Default 0.46.
    pub width_m: f64,
    /// The height a track's own is fitted from, m. Default 1.70.
    pub height_m: f64,
    /// Frames on each side of a point whose ground positions give the walk's direction
    /// there. Default 6.
    pub half_window_frames: u32,
    /// Slowest speed that has a direction, m/s. Default 0.3.
    pub min_speed_mps: f64,
    /// Centres from the track's smoothed path on the ground (see the module
    /// documentation). Default true.
    pub smooth_centres: bool,
    /// `smooth_centres`: spectral densities of the path's white acceleration noise, m²/s³;
    /// each track takes the likeliest. Default 0.3, 3: a walk, and a track that jumps
    /// between walkers.
    pub accel_noise: Vec<f64>,
    /// `smooth_centres`: image noise of a measured box's centre, this, px, plus
    /// `noise_per_px` times the box's longer side. Default 0.5.
    pub noise_px: f64,
    /// Default 0.05.
    pub noise_per_px: f64,
    /// `smooth_centres`: least IoU of a detection with a track's box for it to measure the
    /// track. Default 0.5.
    pub min_iou: f64,
    /// `smooth_centres`: a measurement further than this many noise units from the smoothed
    /// body's box is left out of the next pass. Default 2.
    pub outlier_sigmas: f64,
    /// `smooth_centres`: passes placing the body under the measured boxes. Default 3.
    pub passes: u32,
}

impl Default for WalkerBoxConfig {
    fn default() -> Self {
        Self {
            depth_m: 0.30,
            width_m: 0.46,
            height_m: 1.70,
            half_window_frames: 6,
            min_speed_mps: 0.3,
            smooth_centres: true,
            accel_noise: vec![0.3, 3.0],
            noise_px: 0.5,
            noise_per_px: 0.05,
            min_iou: 0.5,
            outlier_sigmas: 2.0,
            passes: 3,
        }
    }
}

impl WalkerBoxConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        use std::ops::Bound::{Excluded, Included};
        for (name, v) in [
            ("depth_m", self.depth_m),
            ("width_m", self.width_m),
            ("height_m", self.height_m),
        ] {
            check_range("WalkerBoxConfig", name, v, (Excluded(0.0), Included(10.0)))?;
        }
        if self.half_window_frames == 0 || self.half_window_frames > 1000 {
            return Err(Error::config(
                "WalkerBoxConfig",
                "half_window_frames",
                "must be 1–1000",
            ));
        }
        self.path_params().validate("WalkerBoxConfig", self.min_iou)
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
}

/// Fixed-point steps that put the body's centre on the ground under a box's bottom centre.
const CENTRE_STEPS: usize = 2;

impl crate::config::Validate for WalkerBoxConfig {
    fn validate(&self) -> Result<()> {
        WalkerBoxConfig::validate(self)
    }
}

/// The body of [`WalkerBoxConfig`]'s size and `height` (see the module documentation).
fn body(config: &WalkerBoxConfig, height: f64) -> [Block; 3] {
    let (d, w) = (config.depth_m / 2.0, config.width_m / 2.0);
    let legs = [-0.8 * d, 0.8 * d, 0.6 * w];
    [
        Block {
            bottom: legs,
            top: legs,
            z: [0.0, 0.47 * height],
        },
        Block {
            bottom: [-d, d, w],
            top: [-0.9 * d, 0.9 * d, 0.9 * w],
            z: [0.47 * height, 0.83 * height],
        },
        Block {
            bottom: [-0.1, 0.1, 0.085],
            top: [-0.09, 0.08, 0.075],
            z: [0.83 * height, height],
        },
    ]
}

/// The image box of a walker of `height` standing at ground point `(x, y)` and facing
/// `heading` (rad, counter-clockwise from ground `+x`), or `None` when part of the body
/// is behind the camera.
pub fn walker_box(
    camera: &Pinhole,
    config: &WalkerBoxConfig,
    (x, y): (f64, f64),
    heading: f64,
    height: f64,
) -> Option<BBox> {
    image_box(camera, &body(config, height), (x, y), heading)
}

/// The offline stage (see the module documentation).
#[derive(Debug)]
pub struct WalkerBoxStage {
    config: WalkerBoxConfig,
    view: View,
    held: Vec<FramePoints>,
    changed: usize,
}

impl WalkerBoxStage {
    /// A stage for `width × height` px frames seen through `calibration`.
    ///
    /// # Errors
    /// An invalid configuration, or a calibration no pinhole camera can be recovered from
    /// ([`Pinhole::from_calibration`]).
    pub fn new(
        config: WalkerBoxConfig,
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

    /// Boxes reshaped so far (known after [`PointStage::finish`]).
    pub fn changed(&self) -> usize {
        self.changed
    }

    /// Reshapes the boxes of one track: `at` holds `(frame index, point index)` in frame
    /// order.
    fn reshape(&self, frames: &mut [FramePoints], at: &[(usize, usize)]) -> usize {
        let cfg = &self.config;
        let point = |&(f, i): &(usize, usize)| &frames[f].points[i];
        let feet: Vec<Option<(f64, f64)>> = at
            .iter()
            .map(|a| {
                let b = point(a).bbox;
                self.view
                    .calibration
                    .ground_from_image(Point::new(b.centre().x, b.bottom()))
            })
            .collect();
        let k = i64::from(cfg.half_window_frames);
        let frame_of = |j: usize| i64::from(point(&at[j]).frame);
        let mut heading: Vec<Option<f64>> = vec![None; at.len()];
        // The points within k frames of point j: [lo, hi), moved along as j goes (frame order).
        let (mut lo, mut hi) = (0, 0);
        for (j, h) in heading.iter_mut().enumerate() {
            let frame = frame_of(j);
            while frame_of(lo) < frame - k {
                lo += 1;
            }
            while hi < at.len() && frame_of(hi) <= frame + k {
                hi += 1;
            }
            let (mut t, mut xs, mut ys) = (Vec::new(), Vec::new(), Vec::new());
            for i in lo..hi {
                if let Some((x, y)) = feet[i] {
                    t.push(point(&at[i]).time_s);
                    xs.push(x);
                    ys.push(y);
                }
            }
            if t.len() < 3 {
                continue;
            }
            // The box smoother's line, every weight 1 (a slope of 0 when all times are one).
            let ones = vec![1.0; t.len()];
            let (vx, vy) = (
                super::smooth::weighted_line(&t, &xs, &ones).1,
                super::smooth::weighted_line(&t, &ys, &ones).1,
            );
            if vx.hypot(vy) >= cfg.min_speed_mps {
                *h = Some(vy.atan2(vx));
            }
        }
        // Standing still: the last steps' direction, else the first steps' after; a track
        // never seen walking is left as it is.
        let Some(heading) = hold_headings(&heading) else {
            return 0;
        };
        // The box's bottom centre is the image of the nearest corner of the feet, not of
        // the body's centre on the ground: move the ground point until the body's box there
        // has its bottom centre where the track's box has it (two steps of the fixed point
        // take the error from 0.1–0.2 m to under 0.01 m).
        let centres: Vec<Option<(f64, f64)>> = (0..at.len())
            .map(|j| {
                let (seen, heading) = (feet[j]?, heading[j]);
                let mut g = seen;
                for _ in 0..CENTRE_STEPS {
                    let m = walker_box(&self.view.camera, cfg, g, heading, cfg.height_m)?;
                    let (x, y) = self
                        .view
                        .calibration
                        .ground_from_image(Point::new(m.centre().x, m.bottom()))?;
                    g = (g.0 + seen.0 - x, g.1 + seen.1 - y);
                }
                Some(g)
            })
            .collect();
        let model = |j: usize, height: f64| -> Option<BBox> {
            walker_box(&self.view.camera, cfg, centres[j]?, heading[j], height)
        };
        let mut ratios: Vec<f64> = (0..at.len())
            .filter_map(|j| {
                let m = model(j, cfg.height_m)?;
                let r = point(&at[j]).bbox.height / m.height;
                (r.is_finite() && r > 0.0).then_some(r)
            })
            .collect();
        if ratios.is_empty() {
            return 0;
        }
        ratios.sort_by(f64::total_cmp);
        let median = ratios[ratios.len() / 2];
        let height = cfg.height_m * median.clamp(0.6, 1.4);
        let path = if cfg.smooth_centres {
            self.path(frames, at, height)
        } else {
            None
        };
        let mut changed = 0;
        for (j, &(f, i)) in at.iter().enumerate() {
            let b = frames[f].points[i].bbox;
            if self.view.measurements.at_edge(&b) {
                continue;
            }
            let Some(m) = model(j, height) else { continue };
            if !(m.width.is_finite() && m.height.is_finite() && m.width > 0.0 && m.height > 0.0) {
                continue;
            }
            let centre = path.as_ref().and_then(|p| p[j]).unwrap_or(b.centre());
            frames[f].points[i].bbox = BBox::from_centre(centre, m.width, m.height);
            changed += 1;
        }
        changed
    }

    /// The centres of the body of `height` on the track's smoothed ground path, one per
    /// point of `at` (`None` where the body cannot be seen), or `None` when the path cannot
    /// be had (see [`GroundPath::fit`]).
    fn path(
        &self,
        frames: &[FramePoints],
        at: &[(usize, usize)],
        height: f64,
    ) -> Option<Vec<Option<Point>>> {
        let cfg = &self.config;
        let (times, seen) = self.view.measure(frames, at, cfg.min_iou);
        let body = |g: Vector2<f64>, heading: f64| {
            walker_box(&self.view.camera, cfg, (g.x, g.y), heading, height)
                .filter(|b| b.width.is_finite() && b.height.is_finite())
        };
        let ground = self.view.ground(cfg.path_params());
        let (states, heading) = ground.fit(&times, &seen, |g, h| {
            let c = body(g, h)?.centre();
            Some(Vector2::new(c.x, c.y))
        })?;
        Some(
            states
                .iter()
                .zip(&heading)
                .map(|(s, &h)| body(s.xy(), h).map(|b| b.centre()))
                .collect(),
        )
    }
}

impl PointStage for WalkerBoxStage {
    fn push(&mut self, frame: FramePoints) -> Result<Vec<FramePoints>> {
        self.held.push(frame);
        Ok(Vec::new())
    }

    fn wants_detections(&self) -> bool {
        self.config.smooth_centres
    }

    fn see_detections(&mut self, frame: u32, detections: &FrameDetections) {
        self.view.measurements.see(frame, detections);
    }

    fn finish(&mut self) -> Result<Vec<FramePoints>> {
        let mut frames = std::mem::take(&mut self.held);
        frames.sort_by_key(|f| f.frame);
        for at in tracks(&frames, |p| p.class == ObjectClass::Pedestrian).values() {
            self.changed += self.reshape(&mut frames, at);
        }
        Ok(frames)
    }
}

#[cfg(test)]
mod tests;
