//! The energy of eq. 5 (METHODS.md §2), one function per term.
//!
//! ```text
//! U(C_k = O_m, v) = a·(N_k − μ_N)² + b·(M_k − μ_M)² + c·(D_k − μ_D)²
//!                 + f·Σ_{B ∈ nb8(C_k)} |v − V_B|² / N_x          (eq. 5, μ_D = 0)
//! ```
//!
//! `v` is the motion vector from `t − 1` to `t` the block is evaluated with: its own local
//! vector in the improved model (2004), the object's representative vector in the legacy
//! model (2000, which also has no `f` term).

use super::block_matching::{load_rows, sad_full};
use super::object_map::{
    BLOCK_AREA_PX, BLOCK_PX, BlockGrid, NO_OBJECT, ObjectId, ObjectMap, Vector,
};
use super::{MrfConfig, MrfVariant};
use image::GrayImage;

/// `N_k` (eq. 3): how many of the 8 spatial neighbours of block `block` carry `id` in the
/// Object-map `ids` of frame `t`.
pub fn neighbour_count(ids: &[ObjectId], grid: &BlockGrid, block: usize, id: ObjectId) -> u32 {
    grid.neighbours8(block)
        .iter()
        .flatten()
        .filter(|&&n| ids[n] == id && id != NO_OBJECT)
        .count() as u32
}

/// Eq. 3: `U_N = a·(N_k − μ_N)²`.
pub fn neighbour_energy(n: u32, config: &MrfConfig) -> f64 {
    let d = f64::from(n) - config.neighbour_target;
    config.neighbour_weight * d * d
}

/// `M_k` (Fig. 4): move the `8 × 8` square of block `block` back by `v` (to where it was in
/// frame `t − 1`) and count its pixels that lie on blocks carrying `id` in `X(t − 1)`.
/// Pixels off the grid count as not on `id`.
pub fn overlap_pixels(prev_map: &ObjectMap, block: usize, v: Vector, id: ObjectId) -> u32 {
    let grid = prev_map.grid;
    let (bx, by) = grid.coords(block);
    let b = BLOCK_PX as i32;
    let px = (bx * BLOCK_PX) as i32 - i32::from(v[0]);
    let py = (by * BLOCK_PX) as i32 - i32::from(v[1]);
    let (cx, cy) = (px.div_euclid(b), py.div_euclid(b));
    let (rx, ry) = (px.rem_euclid(b), py.rem_euclid(b));
    let mut total = 0u32;
    for (dy, hgt) in [(0, b - ry), (1, ry)] {
        for (dx, wid) in [(0, b - rx), (1, rx)] {
            if wid == 0 || hgt == 0 {
                continue;
            }
            let (x, y) = (cx + dx, cy + dy);
            if x < 0 || y < 0 || x >= grid.cols as i32 || y >= grid.rows as i32 {
                continue;
            }
            if prev_map.ids[grid.index(x as u32, y as u32)] == id {
                total += (wid * hgt) as u32;
            }
        }
    }
    total
}

/// Eq. 1 (second part): `U_M = b·(M_k − μ_M)²`, `μ_M = 64`.
pub fn overlap_energy(m: u32, config: &MrfConfig) -> f64 {
    let d = f64::from(m) - config.overlap_target;
    config.overlap_weight * d * d
}

/// `D_k` (eq. 2): SAD of luminance between block `block` of frame `t` and the square `v`
/// earlier in frame `t − 1`:
///
/// ```text
/// D_k = Σ_{0≤di,dj<8} |G(t; i+di, j+dj) − G(t−1; i+di−v_i, j+dj−v_j)|
/// ```
// Choice: a back-shifted square that leaves frame t − 1 is clamped to the frame edge (the
// 3-block border and the ±24 px window make this rare; paper silent).
pub fn texture_sad(
    prev: &GrayImage,
    cur: &GrayImage,
    grid: &BlockGrid,
    block: usize,
    v: Vector,
) -> u32 {
    let (w, h) = cur.dimensions();
    let (bx, by) = grid.coords(block);
    let (x, y) = ((bx * BLOCK_PX) as usize, (by * BLOCK_PX) as usize);
    let stride = w as usize;
    let rows = load_rows(cur.as_raw(), stride, x, y);
    let max_x = (w - BLOCK_PX) as i32;
    let max_y = (h - BLOCK_PX) as i32;
    let px = (x as i32 - i32::from(v[0])).clamp(0, max_x) as usize;
    let py = (y as i32 - i32::from(v[1])).clamp(0, max_y) as usize;
    sad_full(&rows, prev.as_raw(), stride, px, py)
}

/// Eq. 1 (first part): `U_D = c·(D_k − μ_D)²`, `μ_D = 0`.
pub fn texture_energy(d: u32, config: &MrfConfig) -> f64 {
    let d = f64::from(d);
    config.texture_weight * d * d
}

/// Eq. 4: `U_mv = f·Σ_B |v − V_B|² / N_x` over the neighbours that carry a vector; 0 when
/// none does. `|·|²` is the squared Euclidean length in px².
pub fn smoothness_energy(
    v: Vector,
    neighbours: impl IntoIterator<Item = Vector>,
    config: &MrfConfig,
) -> f64 {
    let mut sum = 0.0;
    let mut n = 0u32;
    for b in neighbours {
        let dx = f64::from(v[0]) - f64::from(b[0]);
        let dy = f64::from(v[1]) - f64::from(b[1]);
        sum += dx * dx + dy * dy;
        n += 1;
    }
    if n == 0 {
        0.0
    } else {
        config.smoothness_weight * sum / f64::from(n)
    }
}

/// The four raw quantities of eq. 5 for one (block, id, vector) state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Terms {
    /// `N_k`, neighbours with the same id (0–8).
    pub n: u32,
    /// `M_k`, overlapping pixels (0–64).
    pub m: u32,
    /// `D_k`, texture SAD.
    pub d: u32,
    /// The already weighted smoothness term `U_mv` (eq. 4).
    pub smoothness: f64,
}

/// Eq. 5: the total energy of `terms` (the smoothness term only in [`MrfVariant::Improved`]).
pub fn total_energy(terms: &Terms, config: &MrfConfig) -> f64 {
    let mut u = neighbour_energy(terms.n, config)
        + overlap_energy(terms.m, config)
        + texture_energy(terms.d, config);
    if config.variant == MrfVariant::Improved {
        u += terms.smoothness;
    }
    u
}

/// `μ_M` as an integer: the pixels of one block.
pub const FULL_OVERLAP_PX: u32 = BLOCK_AREA_PX;

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> MrfConfig {
        MrfConfig::default()
    }

    #[test]
    fn neighbour_term_matches_hand_values() {
        // a = 1/2, μ_N = 8: N = 8 → 0; N = 5 → 0.5·9 = 4.5; N = 0 → 32.
        assert_eq!(neighbour_energy(8, &cfg()), 0.0);
        assert_eq!(neighbour_energy(5, &cfg()), 4.5);
        assert_eq!(neighbour_energy(0, &cfg()), 32.0);
        let g = BlockGrid::for_frame(24, 24);
        let mut ids = vec![0; 9];
        for i in [0, 1, 2, 3] {
            ids[i] = 4;
        }
        ids[5] = 9;
        assert_eq!(neighbour_count(&ids, &g, 4, 4), 4);
        assert_eq!(neighbour_count(&ids, &g, 4, 9), 1);
        assert_eq!(neighbour_count(&ids, &g, 0, 4), 2);
    }

    #[test]
    fn overlap_term_matches_hand_values() {
        // b = 1/256, μ_M = 64: M = 64 → 0; M = 32 → 1024/256 = 4; M = 0 → 16.
        assert_eq!(overlap_energy(64, &cfg()), 0.0);
        assert_eq!(overlap_energy(32, &cfg()), 4.0);
        assert_eq!(overlap_energy(0, &cfg()), 16.0);
        // X(t−1): block (1,1) carries 3. Block (2,1) of X(t) moved back by (−)(5, 2) px
        // lands at px (11, 6): it covers 5 × 6 = 30 px of block (1,0)... of (1,1) it covers
        // x 11..16 (5 px) × y 8..14 (6 px) = 30 px.
        let g = BlockGrid::for_frame(32, 32);
        let mut prev = ObjectMap::empty(g);
        prev.ids[g.index(1, 1)] = 3;
        assert_eq!(overlap_pixels(&prev, g.index(2, 1), [5, 2], 3), 30);
        assert_eq!(overlap_pixels(&prev, g.index(2, 1), [8, 0], 3), 64);
        assert_eq!(overlap_pixels(&prev, g.index(2, 1), [8, 0], 4), 0);
        // Off the grid to the top-left: nothing.
        assert_eq!(overlap_pixels(&prev, g.index(0, 0), [4, 4], 3), 0);
        // Negative vector: block (0,0) moved back by (−8,−8) is block (1,1).
        assert_eq!(overlap_pixels(&prev, 0, [-8, -8], 3), 64);
    }

    #[test]
    fn texture_term_matches_hand_values() {
        // c = 32e-6: D = 1000 → 32; D = 0 → 0.
        assert!((texture_energy(1000, &cfg()) - 32.0).abs() < 1e-12);
        assert_eq!(texture_energy(0, &cfg()), 0.0);
        // Frame t−1 all 10, frame t has block (1,1) at 13 elsewhere 10: D at v = 0 is 64·3.
        let prev = GrayImage::from_pixel(32, 32, image::Luma([10]));
        let mut cur = prev.clone();
        for y in 8..16 {
            for x in 8..16 {
                cur.put_pixel(x, y, image::Luma([13]));
            }
        }
        let g = BlockGrid::for_frame(32, 32);
        assert_eq!(texture_sad(&prev, &cur, &g, g.index(1, 1), [0, 0]), 192);
        assert_eq!(texture_sad(&prev, &cur, &g, g.index(0, 0), [0, 0]), 0);
        // A gradient moved by (3, 1): D at the true vector is 0, elsewhere positive.
        let p = GrayImage::from_fn(32, 32, |x, y| image::Luma([(x * 7 + y * 3) as u8]));
        let c = GrayImage::from_fn(32, 32, |x, y| {
            image::Luma([((x as i32 - 3).max(0) * 7 + (y as i32 - 1).max(0) * 3) as u8])
        });
        assert_eq!(texture_sad(&p, &c, &g, g.index(2, 2), [3, 1]), 0);
        assert_eq!(texture_sad(&p, &c, &g, g.index(2, 2), [2, 1]), 64 * 7);
    }

    #[test]
    fn smoothness_term_matches_hand_values() {
        // f = 1/4: neighbours (0,0) and (2,0), v = (1,1): (1+1 + 1+1)/2 · 1/4 = 0.5.
        assert_eq!(smoothness_energy([1, 1], [[0, 0], [2, 0]], &cfg()), 0.5);
        assert_eq!(smoothness_energy([1, 1], [], &cfg()), 0.0);
        assert_eq!(smoothness_energy([4, -3], [[4, -3]; 8], &cfg()), 0.0);
    }

    #[test]
    fn total_is_zero_for_a_perfect_block_and_legacy_has_no_f_term() {
        let perfect = Terms {
            n: 8,
            m: 64,
            d: 0,
            smoothness: 0.0,
        };
        assert_eq!(total_energy(&perfect, &cfg()), 0.0);
        let t = Terms {
            n: 6,
            m: 48,
            d: 500,
            smoothness: 3.0,
        };
        let expected = 0.5 * 4.0 + 256.0 / 256.0 + 32e-6 * 250_000.0;
        let legacy = MrfConfig {
            variant: MrfVariant::Legacy,
            ..cfg()
        };
        assert!((total_energy(&t, &legacy) - expected).abs() < 1e-12);
        assert!((total_energy(&t, &cfg()) - (expected + 3.0)).abs() < 1e-12);
    }
}
