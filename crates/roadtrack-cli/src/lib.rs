//! The parts of the `roadtrack` command that its benchmarks (`benches/`) share with it:
//! the throughput measurements behind `roadtrack bench`. The command itself is `main.rs`.

pub mod bench;
