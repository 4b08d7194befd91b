//! `roadtrack sweep`: the paper's parameter sweep of relaxation (METHODS.md §1 "Defaults").

use super::matching::RelaxArgs;
use crate::common::Ui;
use anyhow::{Result, bail};
use roadtrack::track::relaxation::sweep::{Steps, SweepRow};
use roadtrack::track::relaxation::{
    DecisionRule, RelaxationConfig, SweepGrid, UpdateWeights, sweep,
};
use roadtrack_viz::plot::{Series, line_chart};
use std::path::PathBuf;

/// Sweep the relaxation weights A, B, C over a folder of two-frame problems and report the
/// correct-match rate of every setting.
///
/// PROBLEMS_DIR holds sub-folders (or is one) with `frame1.csv`, `frame2.csv` and
/// `truth.csv` (`id1,id2`, empty `id2` = no partner), as `roadtrack simulate --pairs`
/// writes them. The default grid is the paper's: A 0–1 step 0.1, B and C 0–10 step 0.2
/// (28 611 settings). The other parameters (T, R, D, iterations, variant, decision) come
/// from the flags or `--config`. Writes `a,b,c,correct,total,rate`, one row per setting;
/// prints the best setting (ties: smallest A, then B, then C) and the paper's
/// (A 0.5, B 1, C 1).
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  \
    roadtrack simulate --scene road --pairs 1.5 --n-pairs 20 -o pairs/\n  \
    roadtrack sweep pairs/ -o sweep.csv --plot sweep.png\n  \
    roadtrack sweep pairs/ --grid-a 0.5:0.5:0.1 --grid-b 0:4:0.5 --grid-c 0:4:0.5 -o -")]
pub struct Args {
    /// Folder of problems.
    pub problems_dir: PathBuf,
    /// Output rate table (`-` for standard output).
    #[arg(short, long, default_value = "sweep.csv")]
    pub output: PathBuf,
    /// Values of A as FROM:TO:STEP [default: 0:1:0.1].
    #[arg(long, value_name = "FROM:TO:STEP", value_parser = parse_steps)]
    pub grid_a: Option<Steps>,
    /// Values of B as FROM:TO:STEP [default: 0:10:0.2].
    #[arg(long, value_name = "FROM:TO:STEP", value_parser = parse_steps)]
    pub grid_b: Option<Steps>,
    /// Values of C as FROM:TO:STEP [default: 0:10:0.2].
    #[arg(long, value_name = "FROM:TO:STEP", value_parser = parse_steps)]
    pub grid_c: Option<Steps>,
    /// Also plot the rate against B (at the best A: for the best C, C = 0, and the
    /// paper's A 0.5, C 1), PNG or SVG by extension.
    #[arg(long, value_name = "F.png|svg", value_parser = crate::common::plot_output)]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub relax: RelaxArgs,
}

/// Parses `FROM:TO:STEP` (inclusive of TO up to rounding) into [`Steps`].
fn parse_steps(s: &str) -> Result<Steps, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let nums: Vec<f64> = parts
        .iter()
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("`{s}`: {e}; expected FROM:TO:STEP, e.g. 0:10:0.2"))?;
    let [from, to, step] = nums[..] else {
        return Err(format!("`{s}`: expected FROM:TO:STEP, e.g. 0:10:0.2"));
    };
    if !(from.is_finite() && to.is_finite() && step.is_finite()) || from < 0.0 || to < from {
        return Err(format!("`{s}`: need 0 ≤ FROM ≤ TO, all finite"));
    }
    if step <= 0.0 && to > from {
        return Err(format!("`{s}`: STEP must be positive"));
    }
    let count = if to > from {
        ((to - from) / step + 1e-9).floor() as usize + 1
    } else {
        1
    };
    if count > 100_000 {
        return Err(format!("`{s}`: {count} values is too many"));
    }
    Ok(Steps {
        start: from,
        step: if step > 0.0 { step } else { 1.0 },
        count,
    })
}

fn fmt_w(w: &UpdateWeights) -> String {
    format!(
        "A {} B {} C {}",
        w.own_weight, w.forward_support_weight, w.backward_support_weight
    )
}

fn fmt_rate(r: &SweepRow) -> String {
    format!("{:.2} % ({}/{})", 100.0 * r.rate(), r.correct, r.total)
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    crate::flags::reject_given(
        &args.relax.weight_flags(),
        "swept here: give its range with --grid-a, --grid-b or --grid-c",
    )?;
    let cfg = args.relax.config()?;
    let def = SweepGrid::default();
    let grid = SweepGrid {
        own_weight: args.grid_a.unwrap_or(def.own_weight),
        forward_support_weight: args.grid_b.unwrap_or(def.forward_support_weight),
        backward_support_weight: args.grid_c.unwrap_or(def.backward_support_weight),
    };
    let bar = ui.progress(Some(grid.len() as u64), "sweep");
    let t0 = std::time::Instant::now();
    let res = sweep(&args.problems_dir, &cfg, &grid, &mut |d, _| {
        bar.set_position(d)
    })?;
    bar.finish_and_clear();
    res.write_csv(&args.output)?;
    let Some(best) = res.best else {
        bail!("the grid is empty");
    };
    let total = best.total;
    ui.info(format!(
        "{} settings × {} problems ({} frame-1 vehicles, variant {}, decision {}) in {:.1} s → {}",
        res.rows.len(),
        res.problems,
        total,
        cfg.variant,
        match cfg.decision {
            DecisionRule::Argmax => "argmax",
            DecisionRule::OneToOne => "one-to-one",
            DecisionRule::Assignment => "assignment",
        },
        t0.elapsed().as_secs_f64(),
        args.output.display()
    ));
    ui.info(format!(
        "best:  {}: {}",
        fmt_w(&best.weights),
        fmt_rate(&best)
    ));
    let paper = RelaxationConfig {
        variant: cfg.variant,
        ..RelaxationConfig::default()
    }
    .weights();
    let same = |a: f64, b: f64| (a - b).abs() < 1e-9;
    let find = |a: f64, c: f64| -> Vec<&SweepRow> {
        res.rows
            .iter()
            .filter(|r| same(r.weights.own_weight, a) && same(r.weights.backward_support_weight, c))
            .collect()
    };
    // The unidirectional variants report C as swept; the paper's row is the one with C = 1.
    match res.rows.iter().find(|r| {
        same(r.weights.own_weight, 0.5)
            && same(r.weights.forward_support_weight, 1.0)
            && same(r.weights.backward_support_weight, 1.0)
    }) {
        Some(p) => ui.info(format!("paper: {}: {}", fmt_w(&p.weights), fmt_rate(p))),
        None => ui.info(format!("paper: {} is not in the grid", fmt_w(&paper))),
    }
    if let Some(plot) = &args.plot {
        let bw = best.weights;
        let mut series = Vec::new();
        let mut wanted = vec![
            (bw.own_weight, bw.backward_support_weight, "best A and C"),
            (bw.own_weight, 0.0, "best A, C = 0"),
            (0.5, 1.0, "paper's A 0.5, C 1"),
        ];
        wanted.dedup_by(|x, y| same(x.0, y.0) && same(x.1, y.1));
        for (a, c, what) in wanted {
            let rows = find(a, c);
            if rows.is_empty() {
                continue;
            }
            series.push(Series {
                label: format!("A = {a}, C = {c} ({what})"),
                points: rows
                    .iter()
                    .map(|r| (r.weights.forward_support_weight, 100.0 * r.rate()))
                    .collect(),
            });
        }
        line_chart(
            &series,
            &format!(
                "Correct-match rate vs B ({} problems, {})",
                res.problems, cfg.variant
            ),
            "B (forward support weight)",
            "correct-match rate, %",
            plot,
        )?;
        ui.info(format!("plot → {}", plot.display()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_parse_inclusive_ranges() {
        let s = parse_steps("0:10:0.2").expect("valid");
        assert_eq!((s.start, s.count), (0.0, 51));
        assert_eq!(s.value(50), 10.0);
        let s = parse_steps("0:1:0.1").expect("valid");
        assert_eq!(s.count, 11);
        let s = parse_steps("0.5:0.5:0.1").expect("valid");
        assert_eq!((s.start, s.count), (0.5, 1));
        assert!(parse_steps("1:0:0.1").is_err());
        assert!(parse_steps("0:1").is_err());
        assert!(parse_steps("0:1:0").is_err());
        assert!(parse_steps("a:1:0.1").is_err());
    }
}
