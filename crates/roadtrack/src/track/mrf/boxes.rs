//! Detector boxes on the Object-map (docs/MRF.md "Detections"; issue 13 item 6): objects
//! are started and split from the boxes, while Steps 1–5 (block matching, propagation,
//! the Gibbs sampler on eq. 5) carry the ids from frame to frame.
//!
//! After the sampler has decided `X(t)`, the boxes of frame `t` are matched one-to-one to
//! objects by their blocks (block IoU), where each object was expected (box IoU and centre
//! distance) and, optionally, their colours (Hungarian or greedy); a box that no object claims
//! starts an object with the blocks it covers — this also splits a region that the boxes
//! show to be several objects: the largest part keeps the region's id, the others get new
//! ones. An object the boxes no longer find keeps its blocks (the Object-map tracks it
//! between detections) until it has been missed too long.

use super::object_map::{BLOCK_PX, BlockGrid, NO_OBJECT, ObjectId};
use crate::geometry::BBox;
use std::collections::BTreeMap;

/// Blocks of `grid` whose centre lies inside `b`; when there is none (a box smaller than a
/// block), the block holding the box centre, if it lies on the grid.
// Choice: a block belongs to a box by its centre, so a box of `w × h` px covers about
// `w·h / 64` blocks whatever its position, and two boxes side by side share no block.
pub fn box_cover(grid: &BlockGrid, b: &BBox) -> Vec<usize> {
    let bp = f64::from(BLOCK_PX);
    let first = |lo: f64| ((lo / bp) - 0.5).ceil().max(0.0);
    let last = |hi: f64, n: u32| (((hi / bp) - 0.5).floor()).min(f64::from(n) - 1.0);
    let (x0, x1) = (first(b.left), last(b.right(), grid.cols));
    let (y0, y1) = (first(b.top), last(b.bottom(), grid.rows));
    let mut out = Vec::new();
    if x0 <= x1 && y0 <= y1 {
        for by in y0 as u32..=y1 as u32 {
            for bx in x0 as u32..=x1 as u32 {
                out.push(grid.index(bx, by));
            }
        }
    }
    if out.is_empty() {
        let c = b.centre();
        if c.x >= 0.0
            && c.y >= 0.0
            && let Some((bx, by)) = grid.blocks_from_px(c.x as u32, c.y as u32)
        {
            out.push(grid.index(bx, by));
        }
    }
    out
}

/// Which blocks the boxes of a frame cover: `covered[i]` is true when block `i` lies in
/// some box.
pub fn covered_blocks(grid: &BlockGrid, boxes: &[BBox]) -> Vec<bool> {
    let mut covered = vec![false; grid.len()];
    for b in boxes {
        for i in box_cover(grid, b) {
            covered[i] = true;
        }
    }
    covered
}

/// How a box and an object are scored ([`apply_boxes`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights {
    /// Weight of the block IoU beside the expected box's IoU (weight 1).
    pub block_iou: f64,
    /// Smallest expected-box IoU that lets an object whose blocks the box does not cover
    /// take the box.
    pub revive_iou: f64,
    /// Weight of the centre-distance term `max(0, 1 − d / gate)` (`d`: distance of the box
    /// centre from the expected box's centre); 0 = off (the scoring before issue 14).
    pub distance: f64,
    /// Gate of the distance term, px: `max(gate_px, gate_width_factor · box width)`. An
    /// object within the gate of a box is a candidate for it even when neither its blocks
    /// nor its expected box overlap the box.
    pub gate_px: f64,
    /// See `gate_px`.
    pub gate_width_factor: f64,
    /// Optimal (Hungarian, maximum total score) instead of greedy one-to-one matching.
    pub optimal: bool,
    /// Lowest total score (the terms above plus `extra`) at which a box may continue an
    /// object; 0 = any candidate pair may match.
    pub min_score: f64,
}

impl Weights {
    /// The scoring before issue 14: block IoU (0.25) and expected-box IoU, greedy.
    pub const GREEDY_IOU: Weights = Weights {
        block_iou: 0.25,
        revive_iou: 0.3,
        distance: 0.0,
        gate_px: 0.0,
        gate_width_factor: 0.0,
        optimal: false,
        min_score: 0.0,
    };

    /// The distance gate for a box of width `width`, px.
    fn gate(&self, width: f64) -> f64 {
        self.gate_px.max(self.gate_width_factor * width)
    }
}

/// How one box of the frame was resolved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoxOutcome {
    /// It covers most of an existing object's blocks: that object.
    Matched(ObjectId),
    /// No object's blocks claimed it, but it overlaps where a tracked object was expected
    /// (`revivable`): that object takes it back.
    Revived(ObjectId),
    /// A new object (started, or split off a region covering several boxes).
    Started(ObjectId),
}

impl BoxOutcome {
    /// The object the box now belongs to.
    pub fn id(self) -> ObjectId {
        match self {
            BoxOutcome::Matched(id) | BoxOutcome::Revived(id) | BoxOutcome::Started(id) => id,
        }
    }
}

/// Matches the boxes of a frame to the objects of `ids` (`X(t)` after the sampler) and
/// rewrites `ids`: every block a box covers takes that box's object; blocks of a matched
/// object that no box covers are cleared; the blocks of unmatched objects are kept.
///
/// `revivable`: tracked objects with their expected box in this frame. A box and an object
/// are scored by `weights.block_iou` × the block IoU of the box's blocks and the object's,
/// plus the IoU of the box and the object's expected box; an object whose blocks the box
/// does not cover at all is a candidate only when that box IoU reaches
/// `weights.revive_iou` or the box lies within its distance gate. `extra(box, id)` is added
/// to every candidate's score (the appearance term); where it is `None` the box may not
/// continue that object (the class gate). A pair whose total score is under
/// `weights.min_score` is not a candidate. New objects take `*next_id` onwards.
///
/// Returns one outcome per box, in the boxes' order.
// Choice: one-to-one matching, by default of maximum total score (Hungarian; greedy by
// descending score, ties lower box index then lower id, with `weights.optimal` off) — the
// box that covers most of a region keeps its id; a second box over the same region starts
// a new object: that is how a group is split. The centre-distance term and its gate (issue
// 14) let a box narrower than a block follow its object when neither the blocks nor the
// expected box overlap it any more (numbers at `MrfConfig::default`). The expected box's IoU is added
// because blocks are coarse: two pedestrians 5 px wide walking side by side share one
// block column, so the block IoU alone cannot say which box is whose (seed 1, block IoU
// alone: HOTA 0.46 / 0.53 on intersection / crossing; with the box IoU and weight 0.25 on
// blocks, see docs/MRF.md "Detections").
// Choice: a block covered by two boxes keeps its id if that id is one of the two boxes'
// objects (eq. 5 decided it in the sampler, e.g. which of two overlapping objects is in
// front); otherwise it goes to the box whose centre is nearest in units of the box size.
// Choice: with `weights.min_score` a box whose best pair scores under it starts a new
// object instead of continuing one: without it, an object that lost its boxes takes any box
// within its gate that no other object claims, however far from where it was expected and
// however unlike it in colour (a queued car's id onto a car passing in front, a walker's
// onto the next walker in). Numbers at `MrfConfig::min_match_score`.
// Choice: a matched object's blocks outside every box are cleared: with a box for the
// object, blocks outside it are background or a neighbour's texture dragged along.
pub fn apply_boxes(
    ids: &mut [ObjectId],
    grid: &BlockGrid,
    boxes: &[BBox],
    revivable: &[(ObjectId, BBox)],
    weights: Weights,
    extra: &dyn Fn(usize, ObjectId) -> Option<f64>,
    next_id: &mut ObjectId,
) -> Vec<BoxOutcome> {
    let covers: Vec<Vec<usize>> = boxes.iter().map(|b| box_cover(grid, b)).collect();
    let mut area: BTreeMap<ObjectId, u32> = BTreeMap::new();
    for &id in ids.iter() {
        if id != NO_OBJECT {
            *area.entry(id).or_insert(0) += 1;
        }
    }
    let expected: BTreeMap<ObjectId, BBox> = revivable.iter().copied().collect();
    // (score, box, id, shares blocks), best first.
    let mut pairs: Vec<(f64, usize, ObjectId, bool)> = Vec::new();
    for (j, cover) in covers.iter().enumerate() {
        let mut hist: BTreeMap<ObjectId, u32> = BTreeMap::new();
        for &b in cover {
            if ids[b] != NO_OBJECT {
                *hist.entry(ids[b]).or_insert(0) += 1;
            }
        }
        let box_iou = |id: ObjectId| expected.get(&id).map_or(0.0, |e| boxes[j].iou(e));
        let gate = weights.gate(boxes[j].width);
        let closeness = |id: ObjectId| {
            expected.get(&id).map_or(0.0, |e| {
                let d = boxes[j].centre().distance(e.centre());
                if weights.distance > 0.0 && gate > 0.0 {
                    (1.0 - d / gate).max(0.0)
                } else {
                    0.0
                }
            })
        };
        for (&id, &inter) in &hist {
            let Some(extra) = extra(j, id) else {
                continue;
            };
            let union = cover.len() as u32 + area[&id] - inter;
            let block_iou = f64::from(inter) / f64::from(union.max(1));
            let s = weights.block_iou * block_iou
                + box_iou(id)
                + weights.distance * closeness(id)
                + extra;
            pairs.push((s, j, id, true));
        }
        for &id in expected.keys() {
            let iou = box_iou(id);
            let near = closeness(id);
            if !hist.contains_key(&id)
                && (iou >= weights.revive_iou || near > 0.0)
                && let Some(extra) = extra(j, id)
            {
                pairs.push((iou + weights.distance * near + extra, j, id, false));
            }
        }
    }
    pairs.retain(|p| p.0 >= weights.min_score);
    let chosen = if weights.optimal {
        optimal_pairs(&pairs, boxes.len())
    } else {
        greedy_pairs(pairs)
    };
    let mut outcome: Vec<Option<BoxOutcome>> = vec![None; boxes.len()];
    let mut taken: BTreeMap<ObjectId, usize> = BTreeMap::new();
    for (j, id, shares) in chosen {
        outcome[j] = Some(if shares {
            BoxOutcome::Matched(id)
        } else {
            BoxOutcome::Revived(id)
        });
        taken.insert(id, j);
    }
    let outcome: Vec<BoxOutcome> = outcome
        .into_iter()
        .map(|o| {
            o.unwrap_or_else(|| {
                let id = *next_id;
                *next_id += 1;
                BoxOutcome::Started(id)
            })
        })
        .collect();
    // The new map, from the old one.
    let mut owners: Vec<Vec<usize>> = vec![Vec::new(); grid.len()];
    for (j, cover) in covers.iter().enumerate() {
        for &b in cover {
            owners[b].push(j);
        }
    }
    let bp = f64::from(BLOCK_PX);
    let mut next = ids.to_vec();
    for (b, owner) in owners.iter().enumerate() {
        let old = ids[b];
        next[b] = match owner.as_slice() {
            [] if taken.contains_key(&old) => NO_OBJECT,
            [] => old,
            [j] => outcome[*j].id(),
            several => {
                if let Some(&j) = several.iter().find(|&&j| outcome[j].id() == old) {
                    outcome[j].id()
                } else {
                    let (bx, by) = grid.coords(b);
                    let (cx, cy) = ((f64::from(bx) + 0.5) * bp, (f64::from(by) + 0.5) * bp);
                    let d = |j: usize| {
                        let c = boxes[j].centre();
                        let (w, h) = (boxes[j].width.max(1.0), boxes[j].height.max(1.0));
                        ((cx - c.x) / w).powi(2) + ((cy - c.y) / h).powi(2)
                    };
                    let j = several
                        .iter()
                        .copied()
                        .min_by(|&a, &b| d(a).total_cmp(&d(b)).then(a.cmp(&b)))
                        .unwrap_or(several[0]);
                    outcome[j].id()
                }
            }
        };
    }
    ids.copy_from_slice(&next);
    outcome
}

/// Greedy one-to-one matching by descending score (ties: lower box index, then lower id).
fn greedy_pairs(mut pairs: Vec<(f64, usize, ObjectId, bool)>) -> Vec<(usize, ObjectId, bool)> {
    pairs.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut box_done = std::collections::BTreeSet::new();
    let mut id_done = std::collections::BTreeSet::new();
    let mut out = Vec::new();
    for (_, j, id, shares) in pairs {
        if !box_done.contains(&j) && !id_done.contains(&id) {
            box_done.insert(j);
            id_done.insert(id);
            out.push((j, id, shares));
        }
    }
    out
}

/// One-to-one matching of maximum total score over the candidate pairs (Hungarian,
/// [`crate::assignment::max_score_assignment`]); pairs that are not candidates score 0 and
/// are never chosen.
fn optimal_pairs(
    pairs: &[(f64, usize, ObjectId, bool)],
    n_boxes: usize,
) -> Vec<(usize, ObjectId, bool)> {
    let ids: Vec<ObjectId> = {
        let set: std::collections::BTreeSet<ObjectId> = pairs.iter().map(|p| p.2).collect();
        set.into_iter().collect()
    };
    if ids.is_empty() || n_boxes == 0 {
        return Vec::new();
    }
    let col = |id: ObjectId| ids.binary_search(&id).unwrap_or(0);
    let mut score = vec![0.0; n_boxes * ids.len()];
    let mut shares = vec![false; n_boxes * ids.len()];
    for &(s, j, id, sh) in pairs {
        // Choice: every candidate scores at least a small positive amount, so a candidate
        // pair is always preferred to leaving both unmatched.
        score[j * ids.len() + col(id)] = s.max(1e-6);
        shares[j * ids.len() + col(id)] = sh;
    }
    crate::assignment::max_score_assignment(&score, n_boxes, ids.len())
        .unwrap_or_default()
        .into_iter()
        .filter(|&(j, c)| score[j * ids.len() + c] > 0.0)
        .map(|(j, c)| (j, ids[c], shares[j * ids.len() + c]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `apply_boxes` without appearance or class gate.
    fn apply(
        ids: &mut [ObjectId],
        grid: &BlockGrid,
        boxes: &[BBox],
        revivable: &[(ObjectId, BBox)],
        weights: Weights,
        next_id: &mut ObjectId,
    ) -> Vec<BoxOutcome> {
        apply_boxes(
            ids,
            grid,
            boxes,
            revivable,
            weights,
            &|_, _| Some(0.0),
            next_id,
        )
    }

    const W: Weights = Weights::GREEDY_IOU;

    fn grid() -> BlockGrid {
        BlockGrid::for_frame(160, 160) // 20 × 20
    }

    fn fill(
        ids: &mut [ObjectId],
        g: &BlockGrid,
        x: std::ops::Range<u32>,
        y: std::ops::Range<u32>,
        id: ObjectId,
    ) {
        for by in y {
            for bx in x.clone() {
                ids[g.index(bx, by)] = id;
            }
        }
    }

    #[test]
    fn a_box_covers_the_blocks_whose_centre_it_holds() {
        let g = grid();
        // Block centres at 4, 12, 20, …: x 10..30 holds 12, 20, 28 → blocks 1, 2, 3.
        let c = box_cover(&g, &BBox::new(10.0, 0.0, 20.0, 9.0));
        assert_eq!(c, vec![g.index(1, 0), g.index(2, 0), g.index(3, 0)]);
        // A box smaller than a block: the block of its centre.
        assert_eq!(
            box_cover(&g, &BBox::new(41.0, 41.0, 3.0, 3.0)),
            vec![g.index(5, 5)]
        );
        // Off the grid: nothing.
        assert!(box_cover(&g, &BBox::new(500.0, 500.0, 3.0, 3.0)).is_empty());
    }

    #[test]
    fn a_box_over_unlabelled_blocks_starts_an_object_with_them() {
        let g = grid();
        let mut ids = vec![NO_OBJECT; g.len()];
        fill(&mut ids, &g, 2..5, 2..5, 7);
        let mut next = 10;
        let out = apply(
            &mut ids,
            &g,
            &[
                BBox::new(16.0, 16.0, 24.0, 24.0),
                BBox::new(96.0, 96.0, 16.0, 16.0),
            ],
            &[],
            W,
            &mut next,
        );
        assert_eq!(out, vec![BoxOutcome::Matched(7), BoxOutcome::Started(10)]);
        assert_eq!(ids[g.index(12, 12)], 10);
        assert_eq!(ids.iter().filter(|&&i| i == 10).count(), 4);
        assert_eq!(next, 11);
    }

    #[test]
    fn two_boxes_over_one_region_split_it_and_the_larger_part_keeps_the_id() {
        let g = grid();
        let mut ids = vec![NO_OBJECT; g.len()];
        // One region of 6 × 3 blocks holding two objects side by side.
        fill(&mut ids, &g, 4..10, 4..7, 3);
        let mut next = 4;
        let left = BBox::new(32.0, 32.0, 16.0, 24.0); // 2 × 3 blocks
        let right = BBox::new(48.0, 32.0, 32.0, 24.0); // 4 × 3 blocks
        let out = apply(&mut ids, &g, &[left, right], &[], W, &mut next);
        assert_eq!(out, vec![BoxOutcome::Started(4), BoxOutcome::Matched(3)]);
        assert_eq!(ids.iter().filter(|&&i| i == 4).count(), 6);
        assert_eq!(ids.iter().filter(|&&i| i == 3).count(), 12);
        assert_eq!(ids[g.index(5, 5)], 4);
    }

    #[test]
    fn an_unmatched_object_keeps_its_blocks_and_a_matched_one_loses_those_outside_its_box() {
        let g = grid();
        let mut ids = vec![NO_OBJECT; g.len()];
        fill(&mut ids, &g, 2..6, 2..4, 1); // matched, with a tail outside its box
        fill(&mut ids, &g, 12..14, 12..14, 2); // no box this frame
        let mut next = 3;
        let out = apply(
            &mut ids,
            &g,
            &[BBox::new(16.0, 16.0, 16.0, 16.0)],
            &[],
            W,
            &mut next,
        );
        assert_eq!(out, vec![BoxOutcome::Matched(1)]);
        assert_eq!(ids.iter().filter(|&&i| i == 1).count(), 4);
        assert_eq!(ids[g.index(5, 3)], NO_OBJECT);
        assert_eq!(ids.iter().filter(|&&i| i == 2).count(), 4);
    }

    #[test]
    fn a_box_where_a_lost_object_was_expected_takes_it_back() {
        let g = grid();
        let mut ids = vec![NO_OBJECT; g.len()];
        let b = BBox::new(80.0, 80.0, 24.0, 16.0);
        let mut next = 9;
        let out = apply(
            &mut ids,
            &g,
            &[b],
            &[(5, BBox::new(82.0, 80.0, 24.0, 16.0))],
            W,
            &mut next,
        );
        assert_eq!(out, vec![BoxOutcome::Revived(5)]);
        assert_eq!(ids.iter().filter(|&&i| i == 5).count(), 6);
        assert_eq!(next, 9);
        // Too far from where it was expected: a new object.
        let mut ids = vec![NO_OBJECT; g.len()];
        let out = apply(
            &mut ids,
            &g,
            &[b],
            &[(5, BBox::new(120.0, 80.0, 24.0, 16.0))],
            W,
            &mut next,
        );
        assert_eq!(out, vec![BoxOutcome::Started(9)]);
    }

    #[test]
    fn a_block_in_two_boxes_keeps_the_id_the_sampler_gave_it() {
        let g = grid();
        let mut ids = vec![NO_OBJECT; g.len()];
        fill(&mut ids, &g, 2..5, 2..4, 1);
        fill(&mut ids, &g, 5..8, 2..4, 2);
        // Box of 1: blocks 2..6 (overlapping 2's first column); box of 2: blocks 5..8.
        let b1 = BBox::new(16.0, 16.0, 32.0, 16.0);
        let b2 = BBox::new(40.0, 16.0, 24.0, 16.0);
        let mut next = 3;
        let out = apply(&mut ids, &g, &[b1, b2], &[], W, &mut next);
        assert_eq!(out, vec![BoxOutcome::Matched(1), BoxOutcome::Matched(2)]);
        assert_eq!(ids[g.index(5, 2)], 2, "the shared column stays with 2");
        // Unlabelled shared blocks go to the nearer box centre.
        let mut ids = vec![NO_OBJECT; g.len()];
        fill(&mut ids, &g, 2..4, 2..4, 1);
        fill(&mut ids, &g, 6..8, 2..4, 2);
        let out = apply(&mut ids, &g, &[b1, b2], &[], W, &mut next);
        assert_eq!(out, vec![BoxOutcome::Matched(1), BoxOutcome::Matched(2)]);
        assert_eq!(ids[g.index(4, 2)], 1);
        assert_eq!(ids[g.index(5, 2)], 2);
    }

    const NEW: Weights = Weights {
        block_iou: 0.25,
        revive_iou: 0.3,
        distance: 2.0,
        gate_px: 8.0,
        gate_width_factor: 1.0,
        optimal: true,
        min_score: 0.0,
    };

    #[test]
    fn a_small_box_near_where_its_object_was_expected_is_matched_within_the_gate() {
        let g = grid();
        // A 5 × 7 px pedestrian expected 4 px to the left: box IoU 0.11, no shared block.
        let b = BBox::new(84.0, 80.0, 5.0, 7.0);
        let expected = [(5, BBox::new(80.0, 80.0, 5.0, 7.0))];
        let mut next = 9;
        let mut ids = vec![NO_OBJECT; g.len()];
        let out = apply(&mut ids, &g, &[b], &expected, NEW, &mut next);
        assert_eq!(out, vec![BoxOutcome::Revived(5)]);
        // Without the distance term (the matching before issue 14): a new object.
        let mut ids = vec![NO_OBJECT; g.len()];
        let out = apply(&mut ids, &g, &[b], &expected, W, &mut next);
        assert_eq!(out, vec![BoxOutcome::Started(9)]);
        // Beyond the gate (max(8 px, 5 px)): a new object either way.
        let far = BBox::new(89.0, 80.0, 5.0, 7.0);
        let mut ids = vec![NO_OBJECT; g.len()];
        let out = apply(&mut ids, &g, &[far], &expected, NEW, &mut next);
        assert_eq!(out, vec![BoxOutcome::Started(10)]);
    }

    #[test]
    fn a_pair_under_the_lowest_score_starts_a_new_object() {
        let g = grid();
        // A 5 × 7 px box 6 px right of where object 5 was expected: no shared block, box
        // IoU 0, within the gate (8 px): score 2 · (1 − 6 / 8) = 0.5.
        let b = BBox::new(86.0, 80.0, 5.0, 7.0);
        let expected = [(5, BBox::new(80.0, 80.0, 5.0, 7.0))];
        let run = |min_score: f64, looks: f64, next: &mut ObjectId| {
            let mut ids = vec![NO_OBJECT; g.len()];
            let w = Weights { min_score, ..NEW };
            apply_boxes(&mut ids, &g, &[b], &expected, w, &|_, _| Some(looks), next)
        };
        let mut next = 9;
        assert_eq!(run(0.0, 0.0, &mut next), vec![BoxOutcome::Revived(5)]);
        assert_eq!(run(0.4, 0.0, &mut next), vec![BoxOutcome::Revived(5)]);
        assert_eq!(run(1.0, 0.0, &mut next), vec![BoxOutcome::Started(9)]);
        // The same box looking like the object (appearance term 0.6): 1.1, it continues it.
        assert_eq!(run(1.0, 0.6, &mut next), vec![BoxOutcome::Revived(5)]);
        // A box covering the object's blocks is held to the same floor.
        let mut ids = vec![NO_OBJECT; g.len()];
        fill(&mut ids, &g, 2..5, 2..5, 7);
        let w = Weights {
            min_score: 1.0,
            ..NEW
        };
        let big = BBox::new(16.0, 16.0, 96.0, 96.0); // 12 × 12 blocks over object 7's 3 × 3
        let out = apply(&mut ids, &g, &[big], &[], w, &mut next);
        assert_eq!(out, vec![BoxOutcome::Started(10)]);
        let mut ids = vec![NO_OBJECT; g.len()];
        fill(&mut ids, &g, 2..5, 2..5, 7);
        let out = apply(&mut ids, &g, &[big], &[], NEW, &mut next);
        assert_eq!(out, vec![BoxOutcome::Matched(7)]);
    }

    #[test]
    fn optimal_matching_maximises_the_total_where_greedy_takes_the_best_pair_first() {
        // Box 0 fits object 1 best (0.9) but also object 2 (0.8); box 1 fits only object 1.
        let pairs = vec![(0.9, 0, 1, false), (0.8, 0, 2, false), (0.7, 1, 1, false)];
        let mut greedy = greedy_pairs(pairs.clone());
        greedy.sort();
        assert_eq!(greedy, vec![(0, 1, false)]);
        let mut optimal = optimal_pairs(&pairs, 2);
        optimal.sort();
        assert_eq!(optimal, vec![(0, 2, false), (1, 1, false)]);
    }

    #[test]
    fn the_appearance_term_decides_between_two_equally_near_objects() {
        let g = grid();
        let b = BBox::new(80.0, 80.0, 5.0, 7.0);
        // Two objects expected 2 px left and 2 px right of the box.
        let expected = [
            (1, BBox::new(78.0, 80.0, 5.0, 7.0)),
            (2, BBox::new(82.0, 80.0, 5.0, 7.0)),
        ];
        let mut next = 3;
        let looks = |_: usize, id: ObjectId| Some(if id == 2 { 1.0 } else { 0.0 });
        let mut ids = vec![NO_OBJECT; g.len()];
        let out = apply_boxes(&mut ids, &g, &[b], &expected, NEW, &looks, &mut next);
        assert_eq!(out, vec![BoxOutcome::Revived(2)]);
        let mut ids = vec![NO_OBJECT; g.len()];
        let out = apply(&mut ids, &g, &[b], &expected, NEW, &mut next);
        assert!(matches!(out[..], [BoxOutcome::Revived(1 | 2)]), "{out:?}");
    }
}
