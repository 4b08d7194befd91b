//! roadtrack: trajectories of vehicles and pedestrians from traffic imagery.
//!
//! The library holds every algorithm; the `roadtrack` command is a thin layer over it.
//! Methods (see `docs/METHODS.md`):
//! - bidirectional probabilistic relaxation with colour (seed 000),
//! - the spatio-temporal MRF model (seed 002),
//! - particle and labelled SMC-PHD filters with a CNN likelihood (seed 004).

pub mod background;
pub mod bench;
pub mod class;
pub mod cnn;
pub mod config;
pub mod detection;
pub mod detector;
pub mod error;
pub mod frame;
pub mod geometry;
pub mod io;
pub mod overlay;
pub mod rng;
pub mod track;

pub use class::ObjectClass;
pub use detection::Detection;
pub use error::{Error, Result};
pub use frame::Frame;
pub use geometry::{BBox, Point};
pub use track::{GroundState, TrackPoint};
