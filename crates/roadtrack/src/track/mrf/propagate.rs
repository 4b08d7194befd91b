//! Step 2 of METHODS.md §2 (propagation of `X(t − 1)` into the initial `X⁰(t)`), growth into
//! newly moving blocks, object birth and death.

use super::block_matching::BlockMatch;
use super::object_map::{
    BLOCK_PX, BlockGrid, NO_OBJECT, ObjectId, ObjectMap, Vector, blocks_from_px_shift,
};

/// One candidate id of a block of `X(t)`, with the local vector it arrived with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Candidate {
    /// The object.
    pub id: ObjectId,
    /// The block-matching vector of the `t − 1` block it came from, px.
    pub vector: Vector,
    /// That vector's SAD (smaller is a better match).
    pub sad: u32,
    /// Whether it arrived by the paper's move rounded to whole blocks (Step 2); `false`
    /// when only the moved square's partial overlap brought it.
    pub rounded: bool,
}

/// A block to optimise: it has two or more candidate ids.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GibbsSite {
    /// Row-major block index in `X(t)`.
    pub block: usize,
    /// Candidates, sorted by id, distinct ids.
    pub candidates: Vec<Candidate>,
}

/// `X⁰(t)` and what the Gibbs sampler must decide.
#[derive(Debug, Clone, PartialEq)]
pub struct Propagated {
    /// Initial id per block of `X(t)` ([`NO_OBJECT`] where none).
    pub ids: Vec<ObjectId>,
    /// Initial local vector per block of `X(t)` (the vector its id arrived with).
    pub vectors: Vec<Option<Vector>>,
    /// Blocks with several candidate ids, ascending block index.
    pub sites: Vec<GibbsSite>,
}

/// Adds `c` to `list`, keeping one candidate per id: a rounded arrival before an overlap
/// arrival, then the smaller SAD, then the earlier one.
fn push_candidate(list: &mut Vec<Candidate>, c: Candidate) {
    match list.iter_mut().find(|e| e.id == c.id) {
        Some(e) if (!c.rounded, c.sad) < (!e.rounded, e.sad) => *e = c,
        Some(_) => {}
        None => list.push(c),
    }
}

/// Step 2: moves every labelled block of `prev_map` by its block-matching vector rounded to
/// whole blocks (nearest, halves away from zero), then lets moving blocks that nobody
/// reached take the ids of their 8 neighbours (growth).
///
/// `matches[i]` is the match of `prev_map` block `i` (`None` for blocks without an id).
/// `moving[i]` says whether block `i` of frame `t` is moving.
// Choice: a block of X(t) can only carry an id if it is moving at t and outside the border
// (the paper labels only blocks that background subtraction marks as moving, and excludes a
// 3-block frame border); propagated ids landing elsewhere are dropped.
// Choice: when several t−1 blocks of the same object land on one block, the one whose
// vector matched best (smallest SAD) gives the candidate's local vector.
// Choice (growth): a moving block that no propagated id reached takes as candidates the ids
// of its 8 neighbours' propagated candidates, each with the vector of the first such
// neighbour (order NW, N, NE, W, E, SW, S, SE). One ring per frame: rounding moves the map
// by whole blocks, so an object moving less than half a block per frame advances through
// growth at its leading edge and loses its trailing blocks as they stop moving.
// Choice: a block with a single candidate takes it without optimisation (the paper
// optimises only blocks with several candidate ids).
// Choice (overlap candidates): besides the rounded target, the moved square also offers its
// id to every block of X(t) it overlaps by at least `min_overlap_px` pixels. With rounding
// alone, an object slower than half a block per frame never reaches a block its neighbour
// holds (both ids move by 0 blocks), so it could never push into a neighbour's region;
// with overlaps, the boundary blocks between two objects become contested and eq. 5
// decides them. `min_overlap_px = 65` switches this off (the paper's Step 2 exactly).
pub fn propagate(
    prev_map: &ObjectMap,
    matches: &[Option<BlockMatch>],
    moving: &[bool],
    border_blocks: u32,
    min_overlap_px: u32,
) -> Propagated {
    let grid = prev_map.grid;
    let n = grid.len();
    let allowed = |i: usize| {
        let (bx, by) = grid.coords(i);
        moving.get(i).copied().unwrap_or(false) && !grid.in_border(bx, by, border_blocks)
    };
    let mut lists: Vec<Vec<Candidate>> = vec![Vec::new(); n];
    let local = local_vectors(prev_map, matches);
    for (s, &id) in prev_map.ids.iter().enumerate() {
        if id == NO_OBJECT {
            continue;
        }
        let Some(m) = matches.get(s).copied().flatten() else {
            continue;
        };
        let (bx, by) = grid.coords(s);
        let tx = bx as i32 + blocks_from_px_shift(m.vector[0]);
        let ty = by as i32 + blocks_from_px_shift(m.vector[1]);
        // The moved square's top-left pixel and the blocks it overlaps.
        let b = BLOCK_PX as i32;
        let px = (bx * BLOCK_PX) as i32 + i32::from(m.vector[0]);
        let py = (by * BLOCK_PX) as i32 + i32::from(m.vector[1]);
        let (cx, cy) = (px.div_euclid(b), py.div_euclid(b));
        let (rx, ry) = (px.rem_euclid(b), py.rem_euclid(b));
        for (x, y, area) in [
            (tx, ty, b * b),
            (cx, cy, (b - rx) * (b - ry)),
            (cx + 1, cy, rx * (b - ry)),
            (cx, cy + 1, (b - rx) * ry),
            (cx + 1, cy + 1, rx * ry),
        ] {
            let rounded = (x, y) == (tx, ty);
            if area < min_overlap_px as i32 && !rounded {
                continue;
            }
            if x < 0 || y < 0 || x >= grid.cols as i32 || y >= grid.rows as i32 {
                continue;
            }
            let t = grid.index(x as u32, y as u32);
            if allowed(t) {
                push_candidate(
                    &mut lists[t],
                    Candidate {
                        id,
                        vector: local[s].unwrap_or(m.vector),
                        sad: m.sad,
                        rounded,
                    },
                );
            }
        }
    }
    // Growth, reading only the propagated lists (one ring).
    let mut grown: Vec<(usize, Vec<Candidate>)> = Vec::new();
    for t in 0..n {
        if !lists[t].is_empty() || !allowed(t) {
            continue;
        }
        let mut cands: Vec<Candidate> = Vec::new();
        for nb in grid.neighbours8(t).into_iter().flatten() {
            for c in &lists[nb] {
                if !cands.iter().any(|e| e.id == c.id) {
                    cands.push(*c);
                }
            }
        }
        if !cands.is_empty() {
            grown.push((t, cands));
        }
    }
    for (t, c) in grown {
        lists[t] = c;
    }
    let mut ids = vec![NO_OBJECT; n];
    let mut vectors = vec![None; n];
    let mut sites = Vec::new();
    for (t, mut list) in lists.into_iter().enumerate() {
        if list.is_empty() {
            continue;
        }
        list.sort_by_key(|c| c.id);
        // Choice: the initial state of a contested block is its best-matching rounded
        // arrival (smallest SAD, then smallest id), else its best overlap arrival; the
        // sampler is free to leave it.
        let init = list
            .iter()
            .min_by_key(|c| (!c.rounded, c.sad, c.id))
            .copied()
            .unwrap_or(list[0]);
        ids[t] = init.id;
        vectors[t] = Some(init.vector);
        if list.len() > 1 {
            sites.push(GibbsSite {
                block: t,
                candidates: list,
            });
        }
    }
    Propagated {
        ids,
        vectors,
        sites,
    }
}

/// The local vector each labelled block of `X(t − 1)` hands to its candidates: the
/// component-wise median of the block-matching vectors of the blocks with the same id in its
/// 3 × 3 neighbourhood (itself included).
// Choice: a block on an object's edge that already shows an intruding object's texture
// block-matches with the intruder's vector; handing that raw vector to its id would let the
// wrong id explain the texture perfectly (D cannot tell the ids apart) and the error would
// persist. The 3 × 3 same-id median is still a local vector (non-rigid objects keep their
// spatially varying motion) but follows the object, not the single block — the role eq. 4's
// smoothness plays in the paper, applied before the sampler.
pub fn local_vectors(prev_map: &ObjectMap, matches: &[Option<BlockMatch>]) -> Vec<Option<Vector>> {
    let grid = prev_map.grid;
    let mut xs: Vec<i16> = Vec::with_capacity(9);
    let mut ys: Vec<i16> = Vec::with_capacity(9);
    (0..grid.len())
        .map(|s| {
            let id = prev_map.ids[s];
            let own = matches.get(s).copied().flatten()?;
            if id == NO_OBJECT {
                return Some(own.vector);
            }
            xs.clear();
            ys.clear();
            xs.push(own.vector[0]);
            ys.push(own.vector[1]);
            for nb in grid.neighbours8(s).into_iter().flatten() {
                if let (true, Some(m)) =
                    (prev_map.ids[nb] == id, matches.get(nb).copied().flatten())
                {
                    xs.push(m.vector[0]);
                    ys.push(m.vector[1]);
                }
            }
            xs.sort_unstable();
            ys.sort_unstable();
            Some([xs[xs.len() / 2], ys[ys.len() / 2]])
        })
        .collect()
}

/// Object birth: every 8-connected component of moving, unlabelled, non-border blocks of at
/// least `min_blocks` blocks gets a fresh id (`*next_id`, then incremented), in raster order
/// of the components' first block. Returns the new ids.
// Choice: births are decided after the optimisation, from what no existing object claimed;
// smaller components stay unlabelled (they are re-examined next frame, when they may have
// grown). Ids are never reused. An object dies when no block carries its id any more
// (it stopped, left through the border, or was absorbed).
pub fn births(
    ids: &mut [ObjectId],
    grid: &BlockGrid,
    moving: &[bool],
    border_blocks: u32,
    min_blocks: u32,
    next_id: &mut ObjectId,
) -> Vec<ObjectId> {
    let n = grid.len();
    let free = |i: usize, ids: &[ObjectId]| {
        let (bx, by) = grid.coords(i);
        moving.get(i).copied().unwrap_or(false)
            && ids[i] == NO_OBJECT
            && !grid.in_border(bx, by, border_blocks)
    };
    let mut seen = vec![false; n];
    let mut born = Vec::new();
    let mut stack = Vec::new();
    let mut component = Vec::new();
    for start in 0..n {
        if seen[start] || !free(start, ids) {
            continue;
        }
        component.clear();
        stack.push(start);
        seen[start] = true;
        while let Some(b) = stack.pop() {
            component.push(b);
            for nb in grid.neighbours8(b).into_iter().flatten() {
                if !seen[nb] && free(nb, ids) {
                    seen[nb] = true;
                    stack.push(nb);
                }
            }
        }
        if component.len() as u32 >= min_blocks {
            let id = *next_id;
            *next_id += 1;
            for &b in &component {
                ids[b] = id;
            }
            born.push(id);
        }
    }
    born
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(v: Vector, sad: u32) -> Option<BlockMatch> {
        Some(BlockMatch { vector: v, sad })
    }

    #[test]
    fn blocks_move_by_rounded_vectors_and_collisions_become_sites() {
        let g = BlockGrid::for_frame(80, 80); // 10 × 10
        let mut prev = ObjectMap::empty(g);
        let mut matches = vec![None; g.len()];
        prev.ids[g.index(3, 5)] = 1;
        matches[g.index(3, 5)] = m([17, -4], 10); // → (5, 4)
        prev.ids[g.index(6, 4)] = 2;
        matches[g.index(6, 4)] = m([-9, 2], 5); // → (5, 4): collision
        prev.ids[g.index(4, 6)] = 1;
        matches[g.index(4, 6)] = m([0, 0], 0); // stays at (4, 6)
        let mut moving = vec![false; g.len()];
        for (x, y) in [(5, 4), (4, 6), (3, 5)] {
            moving[g.index(x, y)] = true;
        }
        let p = propagate(&prev, &matches, &moving, 0, 65);
        let t = g.index(5, 4);
        assert_eq!(p.sites.len(), 1);
        assert_eq!(p.sites[0].block, t);
        assert_eq!(
            p.sites[0]
                .candidates
                .iter()
                .map(|c| c.id)
                .collect::<Vec<_>>(),
            vec![1, 2]
        );
        // Initial state: the better match (id 2, SAD 5).
        assert_eq!(p.ids[t], 2);
        assert_eq!(p.vectors[t], Some([-9, 2]));
        assert_eq!(p.ids[g.index(4, 6)], 1);
        assert_eq!(p.ids[g.index(3, 5)], 1, "grown from its neighbour (4, 6)");
    }

    #[test]
    fn ids_only_land_on_moving_blocks_outside_the_border() {
        let g = BlockGrid::for_frame(80, 80);
        let mut prev = ObjectMap::empty(g);
        let mut matches = vec![None; g.len()];
        prev.ids[g.index(4, 4)] = 1;
        matches[g.index(4, 4)] = m([0, 0], 0);
        prev.ids[g.index(3, 4)] = 1;
        matches[g.index(3, 4)] = m([-8, 0], 0); // → (2, 4): in the 3-block border
        let mut moving = vec![false; g.len()];
        moving[g.index(4, 4)] = true;
        moving[g.index(2, 4)] = true;
        let p = propagate(&prev, &matches, &moving, 3, 65);
        assert_eq!(p.ids.iter().filter(|&&i| i != NO_OBJECT).count(), 1);
        assert_eq!(p.ids[g.index(4, 4)], 1);
        let p0 = propagate(&prev, &matches, &moving, 0, 65);
        assert_eq!(p0.ids[g.index(2, 4)], 1);
    }

    #[test]
    fn growth_takes_one_ring_and_offers_every_neighbour_id() {
        let g = BlockGrid::for_frame(80, 80);
        let mut prev = ObjectMap::empty(g);
        let mut matches = vec![None; g.len()];
        prev.ids[g.index(3, 3)] = 1;
        matches[g.index(3, 3)] = m([0, 0], 0);
        prev.ids[g.index(5, 3)] = 2;
        matches[g.index(5, 3)] = m([0, 0], 0);
        let moving = vec![true; g.len()];
        let p = propagate(&prev, &matches, &moving, 0, 65);
        // (4, 3) touches both: a site with ids 1 and 2.
        let between = p.sites.iter().find(|s| s.block == g.index(4, 3));
        assert_eq!(between.map(|s| s.candidates.len()), Some(2));
        // (2, 3) touches only 1; (1, 3) is two rings away.
        assert_eq!(p.ids[g.index(2, 3)], 1);
        assert_eq!(p.ids[g.index(1, 3)], NO_OBJECT);
    }

    #[test]
    fn partial_overlap_offers_the_id_to_the_next_block() {
        let g = BlockGrid::for_frame(80, 80);
        let mut prev = ObjectMap::empty(g);
        let mut matches = vec![None; g.len()];
        // Id 1 at (4, 4) moving +2 px (rounds to 0 blocks); id 2 holds (5, 4), static.
        prev.ids[g.index(4, 4)] = 1;
        matches[g.index(4, 4)] = m([2, 0], 3);
        prev.ids[g.index(5, 4)] = 2;
        matches[g.index(5, 4)] = m([0, 0], 0);
        let moving = vec![true; g.len()];
        let p = propagate(&prev, &matches, &moving, 0, 16);
        let site = p.sites.iter().find(|s| s.block == g.index(5, 4));
        let c = site.map(|s| s.candidates.clone()).unwrap_or_default();
        assert_eq!(
            c.len(),
            2,
            "2 px × 8 = 16 px overlap makes (5, 4) contested"
        );
        assert!(c[0].id == 1 && !c[0].rounded && c[1].id == 2 && c[1].rounded);
        assert_eq!(
            p.ids[g.index(5, 4)],
            2,
            "the rounded arrival is the initial state"
        );
        // With the paper's rounding only, (5, 4) is not contested.
        let p = propagate(&prev, &matches, &moving, 0, 65);
        assert!(p.sites.iter().all(|s| s.block != g.index(5, 4)));
    }

    #[test]
    fn births_need_min_blocks_and_get_fresh_ids_in_raster_order() {
        let g = BlockGrid::for_frame(80, 80);
        let mut ids = vec![NO_OBJECT; g.len()];
        let mut moving = vec![false; g.len()];
        for (x, y) in [
            (1, 1),
            (2, 2),
            (1, 2),
            (7, 1),
            (7, 7),
            (8, 8),
            (8, 7),
            (6, 6),
        ] {
            moving[g.index(x, y)] = true;
        }
        ids[g.index(6, 6)] = 4; // already labelled: not part of a birth
        let mut next = 10;
        let born = births(&mut ids, &g, &moving, 0, 3, &mut next);
        assert_eq!(born, vec![10, 11]);
        assert_eq!(ids[g.index(2, 2)], 10);
        assert_eq!(ids[g.index(8, 8)], 11);
        assert_eq!(ids[g.index(7, 1)], NO_OBJECT, "a single block is too small");
        assert_eq!(next, 12);
    }
}
