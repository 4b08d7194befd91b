//! Bidirectional probabilistic relaxation with colour (Fuse & Shimizu, seed 000;
//! METHODS.md §1).
//!
//! Matches vehicles between two frames. Every frame-1 vehicle `a_i` gets the labels
//! `L_i`: one displacement to each frame-2 vehicle inside the square gate `D` (eq. 3) and
//! the no-match label `λ_p`. Its label probabilities `P_i` start from colour similarity
//! (eqs. 7–11) or uniform, and are reinforced by neighbour support `P̂` (eqs. 13, 15, 16)
//! and, in the bidirectional variants, by the backward support `Q̂` of the same pair
//! (eqs. 14, 19, 20) until they stop changing. The decision is the per-vehicle argmax.
//!
//! Layout of the module, one file per step of the method:
//!
//! | file | what | equations |
//! | --- | --- | --- |
//! | [`labels`] | candidate labels in the gate, forward and backward, as CSR arrays | 2–6, 12 |
//! | [`probabilities`] | [`Probabilities`] of one direction, a solve's [`Solution`] | — |
//! | [`initial`] | colour or uniform start | 7–11 |
//! | [`support`] | neighbour-support lists (spatial grid + direct label comparison) and sums | 13–16 |
//! | [`problem`] | [`RelaxationProblem`]: labels, support lists and start, built once | — |
//! | [`update`] | one double-buffered iteration and the stop rule | 17–20 |
//! | [`decision`] | argmax and the optional one-to-one decision → [`Matching`] | — |
//! | [`tracker`] | [`RelaxationTracker`]: frames chained into tracks | — |
//! | [`baselines`] | nearest neighbour and optimal assignment with the same gate | — |
//! | [`experiment`] | correct-match rates over problem folders (Tables 1–2) | — |
//! | [`sweep`] | the paper's parameter sweep over `A, B, C` | — |
//! | [`scale`] | a generated wide-area road network and the scale benchmark | — |
//!
//! ```
//! use roadtrack::track::relaxation::{match_vehicles, RelaxationConfig};
//! use roadtrack::{Detection, Point};
//! let mk = |id, x, rgb| Detection { colour_rgb: Some(rgb), ..Detection::at(1, id, Point::new(x, 10.0)) };
//! let frame1 = [mk(1, 0.0, [200.0, 0.0, 0.0]), mk(2, 50.0, [0.0, 0.0, 200.0])];
//! let frame2 = [mk(7, 20.0, [200.0, 0.0, 0.0]), mk(8, 70.0, [0.0, 0.0, 200.0])];
//! let m = match_vehicles(&frame1, &frame2, &RelaxationConfig::default())?;
//! let rows = m.rows();
//! assert_eq!((rows[0].id1, rows[0].id2), (Some(1), Some(7)));
//! assert_eq!((rows[1].id1, rows[1].id2), (Some(2), Some(8)));
//! # Ok::<(), roadtrack::Error>(())
//! ```

pub mod baselines;
pub mod decision;
pub mod experiment;
mod grid;
pub mod initial;
pub mod labels;
pub mod probabilities;
pub mod problem;
pub mod scale;
pub mod support;
pub mod sweep;
pub mod tracker;
pub mod update;

pub use decision::{DecisionRule, Matching};
pub use experiment::{ExperimentMethod, ExperimentTable, run_experiment};
pub use labels::LabelGraph;
pub use probabilities::{Probabilities, Solution};
pub use problem::RelaxationProblem;
pub use scale::{ScaleReport, generate_road_network_pair, scale_experiment};
pub use sweep::{SweepGrid, SweepResult, sweep};
pub use tracker::{RelaxationTracker, RelaxationTrackerConfig};
pub use update::UpdateWeights;

use crate::detection::Detection;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::fmt;
use std::str::FromStr;

/// Largest 8-bit colour value, `C_max` of eq. 8.
pub const COLOUR_MAX: f64 = 255.0;

/// The four methods of Table 1 (METHODS.md §1 "Variants").
///
/// Declared from (d) to (a), the order in which `--variant` lists them; [`RelaxationVariant::ALL`]
/// gives Table 1's order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum RelaxationVariant {
    /// (d) bidirectional, colour start: the proposed method and the default.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(
            alias = "color-bidirectional",
            alias = "d",
            help = "(d) bidirectional, colour start: the paper's method"
        )
    )]
    ColourBidirectional,
    /// (c) bidirectional, uniform start.
    #[cfg_attr(feature = "clap", value(alias = "c"))]
    Bidirectional,
    /// (b) unidirectional, colour start.
    #[cfg_attr(feature = "clap", value(alias = "color-unidirectional", alias = "b"))]
    ColourUnidirectional,
    /// (a) unidirectional, uniform start.
    #[cfg_attr(feature = "clap", value(alias = "a"))]
    Unidirectional,
}

impl RelaxationVariant {
    /// All four, in the order of Table 1: (a), (b), (c), (d).
    pub const ALL: [RelaxationVariant; 4] = [
        RelaxationVariant::Unidirectional,
        RelaxationVariant::ColourUnidirectional,
        RelaxationVariant::Bidirectional,
        RelaxationVariant::ColourBidirectional,
    ];

    /// Whether the start uses colour (eqs. 7–11) rather than uniform probabilities.
    pub fn colour_start(self) -> bool {
        matches!(
            self,
            RelaxationVariant::ColourUnidirectional | RelaxationVariant::ColourBidirectional
        )
    }

    /// Whether the update uses the backward probabilities `Q` (eqs. 19–20 with `C`).
    pub fn bidirectional(self) -> bool {
        matches!(
            self,
            RelaxationVariant::Bidirectional | RelaxationVariant::ColourBidirectional
        )
    }

    /// The name used on the command line and in TOML (`colour-bidirectional`, …).
    pub fn name(self) -> &'static str {
        match self {
            RelaxationVariant::Unidirectional => "unidirectional",
            RelaxationVariant::ColourUnidirectional => "colour-unidirectional",
            RelaxationVariant::Bidirectional => "bidirectional",
            RelaxationVariant::ColourBidirectional => "colour-bidirectional",
        }
    }

    /// The paper's letter in Table 1: `a`, `b`, `c` or `d`.
    pub fn letter(self) -> char {
        match self {
            RelaxationVariant::Unidirectional => 'a',
            RelaxationVariant::ColourUnidirectional => 'b',
            RelaxationVariant::Bidirectional => 'c',
            RelaxationVariant::ColourBidirectional => 'd',
        }
    }
}

impl fmt::Display for RelaxationVariant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for RelaxationVariant {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        RelaxationVariant::ALL
            .into_iter()
            .find(|v| v.name() == s || v.name().replace("colour", "color") == s)
            .ok_or_else(|| {
                Error::config(
                    "RelaxationConfig",
                    "variant",
                    format!(
                        "unknown variant `{s}`; expected one of colour-bidirectional, \
                         bidirectional, colour-unidirectional, unidirectional"
                    ),
                )
            })
    }
}

/// Parameters of bidirectional probabilistic relaxation (METHODS.md §1, seed 000).
///
/// `Default` is the authors' tuning on PARAMICS microsimulation, variant (d):
/// `A = 0.5, B = 1, C = 1, T = 20 px, R = 200 px, D = 150 px`, 50 iterations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RelaxationConfig {
    /// `A`, eqs. 19–20: constant term that keeps a label's own evidence. Default 0.5.
    pub own_weight: f64,
    /// `B`, eqs. 19–20: weight of the same-direction neighbour support (`P̂` for `P`,
    /// `Q̂` for `Q`). Default 1.
    pub forward_support_weight: f64,
    /// `C`, eqs. 19–20: weight of the opposite-direction support of the same pair.
    /// The unidirectional variants (a, b) use 0 whatever this says. Default 1.
    pub backward_support_weight: f64,
    /// `T`, eq. 15: two displacements are similar when they differ by at most this
    /// (Euclidean). Default 20 px.
    pub similar_displacement_px: f64,
    /// `R`, eq. 16: vehicles of the same frame within this distance are neighbours.
    /// Default 200 px.
    pub neighbour_radius_px: f64,
    /// `D`, eq. 3: half-width of the square search gate. Default 150 px.
    pub gate_half_width_px: f64,
    /// Stop when no probability changed by more than this in an iteration. Default 1e-6.
    pub epsilon: f64,
    /// Iteration cap (paper: 50). 0 decides on the initial probabilities.
    pub max_iterations: u32,
    /// Which of the four methods of Table 1. Default `colour-bidirectional` (d).
    pub variant: RelaxationVariant,
    /// How probabilities become pairs. Default `argmax` (the paper's).
    pub decision: DecisionRule,
    /// At most this many real labels per vehicle, in both directions: the nearest inside
    /// the gate ([`LabelGraph::nearest`]). Default
    /// [`DEFAULT_MAX_LABELS`](crate::limits::DEFAULT_MAX_LABELS); at most
    /// [`MAX_LABELS`](crate::limits::MAX_LABELS).
    pub max_labels: usize,
    /// At most this many neighbours (eq. 16) per vehicle: the nearest within `R`
    /// ([`SupportLists::build_nearest`](support::SupportLists::build_nearest)). Default
    /// [`DEFAULT_MAX_NEIGHBOURS`](crate::limits::DEFAULT_MAX_NEIGHBOURS); at most
    /// [`MAX_LABELS`](crate::limits::MAX_LABELS).
    pub max_neighbours: usize,
    /// Motion-compatible support (ours, not the paper's): when positive, a label longer
    /// than `T` (a moving vehicle) takes support (eq. 13) only from neighbours within this
    /// many px of the line along the label (its lane, ahead or behind), so an opposite lane
    /// or a crossing arm no longer supports it ([`support::lateral_compatible`]); labels
    /// within `T` of zero (queued vehicles) keep every neighbour. Default 0: off (eq. 16).
    pub neighbour_lateral_px: f64,
    /// Colour likelihood start (ours, not the paper's): when positive, the start is
    /// `exp(−C(λ) / 2σ²)` with the colour cost `C` of eq. 7 and this `σ` (sd of one
    /// channel's difference between two sightings of a vehicle, 8-bit levels), and the
    /// no-match label weighs as a candidate `2σ` off in every channel. Default 0: the
    /// paper's eqs. 9–11 (nearly flat with many candidates).
    pub colour_sd: f64,
    /// Displacement prior (ours, not the paper's): when positive, the start of every label
    /// is multiplied by `exp(−|λ|² / 2σ²)` with this `σ` px, and the no-match label by
    /// `exp(−2)` (as plausible as a label `2σ` long), then renormalised. Two frames: a
    /// prior for slow traffic; in the tracker with `predict = true` the displacement is the
    /// residual from each track's prediction. Default 0: off (the paper's start).
    pub displacement_sd_px: f64,
    /// No-match handling (ours, not the paper's): when true, a label whose pair no
    /// neighbour could support, in either frame (no neighbour within `R`, in its lane with
    /// `neighbour_lateral_px`, has a label similar to it, eq. 15), is multiplied by 1 like
    /// `λ_p` instead of `A`: a vehicle moving unlike all its neighbours keeps its start,
    /// while `A < 1` still weakens labels that neighbours could support and do not (a
    /// vehicle whose partner is missing). Default false (eqs. 19–20 for every label).
    pub neutral_without_neighbours: bool,
}

impl Default for RelaxationConfig {
    fn default() -> Self {
        Self {
            own_weight: 0.5,
            forward_support_weight: 1.0,
            backward_support_weight: 1.0,
            similar_displacement_px: 20.0,
            neighbour_radius_px: 200.0,
            gate_half_width_px: 150.0,
            epsilon: 1e-6,
            max_iterations: 50,
            variant: RelaxationVariant::ColourBidirectional,
            decision: DecisionRule::Argmax,
            max_labels: crate::limits::DEFAULT_MAX_LABELS,
            max_neighbours: crate::limits::DEFAULT_MAX_NEIGHBOURS,
            neighbour_lateral_px: 0.0,
            colour_sd: 0.0,
            neutral_without_neighbours: false,
            displacement_sd_px: 0.0,
        }
    }
}

impl crate::config::Validate for RelaxationConfig {
    fn validate(&self) -> crate::error::Result<()> {
        RelaxationConfig::validate(self)
    }
}

impl RelaxationConfig {
    /// Checks every field: weights finite and non-negative, lengths finite and
    /// non-negative, `epsilon` finite and non-negative.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        let fields = [
            ("own_weight", self.own_weight),
            ("forward_support_weight", self.forward_support_weight),
            ("backward_support_weight", self.backward_support_weight),
            ("similar_displacement_px", self.similar_displacement_px),
            ("neighbour_radius_px", self.neighbour_radius_px),
            ("gate_half_width_px", self.gate_half_width_px),
            ("epsilon", self.epsilon),
            ("neighbour_lateral_px", self.neighbour_lateral_px),
            ("colour_sd", self.colour_sd),
            ("displacement_sd_px", self.displacement_sd_px),
        ];
        for (name, v) in fields {
            if !v.is_finite() || v < 0.0 {
                return Err(Error::config(
                    "RelaxationConfig",
                    name,
                    format!("{v} must be finite and non-negative"),
                ));
            }
        }
        use crate::limits::{MAX_ITERATIONS, MAX_LABELS, at_most};
        at_most(self.max_iterations, MAX_ITERATIONS, "iterations")
            .map_err(|m| Error::config("RelaxationConfig", "max_iterations", m))?;
        for (name, v) in [
            ("max_labels", self.max_labels),
            ("max_neighbours", self.max_neighbours),
        ] {
            if v == 0 {
                return Err(Error::config(
                    "RelaxationConfig",
                    name,
                    "must be at least 1",
                ));
            }
            at_most(v, MAX_LABELS, name).map_err(|m| Error::config("RelaxationConfig", name, m))?;
        }
        Ok(())
    }

    /// The update weights `A, B, C` this configuration uses (`C = 0` for variants a, b).
    pub fn weights(&self) -> UpdateWeights {
        UpdateWeights {
            own_weight: self.own_weight,
            forward_support_weight: self.forward_support_weight,
            backward_support_weight: if self.variant.bidirectional() {
                self.backward_support_weight
            } else {
                0.0
            },
        }
    }
}

/// Matches the vehicles of `frame1` to those of `frame2` (METHODS.md §1): builds the labels,
/// starts, iterates eqs. 17–20 until `epsilon` or `max_iterations`, and decides.
///
/// Empty frames are allowed: with no frame-2 vehicle every frame-1 vehicle has no partner
/// (probability 1); with no frame-1 vehicle every frame-2 vehicle appeared.
///
/// # Errors
/// An invalid configuration; a non-finite position; a colour that is missing (colour
/// variants), non-finite or outside 0–255; an id repeated within a frame.
pub fn match_vehicles(
    frame1: &[Detection],
    frame2: &[Detection],
    cfg: &RelaxationConfig,
) -> Result<Matching> {
    let problem = RelaxationProblem::new(frame1, frame2, cfg)?;
    let solution = problem.solve(&cfg.weights(), cfg.epsilon, cfg.max_iterations);
    Ok(problem.decide(&solution, cfg.decision))
}

/// Checks the detections of one frame for the relaxation: finite positions, unique ids, and
/// (when `need_colour`) a finite colour in 0–255 on every detection.
///
/// `which` is 1 or 2 and appears in the message.
pub(crate) fn validate_detections(
    detections: &[Detection],
    which: u8,
    need_colour: bool,
    variant: RelaxationVariant,
) -> Result<()> {
    let mut seen = HashSet::with_capacity(detections.len());
    for d in detections {
        if !seen.insert(d.id) {
            return Err(Error::Invalid(format!(
                "frame {which}: id {} appears twice; ids must be unique within a frame",
                d.id
            )));
        }
        if !(d.pos_px.x.is_finite() && d.pos_px.y.is_finite()) {
            return Err(Error::Invalid(format!(
                "frame {which}: id {} has a non-finite position ({}, {})",
                d.id, d.pos_px.x, d.pos_px.y
            )));
        }
        match d.colour_rgb {
            Some(rgb)
                if rgb
                    .iter()
                    .any(|c| !c.is_finite() || !(0.0..=COLOUR_MAX).contains(c)) =>
            {
                return Err(Error::Invalid(format!(
                    "frame {which}: id {} has colour {rgb:?}; colours must be finite and \
                     within 0–255",
                    d.id
                )));
            }
            None if need_colour => {
                return Err(Error::Invalid(format!(
                    "frame {which}: id {} has no colour, but variant `{variant}` starts from \
                     colour (eqs. 7–11); give r,g,b or use variant `{}`",
                    d.id,
                    if variant.bidirectional() {
                        "bidirectional"
                    } else {
                        "unidirectional"
                    }
                )));
            }
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers() {
        // METHODS.md §1 "Defaults".
        let c = RelaxationConfig::default();
        assert_eq!(
            (
                c.own_weight,
                c.forward_support_weight,
                c.backward_support_weight
            ),
            (0.5, 1.0, 1.0)
        );
        assert_eq!(
            (
                c.similar_displacement_px,
                c.neighbour_radius_px,
                c.gate_half_width_px
            ),
            (20.0, 200.0, 150.0)
        );
        assert_eq!((c.epsilon, c.max_iterations), (1e-6, 50));
        assert_eq!(c.variant, RelaxationVariant::ColourBidirectional);
        assert_eq!(c.decision, DecisionRule::Argmax);
    }

    #[test]
    fn committed_config_file_equals_the_default() -> Result<()> {
        let path = std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../configs/relaxation.toml"
        ));
        let c: RelaxationConfig = crate::config::load_toml(path)?;
        assert_eq!(c, RelaxationConfig::default());
        Ok(())
    }

    #[test]
    fn variants_parse_by_name_and_round_trip_through_toml() -> Result<()> {
        for v in RelaxationVariant::ALL {
            assert_eq!(v.name().parse::<RelaxationVariant>()?, v);
            let c = RelaxationConfig {
                variant: v,
                ..Default::default()
            };
            let text = crate::config::to_toml(&c)?;
            assert!(
                text.contains(&format!("variant = \"{}\"", v.name())),
                "{text}"
            );
            let back: RelaxationConfig =
                toml::from_str(&text).map_err(|e| Error::Invalid(e.to_string()))?;
            assert_eq!(back, c);
        }
        assert_eq!(
            "color-bidirectional".parse::<RelaxationVariant>()?,
            RelaxationVariant::ColourBidirectional
        );
        let m = "sideways"
            .parse::<RelaxationVariant>()
            .expect_err("unknown")
            .to_string();
        assert!(
            m.contains("sideways") && m.contains("colour-bidirectional"),
            "{m}"
        );
        Ok(())
    }

    #[test]
    fn unidirectional_variants_use_no_backward_weight() {
        for (v, c) in [
            (RelaxationVariant::Unidirectional, 0.0),
            (RelaxationVariant::ColourUnidirectional, 0.0),
            (RelaxationVariant::Bidirectional, 1.0),
            (RelaxationVariant::ColourBidirectional, 1.0),
        ] {
            let cfg = RelaxationConfig {
                variant: v,
                ..Default::default()
            };
            assert_eq!(cfg.weights().backward_support_weight, c, "{v}");
        }
    }

    #[test]
    fn validate_rejects_negative_and_non_finite_values() {
        let bad = RelaxationConfig {
            neighbour_radius_px: -1.0,
            ..Default::default()
        };
        let m = bad.validate().expect_err("negative").to_string();
        assert!(m.contains("neighbour_radius_px"), "{m}");
        let bad = RelaxationConfig {
            own_weight: f64::NAN,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
        assert!(RelaxationConfig::default().validate().is_ok());
    }
}
