//! The update (METHODS.md §1 "Update", eqs. 17–20) and the iteration to convergence.
//!
//! ```text
//! P̃_i(λ_ik) = P_i(λ_ik) · (A + B·P̂_i(λ_ik) + C·Q̂_k(λ'_ki))     (eq. 19)
//! P̃_i(λ_p)  = P_i(λ_p)                                          (eq. 18)
//! P_i(λ)    ← P̃_i(λ) / Σ_{λ'∈L_i} P̃_i(λ')                       (eq. 17)
//! Q̃_k(λ'_ki) = Q_k(λ'_ki) · (A + B·Q̂_k(λ'_ki) + C·P̂_i(λ_ik))   (eq. 20)
//! ```
//!
//! All vehicles update from the previous iteration's `P` and `Q` (double buffer), so the
//! result does not depend on the order — or the number of threads — in which they run.

use super::labels::PAR_BLOCK;
use super::probabilities::{Probabilities, Solution};
use super::problem::RelaxationProblem;
use rayon::prelude::*;

/// The constants `A, B, C` of eqs. 19–20.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateWeights {
    /// `A`: own evidence.
    pub own_weight: f64,
    /// `B`: same-direction neighbour support.
    pub forward_support_weight: f64,
    /// `C`: opposite-direction support of the same pair (0: unidirectional).
    pub backward_support_weight: f64,
}

/// Work buffers of one iteration.
struct Buffers {
    p_hat: Vec<f64>,
    q_hat: Vec<f64>,
    p_new: Probabilities,
    q_new: Option<Probabilities>,
}

impl RelaxationProblem {
    /// Iterates eqs. 17–20 from the start until no probability changes by more than
    /// `epsilon` or `max_iterations` iterations have run.
    pub fn solve(&self, w: &UpdateWeights, epsilon: f64, max_iterations: u32) -> Solution {
        let mut sol = self.initial();
        let mut buf = self.buffers();
        while sol.iterations < max_iterations {
            let change = self.step_with(&mut sol, w, &mut buf);
            if change <= epsilon {
                sol.converged = true;
                break;
            }
        }
        sol
    }

    /// One iteration of eqs. 17–20 on `sol`; returns the largest change of any probability.
    pub fn step(&self, sol: &mut Solution, w: &UpdateWeights) -> f64 {
        let mut buf = self.buffers();
        self.step_with(sol, w, &mut buf)
    }

    fn buffers(&self) -> Buffers {
        let g = &self.graph;
        Buffers {
            p_hat: vec![0.0; g.n_labels()],
            q_hat: if self.bidirectional() {
                vec![0.0; g.n_labels()]
            } else {
                Vec::new()
            },
            p_new: self.initial_p.clone(),
            q_new: self.initial_q.clone(),
        }
    }

    fn step_with(&self, sol: &mut Solution, w: &UpdateWeights, buf: &mut Buffers) -> f64 {
        let g = &self.graph;
        // Supports from the old probabilities only (double buffer).
        let change = match (&sol.q, &self.bwd_support, &mut buf.q_new) {
            (Some(q), Some(bwd), Some(q_new)) => {
                // The two directions side by side (each value is still computed by one
                // thread in a fixed order: thread count does not change the bits).
                let (p_hat, q_hat) = (&mut buf.p_hat, &mut buf.q_hat);
                rayon::join(
                    || self.fwd_support.sums(&sol.p.real, p_hat),
                    || bwd.sums(&q.real, q_hat),
                );
                let (p_hat, q_hat) = (&buf.p_hat, &buf.q_hat);
                let p_new = &mut buf.p_new;
                let (wf, wb) = self.witnesses();
                let (c1, c2) = rayon::join(
                    || {
                        update_direction(
                            &g.fwd_start,
                            &g.fwd_twin,
                            &sol.p,
                            (p_hat, wf),
                            Some((q_hat, wb)),
                            w,
                            p_new,
                        )
                    },
                    || {
                        update_direction(
                            &g.bwd_start,
                            &g.bwd_twin,
                            q,
                            (q_hat, wb),
                            Some((p_hat, wf)),
                            w,
                            q_new,
                        )
                    },
                );
                c1.max(c2)
            }
            _ => {
                self.fwd_support.sums(&sol.p.real, &mut buf.p_hat);
                let (wf, _) = self.witnesses();
                update_direction(
                    &g.fwd_start,
                    &g.fwd_twin,
                    &sol.p,
                    (&buf.p_hat, wf),
                    None,
                    w,
                    &mut buf.p_new,
                )
            }
        };
        std::mem::swap(&mut sol.p, &mut buf.p_new);
        if let (Some(q), Some(q_new)) = (&mut sol.q, &mut buf.q_new) {
            std::mem::swap(q, q_new);
        }
        sol.iterations += 1;
        sol.last_change = change;
        change
    }
}

impl RelaxationProblem {
    /// The support-list row starts of each direction when `neutral_without_neighbours` is
    /// on: a label whose row is empty has no possible supporter.
    fn witnesses(&self) -> (Option<&[u32]>, Option<&[u32]>) {
        if !self.neutral_without_neighbours {
            return (None, None);
        }
        (
            Some(&self.fwd_support.start[..]),
            self.bwd_support.as_ref().map(|b| &b.start[..]),
        )
    }
}

/// A direction's supports and, with `neutral_without_neighbours`, its support-list row
/// starts (an empty row: no neighbour label similar to this one).
type Side<'a> = (&'a [f64], Option<&'a [u32]>);

/// Eqs. 17–19 (or 20) for every vehicle of one direction: reads `old`, the supports, and
/// writes `out`; returns the largest absolute change.
///
/// With support-list rows (`RelaxationConfig::neutral_without_neighbours`, ours): a label
/// whose pair has no possible supporter on either side (no neighbour has a similar label,
/// eq. 15) is multiplied by 1, as `λ_p` (eq. 18), instead of `A`: no evidence neither
/// reinforces nor weakens it.
///
/// Choice: when every reinforced probability of a vehicle is 0 (possible with `A = 0` and
/// no support, a corner of the paper's sweep), eq. 17 would divide by zero; the vehicle
/// keeps its old probabilities (paper silent).
fn update_direction(
    start: &[u32],
    twin: &[u32],
    old: &Probabilities,
    own: Side<'_>,
    other: Option<Side<'_>>,
    w: &UpdateWeights,
    out: &mut Probabilities,
) -> f64 {
    let (own_support, own_witness) = own;
    let other_support = other.map(|o| o.0);
    let other_witness = other.and_then(|o| o.1);
    let rows = old.none.len();
    let vehicle = |i: usize, real: &mut [f64], none: &mut f64| -> f64 {
        let r = start[i] as usize..start[i + 1] as usize;
        let base = r.start;
        let mut sum = old.none[i];
        for e in r.clone() {
            let back = match other_support {
                Some(s) => w.backward_support_weight * s[twin[e] as usize],
                None => 0.0,
            };
            let empty = |st: &[u32], x: usize| st[x] == st[x + 1];
            let unwitnessed = own_witness.is_some_and(|st| empty(st, e))
                && other_witness.is_none_or(|st| empty(st, twin[e] as usize));
            let factor = if unwitnessed {
                1.0
            } else {
                w.own_weight + w.forward_support_weight * own_support[e] + back
            };
            let v = old.real[e] * factor;
            real[e - base] = v;
            sum += v;
        }
        let mut change: f64 = 0.0;
        if sum > 0.0 && sum.is_finite() {
            for e in r {
                let v = real[e - base] / sum;
                real[e - base] = v;
                change = change.max((v - old.real[e]).abs());
            }
            *none = old.none[i] / sum;
            change.max((*none - old.none[i]).abs())
        } else {
            real.copy_from_slice(&old.real[r]);
            *none = old.none[i];
            0.0
        }
    };
    let n_blocks = rows.div_ceil(PAR_BLOCK);
    // Split the outputs at block boundaries so blocks can run on any thread.
    let mut parts = Vec::with_capacity(n_blocks);
    let (mut real_rest, mut none_rest) = (&mut out.real[..], &mut out.none[..]);
    for b in 0..n_blocks {
        let (v0, v1) = (b * PAR_BLOCK, ((b + 1) * PAR_BLOCK).min(rows));
        let len = (start[v1] - start[v0]) as usize;
        let (real_b, rr) = std::mem::take(&mut real_rest).split_at_mut(len);
        let (none_b, nr) = std::mem::take(&mut none_rest).split_at_mut(v1 - v0);
        real_rest = rr;
        none_rest = nr;
        parts.push((v0, v1, real_b, none_b));
    }
    let run = |(v0, v1, real_b, none_b): (usize, usize, &mut [f64], &mut [f64])| -> f64 {
        let base = start[v0] as usize;
        let mut change: f64 = 0.0;
        for i in v0..v1 {
            let r = start[i] as usize - base..start[i + 1] as usize - base;
            change = change.max(vehicle(i, &mut real_b[r], &mut none_b[i - v0]));
        }
        change
    };
    if n_blocks > 1 {
        parts.into_par_iter().map(run).reduce(|| 0.0, f64::max)
    } else {
        parts.into_iter().map(run).fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::super::{
        DecisionRule, Matching, RelaxationConfig, RelaxationVariant, match_vehicles,
    };
    use super::*;
    use crate::detection::Detection;
    use crate::error::Result;
    use crate::geometry::Point;
    use proptest::prelude::*;

    fn det(id: u64, x: f64, y: f64, rgb: [f64; 3]) -> Detection {
        Detection {
            colour_rgb: Some(rgb),
            ..Detection::at(1, id, Point::new(x, y))
        }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn one_iteration_matches_a_hand_computation() -> Result<()> {
        // Frame 1: a_0 (0,0), a_1 (30,0). Frame 2: b_0 (10,0), b_1 (40,0). Uniform start,
        // bidirectional (variant c), A = 0.5, B = 1, C = 1, D = 150, R = 200, T = 20.
        // Labels: a_0 → b_0 (10,0), b_1 (40,0); a_1 → b_0 (−20,0), b_1 (10,0).
        // Backward: b_0 → a_0 (−10,0), a_1 (20,0); b_1 → a_0 (−40,0), a_1 (−10,0).
        // Start: every vehicle has 3 labels → P = Q = 1/3 each.
        // P̂ (eq. 13): a_0 (10,0): labels of a_1 within 20: (−20,0) d=30 ✗, (10,0) ✓ → 1/3
        //              a_0 (40,0): (10,0) d=30 ✗, (−20,0) ✗ → 0
        //              a_1 (−20,0): (10,0) d=30 ✗, (40,0) ✗ → 0
        //              a_1 (10,0): (10,0) ✓ → 1/3
        // Q̂ (eq. 14): b_0 (−10,0): labels of b_1: (−40,0) ✗, (−10,0) ✓ → 1/3
        //              b_0 (20,0): (−10,0) d=30 ✗ → 0
        //              b_1 (−40,0): (−10,0) d=30 ✗ → 0;  b_1 (−10,0): (−10,0) ✓ → 1/3
        // Eq. 19, a_0: (10,0) [pair a_0–b_0, Q̂ 1/3]: 1/3·(0.5 + 1/3 + 1/3) = 1/3·7/6 = 7/18
        //              (40,0) [pair a_0–b_1, Q̂_1(−40,0) = 0]: 1/3·0.5 = 1/6 = 3/18
        //              λ_p (eq. 18): 1/3 = 6/18.   Σ = 16/18
        //   Eq. 17: P = 7/16, 3/16, 6/16.
        // a_1: (−20,0) [a_1–b_0, Q̂_0(20,0) = 0]: 1/6 = 3/18; (10,0) [a_1–b_1, Q̂ 1/3]: 7/18;
        //   λ_p 6/18 → P = 3/16, 7/16, 6/16. By symmetry Q is the same shape:
        //   b_0: (−10,0) 7/16, (20,0) 3/16, λ_p 6/16;  b_1: (−40,0) 3/16, (−10,0) 7/16, 6/16.
        let f1 = [det(1, 0.0, 0.0, [0.0; 3]), det(2, 30.0, 0.0, [0.0; 3])];
        let f2 = [det(1, 10.0, 0.0, [0.0; 3]), det(2, 40.0, 0.0, [0.0; 3])];
        let cfg = RelaxationConfig {
            variant: RelaxationVariant::Bidirectional,
            ..Default::default()
        };
        let prob = RelaxationProblem::new(&f1, &f2, &cfg)?;
        let mut sol = prob.initial();
        assert!(sol.p.real.iter().all(|&p| close(p, 1.0 / 3.0)));
        let change = prob.step(&mut sol, &cfg.weights());
        let want_p = [7.0 / 16.0, 3.0 / 16.0, 3.0 / 16.0, 7.0 / 16.0];
        for (a, b) in sol.p.real.iter().zip(want_p) {
            assert!(close(*a, b), "{:?}", sol.p.real);
        }
        assert!(sol.p.none.iter().all(|&p| close(p, 6.0 / 16.0)));
        let q = sol.q.as_ref().expect("bidirectional");
        let want_q = [7.0 / 16.0, 3.0 / 16.0, 3.0 / 16.0, 7.0 / 16.0];
        for (a, b) in q.real.iter().zip(want_q) {
            assert!(close(*a, b), "{:?}", q.real);
        }
        // Largest change: |3/16 − 1/3| = |9/48 − 16/48| = 7/48 (7/16 − 1/3 is only 5/48).
        assert!(close(change, 7.0 / 48.0), "{change}");
        Ok(())
    }

    #[test]
    fn unidirectional_update_ignores_the_backward_side() -> Result<()> {
        // Same scene, variant (a): eq. 19 with C = 0.
        // a_0: (10,0): 1/3·(0.5 + 1/3) = 5/18; (40,0): 1/3·0.5 = 3/18; λ_p 6/18; Σ = 14/18
        //   → P = 5/14, 3/14, 6/14.
        let f1 = [det(1, 0.0, 0.0, [0.0; 3]), det(2, 30.0, 0.0, [0.0; 3])];
        let f2 = [det(1, 10.0, 0.0, [0.0; 3]), det(2, 40.0, 0.0, [0.0; 3])];
        let cfg = RelaxationConfig {
            variant: RelaxationVariant::Unidirectional,
            ..Default::default()
        };
        let prob = RelaxationProblem::new(&f1, &f2, &cfg)?;
        let mut sol = prob.initial();
        assert!(sol.q.is_none());
        prob.step(&mut sol, &cfg.weights());
        assert!(close(sol.p.real[0], 5.0 / 14.0) && close(sol.p.real[1], 3.0 / 14.0));
        assert!(close(sol.p.none[0], 6.0 / 14.0));
        Ok(())
    }

    #[test]
    fn all_zero_weights_keep_the_old_probabilities() -> Result<()> {
        let f1 = [det(1, 0.0, 0.0, [0.0; 3])];
        let f2 = [det(1, 0.0, 0.0, [0.0; 3])];
        // Colour-identical single candidate: P⁽⁰⁾ = (1, 0); with A = B = C = 0 eq. 17
        // would be 0/0: the vehicle keeps its probabilities.
        let prob = RelaxationProblem::new(&f1, &f2, &RelaxationConfig::default())?;
        let w = UpdateWeights {
            own_weight: 0.0,
            forward_support_weight: 0.0,
            backward_support_weight: 0.0,
        };
        let sol = prob.solve(&w, 1e-6, 50);
        assert_eq!(sol.p.real, vec![1.0]);
        assert_eq!(sol.p.none, vec![0.0]);
        assert!(sol.converged && sol.iterations == 1);
        Ok(())
    }

    #[test]
    fn a_vehicle_no_neighbour_could_support_keeps_its_start_when_neutral() -> Result<()> {
        // One vehicle, one candidate of a close colour 8 px away, nobody else: eq. 19
        // multiplies the real label by A = 0.5 each iteration and λ_p wins (the paper);
        // with `neutral_without_neighbours` the label is multiplied by 1, like λ_p, and
        // keeps its start.
        let f1 = [det(1, 0.0, 0.0, [100.0; 3])];
        let f2 = [det(9, 8.0, 0.0, [104.0; 3])];
        let paper = RelaxationConfig::default();
        let neutral = RelaxationConfig {
            neutral_without_neighbours: true,
            ..Default::default()
        };
        assert_eq!(match_vehicles(&f1, &f2, &paper)?.partner, vec![None]);
        let prob = RelaxationProblem::new(&f1, &f2, &neutral)?;
        let sol = prob.solve(&neutral.weights(), neutral.epsilon, neutral.max_iterations);
        assert_eq!(sol.p, prob.initial().p);
        assert_eq!(match_vehicles(&f1, &f2, &neutral)?.partner, vec![Some(0)]);
        // Where every label has a possible supporter (T = 1 000 px: every neighbour label
        // is similar) the option changes nothing: the paper's iterations, bit for bit.
        let (f1, f2, _) = super::super::scale::generate_road_network_pair(
            60,
            &super::super::scale::NetworkConfig::default(),
            3,
        )?;
        let wide = |neutral_without_neighbours| RelaxationConfig {
            similar_displacement_px: 1000.0,
            neighbour_radius_px: 5000.0,
            neutral_without_neighbours,
            ..Default::default()
        };
        let solve = |c: &RelaxationConfig| -> Result<Solution> {
            let prob = RelaxationProblem::new(&f1, &f2, c)?;
            Ok(prob.solve(&c.weights(), c.epsilon, c.max_iterations))
        };
        assert_eq!(solve(&wide(true))?, solve(&wide(false))?);
        Ok(())
    }

    /// A random scene: a flow of vehicles moving by about (30, 5) px with noise, random
    /// colours, some vehicles missing from each frame.
    pub(crate) fn arbitrary_pair() -> impl Strategy<Value = (Vec<Detection>, Vec<Detection>)> {
        prop::collection::vec(
            (
                0.0..800.0f64,
                0.0..300.0f64,
                -8.0..8.0f64,
                -8.0..8.0f64,
                prop::array::uniform3(0.0..255.0f64),
                0u8..10,
            ),
            0..40,
        )
        .prop_map(|v| {
            let mut f1 = Vec::new();
            let mut f2 = Vec::new();
            for (i, (x, y, nx, ny, rgb, miss)) in v.into_iter().enumerate() {
                let id = i as u64 + 1;
                if miss != 0 {
                    f1.push(det(id, x, y, rgb));
                }
                if miss != 1 {
                    let c = rgb.map(|c| (c + nx).clamp(0.0, 255.0));
                    f2.push(det(id + 100, x + 30.0 + nx, y + 5.0 + ny, c));
                }
            }
            (f1, f2)
        })
    }

    fn rows_are_distributions(start: &[u32], p: &Probabilities) -> std::result::Result<(), String> {
        for i in 0..p.none.len() {
            let r = start[i] as usize..start[i + 1] as usize;
            let mut s = p.none[i];
            for &v in p.real[r.clone()].iter().chain([&p.none[i]]) {
                if !(0.0..=1.0).contains(&v) {
                    return Err(format!("vehicle {i}: probability {v} outside [0, 1]"));
                }
            }
            s += p.real[r].iter().sum::<f64>();
            if (s - 1.0).abs() > 1e-9 {
                return Err(format!("vehicle {i}: probabilities sum to {s}"));
            }
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Eq. 4 / eq. 17: every vehicle's probabilities lie in [0, 1] and sum to 1 after
        /// every iteration, in both directions, for every variant.
        #[test]
        fn probabilities_stay_distributions((f1, f2) in arbitrary_pair(), v in 0usize..4,
                                            a in 0.0..1.0f64, b in 0.0..10.0f64, c in 0.0..10.0f64) {
            let cfg = RelaxationConfig { variant: RelaxationVariant::ALL[v], own_weight: a,
                forward_support_weight: b, backward_support_weight: c, ..Default::default() };
            let prob = RelaxationProblem::new(&f1, &f2, &cfg).expect("problem");
            let mut sol = prob.initial();
            for _ in 0..12 {
                rows_are_distributions(&prob.graph.fwd_start, &sol.p).map_err(TestCaseError::fail)?;
                if let Some(q) = &sol.q {
                    rows_are_distributions(&prob.graph.bwd_start, q).map_err(TestCaseError::fail)?;
                }
                prob.step(&mut sol, &cfg.weights());
            }
        }

        /// Swapping the frames mirrors the bidirectional result: the forward probabilities
        /// of the swapped problem are the backward ones of the original, bit for bit.
        #[test]
        fn swapping_frames_mirrors_the_bidirectional_result((f1, f2) in arbitrary_pair(), colour in any::<bool>()) {
            let cfg = RelaxationConfig { variant: if colour { RelaxationVariant::ColourBidirectional } else { RelaxationVariant::Bidirectional }, ..Default::default() };
            let ab = RelaxationProblem::new(&f1, &f2, &cfg).expect("problem");
            let ba = RelaxationProblem::new(&f2, &f1, &cfg).expect("problem");
            prop_assert_eq!(&ab.graph.swapped(), &ba.graph);
            let s_ab = ab.solve(&cfg.weights(), cfg.epsilon, cfg.max_iterations);
            let s_ba = ba.solve(&cfg.weights(), cfg.epsilon, cfg.max_iterations);
            prop_assert_eq!(s_ab.q.as_ref(), Some(&s_ba.p));
            prop_assert_eq!(Some(&s_ab.p), s_ba.q.as_ref());
            prop_assert_eq!(s_ab.iterations, s_ba.iterations);
            let m_ab = ab.decide(&s_ab, DecisionRule::Argmax);
            let m_ba = ba.decide(&s_ba, DecisionRule::Argmax);
            prop_assert_eq!(m_ab.backward_partner.as_ref(), Some(&m_ba.partner));
            prop_assert_eq!(m_ba.backward_partner.as_ref(), Some(&m_ab.partner));
        }
    }

    #[test]
    fn permuted_input_order_gives_the_same_matches() -> Result<()> {
        // The internal grid order is computed from positions; the input order only breaks
        // ties inside a cell, which can change the order of additions, not the pairs.
        let (f1, f2, _) = super::super::scale::generate_road_network_pair(
            3000,
            &super::super::scale::NetworkConfig::default(),
            5,
        )?;
        let cfg = RelaxationConfig::default();
        let pairs = |m: &Matching| -> Vec<(u64, Option<u64>)> {
            let mut v: Vec<_> = m
                .ids1
                .iter()
                .zip(&m.partner)
                .map(|(&a, k)| (a, k.map(|k| m.ids2[k])))
                .collect();
            v.sort_unstable();
            v
        };
        let a = match_vehicles(&f1, &f2, &cfg)?;
        let r1: Vec<_> = f1.iter().rev().cloned().collect();
        let r2: Vec<_> = f2.iter().rev().cloned().collect();
        let b = match_vehicles(&r1, &r2, &cfg)?;
        assert_eq!(pairs(&a), pairs(&b));
        // The internal order is the grid order, whatever the input order.
        let prob = RelaxationProblem::new(&f1, &f2, &cfg)?;
        let ys: Vec<f64> = prob
            .order1
            .iter()
            .map(|&i| f1[i as usize].pos_px.y)
            .collect();
        let cells: Vec<i64> = ys.iter().map(|y| (y / 200.0).floor() as i64).collect();
        assert!(cells.windows(2).all(|w| w[0] <= w[1]));
        Ok(())
    }

    #[test]
    fn results_are_identical_at_any_thread_count() -> Result<()> {
        // Large enough (5 000 vehicles) that the label, support and update loops split
        // into parallel blocks.
        let (f1, f2, _) = super::super::scale::generate_road_network_pair(
            5000,
            &super::super::scale::NetworkConfig::default(),
            11,
        )?;
        let cfg = RelaxationConfig::default();
        let run = |threads: usize| -> Result<(Solution, Matching)> {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| crate::Error::Invalid(e.to_string()))?;
            pool.install(|| {
                let prob = RelaxationProblem::new(&f1, &f2, &cfg)?;
                let sol = prob.solve(&cfg.weights(), cfg.epsilon, cfg.max_iterations);
                let m = prob.decide(&sol, cfg.decision);
                Ok((sol, m))
            })
        };
        let one = run(1)?;
        let four = run(4)?;
        assert_eq!(one.0, four.0);
        assert_eq!(one.1, four.1);
        assert_eq!(match_vehicles(&f1, &f2, &cfg)?, one.1);
        Ok(())
    }
}
