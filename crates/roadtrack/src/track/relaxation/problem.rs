//! The two-frame problem (METHODS.md §1): labels in the gate, neighbour-support lists and
//! the start, built once and then solved ([`super::update`]) and decided
//! ([`super::decision`]) for any weights `A, B, C`.

use super::grid::PointGrid;
use super::initial::{displacement_prior, initial_probabilities};
use super::labels::LabelGraph;
use super::probabilities::{Probabilities, Solution};
use super::support::SupportLists;
use super::{RelaxationConfig, validate_detections};
use crate::detection::Detection;
use crate::error::Result;
use crate::geometry::Point;

/// Everything about a two-frame problem that does not depend on `A, B, C`: labels,
/// support lists and initial probabilities. Built once, solved for any weights.
///
/// Layout: the vehicles of each frame are renumbered in grid order (cells of side `R`,
/// row by row, then input order), so that a vehicle's neighbours, their labels and the
/// twins of its labels sit close together in memory: the support sums and the update
/// then read mostly from cache. [`Self::graph`] and every [`Solution`] use this internal
/// numbering; internal vehicle `i` of frame 1 is input detection `order1[i]`, and
/// [`Self::decide`] maps the decision back to input order. The method itself does not
/// depend on the numbering; only the order of floating-point additions does.
#[derive(Debug, Clone)]
pub struct RelaxationProblem {
    /// The labels, between vehicles in internal order.
    pub graph: LabelGraph,
    /// Ids of the frame-1 detections, in input order.
    pub ids1: Vec<u64>,
    /// Ids of the frame-2 detections, in input order.
    pub ids2: Vec<u64>,
    /// Input index of each internal frame-1 vehicle.
    pub order1: Vec<u32>,
    /// Input index of each internal frame-2 vehicle.
    pub order2: Vec<u32>,
    pub(super) fwd_support: SupportLists,
    pub(super) bwd_support: Option<SupportLists>,
    pub(super) initial_p: Probabilities,
    pub(super) initial_q: Option<Probabilities>,
    /// `RelaxationConfig::neutral_without_neighbours`.
    pub(super) neutral_without_neighbours: bool,
}

impl RelaxationProblem {
    /// Labels (gate `D`), support lists (`R`, `T`) and the start (colour or uniform, per
    /// `cfg.variant`) for `frame1 → frame2`.
    ///
    /// # Errors
    /// See [`super::match_vehicles`].
    pub fn new(frame1: &[Detection], frame2: &[Detection], cfg: &RelaxationConfig) -> Result<Self> {
        cfg.validate()?;
        let colour = cfg.variant.colour_start();
        validate_detections(frame1, 1, colour, cfg.variant)?;
        validate_detections(frame2, 2, colour, cfg.variant)?;
        // Choice: the internal order (see the type's doc) uses grid cells of side R, the
        // neighbourhood of eq. 16.
        let cell = cfg.neighbour_radius_px.max(1.0);
        let order = |f: &[Detection]| PointGrid::new(f.iter().map(|d| d.pos_px), cell).order();
        let (order1, order2) = (order(frame1), order(frame2));
        let ids1: Vec<u64> = frame1.iter().map(|d| d.id).collect();
        let ids2: Vec<u64> = frame2.iter().map(|d| d.id).collect();
        let frame1: Vec<&Detection> = order1.iter().map(|&i| &frame1[i as usize]).collect();
        let frame2: Vec<&Detection> = order2.iter().map(|&i| &frame2[i as usize]).collect();
        let p: Vec<Point> = frame1.iter().map(|d| d.pos_px).collect();
        let q: Vec<Point> = frame2.iter().map(|d| d.pos_px).collect();
        let graph = LabelGraph::nearest(&p, &q, cfg.gate_half_width_px, cfg.max_labels)?;
        let (r, t) = (cfg.neighbour_radius_px, cfg.similar_displacement_px);
        let (nb, rho) = (cfg.max_neighbours, cfg.neighbour_lateral_px);
        let bidirectional = cfg.variant.bidirectional();
        // The two directions are independent: built side by side (each is also parallel
        // over vehicle blocks, but its final concatenation is serial).
        let (fwd_support, bwd_support) = rayon::join(
            || SupportLists::build_compatible(&p, &graph.fwd_start, &graph.fwd_disp, r, t, rho, nb),
            || {
                bidirectional
                    .then(|| {
                        SupportLists::build_compatible(
                            &q,
                            &graph.bwd_start,
                            &graph.bwd_disp,
                            r,
                            t,
                            rho,
                            nb,
                        )
                    })
                    .transpose()
            },
        );
        let (fwd_support, bwd_support) = (fwd_support?, bwd_support?);
        // Validated above: every detection has a colour when the variant needs one.
        let colours = |f: &[&Detection]| -> Vec<[f64; 3]> {
            f.iter().map(|d| d.colour_rgb.unwrap_or([0.0; 3])).collect()
        };
        let (c1, c2) = if colour {
            (colours(&frame1), colours(&frame2))
        } else {
            (Vec::new(), Vec::new())
        };
        let (initial_p, initial_q) = rayon::join(
            || {
                initial_probabilities(
                    &graph.fwd_start,
                    &graph.fwd_target,
                    colour.then_some((&c1[..], &c2[..])),
                    cfg.colour_sd,
                )
            },
            || {
                bidirectional.then(|| {
                    initial_probabilities(
                        &graph.bwd_start,
                        &graph.bwd_target,
                        colour.then_some((&c2[..], &c1[..])),
                        cfg.colour_sd,
                    )
                })
            },
        );
        let (mut initial_p, mut initial_q) = (initial_p, initial_q);
        if cfg.displacement_sd_px > 0.0 {
            let s = cfg.displacement_sd_px;
            displacement_prior(&graph.fwd_start, &graph.fwd_disp, s, &mut initial_p);
            if let Some(q) = &mut initial_q {
                displacement_prior(&graph.bwd_start, &graph.bwd_disp, s, q);
            }
        }
        Ok(Self {
            graph,
            ids1,
            ids2,
            order1,
            order2,
            fwd_support,
            bwd_support,
            initial_p,
            initial_q,
            neutral_without_neighbours: cfg.neutral_without_neighbours,
        })
    }

    /// Whether the problem carries backward probabilities (variants c, d).
    pub fn bidirectional(&self) -> bool {
        self.initial_q.is_some()
    }

    /// The start (eqs. 7–11), before any iteration.
    pub fn initial(&self) -> Solution {
        Solution {
            p: self.initial_p.clone(),
            q: self.initial_q.clone(),
            iterations: 0,
            converged: false,
            last_change: 0.0,
        }
    }

    /// Number of (label, supporting label) pairs, forward plus backward.
    pub fn n_support_entries(&self) -> usize {
        self.fwd_support.n_entries() + self.bwd_support.as_ref().map_or(0, |s| s.n_entries())
    }

    /// Heap bytes held by the problem (labels, support lists, start), plus what one solve
    /// allocates (two probability sets and two support buffers per direction).
    pub fn heap_bytes(&self) -> usize {
        let probs = |p: &Probabilities| 8 * (p.real.capacity() + p.none.capacity());
        let orders = 4 * (self.order1.capacity() + self.order2.capacity());
        let dirs = if self.bidirectional() { 2 } else { 1 };
        self.graph.heap_bytes()
            + orders
            + self.fwd_support.heap_bytes()
            + self.bwd_support.as_ref().map_or(0, |s| s.heap_bytes())
            + probs(&self.initial_p)
            + self.initial_q.as_ref().map_or(0, probs)
            + dirs * (2 * probs(&self.initial_p) + 8 * self.graph.n_labels())
    }
}
