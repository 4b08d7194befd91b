//! The paper's parameter sweep (28 611 settings of A, B, C) over a folder of problems.
//!
//! ```text
//! cargo run -p roadtrack --example relaxation_sweep -- PROBLEMS_DIR [OUT.csv]
//! ```

use roadtrack::track::relaxation::{RelaxationConfig, SweepGrid, sweep};
use std::path::PathBuf;

fn main() -> roadtrack::Result<()> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().unwrap_or_else(|| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/relaxation").into()
    }));
    let t = std::time::Instant::now();
    let res = sweep(
        &dir,
        &RelaxationConfig::default(),
        &SweepGrid::default(),
        &mut |_, _| {},
    )?;
    let secs = t.elapsed().as_secs_f64();
    if let Some(out) = args.next() {
        res.write_csv(&PathBuf::from(out))?;
    }
    let paper = res
        .rows
        .iter()
        .find(|r| r.weights == RelaxationConfig::default().weights());
    println!(
        "{} settings x {} problems in {secs:.1} s; best {:?}; paper's setting {:?}",
        res.rows.len(),
        res.problems,
        res.best.map(|b| (b.weights, b.rate())),
        paper.map(|p| p.rate())
    );
    Ok(())
}
