//! One module per subcommand.

pub mod bench;
pub mod check;
pub mod detect;
pub mod evaluate;
pub mod filter;
pub mod plot;
pub mod render;
