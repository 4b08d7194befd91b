//! roadtrack-viz: drawing and plotting for roadtrack — boxes, labels and fading trails over
//! frames ([`render`], drawing primitives in [`overlay`]), the MRF object map over a frame
//! ([`object_map`]), and charts ([`plot`]: trajectories, time-space diagrams, metric
//! curves) as PNG or SVG. Fonts are compiled in, so pictures are the same on every machine.

pub mod object_map;
pub mod overlay;
pub mod plot;
pub mod render;
