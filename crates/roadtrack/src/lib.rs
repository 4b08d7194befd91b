//! roadtrack: trajectories of vehicles and pedestrians from traffic imagery.
//!
//! The library holds every algorithm; the `roadtrack` command is a thin layer over it.
//! Methods (see `docs/METHODS.md`):
//! - bidirectional probabilistic relaxation with colour (seed 000),
//! - the spatio-temporal MRF model (seed 002),
//! - particle and labelled SMC-PHD filters with a CNN likelihood (seed 004).

pub mod analysis;
pub mod background;
pub mod bench;
pub mod calibration;
pub mod class;
pub mod cnn;
pub mod config;
pub mod demo;
pub mod detection;
pub mod detector;
pub mod error;
pub mod filter;
pub mod frame;
pub mod geometry;
pub mod io;
pub mod likelihood;
pub mod metrics;
pub mod mrf;
pub mod overlay;
pub mod plot;
pub mod relaxation;
pub mod render;
pub mod rng;
pub mod sim;
pub mod track;
pub mod tracking;

pub use calibration::Calibration;
pub use class::ObjectClass;
pub use detection::Detection;
pub use error::{Error, Result};
pub use frame::Frame;
pub use geometry::{BBox, Point};
pub use track::{GroundState, TrackPoint};
