//! One module per subcommand.

pub mod bench;
pub mod detect;
pub mod train;
