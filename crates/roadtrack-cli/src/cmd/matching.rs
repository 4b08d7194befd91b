//! `roadtrack match`: two-frame vehicle matching by bidirectional probabilistic relaxation
//! (METHODS.md §1). Also the parameter flags `sweep` and `experiment` share.

use crate::common::{Ui, load_config};
use anyhow::{Context, Result};
use roadtrack::io::{detections::read_detections, matches::write_matches};
use roadtrack::track::relaxation::{
    DecisionRule, RelaxationConfig, RelaxationVariant, match_vehicles,
};
use std::path::{Path, PathBuf};

/// Every parameter of `RelaxationConfig` as a flag; each overrides `--config`.
#[derive(Debug, Clone, clap::Args)]
pub struct RelaxArgs {
    /// TOML file with a `RelaxationConfig` (see configs/relaxation.toml).
    #[arg(long, value_name = "F.toml")]
    pub config: Option<PathBuf>,
    /// Method of Table 1 [default: colour-bidirectional (d)].
    #[arg(long, value_enum, value_name = "V")]
    pub variant: Option<RelaxationVariant>,
    /// A, eqs. 19–20: weight of a label's own evidence [default: 0.5].
    #[arg(long, value_name = "A", value_parser = crate::flags::non_negative)]
    pub own_weight: Option<f64>,
    /// B, eqs. 19–20: weight of the same-direction neighbour support [default: 1].
    #[arg(long, value_name = "B", value_parser = crate::flags::non_negative)]
    pub forward_support_weight: Option<f64>,
    /// C, eqs. 19–20: weight of the opposite-direction support (bidirectional variants)
    /// [default: 1].
    #[arg(long, value_name = "C", value_parser = crate::flags::non_negative)]
    pub backward_support_weight: Option<f64>,
    /// T, eq. 15: displacements within this distance are similar, px [default: 20].
    #[arg(long, value_name = "T", value_parser = crate::flags::non_negative)]
    pub similar_displacement_px: Option<f64>,
    /// R, eq. 16: vehicles within this distance are neighbours, px [default: 200].
    #[arg(long, value_name = "R", value_parser = crate::flags::non_negative)]
    pub neighbour_radius_px: Option<f64>,
    /// D, eq. 3: half-width of the square search gate, px [default: 150].
    #[arg(long, value_name = "D", value_parser = crate::flags::non_negative)]
    pub gate_half_width_px: Option<f64>,
    /// Stop when no probability changes by more than this [default: 1e-6].
    #[arg(long, value_name = "E", value_parser = crate::flags::non_negative)]
    pub epsilon: Option<f64>,
    /// Iteration cap [default: 50].
    #[arg(long, value_name = "N")]
    pub max_iterations: Option<u32>,
    /// How probabilities become pairs [default: argmax, the paper's].
    #[arg(long, value_enum)]
    pub decision: Option<DecisionRule>,
    /// At most N labels per vehicle, the nearest in the gate (bounds time and memory in
    /// dense scenes), 1–4096 [default: 32].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=MAX_LABELS))]
    pub max_labels: Option<u32>,
    /// At most N neighbours per vehicle, the nearest within R, 1–4096 [default: 32].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=MAX_LABELS))]
    pub max_neighbours: Option<u32>,
    /// Motion-compatible support (ours): a moving label takes support only from
    /// neighbours within this many px of its line (its lane) [default: 0, off].
    #[arg(long, value_name = "PX", value_parser = crate::flags::non_negative)]
    pub neighbour_lateral_px: Option<f64>,
    /// Colour likelihood start (ours): exp(−C/2σ²), σ in 8-bit levels [default: 0, the
    /// paper's eqs. 9–11].
    #[arg(long, value_name = "SIGMA", value_parser = crate::flags::non_negative)]
    pub colour_sd: Option<f64>,
    /// No-match handling (ours): labels no neighbour could support keep their start
    /// instead of shrinking by A [default: false].
    #[arg(long, value_name = "BOOL")]
    pub neutral_without_neighbours: Option<bool>,
    /// Displacement prior (ours): start × exp(−|λ|²/2σ²), no-match × exp(−2), σ px
    /// [default: 0, off].
    #[arg(long, value_name = "SIGMA", value_parser = crate::flags::non_negative)]
    pub displacement_sd_px: Option<f64>,
}

/// [`roadtrack::limits::MAX_LABELS`] as a clap range bound.
const MAX_LABELS: i64 = roadtrack::limits::MAX_LABELS as i64;

impl RelaxArgs {
    /// The configuration: `--config` (or the default) with every given flag applied,
    /// validated.
    pub fn config(&self) -> Result<RelaxationConfig> {
        let mut c: RelaxationConfig = load_config(self.config.as_deref())?;
        if let Some(v) = self.variant {
            c.variant = v;
        }
        let set = |field: &mut f64, v: Option<f64>| {
            if let Some(v) = v {
                *field = v;
            }
        };
        set(&mut c.own_weight, self.own_weight);
        set(&mut c.forward_support_weight, self.forward_support_weight);
        set(&mut c.backward_support_weight, self.backward_support_weight);
        set(&mut c.similar_displacement_px, self.similar_displacement_px);
        set(&mut c.neighbour_radius_px, self.neighbour_radius_px);
        set(&mut c.gate_half_width_px, self.gate_half_width_px);
        set(&mut c.epsilon, self.epsilon);
        set(&mut c.neighbour_lateral_px, self.neighbour_lateral_px);
        set(&mut c.colour_sd, self.colour_sd);
        if let Some(b) = self.neutral_without_neighbours {
            c.neutral_without_neighbours = b;
        }
        set(&mut c.displacement_sd_px, self.displacement_sd_px);
        if let Some(n) = self.max_iterations {
            c.max_iterations = n;
        }
        if let Some(d) = self.decision {
            c.decision = d;
        }
        if let Some(n) = self.max_labels {
            c.max_labels = n as usize;
        }
        if let Some(n) = self.max_neighbours {
            c.max_neighbours = n as usize;
        }
        // A bound a flag broke is a usage error naming the flag.
        crate::flags::check_overrides(
            c.validate(),
            &[
                (
                    "max_iterations",
                    "--max-iterations",
                    self.max_iterations.is_some(),
                ),
                ("epsilon", "--epsilon", self.epsilon.is_some()),
                ("max_labels", "--max-labels", self.max_labels.is_some()),
                (
                    "max_neighbours",
                    "--max-neighbours",
                    self.max_neighbours.is_some(),
                ),
            ],
            self.config.as_deref(),
        )?;
        Ok(c)
    }

    /// The weight flags given (A, B, C), for commands that set them otherwise.
    pub fn weight_flags(&self) -> [(&'static str, bool); 3] {
        [
            ("--own-weight", self.own_weight.is_some()),
            (
                "--forward-support-weight",
                self.forward_support_weight.is_some(),
            ),
            (
                "--backward-support-weight",
                self.backward_support_weight.is_some(),
            ),
        ]
    }
}

/// Match the vehicles of two frames (METHODS.md §1, seed 000).
///
/// Each frame is a detections CSV (`x,y` required; `id`; `r,g,b` for the colour
/// variants). Writes the matches CSV `id1,id2,probability`: one row per frame-1 vehicle in
/// input order (`id2` empty = no partner), then one row per frame-2 vehicle nobody chose
/// (`id1` empty = appeared). Default parameters are the paper's (A 0.5, B 1, C 1, T 20 px,
/// R 200 px, D 150 px, 50 iterations).
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  \
    roadtrack match frame1.csv frame2.csv -o matches.csv\n  \
    roadtrack match frame1.csv frame2.csv --variant bidirectional --gate-half-width-px 100 -o -")]
pub struct Args {
    /// Detections of frame 1.
    pub frame1: PathBuf,
    /// Detections of frame 2.
    pub frame2: PathBuf,
    /// Output matches CSV (`-` for standard output).
    #[arg(short, long, default_value = "matches.csv")]
    pub output: PathBuf,
    #[command(flatten)]
    pub relax: RelaxArgs,
}

/// Reads a detections file for matching; every detection must be in one frame.
fn read_frame(path: &Path) -> Result<Vec<roadtrack::Detection>> {
    let d = read_detections(path)?;
    if let (Some(first), Some(other)) = (d.first(), d.iter().find(|x| x.frame != d[0].frame)) {
        anyhow::bail!(
            "{}: holds frames {} and {}; give one frame per file",
            path.display(),
            first.frame,
            other.frame
        );
    }
    Ok(d)
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let cfg = args.relax.config()?;
    if args.relax.backward_support_weight.is_some() && !cfg.variant.bidirectional() {
        return Err(crate::flags::conflict(format!(
            "--backward-support-weight (C) is used by the bidirectional variants only, \
             not by --variant {}",
            cfg.variant
        )));
    }
    let f1 = read_frame(&args.frame1)?;
    let f2 = read_frame(&args.frame2)?;
    let m = match_vehicles(&f1, &f2, &cfg).with_context(|| {
        format!(
            "matching {} with {}",
            args.frame1.display(),
            args.frame2.display()
        )
    })?;
    let rows = m.rows();
    write_matches(&args.output, &rows)?;
    let paired = m.partner.iter().filter(|p| p.is_some()).count();
    ui.info(format!(
        "{} → {} vehicles: {paired} paired, {} without partner, {} appeared; {} iterations{} → {}",
        f1.len(),
        f2.len(),
        f1.len() - paired,
        rows.len() - f1.len(),
        m.iterations,
        if m.converged { "" } else { " (not converged)" },
        args.output.display()
    ));
    Ok(())
}
