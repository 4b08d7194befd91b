//! Correct-match rates over two-frame problems (METHODS.md §1 "Measure"; Tables 1 and 2).
//!
//! A problem is a folder with `frame1.csv`, `frame2.csv` (detections CSV) and `truth.csv`
//! (`id1,id2`, empty `id2` = no partner; read with the matches reader, which takes this
//! header). The correct-match rate is the fraction of frame-1 vehicles whose decision
//! (partner or none) equals the truth.

use super::baselines::{nearest_neighbour, optimal_assignment};
use super::decision::DecisionRule;
use super::{RelaxationConfig, RelaxationProblem, RelaxationVariant};
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::io::detections::read_detections;
use crate::io::matches::read_matches;
use crate::io::natural::natural_cmp;
use rayon::prelude::*;
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// One two-frame problem with its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// The folder it came from.
    pub dir: PathBuf,
    /// Frame-1 detections.
    pub frame1: Vec<Detection>,
    /// Frame-2 detections.
    pub frame2: Vec<Detection>,
    /// For each frame-1 detection (same order), its true frame-2 id or `None`.
    pub truth: Vec<Option<u64>>,
}

impl Problem {
    /// Reads `dir/frame1.csv`, `dir/frame2.csv` and `dir/truth.csv`.
    ///
    /// # Errors
    /// A file that cannot be read; a frame-1 id missing from the truth; a truth row whose
    /// `id1` is not in frame 1 or whose `id2` is not in frame 2.
    pub fn load(dir: &Path) -> Result<Self> {
        let frame1 = read_detections(&dir.join("frame1.csv"))?;
        let frame2 = read_detections(&dir.join("frame2.csv"))?;
        let truth_path = dir.join("truth.csv");
        let rows = read_matches(&truth_path)?;
        let ids2: std::collections::HashSet<u64> = frame2.iter().map(|d| d.id).collect();
        let ids1: std::collections::HashSet<u64> = frame1.iter().map(|d| d.id).collect();
        let mut map = HashMap::new();
        for r in rows {
            let Some(id1) = r.id1 else { continue };
            if !ids1.contains(&id1) {
                return Err(Error::format(
                    &truth_path,
                    format!("id1 {id1} is not in frame1.csv"),
                ));
            }
            if let Some(id2) = r.id2
                && !ids2.contains(&id2)
            {
                return Err(Error::format(
                    &truth_path,
                    format!("id2 {id2} (partner of {id1}) is not in frame2.csv"),
                ));
            }
            map.insert(id1, r.id2);
        }
        let truth = frame1
            .iter()
            .map(|d| {
                map.get(&d.id).copied().ok_or_else(|| {
                    Error::format(
                        &truth_path,
                        format!(
                            "frame-1 id {} has no row (write `{},` for no partner)",
                            d.id, d.id
                        ),
                    )
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            dir: dir.to_owned(),
            frame1,
            frame2,
            truth,
        })
    }

    /// Number of frame-1 decisions that equal the truth, given frame-2 partner indices.
    pub fn correct(&self, partner: &[Option<usize>]) -> usize {
        self.truth
            .iter()
            .zip(partner)
            .filter(|(t, p)| **t == p.map(|k| self.frame2[k].id))
            .count()
    }
}

/// The problem folders under `dir`: `dir` itself when it holds `frame1.csv`, otherwise
/// its sub-folders that do, in natural order of their names.
///
/// # Errors
/// `dir` unreadable, or no problem found.
pub fn problem_dirs(dir: &Path) -> Result<Vec<PathBuf>> {
    if dir.join("frame1.csv").is_file() {
        return Ok(vec![dir.to_owned()]);
    }
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("frame1.csv").is_file())
        .collect();
    out.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
    if out.is_empty() {
        return Err(Error::format(
            dir,
            "no problem found: expected sub-folders with frame1.csv, frame2.csv, truth.csv",
        ));
    }
    Ok(out)
}

/// A matching method of the experiment tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ExperimentMethod {
    /// Relaxation with a variant and a decision rule (other parameters from the config).
    Relaxation(RelaxationVariant, DecisionRule),
    /// [`nearest_neighbour`] with the same gate.
    NearestNeighbour,
    /// [`optimal_assignment`] with the same gate.
    OptimalAssignment,
}

impl ExperimentMethod {
    /// The paper's four variants with argmax, then the two baselines.
    pub fn table1() -> Vec<ExperimentMethod> {
        let mut v: Vec<ExperimentMethod> = RelaxationVariant::ALL
            .iter()
            .map(|&v| ExperimentMethod::Relaxation(v, DecisionRule::Argmax))
            .collect();
        v.push(ExperimentMethod::NearestNeighbour);
        v.push(ExperimentMethod::OptimalAssignment);
        v
    }

    /// Partner indices on `p`.
    fn partners(self, p: &Problem, cfg: &RelaxationConfig) -> Result<Vec<Option<usize>>> {
        match self {
            ExperimentMethod::Relaxation(variant, decision) => {
                let cfg = RelaxationConfig {
                    variant,
                    decision,
                    ..cfg.clone()
                };
                let prob = RelaxationProblem::new(&p.frame1, &p.frame2, &cfg)?;
                let sol = prob.solve(&cfg.weights(), cfg.epsilon, cfg.max_iterations);
                Ok(prob.decide(&sol, decision).partner)
            }
            ExperimentMethod::NearestNeighbour => {
                nearest_neighbour(&p.frame1, &p.frame2, cfg.gate_half_width_px)
            }
            ExperimentMethod::OptimalAssignment => {
                optimal_assignment(&p.frame1, &p.frame2, cfg.gate_half_width_px)
            }
        }
    }
}

impl fmt::Display for ExperimentMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExperimentMethod::Relaxation(v, DecisionRule::Argmax) => write!(f, "{v}"),
            ExperimentMethod::Relaxation(v, DecisionRule::OneToOne) => write!(f, "{v}+one-to-one"),
            ExperimentMethod::Relaxation(v, DecisionRule::Assignment) => {
                write!(f, "{v}+assignment")
            }
            ExperimentMethod::NearestNeighbour => f.write_str("nearest-neighbour"),
            ExperimentMethod::OptimalAssignment => f.write_str("optimal-assignment"),
        }
    }
}

/// One row of an experiment table.
#[derive(Debug, Clone, PartialEq)]
pub struct ExperimentRow {
    /// The method.
    pub method: ExperimentMethod,
    /// Problems scored.
    pub problems: usize,
    /// Frame-1 vehicles over all problems.
    pub vehicles: usize,
    /// Of those, decided as in the truth.
    pub correct: usize,
    /// `correct / vehicles` (pooled over problems).
    pub rate: f64,
    /// Mean of the per-problem rates.
    pub mean_problem_rate: f64,
}

/// Correct-match rates of several methods on the same problems.
#[derive(Debug, Clone, PartialEq)]
pub struct ExperimentTable {
    /// One row per method, in the order asked.
    pub rows: Vec<ExperimentRow>,
}

impl ExperimentTable {
    /// Writes the table as CSV (header
    /// `method,problems,vehicles,correct,rate,mean_problem_rate`), atomically.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        crate::io::write_atomic(path, |w| {
            writeln!(w, "method,problems,vehicles,correct,rate,mean_problem_rate")?;
            for r in &self.rows {
                writeln!(
                    w,
                    "{},{},{},{},{:.6},{:.6}",
                    r.method, r.problems, r.vehicles, r.correct, r.rate, r.mean_problem_rate
                )?;
            }
            Ok(())
        })
    }
}

/// Correct-match rate of every method in `methods` over the problems in `dirs` (each a
/// folder as [`Problem::load`] reads), with the parameters of `cfg` (its variant and
/// decision are replaced by each method's). Problems run in parallel; `progress` is called
/// with (problems done, total) after each batch.
///
/// # Errors
/// A problem that cannot be loaded, or that a method rejects (e.g. a colour variant on
/// detections without colour).
pub fn run_experiment(
    dirs: &[PathBuf],
    methods: &[ExperimentMethod],
    cfg: &RelaxationConfig,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ExperimentTable> {
    cfg.validate()?;
    let total = dirs.len() as u64;
    // Per problem, per method: (correct, vehicles).
    let mut scores: Vec<Vec<(usize, usize)>> = Vec::with_capacity(dirs.len());
    let batch = rayon::current_num_threads().max(1) * 4;
    for chunk in dirs.chunks(batch) {
        let part = chunk
            .par_iter()
            .map(|d| -> Result<Vec<(usize, usize)>> {
                let p = Problem::load(d)?;
                methods
                    .iter()
                    .map(|m| {
                        let partner = m
                            .partners(&p, cfg)
                            .map_err(|e| Error::Invalid(format!("{}: {m}: {e}", d.display())))?;
                        Ok((p.correct(&partner), p.frame1.len()))
                    })
                    .collect()
            })
            .collect::<Result<Vec<_>>>()?;
        scores.extend(part);
        progress(scores.len() as u64, total);
    }
    let rows = methods
        .iter()
        .enumerate()
        .map(|(j, &method)| {
            let correct: usize = scores.iter().map(|s| s[j].0).sum();
            let vehicles: usize = scores.iter().map(|s| s[j].1).sum();
            let per: Vec<f64> = scores
                .iter()
                .map(|s| {
                    if s[j].1 == 0 {
                        1.0
                    } else {
                        s[j].0 as f64 / s[j].1 as f64
                    }
                })
                .collect();
            ExperimentRow {
                method,
                problems: scores.len(),
                vehicles,
                correct,
                rate: if vehicles == 0 {
                    1.0
                } else {
                    correct as f64 / vehicles as f64
                },
                mean_problem_rate: if per.is_empty() {
                    1.0
                } else {
                    per.iter().sum::<f64>() / per.len() as f64
                },
            }
        })
        .collect();
    Ok(ExperimentTable { rows })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixtures() -> PathBuf {
        PathBuf::from(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/fixtures/relaxation"
        ))
    }

    #[test]
    fn experiment_scores_the_committed_problems() -> Result<()> {
        let dirs = problem_dirs(&fixtures())?;
        assert_eq!(dirs.len(), 3, "{dirs:?}");
        let mut calls = Vec::new();
        let table = run_experiment(
            &dirs,
            &ExperimentMethod::table1(),
            &RelaxationConfig::default(),
            &mut |d, t| calls.push((d, t)),
        )?;
        assert_eq!(calls.last(), Some(&(3, 3)));
        let rate = |name: &str| {
            table
                .rows
                .iter()
                .find(|r| r.method.to_string() == name)
                .map(|r| (r.correct, r.vehicles))
        };
        // See tests/fixtures/relaxation/README.md for each problem's expected outcome.
        // 6 + 5 + 6 = 17 frame-1 vehicles.
        assert_eq!(rate("colour-bidirectional"), Some((17, 17)), "{table:#?}");
        assert_eq!(rate("nearest-neighbour").map(|r| r.1), Some(17));
        let nn = rate("nearest-neighbour").map_or(0, |r| r.0);
        assert!(
            nn < 17,
            "nearest neighbour should fail the platoon problem: {table:#?}"
        );
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let out = dir.path().join("t.csv");
        table.write_csv(&out)?;
        let text = std::fs::read_to_string(&out).map_err(|e| Error::io(&out, e))?;
        assert!(text.starts_with("method,problems,vehicles,correct,rate,mean_problem_rate\n"));
        assert!(
            text.contains("\ncolour-bidirectional,3,17,17,1.000000,1.000000\n"),
            "{text}"
        );
        Ok(())
    }

    #[test]
    fn truth_must_cover_frame_one() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let d = dir.path();
        let w = |n: &str, t: &str| std::fs::write(d.join(n), t).map_err(|e| Error::io(n, e));
        w("frame1.csv", "id,x,y\n1,0,0\n2,10,0\n")?;
        w("frame2.csv", "id,x,y\n5,3,0\n")?;
        w("truth.csv", "id1,id2\n1,5\n")?;
        let m = Problem::load(d).expect_err("id 2 missing").to_string();
        assert!(m.contains("truth.csv") && m.contains("frame-1 id 2"), "{m}");
        w("truth.csv", "id1,id2\n1,5\n2,6\n")?;
        let m = Problem::load(d).expect_err("id2 6").to_string();
        assert!(m.contains("id2 6"), "{m}");
        w("truth.csv", "id1,id2\n1,5\n2,\n")?;
        let p = Problem::load(d)?;
        assert_eq!(p.truth, vec![Some(5), None]);
        assert_eq!(p.correct(&[Some(0), None]), 2);
        assert_eq!(p.correct(&[None, Some(0)]), 0);
        Ok(())
    }
}
