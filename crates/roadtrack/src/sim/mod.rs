//! Traffic simulator and renderer with ground truth (issue 3, `roadtrack simulate`).

pub mod config;
pub mod scene;
pub mod traffic;

pub use config::SimConfig;
