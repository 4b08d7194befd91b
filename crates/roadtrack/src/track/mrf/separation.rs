//! Fig. 10 of seed 002 in the MRF tracker's terms: for every occluded object and frame,
//! its visible area in blocks against whether it still came out as a region of its own
//! (METHODS.md §2 "Measure").
//!
//! The paper counts a success when the object's region exists in the output, however
//! small, and a failure when it was absorbed by a neighbouring object's region; front and
//! back objects are counted alike. The judgement and the curve are the evaluation's
//! ([`crate::eval::papers::separated_objects`] with [`SeparationRule::OwnRegion`],
//! [`crate::eval::papers::separation_success`]); this module supplies the truth on the
//! tracker's block grid ([`TruthRegion`], [`truth_regions_from_owner`]) and turns truth and
//! object maps into their inputs ([`separated`], [`occlusion_rows`]):
//!
//! - an output id *belongs to* the truth object whose visible blocks it overlaps most (ties:
//!   the smaller truth id);
//! - a truth object *is separated* when at least one output id overlapping its visible
//!   blocks belongs to it.
//!
//! An object whose visible blocks are covered only by ids that belong to other objects was
//! absorbed; one with no labelled block at all was lost (also a failure).

use super::object_map::{NO_OBJECT, ObjectMap};
use crate::eval::papers::{SeparationRule, separated_objects};
use crate::geometry::BBox;
use crate::io::occlusion::OcclusionRow;
use std::collections::BTreeMap;

/// What the truth says about one object in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRegion {
    /// Truth id.
    pub id: u64,
    /// Full box of the object (visible or not), px.
    pub bbox: BBox,
    /// Row-major indices of the blocks where the object is visible.
    pub visible_blocks: Vec<usize>,
    /// Whether part of the object is hidden by another object.
    pub occluded: bool,
}

/// Whether each truth object with visible blocks is separated in `map` (the paper's rule,
/// [`SeparationRule::OwnRegion`]): `(truth id, visible area in blocks, separated)`, in the
/// order of `truth`.
pub fn separated(truth: &[TruthRegion], map: &ObjectMap) -> Vec<(u64, u32, bool)> {
    let objects: Vec<(u64, &[usize])> = truth
        .iter()
        .map(|r| (r.id, r.visible_blocks.as_slice()))
        .collect();
    let tracker_id = |b: usize| {
        map.ids
            .get(b)
            .copied()
            .filter(|&id| id != NO_OBJECT)
            .map(u64::from)
    };
    let ok = separated_objects(&objects, &tracker_id, SeparationRule::OwnRegion);
    truth
        .iter()
        .zip(ok)
        .filter(|(r, _)| !r.visible_blocks.is_empty())
        .map(|(r, ok)| (r.id, r.visible_blocks.len() as u32, ok))
        .collect()
}

/// Truth regions of one frame from a per-pixel owner map (row-major `width × height`, e.g.
/// `sim::Simulation::visible_object_ids`): a block is visible for the object that owns most
/// of its 64 pixels (ties: the smaller id) when that is at least `min_px` pixels. Blocks within
/// `border_blocks` of the frame edge are left out: the tracker never labels them.
/// `objects` lists `(id, full box, occluded)`; the result has one region per object, in that
/// order (objects with no visible block get an empty set).
// Choice: `min_px` = 16 in the experiments, the tracker's own rule for a moving block
// (`moving_fraction` 0.25 of 64 px).
pub fn truth_regions_from_owner(
    owner: &[Option<u64>],
    width: u32,
    height: u32,
    objects: &[(u64, BBox, bool)],
    border_blocks: u32,
    min_px: u32,
) -> Vec<TruthRegion> {
    let grid = super::object_map::BlockGrid::for_frame(width, height);
    let mut blocks: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    let stride = width as usize;
    let bp = super::object_map::BLOCK_PX as usize;
    let mut counts: BTreeMap<u64, u32> = BTreeMap::new();
    for b in 0..grid.len() {
        let (bx, by) = grid.coords(b);
        if grid.in_border(bx, by, border_blocks) {
            continue;
        }
        counts.clear();
        for r in 0..bp {
            let row = (by as usize * bp + r) * stride + bx as usize * bp;
            for o in owner.get(row..row + bp).into_iter().flatten().flatten() {
                *counts.entry(*o).or_insert(0) += 1;
            }
        }
        // Most pixels, then the smaller id (BTreeMap order keeps the first maximum).
        let mut best: Option<(u64, u32)> = None;
        for (&id, &n) in &counts {
            if best.is_none_or(|(_, bn)| n > bn) {
                best = Some((id, n));
            }
        }
        if let Some((id, _)) = best.filter(|&(_, n)| n >= min_px) {
            blocks.entry(id).or_default().push(b);
        }
    }
    objects
        .iter()
        .map(|&(id, bbox, occluded)| TruthRegion {
            id,
            bbox,
            visible_blocks: blocks.remove(&id).unwrap_or_default(),
            occluded,
        })
        .collect()
}

/// The occlusion outcomes of a run, the input of the Fig. 10 curve
/// ([`crate::eval::papers::separation_success`]): one row per object flagged `occluded`
/// with at least one visible block, per frame. `truth[f]` and `maps[f]` belong to frame
/// `f + 1`.
pub fn occlusion_rows(truth: &[Vec<TruthRegion>], maps: &[ObjectMap]) -> Vec<OcclusionRow> {
    let mut rows = Vec::new();
    for (f, (frame, map)) in truth.iter().zip(maps).enumerate() {
        for ((id, area, ok), r) in separated(frame, map)
            .into_iter()
            .zip(frame.iter().filter(|r| !r.visible_blocks.is_empty()))
        {
            if r.occluded {
                rows.push(OcclusionRow {
                    frame: f as u32 + 1,
                    id,
                    visible_blocks: area,
                    separated: ok,
                });
            }
        }
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::papers::separation_success;
    use crate::track::mrf::object_map::BlockGrid;

    fn truth(id: u64, blocks: Vec<usize>) -> TruthRegion {
        TruthRegion {
            id,
            bbox: BBox::default(),
            visible_blocks: blocks,
            occluded: true,
        }
    }

    #[test]
    fn absorbed_object_fails_and_own_region_succeeds_however_small() {
        let g = BlockGrid::for_frame(64, 8); // 8 blocks in a row
        let mut map = ObjectMap::empty(g);
        // Output id 1 covers truth A (blocks 0–3) and B's blocks 4, 5; id 2 covers B's block 6.
        map.ids = vec![1, 1, 1, 1, 1, 1, 2, 0];
        let a = truth(10, vec![0, 1, 2, 3]);
        let b = truth(20, vec![4, 5, 6]);
        assert_eq!(
            separated(&[a.clone(), b.clone()], &map),
            vec![(10, 4, true), (20, 3, true)]
        );
        // Without id 2, B is absorbed into A's region.
        map.ids[6] = 1;
        assert_eq!(
            separated(&[a, b], &map),
            vec![(10, 4, true), (20, 3, false)]
        );
    }

    #[test]
    fn truth_blocks_go_to_the_pixel_majority_outside_the_border() {
        // 32 × 16 px = 4 × 2 blocks. Object 7 owns all of block (1, 0) and 40 px of (2, 0),
        // object 9 the other 24 px of (2, 0) and 10 px of (3, 0) (below min_px 16).
        let (w, h) = (32u32, 16u32);
        let mut owner = vec![None; (w * h) as usize];
        for y in 0..8usize {
            for x in 8..16usize {
                owner[y * 32 + x] = Some(7);
            }
            for x in 16..24usize {
                owner[y * 32 + x] = Some(if y < 5 { 7 } else { 9 });
            }
        }
        for x in 24..29usize {
            owner[x] = Some(9);
            owner[32 + x] = Some(9);
        }
        let objs = [
            (7, BBox::default(), true),
            (9, BBox::default(), true),
            (5, BBox::default(), false),
        ];
        let r = truth_regions_from_owner(&owner, w, h, &objs, 0, 16);
        assert_eq!(r[0].visible_blocks, vec![1, 2]);
        assert!(r[1].visible_blocks.is_empty());
        assert!(r[2].visible_blocks.is_empty());
        // A 1-block border leaves nothing of a 4 × 2 grid.
        let r = truth_regions_from_owner(&owner, w, h, &objs, 1, 16);
        assert!(r.iter().all(|x| x.visible_blocks.is_empty()));
    }

    #[test]
    fn curve_bins_by_visible_area_and_skips_unoccluded_objects() {
        let g = BlockGrid::for_frame(64, 8);
        let mut map = ObjectMap::empty(g);
        map.ids = vec![1, 1, 1, 1, 1, 1, 2, 0];
        let mut free = truth(30, vec![7]);
        free.occluded = false;
        let frame1 = vec![truth(10, vec![0, 1, 2, 3]), truth(20, vec![4, 5, 6]), free];
        let mut map2 = map.clone();
        map2.ids[6] = 1;
        let frame2 = vec![truth(10, vec![0, 1, 2, 3]), truth(20, vec![4, 5, 6])];
        let rows = occlusion_rows(&[frame1, frame2], &[map, map2]);
        assert_eq!(rows.len(), 4);
        let curve = separation_success(&rows, Some(3));
        assert_eq!(curve.len(), 3);
        assert_eq!((curve[0].n, curve[1].n), (0, 0));
        // Bin "≥ 3": A twice (2 wins), B twice (1 win).
        assert_eq!((curve[2].n, curve[2].separated), (4, 3));
        assert_eq!(curve[2].success_rate, 0.75);
    }
}
