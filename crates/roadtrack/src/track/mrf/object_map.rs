//! The Object-map `X(t)` and the Motion-Vector-map `V(t−1; t)` on the block grid
//! (METHODS.md §2 "Units").
//!
//! The image is cut into `8 × 8` px blocks, row-major; a partial block at the right or
//! bottom edge is not part of the grid (640 × 480 → 80 × 60, 768 × 576 → 96 × 72).

use crate::geometry::{BBox, Point};
use std::collections::BTreeMap;

/// Side of a block, px. The block matching kernel is specialised for it (METHODS.md §2).
pub const BLOCK_PX: u32 = 8;

/// Pixels in one block (`μ_M` of eq. 5 is this number).
pub const BLOCK_AREA_PX: u32 = BLOCK_PX * BLOCK_PX;

/// An object identifier on the map. `0` is never an object: it marks unlabelled blocks.
pub type ObjectId = u32;

/// The "no object" value of an [`ObjectMap`] cell.
pub const NO_OBJECT: ObjectId = 0;

/// A motion vector in whole pixels, `(dx, dy)`, from frame `t − 1` to frame `t`.
pub type Vector = [i16; 2];

/// Size of the block grid of a `width × height` px frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockGrid {
    /// Blocks per row.
    pub cols: u32,
    /// Block rows.
    pub rows: u32,
}

impl BlockGrid {
    /// The grid of a frame of `width × height` px (partial edge blocks dropped).
    pub fn for_frame(width: u32, height: u32) -> Self {
        Self {
            cols: width / BLOCK_PX,
            rows: height / BLOCK_PX,
        }
    }

    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.cols as usize * self.rows as usize
    }

    /// Whether the grid has no block.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row-major index of block `(bx, by)`.
    pub fn index(&self, bx: u32, by: u32) -> usize {
        by as usize * self.cols as usize + bx as usize
    }

    /// Block coordinates `(bx, by)` of a row-major index.
    pub fn coords(&self, index: usize) -> (u32, u32) {
        let cols = self.cols.max(1) as usize;
        ((index % cols) as u32, (index / cols) as u32)
    }

    /// The block holding pixel `(x, y)`, if it lies on the grid.
    pub fn blocks_from_px(&self, x_px: u32, y_px: u32) -> Option<(u32, u32)> {
        let (bx, by) = (x_px / BLOCK_PX, y_px / BLOCK_PX);
        (bx < self.cols && by < self.rows).then_some((bx, by))
    }

    /// Top-left pixel of block `(bx, by)`.
    pub fn px_from_blocks(bx: u32, by: u32) -> (u32, u32) {
        (bx * BLOCK_PX, by * BLOCK_PX)
    }

    /// Indices of the (up to 8) spatial neighbours of block `index` (Fig. 5), in the fixed
    /// order NW, N, NE, W, E, SW, S, SE; `None` where the neighbour is off the grid.
    pub fn neighbours8(&self, index: usize) -> [Option<usize>; 8] {
        let (bx, by) = self.coords(index);
        let mut out = [None; 8];
        let mut k = 0;
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                if dx == 0 && dy == 0 {
                    continue;
                }
                let (x, y) = (i64::from(bx) + dx, i64::from(by) + dy);
                if x >= 0 && y >= 0 && x < i64::from(self.cols) && y < i64::from(self.rows) {
                    out[k] = Some(self.index(x as u32, y as u32));
                }
                k += 1;
            }
        }
        out
    }

    /// Whether block `(bx, by)` lies within `border_blocks` of the frame edge (excluded from
    /// tracking; METHODS.md §2, the paper's 3-block border).
    pub fn in_border(&self, bx: u32, by: u32, border_blocks: u32) -> bool {
        bx < border_blocks
            || by < border_blocks
            || bx + border_blocks >= self.cols
            || by + border_blocks >= self.rows
    }
}

/// The Object-map `X(t)`: an object id (or [`NO_OBJECT`]) for every block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectMap {
    /// The grid.
    pub grid: BlockGrid,
    /// One id per block, row-major.
    pub ids: Vec<ObjectId>,
}

/// What one object of an [`ObjectMap`] covers.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectRegion {
    /// The object's id.
    pub id: ObjectId,
    /// Number of blocks carrying the id.
    pub area_blocks: u32,
    /// Box around its blocks, px (block edges).
    pub bbox: BBox,
    /// Mean of its block centres, px.
    pub centroid_px: Point,
}

impl ObjectMap {
    /// A map with no object.
    pub fn empty(grid: BlockGrid) -> Self {
        Self {
            grid,
            ids: vec![NO_OBJECT; grid.len()],
        }
    }

    /// The id at block `(bx, by)`, `None` when unlabelled or off the grid.
    pub fn get(&self, bx: u32, by: u32) -> Option<ObjectId> {
        if bx >= self.grid.cols || by >= self.grid.rows {
            return None;
        }
        let id = self.ids[self.grid.index(bx, by)];
        (id != NO_OBJECT).then_some(id)
    }

    /// Every object on the map with its block count, box and centroid, sorted by id.
    pub fn regions(&self) -> Vec<ObjectRegion> {
        struct Acc {
            n: u32,
            x0: u32,
            y0: u32,
            x1: u32,
            y1: u32,
            sx: f64,
            sy: f64,
        }
        let mut acc: BTreeMap<ObjectId, Acc> = BTreeMap::new();
        for (i, &id) in self.ids.iter().enumerate() {
            if id == NO_OBJECT {
                continue;
            }
            let (bx, by) = self.grid.coords(i);
            let a = acc.entry(id).or_insert(Acc {
                n: 0,
                x0: u32::MAX,
                y0: u32::MAX,
                x1: 0,
                y1: 0,
                sx: 0.0,
                sy: 0.0,
            });
            a.n += 1;
            a.x0 = a.x0.min(bx);
            a.y0 = a.y0.min(by);
            a.x1 = a.x1.max(bx);
            a.y1 = a.y1.max(by);
            a.sx += f64::from(bx * BLOCK_PX) + f64::from(BLOCK_PX) / 2.0;
            a.sy += f64::from(by * BLOCK_PX) + f64::from(BLOCK_PX) / 2.0;
        }
        let b = f64::from(BLOCK_PX);
        acc.into_iter()
            .map(|(id, a)| ObjectRegion {
                id,
                area_blocks: a.n,
                bbox: BBox::new(
                    f64::from(a.x0) * b,
                    f64::from(a.y0) * b,
                    f64::from(a.x1 - a.x0 + 1) * b,
                    f64::from(a.y1 - a.y0 + 1) * b,
                ),
                centroid_px: Point::new(a.sx / f64::from(a.n), a.sy / f64::from(a.n)),
            })
            .collect()
    }

    /// Block indices carrying `id`, ascending.
    pub fn blocks_of(&self, id: ObjectId) -> Vec<usize> {
        self.ids
            .iter()
            .enumerate()
            .filter(|(_, v)| **v == id)
            .map(|(i, _)| i)
            .collect()
    }
}

/// The Motion-Vector-map: a vector for some blocks (those that carried an object).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MotionMap {
    /// The grid.
    pub grid: BlockGrid,
    /// One optional vector per block, row-major.
    pub vectors: Vec<Option<Vector>>,
}

impl MotionMap {
    /// A map with no vector.
    pub fn empty(grid: BlockGrid) -> Self {
        Self {
            grid,
            vectors: vec![None; grid.len()],
        }
    }
}

/// Rounds a pixel displacement to whole blocks, to the nearest block, halves away from zero
/// (Step 2: `(17, −4)` px → `(2, −1)` blocks... `−4 / 8 = −0.5` rounds to `−1`).
pub fn blocks_from_px_shift(v_px: i16) -> i32 {
    let b = BLOCK_PX as i32;
    let v = i32::from(v_px);
    if v >= 0 {
        (v + b / 2) / b
    } else {
        -((-v + b / 2) / b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_of_vga_is_80_by_60_and_index_round_trips() {
        let g = BlockGrid::for_frame(640, 480);
        assert_eq!((g.cols, g.rows, g.len()), (80, 60, 4800));
        for i in [0, 79, 80, 4799, 1234] {
            let (x, y) = g.coords(i);
            assert_eq!(g.index(x, y), i);
        }
        assert_eq!(g.blocks_from_px(639, 479), Some((79, 59)));
        assert_eq!(g.blocks_from_px(640, 0), None);
        assert_eq!(BlockGrid::px_from_blocks(2, 3), (16, 24));
    }

    #[test]
    fn papers_rounding_example_moves_two_right_one_up() {
        // Step 2 of the paper: (17, −4) px → 2 blocks right, 1 block up.
        assert_eq!(blocks_from_px_shift(17), 2);
        assert_eq!(blocks_from_px_shift(-4), -1);
        assert_eq!(blocks_from_px_shift(3), 0);
        assert_eq!(blocks_from_px_shift(-3), 0);
        assert_eq!(blocks_from_px_shift(4), 1);
        assert_eq!(blocks_from_px_shift(-12), -2);
    }

    #[test]
    fn corner_block_has_three_neighbours() {
        let g = BlockGrid::for_frame(32, 24);
        let n = g.neighbours8(0);
        assert_eq!(n.iter().flatten().count(), 3);
        let inner = g.index(1, 1);
        assert_eq!(g.neighbours8(inner).iter().flatten().count(), 8);
        assert_eq!(g.neighbours8(inner)[0], Some(0));
    }

    #[test]
    fn border_excludes_three_blocks_on_each_side() {
        let g = BlockGrid::for_frame(640, 480);
        assert!(g.in_border(2, 30, 3));
        assert!(!g.in_border(3, 3, 3));
        assert!(g.in_border(77, 30, 3));
        assert!(!g.in_border(76, 56, 3));
        assert!(g.in_border(76, 57, 3));
        assert!(!g.in_border(0, 0, 0));
    }

    #[test]
    fn regions_give_block_boxes_sorted_by_id() {
        let g = BlockGrid::for_frame(32, 32);
        let mut m = ObjectMap::empty(g);
        m.ids[g.index(1, 1)] = 7;
        m.ids[g.index(2, 2)] = 7;
        m.ids[g.index(0, 3)] = 3;
        let r = m.regions();
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].id, 3);
        assert_eq!(r[1].bbox, BBox::new(8.0, 8.0, 16.0, 16.0));
        assert_eq!(r[1].area_blocks, 2);
        assert_eq!(r[1].centroid_px, Point::new(16.0, 16.0));
        assert_eq!(m.get(1, 1), Some(7));
        assert_eq!(m.get(0, 0), None);
    }
}
