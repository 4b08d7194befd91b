//! Training roadtrack's learned detector (`roadtrack train --detector`) with burn on
//! simulator renders, exported as ONNX for tract inference (`roadtrack_cnn::centernet`).
//!
//! - [`net`]: the centre-point network in burn (the layer list of
//!   `roadtrack_cnn::centernet::CenterNetShape`);
//! - [`data`]: randomised simulator episodes, photometric corruption, crops and targets;
//! - [`train`](mod@train): focal + L1 losses and the deterministic training loop.
//!
//! See docs/DETECTION.md "Learned detector" for the recipe and its cost.

pub use roadtrack::detect::centernet as arch;
pub mod data;
pub mod net;
pub mod parity;
pub mod record;
pub mod train;

#[cfg(test)]
mod tests;

pub use burn;
pub use train::{Progress, StepLoss, TrainConfig, train, training_preprocessing};
