//! Labelled SMC-PHD filter (METHODS.md §3 "Extended method", seed 004 §4; Vo, Singh &
//! Doucet 2003 for the SMC-PHD, Ikoma 2010 for labels).
//!
//! The particle weights approximate the PHD (intensity) of the multi-object state: their sum
//! is the expected number of objects. One step is
//!
//! - b) survival: propagate by [`ConstantVelocity`](super::motion::ConstantVelocity),
//!   `w̃ = p_s · w` ([`LabelledPhd::predict`]);
//! - c) birth: particles with total weight `μ_Γ` (grid, [`LabelledPhd::add_grid_births`], or
//!   around measurements, [`LabelledPhd::add_measurement_births`]);
//! - d) update, eqs. 11–13 ([`LabelledPhd::update_image`], [`LabelledPhd::update_points`]);
//! - e) labels: likelihood threshold, border exit, 2-means split, mesh birth, merge
//!   ([`LabelledPhd::update_labels`]);
//! - f) stratified resampling to `ρ` particles per expected object ([`LabelledPhd::resample`]).
//!
//! Step a) (uniform initial particles, weighted by `h`, resampled, labelled by k-means) is
//! [`LabelledPhd::initialise_uniform`]. [`PhdTracker`] runs the steps on frames with a
//! [`Likelihood`](crate::likelihood::Likelihood); [`super::points::filter_points`] on point
//! measurements.
//!
//! Files: `config.rs` (the parameters), `labelled.rs` (the filter's state and steps),
//! `detections.rs` (step d with detections as measurements), `association.rs` (the same
//! with a detection explaining at most one label), `occlusion.rs` (a lower `p_D` for
//! labels hidden behind others), `smoother.rs` (the count smoothed over the next frames),
//! `tracker.rs` (the filter on frames), `tests.rs`.

mod association;
mod cardinality;
mod config;
mod detections;
mod labelled;
mod occlusion;
mod smoother;
#[cfg(test)]
mod tests;
mod tracker;

pub use super::FilterStageTimes;
pub use association::{LabelAssociation, marginal_associations};
pub use cardinality::map_cardinality;
pub use config::{LabelUpdate, PhdConfig};
pub use detections::{BoxMeasurement, DetectionModel};
pub use labelled::LabelledPhd;
#[cfg(test)]
use labelled::kmeans;
pub use occlusion::{LabelBox, occluded_pd, visible_fractions};
pub use smoother::{ExistenceSmoother, LabelWeights, smoothed_existence};
pub use tracker::PhdTracker;

use crate::error::Result;
use crate::geometry::Point;

/// A batch likelihood evaluation: `h` for each position into the output slice.
pub type BatchEval<'a> = dyn FnMut(&[Point], &mut [f64]) -> Result<()> + 'a;

/// One label's estimate at a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelEstimate {
    /// The label (≥ 1).
    pub label: u32,
    /// Weighted mean position.
    pub pos: Point,
    /// Weighted mean velocity, units per unit time.
    pub vel: Point,
    /// Sum of the label's weights (its expected count).
    pub weight: f64,
}
