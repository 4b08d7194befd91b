//! Input and output: frame sources and the file formats of INTERFACES.md.
//!
//! A frame source is any `Iterator<Item = Result<Frame>>`; [`source::open`] picks the right
//! one for a path (folder of numbered images, MOTChallenge sequence, video file). Every
//! writer goes through [`atomic::write_atomic`], so an interrupted run never leaves a
//! half-written file that looks complete.

pub mod atomic;
pub mod detections;
pub mod matches;
pub mod mot;
pub mod natural;
pub mod occlusion;
pub mod points;
pub mod seqinfo;
pub mod source;
mod table;
pub mod trajectories;
pub mod video;

pub use atomic::write_atomic;
pub use source::{FrameSource, SourceInfo, SourceKind, SourceOptions};
