//! The tracking methods.

pub mod filter;
pub mod mrf;
pub mod relaxation;
