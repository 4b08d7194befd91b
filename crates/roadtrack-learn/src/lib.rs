//! Training roadtrack's learned detector with burn (skeleton; the training code lands next).

pub use burn;
