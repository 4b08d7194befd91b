//! Morphological clean-up of a foreground mask (opening, then closing) on a bit-packed
//! mask: 64 pixels per word operation. Re-exported as [`super::regions::clean_mask`].

use super::regions::RegionConfig;

/// Morphological clean-up of a foreground mask: opening then closing with square (L∞)
/// structuring elements.
///
/// Same result as `imageproc::morphology::{open, close}` with `Norm::LInf` (a property test
/// checks it). The mask is packed into 64-pixel words and each square is applied as a
/// horizontal then a vertical pass of word shifts and ORs ([`BitMask`]): 64 pixels per
/// operation, so the four passes cost little beside packing and unpacking the mask.
pub fn clean_mask(mask: &image::GrayImage, config: &RegionConfig) -> image::GrayImage {
    let r_open = u32::from(config.open_radius_px);
    let r_close = u32::from(config.close_radius_px);
    if r_open == 0 && r_close == 0 {
        return mask.clone();
    }
    let mut m = BitMask::pack(mask);
    if r_open > 0 {
        m = m.erode(r_open).dilate(r_open);
    }
    if r_close > 0 {
        m = m.dilate(r_close).erode(r_close);
    }
    m.unpack()
}

/// Opening of `mask` by a square of radius `r` (erosion, then dilation): as [`clean_mask`]
/// with no closing.
pub(crate) fn open(mask: &image::GrayImage, r: u32) -> image::GrayImage {
    BitMask::pack(mask).erode(r).dilate(r).unpack()
}

/// A binary mask, one bit per pixel: row `y`'s pixel `x` is bit `x % 64` of word
/// `y · words_per_row + x / 64`. Bits past the width are always 0.
#[derive(Clone, Debug, PartialEq)]
struct BitMask {
    width: usize,
    height: usize,
    words_per_row: usize,
    words: Vec<u64>,
}

impl BitMask {
    fn empty(width: usize, height: usize) -> Self {
        let words_per_row = width.div_ceil(64);
        Self {
            width,
            height,
            words_per_row,
            words: vec![0; words_per_row * height],
        }
    }

    /// Non-zero pixels of `mask` set.
    fn pack(mask: &image::GrayImage) -> Self {
        let (w, h) = (mask.width() as usize, mask.height() as usize);
        let mut m = Self::empty(w, h);
        if w == 0 {
            return m;
        }
        for (row, dst) in mask
            .as_raw()
            .chunks_exact(w)
            .zip(m.words.chunks_exact_mut(m.words_per_row))
        {
            // Most rows of a traffic frame are empty: one vectorised scan skips them.
            if row.iter().all(|&v| v == 0) {
                continue;
            }
            for (chunk, word) in row.chunks(64).zip(dst.iter_mut()) {
                *word = chunk
                    .iter()
                    .enumerate()
                    .fold(0u64, |acc, (j, &v)| acc | (u64::from(v != 0) << j));
            }
        }
        m
    }

    /// The mask as an image, 255 where set.
    fn unpack(&self) -> image::GrayImage {
        let mut out = vec![0u8; self.width * self.height];
        if self.width > 0 {
            for (row, src) in out
                .chunks_exact_mut(self.width)
                .zip(self.words.chunks_exact(self.words_per_row))
            {
                for (i, &word) in src.iter().enumerate() {
                    let mut bits = word;
                    while bits != 0 {
                        let j = bits.trailing_zeros() as usize;
                        row[64 * i + j] = 255;
                        bits &= bits - 1;
                    }
                }
            }
        }
        image::GrayImage::from_raw(self.width as u32, self.height as u32, out)
            .unwrap_or_else(|| image::GrayImage::new(self.width as u32, self.height as u32))
    }

    /// Mask of the in-image bits of a row's last word.
    fn last_word_mask(&self) -> u64 {
        match self.width % 64 {
            0 => u64::MAX,
            r => (1u64 << r) - 1,
        }
    }

    /// The complement inside the image (bits past the width stay 0).
    fn not(mut self) -> Self {
        let last = self.last_word_mask();
        let n = self.words_per_row;
        for row in self.words.chunks_exact_mut(n.max(1)) {
            for v in row.iter_mut() {
                *v = !*v;
            }
            if let Some(v) = row.last_mut() {
                *v &= last;
            }
        }
        self
    }

    /// Dilation by the `(2r+1)²` square; pixels outside the image count as unset.
    fn dilate(&self, r: u32) -> Self {
        let n = self.words_per_row;
        let mut horiz = Self::empty(self.width, self.height);
        if n == 0 {
            return horiz;
        }
        let last = self.last_word_mask();
        let r = r as isize;
        for (src, dst) in self
            .words
            .chunks_exact(n)
            .zip(horiz.words.chunks_exact_mut(n))
        {
            if src.iter().all(|&v| v == 0) {
                continue;
            }
            for (i, d) in dst.iter_mut().enumerate() {
                let mut acc = src[i];
                for k in 1..=r {
                    acc |= shifted(src, i, k) | shifted(src, i, -k);
                }
                *d = acc;
            }
            dst[n - 1] &= last;
        }
        let mut out = Self::empty(self.width, self.height);
        let h = self.height as isize;
        for y in 0..h {
            let dst = &mut out.words[y as usize * n..(y as usize + 1) * n];
            for yy in (y - r).max(0)..=(y + r).min(h - 1) {
                let src = &horiz.words[yy as usize * n..(yy as usize + 1) * n];
                for (d, &s) in dst.iter_mut().zip(src) {
                    *d |= s;
                }
            }
        }
        out
    }

    /// Erosion by the `(2r+1)²` square; pixels outside the image are ignored (a pixel stays
    /// when every in-image pixel of its window is set, imageproc's convention): the
    /// complement of the complement's dilation.
    fn erode(&self, r: u32) -> Self {
        self.clone().not().dilate(r).not()
    }
}

/// Word `i` of `row` with pixel `x` taking the value of pixel `x + k` (0 outside the row).
#[inline]
fn shifted(row: &[u64], i: usize, k: isize) -> u64 {
    let word = |j: isize| -> u64 {
        if j < 0 || j as usize >= row.len() {
            0
        } else {
            row[j as usize]
        }
    };
    let q = i as isize + k.div_euclid(64);
    let s = k.rem_euclid(64) as u32;
    if s == 0 {
        word(q)
    } else {
        (word(q) >> s) | (word(q + 1) << (64 - s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::regions::extract_regions;
    use image::{GrayImage, Luma, RgbImage};

    proptest::proptest! {
        /// The separable morphology equals imageproc's (the reference) on random masks.
        #[test]
        fn clean_mask_matches_imageproc(w in 1u32..150, h in 1u32..40, seed in 0u64..1000,
                                        open in 0u8..3, close in 0u8..4, density in 1u64..9) {
            use imageproc::distance_transform::Norm;
            use rand::RngExt;
            let mut rng = crate::rng::rng_for(seed, crate::rng::Stream::Synthetic, 0);
            let mask = GrayImage::from_fn(w, h, |_, _| Luma([if rng.random_range(0..10u64) < density { 255 } else { 0 }]));
            let cfg = RegionConfig { open_radius_px: open, close_radius_px: close, ..Default::default() };
            let mut reference = mask.clone();
            if open > 0 {
                proptest::prop_assume!(mask.pixels().any(|p| p[0] == 0));
                reference = imageproc::morphology::open(&reference, Norm::LInf, open);
            }
            if close > 0 {
                // imageproc erodes an image with no background pixel at all to nothing (its
                // distance transform has no seed); ours keeps it, as the pixels outside the
                // image are ignored. Compare only where imageproc's convention applies.
                let dilated = imageproc::morphology::dilate(&reference, Norm::LInf, close);
                proptest::prop_assume!(dilated.pixels().any(|p| p[0] == 0));
                reference = imageproc::morphology::close(&reference, Norm::LInf, close);
            }
            proptest::prop_assert_eq!(clean_mask(&mask, &cfg), reference);
        }
    }

    #[test]
    fn cleaning_removes_speckle_and_keeps_blobs() {
        let mut mask = GrayImage::new(30, 30);
        mask.put_pixel(2, 2, Luma([255]));
        for y in 10..20 {
            for x in 10..20 {
                mask.put_pixel(x, y, Luma([255]));
            }
        }
        let cleaned = clean_mask(&mask, &RegionConfig::default());
        assert_eq!(cleaned.get_pixel(2, 2)[0], 0);
        let cfg = RegionConfig {
            min_area_px: 1,
            ..Default::default()
        };
        let r = extract_regions(&cleaned, &RgbImage::new(30, 30), &cfg);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].area_px, 100);
    }
}
