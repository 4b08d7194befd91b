//! Block matching by the sum of absolute differences (SAD), Step 1 of METHODS.md §2.
//!
//! Every block of frame `t − 1` that carries an object gets the displacement `v` within
//! `±search_radius_px` in each axis that minimises
//!
//! ```text
//! SAD(v) = Σ_{0≤di,dj<8} |G(t; x+di+v_x, y+dj+v_y) − G(t−1; x+di, y+dj)|
//! ```
//!
//! on the luminance planes. Candidate squares must lie inside frame `t`.
//!
//! This is the tracker's hot loop. The fast path ([`match_block`]):
//! - reads each 8-px row as one `u64` from contiguous row-major memory;
//! - sums two rows per instruction with SSE2 `psadbw` on x86-64 (part of the baseline;
//!   one small `unsafe` block, tested against the scalar kernel), and with a portable scalar
//!   loop elsewhere;
//! - evaluates a guessed vector first (the previous frame's vector of the block's object)
//!   to get a tight bound, then stops summing a candidate as soon as its partial SAD exceeds
//!   the best so far (early termination);
//! - runs blocks in parallel with rayon, collecting in block order, so the result does not
//!   depend on the thread count.
//!
//! Ties are broken by a total order (smaller SAD, then smaller `|v_x| + |v_y|`, then
//! smaller `v_y`, then smaller `v_x`), so the fast path and the brute-force reference
//! [`match_block_reference`] return the same vector, which a property test checks.

use super::object_map::{BLOCK_PX, Vector};
use image::{GrayImage, RgbImage};
use rayon::prelude::*;

/// The result of matching one block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockMatch {
    /// Best displacement from `t − 1` to `t`, px.
    pub vector: Vector,
    /// Its SAD over the 64 pixels (luminance levels).
    pub sad: u32,
}

/// Luminance `Y = (77 R + 150 G + 29 B) / 256` (BT.601 weights in 8-bit fixed point).
// Choice: the texture term D (eq. 2) and block matching use luminance, not the sum over
// channels (the paper's G is a grey level; its weight c = 32/1 000 000 fits 8-bit grey).
pub fn gray_from_rgb(image: &RgbImage) -> GrayImage {
    let (w, h) = image.dimensions();
    let raw: Vec<u8> = image
        .as_raw()
        .chunks_exact(3)
        .map(|p| ((77 * u32::from(p[0]) + 150 * u32::from(p[1]) + 29 * u32::from(p[2])) >> 8) as u8)
        .collect();
    GrayImage::from_raw(w, h, raw).unwrap_or_else(|| GrayImage::new(w, h))
}

/// The 8 rows of the block whose top-left pixel is `(x, y)` as little-endian `u64`s.
/// The caller guarantees the block lies inside the image.
#[inline]
pub(crate) fn load_rows(data: &[u8], stride: usize, x: usize, y: usize) -> [u64; 8] {
    let mut rows = [0u64; 8];
    for (r, row) in rows.iter_mut().enumerate() {
        let off = (y + r) * stride + x;
        let mut b = [0u8; 8];
        b.copy_from_slice(&data[off..off + 8]);
        *row = u64::from_le_bytes(b);
    }
    rows
}

/// SAD of two 8-byte rows, scalar (the reference the SIMD path is tested against).
#[inline]
pub fn sad_row_scalar(a: u64, b: u64) -> u32 {
    let (a, b) = (a.to_le_bytes(), b.to_le_bytes());
    let mut s = 0u32;
    for i in 0..8 {
        s += u32::from(a[i].abs_diff(b[i]));
    }
    s
}

/// SAD of two pairs of 8-byte rows, `|a0 − b0| + |a1 − b1|` summed over bytes: SSE2
/// `psadbw` on x86-64 (measured faster than the scalar loop in the dev profile, see
/// docs/PERFORMANCE.md "MRF"), [`sad_row_pair_scalar`] elsewhere.
#[inline]
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[allow(unsafe_code)]
pub fn sad_row_pair(a0: u64, a1: u64, b0: u64, b1: u64) -> u32 {
    use std::arch::x86_64::{_mm_cvtsi128_si32, _mm_extract_epi16, _mm_sad_epu8, _mm_set_epi64x};
    // SAFETY: these intrinsics only need SSE2, which this function is compiled for
    // (`cfg(target_feature = "sse2")`, part of the x86-64 baseline); they take values, not
    // pointers, so there is no memory access to get wrong.
    unsafe {
        let a = _mm_set_epi64x(a1 as i64, a0 as i64);
        let b = _mm_set_epi64x(b1 as i64, b0 as i64);
        let s = _mm_sad_epu8(a, b);
        (_mm_cvtsi128_si32(s) + _mm_extract_epi16::<4>(s)) as u32
    }
}

/// SAD of two pairs of 8-byte rows (portable fallback).
#[inline]
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
pub fn sad_row_pair(a0: u64, a1: u64, b0: u64, b1: u64) -> u32 {
    sad_row_pair_scalar(a0, a1, b0, b1)
}

/// SAD of two pairs of 8-byte rows with the scalar kernel (reference of [`sad_row_pair`]).
#[inline]
pub fn sad_row_pair_scalar(a0: u64, a1: u64, b0: u64, b1: u64) -> u32 {
    sad_row_scalar(a0, b0) + sad_row_scalar(a1, b1)
}

/// SAD between the block `rows` and the block at `(x, y)` of `data`, abandoned (returning
/// a value `> bound`) as soon as the partial sum exceeds `bound`.
#[inline]
pub(crate) fn sad_bounded_with<const SIMD: bool>(
    rows: &[u64; 8],
    data: &[u8],
    stride: usize,
    x: usize,
    y: usize,
    bound: u32,
) -> u32 {
    let c = load_rows(data, stride, x, y);
    let mut s = 0u32;
    for p in 0..4 {
        s += if SIMD {
            sad_row_pair(rows[2 * p], rows[2 * p + 1], c[2 * p], c[2 * p + 1])
        } else {
            sad_row_pair_scalar(rows[2 * p], rows[2 * p + 1], c[2 * p], c[2 * p + 1])
        };
        if s > bound {
            return s;
        }
    }
    s
}

/// [`sad_bounded_with`] with the fast kernel.
#[inline]
pub(crate) fn sad_bounded(
    rows: &[u64; 8],
    data: &[u8],
    stride: usize,
    x: usize,
    y: usize,
    bound: u32,
) -> u32 {
    sad_bounded_with::<true>(rows, data, stride, x, y, bound)
}

/// Full SAD between block `rows` and the block at `(x, y)` of `data`.
#[inline]
pub(crate) fn sad_full(rows: &[u64; 8], data: &[u8], stride: usize, x: usize, y: usize) -> u32 {
    sad_bounded(rows, data, stride, x, y, u32::MAX)
}

/// Tie-break key: smaller is preferred among equal SADs.
#[inline]
fn key(v: Vector) -> (i32, i16, i16) {
    (i32::from(v[0]).abs() + i32::from(v[1]).abs(), v[1], v[0])
}

#[inline]
fn better(sad: u32, v: Vector, best_sad: u32, best_v: Vector) -> bool {
    sad < best_sad || (sad == best_sad && key(v) < key(best_v))
}

/// The range of displacements along one axis that keeps an 8-px block starting at `pos`
/// inside `[0, size)` and within `±radius`.
#[inline]
fn axis_range(pos: u32, size: u32, radius: u32) -> (i32, i32) {
    let lo = -(radius.min(pos) as i32);
    let max_pos = size.saturating_sub(BLOCK_PX);
    let hi = (radius.min(max_pos.saturating_sub(pos))) as i32;
    (lo, hi)
}

/// Matches the block `(bx, by)` of `prev` into `cur` (fast path; see the module doc).
///
/// `guess` is evaluated first when it is in range; it changes only the speed, never the
/// result. Both images must have the same size and hold the block.
pub fn match_block(
    prev: &GrayImage,
    cur: &GrayImage,
    bx: u32,
    by: u32,
    radius_px: u32,
    guess: Vector,
) -> BlockMatch {
    match_block_with::<true>(prev, cur, bx, by, radius_px, guess)
}

/// [`match_block`] with the scalar row kernel (`SIMD = false`) or the fast one; the scalar
/// form exists to measure what the SIMD kernel buys (docs/PERFORMANCE.md "MRF").
pub fn match_block_with<const SIMD: bool>(
    prev: &GrayImage,
    cur: &GrayImage,
    bx: u32,
    by: u32,
    radius_px: u32,
    guess: Vector,
) -> BlockMatch {
    let (w, h) = prev.dimensions();
    let stride = w as usize;
    let (x0, y0) = (bx * BLOCK_PX, by * BLOCK_PX);
    let rows = load_rows(prev.as_raw(), stride, x0 as usize, y0 as usize);
    let data = cur.as_raw();
    let (xlo, xhi) = axis_range(x0, w, radius_px);
    let (ylo, yhi) = axis_range(y0, h, radius_px);
    let at = |vx: i32, vy: i32| ((x0 as i32 + vx) as usize, (y0 as i32 + vy) as usize);
    let mut best_v: Vector = [0, 0];
    let mut best_sad = u32::MAX;
    for g in [guess, [0, 0]] {
        let (gx, gy) = (i32::from(g[0]), i32::from(g[1]));
        if (xlo..=xhi).contains(&gx) && (ylo..=yhi).contains(&gy) {
            let (x, y) = at(gx, gy);
            let s = sad_full(&rows, data, stride, x, y);
            if better(s, g, best_sad, best_v) {
                best_sad = s;
                best_v = g;
            }
        }
    }
    for vy in ylo..=yhi {
        for vx in xlo..=xhi {
            let (x, y) = at(vx, vy);
            let s = sad_bounded_with::<SIMD>(&rows, data, stride, x, y, best_sad);
            let v = [vx as i16, vy as i16];
            if s <= best_sad && better(s, v, best_sad, best_v) {
                best_sad = s;
                best_v = v;
            }
        }
    }
    BlockMatch {
        vector: best_v,
        sad: best_sad,
    }
}

/// Brute-force reference: every candidate summed in full with the scalar kernel, the
/// minimum under the same total order. For tests.
pub fn match_block_reference(
    prev: &GrayImage,
    cur: &GrayImage,
    bx: u32,
    by: u32,
    radius_px: u32,
) -> BlockMatch {
    let (w, h) = prev.dimensions();
    let (x0, y0) = ((bx * BLOCK_PX) as i64, (by * BLOCK_PX) as i64);
    let r = i64::from(radius_px);
    let mut best: Option<(u32, Vector)> = None;
    for vy in -r..=r {
        for vx in -r..=r {
            let (x, y) = (x0 + vx, y0 + vy);
            if x < 0 || y < 0 || x + 8 > i64::from(w) || y + 8 > i64::from(h) {
                continue;
            }
            let mut s = 0u32;
            for dj in 0..8 {
                for di in 0..8 {
                    let a = prev.get_pixel((x0 + di) as u32, (y0 + dj) as u32)[0];
                    let b = cur.get_pixel((x + di) as u32, (y + dj) as u32)[0];
                    s += u32::from(a.abs_diff(b));
                }
            }
            let v = [vx as i16, vy as i16];
            if best.is_none_or(|(bs, bv)| better(s, v, bs, bv)) {
                best = Some((s, v));
            }
        }
    }
    let (sad, vector) = best.unwrap_or((0, [0, 0]));
    BlockMatch { vector, sad }
}

/// Matches every block in `blocks` (row-major indices on a grid of `cols` blocks per row),
/// in parallel, returning results in the order of `blocks`. `guesses[i]` is the guess for
/// `blocks[i]` (see [`match_block`]).
pub fn match_blocks(
    prev: &GrayImage,
    cur: &GrayImage,
    cols: u32,
    blocks: &[usize],
    guesses: &[Vector],
    radius_px: u32,
) -> Vec<BlockMatch> {
    blocks
        .par_iter()
        .with_min_len(16)
        .enumerate()
        .map(|(i, &b)| {
            let (bx, by) = ((b % cols as usize) as u32, (b / cols as usize) as u32);
            let g = guesses.get(i).copied().unwrap_or([0, 0]);
            match_block(prev, cur, bx, by, radius_px, g)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Stream, rng_for};
    use proptest::prelude::*;

    fn random_gray(w: u32, h: u32, seed: u64, levels: u8) -> GrayImage {
        let mut r = rng_for(seed, Stream::Synthetic, 1);
        let raw = (0..w * h).map(|_| r.random_range(0..levels)).collect();
        GrayImage::from_raw(w, h, raw).unwrap_or_default()
    }

    fn shifted(img: &GrayImage, dx: i32, dy: i32, fill_seed: u64) -> GrayImage {
        let (w, h) = img.dimensions();
        let noise = random_gray(w, h, fill_seed, 255);
        GrayImage::from_fn(w, h, |x, y| {
            let (sx, sy) = (x as i32 - dx, y as i32 - dy);
            if sx >= 0 && sy >= 0 && sx < w as i32 && sy < h as i32 {
                *img.get_pixel(sx as u32, sy as u32)
            } else {
                *noise.get_pixel(x, y)
            }
        })
    }

    #[test]
    fn simd_pair_kernel_equals_scalar_kernel() {
        let mut r = rng_for(3, Stream::Synthetic, 2);
        for _ in 0..10_000 {
            let (a0, a1, b0, b1): (u64, u64, u64, u64) =
                (r.random(), r.random(), r.random(), r.random());
            assert_eq!(
                sad_row_pair(a0, a1, b0, b1),
                sad_row_scalar(a0, b0) + sad_row_scalar(a1, b1)
            );
        }
        assert_eq!(sad_row_pair(u64::MAX, u64::MAX, 0, 0), 16 * 255);
    }

    #[test]
    fn recovers_a_known_shift() {
        let prev = random_gray(96, 80, 5, 255);
        let cur = shifted(&prev, 7, -5, 9);
        let m = match_block(&prev, &cur, 5, 5, 24, [0, 0]);
        assert_eq!(
            m,
            BlockMatch {
                vector: [7, -5],
                sad: 0
            }
        );
    }

    #[test]
    fn candidates_stay_inside_the_frame() {
        let prev = random_gray(40, 40, 1, 255);
        let cur = random_gray(40, 40, 2, 255);
        let m = match_block(&prev, &cur, 0, 4, 24, [-24, -24]);
        assert!(m.vector[0] >= 0 && m.vector[1] <= 0, "{m:?}");
        assert_eq!(m, match_block_reference(&prev, &cur, 0, 4, 24));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// The fast search (any guess, any thread count) finds the brute-force vector and SAD,
        /// on random images with few grey levels (many ties) and with a true shift.
        #[test]
        fn fast_search_agrees_with_brute_force(seed in 0u64..1000, w in 24u32..72, h in 24u32..64,
                                               levels in prop::sample::select(vec![2u8, 4, 255]),
                                               dx in -10i32..=10, dy in -10i32..=10,
                                               gx in -12i16..=12, gy in -12i16..=12,
                                               radius in prop::sample::select(vec![0u32, 3, 8, 24])) {
            let prev = random_gray(w, h, seed, levels);
            let cur = shifted(&prev, dx, dy, seed + 1);
            let grid = super::super::object_map::BlockGrid::for_frame(w, h);
            let blocks: Vec<usize> = (0..grid.len()).collect();
            let guesses = vec![[gx, gy]; blocks.len()];
            let fast = match_blocks(&prev, &cur, grid.cols, &blocks, &guesses, radius);
            for (i, &b) in blocks.iter().enumerate() {
                let (bx, by) = grid.coords(b);
                prop_assert_eq!(fast[i], match_block_reference(&prev, &cur, bx, by, radius));
            }
        }
    }
}
