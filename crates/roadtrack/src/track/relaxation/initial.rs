//! Initial label probabilities (METHODS.md §1 "Initial probabilities", eqs. 7–11).
//!
//! Colour start (variants b, d): the closer a candidate's mean colour, the larger its
//! initial probability; the no-match label competes with the colour cost of an average
//! stranger (eq. 8). Uniform start (variants a, c): every label of `L_i` alike.

use super::COLOUR_MAX;
use super::probabilities::Probabilities;

/// Eq. 8: colour cost of the no-match label, `3 · (C_max / 3)²` = 21 675 for 8-bit colour.
pub const NO_MATCH_COLOUR_COST: f64 = 3.0 * (COLOUR_MAX / 3.0) * (COLOUR_MAX / 3.0);

/// Eq. 7: squared RGB distance between two mean colours.
///
/// ```text
/// C_i(λ_ik) = (r_i − r_k)² + (g_i − g_k)² + (b_i − b_k)²
/// ```
pub fn colour_cost(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// Eqs. 9–11 for one vehicle: writes the initial probabilities of its real labels, whose
/// colour costs are `costs`, into `out` and returns that of the no-match label.
///
/// ```text
/// S_i = Σ_{λ∈L_i} C_i(λ)            (λ_p included, C_i(λ_p) from eq. 8)
/// Ĉ_i(λ) = (S_i − C_i(λ)) / S_i     (eq. 9)
/// P_i⁽⁰⁾(λ) = Ĉ_i(λ) / Σ_{λ'∈L_i} Ĉ_i(λ')   (eqs. 10, 11)
/// ```
///
/// A vehicle with no candidate has `P_i(λ_p) = 1` (METHODS.md §1).
pub fn colour_start_row(costs: &[f64], out: &mut [f64]) -> f64 {
    debug_assert_eq!(costs.len(), out.len(), "one output per label");
    if costs.is_empty() {
        return 1.0;
    }
    let s: f64 = costs.iter().sum::<f64>() + NO_MATCH_COLOUR_COST;
    let hat = |c: f64| (s - c) / s;
    let hat_none = hat(NO_MATCH_COLOUR_COST);
    let total: f64 = costs.iter().map(|&c| hat(c)).sum::<f64>() + hat_none;
    for (o, &c) in out.iter_mut().zip(costs) {
        *o = hat(c) / total;
    }
    hat_none / total
}

/// Colour likelihood start (ours, `RelaxationConfig::colour_sd` = `sigma` > 0) for one
/// vehicle: real label `λ` ∝ `exp(−C(λ) / 2σ²)`, no-match label ∝ `exp(−6)` (the weight of
/// a candidate `2σ` off in each channel: `C = 12σ²`); returns the no-match probability.
/// Computed relative to the smallest cost, so no weight underflows to 0 for all labels.
pub fn colour_likelihood_row(costs: &[f64], sigma: f64, out: &mut [f64]) -> f64 {
    debug_assert_eq!(costs.len(), out.len(), "one output per label");
    if costs.is_empty() {
        return 1.0;
    }
    let k = 1.0 / (2.0 * sigma * sigma);
    let none_cost = 12.0 * sigma * sigma;
    let lo = costs.iter().copied().fold(none_cost, f64::min);
    let none_w = (-(none_cost - lo) * k).exp();
    let mut total = none_w;
    for (o, &c) in out.iter_mut().zip(costs) {
        *o = (-(c - lo) * k).exp();
        total += *o;
    }
    for o in out.iter_mut() {
        *o /= total;
    }
    none_w / total
}

/// Uniform start for one vehicle with `out.len()` real labels: `1 / (|L_i|)` each, the
/// no-match label included; returns the no-match probability.
pub fn uniform_start_row(out: &mut [f64]) -> f64 {
    let u = 1.0 / (out.len() + 1) as f64;
    out.fill(u);
    u
}

/// The displacement prior (ours, `RelaxationConfig::displacement_sd_px`): multiplies the
/// start of each real label (rows `start`, displacements `disp`) by `exp(−|λ|² / 2σ²)` and
/// each no-match label by `exp(−2)`, then renormalises every row.
///
/// Choice: the no-match label weighs as much as a label `2σ` long: a vehicle whose only
/// candidates lie far beyond the expected motion starts closer to "no partner". A row
/// whose weights all vanish keeps its start.
pub fn displacement_prior(start: &[u32], disp: &[[f64; 2]], sigma: f64, p: &mut Probabilities) {
    let none_w = (-2.0f64).exp();
    let k = 1.0 / (2.0 * sigma * sigma);
    for i in 0..p.none.len() {
        let r = start[i] as usize..start[i + 1] as usize;
        let mut sum = p.none[i] * none_w;
        let mut w = Vec::with_capacity(r.len());
        for e in r.clone() {
            let d = disp[e];
            let v = p.real[e] * (-(d[0] * d[0] + d[1] * d[1]) * k).exp();
            w.push(v);
            sum += v;
        }
        if sum > 0.0 && sum.is_finite() {
            for (e, v) in r.zip(w) {
                p.real[e] = v / sum;
            }
            p.none[i] = p.none[i] * none_w / sum;
        }
    }
}

/// Own and other frame's mean colours.
pub(crate) type ColourPair<'a> = (&'a [[f64; 3]], &'a [[f64; 3]]);

/// Initial probabilities of one direction: rows `start`, targets `target` (indices into
/// `other`), own colours `own`. `colours` is `None` for the uniform start; `colour_sd`
/// above 0 takes [`colour_likelihood_row`] instead of eqs. 9–11.
pub(crate) fn initial_probabilities(
    start: &[u32],
    target: &[u32],
    colours: Option<ColourPair<'_>>,
    colour_sd: f64,
) -> Probabilities {
    let rows = start.len().saturating_sub(1);
    let mut real = vec![0.0; target.len()];
    let mut none = vec![0.0; rows];
    let mut costs = Vec::new();
    for i in 0..rows {
        let r = start[i] as usize..start[i + 1] as usize;
        none[i] = match colours {
            None => uniform_start_row(&mut real[r]),
            Some((own, other)) => {
                costs.clear();
                costs.extend(
                    target[r.clone()]
                        .iter()
                        .map(|&k| colour_cost(own[i], other[k as usize])),
                );
                if colour_sd > 0.0 {
                    colour_likelihood_row(&costs, colour_sd, &mut real[r])
                } else {
                    colour_start_row(&costs, &mut real[r])
                }
            }
        };
    }
    Probabilities { real, none }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn colour_cost_is_the_squared_rgb_distance() {
        // (10−0)² + (20−0)² + (30−60)² = 100 + 400 + 900 = 1400 (eq. 7).
        assert_eq!(colour_cost([10.0, 20.0, 30.0], [0.0, 0.0, 60.0]), 1400.0);
        // Eq. 8: 3 · (255/3)² = 3 · 85² = 3 · 7225 = 21 675.
        assert_eq!(NO_MATCH_COLOUR_COST, 21_675.0);
    }

    #[test]
    fn colour_start_matches_a_hand_computation() {
        // Two candidates with colour costs 0 and 21 675, plus λ_p (21 675):
        //   S = 0 + 21 675 + 21 675 = 43 350                               (eq. 9 denominator)
        //   Ĉ = (43 350 − 0)/43 350 = 1, (43 350 − 21 675)/43 350 = 0.5, λ_p: 0.5
        //   Σ Ĉ = 2  →  P⁽⁰⁾ = 0.5, 0.25, 0.25                              (eqs. 10, 11)
        let mut out = [0.0; 2];
        let none = colour_start_row(&[0.0, NO_MATCH_COLOUR_COST], &mut out);
        assert!(close(out[0], 0.5) && close(out[1], 0.25) && close(none, 0.25));

        // One candidate with cost 1400:
        //   S = 1400 + 21 675 = 23 075
        //   Ĉ = 21 675/23 075, λ_p: 1400/23 075, ΣĈ = 1
        //   P⁽⁰⁾ = 0.939328…, λ_p 0.060671…
        let mut out = [0.0; 1];
        let none = colour_start_row(&[1400.0], &mut out);
        assert!(close(out[0], 21_675.0 / 23_075.0), "{}", out[0]);
        assert!(close(none, 1400.0 / 23_075.0), "{none}");
    }

    #[test]
    fn a_vehicle_without_candidates_has_no_match_probability_one() {
        assert_eq!(colour_start_row(&[], &mut []), 1.0);
        assert_eq!(uniform_start_row(&mut []), 1.0);
    }

    #[test]
    fn uniform_start_spreads_over_every_label_including_no_match() {
        let mut out = [0.0; 3];
        let none = uniform_start_row(&mut out);
        assert_eq!(out, [0.25; 3]);
        assert_eq!(none, 0.25);
    }

    #[test]
    fn identical_colours_leave_no_match_at_zero() {
        // Every candidate colour-identical: S = C(λ_p), Ĉ(λ_p) = 0: the paper's formula
        // gives the no-match label probability 0 (it can never win). Documented behaviour.
        let mut out = [0.0; 3];
        let none = colour_start_row(&[0.0; 3], &mut out);
        assert_eq!(none, 0.0);
        assert!(out.iter().all(|&p| close(p, 1.0 / 3.0)));
    }

    #[test]
    fn colour_likelihood_start_matches_a_hand_computation() {
        // σ = 10: weights exp(−C/200) relative to the smallest cost (0).
        //   C = 0 → 1;  C = 200 → e⁻¹;  λ_p: C = 12σ² = 1200 → e⁻⁶.
        let mut out = [0.0; 2];
        let none = colour_likelihood_row(&[0.0, 200.0], 10.0, &mut out);
        let total = 1.0 + (-1.0f64).exp() + (-6.0f64).exp();
        assert!(close(out[0], 1.0 / total) && close(out[1], (-1.0f64).exp() / total));
        assert!(close(none, (-6.0f64).exp() / total));
        // Far costs: relative to the smallest (λ_p's 1200 here), so λ_p keeps weight 1
        // and nothing is 0/0.
        let none = colour_likelihood_row(&[1e6, 2e6], 10.0, &mut out);
        assert!(
            none == 1.0 && out.iter().all(|p| (0.0..1e-300).contains(p)),
            "{out:?}"
        );
        // Unlike eqs. 9–11 it separates one close colour among many strangers.
        let costs = [30.0, 3000.0, 3000.0, 3000.0, 3000.0, 3000.0];
        let mut paper = [0.0; 6];
        colour_start_row(&costs, &mut paper);
        let mut ours = [0.0; 6];
        colour_likelihood_row(&costs, 10.0, &mut ours);
        assert!(paper[0] < 0.2 && ours[0] > 0.99, "{paper:?} {ours:?}");
    }

    #[test]
    fn displacement_prior_favours_short_labels_and_renormalises() {
        // One vehicle, labels (0, 0) and (20, 0), σ = 10, uniform start 1/3 each:
        //   weights 1, e⁻², λ_p e⁻²  →  1/(1 + 2e⁻²), e⁻²/(1 + 2e⁻²), e⁻²/(1 + 2e⁻²).
        let mut p = Probabilities {
            real: vec![1.0 / 3.0; 2],
            none: vec![1.0 / 3.0],
        };
        displacement_prior(&[0, 2], &[[0.0, 0.0], [20.0, 0.0]], 10.0, &mut p);
        let e2 = (-2.0f64).exp();
        let t = 1.0 + 2.0 * e2;
        assert!(close(p.real[0], 1.0 / t) && close(p.real[1], e2 / t));
        assert!(close(p.none[0], e2 / t));
    }
}
