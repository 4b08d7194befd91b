//! roadtrack-core: the types, file formats and frame sources every roadtrack crate shares.
//!
//! Nothing here tracks: frames ([`Frame`]), boxes and points ([`geometry`]), classes,
//! detections and track points (the data between the stages), the one [`Error`], the only
//! random-generator constructor ([`rng`]), calibrations, TOML config loading, and [`io`]:
//! frame sources (image folders, MOTChallenge sequences, video through ffmpeg), frame
//! sinks and every file format of `docs/FORMATS.md`, each written atomically.
//!
//! The algorithms are in the `roadtrack` crate, which re-exports these modules under the
//! same names; the simulator (`roadtrack-sim`) and the drawing (`roadtrack-viz`) build on
//! this crate alone.

pub mod calibration;
pub mod camera;
pub mod class;
pub mod config;
pub mod detection;
pub mod error;
pub mod frame;
pub mod geometry;
pub mod io;
pub mod limits;
pub mod rng;
pub mod track_point;

pub use calibration::Calibration;
pub use class::ObjectClass;
pub use detection::Detection;
pub use error::{Error, Result};
pub use frame::Frame;
pub use geometry::{BBox, Point};
pub use track_point::{GroundState, TrackPoint};
