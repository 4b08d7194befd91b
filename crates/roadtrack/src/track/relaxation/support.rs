//! Neighbour support `P̂` and `Q̂` (METHODS.md §1 "Local consistency", eqs. 13–16).
//!
//! ```text
//! P̂_i(λ) = Σ_{j ∈ N_R(i)} Σ_{λ' ∈ L_j \ {λ_p}, |λ' − λ| ≤ T} P_j(λ')     (eqs. 13, 15, 16)
//! ```
//!
//! and `Q̂` the same over frame-2 neighbours and backward labels (eq. 14). The sets of
//! labels that support each label depend only on positions, `R` and `T`, never on the
//! probabilities, so they are found once ([`SupportLists::build`]) and every iteration is
//! a sparse sum over them ([`SupportLists::sums`]).
//!
//! Finding them without scanning every label pair: neighbours `N_R(i)` come from a uniform
//! grid over the frame's vehicles (cell `R`), sorted by index; each own label then tests
//! the neighbours' labels with eq. 15 directly (about 8 neighbours × 8 labels on a road
//! network: cheaper than bucketing displacements, which an earlier version did). Each list
//! comes out ascending by label index, so the sum runs in the same order as the naive
//! double loop ([`naive_support`]) and gives the same bits.

use super::grid::PointGrid;
use super::labels::PAR_BLOCK;
use crate::error::{Error, Result};
use crate::geometry::Point;
use rayon::prelude::*;

/// Eq. 16: whether `a` and `b` are neighbours (Euclidean distance ≤ `radius`).
pub fn within_radius(a: Point, b: Point, radius: f64) -> bool {
    let (dx, dy) = (a.x - b.x, a.y - b.y);
    dx * dx + dy * dy <= radius * radius
}

/// Eq. 15: whether two displacements are similar (Euclidean difference ≤ `t`).
pub fn similar(a: [f64; 2], b: [f64; 2], t: f64) -> bool {
    let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
    dx * dx + dy * dy <= t * t
}

/// Motion-compatible neighbourhood (ours, `RelaxationConfig::neighbour_lateral_px`):
/// whether a neighbour at `offset` (its position minus the vehicle's) may support the
/// vehicle's label `d`. A label longer than `t` (a moving vehicle) takes support only
/// from neighbours within `lateral` px of the line through the vehicle along `d` (the
/// same lane, ahead or behind); a label within `t` of zero (a stopped vehicle) from any
/// neighbour.
///
/// Choice: at an intersection a neighbour in the opposite lane or on a crossing arm moves
/// otherwise; the lane it drives in is the cheapest evidence of its flow that two frames
/// give, and queues (stopped) need no direction.
pub fn lateral_compatible(d: [f64; 2], offset: [f64; 2], t: f64, lateral: f64) -> bool {
    let len2 = d[0] * d[0] + d[1] * d[1];
    if len2 <= t * t {
        return true;
    }
    let cross = d[0] * offset[1] - d[1] * offset[0];
    cross * cross <= lateral * lateral * len2
}

/// For every label, the labels of neighbouring vehicles similar to it (compressed rows).
#[derive(Debug, Clone, PartialEq)]
pub struct SupportLists {
    /// Row starts, one per label plus one.
    pub start: Vec<u32>,
    /// Supporting label indices, each row ascending.
    pub items: Vec<u32>,
}

/// Per-thread scratch of the builder: the neighbours of one vehicle and their labels.
#[derive(Default)]
struct Scratch {
    neighbours: Vec<u32>,
    /// Displacements and indices of the neighbours' labels, ascending by label index.
    dx: Vec<f64>,
    dy: Vec<f64>,
    label: Vec<u32>,
    /// With a lateral limit: each label's owner minus the vehicle, px.
    offset: Vec<[f64; 2]>,
}

impl SupportLists {
    /// The support lists of one direction: vehicles at `owner`, their labels in rows
    /// `start` with displacements `disp`; neighbours within `radius_px` (R), similar within
    /// `similar_px` (T).
    ///
    /// For each vehicle, its neighbours (grid of cell `R`, then eq. 16 exactly) are sorted
    /// by index and their labels copied into one scratch list, which is ascending by label
    /// index because each vehicle's labels are one contiguous row; every label of the
    /// vehicle then tests that list with eq. 15 directly (about 8 neighbours × 8 labels
    /// on a road network, cheaper than bucketing them), so each support row comes out
    /// ascending without a sort.
    ///
    /// # Errors
    /// More than `u32::MAX` supporting entries in all.
    pub fn build(
        owner: &[Point],
        start: &[u32],
        disp: &[[f64; 2]],
        radius_px: f64,
        similar_px: f64,
    ) -> Result<Self> {
        Self::build_nearest(owner, start, disp, radius_px, similar_px, usize::MAX)
    }

    /// [`SupportLists::build`] with at most `max_neighbours` neighbours per vehicle: the
    /// nearest within `R` (ties to the lower index). With no more than `max_neighbours`
    /// vehicles within `R` of any vehicle this is exactly [`SupportLists::build`].
    ///
    /// # Errors
    /// As [`SupportLists::build`].
    // Choice: the support lists hold, per label, the similar labels of every neighbour, so
    // their size grows with the square of the density; the nearest neighbours carry the
    // local consistency of eq. 16, and capping them bounds memory and time.
    pub fn build_nearest(
        owner: &[Point],
        start: &[u32],
        disp: &[[f64; 2]],
        radius_px: f64,
        similar_px: f64,
        max_neighbours: usize,
    ) -> Result<Self> {
        Self::build_compatible(
            owner,
            start,
            disp,
            radius_px,
            similar_px,
            0.0,
            max_neighbours,
        )
    }

    /// [`SupportLists::build_nearest`] with the motion-compatible neighbourhood of
    /// [`lateral_compatible`] (`lateral_px`); with `lateral_px = 0` (off) exactly
    /// [`SupportLists::build_nearest`].
    ///
    /// # Errors
    /// As [`SupportLists::build`].
    pub fn build_compatible(
        owner: &[Point],
        start: &[u32],
        disp: &[[f64; 2]],
        radius_px: f64,
        similar_px: f64,
        lateral_px: f64,
        max_neighbours: usize,
    ) -> Result<Self> {
        let grid = PointGrid::new(owner.iter().copied(), radius_px.max(1.0));
        let t2 = similar_px * similar_px;
        let rows = owner.len();
        let block = |b: usize, s: &mut Scratch| -> (Vec<u32>, Vec<u32>) {
            let v0 = b * PAR_BLOCK;
            let v1 = ((b + 1) * PAR_BLOCK).min(rows);
            let mut counts = Vec::with_capacity((start[v1] - start[v0]) as usize);
            let mut items = Vec::new();
            for i in v0..v1 {
                let own = start[i] as usize..start[i + 1] as usize;
                if own.is_empty() {
                    continue;
                }
                let a = owner[i];
                s.neighbours.clear();
                grid.for_each_candidate(
                    a.x - radius_px,
                    a.y - radius_px,
                    a.x + radius_px,
                    a.y + radius_px,
                    |j| {
                        if j as usize != i && within_radius(a, owner[j as usize], radius_px) {
                            s.neighbours.push(j);
                        }
                    },
                );
                if s.neighbours.len() > max_neighbours && max_neighbours > 0 {
                    let d2 = |j: u32| {
                        let b = owner[j as usize];
                        (a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y)
                    };
                    s.neighbours
                        .select_nth_unstable_by(max_neighbours - 1, |&x, &y| {
                            d2(x).total_cmp(&d2(y)).then(x.cmp(&y))
                        });
                    s.neighbours.truncate(max_neighbours);
                } else if max_neighbours == 0 {
                    s.neighbours.clear();
                }
                s.neighbours.sort_unstable();
                s.dx.clear();
                s.dy.clear();
                s.label.clear();
                s.offset.clear();
                for &j in &s.neighbours {
                    let j = j as usize;
                    for e in start[j]..start[j + 1] {
                        let d = disp[e as usize];
                        s.dx.push(d[0]);
                        s.dy.push(d[1]);
                        s.label.push(e);
                        if lateral_px > 0.0 {
                            s.offset.push([owner[j].x - a.x, owner[j].y - a.y]);
                        }
                    }
                }
                for d in &disp[own] {
                    let before = items.len();
                    if lateral_px > 0.0 {
                        let it = s.dx.iter().zip(&s.dy).zip(&s.label).zip(&s.offset);
                        for (((&x, &y), &e2), &off) in it {
                            let (ex, ey) = (d[0] - x, d[1] - y);
                            if ex * ex + ey * ey <= t2
                                && lateral_compatible(*d, off, similar_px, lateral_px)
                            {
                                items.push(e2);
                            }
                        }
                    } else {
                        for ((&x, &y), &e2) in s.dx.iter().zip(&s.dy).zip(&s.label) {
                            // Eq. 15, the same arithmetic as [`similar`].
                            let (ex, ey) = (d[0] - x, d[1] - y);
                            if ex * ex + ey * ey <= t2 {
                                items.push(e2);
                            }
                        }
                    }
                    counts.push((items.len() - before) as u32);
                }
            }
            (counts, items)
        };
        let n_blocks = rows.div_ceil(PAR_BLOCK);
        let parts: Vec<(Vec<u32>, Vec<u32>)> = if n_blocks > 1 {
            (0..n_blocks)
                .into_par_iter()
                .map_init(Scratch::default, |s, b| block(b, s))
                .collect()
        } else {
            let mut s = Scratch::default();
            (0..n_blocks).map(|b| block(b, &mut s)).collect()
        };
        let total: usize = parts.iter().map(|p| p.1.len()).sum();
        if total >= u32::MAX as usize {
            return Err(Error::Invalid(format!(
                "{total} support entries exceed 2³² − 1; reduce R or T"
            )));
        }
        let mut out_start = Vec::with_capacity(disp.len() + 1);
        let mut out_items = Vec::with_capacity(total);
        out_start.push(0u32);
        for (counts, items) in parts {
            let mut at = out_items.len() as u32;
            for c in counts {
                at += c;
                out_start.push(at);
            }
            out_items.extend_from_slice(&items);
        }
        Ok(Self {
            start: out_start,
            items: out_items,
        })
    }

    /// Eqs. 13–14: the support of every label under probabilities `p` (real labels of the
    /// same direction), written into `out`.
    pub fn sums(&self, p: &[f64], out: &mut [f64]) {
        let one = |(e, o): (usize, &mut f64)| {
            let r = self.start[e] as usize..self.start[e + 1] as usize;
            *o = self.items[r].iter().map(|&x| p[x as usize]).sum();
        };
        const CHUNK: usize = 4 * PAR_BLOCK;
        if out.len() > CHUNK {
            out.par_chunks_mut(CHUNK)
                .enumerate()
                .for_each(|(c, chunk)| {
                    chunk
                        .iter_mut()
                        .enumerate()
                        .for_each(|(o, v)| one((c * CHUNK + o, v)));
                });
        } else {
            out.iter_mut().enumerate().for_each(one);
        }
    }

    /// Number of (label, supporting label) pairs.
    pub fn n_entries(&self) -> usize {
        self.items.len()
    }

    /// Heap bytes held.
    pub fn heap_bytes(&self) -> usize {
        4 * (self.start.capacity() + self.items.capacity())
    }
}

/// The naive O(labels²) reference of eqs. 13–16: for every label of every vehicle, every
/// other vehicle and every one of its labels. For tests and small problems.
pub fn naive_support(
    owner: &[Point],
    start: &[u32],
    disp: &[[f64; 2]],
    p: &[f64],
    radius_px: f64,
    similar_px: f64,
) -> Vec<f64> {
    let mut out = vec![0.0; disp.len()];
    for i in 0..owner.len() {
        for e in start[i] as usize..start[i + 1] as usize {
            let mut s = 0.0;
            for j in 0..owner.len() {
                if j == i || !within_radius(owner[i], owner[j], radius_px) {
                    continue;
                }
                for e2 in start[j] as usize..start[j + 1] as usize {
                    if similar(disp[e], disp[e2], similar_px) {
                        s += p[e2];
                    }
                }
            }
            out[e] = s;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::labels::LabelGraph;
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn support_matches_a_hand_computation() -> Result<()> {
        // Frame 1: a_0 (0,0), a_1 (50,0), a_2 (400,0) (too far from both: R = 200).
        // Frame 2: b_0 (20,0), b_1 (70,0), b_2 (75,5). Gate D = 150, T = 20.
        // Labels: a_0 → b_0 (20,0), b_1 (70,0), b_2 (75,5)
        //         a_1 → b_0 (−30,0), b_1 (20,0), b_2 (25,5)
        //         a_2 → none in the gate.
        let p = [
            Point::new(0.0, 0.0),
            Point::new(50.0, 0.0),
            Point::new(400.0, 0.0),
        ];
        let q = [
            Point::new(20.0, 0.0),
            Point::new(70.0, 0.0),
            Point::new(75.0, 5.0),
        ];
        let g = LabelGraph::new(&p, &q, 150.0)?;
        assert_eq!(g.fwd_start, vec![0, 3, 6, 6]);
        // Probabilities of the real labels (any numbers; rows need not sum to 1 here).
        let prob = [0.1, 0.2, 0.3, 0.05, 0.4, 0.25];
        let lists = SupportLists::build(&p, &g.fwd_start, &g.fwd_disp, 200.0, 20.0)?;
        let mut s = vec![0.0; 6];
        lists.sums(&prob, &mut s);
        // P̂_0(20,0): labels of a_1 within 20 of (20,0): (20,0) d=0 ✓, (25,5) d=√50 ✓,
        //   (−30,0) d=50 ✗  →  0.4 + 0.25 = 0.65
        // P̂_0(70,0): (20,0) d=50 ✗, (25,5) d=√2050 ✗ → 0
        // P̂_0(75,5): 0
        // P̂_1(−30,0): labels of a_0: (20,0) d=50 ✗ … → 0
        // P̂_1(20,0): (20,0) ✓ 0.1, (70,0) d=50 ✗, (75,5) ✗ → 0.1
        // P̂_1(25,5): (20,0) d=√50 ✓ 0.1 → 0.1
        let expect = [0.65, 0.0, 0.0, 0.0, 0.1, 0.1];
        for (a, b) in s.iter().zip(expect) {
            assert!((a - b).abs() < 1e-12, "{s:?}");
        }
        assert_eq!(lists.items, vec![4, 5, 0, 0]);
        Ok(())
    }

    #[test]
    fn nearest_neighbours_bound_the_lists_and_change_nothing_below_the_bound() -> Result<()> {
        // 300 vehicles in a 60 px square, all neighbours of each other, one label each.
        let p: Vec<Point> = (0..300u64)
            .map(|i| Point::new((i * 37 % 60) as f64, (i * 53 % 61) as f64))
            .collect();
        let q: Vec<Point> = p.iter().map(|a| Point::new(a.x + 2.0, a.y)).collect();
        let g = LabelGraph::nearest(&p, &q, 150.0, 1)?;
        // T = 100 px: every label supports every other.
        let all = SupportLists::build(&p, &g.fwd_start, &g.fwd_disp, 200.0, 100.0)?;
        let n = g.n_labels();
        assert_eq!(all.n_entries(), n * (n - 1));
        let capped = SupportLists::build_nearest(&p, &g.fwd_start, &g.fwd_disp, 200.0, 100.0, 5)?;
        assert!(capped.n_entries() <= 5 * n, "{}", capped.n_entries());
        assert!(capped.n_entries() > 0);
        let same = SupportLists::build_nearest(&p, &g.fwd_start, &g.fwd_disp, 200.0, 100.0, 299)?;
        assert_eq!(same, all);
        Ok(())
    }

    #[test]
    fn a_moving_label_takes_support_from_its_lane_only() -> Result<()> {
        // a_0 (0,0) and a_1 (60,0) in one lane, a_2 (30,12) in the next lane; every
        // vehicle moves (20,0): b_k = a_k + (20,0). T = 5, lateral 4 px.
        let p = [
            Point::new(0.0, 0.0),
            Point::new(60.0, 0.0),
            Point::new(30.0, 12.0),
        ];
        let q: Vec<Point> = p.iter().map(|a| Point::new(a.x + 20.0, a.y)).collect();
        let g = LabelGraph::new(&p, &q, 25.0)?;
        // a_0's labels: b_0 (20,0) only (b_2 is (50,12): outside D = 25).
        assert_eq!(g.fwd_range(0).len(), 1);
        let all = SupportLists::build(&p, &g.fwd_start, &g.fwd_disp, 200.0, 5.0)?;
        let lane =
            SupportLists::build_compatible(&p, &g.fwd_start, &g.fwd_disp, 200.0, 5.0, 4.0, 8)?;
        let supporters = |l: &SupportLists, e: usize| -> Vec<u32> {
            let r = l.start[e] as usize..l.start[e + 1] as usize;
            l.items[r]
                .iter()
                .map(|&x| g.fwd_target[x as usize])
                .collect()
        };
        // Eq. 16: a_1 and a_2 both support a_0's (20,0); in its lane only a_1 does.
        assert_eq!(supporters(&all, 0), vec![1, 2]);
        assert_eq!(supporters(&lane, 0), vec![1]);
        // A label within T of zero (a queued vehicle) keeps every neighbour.
        assert!(lateral_compatible([3.0, 0.0], [0.0, 50.0], 5.0, 4.0));
        assert!(!lateral_compatible([30.0, 0.0], [0.0, 50.0], 5.0, 4.0));
        assert!(lateral_compatible([30.0, 0.0], [-80.0, 3.9], 5.0, 4.0));
        // Lateral 0 is off: exactly the paper's lists.
        let off =
            SupportLists::build_compatible(&p, &g.fwd_start, &g.fwd_disp, 200.0, 5.0, 0.0, 8)?;
        assert_eq!(
            off,
            SupportLists::build_nearest(&p, &g.fwd_start, &g.fwd_disp, 200.0, 5.0, 8)?
        );
        Ok(())
    }

    fn scene() -> impl Strategy<Value = (Vec<Point>, Vec<Point>, Vec<f64>, f64, f64, f64)> {
        (
            prop::collection::vec((0.0..600.0f64, 0.0..300.0f64), 0..40),
            prop::collection::vec((0.0..600.0f64, 0.0..300.0f64), 0..40),
            prop::collection::vec(0.0..1.0f64, 2000),
            10.0..200.0f64,
            0.0..60.0f64,
            20.0..300.0f64,
        )
            .prop_map(|(a, b, pr, d, t, r)| {
                let pt = |v: Vec<(f64, f64)>| {
                    // Round to a 5 px lattice so exact ties of eqs. 15–16 occur.
                    v.into_iter()
                        .map(|(x, y)| Point::new((x / 5.0).round() * 5.0, (y / 5.0).round() * 5.0))
                        .collect()
                };
                (pt(a), pt(b), pr, d, (t / 5.0).round() * 5.0, r)
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The grid and the direct label comparison find exactly the naive double loop's terms,
        /// summed in the same order: identical bits.
        #[test]
        fn grid_support_equals_the_naive_reference((p, q, prob, d, t, r) in scene()) {
            let g = LabelGraph::new(&p, &q, d).expect("graph");
            let probs = &prob[..g.n_labels().min(prob.len())];
            prop_assume!(probs.len() == g.n_labels());
            for (owner, start, disp) in [(&p, &g.fwd_start, &g.fwd_disp), (&q, &g.bwd_start, &g.bwd_disp)] {
                let lists = SupportLists::build(owner, start, disp, r, t).expect("lists");
                let mut fast = vec![0.0; disp.len()];
                lists.sums(probs, &mut fast);
                let slow = naive_support(owner, start, disp, probs, r, t);
                prop_assert_eq!(fast, slow);
            }
        }
    }
}
