//! `roadtrack check`: validate a data file against its format and summarise it.

use crate::common::Ui;
use anyhow::{Result, bail};
use roadtrack::io;
use std::path::{Path, PathBuf};

/// File formats `check` knows (docs/FORMATS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Detections CSV (`x,y` required).
    Detections,
    /// Matches CSV (`id1,id2,probability`).
    Matches,
    /// MOTChallenge tracks (no header).
    MotTracks,
    /// MOTChallenge ground truth (no header).
    MotGt,
    /// Trajectories CSV.
    Trajectories,
    /// Point measurements (`step,x,y`).
    Measurements,
    /// Filter estimates (`step,label,x,y,vx,vy,weight`).
    Estimates,
}

/// Check that a file is valid in its format; print a one-line summary or the first error
/// (file, line, column) and exit 1.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack check detections.csv\n  roadtrack check --format mot-gt MOT17-02/gt/gt.txt"
)]
pub struct Args {
    /// The file.
    pub file: PathBuf,
    /// Its format (default: guessed from the name and, for CSV, the header).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
}

pub fn run(args: Args, _ui: &Ui) -> Result<()> {
    let format = match args.format {
        Some(f) => f,
        None => guess(&args.file)?,
    };
    let summary = match format {
        Format::Detections => {
            let d = io::detections::read_detections(&args.file)?;
            format!(
                "{} detections in {} frames",
                d.len(),
                distinct(d.iter().map(|x| x.frame))
            )
        }
        Format::Matches => format!(
            "{} match rows",
            io::matches::read_matches(&args.file)?.len()
        ),
        Format::MotTracks => {
            let r = io::mot::read_tracks(&args.file)?;
            format!(
                "{} boxes, {} ids, {} frames",
                r.len(),
                distinct(r.iter().map(|x| x.id)),
                distinct(r.iter().map(|x| x.frame))
            )
        }
        Format::MotGt => {
            let r = io::mot::read_gt(&args.file)?;
            format!(
                "{} boxes, {} ids, {} frames",
                r.len(),
                distinct(r.iter().map(|x| x.id)),
                distinct(r.iter().map(|x| x.frame))
            )
        }
        Format::Trajectories => {
            let r = io::trajectories::read_trajectories(&args.file)?;
            format!(
                "{} points, {} ids",
                r.len(),
                distinct(r.iter().map(|x| x.id))
            )
        }
        Format::Measurements => format!(
            "{} measurements",
            io::points::read_measurements(&args.file)?.len()
        ),
        Format::Estimates => format!(
            "{} estimates",
            io::points::read_estimates(&args.file)?.len()
        ),
    };
    crate::common::print_out(&format!(
        "{}: ok ({format:?}): {summary}\n",
        args.file.display()
    ))?;
    Ok(())
}

fn distinct<T: Ord>(it: impl Iterator<Item = T>) -> usize {
    it.collect::<std::collections::BTreeSet<_>>().len()
}

/// Guesses the format from the file name, then from the CSV header.
fn guess(path: &Path) -> Result<Format> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if name.ends_with(".txt") {
        return Ok(if name == "gt.txt" {
            Format::MotGt
        } else {
            Format::MotTracks
        });
    }
    let text = std::fs::read_to_string(path).map_err(|e| roadtrack::Error::io(path, e))?;
    let header: Vec<String> = text
        .lines()
        .next()
        .unwrap_or("")
        .split(',')
        .map(|h| h.trim().to_ascii_lowercase())
        .collect();
    let has = |c: &str| header.iter().any(|h| h == c);
    Ok(if has("id1") {
        Format::Matches
    } else if has("x_px") {
        Format::Trajectories
    } else if has("step") && has("label") {
        Format::Estimates
    } else if has("step") {
        Format::Measurements
    } else if has("x") {
        Format::Detections
    } else {
        bail!(
            "{}: cannot tell the format from its name or header; give --format",
            path.display()
        )
    })
}
