//! One module per subcommand.

pub mod bench;
pub mod detect;
pub mod plot;
pub mod render;
