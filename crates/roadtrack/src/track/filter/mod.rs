//! Particle filter and labelled SMC-PHD filter (Ishii, Seo & Fuse; METHODS.md §3, seed 004).
//!
//! - [`motion`]: the constant-velocity system model (eq. 4), with velocity noise
//!   proportional to speed or absolute.
//! - [`resample`]: systematic and stratified resampling.
//! - [`particle`]: the basic particle filter, `ρ` particles per object.
//! - [`phd`]: the labelled SMC-PHD filter (steps a–f, eqs. 11–13), on images through a
//!   [`crate::likelihood::Likelihood`] or on point measurements ([`points`]).
//! - [`config`] and [`tracker`]: PF or PHD over a detector's output with the colour or a
//!   network likelihood, as a [`crate::track::Tracker`] (`roadtrack track --method pf|phd`).
//! - [`detections`]: the detections themselves as measurements (`--likelihood detections`).
//!
//! Particles live in flat arrays ([`Particles`], struct of arrays): one `Vec<f64>` per state
//! component, never one heap object per particle.

pub mod config;
#[cfg(test)]
mod count_diagnostics;
#[cfg(test)]
mod detection_tests;
pub mod detections;
pub mod motion;
pub mod particle;
pub mod phd;
pub mod points;
pub mod resample;
pub mod tracker;

pub use crate::geometry::SurveillanceRegion;
pub use config::{FilterMethod, FilterTrackConfig};
pub use detections::{BoxMeasurement, DetectionLikelihoodConfig, Measurements};
pub use motion::{ConstantVelocity, VelocityNoise};
pub use particle::{ParticleFilterConfig, ParticleFilterTracker};
pub use phd::{LabelAssociation, LabelUpdate, LabelledPhd, PhdConfig, PhdTracker};
pub use points::{BirthProposal, PointFilterConfig, filter_points};
pub use resample::ResamplingScheme;
pub use tracker::{FilterTracker, FrameCount};

use crate::geometry::Point;
use std::time::Duration;

/// Wall time spent in each stage, summed over steps.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FilterStageTimes {
    /// PHD steps b) and c): propagation and births.
    pub predict: Duration,
    /// Likelihood evaluation (`h` for every particle).
    pub likelihood: Duration,
    /// PHD step d): weight update, eqs. 11–13.
    pub update: Duration,
    /// PHD step e): label rules (particle filter: track start and end).
    pub labels: Duration,
    /// PHD step f): resampling and estimate extraction.
    pub resample: Duration,
    /// Number of steps summed.
    pub steps: u64,
}

impl FilterStageTimes {
    /// Total over stages.
    pub fn total(&self) -> Duration {
        self.predict + self.likelihood + self.update + self.labels + self.resample
    }
}

/// Particles as a struct of arrays: state `(x, y, v_x, v_y)`, weight, label and the last
/// likelihood `h(y | x)`, each in its own flat vector of equal length.
///
/// Velocities are in units per unit time (per frame in image trackers, where `dt = 1`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Particles {
    /// Positions, x.
    pub x: Vec<f64>,
    /// Positions, y.
    pub y: Vec<f64>,
    /// Velocities, x.
    pub vx: Vec<f64>,
    /// Velocities, y.
    pub vy: Vec<f64>,
    /// Weights (not normalised in the PHD filter: they sum to the expected count).
    pub w: Vec<f64>,
    /// Labels; 0 means unlabelled (METHODS.md §3 e).
    pub label: Vec<u32>,
    /// The likelihood `h(y | x)` of the last update, in `[0, 1]`.
    pub h: Vec<f64>,
}

impl Particles {
    /// An empty set with room for `n` particles.
    pub fn with_capacity(n: usize) -> Self {
        Self {
            x: Vec::with_capacity(n),
            y: Vec::with_capacity(n),
            vx: Vec::with_capacity(n),
            vy: Vec::with_capacity(n),
            w: Vec::with_capacity(n),
            label: Vec::with_capacity(n),
            h: Vec::with_capacity(n),
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Appends one particle.
    pub fn push(&mut self, pos: Point, vel: Point, w: f64, label: u32) {
        self.x.push(pos.x);
        self.y.push(pos.y);
        self.vx.push(vel.x);
        self.vy.push(vel.y);
        self.w.push(w);
        self.label.push(label);
        self.h.push(0.0);
    }

    /// Removes every particle.
    pub fn clear(&mut self) {
        self.x.clear();
        self.y.clear();
        self.vx.clear();
        self.vy.clear();
        self.w.clear();
        self.label.clear();
        self.h.clear();
    }

    /// Position of particle `i`.
    pub fn pos(&self, i: usize) -> Point {
        Point::new(self.x[i], self.y[i])
    }

    /// Positions of all particles, in order (the batch handed to a likelihood).
    pub fn positions_into(&self, out: &mut Vec<Point>) {
        out.clear();
        out.extend(self.x.iter().zip(&self.y).map(|(&x, &y)| Point::new(x, y)));
    }

    /// Sum of weights (the PHD filter's expected object count).
    pub fn total_weight(&self) -> f64 {
        self.w.iter().sum()
    }

    /// Keeps the particles at `ancestors` (with repetition), each with weight `weight`.
    pub fn select(&mut self, ancestors: &[usize], weight: f64) {
        fn pick<T: Copy>(v: &mut Vec<T>, idx: &[usize]) {
            let new: Vec<T> = idx.iter().map(|&i| v[i]).collect();
            *v = new;
        }
        pick(&mut self.x, ancestors);
        pick(&mut self.y, ancestors);
        pick(&mut self.vx, ancestors);
        pick(&mut self.vy, ancestors);
        pick(&mut self.label, ancestors);
        pick(&mut self.h, ancestors);
        self.w.clear();
        self.w.resize(ancestors.len(), weight);
    }

    /// Weighted mean position and velocity of the particles with indices in `idx`, and their
    /// total weight; `None` when the total weight is not positive.
    pub fn weighted_mean(&self, idx: impl Iterator<Item = usize>) -> Option<(Point, Point, f64)> {
        let (mut sw, mut sx, mut sy, mut svx, mut svy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for i in idx {
            let w = self.w[i];
            sw += w;
            sx += w * self.x[i];
            sy += w * self.y[i];
            svx += w * self.vx[i];
            svy += w * self.vy[i];
        }
        (sw > 0.0 && sw.is_finite()).then(|| {
            (
                Point::new(sx / sw, sy / sw),
                Point::new(svx / sw, svy / sw),
                sw,
            )
        })
    }
}

/// Chunk length for parallel loops over particles. Fixed, so that per-chunk random streams
/// and reductions do not depend on the thread count.
pub(crate) const CHUNK: usize = 256;
