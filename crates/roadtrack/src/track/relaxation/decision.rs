//! The decision (METHODS.md §1 "Decision"): from label probabilities to pairs.
//!
//! The paper's rule is the per-vehicle argmax: `a_i` takes `argmax_λ P_i(λ)`, and `λ_p`
//! means no partner. Two frame-1 vehicles may then choose the same frame-2 vehicle. The
//! optional one-to-one rule forbids that.

use super::probabilities::{Probabilities, Solution};
use super::problem::RelaxationProblem;
use crate::io::matches::MatchRow;
use serde::{Deserialize, Serialize};

/// How probabilities become pairs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum DecisionRule {
    /// The paper's: each vehicle its most probable label, independently.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Each vehicle its most probable label (the paper's)")
    )]
    Argmax,
    /// Pairs one-to-one, greedily by probability: every real label at least as probable as
    /// its vehicle's no-match label is a candidate pair; candidates are taken in order of
    /// decreasing probability when neither vehicle is taken yet. Where the argmax already
    /// is one-to-one the two rules agree.
    #[cfg_attr(
        feature = "clap",
        value(help = "Pairs one-to-one, greedily by probability")
    )]
    OneToOne,
    /// Pairs one-to-one by the most probable joint decision (ours, option): the pairing
    /// that minimises `Σ −ln P_i(λ_ik) − ln Q_k(λ'_ki)` over pairs plus `−ln P_i(λ_p)` for
    /// each unpaired frame-1 vehicle and `−ln Q_k(λ'_p)` for each unpaired frame-2 vehicle
    /// (`Q` terms only in the bidirectional variants), solved exactly per connected
    /// component of the gate graph.
    #[cfg_attr(
        feature = "clap",
        value(help = "Pairs one-to-one by the most probable joint decision (P and Q)")
    )]
    Assignment,
}

impl std::str::FromStr for DecisionRule {
    type Err = crate::Error;

    fn from_str(s: &str) -> crate::Result<Self> {
        match s {
            "argmax" => Ok(Self::Argmax),
            "one-to-one" => Ok(Self::OneToOne),
            "assignment" => Ok(Self::Assignment),
            _ => Err(crate::Error::config(
                "RelaxationConfig",
                "decision",
                format!("unknown decision rule `{s}`; expected argmax, one-to-one or assignment"),
            )),
        }
    }
}

/// The result of matching two frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Matching {
    /// Ids of the frame-1 detections, in input order.
    pub ids1: Vec<u64>,
    /// Ids of the frame-2 detections, in input order.
    pub ids2: Vec<u64>,
    /// For each frame-1 detection, the index (into frame 2) of its partner, or `None`.
    pub partner: Vec<Option<usize>>,
    /// For each frame-1 detection, the final probability of the chosen label.
    pub probability: Vec<f64>,
    /// For each frame-2 detection, the argmax of its backward probabilities `Q` (index
    /// into frame 1, or `None`): bidirectional variants only.
    pub backward_partner: Option<Vec<Option<usize>>>,
    /// The probability of each backward choice.
    pub backward_probability: Option<Vec<f64>>,
    /// Iterations run.
    pub iterations: u32,
    /// Whether the iterations stopped on `epsilon` (rather than `max_iterations`).
    pub converged: bool,
}

impl Matching {
    /// The rows of a matches CSV (INTERFACES.md): one per frame-1 detection in input order,
    /// then one per frame-2 detection no frame-1 detection chose (appeared), in input order.
    pub fn rows(&self) -> Vec<MatchRow> {
        let mut rows: Vec<MatchRow> = self
            .partner
            .iter()
            .zip(&self.probability)
            .zip(&self.ids1)
            .map(|((k, &p), &id1)| MatchRow {
                id1: Some(id1),
                id2: k.map(|k| self.ids2[k]),
                probability: Some(p),
            })
            .collect();
        rows.extend(self.appeared().into_iter().map(|k| MatchRow {
            id1: None,
            id2: Some(self.ids2[k]),
            probability: None,
        }));
        rows
    }

    /// Frame-2 indices that no frame-1 detection chose, ascending.
    pub fn appeared(&self) -> Vec<usize> {
        let mut chosen = vec![false; self.ids2.len()];
        for k in self.partner.iter().flatten() {
            chosen[*k] = true;
        }
        (0..self.ids2.len()).filter(|&k| !chosen[k]).collect()
    }
}

/// The argmax of one vehicle's labels (real labels `targets` with probabilities `real`,
/// no-match `none`): the partner index and its probability.
///
/// Choice: exact ties go to a real label over the no-match label, and among real labels to
/// the lowest index in the other frame (paper silent). Ties are rare except in perfectly
/// symmetric scenes (identical vehicles at one place; an isolated pair under the uniform
/// start with `A = 1`, which stays at (½, ½) for ever and is matched).
pub fn argmax_row(targets: &[u32], real: &[f64], none: f64) -> (Option<usize>, f64) {
    argmax_of(
        targets
            .iter()
            .map(|&k| k as usize)
            .zip(real.iter().copied()),
        none,
    )
}

/// [`argmax_row`] over `(partner index, probability)` pairs in any order.
fn argmax_of(labels: impl Iterator<Item = (usize, f64)>, none: f64) -> (Option<usize>, f64) {
    let mut best: Option<(usize, f64)> = None;
    for (k, p) in labels {
        if best.is_none_or(|(bk, b)| p > b || (p == b && k < bk)) {
            best = Some((k, p));
        }
    }
    match best {
        Some((k, p)) if p >= none => (Some(k), p),
        _ => (None, none),
    }
}

/// The argmax of every row of `p` (rows `start`, partners `target`), in input order:
/// internal row `i` is input vehicle `own[i]`, internal partner `k` is input `other[k]`.
fn argmax_all(
    start: &[u32],
    target: &[u32],
    p: &Probabilities,
    own: &[u32],
    other: &[u32],
) -> (Vec<Option<usize>>, Vec<f64>) {
    let m = p.none.len();
    let mut partner = vec![None; m];
    let mut prob = vec![0.0; m];
    for i in 0..m {
        let r = start[i] as usize..start[i + 1] as usize;
        let labels = target[r.clone()]
            .iter()
            .map(|&k| other[k as usize] as usize)
            .zip(p.real[r].iter().copied());
        let (k, v) = argmax_of(labels, p.none[i]);
        partner[own[i] as usize] = k;
        prob[own[i] as usize] = v;
    }
    (partner, prob)
}

/// One-to-one pairs from the forward probabilities (see [`DecisionRule::OneToOne`]), in
/// input order (`own`, `other` as in [`argmax_all`]).
/// Choice: ties in probability are taken by lower frame-1, then frame-2 index (input order).
fn one_to_one(
    start: &[u32],
    target: &[u32],
    p: &Probabilities,
    own: &[u32],
    other: &[u32],
) -> (Vec<Option<usize>>, Vec<f64>) {
    let m = p.none.len();
    let mut candidates: Vec<(f64, u32, u32)> = Vec::new();
    let mut prob = vec![0.0; m];
    for i in 0..m {
        prob[own[i] as usize] = p.none[i];
        let r = start[i] as usize..start[i + 1] as usize;
        for (&v, &k) in p.real[r.clone()].iter().zip(&target[r]) {
            if v >= p.none[i] {
                candidates.push((v, own[i], other[k as usize]));
            }
        }
    }
    candidates.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut partner = vec![None; m];
    let mut taken = vec![false; other.len()];
    for (v, i, k) in candidates {
        let (i, k) = (i as usize, k as usize);
        if partner[i].is_none() && !taken[k] {
            partner[i] = Some(k);
            prob[i] = v;
            taken[k] = true;
        }
    }
    (partner, prob)
}

impl RelaxationProblem {
    /// [`DecisionRule::Assignment`] on `sol`, in input order.
    ///
    /// Choice: probabilities are floored at `1e-300` before the logarithm, so a label the
    /// relaxation drove to 0 stays allowed but costs about 690; a component too large for
    /// the dense solver ([`super::baselines::MAX_COMPONENT`]) falls back to the one-to-one
    /// rule for the whole problem.
    fn joint_assignment(&self, sol: &Solution) -> (Vec<Option<usize>>, Vec<f64>) {
        let g = &self.graph;
        let nl = |v: f64| -v.max(1e-300).ln();
        let q = sol.q.as_ref();
        let pair =
            |e: usize| nl(sol.p.real[e]) + q.map_or(0.0, |q| nl(q.real[g.fwd_twin[e] as usize]));
        let miss1 = |i: usize| nl(sol.p.none[i]);
        let miss2 = |k: usize| q.map_or(0.0, |q| nl(q.none[k]));
        let Ok(inner) = super::baselines::assign_components(g, &pair, &miss1, &miss2, "decision")
        else {
            let (o1, o2) = (&self.order1[..], &self.order2[..]);
            return one_to_one(&g.fwd_start, &g.fwd_target, &sol.p, o1, o2);
        };
        let m = g.m;
        let mut partner = vec![None; m];
        let mut prob = vec![0.0; m];
        for (i, k) in inner.into_iter().enumerate() {
            let own = self.order1[i] as usize;
            prob[own] = match k {
                Some(k) => {
                    partner[own] = Some(self.order2[k] as usize);
                    g.fwd_range(i)
                        .find(|&e| g.fwd_target[e] as usize == k)
                        .map_or(0.0, |e| sol.p.real[e])
                }
                None => sol.p.none[i],
            };
        }
        (partner, prob)
    }

    /// The decision on `sol` (argmax, or one-to-one).
    pub fn decide(&self, sol: &Solution, rule: DecisionRule) -> Matching {
        let g = &self.graph;
        let (o1, o2) = (&self.order1[..], &self.order2[..]);
        let (partner, probability) = match rule {
            DecisionRule::Argmax => argmax_all(&g.fwd_start, &g.fwd_target, &sol.p, o1, o2),
            DecisionRule::OneToOne => one_to_one(&g.fwd_start, &g.fwd_target, &sol.p, o1, o2),
            DecisionRule::Assignment => self.joint_assignment(sol),
        };
        let (backward_partner, backward_probability) = match &sol.q {
            Some(q) => {
                let (a, b) = argmax_all(&g.bwd_start, &g.bwd_target, q, o2, o1);
                (Some(a), Some(b))
            }
            None => (None, None),
        };
        Matching {
            ids1: self.ids1.clone(),
            ids2: self.ids2.clone(),
            partner,
            probability,
            backward_partner,
            backward_probability,
            iterations: sol.iterations,
            converged: sol.converged,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{RelaxationConfig, RelaxationVariant, match_vehicles};
    use super::*;
    use crate::Result;
    use crate::detection::Detection;
    use crate::geometry::Point;

    fn det(id: u64, x: f64, y: f64, rgb: [f64; 3]) -> Detection {
        Detection {
            colour_rgb: Some(rgb),
            ..Detection::at(1, id, Point::new(x, y))
        }
    }

    #[test]
    fn argmax_prefers_real_labels_on_ties_and_the_lower_index() {
        assert_eq!(argmax_row(&[3, 5], &[0.4, 0.4], 0.2), (Some(3), 0.4));
        assert_eq!(argmax_row(&[3], &[0.5], 0.5), (Some(3), 0.5));
        assert_eq!(argmax_row(&[3, 5], &[0.2, 0.3], 0.5), (None, 0.5));
        assert_eq!(argmax_row(&[], &[], 1.0), (None, 1.0));
    }

    #[test]
    fn one_to_one_gives_a_contested_vehicle_to_the_more_probable_claim() {
        // a_0 → b_0 0.7 (none 0.1), a_1 → b_0 0.6, b_1 0.3 (none 0.1): argmax sends both
        // to b_0; one-to-one gives b_0 to a_0 (0.7 > 0.6) and a_1 falls back to b_1
        // (0.3 ≥ 0.1).
        let start = [0, 1, 3];
        let target = [0, 0, 1];
        let p = Probabilities {
            real: vec![0.7, 0.6, 0.3],
            none: vec![0.1, 0.1],
        };
        let id = [0, 1];
        let (a, _) = argmax_all(&start, &target, &p, &id, &id);
        assert_eq!(a, vec![Some(0), Some(0)]);
        let (o, pr) = one_to_one(&start, &target, &p, &id, &id);
        assert_eq!(o, vec![Some(0), Some(1)]);
        assert_eq!(pr, vec![0.7, 0.3]);
    }

    #[test]
    fn joint_assignment_uses_the_backward_side_where_the_greedy_rule_cannot() -> Result<()> {
        // a_0 (0,0), a_1 (30,0); b_0 (10,0), b_1 (40,0): every pair is a label.
        // P: a_0 → b_0 0.6, b_1 0.35, none 0.05;  a_1 → b_0 0.55, b_1 0, none 0.45.
        // Q: b_0 → a_0 0.05, a_1 0.9, none 0.05;  b_1 → a_0 0.9, a_1 0.05, none 0.05.
        // One-to-one (P only): a_0–b_0 (0.6 first), a_1 none (b_1's 0 < 0.45).
        // Joint: {a_0–b_0, a_1 none, b_1 none} costs −ln .6 − ln .45 − ln .05 − ln .05
        //   = 0.51 + 0.80 + 3.00 + 3.00 = 7.31; {a_0–b_1, a_1–b_0} costs −ln .35 − ln .55
        //   − ln .9 − ln .9 = 1.05 + 0.60 + 0.11 + 0.11 = 1.86: the crossed pairs.
        let f1 = [det(1, 0.0, 0.0, [0.0; 3]), det(2, 30.0, 0.0, [0.0; 3])];
        let f2 = [det(5, 10.0, 0.0, [0.0; 3]), det(6, 40.0, 0.0, [0.0; 3])];
        let cfg = RelaxationConfig {
            variant: RelaxationVariant::Bidirectional,
            ..Default::default()
        };
        let prob = RelaxationProblem::new(&f1, &f2, &cfg)?;
        assert_eq!(
            (prob.order1.clone(), prob.order2.clone()),
            (vec![0, 1], vec![0, 1])
        );
        assert_eq!(prob.graph.fwd_target, vec![0, 1, 0, 1]);
        let sol = Solution {
            p: Probabilities {
                real: vec![0.6, 0.35, 0.55, 0.0],
                none: vec![0.05, 0.45],
            },
            q: Some(Probabilities {
                real: vec![0.05, 0.9, 0.9, 0.05],
                none: vec![0.05, 0.05],
            }),
            iterations: 0,
            converged: true,
            last_change: 0.0,
        };
        assert_eq!(
            prob.decide(&sol, DecisionRule::OneToOne).partner,
            vec![Some(0), None]
        );
        let joint = prob.decide(&sol, DecisionRule::Assignment);
        assert_eq!(joint.partner, vec![Some(1), Some(0)]);
        assert_eq!(joint.probability, vec![0.35, 0.55]);
        assert_eq!(
            "assignment".parse::<DecisionRule>()?,
            DecisionRule::Assignment
        );
        Ok(())
    }

    #[test]
    fn rows_list_frame_one_in_order_then_appeared_vehicles() {
        let m = Matching {
            ids1: vec![10, 11, 12],
            ids2: vec![20, 21, 22, 23],
            partner: vec![Some(2), None, Some(0)],
            probability: vec![0.9, 0.8, 0.7],
            backward_partner: None,
            backward_probability: None,
            iterations: 3,
            converged: true,
        };
        let rows = m.rows();
        let ids: Vec<_> = rows.iter().map(|r| (r.id1, r.id2)).collect();
        assert_eq!(
            ids,
            vec![
                (Some(10), Some(22)),
                (Some(11), None),
                (Some(12), Some(20)),
                (None, Some(21)),
                (None, Some(23)),
            ]
        );
        assert_eq!(rows[1].probability, Some(0.8));
        assert_eq!(rows[3].probability, None);
    }

    #[test]
    fn empty_frames_give_no_partner_or_all_appeared() -> Result<()> {
        let f = [det(1, 0.0, 0.0, [1.0; 3]), det(2, 9.0, 0.0, [1.0; 3])];
        let m = match_vehicles(&f, &[], &RelaxationConfig::default())?;
        assert_eq!(m.partner, vec![None, None]);
        assert_eq!(m.probability, vec![1.0, 1.0]);
        let m = match_vehicles(&[], &f, &RelaxationConfig::default())?;
        assert!(m.partner.is_empty());
        assert_eq!(m.appeared(), vec![0, 1]);
        let m = match_vehicles(&[], &[], &RelaxationConfig::default())?;
        assert!(m.rows().is_empty());
        Ok(())
    }

    #[test]
    fn a_single_vehicle_ends_with_no_partner_under_the_papers_weights() -> Result<()> {
        // Isolated pair, 40 px apart, colour cost 3 · 30² = 2700. Nothing supports the real
        // label (no neighbours: P̂ = Q̂ = 0), so eq. 19 multiplies it by A = 0.5 each
        // iteration while λ_p keeps its weight (eq. 18). Colour start: P = 21 675/24 375 =
        // 0.889 vs 2700/24 375 = 0.111, ratio 8 → after k iterations 8 · 0.5^k: λ_p wins
        // from k = 4. Documented: the method needs neighbours; with A ≥ 1 the start decides.
        for v in RelaxationVariant::ALL {
            let cfg = RelaxationConfig {
                variant: v,
                ..Default::default()
            };
            let f1 = [det(1, 0.0, 0.0, [100.0; 3])];
            let f2 = [det(2, 40.0, 0.0, [130.0; 3])];
            let m = match_vehicles(&f1, &f2, &cfg)?;
            assert_eq!(m.partner, vec![None], "{v}");
            let keep = RelaxationConfig {
                own_weight: 1.0,
                ..cfg
            };
            let expect = Some(0);
            // Uniform start with A = 1: (½, ½) for ever; ties go to the real label.
            assert_eq!(
                match_vehicles(&f1, &f2, &keep)?.partner,
                vec![expect],
                "{v}"
            );
        }
        Ok(())
    }

    #[test]
    fn bad_input_gives_clear_errors() {
        let cfg = RelaxationConfig::default();
        let a = det(1, 0.0, 0.0, [1.0; 3]);
        let dup = [a.clone(), a.clone()];
        let m = match_vehicles(&dup, &[], &cfg)
            .expect_err("dup")
            .to_string();
        assert!(
            m.contains("frame 1") && m.contains("id 1 appears twice"),
            "{m}"
        );
        let no_colour = [Detection::at(1, 5, Point::new(0.0, 0.0))];
        let m = match_vehicles(std::slice::from_ref(&a), &no_colour, &cfg)
            .expect_err("colour")
            .to_string();
        assert!(
            m.contains("frame 2") && m.contains("id 5 has no colour"),
            "{m}"
        );
        assert!(m.contains("variant `bidirectional`"), "{m}");
        // The uniform variants do not need colour.
        let uni = RelaxationConfig {
            variant: RelaxationVariant::Bidirectional,
            ..Default::default()
        };
        assert!(match_vehicles(std::slice::from_ref(&a), &no_colour, &uni).is_ok());
        let nan = [det(3, 0.0, 0.0, [f64::NAN, 0.0, 0.0])];
        let m = match_vehicles(&nan, &[], &uni)
            .expect_err("nan")
            .to_string();
        assert!(m.contains("id 3") && m.contains("colour"), "{m}");
        let out = [det(3, 0.0, 0.0, [256.0, 0.0, 0.0])];
        assert!(match_vehicles(&out, &[], &cfg).is_err());
        let pos = [det(4, f64::INFINITY, 0.0, [0.0; 3])];
        let m = match_vehicles(&pos, &[], &cfg)
            .expect_err("pos")
            .to_string();
        assert!(m.contains("non-finite position"), "{m}");
    }

    #[test]
    fn identical_vehicles_all_choose_the_first_unless_one_to_one() -> Result<()> {
        // Five vehicles at one place with one colour in both frames: every label has the
        // same probability for ever (1/5; λ_p starts at 0, eq. 9). Argmax ties go to the
        // lowest frame-2 index, so all five choose b_0; one-to-one pairs them in order.
        let f1: Vec<_> = (1..=5).map(|i| det(i, 10.0, 10.0, [50.0; 3])).collect();
        let f2: Vec<_> = (1..=5)
            .map(|i| det(i + 10, 10.0, 10.0, [50.0; 3]))
            .collect();
        let m = match_vehicles(&f1, &f2, &RelaxationConfig::default())?;
        assert_eq!(m.partner, vec![Some(0); 5]);
        assert!(m.probability.iter().all(|&p| (p - 0.2).abs() < 1e-12));
        let cfg = RelaxationConfig {
            decision: DecisionRule::OneToOne,
            ..Default::default()
        };
        let m = match_vehicles(&f1, &f2, &cfg)?;
        assert_eq!(m.partner, (0..5).map(Some).collect::<Vec<_>>());
        Ok(())
    }
}
