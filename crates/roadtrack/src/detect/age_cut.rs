//! Cutting a foreground region where the age of its pixels jumps
//! (`[regions] age_gap_s`).
//!
//! A queued vehicle has been foreground for many seconds; a person walking past it, or a
//! vehicle driving by, only for the fraction of a second that its body takes to pass a
//! pixel. Where the two touch in the image the cleaned mask joins them into one region, and
//! the person is lost inside the queue's box. The background model knows how long each
//! pixel of the cleaned mask has been foreground without a break
//! ([`super::background_model::BackgroundModel::held_since`]): across the contact the age
//! jumps by seconds, while inside one object it changes smoothly (a vehicle that drives up
//! and stops covers its pixels one after another, a frame or so apart).
//!
//! Ages are kept here ([`AgeMap`]), not read from the model's hold: a pixel inside a
//! queued vehicle that drops out of the cleaned mask for a frame or two (a road-coloured
//! roof, the closing's edge) keeps its age when it comes back within `age_grace_s`, so the
//! vehicle is not cut along its own flicker.
//!
//! The cut: a mask pixel is left out of the labelling when one of its 8 neighbours in the
//! mask became foreground more than `age_gap_s` earlier. After the cut no two 8-adjacent
//! pixels differ in age by more than the gap, so the younger object is a region of its own;
//! it loses the one-pixel seam along the contact. The mask the model learns under is not
//! changed.

use image::GrayImage;

/// Since when each pixel has been foreground, forgiving short breaks.
#[derive(Debug, Clone, Default)]
pub struct AgeMap {
    /// Time (s) since which the pixel has been in the mask, breaks of at most the grace
    /// time forgiven; NaN when it has not been in the mask.
    since: Vec<f32>,
    /// Time (s) the pixel was last in the mask; NaN before.
    last: Vec<f32>,
    scratch: Scratch,
}

impl AgeMap {
    /// Takes in the cleaned mask of the frame at `time_s`: a pixel in the mask that was out
    /// of it for more than `grace_s` (or never in it) starts its age now.
    pub fn update(&mut self, mask: &GrayImage, time_s: f64, grace_s: f64) {
        let n = mask.as_raw().len();
        if self.since.len() != n {
            self.since = vec![f32::NAN; n];
            self.last = vec![f32::NAN; n];
        }
        let (t, grace) = (time_s as f32, grace_s as f32);
        // Only pixels in the mask change.
        for_each_on(mask.as_raw(), |i| {
            // NaN compares false: a pixel never seen starts now.
            let recent = t - self.last[i] <= grace;
            if !recent {
                self.since[i] = t;
            }
            self.last[i] = t;
        });
    }

    /// Per pixel, the time since which it has been foreground (NaN: never).
    pub fn since(&self) -> &[f32] {
        &self.since
    }

    /// [`cut_by_age`] with these ages, reusing buffers between frames.
    pub fn cut(&mut self, mask: &GrayImage, gap_s: f32, min_piece_px: u32) -> Option<GrayImage> {
        cut_with(mask, &self.since, gap_s, min_piece_px, &mut self.scratch)
    }
}

/// The mask to label: `mask` without the pixels that touch (8-neighbourhood) a mask pixel
/// whose `held_since` is more than `gap_s` earlier than theirs. `None` when nothing is cut
/// (the caller labels `mask` itself).
///
/// `held_since[i]` is the time (s) since which pixel `i` has been in the mask without a
/// break; pixels outside the mask and non-finite times take no part.
pub fn cut_by_age(
    mask: &GrayImage,
    held_since: &[f32],
    gap_s: f32,
    min_piece_px: u32,
) -> Option<GrayImage> {
    cut_with(
        mask,
        held_since,
        gap_s,
        min_piece_px,
        &mut Scratch::default(),
    )
}

/// Buffers of [`cut_by_age`], kept between frames by [`AgeMap::cut`].
#[derive(Debug, Clone, Default)]
struct Scratch {
    /// Indices of the pixels cut.
    cut: Vec<usize>,
}

// Choice: the test visits only the mask's pixels (a tenth of the frame or less in traffic),
// skipping empty stretches of the mask eight bytes at a time, on one thread. The first
// version ran dense passes over every pixel of the frame (a separable 3 × 3 minimum of the
// ages, on the rayon threads) and cost about 30 % of the detector's throughput at 640 × 480
// (docs/PERFORMANCE.md "The age cut's cost"); the cut pixels are the same.
fn cut_with(
    mask: &GrayImage,
    held_since: &[f32],
    gap_s: f32,
    min_piece_px: u32,
    scratch: &mut Scratch,
) -> Option<GrayImage> {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    if held_since.len() != w * h || gap_s.is_nan() || gap_s <= 0.0 || w == 0 || h == 0 {
        return None;
    }
    let m = mask.as_raw();
    // A pixel's age when it is in the mask with a finite time.
    let age = |i: usize| {
        let t = held_since[i];
        (m[i] != 0 && t.is_finite()).then_some(t)
    };
    let cut = &mut scratch.cut;
    cut.clear();
    for y in 0..h {
        let rows = y.saturating_sub(1)..(y + 2).min(h);
        for_each_on(&m[y * w..(y + 1) * w], |x| {
            let Some(t) = age(y * w + x) else { return };
            let cols = x.saturating_sub(1)..(x + 2).min(w);
            let older = rows.clone().any(|yy| {
                cols.clone()
                    .any(|xx| age(yy * w + xx).is_some_and(|s| s < t - gap_s))
            });
            if older {
                cut.push(y * w + x);
            }
        });
    }
    if cut.is_empty() {
        return None;
    }
    let mut out = mask.clone();
    for &i in cut.iter() {
        out.as_mut()[i] = 0;
    }
    if min_piece_px <= 1 {
        return Some(out);
    }
    rejoin_small_pieces(&mut out, cut, min_piece_px);
    // Every piece may have been joined again.
    (out != *mask).then_some(out)
}

/// Calls `f` with the index of every non-zero byte of `m`, in order, passing over
/// all-zero runs of eight bytes in one test.
fn for_each_on(m: &[u8], mut f: impl FnMut(usize)) {
    let mut words = m.chunks_exact(8);
    for (k, c) in words.by_ref().enumerate() {
        let word = u64::from_ne_bytes(c.try_into().expect("eight bytes"));
        if word == 0 {
            continue;
        }
        for (j, &v) in c.iter().enumerate() {
            if v != 0 {
                f(8 * k + j);
            }
        }
    }
    let tail = m.len() - m.len() % 8;
    for (j, &v) in words.remainder().iter().enumerate() {
        if v != 0 {
            f(tail + j);
        }
    }
}

/// Puts back every cut pixel that touches (8-neighbourhood) a piece of the cut mask
/// smaller than `min_piece_px`, so that such a piece is joined again to what it was cut
/// from: the flicker of a standing person's limbs, an old patch under a vehicle driving
/// over it.
fn rejoin_small_pieces(out: &mut GrayImage, cut: &[usize], min_piece_px: u32) {
    let (w, h) = (out.width() as usize, out.height() as usize);
    // Per pixel, whether it belongs to a small piece.
    let mut small = vec![false; w * h];
    for runs in super::regions::component_runs(out) {
        let area: u32 = runs.iter().map(|&(_, x0, x1)| x1 - x0).sum();
        if area < min_piece_px {
            for (y, x0, x1) in runs {
                let row = y as usize * w;
                small[row + x0 as usize..row + x1 as usize].fill(true);
            }
        }
    }
    for &i in cut {
        let (x, y) = (i % w, i / w);
        let touches = (y.saturating_sub(1)..=(y + 1).min(h - 1))
            .any(|yy| (x.saturating_sub(1)..=(x + 1).min(w - 1)).any(|xx| small[yy * w + xx]));
        if touches {
            out.as_mut()[i] = 255;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{AgeMap, cut_by_age};
    use crate::detect::regions::{RegionConfig, extract_regions};
    use image::{GrayImage, RgbImage};

    /// A 40 × 20 mask with two touching 10 × 10 blocks, x 5–14 and 15–24, foreground
    /// since `left` and `right` seconds.
    fn two_blocks(left: f32, right: f32) -> (GrayImage, Vec<f32>) {
        let (w, h) = (40u32, 20u32);
        let mut mask = GrayImage::new(w, h);
        let mut since = vec![f32::NAN; (w * h) as usize];
        for y in 5..15 {
            for x in 5..25 {
                mask.put_pixel(x, y, image::Luma([255]));
                since[(y * w + x) as usize] = if x < 15 { left } else { right };
            }
        }
        (mask, since)
    }

    fn regions(mask: &GrayImage) -> Vec<crate::detect::regions::Region> {
        let cfg = RegionConfig {
            min_area_px: 1,
            ..RegionConfig::default()
        };
        extract_regions(mask, &RgbImage::new(mask.width(), mask.height()), &cfg)
    }

    #[test]
    fn a_young_object_touching_an_old_one_becomes_its_own_region() {
        // A queued block foreground since t = 1 s, a passer-by since t = 9.8 s.
        let (mask, since) = two_blocks(1.0, 9.8);
        assert_eq!(regions(&mask).len(), 1, "joined before the cut");
        let cut = cut_by_age(&mask, &since, 1.0, 0).expect("something cut");
        let r = regions(&cut);
        assert_eq!(r.len(), 2);
        // The old block keeps every pixel; the young one loses its seam column (x = 15).
        assert_eq!(
            (r[0].bbox.left, r[0].bbox.width, r[0].area_px),
            (5.0, 10.0, 100)
        );
        assert_eq!(
            (r[1].bbox.left, r[1].bbox.width, r[1].area_px),
            (16.0, 9.0, 90)
        );
        // The same ages the other way round cut the other block's seam.
        let (mask, since) = two_blocks(9.8, 1.0);
        let r = regions(&cut_by_age(&mask, &since, 1.0, 0).expect("cut"));
        assert_eq!((r[0].bbox.width, r[1].bbox.width), (9.0, 10.0));
    }

    #[test]
    fn ages_within_the_gap_or_changing_smoothly_are_not_cut() {
        let (mask, since) = two_blocks(1.0, 1.9);
        assert!(cut_by_age(&mask, &since, 1.0, 0).is_none());
        // A vehicle that drove up and stopped: each column a frame (0.1 s) younger than
        // the one behind it, 20 columns, 1.9 s from end to end.
        let (mask, mut since) = two_blocks(0.0, 0.0);
        for y in 5..15u32 {
            for x in 5..25u32 {
                since[(y * 40 + x) as usize] = 0.1 * (x - 5) as f32;
            }
        }
        assert!(cut_by_age(&mask, &since, 0.5, 0).is_none());
        // Off, or ages of the wrong length: nothing to cut.
        let (mask, since) = two_blocks(1.0, 9.8);
        assert!(cut_by_age(&mask, &since, 0.0, 0).is_none());
        assert!(cut_by_age(&mask, &since[1..], 1.0, 0).is_none());
    }

    #[test]
    fn a_short_break_keeps_the_age_and_a_long_one_restarts_it() {
        let on = GrayImage::from_pixel(2, 1, image::Luma([255]));
        let mut off_right = on.clone();
        off_right.put_pixel(1, 0, image::Luma([0]));
        let mut ages = AgeMap::default();
        ages.update(&on, 1.0, 0.3);
        ages.update(&off_right, 1.1, 0.3);
        ages.update(&on, 1.2, 0.3);
        assert_eq!(
            ages.since(),
            &[1.0, 1.0],
            "back within the grace: the age is kept"
        );
        ages.update(&off_right, 1.3, 0.3);
        ages.update(&off_right, 1.4, 0.3);
        ages.update(&off_right, 1.5, 0.3);
        ages.update(&off_right, 1.6, 0.3);
        ages.update(&off_right, 1.7, 0.3);
        ages.update(&on, 1.8, 0.3);
        assert_eq!(ages.since(), &[1.0, 1.8], "out 0.6 s: the age starts again");
    }

    #[test]
    fn pieces_under_the_minimum_are_joined_again() {
        // The 10 × 10 blocks of `two_blocks` and a 3 × 3 speck on the old block's top edge,
        // as young as the right block (a moving limb): with a minimum piece of 20 px the
        // speck is joined again to the old block, the right block stays cut off.
        let (mut mask, mut since) = two_blocks(1.0, 9.8);
        for y in 2..5u32 {
            for x in 7..10u32 {
                mask.put_pixel(x, y, image::Luma([255]));
                since[(y * 40 + x) as usize] = 9.8;
            }
        }
        let loose = regions(&cut_by_age(&mask, &since, 1.0, 0).expect("cut"));
        assert_eq!(loose.len(), 3, "speck, old block, young block: {loose:?}");
        let joined = regions(&cut_by_age(&mask, &since, 1.0, 20).expect("cut"));
        assert_eq!(joined.len(), 2, "{joined:?}");
        // The old block with the whole speck back on it: 100 + 9 px, its box from y = 2.
        assert_eq!((joined[0].area_px, joined[0].bbox.top), (109, 2.0));
        assert_eq!((joined[1].area_px, joined[1].bbox.left), (90, 16.0));
        // A minimum above the young block's 90 px joins everything again: nothing cut.
        assert!(cut_by_age(&mask, &since, 1.0, 91).is_none());
    }

    /// The test written out: a mask pixel is cut when one of its 8 neighbours in the mask
    /// is more than the gap older.
    fn cut_pixels_reference(mask: &GrayImage, since: &[f32], gap: f32) -> Vec<bool> {
        let (w, h) = (mask.width() as i64, mask.height() as i64);
        let age = |x: i64, y: i64| {
            if x < 0 || y < 0 || x >= w || y >= h {
                return None;
            }
            let i = (y * w + x) as usize;
            (mask.as_raw()[i] != 0 && since[i].is_finite()).then_some(since[i])
        };
        let mut out = vec![false; (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                let Some(t) = age(x, y) else { continue };
                let mut older = false;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        older |= age(x + dx, y + dy).is_some_and(|s| s < t - gap);
                    }
                }
                out[(y * w + x) as usize] = older;
            }
        }
        out
    }

    #[test]
    fn the_cut_is_the_written_out_test() {
        use rand::RngExt;
        let mut rng = crate::rng::rng_for(99, crate::rng::Stream::Synthetic, 0);
        let mut next = || rng.random::<u32>();
        let mut ages = AgeMap::default();
        let mut cut_somewhere = 0;
        for trial in 0..200 {
            let (w, h) = (1 + next() % 40, 1 + next() % 30);
            let mask =
                GrayImage::from_fn(w, h, |_, _| image::Luma([(next() % 3 != 0) as u8 * 255]));
            // Ages in whole tenths of a second over 0–6 s, some NaN.
            let since: Vec<f32> = (0..w * h)
                .map(|_| match next() % 20 {
                    0 => f32::NAN,
                    k => (k * 3) as f32 / 10.0,
                })
                .collect();
            let gap = [0.5f32, 1.0, 2.0][trial % 3];
            let want = cut_pixels_reference(&mask, &since, gap);
            let mut expected = mask.clone();
            for (p, &c) in expected.as_mut().iter_mut().zip(&want) {
                if c {
                    *p = 0;
                }
            }
            let got = cut_by_age(&mask, &since, gap, 0);
            if want.iter().any(|&c| c) {
                cut_somewhere += 1;
                assert_eq!(got.as_ref(), Some(&expected), "trial {trial}");
            } else {
                assert!(got.is_none(), "trial {trial}");
            }
            // The buffers kept between frames give the same.
            ages.since = since.clone();
            assert_eq!(
                ages.cut(&mask, gap, 0),
                got,
                "trial {trial}, reused buffers"
            );
        }
        assert!(cut_somewhere > 100, "{cut_somewhere}");
    }

    #[test]
    fn every_non_zero_byte_is_visited_once_in_order() {
        use rand::RngExt;
        let mut rng = crate::rng::rng_for(7, crate::rng::Stream::Synthetic, 0);
        for len in 0..70usize {
            // Sparse, so that whole words are zero.
            let m: Vec<u8> = (0..len)
                .map(|_| u8::from(rng.random::<u32>() % 9 == 0) * 255)
                .collect();
            let mut got = Vec::new();
            super::for_each_on(&m, |i| got.push(i));
            let want: Vec<usize> = (0..len).filter(|&i| m[i] != 0).collect();
            assert_eq!(got, want, "length {len}");
        }
    }

    #[test]
    fn diagonal_contact_is_cut_too() {
        // Two 5 × 5 blocks meeting only corner to corner (8-connected: one region).
        let (w, h) = (20u32, 20u32);
        let mut mask = GrayImage::new(w, h);
        let mut since = vec![f32::NAN; (w * h) as usize];
        for (x0, y0, t) in [(2u32, 2u32, 0.0f32), (7, 7, 5.0)] {
            for y in y0..y0 + 5 {
                for x in x0..x0 + 5 {
                    mask.put_pixel(x, y, image::Luma([255]));
                    since[(y * w + x) as usize] = t;
                }
            }
        }
        assert_eq!(regions(&mask).len(), 1);
        let r = regions(&cut_by_age(&mask, &since, 1.0, 0).expect("cut"));
        assert_eq!(r.len(), 2);
        assert_eq!(r[1].area_px, 24, "the young block loses its corner pixel");
    }
}
