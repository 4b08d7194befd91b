//! roadtrack: trajectories of vehicles and pedestrians from traffic imagery.
//!
//! The library holds every algorithm; the `roadtrack` command is a thin layer over it.
//! Methods (see `docs/METHODS.md`):
//! - bidirectional probabilistic relaxation with colour (seed 000),
//! - the spatio-temporal MRF model (seed 002),
//! - particle and labelled SMC-PHD filters with a CNN likelihood (seed 004).
//!
//! Layers (ARCHITECTURE.md): the shared types, formats and frame sources of
//! `roadtrack-core`, re-exported here under their own names; [`detect`] (frame →
//! detections); [`track`] (the methods); [`likelihood`]; [`eval`]; [`analysis`]; and the one
//! linear-assignment solver both the metrics and the relaxation baselines use
//! ([`assignment`]).

pub use roadtrack_core::{
    calibration, camera, class, config, detection, error, frame, geometry, io, limits, rng,
    track_point,
};

pub mod analysis;
pub mod assignment;
pub mod detect;
pub mod eval;
pub mod likelihood;
pub mod track;

pub use calibration::Calibration;
pub use class::ObjectClass;
pub use detection::Detection;
pub use error::{Error, Result};
pub use frame::Frame;
pub use geometry::{BBox, Point};
pub use track_point::{GroundState, TrackPoint};
