//! One module per subcommand.

pub mod analyze;
pub mod bench;
pub mod check;
pub mod demo;
pub mod detect;
pub mod evaluate;
pub mod experiment;
pub mod filter;
pub mod matching;
pub mod plot;
pub mod render;
pub mod simulate;
pub mod sweep;
pub mod track;
pub mod train;
