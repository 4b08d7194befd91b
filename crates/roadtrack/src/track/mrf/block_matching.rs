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
//! This is the tracker's hot loop. On x86-64 CPUs with SSE4.1 (checked at run time),
//! [`match_block`] runs an exhaustive search that computes eight horizontal candidates at
//! once: per block row, two `mpsadbw` (SAD of 4 bytes against 8 sliding positions) give the
//! row's SAD at 8 offsets, eight rows are summed in 16-bit lanes, and `phminposuw` finds the
//! chunk's minimum; only a chunk whose minimum reaches the best so far is examined lane by
//! lane (ties). With AVX2 two vertical displacements go through the two 128-bit lanes at
//! once (16 candidates per step). About 40 instructions per step, no data-dependent
//! branches; the result is exactly the brute force's.
//!
//! Elsewhere the portable path ([`match_block_with`]):
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
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        return match_block_simd(prev, cur, bx, by, radius_px, true);
    } else if std::arch::is_x86_feature_detected!("sse4.1") {
        return match_block_simd(prev, cur, bx, by, radius_px, false);
    }
    match_block_with::<true>(prev, cur, bx, by, radius_px, guess)
}

/// Exhaustive search with `mpsadbw`, 8 horizontal candidates per step with SSE4.1, or
/// 8 horizontal × 2 vertical with AVX2 when `avx2` (see the module doc). Same result as
/// [`match_block_reference`].
///
/// # Panics
/// When the CPU lacks SSE4.1, or AVX2 when `avx2` is asked for (check
/// `is_x86_feature_detected!` first).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
pub fn match_block_simd(
    prev: &GrayImage,
    cur: &GrayImage,
    bx: u32,
    by: u32,
    radius_px: u32,
    avx2: bool,
) -> BlockMatch {
    assert!(
        std::arch::is_x86_feature_detected!("sse4.1"),
        "match_block_simd needs SSE4.1"
    );
    assert!(
        !avx2 || std::arch::is_x86_feature_detected!("avx2"),
        "match_block_simd(avx2 = true) needs AVX2"
    );
    let (w, h) = prev.dimensions();
    let stride = w as usize;
    let (x0, y0) = (bx * BLOCK_PX, by * BLOCK_PX);
    let rows = load_rows(prev.as_raw(), stride, x0 as usize, y0 as usize);
    let (xlo, xhi) = axis_range(x0, w, radius_px);
    let (ylo, yhi) = axis_range(y0, h, radius_px);
    let mut best = (u32::MAX, [0i16, 0i16]);
    let mut vy = ylo;
    if avx2 {
        // SAFETY: AVX2 is present (asserted above); `search_avx2` checks every load against
        // the slice's length itself.
        vy = unsafe {
            search_avx2(
                &rows,
                cur.as_raw(),
                stride,
                (x0, y0),
                (xlo, xhi),
                (vy, yhi),
                &mut best,
            )
        };
    }
    // SAFETY: SSE4.1 is present (asserted above); `search_sse41` checks every load against
    // the slice's length itself.
    unsafe {
        search_sse41(
            &rows,
            cur.as_raw(),
            stride,
            (x0, y0),
            (xlo, xhi),
            (vy, yhi),
            &mut best,
        )
    };
    BlockMatch {
        vector: best.1,
        sad: best.0,
    }
}

/// Lanes `≥ n` of eight 16-bit lanes set to `0xFFFF` (masks candidates past `xhi`).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
#[inline]
fn lane_mask(n: usize) -> std::arch::x86_64::__m128i {
    let mut m = [0u16; 8];
    for (k, v) in m.iter_mut().enumerate() {
        if k >= n {
            *v = u16::MAX;
        }
    }
    // SAFETY: `_mm_loadu_si128` reads 16 bytes from a 16-byte array (SSE2, baseline).
    unsafe { std::arch::x86_64::_mm_loadu_si128(m.as_ptr().cast()) }
}

/// Folds the 8 lane SADs of a chunk (candidates `vx0 .. vx0 + lanes` at `vy`) into `best`
/// under the total order of [`better`].
#[inline]
fn fold_chunk(sads: &[u16; 8], lanes: usize, vx0: i32, vy: i32, best: &mut (u32, Vector)) {
    for (k, &s) in sads.iter().enumerate().take(lanes) {
        let v = [(vx0 + k as i32) as i16, vy as i16];
        if better(u32::from(s), v, best.0, best.1) {
            *best = (u32::from(s), v);
        }
    }
}

/// Two vertical displacements `vy, vy + 1` per step in the two 128-bit lanes of AVX2
/// `vmpsadbw`; returns the first `vy` not done (the caller finishes an odd one with
/// [`search_sse41`]). Pairs whose loads would leave `data` are left to the caller too.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn search_avx2(
    rows: &[u64; 8],
    data: &[u8],
    stride: usize,
    (x0, y0): (u32, u32),
    (xlo, xhi): (i32, i32),
    (ylo, yhi): (i32, i32),
    best: &mut (u32, Vector),
) -> i32 {
    use std::arch::x86_64::{
        __m256i, _mm_cvtsi128_si32, _mm_loadu_si128, _mm_min_epu16, _mm_minpos_epu16,
        _mm_storeu_si128, _mm256_add_epi16, _mm256_castsi256_si128, _mm256_extracti128_si256,
        _mm256_mpsadbw_epu8, _mm256_or_si256, _mm256_set_m128i, _mm256_set1_epi64x,
        _mm256_setzero_si256,
    };
    let block: [__m256i; 8] = rows.map(|r| _mm256_set1_epi64x(r as i64));
    let mut vy = ylo;
    while vy < yhi {
        let y = (y0 as i32 + vy) as usize;
        // Last byte read by the pair: row y + 8 (= (y + 1) + 7), 16 bytes from x.
        if (y + 8) * stride + (x0 as i32 + xhi) as usize + 16 > data.len() {
            break;
        }
        let mut vx0 = xlo;
        while vx0 <= xhi {
            let x = (x0 as i32 + vx0) as usize;
            let lanes = ((xhi - vx0 + 1) as usize).min(8);
            let mut acc = _mm256_setzero_si256();
            for (r, b) in block.iter().enumerate() {
                // SAFETY: (y + 1 + r) * stride + x + 16 ≤ (y + 8) * stride + x0 + xhi + 16
                // ≤ data.len() (checked above), and the low-lane row is earlier.
                let (lo, hi) = unsafe {
                    (
                        _mm_loadu_si128(data.as_ptr().add((y + r) * stride + x).cast()),
                        _mm_loadu_si128(data.as_ptr().add((y + 1 + r) * stride + x).cast()),
                    )
                };
                let a = _mm256_set_m128i(hi, lo);
                acc = _mm256_add_epi16(acc, _mm256_mpsadbw_epu8::<0b000_000>(a, *b));
                acc = _mm256_add_epi16(acc, _mm256_mpsadbw_epu8::<0b101_101>(a, *b));
            }
            if lanes < 8 {
                let m = lane_mask(lanes);
                acc = _mm256_or_si256(acc, _mm256_set_m128i(m, m));
            }
            let (lo, hi) = (
                _mm256_castsi256_si128(acc),
                _mm256_extracti128_si256::<1>(acc),
            );
            let min = (_mm_cvtsi128_si32(_mm_minpos_epu16(_mm_min_epu16(lo, hi))) & 0xFFFF) as u32;
            if min <= best.0 {
                let (mut s0, mut s1) = ([0u16; 8], [0u16; 8]);
                // SAFETY: each writes 16 bytes into a 16-byte array.
                unsafe {
                    _mm_storeu_si128(s0.as_mut_ptr().cast(), lo);
                    _mm_storeu_si128(s1.as_mut_ptr().cast(), hi);
                }
                fold_chunk(&s0, lanes, vx0, vy, best);
                fold_chunk(&s1, lanes, vx0, vy + 1, best);
            }
            vx0 += 8;
        }
        vy += 2;
    }
    vy
}

/// The body of [`match_block_sse41`]. Loads of 16 bytes start at `x0 + vx` for chunk
/// starts `vx`; a chunk whose 16-byte loads would leave `data` is done with the scalar
/// kernel instead. Lanes past `xhi` (inside `data`, but off the allowed range) are masked.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
#[allow(unsafe_code)]
unsafe fn search_sse41(
    rows: &[u64; 8],
    data: &[u8],
    stride: usize,
    (x0, y0): (u32, u32),
    (xlo, xhi): (i32, i32),
    (ylo, yhi): (i32, i32),
    best: &mut (u32, Vector),
) {
    use std::arch::x86_64::{
        __m128i, _mm_add_epi16, _mm_cvtsi128_si32, _mm_loadu_si128, _mm_minpos_epu16,
        _mm_mpsadbw_epu8, _mm_or_si128, _mm_set_epi64x, _mm_setzero_si128, _mm_storeu_si128,
    };
    let block: [__m128i; 8] = rows.map(|r| _mm_set_epi64x(0, r as i64));
    for vy in ylo..=yhi {
        let y = (y0 as i32 + vy) as usize;
        let mut vx0 = xlo;
        while vx0 <= xhi {
            let x = (x0 as i32 + vx0) as usize;
            let lanes = ((xhi - vx0 + 1) as usize).min(8);
            let mut sads = [u16::MAX; 8];
            if (y + 7) * stride + x + 16 <= data.len() {
                let mut acc = _mm_setzero_si128();
                for (r, b) in block.iter().enumerate() {
                    // SAFETY: (y + r) * stride + x + 16 ≤ data.len() (checked above).
                    let a =
                        unsafe { _mm_loadu_si128(data.as_ptr().add((y + r) * stride + x).cast()) };
                    acc = _mm_add_epi16(acc, _mm_mpsadbw_epu8::<0b000>(a, *b));
                    acc = _mm_add_epi16(acc, _mm_mpsadbw_epu8::<0b101>(a, *b));
                }
                if lanes < 8 {
                    acc = _mm_or_si128(acc, lane_mask(lanes));
                }
                let min = (_mm_cvtsi128_si32(_mm_minpos_epu16(acc)) & 0xFFFF) as u32;
                if min > best.0 {
                    vx0 += 8;
                    continue;
                }
                // SAFETY: writes 16 bytes into a 16-byte array.
                unsafe { _mm_storeu_si128(sads.as_mut_ptr().cast(), acc) };
            } else {
                for (k, s) in sads.iter_mut().enumerate().take(lanes) {
                    *s = sad_full(rows, data, stride, x + k, y) as u16;
                }
            }
            fold_chunk(&sads, lanes, vx0, vy, best);
            vx0 += 8;
        }
    }
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

    #[test]
    fn every_search_path_agrees_with_brute_force_at_the_frame_edges() {
        // Blocks in every corner and along the last row, where the SIMD path's 16-byte loads
        // would leave the image and fall back to the scalar kernel.
        for (w, h, seed) in [(40u32, 40u32, 11u64), (64, 24, 12), (27, 33, 13)] {
            let prev = random_gray(w, h, seed, 4);
            let cur = shifted(&prev, 3, -2, seed + 7);
            let grid = super::super::object_map::BlockGrid::for_frame(w, h);
            for b in 0..grid.len() {
                let (bx, by) = grid.coords(b);
                for r in [0u32, 5, 24] {
                    let want = match_block_reference(&prev, &cur, bx, by, r);
                    assert_eq!(
                        match_block_with::<true>(&prev, &cur, bx, by, r, [1, 1]),
                        want
                    );
                    assert_eq!(
                        match_block_with::<false>(&prev, &cur, bx, by, r, [0, 0]),
                        want
                    );
                    #[cfg(target_arch = "x86_64")]
                    if std::arch::is_x86_feature_detected!("sse4.1") {
                        assert_eq!(match_block_simd(&prev, &cur, bx, by, r, false), want);
                    }
                    #[cfg(target_arch = "x86_64")]
                    if std::arch::is_x86_feature_detected!("avx2") {
                        assert_eq!(match_block_simd(&prev, &cur, bx, by, r, true), want);
                    }
                }
            }
        }
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
