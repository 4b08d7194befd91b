//! Finding objects in frames: the per-pixel background model, foreground regions, and the
//! background-subtraction detector built on them.

pub mod background;
pub mod background_model;
pub mod regions;
