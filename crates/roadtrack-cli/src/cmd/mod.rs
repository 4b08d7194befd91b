//! One module per subcommand.

pub mod analyze;
pub mod bench;
pub mod check;
pub mod demo;
pub mod detect;
pub mod plot;
pub mod render;
pub mod track;
pub mod train;
