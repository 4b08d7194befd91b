//! `roadtrack experiment`: correct-match rates of relaxation variants and baselines on the
//! same problems (METHODS.md §1 "Measure"; seed 000's Tables 1 and 2).

use super::matching::RelaxArgs;
use crate::common::Ui;
use anyhow::Result;
use roadtrack::track::relaxation::experiment::problem_dirs;
use roadtrack::track::relaxation::{
    DecisionRule, ExperimentMethod, RelaxationVariant, run_experiment,
};
use std::path::PathBuf;

/// Score relaxation variants and baselines on folders of two-frame problems.
///
/// Each PROBLEMS_DIR holds sub-folders (or is one) with `frame1.csv`, `frame2.csv` and
/// `truth.csv`, as `roadtrack simulate --pairs` writes them; all problems of all folders
/// are pooled. The correct-match rate is the fraction of frame-1 vehicles whose decision
/// (partner or none) equals the truth. Methods: `a`, `b`, `c`, `d` (the paper's variants,
/// also by name, e.g. `colour-bidirectional`), any of them with `+one-to-one` or
/// `+assignment` (the decision rules),
/// `nearest-neighbour` (`nn`) and `optimal-assignment` (`oa`, Hungarian on distance), both
/// with the same gate D. Default: Table 1 = `a,b,c,d,nn,oa`. The other parameters come
/// from the flags or `--config`. Writes
/// `method,problems,vehicles,correct,rate,mean_problem_rate`.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  \
    roadtrack simulate --scene road --pairs 1.5 --n-pairs 50 --seed 1 -o p1/\n  \
    roadtrack simulate --scene road --pairs 1.5 --n-pairs 50 --seed 2 -o p2/\n  \
    roadtrack experiment p1/ p2/ -o table1.csv\n  \
    roadtrack experiment p1/ p2/ --methods d,d+one-to-one -o -")]
pub struct Args {
    /// Folders of problems.
    #[arg(required = true)]
    pub problems_dirs: Vec<PathBuf>,
    /// Output table (`-` for standard output).
    #[arg(short, long, default_value = "experiment.csv")]
    pub output: PathBuf,
    /// Comma-separated methods.
    #[arg(long, value_delimiter = ',', value_parser = parse_method, default_value = "a,b,c,d,nn,oa")]
    pub methods: Vec<ExperimentMethod>,
    #[command(flatten)]
    pub relax: RelaxArgs,
}

/// Parses a method name (see the command's help).
fn parse_method(s: &str) -> Result<ExperimentMethod, String> {
    match s {
        "nn" | "nearest-neighbour" | "nearest-neighbor" => {
            return Ok(ExperimentMethod::NearestNeighbour);
        }
        "oa" | "optimal-assignment" | "hungarian" => {
            return Ok(ExperimentMethod::OptimalAssignment);
        }
        _ => {}
    }
    let (v, decision) = if let Some(v) = s.strip_suffix("+one-to-one") {
        (v, DecisionRule::OneToOne)
    } else if let Some(v) = s.strip_suffix("+assignment") {
        (v, DecisionRule::Assignment)
    } else {
        (s, DecisionRule::Argmax)
    };
    let variant = match v {
        "a" => RelaxationVariant::Unidirectional,
        "b" => RelaxationVariant::ColourUnidirectional,
        "c" => RelaxationVariant::Bidirectional,
        "d" => RelaxationVariant::ColourBidirectional,
        other => other.parse::<RelaxationVariant>().map_err(|_| {
            format!(
                "unknown method `{s}`; expected a, b, c, d (or a variant's name), \
                 optionally with +one-to-one or +assignment, nn or oa"
            )
        })?,
    };
    Ok(ExperimentMethod::Relaxation(variant, decision))
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    crate::flags::reject_given(
        &[
            ("--variant", args.relax.variant.is_some()),
            ("--decision", args.relax.decision.is_some()),
        ],
        "chosen per method here: name it in --methods (e.g. d+one-to-one)",
    )?;
    if args.methods.is_empty() {
        return Err(crate::flags::invalid("--methods is empty"));
    }
    let cfg = args.relax.config()?;
    let mut dirs = Vec::new();
    for d in &args.problems_dirs {
        dirs.extend(problem_dirs(d)?);
    }
    let bar = ui.progress(Some(dirs.len() as u64), "problems");
    let table = run_experiment(&dirs, &args.methods, &cfg, &mut |d, _| bar.set_position(d))?;
    bar.finish_and_clear();
    table.write_csv(&args.output)?;
    if let Some(first) = table.rows.first() {
        ui.info(format!(
            "{} problems, {} frame-1 vehicles → {}",
            first.problems,
            first.vehicles,
            args.output.display()
        ));
    }
    for r in &table.rows {
        ui.info(format!(
            "{:>36}  {:6.2} %  ({}/{})",
            r.method.to_string(),
            100.0 * r.rate,
            r.correct,
            r.vehicles
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_parse() {
        assert_eq!(
            parse_method("d"),
            Ok(ExperimentMethod::Relaxation(
                RelaxationVariant::ColourBidirectional,
                DecisionRule::Argmax
            ))
        );
        assert_eq!(
            parse_method("bidirectional+one-to-one"),
            Ok(ExperimentMethod::Relaxation(
                RelaxationVariant::Bidirectional,
                DecisionRule::OneToOne
            ))
        );
        assert_eq!(parse_method("oa"), Ok(ExperimentMethod::OptimalAssignment));
        assert_eq!(parse_method("nn"), Ok(ExperimentMethod::NearestNeighbour));
        assert!(parse_method("e").is_err());
        // Every name the table prints parses back.
        for m in [
            "unidirectional",
            "colour-unidirectional",
            "colour-bidirectional+one-to-one",
            "colour-bidirectional+assignment",
            "nearest-neighbour",
            "optimal-assignment",
        ] {
            let parsed = parse_method(m).expect(m);
            assert_eq!(parsed.to_string(), m);
        }
    }
}
