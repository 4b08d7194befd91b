//! Baselines for the experiments (issue 5 item 5): nearest neighbour and the globally
//! optimal one-to-one assignment, both with the relaxation's square gate `D`.

use super::labels::LabelGraph;
use crate::assignment::linear_sum_assignment;
use crate::detection::Detection;
use crate::error::Result;
use crate::geometry::Point;

fn positions(f: &[Detection]) -> Vec<Point> {
    f.iter().map(|d| d.pos_px).collect()
}

fn dist(d: [f64; 2]) -> f64 {
    d[0].hypot(d[1])
}

/// Nearest neighbour: every frame-1 vehicle takes the closest frame-2 vehicle inside its
/// gate (Euclidean), independently of the others; none when the gate is empty.
/// Choice: exact ties go to the lower frame-2 index.
///
/// # Errors
/// From [`LabelGraph::new`].
pub fn nearest_neighbour(
    frame1: &[Detection],
    frame2: &[Detection],
    gate_half_width_px: f64,
) -> Result<Vec<Option<usize>>> {
    let g = LabelGraph::new(&positions(frame1), &positions(frame2), gate_half_width_px)?;
    Ok((0..g.m)
        .map(|i| {
            let mut best: Option<(f64, usize)> = None;
            for e in g.fwd_range(i) {
                let d = dist(g.fwd_disp[e]);
                if best.is_none_or(|(b, _)| d < b) {
                    best = Some((d, g.fwd_target[e] as usize));
                }
            }
            best.map(|(_, k)| k)
        })
        .collect())
}

/// Globally optimal assignment: the one-to-one pairing, within the gate, that minimises
/// the total distance plus `D` for every vehicle of either frame left unpaired.
///
/// Choice: with the no-match cost `D` per vehicle a pair (cost ≤ `D·√2 < 2D`) always beats
/// leaving both vehicles unpaired, so this is the minimum-distance matching of maximum
/// size inside the gate. Solved exactly on each connected component of the gate graph by
/// the crate's assignment solver ([`linear_sum_assignment`], shortest augmenting paths,
/// `O(c³)` for a component of `c` vehicles: fine for the paper's ~50 vehicles per pair, not
/// meant for the 100 000 of the scale benchmark). Among several optimal pairings (exact
/// ties only, e.g. integer positions) it returns the one SciPy's `linear_sum_assignment`
/// returns.
///
/// # Errors
/// From [`LabelGraph::new`]; a component larger than [`MAX_COMPONENT`].
pub fn optimal_assignment(
    frame1: &[Detection],
    frame2: &[Detection],
    gate_half_width_px: f64,
) -> Result<Vec<Option<usize>>> {
    let g = LabelGraph::new(&positions(frame1), &positions(frame2), gate_half_width_px)?;
    let miss = gate_half_width_px;
    assign_components(
        &g,
        &|e| dist(g.fwd_disp[e]),
        &|_| miss,
        &|_| miss,
        "optimal assignment",
    )
}

/// The minimum-cost one-to-one pairing on the labels of `g`: pair cost `pair_cost(e)` for
/// forward label `e`, `miss1(i)` for frame-1 vehicle `i` left unpaired, `miss2(k)` for
/// frame-2 vehicle `k`; solved exactly per connected component of the label graph.
/// Returns each frame-1 vehicle's partner (indices of `g`).
///
/// # Errors
/// A component larger than [`MAX_COMPONENT`] (`what` names the caller in the message).
pub(crate) fn assign_components(
    g: &LabelGraph,
    pair_cost: &dyn Fn(usize) -> f64,
    miss1: &dyn Fn(usize) -> f64,
    miss2: &dyn Fn(usize) -> f64,
    what: &str,
) -> Result<Vec<Option<usize>>> {
    let (m, n) = (g.m, g.n);
    // Union-find over frame-1 vehicles 0..m and frame-2 vehicles m..m+n.
    let mut parent: Vec<usize> = (0..m + n).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for i in 0..m {
        for e in g.fwd_range(i) {
            let (a, b) = (
                find(&mut parent, i),
                find(&mut parent, m + g.fwd_target[e] as usize),
            );
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut members: std::collections::BTreeMap<usize, (Vec<usize>, Vec<usize>)> =
        Default::default();
    for v in 0..m + n {
        let root = find(&mut parent, v);
        let entry = members.entry(root).or_default();
        if v < m {
            entry.0.push(v);
        } else {
            entry.1.push(v - m);
        }
    }
    let mut partner = vec![None; m];
    for (rows, cols) in members.values() {
        if rows.is_empty() || cols.is_empty() {
            continue;
        }
        let (a, b) = (rows.len(), cols.len());
        let size = a + b;
        if size > MAX_COMPONENT {
            return Err(crate::Error::Invalid(format!(
                "{what}: {size} vehicles are linked through their gates; the dense \
                 baseline handles at most {MAX_COMPONENT} per component"
            )));
        }
        let mut cost = vec![FORBIDDEN; size * size];
        let col_of: std::collections::HashMap<usize, usize> =
            cols.iter().enumerate().map(|(c, &k)| (k, c)).collect();
        for (r, &i) in rows.iter().enumerate() {
            for e in g.fwd_range(i) {
                let c = col_of[&(g.fwd_target[e] as usize)];
                cost[r * size + c] = pair_cost(e);
            }
            cost[r * size + b + r] = miss1(i); // a_i unpaired
        }
        for c in 0..b {
            cost[(a + c) * size + c] = miss2(cols[c]); // b_k unpaired
            for r in 0..a {
                cost[(a + c) * size + b + r] = 0.0; // dummy–dummy
            }
        }
        for (r, c) in linear_sum_assignment(&cost, size, size)? {
            if r < a && c < b && cost[r * size + c] < FORBIDDEN {
                partner[rows[r]] = Some(cols[c]);
            }
        }
    }
    Ok(partner)
}

/// Largest connected component (vehicles of both frames) the dense assignment accepts:
/// its matrix is `size²` values and the method `O(size³)`.
pub const MAX_COMPONENT: usize = 4096;

/// Cost of a forbidden pair: larger than any sum of allowed costs we build.
const FORBIDDEN: f64 = 1e15;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn at(id: u64, x: f64, y: f64) -> Detection {
        Detection::at(1, id, Point::new(x, y))
    }

    #[test]
    fn nearest_neighbour_may_share_a_partner_and_assignment_may_not() -> Result<()> {
        // a_0 (0,0), a_1 (30,0); b_0 (20,0), b_1 (100,0). NN: a_0 → b_0 (20), a_1 → b_0 (10).
        // Assignment: {a_0–b_0 20, a_1–b_1 70} = 90 vs {a_0–b_1 100, a_1–b_0 10} = 110:
        // a_0 → b_0, a_1 → b_1.
        let f1 = [at(1, 0.0, 0.0), at(2, 30.0, 0.0)];
        let f2 = [at(1, 20.0, 0.0), at(2, 100.0, 0.0)];
        assert_eq!(nearest_neighbour(&f1, &f2, 150.0)?, vec![Some(0), Some(0)]);
        assert_eq!(optimal_assignment(&f1, &f2, 150.0)?, vec![Some(0), Some(1)]);
        // Outside the gate nobody is paired.
        assert_eq!(optimal_assignment(&f1, &f2, 5.0)?, vec![None, None]);
        Ok(())
    }

    /// Every way to pair rows with distinct columns or nothing: the minimum of the
    /// objective of [`optimal_assignment`].
    fn brute_force(d: &[Vec<Option<f64>>], n: usize, miss: f64) -> f64 {
        fn go(r: usize, d: &[Vec<Option<f64>>], used: &mut Vec<bool>, miss: f64) -> f64 {
            if r == d.len() {
                return miss * used.iter().filter(|u| !**u).count() as f64;
            }
            let mut best = miss + go(r + 1, d, used, miss);
            for c in 0..used.len() {
                if let (false, Some(x)) = (used[c], d[r][c]) {
                    used[c] = true;
                    best = best.min(x + go(r + 1, d, used, miss));
                    used[c] = false;
                }
            }
            best
        }
        go(0, d, &mut vec![false; n], miss)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn assignment_reaches_the_brute_force_optimum(
            a in prop::collection::vec((0.0..200.0f64, 0.0..60.0f64), 0..5),
            b in prop::collection::vec((0.0..200.0f64, 0.0..60.0f64), 0..5),
        ) {
            let gate = 50.0;
            let f1: Vec<_> = a.iter().enumerate().map(|(i, &(x, y))| at(i as u64, x, y)).collect();
            let f2: Vec<_> = b.iter().enumerate().map(|(i, &(x, y))| at(i as u64, x, y)).collect();
            let got = optimal_assignment(&f1, &f2, gate).expect("assign");
            let mut used = vec![false; f2.len()];
            let mut total = 0.0;
            for (i, k) in got.iter().enumerate() {
                match k {
                    Some(k) => {
                        prop_assert!(!used[*k], "column used twice");
                        used[*k] = true;
                        let d = [f2[*k].pos_px.x - f1[i].pos_px.x, f2[*k].pos_px.y - f1[i].pos_px.y];
                        prop_assert!(super::super::labels::in_gate(d, gate));
                        total += dist(d);
                    }
                    None => total += gate,
                }
            }
            total += gate * used.iter().filter(|u| !**u).count() as f64;
            let d: Vec<Vec<Option<f64>>> = f1.iter().map(|p| f2.iter().map(|q| {
                let d = [q.pos_px.x - p.pos_px.x, q.pos_px.y - p.pos_px.y];
                super::super::labels::in_gate(d, gate).then(|| dist(d))
            }).collect()).collect();
            let best = brute_force(&d, f2.len(), gate);
            prop_assert!((total - best).abs() < 1e-6, "got {total}, optimum {best}");
        }
    }
}
